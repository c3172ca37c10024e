"""The replay buffers of ``R`` runs on one device, as tensors ``[R, capacity, ...]``; each run samples its own rows.

A run's next observations are not stored beside its observations: a run's worlds step together, so a row's next
observation is the row one step later (``n`` rows on, ``n`` the rows added per step), except at an episode's last
step, whose next observations (the episodes' last, not the reset's) are kept apart, and at the newest step, whose
successor is not stored yet. That keeps the buffers at about half the memory (and a group's state file at about
half the disk) of storing both, with the same transitions.
"""

from typing import Any

import torch as th

from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.run_group.streams import RunStreams

ROW_FIELDS = ("observations", "actions", "rewards", "dones", "selections")
"""The tensors with one row per transition (``[R, capacity, ...]``)."""


def buffer_capacity(buffer_size: int, worlds: int) -> int:
    """
    :param buffer_size: A model's ``buffer_size`` (transitions).
    :param worlds: Its worlds per run (transitions per step).
    :return: The transitions a group's buffers keep per run: whole steps, at least one.
    """
    return max(worlds, buffer_size // worlds * worlds)


def final_slots(steps: int, episode_length: int) -> int:
    """
    :param steps: Steps the buffers hold (capacity / rows per step).
    :param episode_length: The fewest steps an episode has.
    :return: Slots for episodes' last next observations: enough for every episode end among ``steps`` steps.
    """
    return steps // episode_length + 2


def replay_nbytes(
    n_runs: int,
    capacity: int,
    obs_dim: int,
    action_dim: int,
    n_agents: int,
    rows_per_step: int,
    episode_length: int,
    selection_size: int = 0,
) -> int:
    """
    :param n_runs: Number of runs ``R``.
    :param capacity: Transitions each run keeps.
    :param obs_dim: Joint observation size.
    :param action_dim: Joint action size.
    :param n_agents: Number of agents.
    :param rows_per_step: Rows each step adds (the worlds per run).
    :param episode_length: The fewest steps between two episode ends.
    :param selection_size: ``k`` selected agents per agent (0: no selections stored).
    :return: The bytes :class:`RunReplayBuffers` of these sizes hold on their device (float32, int16 selections).
    """
    steps = capacity // rows_per_step
    floats = n_runs * (capacity * (obs_dim + action_dim + 2 * n_agents) + rows_per_step * obs_dim)
    floats += n_runs * final_slots(steps, episode_length) * rows_per_step * obs_dim
    return 4 * floats + 2 * n_runs * capacity * n_agents * selection_size + 8 * steps


class RunReplayBuffers:
    """
    One replay buffer per run, held together on ``device``: one row per joint transition, as
    :class:`~sb3_maddpg.common.buffers.MultiAgentReplayBuffer` (joint observations, actions and next observations, per-agent
    rewards and terminations, the selections made when a transition was stored). All runs are written together,
    ``rows_per_step`` rows at a time (one per world), so they share one write position; each run samples its rows
    from its own generator, uniformly over what it holds, so its batches depend on its seed only.

    Next observations are the next step's rows (see the module docstring): the caller's contract is that a step that
    does not end the episodes (``episode_end=False``) has as next observations the next step's observations, as the
    run group's worlds give them.

    :param n_runs: Number of runs ``R``.
    :param capacity: Transitions each run keeps (the oldest are overwritten); a multiple of ``rows_per_step``.
    :param obs_dim: Joint observation size.
    :param action_dim: Joint action size.
    :param n_agents: Number of agents.
    :param selection_size: ``k`` selected agents per agent (0: no selections stored).
    :param device: Where the buffers live.
    :param rows_per_step: Rows each :meth:`add` writes (the worlds per run).
    :param episode_length: The fewest steps between two episode ends (simple_spread's ``max_cycles``): it sizes the
        store of the episodes' last next observations.
    """

    def __init__(
        self,
        n_runs: int,
        capacity: int,
        obs_dim: int,
        action_dim: int,
        n_agents: int,
        selection_size: int = 0,
        device: th.device | str = "cpu",
        *,
        rows_per_step: int,
        episode_length: int,
    ) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be at least 1 transition, got {capacity}.")
        if rows_per_step < 1 or capacity % rows_per_step:
            raise ValueError(
                f"capacity ({capacity}) must be a multiple of rows_per_step ({rows_per_step}, the rows of one step): "
                "the buffers hold whole steps."
            )
        if episode_length < 1:
            raise ValueError(f"episode_length must be at least 1 step, got {episode_length}.")
        self.n_runs = n_runs
        self.capacity = capacity
        self.rows_per_step = rows_per_step
        self.episode_length = episode_length
        self.steps = capacity // rows_per_step
        """Steps each run holds when full."""
        self.device = th.device(device)
        shape = (n_runs, capacity)
        self.observations = th.zeros((*shape, obs_dim), device=device)
        self.actions = th.zeros((*shape, action_dim), device=device)
        self.rewards = th.zeros((*shape, n_agents), device=device)
        self.dones = th.zeros((*shape, n_agents), device=device)
        # int16 as MultiAgentReplayBuffer; the critics read int64 (converted per sampled batch only).
        self.selections = th.zeros((*shape, n_agents, selection_size), dtype=th.int16, device=device)
        self.selection_size = selection_size
        n_final = final_slots(self.steps, episode_length)
        self.final_observations = th.zeros((n_runs, n_final, rows_per_step, obs_dim), device=device)
        """The next observations of steps that ended the episodes."""
        self.final_slot = th.full((self.steps,), -1, dtype=th.long, device=device)
        """Each stored step's slot in :attr:`final_observations`, -1 for a step that did not end the episodes."""
        self.newest_next_observations = th.zeros((n_runs, rows_per_step, obs_dim), device=device)
        """The newest step's next observations (its successor's rows are not written yet)."""
        self.pos = 0
        self.size = 0
        """Transitions each run holds."""
        # The counters sampling reads, on the device: no host value that changes per step in the kernels' arguments.
        self.filled = th.zeros((), dtype=th.long, device=device)
        """:attr:`size`, on the device."""
        self.newest_step = th.full((), -1, dtype=th.long, device=device)
        """The step slot written last, on the device (its next observations are :attr:`newest_next_observations`)."""
        self._runs = th.arange(n_runs, device=device).unsqueeze(1)
        self.finals_written = 0
        """Episode ends stored so far (the next one goes to slot ``finals_written % n_final``)."""
        # Host-side copies for the check that no episode end overwrites one still held (no device sync per step).
        self._final_owner = [-1] * n_final
        self._final_slot_host = [-1] * self.steps

    def nbytes(self) -> int:
        """Bytes held by the buffers (on their device)."""
        tensors = [getattr(self, name) for name in ROW_FIELDS]
        tensors += [self.final_observations, self.final_slot, self.newest_next_observations]
        return sum(tensor.numel() * tensor.element_size() for tensor in tensors)

    def add(
        self,
        observations: th.Tensor,
        actions: th.Tensor,
        next_observations: th.Tensor,
        rewards: th.Tensor,
        dones: th.Tensor,
        selections: th.Tensor | None = None,
        episode_end: bool = False,
    ) -> None:
        """
        Store one step of every run's worlds: ``n = rows_per_step`` joint transitions per run.

        :param observations: ``[R, n, obs_dim]``.
        :param actions: Joint actions in [-1, 1], ``[R, n, action_dim]``.
        :param next_observations: ``[R, n, obs_dim]``: the episodes' last observations when the step ends them, else
            the next step's observations.
        :param rewards: Per-agent rewards, ``[R, n, n_agents]``.
        :param dones: Per-agent true terminations (a truncation is 0: it bootstraps), ``[R, n, n_agents]``.
        :param selections: Selected agents, ``[R, n, n_agents, k]``, when the buffers store them.
        :param episode_end: Whether this step ends the episodes (of every world: they step together).
        """
        n = observations.shape[1]
        if n != self.rows_per_step:
            raise ValueError(
                f"These buffers take {self.rows_per_step} transitions per run at a time, got {n}: add one step of "
                f"every world at once (rows_per_step={self.rows_per_step} rows per run)."
            )
        if self.selection_size > 0 and selections is None:
            raise ValueError("These buffers store selections (selection_size > 0): pass the transitions' selections.")
        step = self.pos // n
        slot = self._free_final_slot(step) if episode_end else -1  # checked before anything is written
        rows = slice(self.pos, self.pos + n)
        self.observations[:, rows] = observations
        self.actions[:, rows] = actions
        self.rewards[:, rows] = rewards
        self.dones[:, rows] = dones
        if selections is not None and self.selection_size > 0:
            self.selections[:, rows] = selections.to(th.int16)
        self.newest_next_observations.copy_(next_observations)
        if episode_end:
            self.final_observations[:, slot] = next_observations
            self._final_owner[slot] = step
            self.finals_written += 1
        self.final_slot[step] = slot
        self._final_slot_host[step] = slot
        self.newest_step.fill_(step)
        self.pos = (self.pos + n) % self.capacity
        if self.size < self.capacity:
            self.size = min(self.size + n, self.capacity)
            self.filled.fill_(self.size)

    def _free_final_slot(self, step: int) -> int:
        """
        :param step: The step slot about to be written, whose step ends the episodes.
        :return: The slot of :attr:`final_observations` its next observations go to (the next in turn).
        :raise ValueError: When that slot still holds a held step's (episodes shorter than ``episode_length``).
        """
        slot = self.finals_written % len(self._final_owner)
        owner = self._final_owner[slot]
        # The slot's last owner must have been overwritten since (or be this very step slot, being rewritten now).
        if owner >= 0 and owner != step and self._final_slot_host[owner] == slot:
            raise ValueError(
                f"Episodes end more often than every {self.episode_length} steps: build the buffers with the "
                "episodes' real (shortest) length as episode_length."
            )
        return slot

    def sample_rows(self, batch_size: int, streams: RunStreams) -> th.Tensor:
        """
        :param batch_size: Transitions per run.
        :param streams: The runs' random streams, on the buffers' device.
        :return: Rows drawn uniformly from what each run holds, run r's from its own stream, ``[R, batch_size]``.
        """
        self.check_sample(streams)
        return streams.integers(self.filled, (batch_size,))

    def check_sample(self, streams: RunStreams) -> None:
        """
        :param streams: The runs' random streams.
        :raise ValueError: When the buffers cannot be sampled with them (empty; another number of runs).
        """
        if self.size == 0:
            raise ValueError("The replay buffers are empty: add transitions before sampling.")
        if streams.n_runs != self.n_runs:
            raise ValueError(f"Need one random stream per run ({self.n_runs}), got {streams.n_runs}.")

    def draw(self, batch_size: int, streams: RunStreams) -> MultiAgentReplayBufferSamples:
        """
        :meth:`sample` without its checks (:meth:`check_sample`, made before): what a compiled step runs, reading no
        Python value that changes as the buffers fill.

        :param batch_size: Transitions per run.
        :param streams: The runs' random streams, on the buffers' device.
        :return: Each run's batch, ``[R, batch_size, ...]`` each field.
        """
        return self.get(streams.integers(self.filled, (batch_size,)))

    def next_observations_of(self, rows: th.Tensor) -> th.Tensor:
        """
        :param rows: Row indices per run, ``[R, batch]``.
        :return: Their transitions' next observations, ``[R, batch, obs_dim]``.
        """
        runs = self._runs
        step, world = rows // self.rows_per_step, rows % self.rows_per_step
        following = self.observations[runs, (rows + self.rows_per_step) % self.capacity]
        newest = self.newest_next_observations[runs, world]
        following = th.where((step == self.newest_step).unsqueeze(-1), newest, following)
        slot = self.final_slot[step]
        final = self.final_observations[runs, slot.clamp(min=0), world]
        return th.where((slot >= 0).unsqueeze(-1), final, following)

    def get(self, rows: th.Tensor) -> MultiAgentReplayBufferSamples:
        """
        :param rows: Row indices per run, ``[R, batch]``.
        :return: Those transitions, ``[R, batch, ...]`` each field (selections as int64, or None when not stored).
        """
        runs = self._runs
        selections = self.selections[runs, rows].long() if self.selection_size > 0 else None
        return MultiAgentReplayBufferSamples(
            observations=self.observations[runs, rows],
            actions=self.actions[runs, rows],
            next_observations=self.next_observations_of(rows),
            dones=self.dones[runs, rows],
            rewards=self.rewards[runs, rows],
            selections=selections,
        )

    def sample(self, batch_size: int, streams: RunStreams) -> MultiAgentReplayBufferSamples:
        """
        :param batch_size: Transitions per run.
        :param streams: The runs' random streams, on the buffers' device.
        :return: Each run's batch, ``[R, batch_size, ...]`` each field.
        """
        self.check_sample(streams)
        return self.draw(batch_size, streams)

    # ----- save and resume -----

    def state_dict(self, copy: bool = True) -> dict[str, Any]:
        """
        :param copy: Copy the filled rows (on the device). ``False``, to ``torch.save`` the state at once: full
            buffers are the buffers' own tensors (no second copy on the device) and partly filled ones' rows are
            copied to host memory; such a state changes as the buffers are written on.
        :return: What :meth:`load_state_dict` continues from: the filled rows, the episodes' last observations, the
            newest step's next observations and the write position.
        """
        return {
            "pos": self.pos,
            "size": self.size,
            "finals_written": self.finals_written,
            "final_owner": list(self._final_owner),
            **{name: _filled_rows(getattr(self, name), self.size, copy) for name in ROW_FIELDS},
            **{
                name: getattr(self, name).clone() if copy else getattr(self, name)
                for name in ("final_observations", "final_slot", "newest_next_observations")
            },
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """:param state: A state of :meth:`state_dict`, of buffers of the same sizes (its tensors on any device)."""
        for name in ("final_observations", "final_slot", "newest_next_observations"):
            if tuple(state[name].shape) != tuple(getattr(self, name).shape):
                raise ValueError(
                    f"This buffers' state has {name} of shape {tuple(state[name].shape)}, these buffers "
                    f"{tuple(getattr(self, name).shape)}: load a state of buffers of the same runs, capacity, worlds "
                    "and episode length."
                )
        filled = int(state["size"])
        for name in ROW_FIELDS:
            getattr(self, name)[:, :filled] = state[name].to(self.device)
        for name in ("final_observations", "final_slot", "newest_next_observations"):
            getattr(self, name).copy_(state[name].to(self.device))
        self.pos, self.size, self.finals_written = int(state["pos"]), filled, int(state["finals_written"])
        self.filled.fill_(filled)
        self.newest_step.fill_((self.pos // self.rows_per_step - 1) % self.steps)
        self._final_owner = [int(owner) for owner in state["final_owner"]]
        self._final_slot_host = [int(slot) for slot in self.final_slot.tolist()]


def _filled_rows(tensor: th.Tensor, filled: int, copy: bool) -> th.Tensor:
    """:return: A buffer's first ``filled`` rows (along dim 1), as a tensor of their own unless ``copy`` is ``False``."""
    if copy:
        return tensor[:, :filled].clone()
    if filled == tensor.shape[1]:
        return tensor  # full: torch.save writes the tensor itself
    # A view would make torch.save write the whole storage: the rows alone, copied to the host (not the device).
    return tensor[:, :filled].clone() if tensor.device.type == "cpu" else tensor[:, :filled].cpu()
