"""The losses on one team's batch: the targets, the critics' and actors' losses, with values set by hand."""

import math

import pytest
import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.common.argument_ranges import TEAM_ALGORITHM_RANGES
from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.losses import (
    SATURATION_THRESHOLD,
    ActionParts,
    ActorLossTerms,
    actor_loss_terms,
    critic_losses,
    critic_targets,
    team_critic_targets,
)
from sb3_maddpg.envs import make_simple_spread
from tests.loss_helpers import team_actor_terms, team_critic_losses

FAST = dict(learning_starts=50, batch_size=32, buffer_size=1_000, train_freq=25, policy_kwargs=dict(net_arch=[16]))


def trained(seed: int, scheme: str) -> MADDPG:
    selection = 1 if scheme == "selected" else None
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=3), critic_sharing=scheme, selector=selection, seed=seed, **FAST)
    model.learn(100)
    return model


@pytest.mark.parametrize("scheme", ["full", "selected"])
def test_a_trained_teams_targets_and_losses_by_hand(scheme: str) -> None:
    """y_i = r_i + gamma * (1 - done_i) * Q_i'(o', mu'(o')) at the model's gamma, each critic's loss its mean squared TD
    error, and the actor terms as ``train`` computes them, each ``[n_agents]``."""
    model = trained(0, scheme)
    model.gamma, model.actor_reg_coef = 0.9, 0.02
    rows = model.replay_buffer.sample(32)
    with th.no_grad():
        next_selections = rows.selections if rows.next_selections is None else rows.next_selections
        next_q = model.critic_target(rows.next_observations, model.actor_target(rows.next_observations), next_selections)
        expected = rows.rewards + 0.9 * (1.0 - rows.dones) * next_q
    targets = team_critic_targets(
        model.actor_target, model.critic_target, rows, model.gamma, model._action_parts.continuous, None
    )
    th.testing.assert_close(targets, expected)
    losses = critic_losses(model.critic, rows, targets)
    squared = (model.critic(rows.observations, rows.actions, rows.selections) - targets) ** 2
    th.testing.assert_close(losses, squared.mean(dim=0))
    assert targets.shape == (32, 3) and losses.shape == (3,) and th.equal(losses, team_critic_losses(model, rows))
    terms = team_actor_terms(model, rows)
    assert all(term.shape == (3,) for term in terms) and terms.reg_loss.abs().sum() > 0


def test_twin_critics_broadcast_over_the_targets() -> None:
    model = trained(0, "full")
    batch = model.replay_buffer.sample(32)
    targets = model._critic_targets(batch)

    def twins(obs: th.Tensor, actions: th.Tensor, selections: th.Tensor | None) -> th.Tensor:
        q = model.critic(obs, actions, selections)
        return th.stack((q, q + 1.0))  # [2, batch, n_agents]

    both = critic_losses(twins, batch, targets)
    assert both.shape == (2, 3)
    th.testing.assert_close(both[0], critic_losses(model.critic, batch, targets))
    th.testing.assert_close(both[1], critic_losses(lambda *args: model.critic(*args) + 1.0, batch, targets))


def test_total_is_the_sum_of_the_parts() -> None:
    terms = ActorLossTerms(th.tensor([1.0, 2.0]), th.tensor([0.5, 0.25]), th.zeros(2))
    assert th.equal(terms.total, th.tensor([1.5, 2.25]))


@pytest.mark.parametrize("next_selected", [None, 2])
def test_the_target_reads_the_next_selection_when_the_batch_has_one(next_selected: int | None) -> None:
    # A target critic that returns the index its agent selected: y = r + gamma * (1 - done) * that index.
    selections = th.tensor([[[1], [0], [0]], [[2], [2], [1]]])
    batch = MultiAgentReplayBufferSamples(
        observations=th.zeros(2, 6),
        actions=th.zeros(2, 6),
        next_observations=th.zeros(2, 6),
        dones=th.tensor([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]),
        rewards=th.ones(2, 3),
        selections=selections,
        next_selections=None if next_selected is None else th.tensor([[[2], [2], [1]], [[1], [0], [0]]]),
    )

    def target_q(observations: th.Tensor, actions: th.Tensor, chosen: th.Tensor) -> th.Tensor:
        return chosen[..., 0].float()

    targets = critic_targets(th.zeros_like, target_q, batch, gamma=0.5)
    if next_selected is None:  # the stored selection: indices 1, 0, (0) and 2, 2, 1
        expected = [[1.5, 1.0, 1.0], [2.0, 2.0, 1.5]]
    else:  # the next one: 2, 2, (1) and 1, 0, 0
        expected = [[2.0, 2.0, 1.0], [1.5, 1.0, 1.0]]
    assert targets.tolist() == expected


# ---------------------------------------------------------------------------------------------------------------
# Values set by hand: networks that return fixed numbers, so each loss is known without running a model.

TWO_BY_TWO = AgentLayout(("a", "b"), (2, 2), (2, 2))  # two continuous agents, two action components each


def fixed_batch(n_rows: int, active: th.Tensor | None, n_agents: int = 2) -> MultiAgentReplayBufferSamples:
    """A batch of ``n_rows`` zero rows for a team of ``n_agents`` agents (2 observation and 2 action components each):
    the networks below decide every value."""
    zeros = th.zeros(n_rows, 2 * n_agents)
    return MultiAgentReplayBufferSamples(
        observations=zeros,
        actions=zeros,
        next_observations=zeros,
        dones=th.zeros(n_rows, n_agents),
        rewards=th.zeros(n_rows, n_agents),
        selections=None,
        active=active,
    )


