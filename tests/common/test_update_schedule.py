"""The per-transition update rule on its own (no model)."""

import pytest
from stable_baselines3.common.type_aliases import TrainFreq, TrainFrequencyUnit

from sb3_maddpg.common.update_schedule import UpdateSchedule


def steps(n: int) -> TrainFreq:
    return TrainFreq(n, TrainFrequencyUnit.STEP)


@pytest.mark.parametrize(("n_envs", "frequency"), [(1, 100), (3, 33), (16, 6), (100, 1), (256, 1)])
def test_train_freq_counts_transitions(n_envs: int, frequency: int) -> None:
    assert UpdateSchedule.from_arguments(100, None, None).train_freq(n_envs) == steps(frequency)
    assert UpdateSchedule.from_arguments(100, None, 2).train_freq(n_envs) == steps(frequency)  # gradient_steps alone


def test_a_given_train_freq_stands_and_nothing_is_earned() -> None:
    schedule = UpdateSchedule.from_arguments(100, 10, None)
    assert schedule.train_freq(4) is None and not schedule.earns_gradient_steps
    assert not UpdateSchedule.from_arguments(100, None, 3).earns_gradient_steps
    assert UpdateSchedule.from_arguments(100, None, None).earns_gradient_steps
    sb3 = UpdateSchedule.from_arguments(100, 10, 3)  # both given: SB3's meaning of both
    assert sb3.train_freq(4) is None and not sb3.earns_gradient_steps


def test_earned_counts_past_learning_starts_and_carries_the_remainder() -> None:
    schedule = UpdateSchedule.from_arguments(100, None, None)
    assert schedule.earned(num_timesteps=150, learning_starts=200) == 0  # still warming up
    assert schedule.credit == 0
    assert schedule.earned(num_timesteps=350, learning_starts=200) == 1  # 150 past learning_starts
    assert (schedule.credit, schedule.counted_at) == (50, 350)
    assert schedule.earned(num_timesteps=400, learning_starts=200) == 1  # 50 left over + 50 new
    assert schedule.credit == 0
    assert schedule.earned(num_timesteps=400, learning_starts=200) == 0  # nothing new: nothing counted twice
    assert schedule.earned(num_timesteps=1_000, learning_starts=200) == 6
    schedule.reset()
    assert (schedule.credit, schedule.counted_at) == (0, 0)
    assert schedule.earned(num_timesteps=300, learning_starts=200) == 1  # counted from learning_starts again


def test_describe() -> None:
    earned = UpdateSchedule.from_arguments(100, None, None)
    assert earned.describe(steps(1), n_envs=100, gradient_steps=1, batch_size=32, learning_starts=25_600) == (
        "one gradient step (batch 32) per 100 transitions after step 25,600, taken every 1 step(s) of 100 env(s)"
    )
    sb3 = UpdateSchedule.from_arguments(100, 10, 3)
    assert sb3.describe(steps(10), n_envs=4, gradient_steps=3, batch_size=32, learning_starts=0) == (
        "3 gradient step(s) (batch 32) every 10 step(s) of 4 env(s), after step 0 (SB3's train_freq semantics)"
    )
    assert "a gradient step per transition" in sb3.describe(steps(10), 4, -1, 32, 0)


@pytest.mark.parametrize("value", [0, -5, 2.5, True, "100"])
def test_bad_transitions_per_update_is_refused(value: object) -> None:
    with pytest.raises(ValueError, match=r"transitions_per_update must be a positive integer.*the paper's is 100"):
        UpdateSchedule.from_arguments(value, None, None)  # type: ignore[arg-type]
