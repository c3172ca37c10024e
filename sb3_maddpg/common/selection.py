"""Who each agent's critic listens to: the selection S_i of MADDPG-soa (paper, Algorithm 3).

A selector maps a batch of joint observations to, for every agent i, the indices of the ``k`` other
agents whose observations and actions critic i sees. The selection is made when a transition is
stored (from the observation at time t), kept in the replay buffer with it, and reused for the
next-state target.
"""

import warnings
from abc import ABC, abstractmethod
from collections.abc import Callable, Hashable, Sequence
from typing import Any, Literal

import numpy as np

from sb3_maddpg.common.layout import AgentLayout, ArrayT, array_namespace
from sb3_maddpg.common.package_warnings import SB3MADDPGWarning
from sb3_maddpg.common.user_code import user_stacklevel

TargetSelection = Literal["stored", "next"]
"""Which selection a transition's next-state target uses (:attr:`Selector.target`)."""

TARGET_SELECTIONS: tuple[TargetSelection, ...] = ("stored", "next")

SelectionFn = Callable[[np.ndarray, AgentLayout], np.ndarray]
"""``fn(observations [n_envs, obs_dim], layout) -> int array [n_envs, n_agents, k]``."""


class Selector(ABC):
    """
    Base class: chooses ``k`` other agents for every agent.

    Subclasses implement :meth:`_select`; :meth:`select` checks what they return.

    :param k: How many other agents each agent selects (1 to ``n_agents - 1``).
    """

    checks_output: bool = True
    """Whether :meth:`select` validates every output (built-in selectors are valid by construction)."""

    target: TargetSelection = "stored"
    """Which selection the next-state target uses: ``"stored"``, the one made from the observation when the transition
    was stored (the paper's Algorithm 3, the default), or ``"next"``, one made from the next observation when the
    batch is sampled (see :class:`NearestAgents`)."""

    def __init__(self, k: int) -> None:
        if int(k) < 1:
            raise ValueError(f"A selection needs k >= 1 agents, got k={k}.")
        self.k = int(k)

    def validate(self, layout: AgentLayout) -> None:
        """
        Check that this selector can serve a team with this layout.

        :param layout: The team's agent layout.
        """
        if self.k > layout.n_agents - 1:
            raise ValueError(
                f"{type(self).__name__} selects k={self.k} other agents, but the team has only "
                f"{layout.n_agents - 1} other agents per agent: use k <= {layout.n_agents - 1}."
            )

    def select(self, observations: np.ndarray, layout: AgentLayout, positions: np.ndarray | None = None) -> np.ndarray:
        """
        :param observations: Joint observations, shape ``[n_envs, obs_dim]`` (raw, not normalised).
        :param layout: The team's agent layout.
        :param positions: The agents' positions at these observations, ``[n_envs, n_agents, d]``, where the env reports
            them from its state (``layout.positions_in_info``); ``None``: read from the observations where needed.
        :return: Selected agent indices, int64 array ``[n_envs, n_agents, k]``; never the agent itself.
        """
        observations = np.asarray(observations).reshape(-1, layout.obs_dim)
        selection = np.asarray(self._select(observations, layout) if positions is None else self._select_by(positions))
        if self.checks_output:
            check_selection(selection, layout, self.k, n_rows=observations.shape[0], source=type(self).__name__)
        return selection.astype(np.int64, copy=False)

    @property
    def needs_positions(self) -> bool:
        """Whether this rule selects by the agents' positions (so the env must say where they are)."""
        return False

    def stores_next_selection(self, layout: AgentLayout) -> bool:
        """
        :param layout: The team's layout.
        :return: Whether the replay buffer stores the next step's selection with each row: a ``target="next"`` rule
            by positions the env reports in its infos, which cannot be read again at sampling.
        """
        return self.target == "next" and self.needs_positions and layout.positions_in_info

    @abstractmethod
    def _select(self, observations: np.ndarray, layout: AgentLayout) -> np.ndarray:
        """Return the selection for ``observations`` ``[n_envs, obs_dim]``, shape ``[n_envs, n_agents, k]``."""

    def _select_by(self, positions: np.ndarray) -> np.ndarray:
        """Return the selection for the agents' ``positions`` ``[n_envs, n_agents, d]`` (rules that use them)."""
        raise TypeError(f"{type(self).__name__} does not select by positions.")