def test_a_departed_agents_terms_are_the_mean_over_its_active_rows_only() -> None:
    """Each agent's critic loss and policy loss average its active rows: the sum over them divided by their count
    (an agent with none gets 0, not a division by zero)."""
    q = th.tensor([[1.0, 2.0, 0.5], [2.0, 2.0, 0.5], [3.0, 2.0, 0.5], [4.0, 6.0, 0.5]])  # [rows, agents]
    active = th.tensor([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])

    def critic(observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None) -> th.Tensor:
        return q  # [rows, agents], whatever the actions

    batch = fixed_batch(4, active, n_agents=3)
    # Squared errors against targets of 0: agent 0's active rows hold 1 and 4, agent 1's 4 and 36, agent 2 has none.
    losses = critic_losses(critic, batch, th.zeros(4, 3))
    assert losses.tolist() == [(1 + 4) / 2, (4 + 36) / 2, 0.0]

    def policy(observations: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        return th.zeros(4, 6), th.zeros(4, 6)

    parts = ActionParts.of(AgentLayout(("a", "b", "c"), (2, 2, 2), (2, 2, 2)))
    terms = actor_loss_terms(policy, critic, batch, parts, reg_coef=0.0)
    assert terms.policy_loss.tolist() == [-(1 + 2) / 2, -(2 + 6) / 2, 0.0]  # -Q's mean over the same rows


@pytest.mark.parametrize("active", [None, th.ones(3, 2)], ids=["whole team", "agents that may leave"])
def test_an_action_at_the_saturation_threshold_is_not_saturated_and_one_just_above_is(active: th.Tensor | None) -> None:
    """``|a| > SATURATION_THRESHOLD`` counts, as documented: a component exactly at the threshold (as the float32
    actions hold it) does not; the next float32 above it does, either sign; the same with or without ``active``."""
    at = th.tensor(SATURATION_THRESHOLD, dtype=th.float32)
    above = th.nextafter(at, th.tensor(1.0))
    # Rows 0 and 1: agent a's two components at +-threshold, agent b's just above it; row 2: all zero.
    row_a = th.stack((at, -at))
    actions = th.stack([th.cat((row_a, th.stack((above, -above)))), th.cat((row_a, th.stack((-above, above)))), th.zeros(4)])

    def policy(observations: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        return actions, th.zeros(3, 4)

    def critic(observations: th.Tensor, joint: th.Tensor, selections: th.Tensor | None) -> th.Tensor:
        return th.zeros(3, 2)

    terms = actor_loss_terms(policy, critic, fixed_batch(3, active), ActionParts.of(TWO_BY_TWO), reg_coef=0.0)
    th.testing.assert_close(terms.saturation, th.tensor([0.0, 2 / 3]))


@pytest.mark.parametrize("active", [None, th.tensor([[1.0, 1.0], [1.0, 1.0], [0.0, 1.0]])], ids=["whole team", "a leaves"])
def test_the_regulariser_is_the_coefficient_times_the_mean_squared_preactivation_over_active_rows(
    active: th.Tensor | None,
) -> None:
    """``reg_coef`` times the mean, over the agent's (active) rows, of its own components' mean squared pre-``tanh``
    output (Lowe et al.'s ``p_reg``), for any coefficient in (0, 1] too."""
    # Agent a's pre-activations per row: (1, 3), (2, 2), (5, 5), mean squares 5, 4, 25; agent b's (0, 2): 2 each row.
    pre = th.tensor([[1.0, 3.0, 0.0, 2.0], [2.0, 2.0, 0.0, 2.0], [5.0, 5.0, 0.0, 2.0]])

    def policy(observations: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        return th.tanh(pre), pre

    def critic(observations: th.Tensor, joint: th.Tensor, selections: th.Tensor | None) -> th.Tensor:
        return th.zeros(3, 2)

    terms = actor_loss_terms(policy, critic, fixed_batch(3, active), ActionParts.of(TWO_BY_TWO), reg_coef=0.5)
    mean_a = (5 + 4 + 25) / 3 if active is None else (5 + 4) / 2  # a left before row 2: rows 0 and 1 only
    th.testing.assert_close(terms.reg_loss, th.tensor([0.5 * mean_a, 0.5 * 2.0]))
    th.testing.assert_close(terms.total, terms.policy_loss + terms.reg_loss)


def test_a_regulariser_weight_must_be_finite_and_at_least_zero() -> None:
    """0 turns the regulariser off and is taken; anything below it, or not finite, is refused by name."""
    valid = TEAM_ALGORITHM_RANGES["actor_reg_coef"]
    valid.check("actor_reg_coef", 0.0)
    for refused in (-1e-3, math.inf, math.nan):
        with pytest.raises(ValueError, match=r"^actor_reg_coef\b.* >= 0"):
            valid.check("actor_reg_coef", refused)


def test_a_gradient_clip_must_be_above_zero_or_none() -> None:
    """None turns clipping off and the least positive norm is taken; 0 (every gradient zeroed) and below are refused."""
    valid = TEAM_ALGORITHM_RANGES["max_grad_norm"]
    for taken in (None, 1e-9):
        valid.check("max_grad_norm", taken)
    for refused in (0.0, -0.5):
        with pytest.raises(ValueError, match=r"^max_grad_norm\b.* > 0"):
            valid.check("max_grad_norm", refused)
