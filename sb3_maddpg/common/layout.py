"""The agent layout: where each agent's observation and action sit in the flat joint vectors.

This module depends on numpy and array_api_compat only (torch only for a tensor it is given), so both the environment
side (which builds a layout) and the algorithm side (which reads it) can share it without importing each other.
"""

import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar

import array_api_compat
import array_api_compat.numpy
import numpy as np

ArrayT = TypeVar("ArrayT")
"""A numpy array or a torch tensor: what the rules written against the array API standard take and give."""


def array_namespace(array: Any) -> Any:
    """
    The array API namespace of a numpy array or a torch tensor (any other array: ``array_api_compat``'s lookup).

    :param array: The array.
    :return: ``array_api_compat.numpy`` or ``array_api_compat.torch`` (imported only for a tensor: the env side, which
        never imports torch, passes numpy arrays), found by type, not by ``array_api_compat.array_namespace``'s cached
        lookup, which ``torch.compile`` warns about in a compiled run group.
    """
    if isinstance(array, np.ndarray):
        return array_api_compat.numpy
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(array, torch.Tensor):
        import array_api_compat.torch as torch_namespace

        return torch_namespace
    return array_api_compat.array_namespace(array)


@dataclass(frozen=True, repr=False)
class AgentLayout:
    """
    Where each agent's part lies in the flat joint observation and joint action.

    Agents are in ``possible_agents`` order everywhere: in the joint vectors, in
    ``info["agent_rewards"]``, in the replay buffer and in the policy's per-agent networks.

    :param agent_ids: The agents' names, in ``possible_agents`` order.
    :param obs_sizes: The length of each agent's flat observation.
    :param action_sizes: The length of each agent's flat action (for a discrete agent: its number of actions, the
        length of the one-hot vector that stands for its choice in the joint action).
    :param discrete_actions: Which agents choose one of ``action_sizes[i]`` actions (a ``Discrete`` space) rather
        than a continuous vector; empty (the default) for none.
    :param position_slices: Where each agent's position lies within its own flat observation, as the env declares it
        (:class:`~sb3_maddpg.envs.PettingZooToGym`'s ``positions``; the MPE tasks declare theirs), for selection by
        distance; ``None`` where the observations hold no declared positions.
    :param positions_in_info: Whether the env reports positions from its state in its infos
        (``info["agent_positions"]`` and ``info["agent_positions_before"]``) rather than in its observations.
    """

    agent_ids: tuple[str, ...]
    obs_sizes: tuple[int, ...]
    action_sizes: tuple[int, ...]
    discrete_actions: tuple[bool, ...] = ()
    # Where positions are is a fact about the env, not the team's shape: layouts that differ only there compare equal
    # (a replay buffer or a save of the same team fits either).
    position_slices: tuple[slice, ...] | None = field(default=None, compare=False)
    positions_in_info: bool = field(default=False, compare=False)
    obs_slices: tuple[slice, ...] = field(init=False, repr=False, compare=False)
    action_slices: tuple[slice, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "agent_ids", tuple(str(agent) for agent in self.agent_ids))
        object.__setattr__(self, "obs_sizes", tuple(int(size) for size in self.obs_sizes))
        object.__setattr__(self, "action_sizes", tuple(int(size) for size in self.action_sizes))
        n_agents = len(self.agent_ids)
        if n_agents == 0:
            raise ValueError("An agent layout needs at least one agent.")
        if len(set(self.agent_ids)) != n_agents:
            raise ValueError(f"Agent ids must be unique, got {self.agent_ids}.")
        if len(self.obs_sizes) != n_agents or len(self.action_sizes) != n_agents:
            raise ValueError(
                f"The layout has {n_agents} agents but {len(self.obs_sizes)} observation sizes "
                f"and {len(self.action_sizes)} action sizes: give one size per agent."
            )
        if min(self.obs_sizes) < 1 or min(self.action_sizes) < 1:
            raise ValueError(f"Every agent needs a non-empty observation and action, got {self}.")
        discrete = tuple(bool(flag) for flag in self.discrete_actions)
        if discrete and len(discrete) != n_agents:
            raise ValueError(f"discrete_actions needs one flag per agent ({n_agents}), got {self.discrete_actions}.")
        # All-continuous is stored as (), so that layouts saved before discrete actions existed compare equal.
        object.__setattr__(self, "discrete_actions", discrete if any(discrete) else ())
        if self.position_slices is not None:
            object.__setattr__(self, "position_slices", _checked_position_slices(self.position_slices, self.obs_sizes))
            if self.positions_in_info:
                raise ValueError("A layout declares positions either in the observations or in the infos, not both.")
        object.__setattr__(self, "obs_slices", _consecutive_slices(self.obs_sizes))
        object.__setattr__(self, "action_slices", _consecutive_slices(self.action_sizes))

    def __repr__(self) -> str:
        discrete = f", discrete_actions={self.discrete_actions}" if self.discrete_actions else ""
        return (
            f"AgentLayout(agent_ids={self.agent_ids}, obs_sizes={self.obs_sizes}, action_sizes={self.action_sizes}{discrete})"
        )

    @property
    def n_agents(self) -> int:
        """The number of agents."""
        return len(self.agent_ids)

    @property
    def obs_dim(self) -> int:
        """The length of the flat joint observation."""
        return sum(self.obs_sizes)

    @property
    def action_dim(self) -> int:
        """The length of the flat joint action."""
        return sum(self.action_sizes)

    @property
    def declares_positions(self) -> bool:
        """Whether the env declares where its agents' positions are (in the observations or in the infos)."""
        return self.position_slices is not None or self.positions_in_info

    def positions(self, observations: ArrayT, position_slices: Sequence[slice] | None = None) -> ArrayT:
        """
        Each agent's position, read from joint observations (a numpy array or a torch tensor).

        :param observations: Joint observations, ``[..., obs_dim]``.
        :param position_slices: Where each agent's position lies in its own observation (default: the env's
            :attr:`position_slices`).
        :return: Positions, ``[..., n_agents, d]``, in the observations' array library.
        """
        slices = self.position_slices if position_slices is None else tuple(position_slices)
        if slices is None:
            raise ValueError(
                "This team's observations hold no declared positions: declare them with PettingZooToGym(env, "
                "positions=...) (a slice of each agent's observation, a Dict observation key, or a function of the env)."
            )
        joint: Any = observations  # numpy or torch: both index and stack as the array API says
        parts = [joint[..., part][..., where] for part, where in zip(self.obs_slices, slices)]
        return array_namespace(joint).stack(parts, axis=-2)

    @property
    def has_discrete_actions(self) -> bool:
        """Whether any agent chooses a discrete action."""
        return any(self.discrete_actions)

    def is_discrete(self, agent: int) -> bool:
        """
        :param agent: An agent's index.
        :return: Whether it chooses a discrete action.
        """
        return bool(self.discrete_actions) and self.discrete_actions[agent]

    @property
    def is_homogeneous(self) -> bool:
        """Whether every agent has the same observation size and the same action size."""
        return len(set(self.obs_sizes)) == 1 and len(set(self.action_sizes)) == 1

    def describe(self) -> str:
        """
        :return: The team in words, e.g. ``"3 agents (agent_0, agent_1, agent_2) with observations of 18 and actions
            of 5 each"``.
        """

        def sizes(values: tuple[int, ...]) -> str:
            return f"{values[0]} each" if len(set(values)) == 1 else ", ".join(map(str, values))

        kinds = ""
        if self.has_discrete_actions:
            kinds = f"; discrete: {', '.join(a for a, flag in zip(self.agent_ids, self.discrete_actions) if flag)}"
        agents = "agent" if self.n_agents == 1 else "agents"
        return (
            f"{self.n_agents} {agents} ({', '.join(self.agent_ids)}) with observations of {sizes(self.obs_sizes)} and "
            f"actions of {sizes(self.action_sizes)}{kinds}"
        )

    def discrete_components(self) -> np.ndarray:
        """:return: Whether each component of the joint action belongs to a discrete agent's one-hot, ``[action_dim]``."""
        discrete = np.zeros(self.action_dim, dtype=bool)
        for i, action_slice in enumerate(self.action_slices):
            discrete[action_slice] = self.is_discrete(i)
        return discrete

    def one_hot_discrete(self, actions: np.ndarray) -> np.ndarray:
        """
        Make each discrete agent's part of joint actions in the policy's [-1, 1] space the one-hot (1 and -1) of its
        largest entry, in place; continuous agents' parts are left as they are.

        :param actions: Joint actions, ``[batch, action_dim]``.
        :return: ``actions``.
        """
        rows = np.arange(len(actions))
        for i, part in enumerate(self.action_slices):
            if self.is_discrete(i):
                chosen = actions[:, part].argmax(axis=1)
                actions[:, part] = -1.0
                actions[rows, part.start + chosen] = 1.0
        return actions

    def joint_observation(self, observations: Mapping[Any, Any]) -> np.ndarray:
        """
        One joint observation from one observation per agent, as PettingZoo's ``ParallelEnv`` gives them: each agent's
        flattened, in layout order (the order of :class:`~sb3_maddpg.envs.PettingZooToGym`'s joint observation). An
        agent that has left the episode (PettingZoo gives it no observation any more) is seen as zeros, as the adapter
        shows it in training.

        :param observations: Each present agent's observation, by agent id (an id may be any object whose ``str`` is
            the layout's id).
        :return: The joint observation, ``[obs_dim]`` float32.
        """
        given = {str(agent): value for agent, value in observations.items()}
        missing = [agent for agent in self.agent_ids if agent not in given]
        unknown = [agent for agent in given if agent not in self.agent_ids]
        if len(missing) == self.n_agents or unknown:
            problems = [f"No observation of {missing}"] if len(missing) == self.n_agents else []
            problems += [f"Observations of agents not in the team: {unknown}"] if unknown else []
            raise ValueError(
                f"{'; '.join(problems)} (given: {list(given)}). The team is {self.describe()}: pass the observation of "
                "each agent of it still in the episode, no more (after an episode's last step PettingZoo's env.agents "
                "is empty: reset the env)."
            )
        parts = []
        for agent, size in zip(self.agent_ids, self.obs_sizes):
            if agent not in given:
                parts.append(np.zeros(size, np.float32))
                continue
            if isinstance(given[agent], Mapping | tuple):
                raise ValueError(
                    f"{agent}'s observation is a {type(given[agent]).__name__}: pass it flattened as the adapter flattens "
                    "it for training, gymnasium.spaces.flatten(parallel_env.observation_space(agent), observation)."
                )
            part = np.asarray(given[agent], dtype=np.float32).reshape(-1)
            if part.size != size:
                raise ValueError(
                    f"{agent}'s observation has {part.size} numbers (shape {np.shape(given[agent])}), but the team's "
                    f"{agent} observes {size}: pass one step's observation per agent, from an env of the model's team "
                    f"({self.describe()})."
                )
            parts.append(part)
        return np.concatenate(parts)

    def agent_actions(self, action: np.ndarray) -> dict[str, np.ndarray | int]:
        """
        Split one joint action in the env's units into the actions a PettingZoo ``ParallelEnv`` takes, as
        ``PettingZooToGym.agent_actions`` does (the adapter's split, for a ParallelEnv without the adapter).

        :param action: A joint action, ``[action_dim]``, agents in layout order.
        :return: Each agent's action, by agent id: a continuous agent's float32 vector of ``action_sizes[i]``, a
            discrete agent's action, the index of the largest entry of its slot (an ``int``).
        """
        flat = np.asarray(action).reshape(-1)
        if flat.size != self.action_dim:
            raise ValueError(f"Expected a joint action of {self.action_dim} numbers, got shape {np.shape(action)}.")
        return {
            agent: int(np.argmax(flat[part])) if self.is_discrete(i) else flat[part].astype(np.float32)
            for i, (agent, part) in enumerate(zip(self.agent_ids, self.action_slices))
        }

    def index_of(self, agent_id: str) -> int:
        """
        The position of an agent in the layout.

        :param agent_id: The agent's name.
        :return: Its index, from 0 to ``n_agents - 1``.
        """
        try:
            return self.agent_ids.index(agent_id)
        except ValueError as error:
            raise KeyError(f"Unknown agent {agent_id!r}; the layout's agents are {self.agent_ids}.") from error


