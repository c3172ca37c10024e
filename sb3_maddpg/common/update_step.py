"""
One gradient step of a run group's ``M`` teams at once (:mod:`sb3_maddpg.run_group`), with the losses and the
algorithm's own functions that ``MADDPG.train`` and ``MATD3.train`` run for one team.

The one team's functions (the model's ``_target_actions``, ``_target_q`` and ``_trained_q``, its actors' and critics'
forward passes, and the losses of :mod:`sb3_maddpg.common.losses`) are evaluated for every member at once:
:class:`TeamFunctions` binds them to one team's networks, and :class:`GroupFunctions` applies them to each member's
parameters with ``torch.func.functional_call``, ``vmap``-ed over the members. No second copy of the math: what a
subclass of MADDPG changes in its functions (MATD3's twins, minimum and smoothed targets) reaches the group as it is.
A step is: every critic's loss and its optimiser step (gradients clipped per member and agent), then, when the actors
are due, the actors' losses and step and the Polyak updates of every target.
"""

import functools
from collections.abc import Callable
from typing import Any, NamedTuple, Protocol

import torch as th
from torch import nn
from torch.func import functional_call, vmap

from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.gradient_step import optimiser_step
from sb3_maddpg.common.gradient_step import polyak_update_foreach as polyak_update_foreach  # its path of 0.3.0.dev
from sb3_maddpg.common.losses import ActionParts, ActorLossTerms, actor_loss_terms, critic_losses, critic_targets
from sb3_maddpg.common.train_logs import LOSS_NAMES as LOSS_NAMES  # its path of 0.3.0.dev
from sb3_maddpg.common.train_logs import StepLosses as StepLosses
from sb3_maddpg.common.train_logs import step_losses
from sb3_maddpg.common.train_logs import summarise_steps as summarise_steps

MODULE_NAMES = ("actor", "critic", "actor_target", "critic_target")
"""The four modules of a team."""


class MemberModules(Protocol):
    """``M`` teams' stacked actors, critics and targets: their parameters, clipping, targets and random streams."""

    def stacked_parameters(self) -> dict[str, th.Tensor]:
        """:return: Every parameter of the four modules, ``[M, ...]`` each, by ``<module>.<parameter name>``."""
        ...

    def parameters(self, module: str) -> list[th.Tensor]:
        """:return: The trained parameters of ``"actor"`` or ``"critic"``."""
        ...

    def clip_gradients(self, module: str, max_norm: float) -> None:
        """Clip the gradient of ``"actor"`` or ``"critic"`` to ``max_norm``, each member's each agent's (each twin's)
        network separately, as if each had an optimiser of its own."""
        ...

    def update_targets(self, tau: float) -> None:
        """Polyak-average every target towards its module: ``target = (1 - tau) * target + tau * module``."""
        ...

    def normal_like(self, tensor: th.Tensor) -> th.Tensor:
        """:return: Standard normal noise shaped as ``tensor`` (``[M, ...]``), each member's from its own stream."""
        ...


