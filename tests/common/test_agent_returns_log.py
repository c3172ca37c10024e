"""Each agent's episode return in SB3's logger (issue 34): ``rollout/<agent_id>/ep_rew_mean`` beside SB3's
``rollout/ep_rew_mean``, over the same window of finished episodes, checked against a hand computation from the env's
per-agent rewards, on the batched env, the adapter over mpe2 and a team of two kinds of agents."""

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import KVWriter, Logger
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnvWrapper, VecMonitor
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import PettingZooToGym, SimpleSpreadVecEnv, make_simple_spread
from tests.mixed_team import MixedTeam

pytestmark = pytest.mark.filterwarnings("ignore:learn\\(\\) ended at step")  # no update needed: only the logs count

WINDOW = 3
"""SB3's stats_window_size here: fewer than the episodes that finish, so that the window matters."""

ENVS: dict[str, Callable[[], Any]] = {
    "batched": lambda: VecMonitor(SimpleSpreadVecEnv(n_envs=2, n_agents=3, max_cycles=5)),
    "adapter_vec_monitor": lambda: VecMonitor(DummyVecEnv([lambda: make_simple_spread(n_agents=3, max_cycles=5)] * 2)),
    "adapter_monitor": lambda: make_simple_spread(n_agents=3, max_cycles=5),  # SB3 wraps it in a Monitor
    "mixed": lambda: PettingZooToGym(MixedTeam()),  # agents mover and chooser, rewarded differently, 10-step episodes
}


class Records(KVWriter):
    """Every table the logger writes."""

    def __init__(self) -> None:
        self.tables: list[dict[str, Any]] = []

    def write(self, key_values: dict[str, Any], key_excluded: dict[str, Any], step: int = 0) -> None:
        self.tables.append(dict(key_values))


class StepRewards(BaseCallback):
    """Each step's per-agent rewards and dones, as the env gave them, and the step count after it."""

    def __init__(self) -> None:
        super().__init__()
        self.steps: list[tuple[int, np.ndarray, np.ndarray]] = []
        self.learn_starts: list[int] = []  # where each learn() call begins, in self.steps

    def _on_training_start(self) -> None:
        self.learn_starts.append(len(self.steps))

    def _on_step(self) -> bool:
        rewards = np.array([info["agent_rewards"] for info in self.locals["infos"]], dtype=np.float64)
        self.steps.append((self.num_timesteps, rewards, np.array(self.locals["dones"])))
        return True


def by_hand(steps: list[tuple[int, np.ndarray, np.ndarray]], reset_at: int | None = None) -> np.ndarray:
    """
    Each agent's mean return over the last WINDOW episodes finished in ``steps``: rewards summed per env from the
    env's own per-agent rewards, an episode closed at its done.

    :param steps: The recorded steps up to a table.
    :param reset_at: The index of the first step after the envs were reset by a new learn() (from step 0): the
        episodes under way are dropped, and SB3's window starts empty.
    """
    finished: list[np.ndarray] = []
    running = np.zeros_like(steps[0][1])
    for index, (_, rewards, dones) in enumerate(steps):
        if index == reset_at:
            running, finished = np.zeros_like(rewards), []
        running += rewards
        for env in np.flatnonzero(dones):
            finished.append(running[env].copy())
            running[env] = 0.0
    return np.mean(finished[-WINDOW:], axis=0)


def up_to(recorder: StepRewards, timesteps: int) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """:return: The steps of a learn() from step 0 up to ``timesteps``."""
    return [step for step in recorder.steps if step[0] <= timesteps]


def learn(model: MADDPG, steps: int, recorder: StepRewards, reset_num_timesteps: bool = True) -> None:
    model.learn(steps, callback=recorder, log_interval=1, reset_num_timesteps=reset_num_timesteps)


def logged(table: dict[str, Any], agent_ids: tuple[str, ...]) -> np.ndarray:
    return np.array([table[f"rollout/{agent}/ep_rew_mean"] for agent in agent_ids])


