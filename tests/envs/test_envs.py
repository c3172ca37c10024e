"""Tests of the PettingZoo-to-gymnasium adapter, ``make_simple_spread`` and the simple_spread metrics."""

import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import supersuit
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env as gym_check_env
from mpe2 import simple_adversary_v3, simple_speaker_listener_v4, simple_spread_v3
from pettingzoo import ParallelEnv
from pettingzoo.utils.env_logger import EnvLogger
from stable_baselines3.common.env_checker import check_env as sb3_check_env
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

import sb3_maddpg  # noqa: F401  (registers the gymnasium ids)
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.envs import (
    CAPTURE_RADIUS,
    SIMPLE_SPREAD_ID,
    PettingZooToGym,
    SimpleSpreadMetrics,
    make_simple_spread,
)

MAX_CYCLES = 25  # simple_spread's default episode length (the paper's too)
METRIC_KEYS = ("coverage", "success", "collisions", "min_dist_sum")
AGENT_SIZE = 0.15  # mpe2 simple_spread's agent radius: two agents touch below 0.30


def expected_obs_size(n_agents: int, num_agent_neighbors: int | None) -> int:
    """
    Length of one simple_spread agent's observation, from mpe2's ``Scenario.observation``:
    own velocity (2) + own position (2) + one 2-D offset per landmark (2N, N landmarks)
    + one 2-D offset per observed other agent (2 * others) + one 2-D communication slot per
    observed other agent (2 * others, world.dim_c == 2), where others is N - 1 under full
    observability and ``num_agent_neighbors`` under partial observability (zero-padded slots).
    """
    others = n_agents - 1 if num_agent_neighbors is None else num_agent_neighbors
    return 4 + 2 * n_agents + 2 * others + 2 * others


def random_joint_action(env: gym.Env, rng: np.random.Generator) -> np.ndarray:
    return rng.uniform(0.0, 1.0, size=env.action_space.shape).astype(np.float32)


def spy_on_step(monkeypatch: pytest.MonkeyPatch, parallel_env: Any) -> list[tuple[dict, tuple]]:
    """Record every (actions, result) that passes through ``parallel_env.step``."""
    calls: list[tuple[dict, tuple]] = []
    original_step = parallel_env.step

    def step(actions: dict) -> tuple:
        result = original_step(actions)
        calls.append(({agent: np.array(action, copy=True) for agent, action in actions.items()}, result))
        return result

    monkeypatch.setattr(parallel_env, "step", step)
    return calls


# ---------------------------------------------------------------------------------------------
# A tiny scriptable ParallelEnv for the error paths and black_death.
# ---------------------------------------------------------------------------------------------


class FakeParallelEnv(ParallelEnv):
    """
    Agents ``a0, a1, a2`` with Box(0, 1, (2,)) actions. Agent ``ai``'s observation is
    ``[i + 1, t, sum of its last action]`` and its reward ``(i + 1) * t``.

    :param obs_space: Observation space of every agent (a Dict one to test the type check); a Box
        must hold 3 entries.
    :param act_space: Action space of every agent (a Box with 2 entries by default).
    :param reset_agents: Agents present after reset (default: all of ``possible_agents``).
    :param dying_agent: Agent that terminates at step ``die_at`` and is removed (PettingZoo style).
    :param end_at: Step at which every remaining agent terminates (and, with ``end_truncates``,
        is truncated as well).
    :param vanishing_agent: Agent that silently disappears from the outputs at step ``die_at``.
    """

    metadata = {"name": "fake_parallel_v0", "render_modes": []}

    def __init__(
        self,
        obs_space: spaces.Space | None = None,
        act_space: spaces.Space | None = None,
        reset_agents: list[str] | None = None,
        dying_agent: str | None = None,
        vanishing_agent: str | None = None,
        die_at: int = 2,
        end_at: int = 5,
        end_truncates: bool = False,
    ) -> None:
        self.possible_agents = ["a0", "a1", "a2"]
        self.agents: list[str] = []
        self._obs_space = obs_space if obs_space is not None else spaces.Box(-np.inf, np.inf, (3,), np.float32)
        self._act_space = act_space if act_space is not None else spaces.Box(0.0, 1.0, (2,), np.float32)
        self.reset_agents = reset_agents
        self.dying_agent = dying_agent
        self.vanishing_agent = vanishing_agent
        self.die_at = die_at
        self.end_at = end_at
        self.end_truncates = end_truncates
        self.t = 0
        self.received: list[dict[str, np.ndarray]] = []

    def observation_space(self, agent: str) -> spaces.Space:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Space:
        return self._act_space

    def _obs(self, agent: str, action_sum: float = 0.0) -> np.ndarray:
        obs = np.array([self.possible_agents.index(agent) + 1, self.t, action_sum], dtype=np.float32)
        if isinstance(self._obs_space, spaces.Box):  # follow the space's shape and dtype
            obs = obs.reshape(self._obs_space.shape).astype(self._obs_space.dtype)
        return obs

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        self.t = 0
        self.agents = list(self.reset_agents if self.reset_agents is not None else self.possible_agents)
        return {agent: self._obs(agent) for agent in self.agents}, {agent: {} for agent in self.agents}

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        self.t += 1
        self.received.append(dict(actions))
        agents = [agent for agent in self.agents if not (agent == self.vanishing_agent and self.t >= self.die_at)]
        observations = {agent: self._obs(agent, float(np.sum(actions[agent]))) for agent in agents}
        rewards = {agent: float((self.possible_agents.index(agent) + 1) * self.t) for agent in agents}
        ending = self.t >= self.end_at
        terminations = {agent: ending or (agent == self.dying_agent and self.t == self.die_at) for agent in agents}
        truncations = dict.fromkeys(agents, ending and self.end_truncates)
        infos = {agent: {"t": self.t} for agent in agents}
        self.agents = [agent for agent in agents if not (terminations[agent] or truncations[agent])]
        return observations, rewards, terminations, truncations, infos


