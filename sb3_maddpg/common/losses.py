"""
MADDPG's losses as plain functions of one team's networks, settings and noise, and a batch: the target actions
(:func:`target_actions`), the critics' targets (:func:`team_critic_targets`), the critics' losses and the actors' loss
terms.

They take one team's batch (``[batch, ...]`` each field): ``MADDPG.train`` and ``MATD3.train`` apply them to their
replay batch, and a run group to each of its runs' batches under ``vmap`` (:mod:`~sb3_maddpg.common.update_step`),
the same functions. What MATD3 changes is said by its modules and settings, not by other code: its target actions
add TD3's smoothing noise (:class:`TargetSmoothing`), and its twin critics give the minimum of both as the target
(``target_q``) and both stacked in front as the trained values (``trained_q``, ``[2, batch, n_agents]``), which
:func:`critic_losses` broadcasts over. A batch that says which agents were still in the episode (``active``) averages
each agent's terms over its active rows only.
"""

import functools
from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple

import torch as th
from torch.nn import functional as F

from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.layout import AgentLayout

if TYPE_CHECKING:
    from sb3_maddpg.common.policies import MultiAgentActor, MultiAgentCritic

SATURATION_THRESHOLD = 0.99
"""An action component with ``|a| >`` this, in the policy's [-1, 1] space, counts as saturated in the logs."""

Actions = Callable[[th.Tensor], th.Tensor]
"""Observations ``[batch, obs_dim]`` to joint actions in [-1, 1] ``[batch, action_dim]``."""
PolicyWithPreactivation = Callable[[th.Tensor], tuple[th.Tensor, th.Tensor]]
"""Observations ``[batch, obs_dim]`` to the joint actions and the actors' outputs before ``tanh``, both
``[batch, action_dim]``, from one forward pass."""
QValues = Callable[[th.Tensor, th.Tensor, th.Tensor | None], th.Tensor]
"""``(observations [batch, obs_dim], actions, selections [batch, n_agents, k] or None)`` to every agent's Q-value
``[batch, n_agents]`` (twin critics: both stacked in front, ``[2, batch, n_agents]``). The actions are
``[batch, action_dim]``, the same for every critic, or ``[n_agents, batch, action_dim]``, critic i's own joint action
in ``[i]``."""


class ActorLossTerms(NamedTuple):
    """The parts of the agents' actor losses on one batch, ``[n_agents]`` each."""

    policy_loss: th.Tensor
    """-Q_i: the policy-gradient part."""
    reg_loss: th.Tensor
    """``actor_reg_coef`` times the mean squared pre-``tanh`` output of actor i (zeros when the coefficient is 0)."""
    saturation: th.Tensor
    """Fraction of agent i's action components with ``|a| > SATURATION_THRESHOLD`` (no gradient)."""

    @property
    def total(self) -> th.Tensor:
        """The loss each actor minimises: the policy-gradient part plus the regulariser, ``[n_agents]``."""
        return self.policy_loss + self.reg_loss


class ActionParts(NamedTuple):
    """Which components of the joint action are whose: what the actor loss needs of the agent layout."""

    own: th.Tensor
    """``own[i, 0, d]``: action component d is agent i's, ``[n_agents, 1, action_dim]`` (bool)."""
    own_mean: th.Tensor
    """Row i averages over agent i's own components: ``[n_agents, action_dim]``."""
    continuous: th.Tensor
    """Components of continuous agents (a discrete agent's one-hot is never "saturated"), ``[action_dim]`` (bool)."""

    @classmethod
    def of(cls, layout: AgentLayout, device: th.device | str = "cpu") -> "ActionParts":
        """
        :param layout: The team's agent layout.
        :param device: The device of the losses.
        :return: The layout's action parts.
        """
        own = th.zeros(layout.n_agents, 1, layout.action_dim, dtype=th.bool)
        continuous = th.ones(layout.action_dim, dtype=th.bool)
        for i, action_slice in enumerate(layout.action_slices):
            own[i, 0, action_slice] = True
            continuous[action_slice] = not layout.is_discrete(i)
        sizes = th.tensor(layout.action_sizes, dtype=th.float32).unsqueeze(1)
        return cls(own.to(device), (own[:, 0].float() / sizes).to(device), continuous.to(device))


