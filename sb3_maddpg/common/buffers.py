"""The multi-agent replay buffer: one row per joint transition, per-agent rewards and terminations, selections."""

import contextlib
import contextvars
import math
import warnings
from collections.abc import Iterator
from typing import Any, NamedTuple

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.vec_env import VecNormalize

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.package_warnings import SB3MADDPGWarning
from sb3_maddpg.common.selection import Selector
from sb3_maddpg.common.user_code import user_stacklevel

_LOADING = contextvars.ContextVar("loading_a_saved_model", default=False)


class MultiAgentReplayBufferSamples(NamedTuple):
    """A batch of joint transitions; every agent trains on the same rows."""

    observations: th.Tensor
    """Joint observations ``[batch, obs_dim]``."""
    actions: th.Tensor
    """Joint actions in [-1, 1] ``[batch, action_dim]``."""
    next_observations: th.Tensor
    """Joint next observations ``[batch, obs_dim]``."""
    dones: th.Tensor
    """1.0 where agent i's episode truly terminated (time-limit truncation is 0: it bootstraps, unless the buffer has
    ``handle_timeout_termination=False``), ``[batch, n_agents]``."""
    rewards: th.Tensor
    """Per-agent rewards r_i ``[batch, n_agents]``."""
    selections: th.Tensor | None
    """Agents each agent selected when the transition was stored, ``[batch, n_agents, k]`` (LongTensor), or None."""
    next_selections: th.Tensor | None = None
    """The selection the next-state target uses when it is not the stored one (a selector with ``target="next"``:
    made from the next observation at sampling), like :attr:`selections`; None: the target uses :attr:`selections`."""
    active: th.Tensor | None = None
    """1.0 where agent i was in the episode when the transition began, 0.0 after it left, ``[batch, n_agents]``: the
    losses average agent i's terms over its active rows only; None: every agent was active in every row."""


