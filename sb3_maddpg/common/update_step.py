"""
One gradient step of a run group's ``M`` teams at once (:mod:`sb3_maddpg.run_group`), with the functions that
``MADDPG.train`` and ``MATD3.train`` run for one team.

The one team's functions are the plain functions of :mod:`sb3_maddpg.common.losses` (target actions, critic targets,
critic losses, actor loss terms) over its four networks and the step's settings (:class:`StepSettings`, MATD3's
smoothing included): :class:`TeamFunctions` holds one team's networks for them, and :class:`GroupFunctions` applies
them to each member's parameters with ``torch.func.functional_call``, ``vmap``-ed over the members. No second copy
of the math: what MATD3 changes (its twins' ``trained_q`` and ``target_q``, its smoothing) is said by its modules and
settings, which reach the group as they are. A step is: every critic's loss and its optimiser step (gradients clipped
per member and agent), then, when the actors are due, the actors' losses and step and the Polyak updates of every
target.
"""

from collections.abc import Callable
from typing import Any, NamedTuple, Protocol

import torch as th
from torch import nn
from torch.func import functional_call, grad, vmap

from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.losses import (
    ActionParts,
    ActorLossTerms,
    TargetSmoothing,
    actor_loss_terms,
    critic_losses,
    team_critic_targets,
)
from sb3_maddpg.common.networks import clip_coefficients
from sb3_maddpg.common.train_logs import StepLosses, step_losses

MODULE_NAMES = ("actor", "critic", "actor_target", "critic_target")
"""The four modules of a team."""


class MemberModules(Protocol):
    """``M`` teams' stacked actors, critics and targets: their parameters, clipping, targets and random streams."""

    def stacked_parameters(self) -> dict[str, th.Tensor]:
        """:return: Every parameter of the four modules, ``[M, ...]`` each, by ``<module>.<parameter name>``."""
        ...

    def module_parameters(self, module: str) -> dict[str, th.Tensor]:
        """:return: One of :data:`MODULE_NAMES`' parameters, ``[M, ...]`` each, named as in :meth:`stacked_parameters`."""
        ...

    def clip_groups(self, module: str) -> list[list[str]]:
        """
        :return: The names (``<module>.<parameter name>``) of each network of ``"actor"`` or ``"critic"`` whose
            gradient is clipped on its own (the critics and MATD3's twins apart).
        """
        ...

    def update_targets(self, tau: float) -> None:
        """Polyak-average every target towards its module: ``target = (1 - tau) * target + tau * module``."""
        ...

    def normal_like(self, tensor: th.Tensor) -> th.Tensor:
        """:return: Standard normal noise shaped as ``tensor`` (``[M, ...]``), each member's from its own stream."""
        ...


class TeamFunctions(nn.Module):
    """
    One team's four networks (templates, whose parameters :class:`GroupFunctions` replaces by one member's) with the
    step's functions over them, as ``train`` calls them: :func:`~sb3_maddpg.common.losses.team_critic_targets`,
    :func:`~sb3_maddpg.common.losses.critic_losses` and :func:`~sb3_maddpg.common.losses.actor_loss_terms`. The smoothing
    noise (MATD3) is the member's own, drawn before and passed in.

    :param modules: The four networks, by :data:`MODULE_NAMES`.
    :param parts: The layout's action parts, on the networks' device.
    :param smoothing: The target actions' smoothing (MATD3's), or None.
    """

    def __init__(self, modules: dict[str, nn.Module], parts: ActionParts, smoothing: TargetSmoothing | None) -> None:
        super().__init__()
        self.actor: Any = modules["actor"]
        self.critic: Any = modules["critic"]
        self.actor_target: Any = modules["actor_target"]
        self.critic_target: Any = modules["critic_target"]
        self._action_parts = parts
        self._smoothing = smoothing

    def critic_losses(self, batch: MultiAgentReplayBufferSamples, gamma: float, noise: th.Tensor | None) -> th.Tensor:
        """One member's critic losses on its batch, as ``train`` computes them (``[n_agents]``; MATD3 ``[2, n_agents]``)."""
        targets = team_critic_targets(
            self.actor_target, self.critic_target, batch, gamma, self._action_parts.continuous, self._smoothing, noise
        )
        return critic_losses(self.critic.trained_q, batch, targets)

    def act(self, observations: th.Tensor) -> th.Tensor:
        """One member's actors on its observations ``[batch, obs_dim]``: its actions ``[batch, action_dim]``."""
        return self.actor(observations)  # type: ignore[operator, no-any-return]

    def actor_loss_terms(self, batch: MultiAgentReplayBufferSamples, reg_coef: float) -> ActorLossTerms:
        """One member's actor loss terms on its batch, as ``train`` computes them (``[n_agents]`` each)."""
        return actor_loss_terms(self.actor.forward_with_preactivation, self.critic, batch, self._action_parts, reg_coef)


