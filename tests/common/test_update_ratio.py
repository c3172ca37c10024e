"""The paper's update ratio (one gradient step per 100 transitions) for any number of envs, and SB3's when asked."""

import pytest
from stable_baselines3.common.type_aliases import TrainFreq, TrainFrequencyUnit

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import SimpleSpreadVecEnv

SMALL = dict(batch_size=32, policy_kwargs=dict(net_arch=[8]), seed=0)


def make_model(n_envs: int, **kwargs: object) -> MADDPG:
    return MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs, n_agents=3), **{**SMALL, **kwargs})  # type: ignore[arg-type]


@pytest.mark.slow
@pytest.mark.parametrize("n_envs", [1, 3, 16, 100, 256])
def test_one_gradient_step_per_100_transitions_for_any_n_envs(n_envs: int) -> None:
    model = make_model(n_envs, learning_starts=500)
    model.learn(5_000)
    # Every transition past learning_starts counts, whatever the number of envs.
    assert model._n_updates == (model.num_timesteps - 500) // 100
    assert model.num_timesteps >= 5_000  # SB3 finishes the rollout it is in
    assert model.train_freq == TrainFreq(max(1, 100 // n_envs), TrainFrequencyUnit.STEP)


def test_with_100_envs_one_gradient_step_per_vectorised_step() -> None:
    model = make_model(100, learning_starts=0)
    counts = []
    for _ in range(3):
        model.learn(100, reset_num_timesteps=False)
        counts.append(model._n_updates)
    assert counts == [1, 2, 3]
    model.learn(100)  # timesteps count from 0 again, and so do the earned gradient steps
    assert model._n_updates == 4


def test_a_remainder_carries_over_to_the_next_learn() -> None:
    model = make_model(16, learning_starts=0)
    model.learn(400)  # 5 updates of 96 transitions: 480 transitions, 4 gradient steps and 80 left over
    assert (model.num_timesteps, model._n_updates) == (480, 4)
    model.learn(400, reset_num_timesteps=False)  # 480 more: with the 80 left over, 5 more gradient steps
    assert (model.num_timesteps, model._n_updates) == (960, 9)


def test_the_credit_carries_over_and_restarts_with_the_timesteps() -> None:
    model = make_model(16, learning_starts=0, transitions_per_update=40)
    model.learn(400)  # 25 vectorised steps of 16 = 400 transitions = 10 gradient steps, in updates every 2 steps
    assert model._n_updates == 10 and model.train_freq.frequency == 2  # type: ignore[union-attr]
    model.learn(400, reset_num_timesteps=True)  # counting restarts: no credit left from the first run
    assert model._n_updates == 20


def test_explicit_train_freq_and_gradient_steps_keep_sb3s_meaning() -> None:
    model = make_model(4, learning_starts=0, train_freq=10, gradient_steps=3)
    model.learn(400)  # 100 vectorised steps: an update every 10 of them, 3 gradient steps each
    assert model._n_updates == 30
    assert "3 gradient step(s) (batch 32) every 10 step(s) of 4 env(s)" in model.update_schedule
    # train_freq alone: SB3's default of one gradient step per update.
    only_freq = make_model(1, learning_starts=0, train_freq=(1, "episode"))
    only_freq.learn(400)
    assert only_freq._n_updates == 16
    # gradient_steps alone: updates at the derived frequency, with that many steps each.
    only_steps = make_model(20, learning_starts=0, gradient_steps=2)
    only_steps.learn(400)  # an update every 5 vectorised steps of 20 envs: 4 updates
    assert only_steps._n_updates == 8


def test_the_rule_follows_the_env_on_load(tmp_path: object) -> None:
    model = make_model(4, learning_starts=0)
    assert model.train_freq.frequency == 25  # type: ignore[union-attr]
    path = f"{tmp_path}/model.zip"
    model.save(path)
    loaded = MADDPG.load(path, env=SimpleSpreadVecEnv(100, n_agents=3))
    assert loaded.train_freq.frequency == 1 and loaded.transitions_per_update == 100  # type: ignore[union-attr]
    assert "per 100 transitions" in loaded.update_schedule


@pytest.mark.parametrize("value", [0, -5, 2.5, True])
def test_bad_transitions_per_update_is_refused(value: object) -> None:
    with pytest.raises(ValueError, match=r"^transitions_per_update \(.*\) must be an integer >= 1, got "):
        make_model(2, transitions_per_update=value)


def test_update_schedule_says_the_rule() -> None:
    schedule = make_model(100, learning_starts=25_600).update_schedule
    assert schedule == (
        "one gradient step (batch 32) per 100 transitions after step 25,600, taken every 1 step(s) of 100 env(s)"
    )
