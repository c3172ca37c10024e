"""The scripted simple_spread controller and the random team: placed worlds, hand-computed actions, both env paths,
and the normalised score between them."""

import math

import numpy as np
import pytest

from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.analysis.normalised_score import describe_normalised, normalised_score, normalised_scores, reference_scores
from sb3_maddpg.envs import RandomTeamPolicy, ScriptedSpreadPolicy, SimpleSpreadVecEnv, make_simple_spread
from sb3_maddpg.envs.simple_spread_reference import POSITION_GAIN, VELOCITY_GAIN


def placed(env: SimpleSpreadVecEnv, agents: list, landmarks: list, velocities: list | None = None) -> np.ndarray:
    """Put world 0's agents and landmarks where given; return its joint observation."""
    env.reset()
    worlds = env.worlds
    worlds.agent_pos[0] = np.array(agents, dtype=np.float64)
    worlds.landmark_pos[0] = np.array(landmarks, dtype=np.float64)
    worlds.agent_vel[0] = 0.0 if velocities is None else np.array(velocities, dtype=np.float64)
    return worlds.observations(worlds.distances()).reshape(env.num_envs, -1)


def forces(actions: np.ndarray, n_agents: int) -> np.ndarray:
    """mpe2's force direction of each agent: (a[2] - a[1], a[4] - a[3])."""
    per_agent = actions.reshape(n_agents, 5)
    return np.stack([per_agent[:, 2] - per_agent[:, 1], per_agent[:, 4] - per_agent[:, 3]], axis=-1)


def test_the_assignment_is_the_least_total_distance_not_each_agents_nearest() -> None:
    env = SimpleSpreadVecEnv(n_envs=1, n_agents=2)
    # Both agents are nearest to landmark 0 at x=0.4; the least total distance sends agent 0 to x=-1 instead
    # (1.0 + 0.1 against 0.4 + 1.3).
    obs = placed(env, agents=[[0.0, 0.0], [0.3, 0.0]], landmarks=[[0.4, 0.0], [-1.0, 0.0]])
    actions, _ = ScriptedSpreadPolicy(2).predict(obs)
    force = forces(actions[0], 2)
    assert force[0, 0] == pytest.approx(-1.0)  # agent 0: full push to -x (clipped)
    assert force[1, 0] == pytest.approx(POSITION_GAIN * 0.1, abs=1e-6)  # agent 1: gently to +x
    np.testing.assert_allclose(force[:, 1], 0.0, atol=1e-6)


def test_the_pd_law_is_the_hand_computation() -> None:
    env = SimpleSpreadVecEnv(n_envs=1, n_agents=2)
    agents, landmarks, velocities = [[0.0, 0.0], [0.5, 0.5]], [[0.05, -0.02], [0.52, 0.55]], [[0.1, -0.3], [0.0, 0.2]]
    obs = placed(env, agents, landmarks, velocities)
    actions, _ = ScriptedSpreadPolicy(2).predict(obs[0])  # a single joint observation: a single joint action
    expected = np.clip(
        POSITION_GAIN * (np.array(landmarks) - np.array(agents)) - VELOCITY_GAIN * np.array(velocities), -1.0, 1.0
    )
    np.testing.assert_allclose(forces(actions, 2), expected, atol=1e-6)
    assert actions.min() >= 0.0 and actions.max() <= 1.0 and actions.dtype == np.float32
    assert np.all(actions.reshape(2, 5)[:, 0] == 0.0)  # no-op slot unused


def test_the_team_covers_every_landmark_from_a_placed_start() -> None:
    env = SimpleSpreadVecEnv(n_envs=1, n_agents=3, max_cycles=25)
    obs = placed(env, agents=[[-0.9, -0.9], [0.9, -0.9], [0.0, 0.9]], landmarks=[[0.8, 0.7], [-0.7, 0.6], [0.0, -0.8]])
    policy = ScriptedSpreadPolicy(3)
    for _ in range(24):  # the episode's steps but the last (the 25th resets the world)
        obs, _, _, infos = env.step(policy.predict(obs)[0])
    assert max(infos[0]["landmark_distances"]) < 0.1, infos[0]["landmark_distances"]


