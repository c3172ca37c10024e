"""The multi-agent replay buffer: joint rows, per-agent rewards and terminations, stored selections."""

import os
import re
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces

from sb3_maddpg import MADDPG
from sb3_maddpg.common.buffers import (
    MultiAgentReplayBuffer,
    available_memory_bytes,
    check_replay_buffer_fits,
    replay_buffer_bytes,
)
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.selection import NearestAgents
from sb3_maddpg.envs import make_simple_spread
from tests.settings import FILLS_THE_BUFFER_ONLY

LAYOUT = AgentLayout(("a", "b", "c"), (4, 4, 4), (2, 2, 2), position_slices=(slice(2, 4),) * 3)
OBS_SPACE = spaces.Box(-np.inf, np.inf, (12,), np.float32)
ACTION_SPACE = spaces.Box(-1, 1, (6,), np.float32)


def make_buffer(n_envs: int = 2, selector: NearestAgents | None = None, **kwargs: Any) -> MultiAgentReplayBuffer:
    return MultiAgentReplayBuffer(
        50, OBS_SPACE, ACTION_SPACE, "cpu", n_envs=n_envs, layout=LAYOUT, selector=selector, **kwargs
    )


def info(rewards: list[float], terminated: bool = False, truncated: bool = False) -> dict[str, Any]:
    return {
        "agent_rewards": np.array(rewards, dtype=np.float32),
        "agent_terminations": np.array([terminated] * 3),
        "TimeLimit.truncated": truncated,
    }


def test_rows_hold_per_agent_rewards_terminations_and_selection() -> None:
    selector = NearestAgents(k=1)
    buffer = make_buffer(selector=selector)
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(2, 12)).astype(np.float32)
    next_obs = rng.normal(size=(2, 12)).astype(np.float32)  # other positions: another selection
    assert (selector.select(next_obs, LAYOUT) != selector.select(obs, LAYOUT)).any()
    buffer.add(
        obs,
        next_obs,
        np.zeros((2, 6)),
        np.array([6.0, 0.0]),
        np.array([True, True]),
        [info([1, 2, 3], terminated=True), info([-1, -2, -3], truncated=True)],
    )
    assert buffer.rewards[0].tolist() == [[1, 2, 3], [-1, -2, -3]]
    assert buffer.dones[0].tolist() == [[1, 1, 1], [0, 0, 0]]  # truncation is not termination
    assert buffer.timeouts[0].tolist() == [0, 1]
    assert (buffer.selections[0] == selector.select(obs, LAYOUT)).all()  # made from the observation at time t


def test_without_timeout_handling_truncation_is_stored_as_termination() -> None:
    """handle_timeout_termination=False: SB3's meaning, every end of an episode stops the bootstrap."""
    buffer = make_buffer(n_envs=4, handle_timeout_termination=False)
    infos = [info([1, 2, 3], truncated=True), info([1, 2, 3], terminated=True), info([1, 2, 3]), info([1, 2, 3])]
    infos[3]["agent_terminations"] = np.array([False, True, False])  # one agent done, the episode goes on
    obs = np.zeros((4, 12), dtype=np.float32)
    buffer.add(obs, obs, np.zeros((4, 6)), np.zeros(4), np.array([True, True, False, False]), infos)
    assert buffer.dones[0].tolist() == [[1, 1, 1], [1, 1, 1], [0, 0, 0], [0, 1, 0]]
    assert buffer.timeouts[0].tolist() == [0, 0, 0, 0]
    # Without agent_terminations in the info, the episode's end is every agent's.
    del infos[0]["agent_terminations"]
    buffer.add(obs, obs, np.zeros((4, 6)), np.zeros(4), np.array([True, True, False, False]), infos)
    assert buffer.dones[1, 0].tolist() == [1, 1, 1]


def test_samples_align_every_agent_on_the_same_rows() -> None:
    buffer = make_buffer(n_envs=1, selector=NearestAgents(k=2))
    for t in range(20):
        obs = np.full((1, 12), float(t), dtype=np.float32)
        obs[0, [2, 6, 10]] = [0.0, t % 3, 5.0]  # positions vary, so selections vary by row
        buffer.add(obs, obs + 0.5, np.full((1, 6), t / 20), np.zeros(1), np.zeros(1), [info([t, 10 * t, 100 * t])])
    data = buffer.sample(64)
    t = data.observations[:, 0]
    assert th.equal(data.rewards, th.stack([t, 10 * t, 100 * t], dim=1))
    assert th.allclose(data.next_observations[:, 0], t + 0.5)
    assert th.allclose(data.actions[:, 0], t / 20)
    assert data.selections is not None and data.selections.dtype == th.long and data.selections.shape == (64, 3, 2)


