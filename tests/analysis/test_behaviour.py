"""The plateau diagnosis: what a team does at the end of its episodes, from placed worlds and by hand."""

from typing import Any

import numpy as np
import pytest

from sb3_maddpg.analysis.behaviour import behaviour_of, final_distances, team_behaviour
from sb3_maddpg.envs import RandomTeamPolicy, ScriptedSpreadPolicy, SimpleSpreadVecEnv, make_simple_spread_vec_env


def test_two_agents_on_one_landmark_and_one_stopped_between() -> None:
    # Landmarks at x = 0, 1, 2. Agents 0 and 1 both on landmark 0; agent 2 stopped at x = 1.5, between 1 and 2.
    agents = np.array([[0.0, 0.0], [0.1, 0.0], [1.5, 0.0]])
    landmarks = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    distances = np.linalg.norm(agents[:, None] - landmarks[None], axis=-1)[None]  # [1 episode, agent, landmark]
    speeds = np.array([[0.0, 0.0, 0.05]])
    result = behaviour_of(distances, speeds, radius=0.3)
    assert result["covered"] == 1 and result["crowded"] == 1 and result["strays"] == 1
    assert result["stray_speed"] == pytest.approx(0.05)
    # min-dist sum: 0 + 0.5 + 0.5 = 1.0; the best assignment: 0 -> 0 (0), 1 -> 1 (0.9), 2 -> 2 (0.5) = 1.4.
    assert result["min_dist_sum"] == pytest.approx(1.0) and result["assignment_gap"] == pytest.approx(0.4)


def test_a_spread_team_has_no_gap() -> None:
    distances = np.array([[[0.05, 1.0], [1.0, 0.1]]])  # each agent on its own landmark
    result = behaviour_of(distances, np.zeros((1, 2)))
    assert (result["covered"], result["crowded"], result["strays"], result["assignment_gap"]) == (2, 0, 0, 0)
    assert np.isnan(result["stray_speed"])  # no stray: no speed


def placed_worlds(**env_kwargs: Any) -> tuple[np.ndarray, np.ndarray]:
    """:return: One placed world of 3 agents' joint observation, and its true agent-to-landmark distances."""
    env = SimpleSpreadVecEnv(n_envs=1, n_agents=3, **env_kwargs)
    env.reset()
    worlds = env.worlds
    worlds.agent_pos[0] = [[0.0, 0.0], [0.5, 0.5], [-0.5, 0.2]]
    worlds.landmark_pos[0] = [[0.3, -0.4], [1.0, 1.0], [-0.9, 0.0]]
    worlds.agent_vel[0] = [[0.3, 0.4], [0.0, 0.0], [0.0, -1.0]]
    observation = worlds.observations(worlds.distances()).reshape(1, -1)
    return observation, np.linalg.norm(worlds.agent_pos[0][:, None] - worlds.landmark_pos[0][None], axis=-1)


def test_final_distances_read_a_placed_worlds_observation() -> None:
    observation, truth = placed_worlds()
    distances, speeds = final_distances(observation, 3)
    np.testing.assert_allclose(distances[0], truth, atol=1e-6)
    np.testing.assert_allclose(speeds[0], [0.5, 0.0, 1.0], atol=1e-6)


def test_final_distances_read_landmarks_observed_nearest_first() -> None:
    # The same placed world observed nearest first: each agent lists the landmarks in its own order, and the
    # distances must still be agent i to landmark l (matched by absolute position), not agent i to its l-th nearest.
    observation, truth = placed_worlds(num_landmark_neighbors=3, num_agent_neighbors=2)
    distances, _ = final_distances(observation, 3)
    agent_0_order = np.argsort(truth[0])  # landmark l of the result is agent 0's l-th nearest
    np.testing.assert_allclose(distances[0], truth[:, agent_0_order], atol=1e-6)
    # So the behaviour is the index-ordered observation's (min-dist sum 0.5 + 0.71 + 0.45).
    assert behaviour_of(distances, np.zeros((1, 3)))["min_dist_sum"] == pytest.approx(truth.min(axis=0).sum(), abs=1e-6)


@pytest.mark.parametrize("path", ["batched", "mpe2"])
def test_the_scripted_team_spreads_and_the_random_one_strays(path: str) -> None:
    env = make_simple_spread_vec_env(20 if path == "batched" else 2, path, n_agents=3)
    scripted = team_behaviour(ScriptedSpreadPolicy.for_env(env), env, n_episodes=20, seed=0)
    assert scripted["covered"] > 2.8 and scripted["strays"] < 0.2 and scripted["assignment_gap"] < 0.02
    random = team_behaviour(RandomTeamPolicy(env.action_space, seed=0), env, n_episodes=20, seed=0)
    assert random["strays"] > 2 and random["assignment_gap"] > 0.2
