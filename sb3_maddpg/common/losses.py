"""
MADDPG's losses as functions of the networks and a batch: the critics' targets, the critics' losses and the actors'
loss terms.

They take one team's batch (``[batch, ...]`` each field): ``MADDPG.train`` applies them to its replay batch, and a
run group to each of its runs' batches under ``vmap`` (:mod:`~sb3_maddpg.common.update_step`). The networks are passed
as functions (the model's own methods, which a run group applies to every run), so that a sibling
algorithm changes them, not the math: MATD3's target actor adds its smoothing noise, its target critic returns the
minimum of its twins, and its critic returns both twins stacked in front (``[2, batch, n_agents]``), which
:func:`critic_losses` broadcasts over. A batch that says which agents were still in the episode (``active``) averages
each agent's terms over its active rows only.
"""

from collections.abc import Callable
from typing import NamedTuple

import torch as th
from torch.nn import functional as F

from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.layout import AgentLayout

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