class TargetSmoothing(NamedTuple):
    """TD3's target policy smoothing (MATD3's; MADDPG has none), in the policy's [-1, 1] space."""

    noise_std: float
    """The noise's standard deviation (TD3's ``target_policy_noise``)."""
    noise_clip: float
    """The largest noise magnitude (TD3's ``target_noise_clip``)."""


def smooth_target_actions(
    actions: th.Tensor, noise_std: float, noise_clip: float, continuous: th.Tensor, noise: th.Tensor | None = None
) -> th.Tensor:
    """
    TD3's target policy smoothing, in the policy's [-1, 1] space: Gaussian noise of ``noise_std``, clipped to
    ``[-noise_clip, noise_clip]``, added to the continuous agents' components, the sum clipped to [-1, 1]. A discrete
    agent's one-hot stays the target actor's Gumbel-max sample (noise on a one-hot is not an action).

    :param actions: The target actors' joint actions in [-1, 1], ``[..., action_dim]``.
    :param noise_std: The noise's standard deviation (TD3's ``target_policy_noise``).
    :param noise_clip: The largest noise magnitude (TD3's ``target_noise_clip``).
    :param continuous: The continuous agents' components, ``[action_dim]`` (bool).
    :param noise: Standard normal noise shaped as ``actions``, each member's from its own stream;
        None: drawn from torch's global generator (which SB3's seeding seeds).
    :return: The smoothed actions, the shape of ``actions``.
    """
    # Out of place: under a run group's vmap an in-place clamp has no batching rule (a slow per-run fallback).
    noise = ((th.randn_like(actions) if noise is None else noise) * noise_std).clamp(-noise_clip, noise_clip)
    return th.where(continuous, (actions + noise).clamp(-1.0, 1.0), actions)


def target_actions(
    actor_target: "MultiAgentActor",
    observations: th.Tensor,
    continuous: th.Tensor,
    smoothing: TargetSmoothing | None,
    noise: th.Tensor | None = None,
) -> th.Tensor:
    """
    Every target actor on its agent's observation (a discrete agent's: a Gumbel-max sample), smoothed where the
    algorithm smooths (MATD3).

    :param actor_target: The target actors.
    :param observations: ``[batch, obs_dim]``.
    :param continuous: The continuous agents' components (``ActionParts.continuous``).
    :param smoothing: TD3's smoothing, or None (MADDPG).
    :param noise: The smoothing's standard normal noise (a run group's member's); None: drawn after the sample.
    :return: The joint target actions, ``[batch, action_dim]``.
    """
    actions = actor_target.sample(observations)
    if smoothing is None:
        return actions
    return smooth_target_actions(actions, smoothing.noise_std, smoothing.noise_clip, continuous, noise)


def team_critic_targets(
    actor_target: "MultiAgentActor",
    critic_target: "MultiAgentCritic",
    batch: MultiAgentReplayBufferSamples,
    gamma: float,
    continuous: th.Tensor,
    smoothing: TargetSmoothing | None,
    noise: th.Tensor | None = None,
) -> th.Tensor:
    """
    One team's critic targets (:func:`critic_targets`) from its target networks: :func:`target_actions` and the target
    critics' ``target_q`` (MATD3's: the minimum of its twins).

    :param actor_target: The target actors.
    :param critic_target: The target critics.
    :param batch: A replay batch, ``[batch, ...]`` each field.
    :param gamma: The discount.
    :param continuous: The continuous agents' components.
    :param smoothing: TD3's smoothing, or None.
    :param noise: The smoothing's noise (see :func:`target_actions`).
    :return: ``[batch, n_agents]``.
    """
    actions = functools.partial(target_actions, actor_target, continuous=continuous, smoothing=smoothing, noise=noise)
    return critic_targets(actions, critic_target.target_q, batch, gamma)


