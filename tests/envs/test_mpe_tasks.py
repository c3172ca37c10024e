"""Every mpe2 task through ``make_mpe_env``: layouts against mpe2, MADDPG smoke training, task metrics by hand."""

import importlib
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import MPE_TASK_METRICS, MPE_TASKS, PettingZooToGym, SimpleSpreadMetrics, make_mpe_env, make_simple_spread

NINE = (
    "simple",
    "simple_adversary",
    "simple_crypto",
    "simple_push",
    "simple_reference",
    "simple_speaker_listener",
    "simple_spread",
    "simple_tag",
    "simple_world_comm",
)
DOCS_GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "pettingzoo.rst"


def built(task: str, **kwargs: Any) -> PettingZooToGym:
    env = make_mpe_env(task, **kwargs)
    env.reset(seed=0)
    return env


def place(env: PettingZooToGym, agents: dict[int, tuple[float, float]], landmarks: dict[int, tuple[float, float]]) -> Any:
    """Put agents and landmarks (by index) at the given positions; return the world."""
    world = env.parallel_env.unwrapped.world
    for index, position in agents.items():
        world.agents[index].state.p_pos = np.array(position, dtype=float)
    for index, position in landmarks.items():
        world.landmarks[index].state.p_pos = np.array(position, dtype=float)
    return world


def metrics(env: PettingZooToGym) -> dict[str, Any]:
    assert env.metrics_fn is not None
    return env.metrics_fn(env.parallel_env)


def reference_env(task: str) -> Any:
    """The mpe2 env that make_mpe_env(task) wraps, built straight from mpe2 (simple_spread: 5 agents, as ours)."""
    extra = {"N": 5} if task == "simple_spread" else {}
    return importlib.import_module(MPE_TASKS[task]).parallel_env(continuous_actions=True, **extra)


# ---------------------------------------------------------------------------------------------- building


def test_the_nine_tasks_and_their_metrics_are_listed() -> None:
    assert tuple(MPE_TASKS) == NINE
    assert tuple(MPE_TASK_METRICS) == NINE
    for task, module in MPE_TASKS.items():
        assert importlib.import_module(module).__name__.startswith(f"mpe2.{task}_v")


@pytest.mark.parametrize("task", NINE)
def test_layout_and_first_observation_match_mpe2(task: str) -> None:
    env = make_mpe_env(task)
    mpe = reference_env(task)
    agents = tuple(mpe.possible_agents)
    layout = env.agent_layout
    assert layout.agent_ids == agents
    assert layout.obs_sizes == tuple(mpe.observation_space(agent).shape[0] for agent in agents)
    assert layout.action_sizes == tuple(mpe.action_space(agent).shape[0] for agent in agents)
    np.testing.assert_array_equal(env.action_space.low, np.concatenate([mpe.action_space(a).low for a in agents]))
    np.testing.assert_array_equal(env.action_space.high, np.concatenate([mpe.action_space(a).high for a in agents]))
    # Same seed, same world: the joint observation is mpe2's, agent by agent in possible_agents order.
    obs, _ = env.reset(seed=3)
    mpe_obs, _ = mpe.reset(seed=3)
    np.testing.assert_array_equal(obs, np.concatenate([mpe_obs[agent] for agent in agents]))


@pytest.mark.parametrize("task", NINE)
def test_declared_metrics_in_info_at_reset_and_every_step(task: str) -> None:
    env = make_mpe_env(task, max_cycles=5)
    declared = {metric.key for metric in MPE_TASK_METRICS[task]}
    extra = {"landmark_distances"} if task == "simple_spread" else set()
    _, info = env.reset(seed=1)
    infos, truncated = [info], False
    rng = np.random.default_rng(1)
    for _ in range(5):
        _, _, terminated, truncated, info = env.step(rng.uniform(0, 1, env.action_space.shape).astype(np.float32))
        infos.append(info)
        assert not terminated
    assert truncated  # max_cycles reached mpe2
    for info in infos:
        keys = set(info) - {"agent_rewards", "agent_terminations", "agent_truncations", "agent_infos"}
        keys -= {"agent_positions", "agent_positions_before", "agent_active"}  # positions for selection; who is there
        assert keys == declared | extra
        assert all(isinstance(info[key], float) and math.isfinite(info[key]) for key in declared)