class MultiAgentReplayBuffer(ReplayBuffer):
    """
    Replay buffer with one row per joint transition (paper, Algorithm 3): joint observation, next
    observation and action (float32), per-agent rewards and terminations (float32), time-limit
    truncations, and the selection made from the observation when the transition was stored (int16).

    Per-agent rewards are read from ``info["agent_rewards"]`` and per-agent terminations from
    ``info["agent_terminations"]`` (both written by :class:`~sb3_maddpg.envs.PettingZooToGym`).

    Memory: ``4 * (2 * obs_dim + action_dim + 2 * n_agents + 1) + 2 * n_agents * k`` bytes per row, and ``n_agents``
    more once an agent leaves mid-episode (:meth:`nbytes` tells), e.g. for 1e6 transitions of simple_spread with N=5:
    1.36 GB with full observability (obs_dim 150, action_dim 25, k=2), 1.04 GB with two observed neighbours (obs_dim 110).

    :param buffer_size: Max number of joint transitions.
    :param observation_space: The joint observation space.
    :param action_space: The joint action space.
    :param device: PyTorch device for the samples.
    :param n_envs: Number of parallel environments.
    :param optimize_memory_usage: Not supported (must be False).
    :param handle_timeout_termination: Bootstrap on time-limit truncation (SB3's ``TimeLimit.truncated``). False:
        every end of an episode, truncation included, is stored as every agent's termination (no bootstrap), as in SB3.
    :param layout: The team's agent layout (MADDPG passes it).
    :param selector: The selection rule, for schemes that use one; None otherwise.
    """

    rewards: np.ndarray
    dones: np.ndarray
    selections: np.ndarray
    next_selections: np.ndarray | None = None
    """Selections of the next step, made when stored (positions from the env's state); None otherwise (class default:
    buffers saved before it existed have none)."""
    active: np.ndarray | None = None
    """Which agents were in the episode when each transition began, allocated when an agent first leaves (bool)."""

    def __init__(
        self,
        buffer_size: int,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        device: th.device | str = "auto",
        n_envs: int = 1,
        optimize_memory_usage: bool = False,
        handle_timeout_termination: bool = True,
        layout: AgentLayout | None = None,
        selector: Selector | None = None,
    ) -> None:
        if layout is None:
            raise ValueError("MultiAgentReplayBuffer needs the team's layout: pass replay_buffer_kwargs=dict(layout=...).")
        if optimize_memory_usage:
            raise ValueError("MultiAgentReplayBuffer does not support optimize_memory_usage=True: leave it False.")
        k = selector.k if selector is not None else 0
        next_stored = selector is not None and selector.stores_next_selection(layout)
        self.planned_bytes = replay_buffer_bytes(buffer_size, n_envs, layout, k, next_selections=next_stored)
        check_replay_buffer_fits(self.planned_bytes, buffer_size, available_memory_bytes())
        super().__init__(buffer_size, observation_space, action_space, device, n_envs, False, handle_timeout_termination)
        self.layout = layout
        self.selector = selector
        n_agents = layout.n_agents
        self.rewards = np.zeros((self.buffer_size, self.n_envs, n_agents), dtype=np.float32)
        self.dones = np.zeros((self.buffer_size, self.n_envs, n_agents), dtype=np.float32)
        self.selection_size = selector.k if selector is not None else 0
        self.selections = np.zeros((self.buffer_size, self.n_envs, n_agents, self.selection_size), dtype=np.int16)
        # Positions from the env's state (in its infos, not its observations) cannot be read again at sampling: a
        # selection the target makes from the next observation is made here, when the transition is stored.
        self.next_selections = None
        self.active = None
        if selector is not None and selector.stores_next_selection(layout):
            self.next_selections = np.zeros_like(self.selections)

    def nbytes(self) -> int:
        """Bytes held by the buffer's arrays (allocated lazily by the OS until rows are written)."""
        arrays = (self.observations, self.next_observations, self.actions, self.rewards, self.dones, self.timeouts)
        extra = sum(array.nbytes for array in (self.next_selections, self.active) if array is not None)
        return int(sum(array.nbytes for array in arrays)) + int(self.selections.nbytes) + int(extra)

    def _selects_from_info_positions(self) -> bool:
        return self.selector is not None and self.selector.needs_positions and self.layout.positions_in_info

    def _info_positions(self, infos: list[dict[str, Any]], key: str) -> np.ndarray:
        try:
            return np.stack([info[key] for info in infos])
        except KeyError:
            raise KeyError(
                f"The env's info has no {key!r}, though its layout says it reports positions in its infos: build it "
                "with PettingZooToGym(parallel_env, positions=fn), which writes them at every step."
            ) from None

    def add(
        self,
        obs: np.ndarray,
        next_obs: np.ndarray,
        action: np.ndarray,
        reward: np.ndarray,
        done: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        """
        Store one joint transition per env.

        :param obs: Joint observations ``[n_envs, obs_dim]`` (unnormalised; the selection is made from them).
        :param next_obs: Joint next observations.
        :param action: Joint actions in [-1, 1].
        :param reward: Team rewards (unused: per-agent rewards come from ``infos``).
        :param done: Episode ends (termination or truncation).
        :param infos: Per-env infos with ``agent_rewards`` (and ``agent_terminations``).
        """
        pos, n_envs, handle_timeouts = self.pos, self.n_envs, self.handle_timeout_termination
        obs = np.asarray(obs).reshape(n_envs, self.obs_shape[0])
        self.observations[pos] = obs
        self.next_observations[pos] = np.asarray(next_obs).reshape(n_envs, self.obs_shape[0])
        self.actions[pos] = np.asarray(action).reshape(n_envs, self.action_dim)
        for env_index, info in enumerate(infos):
            active = info.get("agent_active")
            if active is not None and (self.active is not None or not np.all(active)):
                if self.active is None:  # the first agent that leaves: every row before had the whole team
                    self.active = np.ones((self.buffer_size, self.n_envs, self.layout.n_agents), dtype=bool)
                self.active[pos, env_index] = active
            try:
                self.rewards[pos, env_index] = info["agent_rewards"]
            except KeyError:
                raise KeyError(
                    "The env's info has no 'agent_rewards': MADDPG trains critic i on agent i's reward. Wrap the "
                    "PettingZoo env in sb3_maddpg.envs.PettingZooToGym, or put one reward per agent in info['agent_rewards']."
                ) from None
            timeout = handle_timeouts and bool(info.get("TimeLimit.truncated", False))
            terminations = info.get("agent_terminations")
            if terminations is None:
                terminations = float(done[env_index]) * (1.0 - timeout)
            elif not handle_timeouts and done[env_index]:
                terminations = 1.0  # SB3's meaning without timeout handling: every end of an episode is terminal
            self.dones[pos, env_index] = terminations
            self.timeouts[pos, env_index] = timeout
        if self._selects_from_info_positions():
            assert self.selector is not None
            self.selections[pos] = self.selector.select(
                obs, self.layout, self._info_positions(infos, "agent_positions_before")
            )
            if self.next_selections is not None:
                next_positions = self._info_positions(infos, "agent_positions")
                self.next_selections[pos] = self.selector.select(next_obs, self.layout, next_positions)
        elif self.selector is not None:
            self.selections[pos] = self.selector.select(obs, self.layout)
        self.pos += 1
        if self.pos == self.buffer_size:
            self.full = True
            self.pos = 0

    def sample(self, batch_size: int, env: VecNormalize | None = None) -> MultiAgentReplayBufferSamples:  # type: ignore[override]
        """
        Sample joint transitions uniformly (the same rows for every agent).

        :param batch_size: Number of transitions.
        :param env: The VecNormalize wrapper, to normalise observations.
        :return: The batch.
        """
        upper_bound = self.buffer_size if self.full else self.pos
        return self._get_samples(np.random.randint(0, upper_bound, size=batch_size), env=env)

    def _get_samples(self, batch_inds: np.ndarray, env: VecNormalize | None = None) -> MultiAgentReplayBufferSamples:  # type: ignore[override]
        env_indices = np.random.randint(0, high=self.n_envs, size=(len(batch_inds),))
        selections = next_selections = None
        if self.selection_size > 0:
            selections = th.as_tensor(self.selections[batch_inds, env_indices].astype(np.int64), device=self.device)
        if self.next_selections is not None:  # made when stored, from the env's positions
            chosen = self.next_selections[batch_inds, env_indices].astype(np.int64)
            next_selections = th.as_tensor(chosen, device=self.device)
        elif self.selector is not None and self.selector.target == "next":  # from the raw next observations, as stored
            chosen = self.selector.select(self.next_observations[batch_inds, env_indices], self.layout)
            next_selections = th.as_tensor(chosen, device=self.device)
        active = None if self.active is None else self.to_torch(self.active[batch_inds, env_indices].astype(np.float32))
        observations = self._normalize_obs(self.observations[batch_inds, env_indices], env)
        next_observations = self._normalize_obs(self.next_observations[batch_inds, env_indices], env)
        assert isinstance(observations, np.ndarray) and isinstance(next_observations, np.ndarray)
        return MultiAgentReplayBufferSamples(
            observations=self.to_torch(observations),
            actions=self.to_torch(self.actions[batch_inds, env_indices]),
            next_observations=self.to_torch(next_observations),
            dones=self.to_torch(self.dones[batch_inds, env_indices]),
            rewards=self.to_torch(self.rewards[batch_inds, env_indices]),
            selections=selections,
            next_selections=next_selections,
            active=active,
        )


def replay_buffer_bytes(
    buffer_size: int, n_envs: int, layout: AgentLayout, selection_size: int = 0, next_selections: bool = False
) -> int:
    """
    The bytes a :class:`MultiAgentReplayBuffer`'s arrays take once filled (what :meth:`~MultiAgentReplayBuffer.nbytes`
    reports after allocation), before any is allocated.

    :param buffer_size: Joint transitions held (all envs counted, as SB3's ``buffer_size``).
    :param n_envs: Envs stepped together (SB3 keeps ``buffer_size // n_envs`` rows of ``n_envs`` each).
    :param layout: The team's agent layout.
    :param selection_size: The selection's ``k`` (0 without one).
    :param next_selections: Whether the next step's selection is stored too (positions from the env's state).
    :return: Bytes.
    """
    rows = max(buffer_size // n_envs, 1) * n_envs
    floats = 2 * layout.obs_dim + layout.action_dim + 2 * layout.n_agents + 1  # obs, next obs, actions, r_i, d_i, timeout
    selections = 2 * layout.n_agents * selection_size * (2 if next_selections else 1)  # int16
    return rows * (4 * floats + selections)


def available_memory_bytes() -> int | None:
    """:return: The memory the system can still give (Linux's ``MemAvailable``), or ``None`` where it cannot tell."""
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


@contextlib.contextmanager
def loading_a_saved_model() -> Iterator[None]:
    """Within: a replay buffer too large for this machine is warned about, not refused (a saved model is often loaded
    only to act, and its buffer, allocated lazily, is never filled)."""
    token = _LOADING.set(True)
    try:
        yield
    finally:
        _LOADING.reset(token)


def check_replay_buffer_fits(needed: int, buffer_size: int, available: int | None) -> None:
    """
    Refuse a replay buffer larger than the memory available, and warn about one that takes over half of it: its
    arrays are allocated at once but filled over training, so without this a run fails hours later. While a saved
    model is loaded (:func:`loading_a_saved_model`) a buffer larger than the memory is warned about only.

    :param needed: The buffer's bytes (:func:`replay_buffer_bytes`).
    :param buffer_size: Its ``buffer_size``, for the message.
    :param available: The memory available (:func:`available_memory_bytes`); ``None``: no check.
    """
    if available is None or needed <= available // 2:
        return
    per_transition = needed / max(buffer_size, 1)
    fitting = max(10 ** int(math.log10(max(available // 2 / per_transition, 1))), 1)
    what = (
        f"The replay buffer would take {needed / 2**30:.1f} GiB (buffer_size={buffer_size:,} joint transitions of "
        f"{per_transition:,.0f} bytes each)"
    )
    fix = f"lower buffer_size (e.g. buffer_size={fitting:_} takes {fitting * per_transition / 2**30:.2f} GiB)"
    if needed > available and not _LOADING.get():
        raise ValueError(f"{what}, more than the {available / 2**30:.1f} GiB of memory available: {fix}.")
    if needed > available:
        message = (
            f"{what}, more than the {available / 2**30:.1f} GiB of memory available: fine to act, but training would "
            f"run out of memory; load(..., custom_objects={{'buffer_size': {fitting}}}) to train this model here."
        )
    else:
        message = (
            f"{what}, over half of the {available / 2**30:.1f} GiB of memory available; it fills as training goes: "
            f"{fix} if other work needs the memory."
        )
    warnings.warn(message, SB3MADDPGWarning, stacklevel=user_stacklevel())


def refuse_buffer_of_another_team(buffer: ReplayBuffer, layout: AgentLayout | None, selection_size: int, n_envs: int) -> None:
    """
    Refuse a replay buffer whose rows a model would misread.

    :param buffer: The buffer to check (e.g. one loaded with ``load_replay_buffer``).
    :param layout: The model's agent layout.
    :param selection_size: The model's selection size ``k`` (0 without a selection).
    :param n_envs: The model's number of envs.
    :raises TypeError: For a buffer without per-agent rewards.
    :raises ValueError: For a buffer of another layout, selection size or number of envs.
    """
    if not isinstance(buffer, MultiAgentReplayBuffer):
        raise TypeError(
            f"The replay buffer is a {type(buffer).__name__}, not a MultiAgentReplayBuffer: it has no per-agent "
            "rewards. Load a buffer saved by a MADDPG model's save_replay_buffer()."
        )
    if (buffer.layout, buffer.selection_size, buffer.n_envs) != (layout, selection_size, n_envs):
        raise ValueError(
            f"The replay buffer holds transitions of agent layout {buffer.layout} with selections of "
            f"k={buffer.selection_size} from {buffer.n_envs} env(s), but this model has agent layout "
            f"{layout} with k={selection_size} and {n_envs} env(s): load a buffer saved by a model of the same "
            "team (same agents, sizes and order), the same selection size and the same number of envs."
        )