# ---------------------------------------------------------------------------------------------
# Layout and spaces
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n_agents, num_agent_neighbors", [(3, None), (5, None), (5, 2)])
def test_simple_spread_layout_and_spaces(n_agents: int, num_agent_neighbors: int | None) -> None:
    env = make_simple_spread(n_agents=n_agents, num_agent_neighbors=num_agent_neighbors)
    layout = env.agent_layout
    obs_size = expected_obs_size(n_agents, num_agent_neighbors)

    assert isinstance(layout, AgentLayout)
    assert layout.agent_ids == tuple(f"agent_{i}" for i in range(n_agents))
    assert env.n_agents == n_agents
    assert layout.obs_sizes == (obs_size,) * n_agents
    assert layout.action_sizes == (5,) * n_agents
    # Slices are consecutive, in agent order, and tile the joint vectors exactly.
    for slices, size in ((layout.obs_slices, obs_size), (layout.action_slices, 5)):
        assert [(sl.start, sl.stop) for sl in slices] == [(i * size, (i + 1) * size) for i in range(n_agents)]
    assert env.observation_space.shape == (n_agents * obs_size,) == (layout.obs_dim,)
    assert env.action_space.shape == (n_agents * 5,) == (layout.action_dim,)
    assert env.observation_space.dtype == np.float32
    assert env.action_space.dtype == np.float32
    np.testing.assert_array_equal(env.action_space.low, np.zeros(n_agents * 5, np.float32))
    np.testing.assert_array_equal(env.action_space.high, np.ones(n_agents * 5, np.float32))

    obs, _ = env.reset(seed=0)
    assert obs.shape == env.observation_space.shape
    assert obs.dtype == np.float32
    # Each agent's slice holds that agent's own position (observation entries 2:4).
    world = env.parallel_env.unwrapped.world
    for sl, agent in zip(layout.obs_slices, world.agents, strict=True):
        np.testing.assert_allclose(obs[sl][2:4], agent.state.p_pos, rtol=1e-6)
    env.close()


def test_obs_size_formula_matches_mpe2_spaces() -> None:
    for n_agents, neighbors in [(3, None), (5, None), (5, 2), (4, 1)]:
        parallel_env = simple_spread_v3.parallel_env(N=n_agents, continuous_actions=True, num_agent_neighbors=neighbors)
        shapes = {parallel_env.observation_space(agent).shape for agent in parallel_env.possible_agents}
        assert shapes == {(expected_obs_size(n_agents, neighbors),)}
    assert (expected_obs_size(3, None), expected_obs_size(5, None), expected_obs_size(5, 2)) == (18, 30, 22)


def test_layout_through_dummy_and_subproc_vec_env() -> None:
    expected = make_simple_spread(n_agents=3, num_agent_neighbors=2).agent_layout

    def make() -> gym.Env:
        return make_simple_spread(n_agents=3, num_agent_neighbors=2)

    dummy = DummyVecEnv([make, make])
    assert dummy.get_attr("agent_layout") == [expected, expected]
    dummy.close()

    subproc = SubprocVecEnv([make, make], start_method="fork")
    try:
        layouts = subproc.get_attr("agent_layout")
        assert layouts == [expected, expected]
        assert layouts[1].obs_slices == expected.obs_slices
        assert layouts[1].action_slices == expected.action_slices
        subproc.reset()
        obs, rewards, _, infos = subproc.step(np.full((2, expected.action_dim), 0.5, np.float32))
        assert obs.shape == (2, expected.obs_dim)
        np.testing.assert_allclose(rewards, [info["agent_rewards"].sum() for info in infos], rtol=1e-6)
    finally:
        subproc.close()