def test_missing_agent_rewards_is_a_clear_error() -> None:
    with pytest.raises(KeyError, match="agent_rewards.*PettingZooToGym"):
        make_buffer(n_envs=1).add(np.zeros((1, 12)), np.zeros((1, 12)), np.zeros((1, 6)), np.zeros(1), np.zeros(1), [{}])


def test_buffer_needs_layout_and_refuses_memory_optimisation() -> None:
    with pytest.raises(ValueError, match="layout"):
        MultiAgentReplayBuffer(10, OBS_SPACE, ACTION_SPACE)
    with pytest.raises(ValueError, match="optimize_memory_usage"):
        MultiAgentReplayBuffer(10, OBS_SPACE, ACTION_SPACE, optimize_memory_usage=True, layout=LAYOUT)


def test_memory_formula_in_the_docstring() -> None:
    """4 * (2 * obs_dim + action_dim + 2 * n_agents + 1) + 2 * n_agents * k bytes per row."""
    env = make_simple_spread(n_agents=5)
    layout = env.agent_layout
    buffer = MultiAgentReplayBuffer(1000, env.observation_space, env.action_space, layout=layout, selector=NearestAgents(k=2))
    per_row = 4 * (2 * layout.obs_dim + layout.action_dim + 2 * layout.n_agents + 1) + 2 * layout.n_agents * 2
    assert buffer.nbytes() == 1000 * per_row
    assert 1e6 * per_row / 1e9 == pytest.approx(1.36, abs=0.01)  # the figure stated for N=5 at 1e6 transitions


class TerminatingTeam(gym.Env):
    """Two agents; the episode truly terminates at step 3 (no time limit)."""

    observation_space = spaces.Box(-10, 10, (4,), np.float32)
    action_space = spaces.Box(-1, 1, (2,), np.float32)
    agent_layout = AgentLayout(("x", "y"), (2, 2), (1, 1))

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.t = 0
        return np.zeros(4, np.float32), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.t += 1
        done = self.t == 3
        rewards = np.array([1.0, -1.0], dtype=np.float32)
        return np.full(4, self.t, np.float32), 0.0, done, False, {"agent_rewards": rewards, "agent_terminations": [done] * 2}


@pytest.mark.parametrize("target", ["stored", "next"])
def test_a_selector_targeting_the_next_step_selects_again_from_the_next_observation(target: str) -> None:
    selector = NearestAgents(k=1, target=target)  # type: ignore[arg-type]
    buffer = make_buffer(selector=selector)
    rng = np.random.default_rng(0)
    obs, next_obs = (rng.normal(size=(2, 12)).astype(np.float32) for _ in range(2))
    assert (selector.select(next_obs, LAYOUT) != selector.select(obs, LAYOUT)).any()  # the nearest changed
    buffer.add(obs, next_obs, np.zeros((2, 6)), np.zeros(2), np.array([False, False]), [info([0, 0, 0])] * 2)
    np.random.seed(3)
    data = buffer._get_samples(np.zeros(8, dtype=np.int64))
    np.random.seed(3)
    envs = np.random.randint(0, 2, size=8)  # the env of each sampled row, as the buffer drew it
    assert len(set(envs.tolist())) == 2
    assert th.equal(data.selections, th.as_tensor(selector.select(obs[envs], LAYOUT)))  # stored at time t
    if target == "stored":
        assert data.next_selections is None  # the target reuses the stored selection
    else:
        assert th.equal(data.next_selections, th.as_tensor(selector.select(next_obs[envs], LAYOUT)))


@FILLS_THE_BUFFER_ONLY
def test_true_termination_stops_bootstrapping() -> None:
    model = MADDPG("MlpPolicy", TerminatingTeam(), policy_kwargs=dict(net_arch=[8]), learning_starts=1000, batch_size=4)
    model.learn(9)
    buffer = model.replay_buffer
    assert buffer.dones[:9, 0, 0].tolist() == [0, 0, 1] * 3
    assert buffer.timeouts[:9].sum() == 0
    data = buffer._get_samples(np.array([2, 5, 1]))
    targets = model._critic_targets(data)
    assert th.equal(targets[:2], data.rewards[:2])  # terminal rows: y = r
    assert not th.equal(targets[2], data.rewards[2])  # a non-terminal row bootstraps