@pytest.mark.slow
@pytest.mark.parametrize("continuous_actions", [True, False], ids=["continuous", "discrete"])
@pytest.mark.parametrize("task", NINE)
def test_maddpg_updates_and_predicts_valid_actions_on_each_mpe_task(task: str, continuous_actions: bool) -> None:
    env = make_mpe_env(task, continuous_actions=continuous_actions)
    assert env.agent_layout.has_discrete_actions == (not continuous_actions)
    model = MADDPG(
        "MlpPolicy",
        env,
        critic_sharing="full",
        learning_starts=100,
        batch_size=32,
        buffer_size=1_000,
        transitions_per_update=20,
        policy_kwargs=dict(net_arch=[16]),
        seed=0,
    )
    model.learn(total_timesteps=300)
    assert model._n_updates >= 5
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action.astype(np.float32))
    noisy, _ = model.predict(np.stack([obs, env.observation_space.sample()]), deterministic=False)
    assert noisy.shape == (2, *env.action_space.shape)
    assert all(env.action_space.contains(row.astype(np.float32)) for row in noisy)
    if not continuous_actions:  # every agent's slot is an exact one-hot, which the env reads as its action
        for sl in env.agent_layout.action_slices:
            assert sorted(action[sl].tolist()) == [0.0] * (sl.stop - sl.start - 1) + [1.0]


def test_simple_spread_is_make_simple_spread() -> None:
    ours, theirs = make_mpe_env("simple_spread", n_agents=3, max_cycles=7), make_simple_spread(n_agents=3, max_cycles=7)
    assert isinstance(ours.metrics_fn, SimpleSpreadMetrics)
    assert ours.agent_layout == theirs.agent_layout
    assert make_mpe_env("simple_spread").n_agents == make_simple_spread().n_agents == 5
    assert make_mpe_env("simple_spread", N=4).n_agents == 4  # mpe2's name for the team size
    assert make_mpe_env("simple_spread", capture_radius=0.5).metrics_fn.capture_radius == 0.5  # type: ignore[union-attr]
    obs, info = ours.reset(seed=2)
    their_obs, their_info = theirs.reset(seed=2)
    np.testing.assert_array_equal(obs, their_obs)
    assert info["min_dist_sum"] == their_info["min_dist_sum"]


def test_task_arguments_reach_mpe2() -> None:
    assert built("simple_tag", num_good=2, num_adversaries=2).agent_layout.agent_ids == (
        "adversary_0",
        "adversary_1",
        "agent_0",
        "agent_1",
    )
    assert built("simple_adversary", N=3).n_agents == 4
    assert built("simple_reference", local_ratio=0.2).parallel_env.unwrapped.local_ratio == 0.2
    assert built("simple", team_reward="mean").team_reward == "mean"


# ---------------------------------------------------------------------------------------------- errors


def test_unknown_task_lists_the_nine() -> None:
    with pytest.raises(ValueError, match=r"Unknown MPE task 'simple_tags'.*" + re.escape(", ".join(NINE))):
        make_mpe_env("simple_tags")


@pytest.mark.parametrize("task", ["simple_tag", "simple_spread"])
def test_discrete_actions_reach_mpe2(task: str) -> None:
    env = make_mpe_env(task, continuous_actions=False)
    assert all(str(env.parallel_env.action_space(agent)).startswith("Discrete") for agent in env.agent_layout.agent_ids)