@pytest.mark.parametrize(("n_agents", "max_min_dist", "min_success"), [(3, 0.05, 0.9), (5, 0.2, 0.7)])
def test_reference_numbers_on_the_batched_env(n_agents: int, max_min_dist: float, min_success: float) -> None:
    env = SimpleSpreadVecEnv(n_envs=100, n_agents=n_agents)
    result = evaluate_team(ScriptedSpreadPolicy.for_env(env), env, n_episodes=100, seed=3)
    assert result["min_dist_sum"] < max_min_dist and result["success_rate"] >= min_success, result


def test_the_controller_scores_alike_on_mpe2_through_the_adapter() -> None:
    env = make_simple_spread(n_agents=3)
    result = evaluate_team(ScriptedSpreadPolicy.for_env(env), env, n_episodes=20, seed=5)
    assert result["min_dist_sum"] < 0.1 and result["success_rate"] >= 0.8, result


def test_nearest_first_observations_and_partial_agent_observability_are_served() -> None:
    # The landmarks in another order and fewer agents observed: the controller reads only positions.
    env = SimpleSpreadVecEnv(n_envs=50, n_agents=4, num_agent_neighbors=1, num_landmark_neighbors=4)
    result = evaluate_team(ScriptedSpreadPolicy.for_env(env), env, n_episodes=50, seed=7)
    assert result["min_dist_sum"] < 0.15, result
    mpe2_env = make_simple_spread(n_agents=4, num_agent_neighbors=1, num_landmark_neighbors=4)
    assert ScriptedSpreadPolicy.for_env(mpe2_env).n_agents == 4


def test_what_the_controller_cannot_serve_says_why() -> None:
    with pytest.raises(ValueError, match=r"needs every landmark.*observes the 2 nearest of 3.*num_landmark_neighbors=None"):
        ScriptedSpreadPolicy.for_env(SimpleSpreadVecEnv(n_envs=1, n_agents=3, num_landmark_neighbors=2))
    with pytest.raises(ValueError, match=r"needs every landmark"):
        ScriptedSpreadPolicy.for_env(make_simple_spread(n_agents=3, num_landmark_neighbors=2))
    with pytest.raises(ValueError, match=r"continuous force actions.*continuous_actions=True"):
        ScriptedSpreadPolicy.for_env(make_simple_spread(n_agents=3, continuous_actions=False))


def test_random_team_draws_uniform_actions_in_the_box() -> None:
    env = SimpleSpreadVecEnv(n_envs=64, n_agents=3)
    team = RandomTeamPolicy(env.action_space, seed=0)
    actions, _ = team.predict(env.reset())
    assert actions.shape == (64, 15) and actions.dtype == np.float32
    assert actions.min() >= 0.0 and actions.max() <= 1.0 and abs(actions.mean() - 0.5) < 0.02
    single, _ = RandomTeamPolicy(env.action_space, seed=0).predict(env.reset()[0])
    np.testing.assert_array_equal(single, actions[0])  # same seed, same first draw


def test_normalised_score_is_zero_at_random_and_one_at_the_controller() -> None:
    references = reference_scores(3)
    random, scripted = references["random"], references["scripted"]
    # The controller is far better than random on both scores, whichever way "better" points.
    assert scripted["min_dist_sum"] < 0.1 < 1.5 < random["min_dist_sum"]
    assert scripted["return_mean"] > random["return_mean"] + 30
    assert normalised_scores(random, references) == pytest.approx({"min_dist_sum": 0.0, "return_mean": 0.0})
    assert normalised_scores(scripted, references) == pytest.approx({"min_dist_sum": 1.0, "return_mean": 1.0})
    # Halfway in min-dist sum, a quarter of the way in return: by hand.
    halfway = {
        "min_dist_sum": (random["min_dist_sum"] + scripted["min_dist_sum"]) / 2,
        "return_mean": random["return_mean"] + 0.25 * (scripted["return_mean"] - random["return_mean"]),
    }
    assert normalised_scores(halfway, references) == pytest.approx({"min_dist_sum": 0.5, "return_mean": 0.25})
    assert "min-dist sum 0.50" in describe_normalised(halfway, references)
    assert math.isnan(normalised_score(1.0, 2.0, 2.0))  # no span between the references: no score
    assert reference_scores(3) is references  # measured once per task and process
