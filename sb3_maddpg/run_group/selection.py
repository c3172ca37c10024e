"""The selections of ``selected`` sharing made on the device, for observations that never leave it."""

import torch as th

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.selection import FixedGraph, NearestAgents, Selector


class DeviceSelector:
    """
    What ``selector.select`` returns, computed where the observations are: the built-in rules (:class:`NearestAgents`,
    :class:`FixedGraph`) in torch, their tables made on the device once; any other selector on the host (a copy there
    and back, each call).

    :param selector: The selection rule.
    :param layout: The team's agent layout.
    :param device: Where the observations are.
    """

    def __init__(self, selector: Selector, layout: AgentLayout, device: th.device | str) -> None:
        self.selector = selector
        self.layout = layout
        self._own = th.eye(layout.n_agents, dtype=th.bool, device=device)
        self._table = (
            th.as_tensor(selector.neighbors, dtype=th.long, device=device) if isinstance(selector, FixedGraph) else None
        )

    def __call__(self, observations: th.Tensor) -> th.Tensor:
        """
        :param observations: Joint observations ``[..., obs_dim]``.
        :return: Selected agent indices, int64 ``[..., n_agents, k]``.
        """
        selector, layout, lead = self.selector, self.layout, observations.shape[:-1]
        if isinstance(selector, NearestAgents):
            slices = selector.position_slices(layout)
            if slices is None:
                raise ValueError(
                    "This env reports its agents' positions in its infos, not its observations: a run group selects "
                    "on the device from observations; train such an env's runs one by one (MADDPG.learn)."
                )
            parts = [observations[..., part][..., where] for part, where in zip(layout.obs_slices, slices)]
            positions = th.stack(parts, dim=-2)
            offsets = positions.unsqueeze(-2) - positions.unsqueeze(-3)
            distances = (offsets * offsets).sum(dim=-1)
            # An agent never selects itself; ties go to the lower index (a stable sort), as NearestAgents.
            distances = distances.masked_fill(self._own, float("inf"))
            return th.argsort(distances, dim=-1, stable=True)[..., : selector.k]
        if self._table is not None:
            return self._table.expand(*lead, *self._table.shape)
        flat = observations.detach().reshape(-1, observations.shape[-1]).cpu().numpy()
        selection = th.as_tensor(selector.select(flat, layout), device=observations.device)
        return selection.reshape(*lead, layout.n_agents, selector.k)


def select_on_device(selector: Selector, observations: th.Tensor, layout: AgentLayout) -> th.Tensor:
    """
    :param selector: The selection rule.
    :param observations: Joint observations ``[..., obs_dim]``.
    :param layout: The team's agent layout.
    :return: What ``selector.select`` returns, computed where ``observations`` are (:class:`DeviceSelector`, once).
    """
    return DeviceSelector(selector, layout, observations.device)(observations)
