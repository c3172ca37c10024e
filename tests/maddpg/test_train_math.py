"""The update equations: critic targets, termination masking, per-agent rewards, actor gradients, Polyak targets."""

import copy
from typing import Any

import numpy as np
import pytest
import torch as th

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.common.policies import AgentCritic
from sb3_maddpg.envs import make_simple_spread
from tests.loss_helpers import team_actor_terms, team_critic_losses
from tests.settings import FILLS_THE_BUFFER_ONLY

pytestmark = [FILLS_THE_BUFFER_ONLY]  # a side effect of the tests' short setups (tests/settings.py)

BATCH = 8


@pytest.mark.parametrize("scheme", ["full", "independent", "selected", "attention", "learned_selection"])
def test_critic_target_matches_hand_computation(scheme: str, collected_model: Any, replay_batch: Any) -> None:
    model = collected_model(scheme)
    data = replay_batch(model)
    layout = model.agent_layout
    assert layout is not None
    # Every agent's *target* actor on its own *next* observation, one agent at a time.
    next_actions = th.cat(
        [model.actor_target.mlp.forward_agent(j, data.next_observations[:, layout.obs_slices[j]]) for j in range(3)], dim=1
    )
    with th.no_grad():
        for i in range(3):
            next_q = AgentCritic(model.critic_target, i)(data.next_observations, next_actions, data.selections)[:, 0]
            expected = data.rewards[:, i] + model.gamma * (1 - data.dones[:, i]) * next_q
            assert th.allclose(model._critic_targets(data)[:, i], expected, atol=1e-6)
    # At a true termination the target is the reward alone.
    terminal = data.dones[:, 0] == 1
    assert terminal.any() and not terminal.all()  # the batch has both kinds of rows
    assert th.equal(model._critic_targets(data)[terminal], data.rewards[terminal])


def test_targets_use_target_actors_not_online_ones(collected_model: Any, replay_batch: Any) -> None:
    model = collected_model()
    data = replay_batch(model)
    before = model._critic_targets(data)
    with th.no_grad():
        for param in model.actor.parameters():
            param.add_(1.0)
    assert th.equal(model._critic_targets(data), before)
    with th.no_grad():
        model.actor_target.mlp.weights[0][2].add_(1.0)  # agent 2's target actor
    changed = (model._critic_targets(data) - before).abs().amax(dim=0) > 0
    # With full sharing every critic sees agent 2's target action.
    assert changed.tolist() == [True, True, True]


def test_each_critics_loss_depends_only_on_its_own_reward(collected_model: Any, replay_batch: Any) -> None:
    model = collected_model()
    data = replay_batch(model)
    base = team_critic_losses(model, data).detach()
    rewards = data.rewards.clone()
    rewards[:, 1] += 5.0
    moved = team_critic_losses(model, data._replace(rewards=rewards)).detach()
    assert moved[1] != base[1]
    assert th.equal(moved[[0, 2]], base[[0, 2]])


def test_critic_loss_reaches_only_its_own_critic(collected_model: Any, replay_batch: Any) -> None:
    model = collected_model()
    losses = team_critic_losses(model, replay_batch(model))
    for i in range(3):
        grads = th.autograd.grad(losses[i], list(model.critic.mlp.weights), retain_graph=True)
        for grad in grads:
            assert grad[i].abs().sum() > 0
            assert all(grad[j].abs().sum() == 0 for j in range(3) if j != i)


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3], ids=lambda algorithm: algorithm.__name__)
@pytest.mark.parametrize("scheme", ["full", "actions", "selected", "attention", "learned_selection"])
def test_actor_loss_reaches_only_its_own_actor(
    scheme: str, algorithm: type[MADDPG], collected_model: Any, replay_batch: Any
) -> None:
    model = collected_model(scheme, algorithm=algorithm)
    losses = team_actor_terms(model, replay_batch(model)).total
    params = list(model.actor.parameters())
    for i in range(3):
        for grad in th.autograd.grad(losses[i], params, retain_graph=True):
            assert grad[i].abs().sum() > 0
            assert all(grad[j].abs().sum() == 0 for j in range(3) if j != i)


