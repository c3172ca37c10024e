"""The selections of ``selected`` sharing made on the device, for observations that never leave it."""

import torch as th

from sb3_maddpg.layout import AgentLayout
from sb3_maddpg.selection import FixedGraph, NearestAgents, Selector


def select_on_device(selector: Selector, observations: th.Tensor, layout: AgentLayout) -> th.Tensor:
    """
    What ``selector.select`` returns, computed where ``observations`` are: the built-in rules (:class:`NearestAgents`,
    :class:`FixedGraph`) in torch; any other selector on the host (a copy there and back, each call).

    :param selector: The selection rule.
    :param observations: Joint observations ``[..., obs_dim]``.
    :param layout: The team's agent layout.
    :return: Selected agent indices, int64 ``[..., n_agents, k]``.
    """
    lead = observations.shape[:-1]
    if isinstance(selector, NearestAgents):
        positions = th.stack([observations[..., part][..., selector.position_slice] for part in layout.obs_slices], dim=-2)
        offsets = positions.unsqueeze(-2) - positions.unsqueeze(-3)
        distances = (offsets * offsets).sum(dim=-1)
        # An agent never selects itself; ties go to the lower index (a stable sort), as NearestAgents.
        own = th.eye(layout.n_agents, dtype=th.bool, device=observations.device)
        distances = distances.masked_fill(own, float("inf"))
        return th.argsort(distances, dim=-1, stable=True)[..., : selector.k]
    if isinstance(selector, FixedGraph):
        table = th.as_tensor(selector.neighbors, dtype=th.long, device=observations.device)
        return table.expand(*lead, *table.shape)
    flat = observations.detach().reshape(-1, observations.shape[-1]).cpu().numpy()
    selection = th.as_tensor(selector.select(flat, layout), device=observations.device)
    return selection.reshape(*lead, layout.n_agents, selector.k)