def _checked_position_slices(position_slices: Sequence[slice], obs_sizes: Sequence[int]) -> tuple[slice, ...]:
    """Position slices that fit each agent's observation and cut positions of one length: else a ``ValueError``."""
    slices = tuple(position_slices)
    if len(slices) != len(obs_sizes) or not all(isinstance(part, slice) for part in slices):
        raise ValueError(f"position_slices needs one slice per agent ({len(obs_sizes)}), got {position_slices!r}.")
    for index, (part, size) in enumerate(zip(slices, obs_sizes)):
        start, stop, step = part.indices(size)
        if step != 1 or stop <= start or (part.stop is not None and part.stop > size):
            raise ValueError(
                f"Agent {index}'s position slice {part} does not fit its observation of size {size}: give a slice "
                "(step 1) inside each agent's observation where its position lies."
            )
    lengths = {len(range(*part.indices(size))) for part, size in zip(slices, obs_sizes)}
    if len(lengths) > 1:
        raise ValueError(
            f"The position slices {slices} cut positions of different lengths {sorted(lengths)} from observations of "
            f"sizes {list(obs_sizes)}: every agent's position needs the same length."
        )
    return slices


def _consecutive_slices(sizes: Sequence[int]) -> tuple[slice, ...]:
    slices = []
    start = 0
    for size in sizes:
        slices.append(slice(start, start + size))
        start += size
    return tuple(slices)
