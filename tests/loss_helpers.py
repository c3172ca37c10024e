"""A model's losses on a plain replay batch (one team, no member dimension), through :mod:`sb3_maddpg.losses`."""

import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.losses import ActorLossTerms, actor_loss_terms, critic_losses, critic_targets, one_member


def team_critic_losses(model: MADDPG, data: MultiAgentReplayBufferSamples) -> th.Tensor:
    """:return: Each critic's loss, ``[n_agents]``, as ``train()`` computes it."""
    batch, team = one_member(data), model._team
    targets = critic_targets(team.target_actions, team.target_q, batch, model.gamma)
    return critic_losses(team.q, batch, targets)[0]


def team_actor_terms(model: MADDPG, data: MultiAgentReplayBufferSamples) -> ActorLossTerms:
    """:return: The actor loss terms, ``[n_agents]`` each, as ``train()`` computes them."""
    team = model._team
    terms = actor_loss_terms(team.policy, team.q, one_member(data), model._action_parts, model.actor_reg_coef)
    return ActorLossTerms(*(term[0] for term in terms))