def test_actor_loss_takes_other_agents_actions_from_the_sample(collected_model: Any, replay_batch: Any) -> None:
    model = collected_model()
    data = replay_batch(model)
    before = team_actor_terms(model, data).total.detach()
    with th.no_grad():
        model.actor.mlp.weights[-1][1].add_(1.0)  # change agent 1's actor only
    after = team_actor_terms(model, data).total.detach()
    assert after[1] != before[1]
    assert th.equal(after[[0, 2]], before[[0, 2]])
    # ...while the sampled actions of agent 1 do matter to critic 0 (it sees them).
    actions = data.actions.clone()
    actions[:, 5:10] = -actions[:, 5:10]
    assert team_actor_terms(model, data._replace(actions=actions)).total[0] != after[0]


@pytest.mark.parametrize("scheme", ["full", "attention", "learned_selection"])
def test_one_update_moves_targets_by_polyak_average(scheme: str, collected_model: Any) -> None:
    model = collected_model(scheme)
    old_actor_target = copy.deepcopy(model.actor_target.state_dict())
    old_critic_target = copy.deepcopy(model.critic_target.state_dict())
    old_actor = copy.deepcopy(model.actor.state_dict())
    old_critic = copy.deepcopy(model.critic.state_dict())
    model.train(gradient_steps=1, batch_size=BATCH)
    # A learned extractor's weights (encoders, attention, scores) are in the critic's state and move with it.
    extractor_weights = [name for name in old_critic if name.startswith("extractors.")]
    assert bool(extractor_weights) == (scheme != "full")
    assert all(not th.equal(model.critic.state_dict()[name], old_critic[name]) for name in extractor_weights)
    for online, target, old_target, old_online in (
        (model.actor, model.actor_target, old_actor_target, old_actor),
        (model.critic, model.critic_target, old_critic_target, None),
    ):
        new_online, new_target = online.state_dict(), target.state_dict()
        for name, value in new_target.items():
            expected = (1 - model.tau) * old_target[name] + model.tau * new_online[name]
            assert th.allclose(value, expected, atol=1e-6), name
        if old_online is not None:  # the online actor did move
            assert any(not th.equal(new_online[name], old_online[name]) for name in new_online)


def _per_agent_step_norms(before: list[th.Tensor], after: list[th.Tensor]) -> th.Tensor:
    """The norm of each agent's parameter change, over all its stacked tensors ``[n_agents, ...]``, ``[n_agents]``."""
    return th.stack([(a.detach() - b).pow(2).flatten(1).sum(1) for b, a in zip(before, after)]).sum(0).sqrt()


def sgd_model(scheme: str, max_grad_norm: float | None) -> MADDPG:
    """A model whose step is minus its (clipped) gradient: SGD at learning rate 1, after 60 collected steps."""
    model = MADDPG(
        "MlpPolicy",
        make_simple_spread(n_agents=3),
        critic_sharing=scheme,
        learning_rate=1.0,
        max_grad_norm=max_grad_norm,
        policy_kwargs=dict(net_arch=[16, 16], optimizer_class=th.optim.SGD),
        learning_starts=10_000,
        buffer_size=1_000,
        batch_size=BATCH,
        seed=0,
    )
    model.learn(60)
    return model


@pytest.mark.parametrize("max_grad_norm", [1e-3, None])
def test_each_agents_whole_gradient_is_clipped(max_grad_norm: float | None) -> None:
    """With SGD at learning rate 1 a step is minus the gradient: each agent's step norm is its clipped gradient norm."""
    model = sgd_model("full", max_grad_norm)
    actor_before = [p.detach().clone() for p in model.actor.parameters()]
    critic_before = [p.detach().clone() for p in model.critic.parameters()]
    model.train(gradient_steps=1, batch_size=BATCH)
    actor_steps = _per_agent_step_norms(actor_before, list(model.actor.parameters()))
    critic_steps = _per_agent_step_norms(critic_before, list(model.critic.parameters()))
    if max_grad_norm is not None:
        # Every agent's whole gradient was longer and is brought down to max_grad_norm, each agent on its own.
        assert th.allclose(actor_steps, th.full((3,), max_grad_norm), rtol=1e-3), actor_steps
        assert th.allclose(critic_steps, th.full((3,), max_grad_norm), rtol=1e-3), critic_steps
    else:  # the same step unclipped is far longer: the clipped case above is not vacuous
        assert actor_steps.min() > 10 * 1e-3 and critic_steps.min() > 10 * 1e-3, (actor_steps, critic_steps)