class NearestAgents(Selector):
    """
    Each agent selects its ``k`` nearest other agents by Euclidean distance, nearest first
    (ties: lower index first).

    Positions are where the env says they are (:class:`~sb3_maddpg.envs.PettingZooToGym`'s ``positions``: a slice or
    a ``Dict`` key of each agent's observation, or a function of the env's state); every MPE task and
    ``SimpleSpreadVecEnv`` declare theirs (in simple_spread an observation starts with ``[velocity (2), position (2),
    ...]``). On an env that declares none, a model with this selector is refused, unless ``position_slice`` says where
    each agent's position lies in its own observation.

    Agents move, so the nearest ones at the next step may be others, or the same in another order: with
    ``target="stored"`` (the paper's Algorithm 3) the next-state target sees the agents selected at the transition's
    first step, in that order, in slots the critic only ever saw hold the nearest agents (under random actions at N=5,
    k=2, 11.5% of agent-transitions); ``target="next"`` selects again from the next observation, so the target's
    input is laid out as the critic's inputs are. At N=5 with one critic shared by the agents the stored selection can
    send training astray (``benchmarks/paper_n5``).

    :param k: How many other agents each agent selects (paper's partially observable setting: 2).
    :param position_slice: Where an agent's position lies within its own observation; ``None`` (the default): where
        the env declares it.
    :param target: The selection the next-state target uses: ``"stored"`` or ``"next"`` (see above).
    """

    checks_output = False

    def __init__(self, k: int = 2, position_slice: slice | None = None, target: TargetSelection = "stored") -> None:
        super().__init__(k)
        if position_slice is not None and not isinstance(position_slice, slice):
            raise TypeError(
                f"position_slice must be a slice of each agent's observation (e.g. slice(2, 4)) or None (where the env "
                f"declares positions), got {position_slice!r}."
            )
        self.position_slice = position_slice
        self.target = check_target(target)

    @property
    def needs_positions(self) -> bool:
        return True

    def validate(self, layout: AgentLayout) -> None:
        # The positions first: without them this selector cannot serve the team whatever k is.
        if self.position_slice is None and not layout.declares_positions:
            raise ValueError(
                "NearestAgents selects by distance, but this env does not say where its agents' positions are: declare "
                "them with PettingZooToGym(parallel_env, positions=...) (a slice of each agent's observation, a Dict "
                "observation key, or a function of the env returning [n_agents, d] positions), or pass "
                "NearestAgents(position_slice=...), or select by another rule (FixedGraph, CallableSelector)."
            )
        if self.position_slice is not None:
            for agent, size in zip(layout.agent_ids, layout.obs_sizes):
                start, stop, _ = self.position_slice.indices(size)
                if stop <= start or (self.position_slice.stop is not None and self.position_slice.stop > size):
                    raise ValueError(
                        f"position_slice={self.position_slice} does not fit agent {agent!r}'s observation of size "
                        f"{size}: pass NearestAgents(position_slice=...) pointing at the position inside each agent's "
                        "observation, or select by another rule (FixedGraph, CallableSelector)."
                    )
            # An open-ended slice fits each observation but may cut positions of different lengths from unequal ones.
            lengths = {len(range(*self.position_slice.indices(size))) for size in layout.obs_sizes}
            if len(lengths) > 1:
                raise ValueError(
                    f"position_slice={self.position_slice} cuts positions of different lengths {sorted(lengths)} from "
                    f"the agents' observations of sizes {list(layout.obs_sizes)}: give it a stop (e.g. slice(2, 4)), "
                    "so that every agent's position has the same length."
                )
        super().validate(layout)

    def position_slices(self, layout: AgentLayout) -> tuple[slice, ...] | None:
        """
        :param layout: The team's layout.
        :return: Where each agent's position lies in its own observation: this selector's ``position_slice``, else
            the env's declared slices; ``None`` where the env reports positions in its infos instead.
        """
        if self.position_slice is not None:
            return (self.position_slice,) * layout.n_agents
        return layout.position_slices

    def _select(self, observations: np.ndarray, layout: AgentLayout) -> np.ndarray:
        slices = self.position_slices(layout)
        if slices is None and layout.positions_in_info:
            raise ValueError(
                "This env reports its agents' positions in its infos, not in its observations: pass them, "
                "select(observations, layout, positions) (the replay buffer does, from info['agent_positions_before'])."
            )
        return self._select_by(layout.positions(observations, slices))

    def _select_by(self, positions: np.ndarray) -> np.ndarray:
        return nearest_agents(positions, self.k)


