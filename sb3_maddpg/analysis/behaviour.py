"""What a simple_spread team does at the end of its episodes: a diagnosis of a plateau, not a score.

A min-dist sum of 1.8 at N=5 can mean many things: every agent halfway to its landmark, two agents on one landmark
and one landmark bare, or agents stopped between landmarks. :func:`team_behaviour` tells them apart from the last
joint observation of each episode (each agent's velocity and its offsets to every landmark):

- ``covered``: landmarks with an agent within ``radius``;
- ``crowded``: landmarks with two or more agents within ``radius`` (agents spent where one would do);
- ``strays``: agents within ``radius`` of no landmark, and ``stray_speed``, their mean speed (near 0: stopped
  between landmarks; high: still on their way);
- ``assignment_gap``: the total distance of the optimal assignment of agents to landmarks minus the min-dist sum.
  0 when each landmark's nearest agent is a different agent; it grows as agents share their nearest landmark, the
  coordination failure that full coverage cannot have.

Counts are means per episode; N is the number of agents and landmarks.
"""

from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg.envs.simple_spread_worlds import DIM_P

BEHAVIOUR_RADIUS = 0.3
"""The radius of ``covered``, ``crowded`` and ``strays`` by default: the issue's "within 0.3" (mpe2's is 0.1)."""


def final_distances(final_observations: np.ndarray, n_agents: int) -> tuple[np.ndarray, np.ndarray]:
    """
    :param final_observations: Joint observations at episodes' last steps, ``[episodes, n_agents * obs_size]``, with
        every landmark observed (``num_landmark_neighbors`` ``None`` or N: in index order, or nearest first).
    :param n_agents: Agents (and landmarks).
    :return: ``distances[e, i, l]``, agent i to landmark l, and ``speeds[e, i]``.
    """
    per_agent = final_observations.reshape(final_observations.shape[0], n_agents, -1).astype(np.float64)
    offsets = per_agent[:, :, 2 * DIM_P : 2 * DIM_P + DIM_P * n_agents].reshape(-1, n_agents, n_agents, DIM_P)
    # Landmark l is agent 0's l-th: each agent lists the landmarks in its own order when it observes them nearest
    # first, so its slots are matched to agent 0's by their absolute positions (own position plus offset).
    absolute = per_agent[:, :, None, DIM_P : 2 * DIM_P] + offsets  # [episode, agent, slot, xy]
    gaps = np.linalg.norm(absolute[:, :, :, None, :] - absolute[:, :1, None, :, :], axis=-1)  # [e, agent, slot, l]
    slot_of = gaps.argmin(axis=2)  # [episode, agent, landmark]: the agent's slot holding landmark l
    distances = np.take_along_axis(np.linalg.norm(offsets, axis=-1), slot_of, axis=2)
    return distances, np.linalg.norm(per_agent[:, :, :DIM_P], axis=-1)


def behaviour_of(distances: np.ndarray, speeds: np.ndarray, radius: float = BEHAVIOUR_RADIUS) -> dict[str, float]:
    """
    :param distances: ``[episodes, agent, landmark]`` at the last step (:func:`final_distances`).
    :param speeds: ``[episodes, agent]``.
    :param radius: Within this distance an agent holds a landmark.
    :return: The means per episode described in the module's docstring.
    """
    near = distances < radius
    strays = ~near.any(axis=2)
    min_dist_sum = distances.min(axis=1).sum(axis=1)
    assignment = np.array([episode[linear_sum_assignment(episode)].sum() for episode in distances])
    stray_speeds = speeds[strays]
    return {
        "covered": float(near.any(axis=1).sum(axis=1).mean()),
        "crowded": float((near.sum(axis=1) >= 2).sum(axis=1).mean()),
        "strays": float(strays.sum(axis=1).mean()),
        "stray_speed": float(stray_speeds.mean()) if stray_speeds.size else float("nan"),
        "assignment_gap": float((assignment - min_dist_sum).mean()),
        "min_dist_sum": float(min_dist_sum.mean()),
    }


def team_behaviour(
    model: Any, env: VecEnv, n_episodes: int = 100, seed: int | None = None, radius: float = BEHAVIOUR_RADIUS
) -> dict[str, float]:
    """
    Run a team deterministically and describe what it does at the end of its episodes (see the module docstring).

    :param model: Anything with SB3's ``predict`` (a model, or :class:`~sb3_maddpg.envs.ScriptedSpreadPolicy`).
    :param env: A simple_spread VecEnv (:class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`, or mpe2 through the adapter in
        a ``DummyVecEnv``) observing every landmark; it is reset here.
    :param n_episodes: Episodes (at least; whole rounds of the env's worlds).
    :param seed: Seed of the first reset.
    :param radius: See :func:`behaviour_of`.
    :return: The behaviour's means per episode.
    """
    n_agents = env.get_attr("agent_layout")[0].n_agents
    if seed is not None:
        env.seed(seed)
    observations = env.reset()
    finals: list[np.ndarray] = []
    while len(finals) < n_episodes:
        actions, _ = model.predict(observations, deterministic=True)
        observations, _, dones, infos = env.step(actions)
        finals.extend(info["terminal_observation"] for done, info in zip(dones, infos) if done)
    distances, speeds = final_distances(np.stack(finals), n_agents)
    return behaviour_of(distances, speeds, radius)