def test_bad_task_arguments() -> None:
    with pytest.raises(TypeError, match=r"^simple_tag has no argument 'N': its arguments are num_good, num_adversaries"):
        make_mpe_env("simple_tag", N=3)
    with pytest.raises(TypeError, match=r"^simple_spread has no argument 'num_good'.*n_agents, num_agent_neighbors"):
        make_mpe_env("simple_spread", num_good=2)
    with pytest.raises(TypeError, match="both N=3 and n_agents=4"):
        make_mpe_env("simple_spread", N=3, n_agents=4)
    with pytest.raises(ValueError, match=r"^max_cycles \(.*\) must be an integer >= 1.*, got 0"):
        make_mpe_env("simple_push", max_cycles=0)
    with pytest.raises(ValueError, match="team_reward must be 'sum' or 'mean'"):
        make_mpe_env("simple_push", team_reward="max")  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------------------- metrics by hand


def test_simple_goal_distance() -> None:
    env = built("simple")
    place(env, {0: (0.3, 0.4)}, {0: (0.0, 0.0)})
    assert metrics(env) == {"goal_distance": pytest.approx(0.5)}
    place(env, {0: (-1.0, 0.5)}, {0: (0.2, -0.4)})
    assert metrics(env)["goal_distance"] == pytest.approx(math.hypot(1.2, 0.9))


@pytest.mark.parametrize("task", ["simple_adversary", "simple_push"])
def test_goal_race_distances(task: str) -> None:
    env = built(task)
    world = env.parallel_env.unwrapped.world
    # Agent 0 is the adversary; the last good agent is the nearest one to the goal (3-4-5 triangle: 0.5).
    last = len(world.agents) - 1
    place(env, {0: (0.0, -0.2), last: (0.3, 0.4), **dict.fromkeys(range(1, last), (1.0, 1.0))}, {})
    for goal_index, goal in enumerate(world.landmarks):  # whichever landmark mpe2 draws as the goal
        for agent in world.agents:
            agent.goal_a = goal
        place(env, {}, {index: (-2.0, 2.0 + index) for index in range(len(world.landmarks))})
        place(env, {}, {goal_index: (0.0, 0.0)})
        assert metrics(env) == {"goal_distance": pytest.approx(0.5), "adversary_goal_distance": pytest.approx(0.2)}


def test_simple_crypto_who_recovers_the_message() -> None:
    env = built("simple_crypto")
    eve, bob, alice = env.parallel_env.unwrapped.world.agents
    assert (eve.adversary, bob.speaker, alice.speaker) == (True, False, True)
    message = np.zeros(4)
    message[1] = 1.0
    for agent in (eve, bob, alice):
        agent.goal_a.color = message
    bob.state.c = np.array([0.2, 0.9, 0.1, 0.3])
    eve.state.c = np.array([0.8, 0.7, 0.0, 0.0])
    assert metrics(env) == {"bob_correct": 1.0, "eve_correct": 0.0}
    bob.state.c = np.array([0.2, 0.9, 0.1, 0.95])  # loudest on the wrong channel
    eve.state.c = np.array([0.0, 0.6, 0.6, 0.0])  # a tie: the first largest is the message's
    assert metrics(env) == {"bob_correct": 0.0, "eve_correct": 1.0}
    # Silence recovers nothing, even when the message is channel 0 (argmax of zeros).
    message = np.array([1.0, 0.0, 0.0, 0.0])
    for agent in (eve, bob, alice):
        agent.goal_a.color = message
    bob.state.c, eve.state.c = np.zeros(4), np.array([0.5, 0.0, 0.0, 0.0])
    assert metrics(env) == {"bob_correct": 0.0, "eve_correct": 1.0}


