"""
The networks of ``R`` teams stacked along a run dimension: every parameter of R copies of one module as one tensor
``[R, ...]``, evaluated for every run at once with ``torch.func.vmap`` over ``functional_call``.

The modules themselves are the package's (:class:`~sb3_maddpg.policies.MultiAgentActor`,
:class:`~sb3_maddpg.policies.MultiAgentCritic`), so their forward passes are not copied; only their parameters are
stacked. Run r's outputs depend on run r's parameters and inputs only, and its gradients land in slice ``[r]``.
"""

import copy
from collections.abc import Callable, Sequence
from typing import Any

import torch as th
from torch import nn
from torch.func import functional_call, vmap

from sb3_maddpg.networks import clip_coefficients
from sb3_maddpg.policies import MultiAgentActor, MultiAgentCritic


class _Method(nn.Module):
    """Calls one method of a module as ``forward``: ``functional_call`` calls only ``forward``."""

    def __init__(self, module: nn.Module, method: str) -> None:
        super().__init__()
        self.module = module
        self.method = method

    def forward(self, *args: Any) -> Any:
        return getattr(self.module, self.method)(*args)


class StackedModule:
    """
    ``R`` copies of one module's parameters, stacked along a leading run dimension, on ``device``.

    The template (a copy of the first module) keeps the buffers (e.g. a fixed scheme's gather indices), which the
    runs share: they come from the layout, which every run has in common.

    :param modules: One module per run, all of the same architecture.
    :param device: Where the stacked parameters live.
    :param requires_grad: Whether the stacked parameters train (False for target networks).
    """

    def __init__(self, modules: Sequence[nn.Module], device: th.device | str, requires_grad: bool) -> None:
        self.template = copy.deepcopy(modules[0]).to(device)
        self.names = [name for name, _ in modules[0].named_parameters()]
        self.params: dict[str, th.Tensor] = {}
        """Each parameter of every run, ``[R, *shape]``, in the module's ``named_parameters`` order."""
        for name in self.names:
            stacked = th.stack([module.get_parameter(name).detach() for module in modules]).to(device)
            self.params[name] = stacked.requires_grad_(requires_grad)
        self._calls: dict[tuple[str, tuple[int | None, ...]], Callable[..., Any]] = {}

    @property
    def n_runs(self) -> int:
        """The number of runs ``R``."""
        return next(iter(self.params.values())).shape[0]

    def parameters(self) -> list[th.Tensor]:
        """:return: The stacked parameters, in the module's order."""
        return [self.params[name] for name in self.names]

    def call(self, method: str, *args: th.Tensor | None) -> Any:
        """
        The module's ``method`` for every run at once.

        :param method: The method's name (``"forward"``, ``"forward_with_preactivation"``...).
        :param args: Its arguments with the run dimension in front, or None (passed to every run as None).
        :return: What the method returns, with the run dimension in front.
        """
        in_dims = tuple(None if arg is None else 0 for arg in args)
        key = (method, in_dims)
        if key not in self._calls:
            wrapper = _Method(self.template, method)

            def run(params: dict[str, th.Tensor], *run_args: th.Tensor | None) -> Any:
                return functional_call(wrapper, {f"module.{name}": value for name, value in params.items()}, run_args)

            self._calls[key] = vmap(run, in_dims=(0, *in_dims))
        return self._calls[key](self.params, *args)

    def load_into(self, run: int, module: nn.Module) -> None:
        """
        Copy run ``run``'s parameters into a module of the same architecture (in place, keeping its tensors).

        :param run: The run.
        :param module: The module to write into.
        """
        with th.no_grad():
            for name in self.names:
                target = module.get_parameter(name)
                target.copy_(self.params[name][run].to(target.device))


class StackedTeams:
    """
    The actors, critics and their targets of ``R`` teams, stacked, as the functions of :mod:`sb3_maddpg.losses`: the
    many-runs counterpart of :class:`~sb3_maddpg.losses.TeamNetworks` (member dimension ``M = R``).

    :param actors: Each run's team actor.
    :param critics: Each run's team critic.
    :param actor_targets: Each run's target actor.
    :param critic_targets: Each run's target critic.
    :param device: Where the stacked parameters live.
    """

    def __init__(
        self,
        actors: Sequence[MultiAgentActor],
        critics: Sequence[MultiAgentCritic],
        actor_targets: Sequence[MultiAgentActor],
        critic_targets: Sequence[MultiAgentCritic],
        device: th.device | str,
    ) -> None:
        self.actor = StackedModule(actors, device, requires_grad=True)
        self.critic = StackedModule(critics, device, requires_grad=True)
        self.actor_target = StackedModule(actor_targets, device, requires_grad=False)
        self.critic_target = StackedModule(critic_targets, device, requires_grad=False)

    def policy(self, observations: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """The actors' actions and pre-activations, ``[R, batch, action_dim]`` each."""
        return self.actor.call("forward_with_preactivation", observations)

    def actions(self, observations: th.Tensor) -> th.Tensor:
        """The actors' actions when acting, ``[R, batch, action_dim]``."""
        return self.actor.call("forward", observations)

    def q(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None) -> th.Tensor:
        """The critics, ``[R, batch, n_agents]``."""
        return self.critic.call("forward", observations, actions, selections)

    def target_actions(self, observations: th.Tensor) -> th.Tensor:
        """The target actors, ``[R, batch, action_dim]``."""
        return self.actor_target.call("sample", observations)

    def target_q(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None) -> th.Tensor:
        """The target critics, ``[R, batch, n_agents]``."""
        return self.critic_target.call("forward", observations, actions, selections)


def clip_grad_norm_per_run_and_agent(params: Sequence[th.Tensor], max_norm: float) -> None:
    """
    Clip each run's and agent's gradient norm separately, as ``clip_grad_norm_per_agent`` does within one run: the
    gradients of an :class:`~sb3_maddpg.networks.AgentEnsembleMLP`, stacked, are ``[R, n_members, ...]``, and slice
    ``[r, i]`` is agent i's network in run r (one slice for all agents with shared parameters).

    :param params: Stacked ensemble parameters with their ``.grad`` set, ``[R, n_members, ...]`` each.
    :param max_norm: The largest norm of each slice.
    """
    grads = [param.grad for param in params if param.grad is not None]
    if not grads:
        return
    squared = th.zeros(grads[0].shape[:2], device=grads[0].device)
    for grad in grads:
        squared += grad.pow(2).sum(dim=tuple(range(2, grad.dim())))
    coefficients = clip_coefficients(squared, max_norm)
    for grad in grads:
        grad.mul_(coefficients.view(*coefficients.shape, *(1,) * (grad.dim() - 2)))