def test_sampling_after_the_buffer_wrapped_reads_only_the_newest_rows_whole() -> None:
    # Every 2.5M-step run with a 1e6 buffer wraps around: the oldest rows are overwritten, and every sampled row's
    # observation, action, reward, next observation and done are still one transition's.
    # 10 transitions of 2 envs: 5 rows (SB3 counts buffer_size over all envs).
    buffer = MultiAgentReplayBuffer(10, OBS_SPACE, ACTION_SPACE, "cpu", n_envs=2, layout=LAYOUT)
    for step in range(8):  # 8 adds into 5 rows: steps 3..7 remain, 5..7 in rows 0..2
        obs = np.full((2, 12), step, dtype=np.float32) + np.array([[0.0], [0.5]], dtype=np.float32)
        infos = [info([step, step, step], terminated=step % 2 == 1) for _ in range(2)]
        buffer.add(obs, obs + 100, np.full((2, 6), step / 10), np.zeros(2), np.array([step % 2 == 1] * 2), infos)
    assert buffer.full and buffer.pos == 3
    np.random.seed(0)
    batch = buffer.sample(2_000)
    steps = np.floor(batch.observations[:, 0].numpy())
    assert set(steps.tolist()) == {3.0, 4.0, 5.0, 6.0, 7.0}  # the newest five, each of them
    np.testing.assert_allclose(batch.next_observations[:, 0].numpy(), batch.observations[:, 0].numpy() + 100)
    np.testing.assert_allclose(batch.actions[:, 0].numpy(), steps / 10, rtol=1e-6)
    np.testing.assert_allclose(batch.rewards.numpy(), np.repeat(steps[:, None], 3, axis=1))
    np.testing.assert_allclose(batch.dones.numpy(), np.repeat((steps % 2 == 1)[:, None], 3, axis=1).astype(np.float32))


@pytest.mark.parametrize(
    ("done", "truncated", "expected_done", "expected_timeout"),
    [(True, True, 0.0, 1.0), (True, False, 1.0, 0.0), (False, False, 0.0, 0.0)],
)
def test_without_agent_terminations_a_truncation_is_not_terminal(
    done: bool, truncated: bool, expected_done: float, expected_timeout: float
) -> None:
    # An env whose info has no per-agent terminations: the episode's end counts for every agent, unless it was a
    # truncation (then the target bootstraps). A wrong sign here would store done = 2.0.
    buffer = make_buffer(n_envs=1)
    row = {"agent_rewards": np.zeros(3, dtype=np.float32), "TimeLimit.truncated": truncated}
    buffer.add(np.zeros((1, 12)), np.zeros((1, 12)), np.zeros((1, 6)), np.zeros(1), np.array([done]), [row])
    assert buffer.dones[0, 0].tolist() == [expected_done] * 3
    assert buffer.timeouts[0, 0] == expected_timeout


@pytest.mark.parametrize(("n_envs", "k", "next_stored"), [(1, 0, False), (3, 2, False), (4, 1, True)])
def test_the_memory_planned_before_allocation_is_what_the_arrays_take(n_envs: int, k: int, next_stored: bool) -> None:
    from sb3_maddpg.envs import PettingZooToGym
    from tests.envs.walkers import Walkers

    positions = (lambda e: e.positions()) if next_stored else slice(3, 5)
    env = PettingZooToGym(Walkers(observe="dict" if not next_stored else "noise"), positions=positions)
    selector = NearestAgents(k=k, target="next") if k else None
    buffer = MultiAgentReplayBuffer(
        101, env.observation_space, env.action_space, layout=env.agent_layout, selector=selector, n_envs=n_envs
    )
    assert (buffer.next_selections is not None) is next_stored
    assert buffer.planned_bytes == buffer.nbytes() == replay_buffer_bytes(101, n_envs, env.agent_layout, k, next_stored)


@pytest.mark.parametrize("buffer_size", [1, 4, 7, 8])
def test_a_buffer_of_fewer_transitions_than_two_per_env_plans_the_rows_sb3_allocates(buffer_size: int) -> None:
    """SB3 keeps ``max(buffer_size // n_envs, 1)`` rows of ``n_envs`` transitions: at 4 envs, a buffer_size of 1, 4 or 7
    is one row and 8 is two; the memory planned before allocation is what those rows take."""
    buffer = MultiAgentReplayBuffer(buffer_size, OBS_SPACE, ACTION_SPACE, "cpu", n_envs=4, layout=LAYOUT)
    assert buffer.buffer_size == (2 if buffer_size == 8 else 1)
    assert buffer.nbytes() == replay_buffer_bytes(buffer_size, 4, LAYOUT, 0, False) == buffer.planned_bytes


@pytest.mark.skipif(not Path("/proc/meminfo").exists(), reason="reads Linux's /proc/meminfo")
def test_the_memory_available_is_read_on_linux_in_bytes() -> None:
    """Where Linux says (MemAvailable, in kB), the memory check has a number to check against: some bytes, whole kB,
    no more than the machine has."""
    available = available_memory_bytes()
    physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    assert available is not None and 0 < available <= physical and available % 1024 == 0


