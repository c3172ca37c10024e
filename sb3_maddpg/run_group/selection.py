"""The selections of ``selected`` sharing made on the device, for observations that never leave it."""

import torch as th

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.selection import FixedGraph, NearestAgents, Selector, nearest_agents


class DeviceSelector:
    """
    What ``selector.select`` returns, computed where the observations are: the built-in rules in torch
    (:class:`NearestAgents` by the host's own rule, :func:`~sb3_maddpg.common.selection.nearest_agents`, written once
    against the array API; :class:`FixedGraph`'s table made on the device once); any other selector on the host (a
    copy there and back, each call).

    :param selector: The selection rule.
    :param layout: The team's agent layout.
    :param device: Where the observations are.
    """

    def __init__(self, selector: Selector, layout: AgentLayout, device: th.device | str) -> None:
        self.selector = selector
        self.layout = layout
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
            return nearest_agents(layout.positions(observations, slices), selector.k)  # the host's rule, in torch
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