def test_layout_through_gymnasium_make() -> None:
    env = gym.make(SIMPLE_SPREAD_ID, n_agents=3)
    assert env.unwrapped is not env  # gymnasium wraps it
    layout = env.get_wrapper_attr("agent_layout")
    assert layout.obs_sizes == (expected_obs_size(3, None),) * 3
    assert layout.action_sizes == (5,) * 3
    assert env.observation_space.shape == (layout.obs_dim,)
    obs, info = env.reset(seed=1)
    assert obs.shape == (layout.obs_dim,)
    assert set(METRIC_KEYS) <= set(info)
    env.close()


def test_layout_through_make_vec_env() -> None:
    vec_env = make_vec_env(SIMPLE_SPREAD_ID, n_envs=2, env_kwargs={"n_agents": 3, "num_agent_neighbors": 2})
    layouts = vec_env.get_attr("agent_layout")
    assert len(layouts) == 2
    for layout in layouts:
        assert layout.agent_ids == ("agent_0", "agent_1", "agent_2")
        assert layout.obs_sizes == (expected_obs_size(3, 2),) * 3
    assert vec_env.observation_space.shape == (3 * expected_obs_size(3, 2),)
    assert vec_env.get_attr("parallel_env")[0].unwrapped.scenario.num_agent_neighbors == 2
    vec_env.close()


# ---------------------------------------------------------------------------------------------
# Equivalence with driving mpe2 directly
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n_agents, num_agent_neighbors", [(3, None), (5, 2)])
def test_adapter_matches_mpe2_for_a_whole_episode(n_agents: int, num_agent_neighbors: int | None) -> None:
    seed = 123
    env = make_simple_spread(n_agents=n_agents, num_agent_neighbors=num_agent_neighbors)
    mean_env = make_simple_spread(n_agents=n_agents, num_agent_neighbors=num_agent_neighbors, team_reward="mean")
    direct = simple_spread_v3.parallel_env(N=n_agents, continuous_actions=True, num_agent_neighbors=num_agent_neighbors)
    agents = direct.possible_agents
    layout = env.agent_layout

    obs, _ = env.reset(seed=seed)
    mean_obs, _ = mean_env.reset(seed=seed)
    direct_obs, _ = direct.reset(seed=seed)
    np.testing.assert_array_equal(obs, np.concatenate([direct_obs[agent] for agent in agents]))
    np.testing.assert_array_equal(mean_obs, obs)

    rng = np.random.default_rng(7)
    for t in range(1, MAX_CYCLES + 1):
        action = random_joint_action(env, rng)
        obs, reward, terminated, truncated, info = env.step(action)
        _, mean_reward, _, _, mean_info = mean_env.step(action)
        direct_obs, direct_rewards, direct_terms, direct_truncs, _ = direct.step(
            {agent: action[sl] for agent, sl in zip(agents, layout.action_slices, strict=True)}
        )
        np.testing.assert_array_equal(obs, np.concatenate([direct_obs[agent] for agent in agents]))
        expected_rewards = np.array([direct_rewards[agent] for agent in agents], dtype=np.float32)
        np.testing.assert_array_equal(info["agent_rewards"], expected_rewards)
        np.testing.assert_array_equal(mean_info["agent_rewards"], expected_rewards)
        assert info["agent_rewards"].dtype == np.float32
        assert reward == pytest.approx(sum(direct_rewards.values()), rel=1e-5, abs=1e-5)
        assert mean_reward == pytest.approx(sum(direct_rewards.values()) / n_agents, rel=1e-5, abs=1e-5)
        assert terminated is False
        assert truncated is (t == MAX_CYCLES)
        np.testing.assert_array_equal(info["agent_truncations"], [direct_truncs[agent] for agent in agents])
        np.testing.assert_array_equal(info["agent_terminations"], [direct_terms[agent] for agent in agents])
        assert len(info["agent_infos"]) == n_agents
    assert info["agent_truncations"].all()
    assert not info["agent_terminations"].any()
    assert direct.agents == []  # mpe2 empties `agents` after the last step; the layout keeps the order


def test_step_after_episode_end_or_before_reset_raises() -> None:
    env = make_simple_spread(n_agents=3)
    action = np.full(env.action_space.shape, 0.5, np.float32)
    with pytest.raises(RuntimeError, match=r"call reset\(\)"):
        env.step(action)
    env.reset(seed=0)
    for _ in range(MAX_CYCLES):
        env.step(action)
    with pytest.raises(RuntimeError, match=r"episode is over.*reset\(\)"):
        env.step(action)
    env.reset(seed=1)
    env.step(action)  # works again after reset


