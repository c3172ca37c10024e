"""Two teams to measure a learned one against on simple_spread: a scripted controller and uniformly random actions.

The scripted controller reads the joint observation (it is a centralised reference, not a decentralised policy):
each agent's position and velocity from its own slice, the landmarks from agent 0's (its position plus the offsets),
assigns agents to landmarks by the assignment of least total distance (``scipy.optimize.linear_sum_assignment``),
recomputed every step, and steers each agent to its landmark by a proportional-derivative law on mpe2's force
actions. It ignores collisions. Both have SB3's ``predict``, so :func:`~sb3_maddpg.analysis.evaluation.evaluate_team` scores
them like a model, on :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` or on mpe2 through the adapter.
"""

from typing import Any

import numpy as np
from gymnasium import spaces
from scipy.optimize import linear_sum_assignment

from sb3_maddpg.envs.simple_spread_worlds import ACTION_SIZE, DIM_P

POSITION_GAIN = 8.0
"""The controller's force per unit of distance to the landmark (before clipping to mpe2's [-1, 1] per axis)."""
VELOCITY_GAIN = 2.0
"""The controller's braking force per unit of velocity."""


class ScriptedSpreadPolicy:
    """
    A scripted simple_spread team: optimal assignment of agents to landmarks, then a PD law to each one's landmark.

    :param n_agents: Agents (and landmarks).
    :param num_landmark_neighbors: The env's ``num_landmark_neighbors``: ``None`` or ``n_agents`` (every landmark
        observed, in any order); fewer is refused (no agent sees every landmark, so the assignment cannot be made).
    :param position_gain: Force per unit of distance to the target.
    :param velocity_gain: Braking force per unit of velocity.
    """

    def __init__(
        self,
        n_agents: int,
        num_landmark_neighbors: int | None = None,
        position_gain: float = POSITION_GAIN,
        velocity_gain: float = VELOCITY_GAIN,
    ) -> None:
        if num_landmark_neighbors is not None and num_landmark_neighbors < n_agents:
            raise ValueError(
                f"The scripted controller needs every landmark in agent 0's observation, but the env observes the "
                f"{num_landmark_neighbors} nearest of {n_agents}: use num_landmark_neighbors=None (or {n_agents}) for "
                "the reference; the other agents' observability (num_agent_neighbors) does not matter."
            )
        self.n_agents = n_agents
        self.position_gain = position_gain
        self.velocity_gain = velocity_gain
        self._landmark_slice = slice(2 * DIM_P, 2 * DIM_P + DIM_P * n_agents)

    @classmethod
    def for_env(cls, env: Any) -> "ScriptedSpreadPolicy":
        """
        :param env: A simple_spread env: :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` or the adapter over mpe2 (or a
            VecEnv of adapters).
        :return: The controller for its team.
        """
        layout = env.get_attr("agent_layout")[0] if hasattr(env, "get_attr") else env.agent_layout
        if layout.has_discrete_actions:
            raise ValueError(
                "The scripted controller drives mpe2's continuous force actions, but this env has discrete ones: build "
                "it with continuous_actions=True (the paper's setting)."
            )
        worlds = getattr(env, "worlds", None)
        if worlds is not None:  # the batched env
            neighbors = worlds.num_landmark_neighbors
        else:
            parallel_env = env.get_attr("parallel_env")[0] if hasattr(env, "get_attr") else env.parallel_env
            scenario = getattr(getattr(parallel_env, "unwrapped", parallel_env), "scenario", None)
            neighbors = getattr(scenario, "num_landmark_neighbors", None)
        return cls(layout.n_agents, neighbors)

    def actions(self, observation: np.ndarray) -> np.ndarray:
        """
        :param observation: Joint observations, ``[n_envs, n_agents * obs_size]``.
        :return: Joint actions in mpe2's units ([0, 1]), ``[n_envs, n_agents * 5]``.
        """
        n_envs = observation.shape[0]
        per_agent = observation.reshape(n_envs, self.n_agents, -1).astype(np.float64)
        velocity, position = per_agent[:, :, 0:DIM_P], per_agent[:, :, DIM_P : 2 * DIM_P]
        landmarks = position[:, :1] + per_agent[:, 0, self._landmark_slice].reshape(n_envs, self.n_agents, DIM_P)
        targets = np.empty_like(position)
        for world in range(n_envs):
            cost = np.linalg.norm(position[world, :, None] - landmarks[world, None], axis=-1)  # [agent, landmark]
            agents, assigned = linear_sum_assignment(cost)
            targets[world, agents] = landmarks[world, assigned]
        force = np.clip(self.position_gain * (targets - position) - self.velocity_gain * velocity, -1.0, 1.0)
        # mpe2's force is (a[2] - a[1], a[4] - a[3]): push on the positive or the negative component of each axis.
        actions = np.zeros((n_envs, self.n_agents, ACTION_SIZE), dtype=np.float32)
        actions[..., 1], actions[..., 2] = np.maximum(-force[..., 0], 0), np.maximum(force[..., 0], 0)
        actions[..., 3], actions[..., 4] = np.maximum(-force[..., 1], 0), np.maximum(force[..., 1], 0)
        return actions.reshape(n_envs, -1)

    def predict(
        self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ) -> tuple[np.ndarray, None]:
        """
        SB3's ``predict`` (the controller is deterministic either way).

        :param observation: A joint observation, or a batch of them.
        :param state: Unused (no recurrent state).
        :param episode_start: Unused.
        :param deterministic: Unused.
        :return: The joint actions in mpe2's units and ``None``.
        """
        observation = np.asarray(observation)
        if observation.ndim == 1:
            return self.actions(observation[None])[0], None
        return self.actions(observation), None


class RandomTeamPolicy:
    """
    Uniformly random joint actions over an action space: the other end of the normalised score.

    :param action_space: The env's (joint) action space.
    :param seed: Seed of the draws.
    """

    def __init__(self, action_space: spaces.Space, seed: int | None = None) -> None:
        self.action_space = action_space
        self.rng = np.random.default_rng(seed)

    def predict(
        self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = False
    ) -> tuple[np.ndarray, None]:
        """
        :param observation: A joint observation, or a batch of them (only its batch size is read).
        :param state: Unused.
        :param episode_start: Unused.
        :param deterministic: Unused: the actions are random either way.
        :return: Uniform actions of the action space (one per observation of a batch) and ``None``.
        """
        if not isinstance(self.action_space, spaces.Box):
            raise TypeError(f"RandomTeamPolicy draws from a Box action space, got {self.action_space}.")
        observation = np.asarray(observation)
        batch = () if observation.ndim == 1 else (observation.shape[0],)
        low, high = self.action_space.low, self.action_space.high
        return self.rng.uniform(low, high, size=batch + low.shape).astype(self.action_space.dtype), None
