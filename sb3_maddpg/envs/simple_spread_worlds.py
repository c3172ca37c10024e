"""Many simple_spread worlds as arrays: mpe2's physics, observations, rewards and task metrics, vectorised.

Every formula here is mpe2's (``mpe2/_mpe_utils/core.py``, ``simple_env.py`` and
``simple_spread/simple_spread.py``, version 1.1), computed in float64 as mpe2 does, with the worlds on the
first axis and the agents on the second, so that a step costs a few dozen numpy calls whatever the
number of worlds. ``tests/test_simple_spread_vec_env.py`` checks it against mpe2 itself.
"""

from dataclasses import dataclass

import numpy as np

DIM_P = 2
"""Position dimensions (``World.dim_p``)."""
DIM_C = 2
"""Communication channel size (simple_spread's ``world.dim_c``); its agents are silent, so the slots are zeros."""
DT = 0.1
"""Integration time step (``World.dt``)."""
DAMPING = 0.25
"""Velocity damping per step (``World.damping``)."""
CONTACT_FORCE = 1e2
"""Contact force scale (``World.contact_force``)."""
CONTACT_MARGIN = 1e-3
"""Softness of the contact penetration (``World.contact_margin``)."""
AGENT_SIZE = 0.15
"""simple_spread's agent radius (landmarks do not collide)."""
SENSITIVITY = 5.0
"""Action-to-force gain (``SimpleEnv._set_action`` when ``agent.accel`` is None)."""
ACTION_SIZE = 2 * DIM_P + 1
"""Continuous action per agent: no-op, left, right, down, up (mpe2's ``Box(0, 1, (5,))``)."""


@dataclass
class WorldDistances:
    """Offsets and distances in every world, computed once and shared by rewards, observations and metrics."""

    other_offsets: np.ndarray
    """``other_offsets[w, i, j]``: agent i's j-th other agent's position minus its own (index order), ``[E, N, N-1, 2]``."""
    landmark_offsets: np.ndarray
    """``landmark_offsets[w, i, l]``: position of landmark l minus agent i's, ``[E, N, N, 2]``."""
    others: np.ndarray
    """``others[w, i, j]``: agent i to its j-th other agent, ``[E, N, N-1]``."""
    to_landmarks: np.ndarray
    """``to_landmarks[w, l, i]``: landmark l to agent i, ``[E, N, N]``."""
    nearest_agent: np.ndarray
    """``nearest_agent[w, l]``: landmark l to its nearest agent, ``[E, N]``."""
    in_contact: np.ndarray
    """``in_contact[w, i, j]``: agent i and its j-th other agent overlap (mpe2's ``is_collision``), ``[E, N, N-1]``."""