def test_max_cycles_sets_episode_length() -> None:
    env = make_simple_spread(n_agents=3, max_cycles=4)
    env.reset(seed=0)
    action = np.full(env.action_space.shape, 0.5, np.float32)
    flags = [env.step(action)[2:4] for _ in range(4)]
    assert flags == [(False, False)] * 3 + [(False, True)]


# ---------------------------------------------------------------------------------------------
# Actions
# ---------------------------------------------------------------------------------------------


def test_float64_actions_reach_mpe2_as_float32(monkeypatch: pytest.MonkeyPatch) -> None:
    env = make_simple_spread(n_agents=3)
    calls = spy_on_step(monkeypatch, env.parallel_env)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    queued = len(EnvLogger.mqueue)
    for _ in range(3):
        action = rng.uniform(0.0, 1.0, env.action_space.shape)  # float64
        assert action.dtype == np.float64
        env.step(action)
        agent_actions = calls[-1][0]
        assert list(agent_actions) == list(env.agent_layout.agent_ids)
        for agent, sl in zip(env.agent_layout.agent_ids, env.agent_layout.action_slices, strict=True):
            assert agent_actions[agent].dtype == np.float32
            assert agent_actions[agent].shape == (5,)
            np.testing.assert_allclose(agent_actions[agent], action[sl], rtol=1e-6)
    # pettingzoo's ClipOutOfBoundsWrapper logs "outside action space" for float64 actions.
    assert len(EnvLogger.mqueue) == queued, EnvLogger.mqueue[queued:]

    # Control: the same check does catch a float64 action sent to mpe2 directly.
    direct = simple_spread_v3.parallel_env(N=3, continuous_actions=True)
    direct.reset(seed=0)
    direct.step({agent: np.full(5, 0.5) for agent in direct.agents})
    assert len(EnvLogger.mqueue) > queued
    del EnvLogger.mqueue[queued:]


def test_wrong_joint_action_length_raises() -> None:
    env = make_simple_spread(n_agents=3)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"joint action of length 15"):
        env.step(np.zeros(14, np.float32))
    with pytest.raises(ValueError, match=r"joint action of length 15"):
        env.step(np.zeros(20, np.float32))
    env.step(np.zeros((3, 5), np.float32))  # any shape with 15 entries is flattened


# ---------------------------------------------------------------------------------------------
# Checkers, Monitor, DummyVecEnv, seeding, rendering
# ---------------------------------------------------------------------------------------------


@pytest.mark.filterwarnings("ignore")
def test_env_checkers_pass() -> None:
    sb3_check_env(make_simple_spread(n_agents=3))
    sb3_check_env(make_simple_spread(n_agents=5, num_agent_neighbors=2))
    gym_check_env(make_simple_spread(n_agents=3))
    gym_check_env(gym.make(SIMPLE_SPREAD_ID, n_agents=3).unwrapped)


def test_monitor_episode_return_is_sum_of_team_rewards() -> None:
    env = Monitor(make_simple_spread(n_agents=3))
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    team_rewards = []
    agent_reward_sums = np.zeros(3)
    done = False
    while not done:
        _, reward, terminated, truncated, info = env.step(random_joint_action(env, rng))
        team_rewards.append(reward)
        agent_reward_sums += info["agent_rewards"]
        done = terminated or truncated
    assert len(team_rewards) == MAX_CYCLES
    assert info["episode"]["l"] == MAX_CYCLES
    assert info["episode"]["r"] == pytest.approx(sum(team_rewards), abs=1e-5)
    assert info["episode"]["r"] == pytest.approx(agent_reward_sums.sum(), rel=1e-5)
    assert env.get_episode_rewards() == [pytest.approx(sum(team_rewards))]


def test_dummy_vec_env_with_two_envs() -> None:
    vec_env = DummyVecEnv([lambda: make_simple_spread(n_agents=3)] * 2)
    vec_env.seed(3)
    obs = vec_env.reset()
    assert obs.shape == (2, 54)
    assert not np.array_equal(obs[0], obs[1])  # seeds 3 and 4
    rng = np.random.default_rng(2)
    for t in range(1, MAX_CYCLES + 1):
        obs, rewards, dones, infos = vec_env.step(rng.uniform(0, 1, (2, 15)).astype(np.float32))
        assert obs.shape == (2, 54) and rewards.shape == (2,)
        np.testing.assert_allclose(rewards, [info["agent_rewards"].sum() for info in infos], rtol=1e-5)
        assert dones.tolist() == [t == MAX_CYCLES] * 2
        for info in infos:
            assert set(METRIC_KEYS) <= set(info)
    for info in infos:
        assert info["TimeLimit.truncated"] is True  # SB3 will bootstrap: truncation, not termination
        assert info["terminal_observation"].shape == (54,)
    vec_env.close()