class TeamFunctions(nn.Module):
    """
    One team's four networks (templates, whose parameters :class:`GroupFunctions` replaces by one member's) and the
    algorithm's own functions over them: ``algorithm._target_actions(self, ...)`` and the others run here as they run
    on a model, reading the same attributes (the networks, ``_action_parts``, MATD3's noise settings), except that the
    smoothing noise is the member's own, drawn before and passed in (:meth:`_smoothing_noise`).

    :param algorithm: The model's class (MADDPG, MATD3 or a subclass).
    :param modules: The four networks, by :data:`MODULE_NAMES`.
    :param parts: The layout's action parts, on the networks' device.
    :param settings: The model's attributes its functions read beyond the networks (e.g. ``target_policy_noise``).
    """

    def __init__(self, algorithm: type, modules: dict[str, nn.Module], parts: ActionParts, settings: dict[str, Any]) -> None:
        super().__init__()
        for name in MODULE_NAMES:
            self.add_module(name, modules[name])
        self.algorithm = algorithm
        self._action_parts = parts
        for name, value in settings.items():
            setattr(self, name, value)
        self._noise: th.Tensor | None = None

    def _smoothing_noise(self, actions: th.Tensor) -> th.Tensor:
        """The member's own smoothing noise (MATD3), set by :meth:`critic_losses` for its call."""
        assert self._noise is not None, "the smoothing noise is drawn per member and passed in"
        return self._noise

    def critic_losses(self, batch: MultiAgentReplayBufferSamples, gamma: float, noise: th.Tensor | None) -> th.Tensor:
        """One member's critic losses on its batch, as ``train`` computes them (``[n_agents]``; MATD3 ``[2, n_agents]``)."""
        self._noise = noise
        algorithm: Any = self.algorithm
        targets = critic_targets(
            functools.partial(algorithm._target_actions, self), functools.partial(algorithm._target_q, self), batch, gamma
        )
        return critic_losses(functools.partial(algorithm._trained_q, self), batch, targets)

    def actor_loss_terms(self, batch: MultiAgentReplayBufferSamples, reg_coef: float) -> ActorLossTerms:
        """One member's actor loss terms on its batch, as ``train`` computes them (``[n_agents]`` each)."""
        actor: Any = self.actor
        critic: Any = self.critic
        return actor_loss_terms(actor.forward_with_preactivation, critic, batch, self._action_parts, reg_coef)


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
    ``functional_call``, ``vmap``-ed over the members; the smoothing noise drawn from each member's own stream.

    :param model: The group's first model (its class and settings are every member's: checked by the group).
    :param members: The members' stacked modules.
    :param templates: One team's four networks on the group's device, by :data:`MODULE_NAMES`.
    :param parts: The layout's action parts on that device.
    """

    def __init__(self, model: Any, members: MemberModules, templates: dict[str, nn.Module], parts: ActionParts) -> None:
        algorithm = type(model)
        # MATD3's functions draw smoothing noise; MADDPG's draw none.
        self.smooths = getattr(algorithm, "_smoothing_noise", None) is not None
        settings = {name: getattr(model, name) for name in ("target_policy_noise", "target_noise_clip") if self.smooths}
        self.team = TeamFunctions(algorithm, templates, parts, settings)
        self.members = members
        prefixed = lambda function: _Bound(self.team, function)  # noqa: E731

        def member_call(function: Callable[..., Any]) -> Callable[..., Any]:
            bound = prefixed(function)

            def call(params: dict[str, th.Tensor], *args: Any) -> Any:
                return functional_call(bound, {f"team.{name}": value for name, value in params.items()}, args)

            return call

        self._critic = member_call(TeamFunctions.critic_losses)
        self._actor = member_call(TeamFunctions.actor_loss_terms)

    def critic_losses(self, batch: MultiAgentReplayBufferSamples, gamma: float) -> th.Tensor:
        """Every member's critic losses, ``[M, n_agents]`` (MATD3: ``[M, 2, n_agents]``)."""
        noise = self.members.normal_like(batch.actions) if self.smooths else None
        calls = vmap(self._critic, in_dims=(0, _batch_dims(batch), None, None if noise is None else 0))
        return calls(self.members.stacked_parameters(), batch, gamma, noise)  # type: ignore[no-any-return]

    def actor_loss_terms(self, batch: MultiAgentReplayBufferSamples, reg_coef: float) -> ActorLossTerms:
        """Every member's actor loss terms, ``[M, n_agents]`` each."""
        calls = vmap(self._actor, in_dims=(0, _batch_dims(batch), None))
        return calls(self.members.stacked_parameters(), batch, reg_coef)  # type: ignore[no-any-return]


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

    def actor_due(self, n_updates: int) -> bool:
        """:return: Whether the critic update numbered ``n_updates`` (from 1) is followed by the actors' and targets'."""
        return n_updates % self.policy_delay == 0


def update_step(
    functions: GroupFunctions,
    optimizers: tuple[th.optim.Optimizer, th.optim.Optimizer],
    batch: MultiAgentReplayBufferSamples,
    settings: StepSettings,
    actor_due: bool,
) -> StepLosses:
    """
    One gradient step of every member on its batch: the critics, then (when due) the actors against the updated
    critics, then the targets; each member's losses are those ``train`` computes for one team.

    :param functions: The algorithm's functions over the members.
    :param optimizers: The actors' and the critics' optimisers.
    :param batch: Each member's replay batch, ``[M, batch, ...]`` each field.
    :param settings: The algorithm's hyperparameters.
    :param actor_due: Whether the actors and targets are updated at this step (:meth:`StepSettings.actor_due`).
    :return: The step's losses, ``[M, n_agents]`` each.
    """
    members = functions.members
    actor_optimizer, critic_optimizer = optimizers
    critic_loss = functions.critic_losses(batch, settings.gamma)
    _optimise(members, "critic", critic_optimizer, critic_loss.sum(), settings.max_grad_norm)
    # Per member and agent, the mean over the agent's critics (MATD3's twins come after the member dimension).
    critic_log = critic_loss.detach().reshape(critic_loss.shape[0], -1, critic_loss.shape[-1]).mean(1)
    if not actor_due:
        return step_losses(critic_log, None)
    terms = functions.actor_loss_terms(batch, settings.actor_reg_coef)
    _optimise(members, "actor", actor_optimizer, terms.total.sum(), settings.max_grad_norm)
    members.update_targets(settings.tau)
    return step_losses(critic_log, terms)


def _optimise(
    modules: MemberModules, module: str, optimizer: th.optim.Optimizer, loss: th.Tensor, max_norm: float | None
) -> None:
    """One optimiser step of ``module`` on ``loss``: only its own parameters' gradients are computed."""
    clip = None if max_norm is None else functools.partial(modules.clip_gradients, module, max_norm)
    optimiser_step(modules.parameters(module), optimizer, loss, clip)
