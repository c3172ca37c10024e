"""
One gradient step of a run group's ``M`` teams at once (:mod:`sb3_maddpg.run_group`), on the losses of
:mod:`sb3_maddpg.common.losses`, which ``MADDPG.train`` and ``MATD3.train`` run on one team's modules directly.

A step is: the critic targets, every critic's loss and its optimiser step (gradients clipped per member and agent),
then, when the actors are due, the actors' losses and step and the Polyak updates of every target. Two things vary and
are passed in: how ``M`` teams' modules are evaluated (:class:`MemberModules`: the runs' stacked parameters under
``vmap``) and what the algorithm makes of them (:class:`UpdateNetworks`: MADDPG's critic and target
actor, MATD3's twins and smoothed targets).
"""

import contextlib
import functools
from collections.abc import Callable
from typing import Any, NamedTuple, Protocol

import torch as th

from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.gradient_step import optimiser_step
from sb3_maddpg.common.gradient_step import polyak_update_foreach as polyak_update_foreach  # its path of 0.3.0.dev
from sb3_maddpg.common.losses import ActionParts, actor_loss_terms, critic_losses, critic_targets
from sb3_maddpg.common.train_logs import LOSS_NAMES as LOSS_NAMES  # its path of 0.3.0.dev
from sb3_maddpg.common.train_logs import StepLosses as StepLosses
from sb3_maddpg.common.train_logs import step_losses
from sb3_maddpg.common.train_logs import summarise_steps as summarise_steps

MODULE_NAMES = ("actor", "critic", "actor_target", "critic_target")
"""The four modules of a team, as :class:`MemberModules` names them."""


class MemberModules(Protocol):
    """How ``M`` teams' actors, critics and targets are evaluated and updated, every tensor ``[M, ...]``."""

    def call(self, module: str, method: str, *args: th.Tensor | None) -> Any:
        """
        :param module: One of :data:`MODULE_NAMES`.
        :param method: The method of the package's module (``"forward"``, ``"sample"``, ``"twins"``...).
        :param args: Its arguments with the member dimension in front (None is passed as None).
        :return: What it returns, with the member dimension in front.
        """
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
        """:return: Standard normal noise shaped as ``tensor``, each member's from its own stream."""
        ...


class UpdateNetworks:
    """
    MADDPG's networks as the functions of :mod:`sb3_maddpg.common.losses`, over :class:`MemberModules`.

    :param modules: The members' modules.
    """

    def __init__(self, modules: MemberModules) -> None:
        self.modules = modules

    def policy(self, observations: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """The actors' actions and pre-activations (a discrete agent's: straight-through Gumbel-softmax)."""
        return self.modules.call("actor", "forward_with_preactivation", observations)

    def q(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None) -> th.Tensor:
        """The critics the actors ascend, ``[M, batch, n_agents]``."""
        return self.modules.call("critic", "forward", observations, actions, selections)

    def trained_q(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None) -> th.Tensor:
        """Every critic trained at a step (MADDPG: one per agent), ``[..., M, batch, n_agents]``."""
        return self.q(observations, actions, selections)

    def target_actions(self, observations: th.Tensor) -> th.Tensor:
        """The target actors (a discrete agent's: a Gumbel-max sample)."""
        return self.modules.call("actor_target", "sample", observations)

    def target_q(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None) -> th.Tensor:
        """The target critics, ``[M, batch, n_agents]``."""
        return self.modules.call("critic_target", "forward", observations, actions, selections)


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
    networks: UpdateNetworks,
    optimizers: tuple[th.optim.Optimizer, th.optim.Optimizer],
    batch: MultiAgentReplayBufferSamples,
    settings: StepSettings,
    actor_due: bool,
    recording: Callable[[], contextlib.AbstractContextManager[Any]] = contextlib.nullcontext,
) -> StepLosses:
    """
    One gradient step of every member on its batch: the critics, then (when due) the actors against the updated
    critics, then the targets.

    :param networks: The algorithm's networks over the members' modules.
    :param optimizers: The actors' and the critics' optimisers.
    :param batch: Each member's replay batch, ``[M, batch, ...]`` each field.
    :param settings: The algorithm's hyperparameters.
    :param actor_due: Whether the actors and targets are updated at this step (:meth:`StepSettings.actor_due`).
    :param recording: A context in which the critics' forward pass on the replayed batch runs (e.g. the extractors
        recording their diagnostics).
    :return: The step's losses.
    """
    modules = networks.modules
    actor_optimizer, critic_optimizer = optimizers
    target_q = critic_targets(networks.target_actions, networks.target_q, batch, settings.gamma)
    with recording():
        critic_loss = critic_losses(networks.trained_q, batch, target_q)
    _optimise(modules, "critic", critic_optimizer, critic_loss.sum(), settings.max_grad_norm)
    # Per member and agent, the mean over the agent's critics (MATD3's twins are stacked in front).
    critic_log = critic_loss.detach().reshape(-1, *critic_loss.shape[-2:]).mean(0)
    if not actor_due:
        return step_losses(critic_log, None)
    terms = actor_loss_terms(networks.policy, networks.q, batch, settings.parts, settings.actor_reg_coef)
    _optimise(modules, "actor", actor_optimizer, terms.total.sum(), settings.max_grad_norm)
    modules.update_targets(settings.tau)
    return step_losses(critic_log, terms)


def _optimise(
    modules: MemberModules, module: str, optimizer: th.optim.Optimizer, loss: th.Tensor, max_norm: float | None
) -> None:
    """One optimiser step of ``module`` on ``loss``: only its own parameters' gradients are computed."""
    clip = None if max_norm is None else functools.partial(modules.clip_gradients, module, max_norm)
    optimiser_step(modules.parameters(module), optimizer, loss, clip)