def test_seeding_is_reproducible() -> None:
    env_a, env_b = make_simple_spread(n_agents=3), make_simple_spread(n_agents=3)
    obs_a, info_a = env_a.reset(seed=42)
    obs_b, info_b = env_b.reset(seed=42)
    np.testing.assert_array_equal(obs_a, obs_b)
    assert {key: info_a[key] for key in METRIC_KEYS} == {key: info_b[key] for key in METRIC_KEYS}
    rng = np.random.default_rng(0)
    for _ in range(5):
        action = random_joint_action(env_a, rng)
        np.testing.assert_array_equal(env_a.step(action)[0], env_b.step(action)[0])

    obs_c, _ = env_b.reset(seed=43)
    assert not np.allclose(obs_a, obs_c)
    obs_again, _ = env_a.reset(seed=42)
    np.testing.assert_array_equal(obs_again, obs_a)


def test_render_rgb_array() -> None:
    env = make_simple_spread(n_agents=3, render_mode="rgb_array")
    assert env.render_mode == "rgb_array"
    assert "rgb_array" in env.metadata["render_modes"]
    env.reset(seed=0)
    frame = env.render()
    assert isinstance(frame, np.ndarray)
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.shape[0] > 0 and frame.shape[1] > 0
    assert frame.dtype == np.uint8
    assert frame.min() < frame.max()  # something is drawn
    env.close()


# ---------------------------------------------------------------------------------------------
# Heterogeneous teams
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("module", [simple_speaker_listener_v4, simple_adversary_v3], ids=["speaker_listener", "adversary"])
def test_heterogeneous_agents(module: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    parallel_env = module.parallel_env(continuous_actions=True)
    env = PettingZooToGym(parallel_env)
    layout = env.agent_layout
    agents = parallel_env.possible_agents
    obs_shapes = [parallel_env.observation_space(agent).shape for agent in agents]
    action_shapes = [parallel_env.action_space(agent).shape for agent in agents]
    assert layout.agent_ids == tuple(agents)
    assert layout.obs_sizes == tuple(shape[0] for shape in obs_shapes)
    assert layout.action_sizes == tuple(shape[0] for shape in action_shapes)
    assert not layout.is_homogeneous
    assert env.observation_space.shape == (sum(layout.obs_sizes),)
    assert env.action_space.shape == (sum(layout.action_sizes),)

    calls = spy_on_step(monkeypatch, parallel_env)
    obs, _ = env.reset(seed=0)
    assert obs.shape == env.observation_space.shape
    steps = 0
    done = False
    while not done:
        steps += 1
        # Distinct values per entry, so a wrong split shows up.
        action = ((np.arange(layout.action_dim) + steps) % 10 / 10).astype(np.float32)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        sent, (agent_obs, agent_rewards, *_) = calls[-1]
        for i, agent in enumerate(agents):
            assert sent[agent].shape == action_shapes[i]
            np.testing.assert_array_equal(sent[agent], action[layout.action_slices[i]])
            np.testing.assert_array_equal(obs[layout.obs_slices[i]], agent_obs[agent])
            assert info["agent_rewards"][i] == np.float32(agent_rewards[agent])
    assert steps == MAX_CYCLES and truncated and not terminated


# ---------------------------------------------------------------------------------------------
# Errors: each names the cause and the fix
# ---------------------------------------------------------------------------------------------


def test_multi_discrete_actions_are_refused() -> None:
    with pytest.raises(TypeError, match=r"MultiDiscrete action space") as error:
        PettingZooToGym(FakeParallelEnv(act_space=spaces.MultiDiscrete([3, 2])))
    assert "'a0'" in str(error.value) and "Discrete or continuous actions" in str(error.value)


def test_dict_observation_space_is_accepted_with_its_flat_size() -> None:
    """A Dict observation space is taken (flattened as gymnasium flattens it; tests/envs/test_structured_observations.py
    checks the values on mpe2), not refused."""
    obs_space = spaces.Dict({"position": spaces.Box(-1, 1, (2,), np.float32), "id": spaces.Discrete(3)})
    env = PettingZooToGym(FakeParallelEnv(obs_space=obs_space))
    assert env.agent_layout.obs_sizes == (5, 5, 5)


def test_fake_env_works_when_well_behaved() -> None:
    # The fake env itself is fine: the failures below come from the scripted misbehaviour.
    fake = FakeParallelEnv(end_at=3)
    env = PettingZooToGym(fake)
    obs, _ = env.reset()
    np.testing.assert_array_equal(obs, [1, 0, 0, 2, 0, 0, 3, 0, 0])
    obs, reward, terminated, truncated, info = env.step(np.arange(6, dtype=np.float32) / 10)
    np.testing.assert_allclose(obs, [1, 1, 0.1, 2, 1, 0.5, 3, 1, 0.9], rtol=1e-6)
    assert reward == 1 + 2 + 3
    np.testing.assert_array_equal(info["agent_rewards"], [1, 2, 3])
    assert info["agent_infos"] == [{"t": 1}] * 3
    env.step(np.zeros(6, np.float32))
    *_, terminated, truncated, info = env.step(np.zeros(6, np.float32))
    assert terminated and not truncated  # every agent terminated: termination, not truncation
    assert info["agent_terminations"].all()


def test_non_flat_and_float64_agent_spaces() -> None:
    # Agents with a (3, 1) float64 observation and a (1, 2) float64 action: the joint vectors are
    # flat float32, and each agent's action reaches the env in its own space's shape and dtype.
    obs_space = spaces.Box(-np.inf, np.inf, (3, 1), np.float64)
    act_space = spaces.Box(0.0, 1.0, (1, 2), np.float64)
    fake = FakeParallelEnv(obs_space=obs_space, act_space=act_space)
    env = PettingZooToGym(fake)
    assert env.agent_layout.obs_sizes == (3, 3, 3) and env.agent_layout.action_sizes == (2, 2, 2)
    assert env.observation_space.shape == (9,) and env.observation_space.dtype == np.float32
    assert env.action_space.shape == (6,) and env.action_space.dtype == np.float32
    obs, _ = env.reset()
    assert obs.shape == (9,) and obs.dtype == np.float32
    action = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6], np.float32)
    obs, *_ = env.step(action)
    np.testing.assert_allclose(obs, [1, 1, 0.3, 2, 1, 0.7, 3, 1, 1.1], rtol=1e-6)
    for i, agent in enumerate(fake.possible_agents):
        sent = fake.received[-1][agent]
        assert sent.shape == (1, 2) and sent.dtype == np.float64
        np.testing.assert_allclose(sent.ravel(), action[2 * i : 2 * i + 2], rtol=1e-6)