def nearest_agents(positions: ArrayT, k: int) -> ArrayT:
    """
    :class:`NearestAgents`' rule, written once against the array API standard: numpy on the host (the replay buffer),
    torch where a run group's observations are (:class:`~sb3_maddpg.run_group.selection.DeviceSelector`).

    :param positions: The agents' positions, ``[..., n_agents, d]``.
    :param k: Agents each agent selects.
    :return: Each agent's ``k`` nearest other agents, nearest first, ties to the lower index, int64 ``[..., n_agents, k]``.
    """
    where: Any = positions  # numpy or torch
    xp = array_namespace(where)
    offsets = where[..., :, None, :] - where[..., None, :, :]
    distances = xp.vecdot(offsets, offsets, axis=-1)
    own = xp.eye(where.shape[-2], dtype=xp.bool, device=getattr(where, "device", None))  # numpy < 2: none
    distances = xp.where(own, xp.inf, distances)  # an agent never selects itself
    return xp.astype(xp.argsort(distances, axis=-1, stable=True)[..., :k], xp.int64, copy=False)


class FixedGraph(Selector):
    """
    A fixed neighbour graph: agent i always selects ``neighbors[i]`` (in that order).

    :param neighbors: One list of ``k`` agent indices per agent, each without the agent itself.
    """

    checks_output = False  # the table is checked once, in validate()

    def __init__(self, neighbors: Sequence[Sequence[int]]) -> None:
        try:
            table = np.asarray(neighbors, dtype=np.int64)
        except ValueError:  # ragged lists
            table = np.zeros((0,), dtype=np.int64)
        if table.ndim != 2 or table.shape[1] < 1:
            raise ValueError(
                "FixedGraph needs one list of k >= 1 neighbour indices per agent, all of the same length "
                f"(e.g. [[1, 2], [0, 2], [0, 1]]), got {neighbors!r}."
            )
        super().__init__(table.shape[1])
        self.neighbors = table

    @classmethod
    def from_roles(cls, roles: Sequence[Hashable]) -> "FixedGraph":
        """
        Every agent selects all other agents with the same role (in index order).

        :param roles: One role per agent, e.g. ``["scout", "scout", "carrier", "carrier"]``. Every role
            must have the same number of agents (at least two), so every agent selects the same number.
        :return: The graph.
        """
        roles = list(roles)
        groups: dict[Hashable, list[int]] = {}
        for index, role in enumerate(roles):
            groups.setdefault(role, []).append(index)
        sizes = {len(members) for members in groups.values()}
        if len(sizes) != 1 or sizes.pop() < 2:
            raise ValueError(
                f"from_roles needs every role shared by the same number (>= 2) of agents, got groups "
                f"{groups}; use FixedGraph(neighbors) for uneven roles."
            )
        return cls([[j for j in groups[role] if j != i] for i, role in enumerate(roles)])

    def validate(self, layout: AgentLayout) -> None:
        super().validate(layout)
        if self.neighbors.shape[0] != layout.n_agents:
            raise ValueError(
                f"FixedGraph has neighbour lists for {self.neighbors.shape[0]} agents, the team has {layout.n_agents}."
            )
        check_selection(self.neighbors[None], layout, self.k, n_rows=1, source="FixedGraph")

    def _select(self, observations: np.ndarray, layout: AgentLayout) -> np.ndarray:
        return np.broadcast_to(self.neighbors, (observations.shape[0], *self.neighbors.shape))


class CallableSelector(Selector):
    """
    A user's rule: ``fn(observations, layout)`` returns the selection.

    :param fn: ``fn(observations [n_envs, obs_dim], layout) -> int array [n_envs, n_agents, k]`` of the
        other agents each agent selects. It must be picklable (cloudpickle) for ``save`` and ``SubprocVecEnv``.
    :param k: How many agents ``fn`` selects for each agent.
    """

    def __init__(self, fn: SelectionFn, k: int) -> None:
        if not callable(fn):
            raise TypeError(f"CallableSelector needs a callable, got {type(fn).__name__}.")
        super().__init__(k)
        self.fn = fn

    def _select(self, observations: np.ndarray, layout: AgentLayout) -> np.ndarray:
        return self.fn(observations, layout)