class SimpleSpreadWorlds:
    """
    The state of ``n_worlds`` simple_spread worlds (positions, velocities, landmarks) and mpe2's rules on them.

    :param n_worlds: Number of worlds.
    :param n_agents: Agents (and landmarks) per world.
    :param num_agent_neighbors: Nearest other agents each agent observes (``None``: all), as mpe2's.
    :param num_landmark_neighbors: Nearest landmarks each agent observes (``None``: all), as mpe2's.
    :param local_ratio: Weight of the local collision penalty against the shared distance reward.
    """

    def __init__(
        self,
        n_worlds: int,
        n_agents: int,
        num_agent_neighbors: int | None = None,
        num_landmark_neighbors: int | None = None,
        local_ratio: float = 0.5,
    ) -> None:
        self.n_worlds = n_worlds
        self.n_agents = n_agents
        self.num_agent_neighbors = num_agent_neighbors
        self.num_landmark_neighbors = num_landmark_neighbors
        self.local_ratio = local_ratio
        # others[i]: the other agents of agent i in index order, as mpe2's observation and contact loops see them.
        self._others = np.array([[j for j in range(n_agents) if j != i] for i in range(n_agents)], dtype=np.intp)
        shape = (n_worlds, n_agents, DIM_P)
        self.agent_pos = np.zeros(shape)
        self.agent_vel = np.zeros(shape)
        self.landmark_pos = np.zeros(shape)

    @property
    def obs_size(self) -> int:
        """Each agent's observation length (mpe2's)."""
        n_landmarks = self.num_landmark_neighbors or self.n_agents
        n_others = self.num_agent_neighbors or self.n_agents - 1
        return 2 * DIM_P + DIM_P * n_landmarks + (DIM_P + DIM_C) * n_others

    def reset_world(self, world: int, np_random: np.random.Generator) -> None:
        """
        New random positions for one world, drawn as mpe2's ``Scenario.reset_world`` draws them.

        :param world: The world's index.
        :param np_random: The world's generator (mpe2's ``env.np_random``).
        """
        # mpe2 draws uniform(-1, 1, 2) for each agent, then for each landmark: one draw of the same stream.
        positions = np_random.uniform(-1, +1, (2 * self.n_agents, DIM_P))
        self.agent_pos[world] = positions[: self.n_agents]
        self.landmark_pos[world] = positions[self.n_agents :]
        self.agent_vel[world] = 0.0

    def step(self, actions: np.ndarray) -> WorldDistances:
        """
        One physics step of every world (``World.step``), from the agents' continuous actions.

        :param actions: ``[E, N, 5]`` float32 actions in [0, 1].
        :return: The distances after the step.
        """
        # float32 differences, as mpe2 computes them from the float32 action before adding them to a float64 zero.
        move = np.stack([actions[..., 2] - actions[..., 1], actions[..., 4] - actions[..., 3]], axis=-1)
        force = move.astype(np.float64) * SENSITIVITY
        offsets = self.agent_pos[:, self._others] - self.agent_pos[:, :, None]  # other minus self, [E, N, N-1, 2]
        distances = _norm(offsets)
        # Softplus penetration on every pair (no cutoff, as mpe2): force on i from j along (p_i - p_j).
        penetration = np.logaddexp(0, -(distances - 2 * AGENT_SIZE) / CONTACT_MARGIN) * CONTACT_MARGIN
        contact = CONTACT_FORCE * -offsets / distances[..., None] * penetration[..., None]
        # mpe2 adds each pair's force to the action force in turn, others in index order: a running sum
        # (cumsum is sequential) gives its bits exactly, where sum() would add the contacts first.
        force = np.concatenate([force[:, :, None], contact], axis=2).cumsum(axis=2)[:, :, -1]
        # Semi-implicit Euler in mpe2's order: position from the old velocity, then damping, then force.
        self.agent_pos += self.agent_vel * DT
        self.agent_vel = self.agent_vel * (1 - DAMPING) + force * DT
        return self.distances()

    def distances(self) -> WorldDistances:
        """:return: The current offsets and distances between agents and to landmarks."""
        other_offsets = self.agent_pos[:, self._others] - self.agent_pos[:, :, None]
        landmark_offsets = self.landmark_pos[:, None] - self.agent_pos[:, :, None]  # [E, agent, landmark, 2]
        others = _norm(other_offsets)
        to_landmarks = _norm(landmark_offsets).transpose(0, 2, 1)  # the same bits as landmark minus agent, squared
        return WorldDistances(
            other_offsets=other_offsets,
            landmark_offsets=landmark_offsets,
            others=others,
            to_landmarks=to_landmarks,
            nearest_agent=to_landmarks.min(axis=2),
            in_contact=others < 2 * AGENT_SIZE,
        )

    def rewards(self, distances: WorldDistances) -> np.ndarray:
        """
        Each agent's reward (``SimpleEnv._execute_world_step``): the shared minus sum of landmark-to-nearest-agent
        distances weighted ``1 - local_ratio``, plus minus one per agent in contact weighted ``local_ratio``.

        :param distances: The distances after the step.
        :return: ``[E, N]`` float64.
        """
        global_reward = -distances.nearest_agent.sum(axis=1)
        local_reward = -distances.in_contact.sum(axis=2).astype(np.float64)
        return global_reward[:, None] * (1 - self.local_ratio) + local_reward * self.local_ratio

    def observations(self, distances: WorldDistances) -> np.ndarray:
        """
        Every agent's observation (``Scenario.observation``): own velocity, own position, landmark offsets,
        other agents' offsets (nearest first under partial observability), communication (zeros).

        :param distances: The current distances.
        :return: ``[E, N, obs_size]`` float32.
        """
        n_worlds, n_agents = self.n_worlds, self.n_agents
        landmark_offsets = distances.landmark_offsets
        if self.num_landmark_neighbors is not None:
            landmark_offsets = _nearest(
                landmark_offsets, distances.to_landmarks.transpose(0, 2, 1), self.num_landmark_neighbors
            )
        other_offsets = distances.other_offsets
        if self.num_agent_neighbors is not None:
            other_offsets = _nearest(other_offsets, distances.others, self.num_agent_neighbors)
        n_others = other_offsets.shape[2]
        parts = [
            self.agent_vel,
            self.agent_pos,
            landmark_offsets.reshape(n_worlds, n_agents, -1),
            other_offsets.reshape(n_worlds, n_agents, -1),
            np.zeros((n_worlds, n_agents, DIM_C * n_others)),
        ]
        return np.concatenate(parts, axis=-1).astype(np.float32)

    def metrics(self, distances: WorldDistances, capture_radius: float) -> dict[str, np.ndarray]:
        """
        The task metrics of :class:`~sb3_maddpg.envs.SimpleSpreadMetrics` (mpe2's ``benchmark_data``) in every world.

        :param distances: The current distances.
        :param capture_radius: Distance within which an agent covers a landmark.
        :return: ``coverage``, ``success``, ``collisions`` (agent pairs in contact) and ``min_dist_sum``, ``[E]`` each,
            and ``landmark_distances`` (each landmark's distance to its nearest agent), ``[E, N]``.
        """
        nearest = distances.nearest_agent
        covered = (nearest < capture_radius).sum(axis=1)
        return {
            "coverage": covered / self.n_agents,
            "success": (covered == self.n_agents).astype(np.float64),
            "collisions": distances.in_contact.sum(axis=(1, 2)) / 2.0,  # each pair seen from both ends
            "min_dist_sum": nearest.sum(axis=1),
            "landmark_distances": nearest,
        }


def _norm(offsets: np.ndarray) -> np.ndarray:
    """Euclidean length over the last axis (of size 2): mpe2's ``np.sqrt(np.sum(np.square(delta)))``, bit for bit."""
    x, y = offsets[..., 0], offsets[..., 1]
    return np.sqrt(x * x + y * y)


def _nearest(offsets: np.ndarray, distances: np.ndarray, count: int) -> np.ndarray:
    """
    The ``count`` entries of smallest distance, nearest first (mpe2's ``nearest_entities``), zero-padded to ``count``.

    :param offsets: ``[E, N, M, 2]``.
    :param distances: ``[E, N, M]``.
    :param count: How many to keep.
    :return: ``[E, N, count, 2]``.
    """
    # A stable sort equals mpe2's np.argsort on these short rows (insertion sort below 16 elements).
    order = np.argsort(distances, axis=-1, kind="stable")[..., :count]
    nearest = np.take_along_axis(offsets, order[..., None], axis=2)
    missing = count - nearest.shape[2]
    if missing > 0:
        nearest = np.concatenate([nearest, np.zeros((*nearest.shape[:2], missing, DIM_P))], axis=2)
    return nearest