def test_an_agent_that_leaves_gets_no_action_and_is_seen_as_zeros() -> None:
    fake = FakeParallelEnv(dying_agent="a1", die_at=2, end_at=4)
    env = PettingZooToGym(fake)
    env.reset()
    results = [env.step(np.full(6, 0.5, np.float32)) for _ in range(4)]
    gone = env.agent_layout.obs_slices[1]
    assert ["a1" in sent for sent in fake.received] == [True, True, False, False]
    np.testing.assert_array_equal(results[1][0][gone], [2, 2, 1.0])  # its last observation, as the env gave it
    for obs, _, _, _, info in results[2:]:
        np.testing.assert_array_equal(obs[gone], np.zeros(3))
        assert info["agent_rewards"][1] == 0 and info["agent_terminations"][1]
    assert [result[2] for result in results] == [False, False, False, True]  # every agent terminated at step 4


def test_an_agent_that_vanishes_without_a_flag_counts_as_terminated() -> None:
    env = PettingZooToGym(FakeParallelEnv(vanishing_agent="a2", die_at=2, end_at=4, end_truncates=True))
    env.reset()
    env.step(np.zeros(6, np.float32))
    obs, _, terminated, truncated, info = env.step(np.zeros(6, np.float32))
    np.testing.assert_array_equal(obs[env.agent_layout.obs_slices[2]], np.zeros(3))
    assert info["agent_terminations"].tolist() == [False, False, True] and not (terminated or truncated)


def test_reset_without_the_whole_team_raises() -> None:
    env = PettingZooToGym(FakeParallelEnv(reset_agents=["a0", "a2"]))
    with pytest.raises(RuntimeError, match=r"possible_agents") as error:
        env.reset()
    assert "['a0', 'a2']" in str(error.value)
    assert "all of possible_agents" in str(error.value)


@pytest.mark.parametrize("n_agents, neighbors", [(5, 0), (5, 5), (5, -1), (3, 3)])
def test_num_agent_neighbors_out_of_range(n_agents: int, neighbors: int) -> None:
    with pytest.raises(
        ValueError,
        match=rf"^num_agent_neighbors .* must be an integer in \[1, n_agents - 1 = {n_agents - 1}\].*got {neighbors}",
    ):
        make_simple_spread(n_agents=n_agents, num_agent_neighbors=neighbors)


def test_too_few_agents_raise() -> None:
    with pytest.raises(ValueError, match=r"^n_agents \(.*\) must be an integer >= 2.*, got 1"):
        make_simple_spread(n_agents=1)


def test_unknown_team_reward_raises() -> None:
    with pytest.raises(ValueError, match=r"'sum' or 'mean'.*'max'"):
        make_simple_spread(n_agents=3, team_reward="max")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"'sum' or 'mean'.*'max'"):
        PettingZooToGym(FakeParallelEnv(), team_reward="max")  # type: ignore[arg-type]