def test_simple_reference_goal_distance() -> None:
    env = built("simple_reference")
    world = env.parallel_env.unwrapped.world
    place(env, {0: (0.0, 0.0), 1: (1.0, 1.0)}, {0: (-1.0, 0.0), 1: (0.0, 1.0), 2: (1.0, -1.0)})
    # Agent 0 must reach the landmark agent 1 knows (agent 1's goal_b), and the other way round.
    target_0 = world.agents[1].goal_b.state.p_pos
    target_1 = world.agents[0].goal_b.state.p_pos
    expected = math.dist((0.0, 0.0), target_0) + math.dist((1.0, 1.0), target_1)
    assert metrics(env) == {"goal_distance": pytest.approx(expected)}
    world.agents[1].goal_b = world.landmarks[0]
    world.agents[0].goal_b = world.landmarks[2]
    assert metrics(env)["goal_distance"] == pytest.approx(1.0 + math.dist((1.0, 1.0), (1.0, -1.0)))


def test_simple_speaker_listener_goal_distance() -> None:
    env = built("simple_speaker_listener")
    world = env.parallel_env.unwrapped.world
    # The speaker sits on landmark 0; what counts is the listener's distance to the goal landmark.
    place(env, {0: (-1.0, 0.0), 1: (0.6, 0.8)}, {0: (-1.0, 0.0), 1: (0.0, 0.0), 2: (0.6, -0.2)})
    world.agents[0].goal_b = world.landmarks[1]
    assert metrics(env) == {"goal_distance": pytest.approx(1.0)}
    world.agents[0].goal_b = world.landmarks[2]
    assert metrics(env)["goal_distance"] == pytest.approx(1.0)
    world.agents[0].goal_b = world.landmarks[0]
    assert metrics(env)["goal_distance"] == pytest.approx(math.dist((0.6, 0.8), (-1.0, 0.0)))


def test_simple_tag_catches() -> None:
    env = built("simple_tag")  # adversaries 0-2 (size 0.075), the good agent 3 (size 0.05): contact below 0.125
    far = (5.0, 5.0)
    place(env, {0: (0.12, 0.0), 1: (0.0, 0.13), 2: far, 3: (0.0, 0.0)}, {})
    assert metrics(env) == {"collisions": 1.0}  # adversary 1 is 0.13 away: no contact
    place(env, {0: (0.12, 0.0), 1: (0.0, 0.1), 2: (-0.1, 0.0), 3: (0.0, 0.0)}, {})
    assert metrics(env) == {"collisions": 3.0}  # three adversaries on the prey
    place(env, {0: (0.0, 0.0), 1: (0.1, 0.0), 2: far, 3: (-2.0, -2.0)}, {0: (-2.0, -2.0)})
    assert metrics(env) == {"collisions": 0.0}  # adversaries touching each other, the prey inside an obstacle


def test_simple_world_comm_catches() -> None:
    env = built("simple_world_comm")  # 4 adversaries (size 0.075), good agents 4 and 5 (size 0.045): contact below 0.12
    far = {0: (3.0, 3.0), 1: (4.0, 4.0), 2: (5.0, 5.0), 3: (6.0, 6.0)}
    place(env, {**far, 4: (0.0, 0.0), 5: (1.0, 1.0)}, {})
    assert metrics(env) == {"collisions": 0.0}
    # The leader on agent 4 (0.11), adversary 2 on agent 5 (0.119), adversary 1 just off agent 5 (0.121).
    place(env, {0: (0.11, 0.0), 1: (1.0, 1.121), 2: (1.119, 1.0), 4: (0.0, 0.0), 5: (1.0, 1.0)}, {})
    assert metrics(env) == {"collisions": 2.0}
    place(env, {3: (0.0, 0.05)}, {})  # a third adversary catches agent 4
    assert metrics(env) == {"collisions": 3.0}


# ---------------------------------------------------------------------------------------------- metrics against mpe2


def rollout(task: str, steps: int = 25, **kwargs: Any) -> list[tuple[dict[str, float], dict[str, Any]]]:
    """(per-agent rewards by agent id, info) at every step of a random episode."""
    env = make_mpe_env(task, **kwargs)
    env.reset(seed=7)
    rng = np.random.default_rng(7)
    steps_seen = []
    for _ in range(steps):
        _, _, _, _, info = env.step(rng.uniform(0, 1, env.action_space.shape).astype(np.float32))
        rewards = dict(zip(env.agent_layout.agent_ids, info["agent_rewards"].tolist(), strict=True))
        steps_seen.append((rewards, info))
    return steps_seen