def test_a_buffer_larger_than_the_memory_is_refused_and_over_half_of_it_warned_about() -> None:
    per = 1000
    check_replay_buffer_fits(500 * per, 500, 1000 * per)  # exactly half: quiet
    with pytest.warns(UserWarning, match=r"^The replay buffer would take .* over half of the"):
        check_replay_buffer_fits(501 * per, 501, 1000 * per)
    with pytest.warns(UserWarning):
        check_replay_buffer_fits(1000 * per, 1000, 1000 * per)  # exactly all of it: still allowed
    message = r"^The replay buffer would take .*\(buffer_size=1,001 joint transitions of 1,000 bytes each\), more than"
    with pytest.raises(ValueError, match=message + r".*lower buffer_size \(e\.g\. buffer_size=100 takes"):
        check_replay_buffer_fits(1001 * per, 1001, 1000 * per)
    check_replay_buffer_fits(10**15, 10**12, None)  # memory unknown: no check


def test_a_buffer_of_exactly_half_the_memory_is_quiet_and_one_byte_more_warns() -> None:
    """The warning is for a buffer that takes *over* half of the memory: at exactly half nothing is said, one byte more
    is warned about (with an odd number of bytes, half is rounded down: 500,000 of 1,000,001)."""
    for available in (1_000_000, 1_000_001):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # any warning fails
            check_replay_buffer_fits(500_000, 500, available)
        with pytest.warns(UserWarning, match="over half of the"):
            check_replay_buffer_fits(500_001, 500, available)


def suggested_buffer_size(needed: int, buffer_size: int, available: int) -> int:
    """:return: The ``buffer_size`` that :func:`check_replay_buffer_fits`'s warning or refusal suggests."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            check_replay_buffer_fits(needed, buffer_size, available)
        except ValueError as error:
            message = str(error)
        else:
            assert len(caught) == 1, "a warning or a refusal was expected"
            message = str(caught[0].message)
    found = re.search(r"e\.g\. buffer_size=([\d_]+) takes", message)
    assert found, message
    return int(found.group(1))


@pytest.mark.parametrize(
    "available, expected",
    [
        (2_000_000, 1_000),  # half is 1,000,000 bytes: 1,000 rows of 1,000 bytes fit it exactly (quiet, as above)
        (1_999_998, 100),  # half is 999,999 bytes: 1,000 rows are one byte too many, so the next power of ten down
        (50_000, 10),  # half holds 25 rows
        (1_000, 1),  # half holds not one row: the smallest buffer there is
    ],
)
def test_the_suggested_buffer_size_is_the_largest_power_of_ten_that_fits_half_the_memory(
    available: int, expected: int
) -> None:
    per_row = 1_000
    # A buffer of all the memory (warned about) and one of twice it (refused) get the same suggestion.
    for buffer_size in (available // per_row, 2 * available // per_row):
        suggested = suggested_buffer_size(buffer_size * per_row, buffer_size, available)
        assert suggested == expected
        if suggested > 1:  # the suggestion is quiet, and ten times it would not be
            assert suggested * per_row <= available // 2 < 10 * suggested * per_row


def test_maddpg_with_a_buffer_that_cannot_fit_is_refused_before_allocating_it_but_a_saved_one_loads(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Any
) -> None:
    env = make_simple_spread(n_agents=3)
    saved = MADDPG("MlpPolicy", env, buffer_size=10_000, policy_kwargs={"net_arch": [8]})
    saved.save(tmp_path / "team")
    monkeypatch.setattr("sb3_maddpg.common.buffers.available_memory_bytes", lambda: 2**20)  # a machine of 1 MiB free
    with pytest.raises(ValueError, match=r"^The replay buffer would take [\d.]+ GiB \(buffer_size=10,000 joint "):
        MADDPG("MlpPolicy", env, buffer_size=10_000)
    # A saved model is often loaded only to act: its buffer is allocated lazily and never filled, so it loads with a
    # warning that says how to train it here.
    with pytest.warns(UserWarning, match=r"fine to act, but training would run out of memory; .*custom_objects"):
        loaded = MADDPG.load(tmp_path / "team")
    assert loaded.predict(env.reset(seed=0)[0])[0].shape == env.action_space.shape


def test_an_info_without_agent_terminations_or_a_time_limit_flag_ends_every_agent_at_the_episodes_end() -> None:
    """A custom VecEnv's infos may carry only agent_rewards: then an episode's end is every agent's termination, and
    a step that does not end it is none's (timeout handling on, nothing says it was a time limit)."""
    buffer = make_buffer(n_envs=3)
    infos = [{"agent_rewards": np.ones(3, np.float32)} for _ in range(3)]
    infos[2]["TimeLimit.truncated"] = True  # beside it: the same end, said to be a time limit, bootstraps
    obs = np.zeros((3, 12), dtype=np.float32)
    buffer.add(obs, obs, np.zeros((3, 6)), np.zeros(3), np.array([True, False, True]), infos)
    assert buffer.dones[0].tolist() == [[1, 1, 1], [0, 0, 0], [0, 0, 0]]
    assert buffer.timeouts[0].tolist() == [0, 0, 1]
