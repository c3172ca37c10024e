"""
simple_spread's worlds as torch tensors on any device: :class:`~sb3_maddpg.envs.simple_spread_worlds.SimpleSpreadWorlds`'
rules, new episodes from a torch generator or from draws the caller makes.

The one module of :mod:`sb3_maddpg.envs` that imports torch: import it from here
(``from sb3_maddpg.envs.torch_spread_worlds import TorchSpreadWorlds``); the env package itself does not.
"""

from typing import Any

import torch as th

from sb3_maddpg.envs.simple_spread_worlds import DIM_P, SpreadWorldRules


class TorchSpreadWorlds(SpreadWorldRules[th.Tensor]):
    """
    The state of ``n_worlds`` simple_spread worlds as torch tensors on ``device``, and mpe2's rules on them: the same
    physics, observations, per-agent rewards and metrics as :class:`~sb3_maddpg.envs.simple_spread_worlds.SimpleSpreadWorlds`
    (one implementation of the rules, run by torch through the array API), so that a trainer can keep the worlds
    on its GPU and step them without a copy to the host.

    The worlds lie on the first axis: ``R`` runs of ``E`` worlds each are ``n_worlds = R * E`` worlds, run ``r`` the
    ``r``-th block of ``E``. New episodes (:meth:`reset`) are drawn from a ``torch.Generator`` or from uniform draws
    the caller makes (a run group: each run's block from its own stream), from the distribution mpe2 draws them from
    (positions uniform in [-1, 1], agents and landmarks, velocities zero), but not from mpe2's seed stream:
    replaying mpe2's seeds is :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`'s job.
    Truncation after ``max_cycles`` steps is the caller's: every world's episode has the same length, so a caller
    counts steps and calls :meth:`reset` for all worlds at once.

    In float64 (the default) it computes what the numpy worlds compute, to rounding (torch's ``logaddexp`` differs
    from numpy's in the last bit: about 1e-15 after one step, 1e-13 after 25 on a CPU); float32 is lighter and
    faster (1.3x float64 with 1000 worlds on a CPU core) and is no longer mpe2's arithmetic.

    :param n_worlds: Number of worlds (all runs together).
    :param n_agents: Agents (and landmarks) per world.
    :param num_agent_neighbors: Nearest other agents each agent observes (``None``: all), as mpe2's.
    :param num_landmark_neighbors: Nearest landmarks each agent observes (``None``: all), as mpe2's.
    :param local_ratio: Weight of the local collision penalty against the shared distance reward.
    :param device: Where the state lives (and every rule runs).
    :param dtype: The state's floating dtype.
    """

    def __init__(
        self,
        n_worlds: int,
        n_agents: int,
        num_agent_neighbors: int | None = None,
        num_landmark_neighbors: int | None = None,
        local_ratio: float = 0.5,
        device: th.device | str = "cpu",
        dtype: th.dtype = th.float64,
    ) -> None:
        if not dtype.is_floating_point:
            raise ValueError(f"dtype must be a floating dtype (th.float64 for mpe2's arithmetic), got {dtype}.")
        agent_pos = th.zeros((n_worlds, n_agents, DIM_P), dtype=dtype, device=device)
        super().__init__(n_worlds, n_agents, num_agent_neighbors, num_landmark_neighbors, local_ratio, agent_pos)

    @property
    def device(self) -> th.device:
        """Where the state lives."""
        return self.agent_pos.device

    @property
    def dtype(self) -> th.dtype:
        """The state's floating dtype."""
        return self.agent_pos.dtype

    def reset(self, source: th.Generator | th.Tensor) -> None:
        """
        New episodes in every world, drawn as mpe2's ``Scenario.reset_world`` draws them: each world's agents, then
        its landmarks, uniform in [-1, 1] per coordinate; velocities zero.

        :param source: A generator on the worlds' device type, or the draws themselves: uniform numbers in [0, 1),
            ``[n_worlds, 2 * n_agents, 2]`` on the worlds' device (e.g. each run's block of worlds from its own stream,
            :class:`~sb3_maddpg.run_group.streams.RunStreams`).
        """
        shape = (self.n_worlds, 2 * self.n_agents, DIM_P)
        if isinstance(source, th.Generator):
            if source.device.type != self.device.type:
                raise ValueError(
                    f"A generator on {source.device} cannot draw on {self.device}: make it with "
                    f"th.Generator(device={str(self.device)!r}).manual_seed(seed)."
                )
            source = th.rand(shape, generator=source, dtype=self.dtype, device=self.device)
        elif tuple(source.shape) != shape or source.device != self.device:
            raise ValueError(
                f"The draws must be uniform numbers of shape {shape} (n_worlds, 2 * n_agents, 2) on {self.device}, "
                f"got shape {tuple(source.shape)} on {source.device}."
            )
        positions = source * 2 - 1  # numpy's uniform(-1, 1): low + (high - low) * u
        self.agent_pos = positions[:, : self.n_agents].contiguous()
        self.landmark_pos = positions[:, self.n_agents :].contiguous()
        self.agent_vel = th.zeros_like(self.agent_pos)

    def set_state(self, agent_pos: Any, agent_vel: Any, landmark_pos: Any) -> None:
        """
        Copy a state in (e.g. the numpy worlds', to step both from the same start).

        :param agent_pos: ``[n_worlds, n_agents, 2]``, any array torch reads (a numpy array, a tensor).
        :param agent_vel: ``[n_worlds, n_agents, 2]``.
        :param landmark_pos: ``[n_worlds, n_agents, 2]``.
        """
        shape = (self.n_worlds, self.n_agents, DIM_P)
        state = [
            th.as_tensor(array, dtype=self.dtype, device=self.device).clone() for array in (agent_pos, agent_vel, landmark_pos)
        ]
        for name, array in zip(("agent_pos", "agent_vel", "landmark_pos"), state):
            if tuple(array.shape) != shape:
                raise ValueError(f"{name} must have shape {shape} (n_worlds, n_agents, 2), got {tuple(array.shape)}.")
        self.agent_pos, self.agent_vel, self.landmark_pos = state
