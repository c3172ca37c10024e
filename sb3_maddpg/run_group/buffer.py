"""The replay buffers of ``R`` runs on one device, as tensors ``[R, capacity, ...]``; each run samples its own rows."""

from collections.abc import Sequence

import torch as th

from sb3_maddpg.buffers import MultiAgentReplayBufferSamples


class RunReplayBuffers:
    """
    One replay buffer per run, held together on ``device``: one row per joint transition, as
    :class:`~sb3_maddpg.buffers.MultiAgentReplayBuffer` (joint observations, actions and next observations, per-agent
    rewards and terminations, the selections made when a transition was stored). All runs are written together, the
    same number of rows at a time, so they share one write position; each run samples its rows from its own
    generator, uniformly over what it holds, so its batches depend on its seed only.

    :param n_runs: Number of runs ``R``.
    :param capacity: Transitions each run keeps (the oldest are overwritten).
    :param obs_dim: Joint observation size.
    :param action_dim: Joint action size.
    :param n_agents: Number of agents.
    :param selection_size: ``k`` selected agents per agent (0: no selections stored).
    :param device: Where the buffers live.
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
    ) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be at least 1 transition, got {capacity}.")
        self.n_runs = n_runs
        self.capacity = capacity
        self.device = th.device(device)
        shape = (n_runs, capacity)
        self.observations = th.zeros((*shape, obs_dim), device=device)
        self.actions = th.zeros((*shape, action_dim), device=device)
        self.next_observations = th.zeros((*shape, obs_dim), device=device)
        self.rewards = th.zeros((*shape, n_agents), device=device)
        self.dones = th.zeros((*shape, n_agents), device=device)
        # int16 as MultiAgentReplayBuffer; the critics read int64 (converted per sampled batch only).
        self.selections = th.zeros((*shape, n_agents, selection_size), dtype=th.int16, device=device)
        self.selection_size = selection_size
        self.pos = 0
        self.size = 0
        """Transitions each run holds."""

    def nbytes(self) -> int:
        """Bytes held by the buffers (on their device)."""
        tensors = (self.observations, self.actions, self.next_observations, self.rewards, self.dones, self.selections)
        return sum(tensor.numel() * tensor.element_size() for tensor in tensors)

    def add(
        self,
        observations: th.Tensor,
        actions: th.Tensor,
        next_observations: th.Tensor,
        rewards: th.Tensor,
        dones: th.Tensor,
        selections: th.Tensor | None = None,
    ) -> None:
        """
        Store ``n`` joint transitions per run (e.g. one per world).

        :param observations: ``[R, n, obs_dim]``.
        :param actions: Joint actions in [-1, 1], ``[R, n, action_dim]``.
        :param next_observations: ``[R, n, obs_dim]``.
        :param rewards: Per-agent rewards, ``[R, n, n_agents]``.
        :param dones: Per-agent true terminations (a truncation is 0: it bootstraps), ``[R, n, n_agents]``.
        :param selections: Selected agents, ``[R, n, n_agents, k]``, when the buffers store them.
        """
        n = observations.shape[1]
        if n > self.capacity:
            raise ValueError(f"Cannot add {n} transitions per run at once to buffers of capacity {self.capacity}.")
        rows = (th.arange(n, device=self.device) + self.pos) % self.capacity
        self.observations[:, rows] = observations
        self.actions[:, rows] = actions
        self.next_observations[:, rows] = next_observations
        self.rewards[:, rows] = rewards
        self.dones[:, rows] = dones
        if self.selection_size > 0:
            if selections is None:
                raise ValueError("These buffers store selections (selection_size > 0): pass the transitions' selections.")
            self.selections[:, rows] = selections.to(th.int16)
        self.pos = (self.pos + n) % self.capacity
        self.size = min(self.size + n, self.capacity)

    def sample_rows(self, batch_size: int, generators: Sequence[th.Generator]) -> th.Tensor:
        """
        :param batch_size: Transitions per run.
        :param generators: One generator per run, on the buffers' device.
        :return: Rows drawn uniformly from what each run holds, run r's from ``generators[r]``, ``[R, batch_size]``.
        """
        if self.size == 0:
            raise ValueError("The replay buffers are empty: add transitions before sampling.")
        if len(generators) != self.n_runs:
            raise ValueError(f"Need one generator per run ({self.n_runs}), got {len(generators)}.")
        return th.stack(
            [th.randint(0, self.size, (batch_size,), generator=g, device=self.device) for g in generators]  # own stream
        )

    def get(self, rows: th.Tensor) -> MultiAgentReplayBufferSamples:
        """
        :param rows: Row indices per run, ``[R, batch]``.
        :return: Those transitions, ``[R, batch, ...]`` each field (selections as int64, or None when not stored).
        """
        runs = th.arange(self.n_runs, device=self.device).unsqueeze(1)
        selections = self.selections[runs, rows].long() if self.selection_size > 0 else None
        return MultiAgentReplayBufferSamples(
            observations=self.observations[runs, rows],
            actions=self.actions[runs, rows],
            next_observations=self.next_observations[runs, rows],
            dones=self.dones[runs, rows],
            rewards=self.rewards[runs, rows],
            selections=selections,
        )

    def sample(self, batch_size: int, generators: Sequence[th.Generator]) -> MultiAgentReplayBufferSamples:
        """
        :param batch_size: Transitions per run.
        :param generators: One generator per run, on the buffers' device.
        :return: Each run's batch, ``[R, batch_size, ...]`` each field.
        """
        return self.get(self.sample_rows(batch_size, generators))