def test_black_death_is_not_needed_and_warned_about() -> None:
    with pytest.warns(UserWarning, match=r"^The env is wrapped in supersuit\.black_death_v3, which the adapter does not"):
        PettingZooToGym(supersuit.black_death_v3(FakeParallelEnv()))


# ---------------------------------------------------------------------------------------------
# simple_spread task metrics
# ---------------------------------------------------------------------------------------------


def place(env: PettingZooToGym, agents: list, landmarks: list) -> Any:
    world = env.parallel_env.unwrapped.world
    for entity, position in zip(world.agents, agents, strict=True):
        entity.state.p_pos = np.array(position, dtype=float)
    for entity, position in zip(world.landmarks, landmarks, strict=True):
        entity.state.p_pos = np.array(position, dtype=float)
    return world


@pytest.fixture
def spread3() -> PettingZooToGym:
    env = make_simple_spread(n_agents=3)
    env.reset(seed=0)
    return env


LANDMARKS3 = [(-1.0, 0.0), (0.0, 0.0), (1.0, 0.0)]


def test_metrics_all_landmarks_covered(spread3: PettingZooToGym) -> None:
    place(spread3, [(-1.0, 0.05), (0.0, 0.0), (1.0, -0.08)], LANDMARKS3)
    metrics = SimpleSpreadMetrics()(spread3.parallel_env)
    assert metrics == {
        "coverage": 1.0,
        "success": 1.0,
        "collisions": 0.0,
        "min_dist_sum": pytest.approx(0.05 + 0.0 + 0.08),
        "landmark_distances": pytest.approx([0.05, 0.0, 0.08]),
    }


def test_metrics_two_of_three_covered(spread3: PettingZooToGym) -> None:
    place(spread3, [(-1.0, 0.0), (0.0, 0.05), (0.5, 0.5)], LANDMARKS3)
    metrics = spread3.metrics_fn(spread3.parallel_env)
    # Landmark 3 at (1, 0): nearest agent is (0.5, 0.5) at sqrt(0.5), farther than the 0.1 radius.
    assert metrics["coverage"] == pytest.approx(2 / 3)
    assert metrics["success"] == 0.0
    assert metrics["collisions"] == 0.0
    assert metrics["min_dist_sum"] == pytest.approx(0.0 + 0.05 + math.sqrt(0.5))
    # Just outside the radius does not count.
    place(spread3, [(-1.0, 0.0), (0.0, CAPTURE_RADIUS + 1e-3), (1.0, 0.0)], LANDMARKS3)
    assert spread3.metrics_fn(spread3.parallel_env)["coverage"] == pytest.approx(2 / 3)


def test_metrics_collisions_per_unordered_pair(spread3: PettingZooToGym) -> None:
    assert spread3.parallel_env.unwrapped.world.agents[0].size == AGENT_SIZE
    metrics = SimpleSpreadMetrics()
    far = [(5.0, 5.0)] * 3
    # 0-1 in contact (0.29 < 0.30), 0-2 not (0.31), 1-2 not.
    place(spread3, [(0.0, 0.0), (0.29, 0.0), (0.0, 0.31)], far)
    assert metrics(spread3.parallel_env)["collisions"] == 1.0
    # 0-1 and 0-2 in contact, 1-2 not (sqrt(0.29^2 + 0.2^2) = 0.35).
    place(spread3, [(0.0, 0.0), (0.29, 0.0), (0.0, 0.2)], far)
    assert metrics(spread3.parallel_env)["collisions"] == 2.0
    # All three pairs: 3, not 6 (ordered pairs).
    place(spread3, [(0.0, 0.0), (0.1, 0.0), (0.0, 0.1)], far)
    assert metrics(spread3.parallel_env)["collisions"] == 3.0
    # Nobody in contact.
    place(spread3, [(0.0, 0.0), (0.31, 0.0), (0.0, 0.31)], far)
    assert metrics(spread3.parallel_env)["collisions"] == 0.0


def test_metrics_min_dist_sum_by_hand(spread3: PettingZooToGym) -> None:
    agents = [(0.3, 0.4), (-0.6, 0.8), (2.0, 2.0)]
    landmarks = [(0.0, 0.0), (-0.6, 0.0), (1.0, 1.0)]
    place(spread3, agents, landmarks)
    # Landmark (0, 0): nearest (0.3, 0.4) at 0.5. Landmark (-0.6, 0): min(0.9 to (0.3, 0.4) -> sqrt(0.81 + 0.16),
    # 0.8 to (-0.6, 0.8)) = 0.8. Landmark (1, 1): min(sqrt(0.49 + 0.36), sqrt(2)) = sqrt(0.85).
    expected = 0.5 + min(math.sqrt(0.97), 0.8) + min(math.sqrt(0.85), math.sqrt(2.0))
    assert SimpleSpreadMetrics()(spread3.parallel_env)["min_dist_sum"] == pytest.approx(expected)
    by_landmark = [0.5, min(math.sqrt(0.97), 0.8), min(math.sqrt(0.85), math.sqrt(2.0))]
    assert SimpleSpreadMetrics()(spread3.parallel_env)["landmark_distances"] == pytest.approx(by_landmark)
    assert SimpleSpreadMetrics()(spread3.parallel_env)["coverage"] == 0.0