def check_selection(selection: np.ndarray, layout: AgentLayout, k: int, n_rows: int, source: str) -> None:
    """
    Raise a clear error if a selection has the wrong shape, an index out of range or an agent selecting itself.

    :param selection: The selection to check, ``[n_rows, n_agents, k]``.
    :param layout: The team's layout.
    :param k: The expected number of selected agents.
    :param n_rows: The expected batch size.
    :param source: Who made the selection (for the message).
    """
    expected = (n_rows, layout.n_agents, k)
    if selection.shape != expected:
        raise ValueError(
            f"{source} returned a selection of shape {selection.shape}, expected {expected} ([n_envs, n_agents, k])."
        )
    if not np.issubdtype(selection.dtype, np.integer):
        raise TypeError(f"{source} returned a selection of dtype {selection.dtype}; it must hold integer agent indices.")
    if selection.size and (selection.min() < 0 or selection.max() >= layout.n_agents):
        raise ValueError(
            f"{source} selected agent index {int(selection.min()) if selection.min() < 0 else int(selection.max())}, "
            f"out of range for {layout.n_agents} agents: indices must be in [0, {layout.n_agents - 1}]."
        )
    own = np.arange(layout.n_agents)[None, :, None]
    if np.any(selection == own):
        raise ValueError(
            f"{source} made an agent select itself: S_i holds other agents only (its own o_i, a_i are always seen)."
        )


def check_target(target: Any) -> TargetSelection:
    """:return: ``target`` if it is one of :data:`TARGET_SELECTIONS`; else a ``ValueError`` naming them."""
    if target not in TARGET_SELECTIONS:
        raise ValueError(
            f"target={target!r} is not a target selection: use 'stored' (the selection made when the transition was "
            "stored, the paper's) or 'next' (made again from the next observation)."
        )
    return target  # type: ignore[no-any-return]


def resolve_selector(selector: Selector | int | dict[str, Any] | None) -> Selector:
    """
    The selector of ``selected`` sharing.

    :param selector: ``None`` for the default ``NearestAgents(k=2)``; an int ``k`` for ``NearestAgents(k)``; a dict of
        :class:`NearestAgents`'s arguments ``k`` and ``target`` (as a JSON experiment file gives them, e.g.
        ``{"k": 2, "target": "next"}``), or of :class:`FixedGraph`'s ``neighbors`` (``{"neighbors": [[1, 2], [0, 2],
        [0, 1]]}``); or a :class:`Selector`.
    :return: The selector.
    """
    if selector is None:
        return NearestAgents(k=2)
    if isinstance(selector, int) and not isinstance(selector, bool):
        return NearestAgents(k=selector)
    if isinstance(selector, dict):
        keys = {"neighbors"} if "neighbors" in selector else {"k", "target"}
        unknown = sorted(set(selector) - keys)
        if unknown:
            raise ValueError(
                f"selector={selector!r} has unknown key(s) {unknown}: a dict selector gives NearestAgents's 'k' and "
                "'target' (e.g. {'k': 2, 'target': 'next'}) or FixedGraph's 'neighbors' (e.g. {'neighbors': [[1, 2], "
                "[0, 2], [0, 1]]}); pass a Selector object for any other rule."
            )
        if keys == {"neighbors"}:
            return FixedGraph(selector["neighbors"])
        k = selector.get("k", 2)
        if isinstance(k, bool) or not isinstance(k, int):
            raise ValueError(f"selector={selector!r}: 'k' must be an int (the k nearest agents), got {k!r}.")
        return NearestAgents(**selector)
    if not isinstance(selector, Selector):
        raise TypeError(
            f"selector must be a sb3_maddpg.common.selection.Selector, an int k (the k nearest agents) or a dict of "
            f"NearestAgents's k and target, got {type(selector).__name__}: wrap a function as CallableSelector(fn, k=...)."
        )
    return selector


def warn_if_selecting_everyone(selector: Selector, layout: AgentLayout) -> None:
    """Selecting all n - 1 other agents is full sharing in another order: say so, since it compares nothing."""
    if selector.k == layout.n_agents - 1:
        warnings.warn(
            f"critic_sharing='selected' with k={selector.k} selects every other agent of this {layout.n_agents}-agent "
            "team: each critic sees what 'full' sees, in another order. "
            + (
                "Select fewer (e.g. selector=1, the nearest agent) for a critic that selects."
                if layout.n_agents > 2
                else "A team of 2 has one other agent to select: compare 'selected' with 'full' on a larger team."
            ),
            SB3MADDPGWarning,
            stacklevel=user_stacklevel(),
        )