def test_distances_agree_with_mpe2_rewards() -> None:
    """Where mpe2's reward is a function of the metric, check the metric through the reward over random episodes."""
    for rewards, info in rollout("simple"):
        assert rewards["agent_0"] == pytest.approx(-(info["goal_distance"] ** 2), rel=1e-5)
    for rewards, info in rollout("simple_speaker_listener"):
        assert rewards["listener_0"] == pytest.approx(-(info["goal_distance"] ** 2), rel=1e-5)
    for rewards, info in rollout("simple_push"):
        assert rewards["agent_0"] == pytest.approx(-info["goal_distance"], rel=1e-5)
        assert rewards["adversary_0"] == pytest.approx(info["goal_distance"] - info["adversary_goal_distance"], abs=1e-5)
    for rewards, info in rollout("simple_adversary"):
        expected = info["adversary_goal_distance"] - info["goal_distance"]
        assert rewards["agent_0"] == pytest.approx(expected, abs=1e-5) == rewards["agent_1"]
    for rewards, info in rollout("simple_reference", local_ratio=0.3):
        # Local and global terms are both minus distances: the agents' rewards add up to minus the sum.
        assert sum(rewards.values()) == pytest.approx(-info["goal_distance"], rel=1e-5)


@pytest.mark.parametrize("task", ["simple_tag", "simple_world_comm"])
def test_catches_agree_with_mpe2_benchmark_data(task: str) -> None:
    env = built(task)
    world, scenario = env.parallel_env.unwrapped.world, env.parallel_env.unwrapped.scenario
    rng = np.random.default_rng(0)
    seen = set()
    for _ in range(60):
        place(env, dict(enumerate(rng.uniform(-0.25, 0.25, (len(world.agents), 2)))), {})
        catches = metrics(env)["collisions"]
        assert catches == sum(scenario.benchmark_data(agent, world) for agent in world.agents)
        seen.add(catches)
    assert len(seen) >= 3
    if task == "simple_tag":  # and each adversary's reward is +10 per catch after a step from a crowded start
        rewards_seen = set()
        for _ in range(20):
            env.reset(seed=int(rng.integers(1000)))
            place(env, dict(enumerate(rng.uniform(-0.15, 0.15, (len(world.agents), 2)))), {})
            _, _, _, _, info = env.step(rng.uniform(0, 1, env.action_space.shape).astype(np.float32))
            assert info["agent_rewards"][0] == pytest.approx(10.0 * info["collisions"])
            rewards_seen.add(float(info["agent_rewards"][0]))
        assert len(rewards_seen) >= 2


# ---------------------------------------------------------------------------------------------- the docs


def every_mpe_task_snippets() -> list[str]:
    text = DOCS_GUIDE.read_text()
    section = text.split("Every MPE task\n--------------\n", 1)[1]
    section = re.split(r"\n[^\n]+\n-{3,}\n", section, maxsplit=1)[0]  # up to the next section
    blocks = re.findall(r"\.\. code-block:: python\n\n((?:   .*\n|\n)+)", section)
    return [re.sub(r"^   ", "", block, flags=re.MULTILINE) for block in blocks]


def test_docs_every_mpe_task_snippets_run() -> None:
    snippets = every_mpe_task_snippets()
    assert len(snippets) >= 2
    namespace: dict[str, Any] = {}
    for snippet in snippets:  # in order, as a reader runs them
        exec(compile(snippet, str(DOCS_GUIDE), "exec"), namespace)


def test_docs_table_lists_every_task_and_metric() -> None:
    section = DOCS_GUIDE.read_text().split("Every MPE task\n--------------\n", 1)[1]
    for task, task_metrics in MPE_TASK_METRICS.items():
        assert f"``{task}``" in section
        for metric in task_metrics:
            assert f"``{metric.key}``" in section
