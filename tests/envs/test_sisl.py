"""SISL pursuit through ``sb3_maddpg.envs.sisl.pursuit_env``: the pursuers' positions and the evaders caught against
the env's own state, episodes seeded one by one, and pettingzoo.sisl imported only when an env is built."""

import subprocess
import sys
from typing import Any

import numpy as np
import pytest

pytest.importorskip("pettingzoo.sisl.pursuit_v5", reason="pursuit needs the sisl extra (pygame)")

from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.envs import PettingZooToGym, RandomTeamPolicy
from sb3_maddpg.envs.sisl import PURSUIT_NO_OP, pursuit_env, sisl_state

SETTING: dict[str, Any] = dict(x_size=8, y_size=8, n_pursuers=4, n_evaders=4, max_cycles=100, surround=False, n_catch=2)
"""The Beyond MPE setting (the preset ``pursuit``'s)."""

MOVES = np.array([[-1, 0], [1, 0], [0, 1], [0, -1], [0, 0]])
"""Pursuit's moves by action (``pursuit/utils/discrete_agent.py``: left, right, up, down, stay)."""


def joint_action(moves: np.ndarray) -> np.ndarray:
    """:return: The adapter's joint action (a one-hot slot of 5 per pursuer) for each pursuer's move."""
    action = np.zeros((len(moves), len(MOVES)), dtype=np.float32)
    action[np.arange(len(moves)), moves] = 1.0
    return action.reshape(-1)


def expected_cell(env: PettingZooToGym, cell: np.ndarray, move: int) -> np.ndarray:
    """:return: Where pursuit's rules take a pursuer from ``cell`` by ``move``: the next cell, or ``cell`` at the
    grid's edge or a building (``DiscreteAgent.step``)."""
    state = sisl_state(env.parallel_env)
    x, y = (cell + MOVES[move]).astype(int)
    if not (0 <= x < state.x_size and 0 <= y < state.y_size) or state.map_matrix[x, y] == -1:
        return cell
    return np.array([x, y], dtype=cell.dtype)


def cell_counts(positions: np.ndarray, env: PettingZooToGym) -> np.ndarray:
    """:return: Pursuers per cell as pursuit's global state lays them out (``state()[y, x, 1]``)."""
    state = sisl_state(env.parallel_env)
    counts = np.zeros((state.y_size, state.x_size))
    for x, y in positions.astype(int):
        counts[y, x] += 1
    return counts


def test_the_positions_are_the_pursuers_cells_in_the_envs_state_step_by_step() -> None:
    env = pursuit_env(**SETTING)
    assert env.agent_layout.positions_in_info and env.agent_layout.declares_positions
    rng = np.random.default_rng(0)
    _, info = env.reset(seed=7)
    positions = info["agent_positions"]
    for _ in range(100):
        # Whole-grid counts from the env's state (its own layout of pursuers), then each pursuer's move by its action.
        np.testing.assert_array_equal(cell_counts(positions, env), env.parallel_env.unwrapped.state()[..., 1])
        moves = rng.integers(len(MOVES), size=4)
        _, _, terminated, truncated, info = env.step(joint_action(moves))
        np.testing.assert_array_equal(info["agent_positions_before"], positions)
        expected = np.array([expected_cell(env, cell, move) for cell, move in zip(positions, moves)])
        np.testing.assert_array_equal(info["agent_positions"], expected)  # pursuer i moved by action i
        positions = info["agent_positions"]
        if terminated or truncated:
            break


def test_the_evaders_caught_are_those_pursuit_removed_and_paid_for() -> None:
    env = pursuit_env(**SETTING)
    rng = np.random.default_rng(1)
    catches = 0
    for episode in range(8):
        _, info = env.reset(seed=100 + episode)
        assert info["evaders_caught"] == 0
        caught, done = 0.0, False
        while not done:
            _, reward, terminated, truncated, info = env.step(joint_action(rng.integers(len(MOVES), size=4)))
            state = sisl_state(env.parallel_env)
            remaining = state.evader_layer.n_agents()
            assert info["evaders_caught"] == SETTING["n_evaders"] - remaining  # the evaders left on the grid
            assert env.parallel_env.unwrapped.state()[..., 2].sum() == remaining  # and in the env's global state
            # A catch pays catch_reward (5) to each of the >= n_catch pursuers on the evader's cell; a step without one
            # pays no more than the tag rewards (0.01 per adjacent evader) less the urgency penalty (-0.1 each).
            if info["evaders_caught"] > caught:
                assert float(reward) >= 5.0 * SETTING["n_catch"] - 0.4
            else:
                assert float(reward) < 1.0
            caught, done = info["evaders_caught"], terminated or truncated
        catches += int(caught)
        assert terminated == (caught == SETTING["n_evaders"])  # the episode ends early when every evader is caught
    assert catches > 0  # random moves catch some: the metric is not trivially 0


def test_evaluate_team_scores_the_evaders_caught_at_each_episodes_end() -> None:
    env = pursuit_env(**SETTING)
    team = RandomTeamPolicy(env.action_space, seed=3)
    result = evaluate_team(team, env, n_episodes=6, seed=50)
    assert [metric.key for metric in result["task_metrics"]] == ["evaders_caught"]
    # By hand, on the same episodes and actions: the evaders pursuit removed by each episode's last step.
    by_hand, team = [], RandomTeamPolicy(env.action_space, seed=3)
    for episode in range(6):
        observation, _ = env.reset(seed=50) if episode == 0 else env.reset()
        done = False
        while not done:
            observation, _, terminated, truncated, _ = env.step(team.predict(observation)[0])
            done = terminated or truncated
        by_hand.append(SETTING["n_evaders"] - sisl_state(env.parallel_env).evader_layer.n_agents())
    assert result["evaders_caught"] == pytest.approx(np.mean(by_hand))


def episode_starts(env: PettingZooToGym, act: Any, episodes: int, seed: int) -> list[np.ndarray]:
    """:return: The first observation of each episode after a reset with ``seed``, the team acting by ``act``."""
    starts = []
    for episode in range(episodes):
        observation, _ = env.reset(seed=seed) if episode == 0 else env.reset()
        starts.append(observation)
        done = False
        while not done:
            observation, _, terminated, truncated, _ = env.step(act(observation))
            done = terminated or truncated
    return starts


def test_every_episode_after_a_seed_starts_the_same_whatever_the_team_does() -> None:
    nothing = joint_action(np.full(4, PURSUIT_NO_OP))
    random = RandomTeamPolicy(pursuit_env(**SETTING).action_space, seed=0)
    for seeded in (True, False):
        env = pursuit_env(seed_each_episode=seeded, **SETTING)
        idle = episode_starts(env, lambda _: nothing, 4, seed=11)
        busy = episode_starts(env, lambda observation: random.predict(observation)[0], 4, seed=11)
        np.testing.assert_array_equal(idle[0], busy[0])  # a seeded reset: the same first episode either way
        same = all(np.array_equal(a, b) for a, b in zip(idle, busy))
        # Pursuit draws its evaders' moves from the env's generator, as many as evaders are left: one generator for
        # all episodes makes the later episodes depend on what the team caught.
        assert same == seeded


def test_importing_the_package_does_not_import_pettingzoos_sisl_envs() -> None:
    code = (
        "import sys, sb3_maddpg, sb3_maddpg.envs.sisl, sb3_maddpg.experiments.config; "
        "print(sorted(m for m in sys.modules if m.startswith(('pettingzoo.sisl', 'pygame'))))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"