class _Bound(nn.Module):
    """Calls one function of :class:`TeamFunctions` as ``forward``: ``functional_call`` calls only ``forward``."""

    def __init__(self, team: TeamFunctions, function: Callable[..., Any]) -> None:
        super().__init__()
        self.team = team
        self.function = function

    def forward(self, *args: Any) -> Any:
        return self.function(self.team, *args)


class GroupFunctions:
    """
    :class:`TeamFunctions` applied to every member at once: each member's parameters swapped in with
    ``functional_call``, its gradients taken with ``torch.func.grad`` and clipped per agent, all ``vmap``-ed over the
    members; the smoothing noise drawn from each member's own stream. Nothing here holds state: the parameters come in
    as tensors and the gradients go out, so a whole step traces as one graph.

    :param settings: The members' step settings (every member's the same: checked by the group), on the group's device.
    :param members: The members' stacked modules.
    :param templates: One team's four networks on the group's device, by :data:`MODULE_NAMES`.
    """

    def __init__(self, settings: "StepSettings", members: MemberModules, templates: dict[str, nn.Module]) -> None:
        self.smooths = settings.smoothing is not None  # MATD3's target actions draw smoothing noise; MADDPG's none
        self.team = TeamFunctions(templates, settings.parts, settings.smoothing)
        self.members = members
        self._critic = _member_call(_Bound(self.team, TeamFunctions.critic_losses))
        self._actor = _member_call(_Bound(self.team, TeamFunctions.actor_loss_terms))
        self._act = _member_call(_Bound(self.team, TeamFunctions.act))

    def actions(self, observations: th.Tensor) -> th.Tensor:
        """Every member's actors' actions (no gradient), ``[M, batch, action_dim]`` from ``[M, batch, obs_dim]``."""
        with th.no_grad():
            return vmap(self._act)(self.members.stacked_parameters(), observations)  # type: ignore[no-any-return]

    def critic_losses(self, batch: MultiAgentReplayBufferSamples, gamma: float) -> th.Tensor:
        """Every member's critic losses, ``[M, n_agents]`` (MATD3: ``[M, 2, n_agents]``)."""
        noise = self.members.normal_like(batch.actions) if self.smooths else None
        calls = vmap(self._critic, in_dims=(0, _batch_dims(batch), None, None if noise is None else 0))
        return calls(self.members.stacked_parameters(), batch, gamma, noise)  # type: ignore[no-any-return]

    def actor_loss_terms(self, batch: MultiAgentReplayBufferSamples, reg_coef: float) -> ActorLossTerms:
        """Every member's actor loss terms, ``[M, n_agents]`` each."""
        calls = vmap(self._actor, in_dims=(0, _batch_dims(batch), None))
        return calls(self.members.stacked_parameters(), batch, reg_coef)  # type: ignore[no-any-return]

    def critic_gradients(
        self, batch: MultiAgentReplayBufferSamples, gamma: float, max_norm: float | None
    ) -> tuple[dict[str, th.Tensor], th.Tensor]:
        """
        Every member's critic gradients (of the sum of its agents' losses), each agent's (each twin's) clipped to
        ``max_norm`` on its own, and its losses.

        :return: The gradients by ``critic.<parameter name>`` (``[M, ...]`` each) and the losses ``[M, n_agents]``
            (MATD3: ``[M, 2, n_agents]``).
        """
        noise = self.members.normal_like(batch.actions) if self.smooths else None
        step = _clipped_gradients(self._critic, max_norm, self.members.clip_groups("critic"))
        calls = vmap(step, in_dims=(0, 0, _batch_dims(batch), None, None if noise is None else 0))
        trained, others = _split(self.members.stacked_parameters(), self.members.module_parameters("critic"))
        return calls(trained, others, batch, gamma, noise)  # type: ignore[no-any-return]

    def actor_gradients(
        self, batch: MultiAgentReplayBufferSamples, reg_coef: float, max_norm: float | None
    ) -> tuple[dict[str, th.Tensor], ActorLossTerms]:
        """
        Every member's actor gradients (of the sum of its agents' loss totals), each agent's clipped to ``max_norm`` on
        its own, and its loss terms.

        :return: The gradients by ``actor.<parameter name>`` (``[M, ...]`` each) and the terms (``[M, n_agents]`` each).
        """
        step = _clipped_gradients(self._actor, max_norm, self.members.clip_groups("actor"))
        calls = vmap(step, in_dims=(0, 0, _batch_dims(batch), None))
        trained, others = _split(self.members.stacked_parameters(), self.members.module_parameters("actor"))
        return calls(trained, others, batch, reg_coef)  # type: ignore[no-any-return]