def critic_targets(
    target_actions: Actions, target_q: QValues, batch: MultiAgentReplayBufferSamples, gamma: float
) -> th.Tensor:
    """
    y_i = r_i + gamma * (1 - done_i) * Q_i'(x_i'), with x_i' built from the next observations and every agent's target
    action a_j' = mu_j'(o_j'); done_i is a true termination (a truncation bootstraps). No gradient.

    :param target_actions: The target actors (MADDPG: ``mu'(o')``, a discrete agent's a sample).
    :param target_q: The target critics.
    :param batch: A replay batch, ``[batch, ...]`` each field.
    :param gamma: The discount.
    :return: ``[batch, n_agents]``.
    """
    with th.no_grad():
        next_actions = target_actions(batch.next_observations)
        next_selections = batch.selections if batch.next_selections is None else batch.next_selections
        next_q = target_q(batch.next_observations, next_actions, next_selections)
        return batch.rewards + (1.0 - batch.dones) * gamma * next_q


def critic_losses(critic: QValues, batch: MultiAgentReplayBufferSamples, targets: th.Tensor) -> th.Tensor:
    """
    Each critic's mean squared TD error on the batch.

    :param critic: The critics (twin critics: both stacked in front, ``[2, batch, n_agents]``).
    :param batch: A replay batch, ``[batch, ...]`` each field.
    :param targets: :func:`critic_targets`, ``[batch, n_agents]``.
    :return: One loss per agent, ``[n_agents]`` (twin critics: ``[2, n_agents]``).
    """
    current_q = critic(batch.observations, batch.actions, batch.selections)
    return _mean_over_rows(F.mse_loss(current_q, targets.expand_as(current_q), reduction="none"), batch.active)


def _mean_over_rows(values: th.Tensor, active: th.Tensor | None) -> th.Tensor:
    """The mean over the batch (``dim=-2``) of each agent's values, over the rows where it was active when given."""
    if active is None:
        return values.mean(dim=-2)
    return (values * active).sum(dim=-2) / active.sum(dim=-2).clamp(min=1.0)


def actor_loss_terms(
    policy: PolicyWithPreactivation,
    critic: QValues,
    batch: MultiAgentReplayBufferSamples,
    parts: ActionParts,
    reg_coef: float,
) -> ActorLossTerms:
    """
    The actor losses' parts from one forward pass of the actors.

    Policy loss: -Q_i(x_i) with only a_i replaced by mu_i(o_i); the other agents' actions are the sampled ones.
    Regulariser: ``reg_coef`` times the mean over the batch and agent i's action components of its pre-``tanh`` output
    squared, as Lowe et al.'s ``p_reg``; it depends on actor i only.

    :param policy: The actors.
    :param critic: The critics the actors ascend (MATD3: the first twin).
    :param batch: A replay batch, ``[batch, ...]`` each field.
    :param parts: Which action components are whose.
    :param reg_coef: The regulariser's weight; 0 skips it.
    :return: The policy loss, the regulariser and the action saturation, ``[n_agents]`` each.
    """
    policy_actions, preactivations = policy(batch.observations)
    per_critic_actions = th.where(parts.own, policy_actions.unsqueeze(-3), batch.actions.unsqueeze(-3))
    policy_loss = -_mean_over_rows(critic(batch.observations, per_critic_actions, batch.selections), batch.active)
    if batch.active is not None:  # each agent's terms over its active rows (its own components' mean per row first)
        reg = reg_coef * _mean_over_rows(preactivations.pow(2) @ parts.own_mean.T, batch.active)
        reg_loss = reg if reg_coef > 0 else th.zeros_like(policy_loss)
        with th.no_grad():
            saturated = ((policy_actions.abs() > SATURATION_THRESHOLD) & parts.continuous).float()
            saturation = _mean_over_rows(saturated @ parts.own_mean.T, batch.active)
        return ActorLossTerms(policy_loss, reg_loss, saturation)
    if reg_coef > 0:
        reg_loss = reg_coef * (preactivations.pow(2).mean(dim=-2) @ parts.own_mean.T)
    else:
        reg_loss = th.zeros_like(policy_loss)
    with th.no_grad():
        saturated = ((policy_actions.abs() > SATURATION_THRESHOLD) & parts.continuous).float().mean(dim=-2)
        saturation = saturated @ parts.own_mean.T
    return ActorLossTerms(policy_loss, reg_loss, saturation)
