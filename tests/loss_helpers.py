"""A model's losses on a plain replay batch (one team, no member dimension), through :mod:`sb3_maddpg.common.losses`."""

import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.losses import ActorLossTerms, actor_loss_terms, critic_losses


def critic_losses_by_critic(model: MADDPG, data: MultiAgentReplayBufferSamples) -> th.Tensor:
    """:return: Each critic's loss, ``[critics per agent, n_agents]`` (1 for MADDPG, 2 for MATD3), as ``train()``
    computes it (its hooks)."""
    losses = critic_losses(model.critic.trained_q, data, model._critic_targets(data))
    return losses.reshape(-1, losses.shape[-1])


def team_critic_losses(model: MADDPG, data: MultiAgentReplayBufferSamples) -> th.Tensor:
    """:return: Each critic's loss, ``[n_agents]``, as ``train()`` computes it (a model of one critic per agent)."""
    losses = critic_losses_by_critic(model, data)
    assert losses.shape[0] == 1, "one critic per agent expected: use critic_losses_by_critic"
    return losses[0]


def team_actor_terms(model: MADDPG, data: MultiAgentReplayBufferSamples) -> ActorLossTerms:
    """:return: The actor loss terms, ``[n_agents]`` each, as ``train()`` computes them."""
    return actor_loss_terms(
        model.actor.forward_with_preactivation, model.critic, data, model._action_parts, model.actor_reg_coef
    )