def test_metrics_custom_capture_radius(spread3: PettingZooToGym) -> None:
    place(spread3, [(-1.0, 0.0), (0.0, 0.05), (0.5, 0.5)], LANDMARKS3)  # landmark 3 at sqrt(0.5) ~ 0.707
    assert SimpleSpreadMetrics(capture_radius=0.7)(spread3.parallel_env)["coverage"] == pytest.approx(2 / 3)
    wide = SimpleSpreadMetrics(capture_radius=0.75)(spread3.parallel_env)
    assert wide["coverage"] == 1.0 and wide["success"] == 1.0
    narrow = SimpleSpreadMetrics(capture_radius=0.01)(spread3.parallel_env)
    assert narrow["coverage"] == pytest.approx(1 / 3)  # only the exact hit (0 away)

    env = make_simple_spread(n_agents=3, capture_radius=0.75)
    env.reset(seed=0)
    place(env, [(-1.0, 0.0), (0.0, 0.05), (0.5, 0.5)], LANDMARKS3)
    assert env.metrics_fn(env.parallel_env)["success"] == 1.0
    for radius in (0.0, -0.1):
        with pytest.raises(ValueError, match=r"^capture_radius \(.*\) must be a number > 0"):
            SimpleSpreadMetrics(capture_radius=radius)


@pytest.mark.parametrize("n_agents", [3, 5])
def test_metrics_agree_with_mpe2_benchmark_data(n_agents: int) -> None:
    env = make_simple_spread(n_agents=n_agents)
    env.reset(seed=0)
    world = env.parallel_env.unwrapped.world
    scenario = env.parallel_env.unwrapped.scenario
    metrics_fn = SimpleSpreadMetrics()
    rng = np.random.default_rng(n_agents)
    seen_coverage, seen_collisions = set(), set()
    for _ in range(50):
        landmarks = rng.uniform(-1, 1, (n_agents, 2))
        # Mix of states: agents near their landmarks (some covered), or crowded together (collisions).
        near = landmarks + rng.normal(0, 0.08, (n_agents, 2))
        crowded = rng.uniform(-0.3, 0.3, (n_agents, 2))
        agents = np.where(rng.random((n_agents, 1)) < 0.5, near, crowded)
        place(env, list(agents), list(landmarks))
        metrics = metrics_fn(env.parallel_env)
        data = [scenario.benchmark_data(agent, world) for agent in world.agents]  # (rew, collisions, min_dists, occupied)
        assert metrics["coverage"] == pytest.approx(data[0][3] / n_agents)
        assert metrics["success"] == float(data[0][3] == n_agents)
        assert metrics["min_dist_sum"] == pytest.approx(data[0][2], rel=1e-9)
        assert metrics["collisions"] == sum(d[1] for d in data) / 2
        seen_coverage.add(metrics["coverage"])
        seen_collisions.add(metrics["collisions"])
    # The random states exercised more than the trivial values.
    assert len(seen_coverage) >= 3 and len(seen_collisions) >= 2


def test_metrics_in_info_after_reset_and_every_step() -> None:
    env = make_simple_spread(n_agents=5, num_agent_neighbors=2)
    scenario = env.parallel_env.unwrapped.scenario
    world = env.parallel_env.unwrapped.world
    _, info = env.reset(seed=5)
    infos = [info]
    rng = np.random.default_rng(5)
    for _ in range(MAX_CYCLES):
        infos.append(env.step(random_joint_action(env, rng))[4])
        data = [scenario.benchmark_data(agent, world) for agent in world.agents]
        assert infos[-1]["min_dist_sum"] == pytest.approx(data[0][2])
        assert infos[-1]["collisions"] == sum(d[1] for d in data) / 2
    for info in infos:
        assert set(METRIC_KEYS) <= set(info)
        assert all(isinstance(info[key], float) for key in METRIC_KEYS)
        assert 0.0 <= info["coverage"] <= 1.0
    # The metrics follow the state: they change over the episode.
    assert len({info["min_dist_sum"] for info in infos}) > 1
    # An adapter without metrics_fn adds none.
    bare = PettingZooToGym(simple_spread_v3.parallel_env(N=3, continuous_actions=True))
    _, info = bare.reset(seed=0)
    assert not set(METRIC_KEYS) & set(info)