@pytest.mark.parametrize("scheme", ["attention", "learned_selection"])
def test_each_critics_gradient_is_clipped_with_its_extractors(scheme: str) -> None:
    """Learned critics: agent i's critic step is its network slice and its extractor's parameters, clipped together."""
    model = sgd_model(scheme, 1e-3)
    mlp_before = [p.detach().clone() for p in model.critic.mlp.parameters()]
    extractors_before = [[p.detach().clone() for p in e.parameters()] for e in model.critic.extractors]
    model.train(gradient_steps=1, batch_size=BATCH)
    mlp_steps = _per_agent_step_norms(mlp_before, list(model.critic.mlp.parameters()))
    for i, (before, extractor) in enumerate(zip(extractors_before, model.critic.extractors)):
        extractor_step = sum((a.detach() - b).pow(2).sum() for b, a in zip(before, extractor.parameters()))
        assert extractor_step > 0  # the extractor learns
        assert float((mlp_steps[i] ** 2 + extractor_step).sqrt()) == pytest.approx(1e-3, rel=1e-3)


def test_learning_rate_schedule_reaches_both_optimizers(collected_model: Any) -> None:
    model = collected_model(learning_rate=lambda progress: 0.02 * progress)
    model._current_progress_remaining = 0.25
    model.train(gradient_steps=1, batch_size=BATCH)
    for optimizer in (model.actor.optimizer, model.critic.optimizer):
        assert optimizer.param_groups[0]["lr"] == pytest.approx(0.005)


def test_targets_stay_in_eval_mode_and_frozen(collected_model: Any) -> None:
    model = collected_model()
    model.policy.set_training_mode(True)
    assert model.actor.training and model.critic.training
    assert not model.actor_target.training and not model.critic_target.training
    assert not any(param.requires_grad for param in model.critic_target.parameters())
    model.policy.set_training_mode(False)
    assert not model.actor.training and not model.critic.training


def test_truncation_bootstraps_in_stored_transitions(collected_model: Any) -> None:
    """simple_spread ends by truncation at max_cycles: its last transition must keep bootstrapping."""
    model = collected_model()  # 60 steps: episodes of 25 end at rows 24 and 49
    buffer = model.replay_buffer
    assert buffer.timeouts[24, 0] == 1 and buffer.timeouts[49, 0] == 1
    assert buffer.timeouts[:60].sum() == 2
    assert buffer.dones[:60].sum() == 0  # no true termination: every row bootstraps


def test_without_timeout_handling_truncation_stops_bootstrapping(collected_model: Any) -> None:
    """replay_buffer_kwargs=dict(handle_timeout_termination=False): SB3's meaning, a time limit is a terminal."""
    model = collected_model(replay_buffer_kwargs=dict(handle_timeout_termination=False))
    buffer = model.replay_buffer
    assert buffer.dones[:60, 0].sum(axis=0).tolist() == [2, 2, 2]  # rows 24 and 49, every agent
    assert buffer.dones[24, 0].tolist() == buffer.dones[49, 0].tolist() == [1, 1, 1]
    assert buffer.timeouts[:60].sum() == 0
    data = buffer._get_samples(np.array([24, 49, 10]))
    targets = model._critic_targets(data)
    assert th.equal(targets[:2], data.rewards[:2])  # y = r at the time limit
    assert not th.equal(targets[2], data.rewards[2])  # a mid-episode row bootstraps


def test_caller_kwargs_are_not_modified() -> None:
    policy_kwargs = dict(net_arch=[8])
    replay_buffer_kwargs: dict = {}
    MADDPG("MlpPolicy", make_simple_spread(n_agents=3), policy_kwargs=policy_kwargs, replay_buffer_kwargs=replay_buffer_kwargs)
    assert policy_kwargs == dict(net_arch=[8])
    assert replay_buffer_kwargs == {}