@pytest.mark.parametrize("env", sorted(ENVS))
def test_each_agents_mean_return_is_its_summed_rewards_over_sb3s_window(env: str) -> None:
    model = MADDPG("MlpPolicy", ENVS[env](), learning_starts=10_000, stats_window_size=WINDOW, seed=0)
    records, recorder = Records(), StepRewards()
    model.set_logger(Logger(None, [records]))
    learn(model, 60, recorder)
    agent_ids = model.agent_layout.agent_ids
    tables = [table for table in records.tables if "rollout/ep_rew_mean" in table]
    assert len(tables) >= 5  # a table at every finished episode (log_interval=1), most with a full window
    for table in tables:
        expected = by_hand(up_to(recorder, table["time/total_timesteps"]))
        np.testing.assert_allclose(logged(table, agent_ids), expected, rtol=1e-6)
        # The team return SB3 logs is their sum (team_reward="sum"), over the same episodes.
        np.testing.assert_allclose(expected.sum(), table["rollout/ep_rew_mean"], rtol=1e-5)
    # Not the same numbers for every agent (the hand computation tells them apart).
    assert any(np.ptp(logged(table, agent_ids)) > 0 for table in tables)
    # The returns travel with SB3's episode statistics (saved with them, seen by callbacks).
    assert all(len(episode["agent_returns"]) == len(agent_ids) for episode in model.ep_info_buffer)


def test_an_episode_across_two_learn_calls_counts_whole_and_a_new_learn_starts_afresh() -> None:
    model = MATD3(
        "MlpPolicy",
        make_simple_spread(n_agents=3, max_cycles=5),
        learning_starts=10_000,
        transitions_per_update=1,  # a rollout of one step: learn(7) stops at step 7
        stats_window_size=WINDOW,
        seed=0,
    )
    records, recorder = Records(), StepRewards()
    model.set_logger(Logger(None, [records]))
    learn(model, 7, recorder)  # ends 2 steps into the second episode
    learn(model, 10, recorder, reset_num_timesteps=False)  # the same episode goes on: its first 2 steps count
    agent_ids = model.agent_layout.agent_ids
    continued = [table for table in records.tables if "rollout/ep_rew_mean" in table]
    assert [table["time/total_timesteps"] for table in continued] == [5, 10, 15]
    for table in continued:
        np.testing.assert_allclose(logged(table, agent_ids), by_hand(up_to(recorder, table["time/total_timesteps"])))
    records.tables.clear()
    learn(model, 17, recorder)  # SB3 resets the env 2 steps into the 4th episode: those steps are in no new episode
    restart = recorder.learn_starts[-1]
    fresh = [table for table in records.tables if "rollout/ep_rew_mean" in table]
    assert [table["time/total_timesteps"] for table in fresh] == [5, 10, 15]
    for table in fresh:
        steps = recorder.steps[: restart + table["time/total_timesteps"]]  # one env: one recorded step per timestep
        np.testing.assert_allclose(logged(table, agent_ids), by_hand(steps, reset_at=restart))


def test_no_episode_statistics_no_agent_returns() -> None:
    """A bare SimpleSpreadVecEnv has no Monitor: SB3 logs no ep_rew_mean, and no agent's either."""
    model = MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs=2, n_agents=3, max_cycles=5), learning_starts=10_000, seed=0)
    records = Records()
    model.set_logger(Logger(None, [records]))
    model.learn(30, log_interval=1)
    assert records.tables and not any(key.startswith("rollout/") for table in records.tables for key in table)


class WithoutAgentRewards(VecEnvWrapper):
    """A VecEnv whose infos lack ``agent_rewards`` (a custom env that forgot them)."""

    def reset(self) -> VecEnvObs:
        return self.venv.reset()

    def step_wait(self) -> VecEnvStepReturn:
        observations, rewards, dones, infos = self.venv.step_wait()
        for info in infos:
            info.pop("agent_rewards")
        return observations, rewards, dones, infos


def test_an_env_without_agent_rewards_still_gets_the_buffers_error() -> None:
    """The returns' bookkeeping, which runs first, must not hide the replay buffer's error that says what to do."""
    model = MADDPG("MlpPolicy", WithoutAgentRewards(SimpleSpreadVecEnv(n_envs=2, n_agents=3)), seed=0)
    with pytest.raises(KeyError, match="The env's info has no 'agent_rewards': MADDPG trains critic i on agent i's reward"):
        model.learn(10)
