"""One optimiser step of a team's actors or critics, and the Polyak update of its targets."""

import functools
from collections.abc import Callable, Sequence

import torch as th

from sb3_maddpg.common.policies import MultiAgentActor, MultiAgentCritic


def gradient_step(module: MultiAgentActor | MultiAgentCritic, loss: th.Tensor, max_grad_norm: float | None) -> None:
    """
    One step of ``module.optimizer`` on ``loss``, each agent's gradient clipped to ``max_grad_norm`` on its own (as if
    each agent had an optimiser of its own).

    Only ``module``'s own gradients are computed (``torch.autograd.grad``): the actors' loss runs through the critics,
    whose gradients that step would otherwise compute for nothing.

    :param module: The team's actors or critics.
    :param loss: The sum of its agents' losses.
    :param max_grad_norm: The largest norm of each agent's gradient, or None for no clipping.
    """
    clip = None if max_grad_norm is None else functools.partial(module.clip_grad_norm_per_agent, max_grad_norm)
    optimiser_step(list(module.parameters()), module.optimizer, loss, clip)


def optimiser_step(
    params: Sequence[th.Tensor], optimizer: th.optim.Optimizer, loss: th.Tensor, clip: Callable[[], None] | None
) -> None:
    """
    One step of ``optimizer`` on ``loss``, the gradients of ``params`` only (clipped by ``clip`` before the step).

    :param params: The parameters the step moves.
    :param optimizer: Their optimiser.
    :param loss: The loss.
    :param clip: Clips the gradients in place (per agent, or per run and agent), or None.
    """
    optimizer.zero_grad()
    # allow_unused: a parameter outside this loss's graph keeps no gradient, as backward() would leave it.
    for param, grad in zip(params, th.autograd.grad(loss, list(params), allow_unused=True)):
        param.grad = grad
    if clip is not None:
        clip()
    optimizer.step()


def polyak_update_foreach(params: Sequence[th.Tensor], targets: Sequence[th.Tensor], tau: float) -> None:
    """
    ``target = (1 - tau) * target + tau * param`` for every pair, in two multi-tensor operations (SB3's
    ``polyak_update`` does the same arithmetic in two operations per pair).

    :param params: The trained parameters.
    :param targets: Their targets, in the same order.
    :param tau: The Polyak coefficient.
    """
    if len(params) != len(targets):
        raise ValueError(f"{len(params)} parameters but {len(targets)} targets: pair each parameter with its target.")
    with th.no_grad():
        th._foreach_mul_(list(targets), 1.0 - tau)
        th._foreach_add_(list(targets), list(params), alpha=tau)
