"""Many simple_spread worlds as arrays: mpe2's physics, observations, rewards and task metrics, vectorised.

Every formula here is mpe2's (``mpe2/_mpe_utils/core.py``, ``simple_env.py`` and
``simple_spread/simple_spread.py``, version 1.1), computed in float64 as mpe2 does, with the worlds on the
first axis and the agents on the second, so that a step costs a few dozen array calls whatever the
number of worlds. ``tests/envs/test_simple_spread_vec_env.py`` checks it against mpe2 itself.

The rules (:class:`SpreadWorldRules`) are written once against the array API standard: the namespace ``xp``
of the state's arrays runs them, numpy here (:class:`SimpleSpreadWorlds`) and torch on any device in
:mod:`sb3_maddpg.envs.torch_spread_worlds`, the one module of the env package that imports torch.
"""

from dataclasses import dataclass
from typing import Any, Generic, TypeVar

import array_api_compat
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


ArrayT = TypeVar("ArrayT")
"""The array type of a set of worlds: ``np.ndarray``, or ``torch.Tensor``."""


class NumpyNamespace:
    """
    numpy under the array API standard's names, for the few functions the rules call.

    numpy 2 implements the standard itself, but several of its functions (``np.min``, ``np.astype``,
    ``np.cumulative_sum``, ...) cost microseconds of dispatch more than the array methods they call, which is
    a fifth of a step with one world; these call the methods (the same computation, bit for bit, as mpe2's and as
    before the rules were shared), and work on numpy 1 too.
    """

    float32 = np.float32
    int64 = np.int64
    concat = staticmethod(np.concatenate)
    logaddexp = staticmethod(np.logaddexp)
    sqrt = staticmethod(np.sqrt)
    stack = staticmethod(np.stack)
    take = staticmethod(np.take)
    take_along_axis = staticmethod(np.take_along_axis)
    zeros_like = staticmethod(np.zeros_like)

    @staticmethod
    def asarray(obj: Any, dtype: Any = None, device: Any = None) -> np.ndarray:
        return np.asarray(obj, dtype=dtype)

    @staticmethod
    def zeros(shape: tuple[int, ...], dtype: Any = None, device: Any = None) -> np.ndarray:
        return np.zeros(shape, dtype=dtype)

    @staticmethod
    def astype(x: np.ndarray, dtype: Any) -> np.ndarray:
        return x.astype(dtype)

    @staticmethod
    def reshape(x: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
        return x.reshape(shape)

    @staticmethod
    def permute_dims(x: np.ndarray, axes: tuple[int, ...]) -> np.ndarray:
        return x.transpose(axes)

    @staticmethod
    def min(x: np.ndarray, axis: int) -> np.ndarray:
        return x.min(axis=axis)

    @staticmethod
    def sum(x: np.ndarray, axis: int | tuple[int, ...]) -> np.ndarray:
        return x.sum(axis=axis)

    @staticmethod
    def cumulative_sum(x: np.ndarray, axis: int) -> np.ndarray:
        return x.cumsum(axis=axis)

    @staticmethod
    def argsort(x: np.ndarray, axis: int, stable: bool) -> np.ndarray:
        return np.argsort(x, axis=axis, kind="stable" if stable else None)


def array_namespace(array: Any) -> Any:
    """
    The array API namespace that runs the rules on ``array``.

    :param array: A numpy array or a torch tensor (or any array that ``array_api_compat`` knows).
    :return: :class:`NumpyNamespace` for a numpy array, otherwise ``array_api_compat``'s namespace for the array.
    """
    if isinstance(array, np.ndarray):
        return NumpyNamespace
    return array_api_compat.array_namespace(array)


@dataclass
class WorldDistances(Generic[ArrayT]):
    """Offsets and distances in every world, computed once and shared by rewards, observations and metrics."""

    other_offsets: ArrayT
    """``other_offsets[w, i, j]``: agent i's j-th other agent's position minus its own (index order), ``[E, N, N-1, 2]``."""
    landmark_offsets: ArrayT
    """``landmark_offsets[w, i, l]``: position of landmark l minus agent i's, ``[E, N, N, 2]``."""
    others: ArrayT
    """``others[w, i, j]``: agent i to its j-th other agent, ``[E, N, N-1]``."""
    to_landmarks: ArrayT
    """``to_landmarks[w, l, i]``: landmark l to agent i, ``[E, N, N]``."""
    nearest_agent: ArrayT
    """``nearest_agent[w, l]``: landmark l to its nearest agent, ``[E, N]``."""
    in_contact: ArrayT
    """``in_contact[w, i, j]``: agent i and its j-th other agent overlap (mpe2's ``is_collision``), ``[E, N, N-1]``."""


class SpreadWorldRules(Generic[ArrayT]):
    """
    mpe2's simple_spread rules on the state of many worlds, for any array library of the array API standard.

    Subclasses hold the state (``agent_pos``, ``agent_vel``, ``landmark_pos``: ``[E, N, 2]`` arrays of one
    floating dtype on one device) and draw new episodes; every rule below reads the namespace (``xp``), dtype and
    device from that state, so one implementation serves numpy and torch, on any device.

    :param n_worlds: Number of worlds.
    :param n_agents: Agents (and landmarks) per world.
    :param num_agent_neighbors: Nearest other agents each agent observes (``None``: all), as mpe2's.
    :param num_landmark_neighbors: Nearest landmarks each agent observes (``None``: all), as mpe2's.
    :param local_ratio: Weight of the local collision penalty against the shared distance reward.
    :param agent_pos: The agents' positions, ``[E, N, 2]`` (they fix the worlds' array library, dtype and device).
    """

    def __init__(
        self,
        n_worlds: int,
        n_agents: int,
        num_agent_neighbors: int | None,
        num_landmark_neighbors: int | None,
        local_ratio: float,
        agent_pos: ArrayT,
    ) -> None:
        self.n_worlds = n_worlds
        self.n_agents = n_agents
        self.num_agent_neighbors = num_agent_neighbors
        self.num_landmark_neighbors = num_landmark_neighbors
        self.local_ratio = local_ratio
        xp = self.xp = array_namespace(agent_pos)
        """The array namespace that runs the rules (:func:`array_namespace` of the state)."""
        self.agent_pos: ArrayT = agent_pos
        self.agent_vel: ArrayT = xp.zeros_like(agent_pos)
        self.landmark_pos: ArrayT = xp.zeros_like(agent_pos)
        # The other agents of agent i in index order, as mpe2's observation and contact loops see them: row i of an
        # [N, N-1] table, flattened, because the standard's `take` reads one axis through a 1-D index.
        others = [j for i in range(n_agents) for j in range(n_agents) if j != i]
        self._others = xp.asarray(others, dtype=xp.int64, device=agent_pos.device)  # type: ignore[attr-defined]
        # The softplus's zero, made once on the device: a literal 0 would become a new device tensor every step.
        self._zero = xp.zeros((), dtype=agent_pos.dtype, device=agent_pos.device)  # type: ignore[attr-defined]

    @property
    def obs_size(self) -> int:
        """Each agent's observation length (mpe2's)."""
        n_landmarks = self.num_landmark_neighbors or self.n_agents
        n_others = self.num_agent_neighbors or self.n_agents - 1
        return 2 * DIM_P + DIM_P * n_landmarks + (DIM_P + DIM_C) * n_others

    def step(self, actions: ArrayT) -> WorldDistances[ArrayT]:
        """
        One physics step of every world (``World.step``), from the agents' continuous actions.

        :param actions: ``[E, N, 5]`` float32 actions in [0, 1] (not clipped here), on the worlds' device.
        :return: The distances after the step.
        """
        actions_: Any = actions
        xp = self.xp
        pos: Any = self.agent_pos
        # float32 differences, as mpe2 computes them from the float32 action before adding them to a float64 zero.
        move = xp.stack([actions_[..., 2] - actions_[..., 1], actions_[..., 4] - actions_[..., 3]], axis=-1)
        force = xp.astype(move, pos.dtype) * SENSITIVITY
        offsets = self._other_offsets()  # other minus self, [E, N, N-1, 2]
        distances = _norm(xp, offsets)
        # Softplus penetration on every pair (no cutoff, as mpe2): force on i from j along (p_i - p_j).
        penetration = xp.logaddexp(self._zero, -(distances - 2 * AGENT_SIZE) / CONTACT_MARGIN) * CONTACT_MARGIN
        contact = CONTACT_FORCE * -offsets / distances[..., None] * penetration[..., None]
        # mpe2 adds each pair's force to the action force in turn, others in index order: a running sum
        # (cumsum is sequential) gives its bits exactly, where sum() would add the contacts first.
        force = xp.cumulative_sum(xp.concat([force[:, :, None], contact], axis=2), axis=2)[:, :, -1]
        # Semi-implicit Euler in mpe2's order: position from the old velocity, then damping, then force.
        pos += self.agent_vel * DT  # type: ignore[operator]
        self.agent_vel = self.agent_vel * (1 - DAMPING) + force * DT  # type: ignore[operator]
        return self.distances()

    def _other_offsets(self) -> Any:
        """``[E, N, N-1, 2]``: each agent's others' positions minus its own, others in index order."""
        xp = self.xp
        pos: Any = self.agent_pos
        others = xp.reshape(xp.take(pos, self._others, axis=1), (self.n_worlds, self.n_agents, self.n_agents - 1, DIM_P))
        return others - pos[:, :, None]

    def distances(self) -> WorldDistances[ArrayT]:
        """:return: The current offsets and distances between agents and to landmarks."""
        xp = self.xp
        pos: Any = self.agent_pos
        landmarks: Any = self.landmark_pos
        other_offsets = self._other_offsets()
        landmark_offsets = landmarks[:, None] - pos[:, :, None]  # [E, agent, landmark, 2]
        others = _norm(xp, other_offsets)
        to_landmarks = xp.permute_dims(_norm(xp, landmark_offsets), (0, 2, 1))  # the same bits as landmark minus agent
        return WorldDistances(
            other_offsets=other_offsets,
            landmark_offsets=landmark_offsets,
            others=others,
            to_landmarks=to_landmarks,
            nearest_agent=xp.min(to_landmarks, axis=2),
            in_contact=others < 2 * AGENT_SIZE,
        )

    def rewards(self, distances: WorldDistances[ArrayT]) -> ArrayT:
        """
        Each agent's reward (``SimpleEnv._execute_world_step``): the shared minus sum of landmark-to-nearest-agent
        distances weighted ``1 - local_ratio``, plus minus one per agent in contact weighted ``local_ratio``.

        :param distances: The distances after the step.
        :return: ``[E, N]``, in the worlds' dtype (float64 for mpe2's).
        """
        xp = self.xp
        nearest: Any = distances.nearest_agent
        global_reward = -xp.sum(nearest, axis=1)
        local_reward = -xp.sum(xp.astype(distances.in_contact, nearest.dtype), axis=2)
        return global_reward[:, None] * (1 - self.local_ratio) + local_reward * self.local_ratio

    def observations(self, distances: WorldDistances[ArrayT]) -> ArrayT:
        """
        Every agent's observation (``Scenario.observation``): own velocity, own position, landmark offsets,
        other agents' offsets (nearest first under partial observability), communication (zeros).

        :param distances: The current distances.
        :return: ``[E, N, obs_size]`` float32.
        """
        xp = self.xp
        n_worlds, n_agents = self.n_worlds, self.n_agents
        landmark_offsets: Any = distances.landmark_offsets
        if self.num_landmark_neighbors is not None:
            landmark_offsets = _nearest(
                xp, landmark_offsets, xp.permute_dims(distances.to_landmarks, (0, 2, 1)), self.num_landmark_neighbors
            )
        other_offsets: Any = distances.other_offsets
        if self.num_agent_neighbors is not None:
            other_offsets = _nearest(xp, other_offsets, distances.others, self.num_agent_neighbors)
        n_others = other_offsets.shape[2]
        parts = [
            self.agent_vel,
            self.agent_pos,
            xp.reshape(landmark_offsets, (n_worlds, n_agents, -1)),
            xp.reshape(other_offsets, (n_worlds, n_agents, -1)),
            xp.zeros((n_worlds, n_agents, DIM_C * n_others), dtype=other_offsets.dtype, device=other_offsets.device),
        ]
        return xp.astype(xp.concat(parts, axis=-1), xp.float32)

    def metrics(self, distances: WorldDistances[ArrayT], capture_radius: float) -> dict[str, ArrayT]:
        """
        The task metrics of :class:`~sb3_maddpg.envs.SimpleSpreadMetrics` (mpe2's ``benchmark_data``) in every world.

        :param distances: The current distances.
        :param capture_radius: Distance within which an agent covers a landmark.
        :return: ``coverage``, ``success``, ``collisions`` (agent pairs in contact) and ``min_dist_sum``, ``[E]`` each,
            and ``landmark_distances`` (each landmark's distance to its nearest agent), ``[E, N]``; in the worlds' dtype.
        """
        xp = self.xp
        nearest: Any = distances.nearest_agent
        # Counts as floats: the standard leaves the sum of booleans and integer true division undefined.
        covered = xp.sum(xp.astype(nearest < capture_radius, nearest.dtype), axis=1)
        return {
            "coverage": covered / self.n_agents,
            "success": xp.astype(covered == self.n_agents, nearest.dtype),
            "collisions": xp.sum(xp.astype(distances.in_contact, nearest.dtype), axis=(1, 2)) / 2.0,  # pairs seen twice
            "min_dist_sum": xp.sum(nearest, axis=1),
            "landmark_distances": nearest,
        }


class SimpleSpreadWorlds(SpreadWorldRules[np.ndarray]):
    """
    The state of ``n_worlds`` simple_spread worlds (positions, velocities, landmarks) as float64 numpy arrays, and
    mpe2's rules on them; each world's episodes are drawn from its own numpy generator, as mpe2 draws them.

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
        agent_pos = np.zeros((n_worlds, n_agents, DIM_P))
        super().__init__(n_worlds, n_agents, num_agent_neighbors, num_landmark_neighbors, local_ratio, agent_pos)

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


def _norm(xp: Any, offsets: Any) -> Any:
    """Euclidean length over the last axis (of size 2): mpe2's ``np.sqrt(np.sum(np.square(delta)))``, bit for bit."""
    x, y = offsets[..., 0], offsets[..., 1]
    return xp.sqrt(x * x + y * y)


def _nearest(xp: Any, offsets: Any, distances: Any, count: int) -> Any:
    """
    The ``count`` entries of smallest distance, nearest first (mpe2's ``nearest_entities``), zero-padded to ``count``.

    :param xp: The arrays' namespace.
    :param offsets: ``[E, N, M, 2]``.
    :param distances: ``[E, N, M]``.
    :param count: How many to keep.
    :return: ``[E, N, count, 2]``.
    """
    # A stable sort equals mpe2's np.argsort on these short rows (insertion sort below 16 elements).
    order = xp.argsort(distances, axis=-1, stable=True)[..., :count]
    nearest = xp.take_along_axis(offsets, order[..., None], axis=2)
    missing = count - nearest.shape[2]
    if missing > 0:
        padding = xp.zeros((*nearest.shape[:2], missing, DIM_P), dtype=nearest.dtype, device=nearest.device)
        nearest = xp.concat([nearest, padding], axis=2)
    return nearest
