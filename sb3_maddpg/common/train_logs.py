"""What a team's training writes to SB3's logger: per-agent values and the team's mean, under ``train/``; each agent's
episode return beside SB3's team return, under ``rollout/``; and what a gradient step reports (:class:`StepLosses`),
summarised over a train call."""

from collections.abc import Iterable, Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
import torch as th
from stable_baselines3.common.logger import Logger

from sb3_maddpg.common.losses import ActorLossTerms


def record_per_agent(logger: Logger, agent_ids: Sequence[str], values: Mapping[str, Sequence[float | None]]) -> None:
    """
    Record each agent's value as ``train/<agent>/<name>`` and the team's mean over the agents that have one as
    ``train/<name>``.

    :param logger: SB3's logger.
    :param agent_ids: The agents, in layout order.
    :param values: Per name, one value per agent (or ``None`` for an agent that has none).
    """
    for name, per_agent in values.items():
        given = [value for value in per_agent if value is not None]
        logger.record(f"train/{name}", sum(given) / len(given))
        for agent, value in zip(agent_ids, per_agent):
            if value is not None:
                logger.record(f"train/{agent}/{name}", value)


def record_losses(logger: Logger, agent_ids: Sequence[str], n_updates: int, losses: Mapping[str, th.Tensor]) -> None:
    """
    Record a train call's losses: each agent's mean over the call's gradient steps, and the team's.

    :param logger: SB3's logger.
    :param agent_ids: The agents, in layout order.
    :param n_updates: The gradient steps taken so far.
    :param losses: Per name (e.g. ``"critic_loss"``), the per-agent means, ``[n_agents]`` each.
    """
    per_agent = th.stack(tuple(losses.values())).tolist()  # one transfer from the device
    logger.record("train/n_updates", n_updates, exclude="tensorboard")
    record_per_agent(logger, agent_ids, dict(zip(losses, per_agent)))


def record_critic_diagnostics(logger: Logger, agent_ids: Sequence[str], diagnostics: Sequence[Mapping[str, float]]) -> None:
    """
    Record what each critic's features extractor reports (e.g. whom an attention critic listens to).

    :param logger: SB3's logger.
    :param agent_ids: The agents, in layout order.
    :param diagnostics: One summary per critic (``MultiAgentCritic.diagnostics()``); a critic may lack a name.
    """
    names = sorted({name for summary in diagnostics for name in summary})
    record_per_agent(logger, agent_ids, {name: [summary.get(name) for summary in diagnostics] for name in names})


def record_agent_returns(logger: Logger, agent_ids: Sequence[str], episodes: Iterable[Mapping[str, Any]]) -> None:
    """
    Record each agent's mean episode return as ``rollout/<agent_id>/ep_rew_mean``, over the episodes of SB3's
    ``ep_info_buffer`` (the ones its ``rollout/ep_rew_mean`` averages) that carry ``agent_returns`` (every one the model
    saw finish; not those a save of an earlier version holds); nothing without one.

    :param logger: SB3's logger.
    :param agent_ids: The agents, in layout order.
    :param episodes: SB3's episode statistics (``model.ep_info_buffer``), each a Monitor's ``info["episode"]``.
    """
    returns = [episode["agent_returns"] for episode in episodes if "agent_returns" in episode]
    if not returns:
        return
    for agent, mean in zip(agent_ids, np.mean(returns, axis=0).tolist()):
        logger.record(f"rollout/{agent}/ep_rew_mean", mean)


LOSS_NAMES = ("critic_loss", "actor_loss", "actor_reg_loss", "action_saturation")
"""What a step reports, ``[M, n_agents]`` each (the last three only when the actors were updated)."""


class StepLosses(NamedTuple):
    """What a step reports, ``[M, n_agents]`` each, detached; the actors' parts None when the actors were not due."""

    critic_loss: th.Tensor
    """The critics' losses (MATD3: the mean of the twins')."""
    actor_loss: th.Tensor | None
    actor_reg_loss: th.Tensor | None
    action_saturation: th.Tensor | None


def step_losses(critic_loss: th.Tensor, actor_terms: ActorLossTerms | None) -> StepLosses:
    """
    :param critic_loss: Each agent's critic loss (the mean over its critics).
    :param actor_terms: The actors' loss terms, or None when the actors were not due.
    :return: What the step reports, detached.
    """
    if actor_terms is None:
        return StepLosses(critic_loss.detach(), None, None, None)
    policy_loss, reg_loss = actor_terms.policy_loss.detach(), actor_terms.reg_loss.detach()
    return StepLosses(critic_loss.detach(), policy_loss, reg_loss, actor_terms.saturation)


def summarise_steps(steps: Sequence[StepLosses]) -> dict[str, th.Tensor]:
    """
    :param steps: The losses of a train call's steps.
    :return: Each of :data:`LOSS_NAMES`' mean over the steps that have it, ``[M, n_agents]`` each (the actors' parts
        only when some step updated the actors: a delayed one, as TD3's, records none).
    """
    means: dict[str, th.Tensor] = {}
    for index, name in enumerate(LOSS_NAMES):
        values: list[th.Tensor] = [value for step in steps if (value := step[index]) is not None]
        if values:
            means[name] = th.stack(values).mean(0)
    return means