def _member_call(bound: nn.Module) -> Callable[..., Any]:
    """:return: ``bound``'s forward with one member's parameters (``<module>.<name>``) swapped in."""

    def call(params: dict[str, th.Tensor], *args: Any) -> Any:
        return functional_call(bound, {f"team.{name}": value for name, value in params.items()}, args)

    return call


def _split(params: dict[str, th.Tensor], trained: dict[str, th.Tensor]) -> tuple[dict[str, th.Tensor], dict[str, th.Tensor]]:
    """:return: ``trained`` (one module's parameters, named as in ``params``) and the other parameters."""
    return trained, {name: value for name, value in params.items() if name not in trained}


def _clipped_gradients(
    call: Callable[..., Any], max_norm: float | None, clip_groups: list[list[str]]
) -> Callable[..., tuple[dict[str, th.Tensor], Any]]:
    """
    One member's gradient step function: the gradients of ``call``'s losses (summed) with respect to its first
    argument's parameters (the trained module's), each network's clipped on its own (:func:`clip_per_agent` on each
    group of ``clip_groups``).

    :param call: A member call (:func:`_member_call`) returning the losses (a tensor, or terms with a ``total``).
    :param max_norm: The largest norm of each agent's gradient, or None for no clipping.
    :param clip_groups: The names of the parameters clipped together (a network and its twin apart).
    """

    def losses(trained: dict[str, th.Tensor], others: dict[str, th.Tensor], *args: Any) -> tuple[th.Tensor, Any]:
        out = call({**trained, **others}, *args)
        total = out.total if isinstance(out, ActorLossTerms) else out
        return total.sum(), _detached(out)

    gradients = grad(losses, has_aux=True)

    def step(trained: dict[str, th.Tensor], others: dict[str, th.Tensor], *args: Any) -> tuple[dict[str, th.Tensor], Any]:
        grads, out = gradients(trained, others, *args)
        if max_norm is not None:
            for names in clip_groups:
                grads.update(zip(names, clip_per_agent([grads[name] for name in names], max_norm)))
        return grads, out

    return step


def _detached(out: Any) -> Any:
    if isinstance(out, ActorLossTerms):
        return ActorLossTerms(*(term.detach() for term in out))
    return out.detach()


def clip_per_agent(grads: list[th.Tensor], max_norm: float) -> list[th.Tensor]:
    """
    One team's gradients with each agent's norm clipped to ``max_norm`` on its own, as if each agent had an optimiser
    of its own: the gradients of an :class:`~sb3_maddpg.common.networks.AgentEnsembleMLP` are ``[n_members, ...]``, and
    slice ``[i]`` is agent i's network (one slice for all agents with shared parameters). Out of place; under ``vmap``
    over a group's members, each member's each agent's.

    :param grads: The network's gradients, ``[n_members, ...]`` each.
    :param max_norm: The largest norm of each slice.
    :return: The clipped gradients.
    """
    squared = th.cat([g.flatten(1) for g in grads], dim=1).pow(2).sum(dim=1)
    coefficients = clip_coefficients(squared, max_norm)
    return [g * coefficients.view(-1, *(1,) * (g.dim() - 1)) for g in grads]


def _batch_dims(batch: MultiAgentReplayBufferSamples) -> MultiAgentReplayBufferSamples:
    """``vmap``'s ``in_dims`` of a batch: the member dimension of each field, None for a field that is None."""
    return MultiAgentReplayBufferSamples(*(None if field is None else 0 for field in batch))  # type: ignore[arg-type]


class StepSettings(NamedTuple):
    """An algorithm's hyperparameters of one step (the same for every member)."""

    gamma: float
    tau: float
    actor_reg_coef: float
    max_grad_norm: float | None
    parts: ActionParts
    policy_delay: int = 1
    """Critic updates per actor and target update (MATD3's; MADDPG's is 1)."""
    smoothing: TargetSmoothing | None = None
    """The target actions' smoothing (MATD3's; MADDPG has none)."""

    def actor_due(self, n_updates: int) -> bool:
        """:return: Whether the critic update numbered ``n_updates`` (from 1) is followed by the actors' and targets'."""
        return n_updates % self.policy_delay == 0


def update_step(
    functions: GroupFunctions,
    optimizers: tuple[Any, Any],
    batch: MultiAgentReplayBufferSamples,
    settings: StepSettings,
    actor_due: bool,
    capturable: bool = False,
) -> StepLosses:
    """
    One gradient step of every member on its batch: the critics, then (when due) the actors against the updated
    critics, then the targets; each member's losses are those ``train`` computes for one team.

    :param functions: The algorithm's functions over the members.
    :param optimizers: The actors' and the critics' optimisers over the stacked parameters (each with
        ``step(grads, capturable)`` and the parameters in the members' order: a run group's
        :class:`~sb3_maddpg.run_group.stacked_adam.StackedAdam`).
    :param batch: Each member's replay batch, ``[M, batch, ...]`` each field.
    :param settings: The algorithm's hyperparameters.
    :param actor_due: Whether the actors and targets are updated at this step (:meth:`StepSettings.actor_due`).
    :param capturable: The optimisers' capturable form (a compiled or captured step; see ``StackedAdam.step``).
    :return: The step's losses, ``[M, n_agents]`` each.
    """
    actor_optimizer, critic_optimizer = optimizers
    grads, critic_loss = functions.critic_gradients(batch, settings.gamma, settings.max_grad_norm)
    critic_optimizer.step(list(grads.values()), capturable)
    # Per member and agent, the mean over the agent's critics (MATD3's twins come after the member dimension).
    critic_log = critic_loss.reshape(critic_loss.shape[0], -1, critic_loss.shape[-1]).mean(1)
    if not actor_due:
        return step_losses(critic_log, None)
    grads, terms = functions.actor_gradients(batch, settings.actor_reg_coef, settings.max_grad_norm)
    actor_optimizer.step(list(grads.values()), capturable)
    functions.members.update_targets(settings.tau)
    return step_losses(critic_log, terms)
