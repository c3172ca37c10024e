"""MATD3: the min of the twin target critics, clipped target smoothing (none on one-hots, none when acting), delayed
actor and target updates, what each critic sees (MADDPG and MATD3 alike), the actors' first-critic gradient, save/load."""

import functools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch as th

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.common.losses import critic_losses, smooth_target_actions, target_actions
from sb3_maddpg.common.policies import AgentCritic
from sb3_maddpg.envs import PettingZooToGym, make_simple_spread
from sb3_maddpg.matd3.policies import MATD3Policy, TwinMultiAgentCritic
from tests.mixed_team import MixedTeam
from tests.settings import UPDATES_PER_10_TRANSITIONS

pytestmark = pytest.mark.filterwarnings("ignore:learn\\(\\) ended at step")  # make_model() only collects

BATCH = 8
N_AGENTS = 3
ALGORITHMS = {"MADDPG": MADDPG, "MATD3": MATD3}
PER_AGENT_MAP = {"agent_0": "full", "agent_1": "independent", "agent_2": "actions"}


@pytest.fixture
def collected_model(collected_model: Any) -> Any:
    """The shared fixture's model (conftest.py), a MATD3 unless a test asks for another algorithm."""
    return functools.partial(collected_model, algorithm=MATD3)


def states(module: th.nn.Module) -> dict[str, th.Tensor]:
    return {name: value.detach().clone() for name, value in module.state_dict().items()}


def moved(before: dict[str, th.Tensor], module: th.nn.Module) -> bool:
    return any(not th.equal(before[name], value) for name, value in module.state_dict().items())


def one_update(model: MADDPG) -> None:
    """One gradient step with fixed random draws (the batch, the smoothing noise)."""
    np.random.seed(7)
    th.manual_seed(7)
    model.train(gradient_steps=1, batch_size=BATCH)


def is_one_hot(values: th.Tensor) -> bool:
    """Every row is one 1 and the rest -1 (a discrete agent's action in the [-1, 1] space)."""
    return bool(th.isin(values, th.tensor([-1.0, 1.0])).all() and ((values == 1.0).sum(dim=-1) == 1).all())


# --- The critics' target -----------------------------------------------------------------------------------------


@pytest.mark.parametrize("scheme", ["full", "selected", "attention"])
def test_critic_target_is_the_min_of_the_two_target_critics_by_hand(
    scheme: str, collected_model: Any, replay_batch: Any
) -> None:
    model = collected_model(scheme)
    data = replay_batch(model)
    layout = model.agent_layout
    assert layout is not None
    th.manual_seed(5)
    targets = model._critic_targets(data)
    # By hand: each target actor on its own next observation, TD3's clipped noise, then per agent the smaller twin.
    next_actions = th.cat(
        [model.actor_target.mlp.forward_agent(j, data.next_observations[:, layout.obs_slices[j]]) for j in range(3)], dim=1
    )
    th.manual_seed(5)
    noise = (th.randn(BATCH, layout.action_dim) * model.target_policy_noise).clamp(-0.5, 0.5)
    next_actions = (next_actions + noise).clamp(-1.0, 1.0)
    twin_1_smaller, twin_2_smaller = False, False
    with th.no_grad():
        for i in range(N_AGENTS):
            q1 = AgentCritic(model.critic_target, i)(data.next_observations, next_actions, data.selections)[:, 0]
            q2 = AgentCritic(model.critic_target.twin, i)(data.next_observations, next_actions, data.selections)[:, 0]
            expected = data.rewards[:, i] + model.gamma * (1 - data.dones[:, i]) * th.minimum(q1, q2)
            assert th.allclose(targets[:, i], expected, atol=1e-6)
            live = data.dones[:, i] == 0
            twin_1_smaller |= bool((q1 < q2)[live].any())
            twin_2_smaller |= bool((q2 < q1)[live].any())
    assert twin_1_smaller and twin_2_smaller  # the min is taken row by row, not one twin throughout


@pytest.mark.parametrize("scheme", ["full", "attention"])
def test_the_critic_update_descends_both_twins_losses_at_that_target(scheme: str, collected_model: Any) -> None:
    """With SGD at learning rate 1 and no clipping, train()'s critic step is minus the gradient of both twins' losses
    against :meth:`_critic_targets` (the smoothed min target above), on the same batch and the same noise."""
    model = collected_model(
        scheme, learning_rate=1.0, max_grad_norm=None, policy_kwargs=dict(net_arch=[16, 16], optimizer_class=th.optim.SGD)
    )
    np.random.seed(7)
    data = model.replay_buffer.sample(BATCH)
    th.manual_seed(7)
    targets = model._critic_targets(data)
    losses = critic_losses(model.critic.trained_q, data, targets)
    params = list(model.critic.parameters())
    grads = th.autograd.grad(losses.sum(), params, allow_unused=True)
    expected = [p.detach() - (0 if g is None else g) for p, g in zip(params, grads)]
    twin_1, twin_2 = states(model.critic.mlp), states(model.critic.twin)
    one_update(model)
    for param, value in zip(model.critic.parameters(), expected):
        assert th.allclose(param, value, atol=1e-6)
    assert moved(twin_1, model.critic.mlp) and moved(twin_2, model.critic.twin)


@pytest.mark.parametrize("scheme", ["attention", "learned_selection"])
def test_twin_critics_are_independent_networks_with_their_own_extractors(scheme: str, collected_model: Any) -> None:
    model = collected_model(scheme)
    assert isinstance(model.policy, MATD3Policy) and isinstance(model.critic, TwinMultiAgentCritic)
    first, second = model.critic.extractors, model.critic.twin.extractors
    assert all(a is not b and type(a) is type(b) for a, b in zip(first, second))
    first_params = {id(p) for p in model.critic.mlp.parameters()} | {id(p) for p in first.parameters()}
    assert first_params.isdisjoint(id(p) for p in model.critic.twin.parameters())
    assert not th.equal(model.critic.mlp.weights[0], model.critic.twin.mlp.weights[0])  # initialised apart
    assert not th.equal(next(first[0].parameters()), next(second[0].parameters()))
    # One critic optimiser over both twins, as SB3's TD3.
    optimised = {id(p) for group in model.critic.optimizer.param_groups for p in group["params"]}
    assert optimised == {id(p) for p in model.critic.parameters()}


# --- Target policy smoothing ----------------------------------------------------------------------------------------


def test_smoothing_noise_is_clipped_and_absent_on_discrete_one_hots() -> None:
    th.manual_seed(0)
    actions = th.zeros(1, 4096, 5)
    actions[..., 2:] = -1.0
    actions[..., 3] = 1.0  # components 2..4: a discrete agent's one-hot
    continuous = th.tensor([True, True, False, False, False])
    smoothed = smooth_target_actions(actions, noise_std=1.0, noise_clip=0.5, continuous=continuous)
    noise = smoothed[..., :2]
    assert noise.abs().max() == 0.5 and (noise.abs() == 0.5).float().mean() > 0.5  # clipped: P(|N(0,1)| > .5) = .62
    assert (noise.abs() < 0.5).any() and noise.std() > 0.1
    assert th.equal(smoothed[..., 2:], actions[..., 2:])
    # The sum stays in [-1, 1].
    near_edge = smooth_target_actions(th.full((1, 4096, 5), 0.9), 1.0, 0.5, continuous)
    assert near_edge.max() == 1.0 and near_edge[..., :2].min() >= 0.4 - 1e-6


def model_target_actions(model: MATD3, observations: th.Tensor) -> th.Tensor:
    """:return: The target actions ``train`` computes for ``model`` now (its settings read at the call)."""
    return target_actions(model.actor_target, observations, model._action_parts.continuous, model._step_settings().smoothing)


def test_a_mixed_teams_target_actions_keep_the_one_hot_and_smooth_the_continuous_agent() -> None:
    model = MATD3("MlpPolicy", PettingZooToGym(MixedTeam()), learning_starts=1_000, target_policy_noise=1.0, seed=0)
    model.learn(40)
    next_obs = th.as_tensor(model.replay_buffer.next_observations[:40, 0])
    smoothed = model_target_actions(model, next_obs)
    assert is_one_hot(smoothed[:, 1:])
    with th.no_grad():
        offset = smoothed[:, 0] - model.actor_target(next_obs)[:, 0]
    assert offset.abs().max() <= 0.5 + 1e-6 and offset.abs().max() > 0.1


def test_no_smoothing_noise_when_acting_or_evaluating(collected_model: Any) -> None:
    model = collected_model(target_policy_noise=1.0, target_noise_clip=1.0)
    obs = model.replay_buffer.observations[:16, 0]
    first, _ = model.predict(obs, deterministic=True)
    second, _ = model.predict(obs, deterministic=True)
    with th.no_grad():
        expected = model.policy.unscale_action(model.actor(th.as_tensor(obs)).numpy())
    np.testing.assert_array_equal(first, second)
    np.testing.assert_allclose(first, expected, atol=1e-6)
    env = make_simple_spread(n_agents=N_AGENTS)
    assert evaluate_team(model, env, n_episodes=2, seed=3) == evaluate_team(model, env, n_episodes=2, seed=3)


# --- Delayed updates ------------------------------------------------------------------------------------------------


def test_actor_and_targets_move_only_every_policy_delay_critic_updates(collected_model: Any) -> None:
    model = collected_model(policy_delay=3)
    moves = []
    for _ in range(6):
        before = {name: states(getattr(model, name)) for name in ("critic", "actor", "actor_target", "critic_target")}
        model.train(gradient_steps=1, batch_size=BATCH)
        moves.append({name: moved(state, getattr(model, name)) for name, state in before.items()})
    assert [m["critic"] for m in moves] == [True] * 6
    for name in ("actor", "actor_target", "critic_target"):
        assert [m[name] for m in moves] == [False, False, True, False, False, True], name
    # Counted over the model's updates, inside a train() call as across calls: updates 7 and 8 move no actor, 9 does.
    before_actor = states(model.actor)
    model.train(gradient_steps=2, batch_size=BATCH)
    assert not moved(before_actor, model.actor)
    model.train(gradient_steps=1, batch_size=BATCH)
    assert moved(before_actor, model.actor)


# --- What each critic sees: MADDPG and MATD3 alike ------------------------------------------------------------------


def visible(scheme: Any, i: int, selections: th.Tensor | None) -> tuple[list[set[int]], list[set[int]]]:
    """Row by row, whose observations and whose actions critic i may see (the paper's Table 1)."""
    if isinstance(scheme, dict):
        scheme = scheme[f"agent_{i}"]
    everyone, alone = set(range(N_AGENTS)), {i}
    obs, actions = {
        "independent": (alone, alone),
        "full": (everyone, everyone),
        "observations": (everyone, alone),
        "actions": (alone, everyone),
        "attention": (everyone, everyone),
        # Straight-through: the backward pass is the softmax mixture of every other agent's slot (the value sees only
        # the k chosen agents: tests/sharing/test_attention.py)
        "learned_selection": (everyone, everyone),
        "selected": (None, None),
    }[scheme]
    if obs is None:
        assert selections is not None
        rows = [{i, *selections[b, i].tolist()} for b in range(BATCH)]
        return rows, rows
    return [obs] * BATCH, [actions] * BATCH


@pytest.mark.parametrize("algorithm", list(ALGORITHMS))
@pytest.mark.parametrize(
    "scheme",
    ["independent", "full", "observations", "actions", "selected", "attention", "learned_selection", PER_AGENT_MAP],
    ids=str,
)
def test_each_critics_loss_reaches_exactly_the_inputs_its_scheme_allows(
    algorithm: str, scheme: Any, collected_model: Any, replay_batch: Any
) -> None:
    model = collected_model(scheme, algorithm=ALGORITHMS[algorithm])
    layout = model.agent_layout
    assert layout is not None
    data = replay_batch(model)
    obs, actions = data.observations.clone().requires_grad_(True), data.actions.clone().requires_grad_(True)
    # As train() computes them: its hooks give MATD3's smoothed min target and both twins' losses
    targets = model._critic_targets(data)
    losses = critic_losses(model.critic.trained_q, data._replace(observations=obs, actions=actions), targets)
    twins = losses.reshape(-1, N_AGENTS)  # [n_twins, n_agents]: 1 for MADDPG, 2 for MATD3
    assert twins.shape[0] == (2 if algorithm == "MATD3" else 1)
    selections = data.selections
    for twin in range(twins.shape[0]):
        for i in range(N_AGENTS):
            obs_grad, action_grad = th.autograd.grad(twins[twin, i], (obs, actions), retain_graph=True)
            seen_obs, seen_actions = visible(scheme, i, selections)
            for b in range(BATCH):
                for j in range(N_AGENTS):
                    sees_obs = bool(obs_grad[b, layout.obs_slices[j]].abs().sum() > 0)
                    sees_action = bool(action_grad[b, layout.action_slices[j]].abs().sum() > 0)
                    assert sees_obs == (j in seen_obs[b]), (twin, i, b, j, "observation")
                    assert sees_action == (j in seen_actions[b]), (twin, i, b, j, "action")


@pytest.mark.parametrize("scheme", ["full", "attention"])
def test_each_twins_loss_moves_only_its_own_agents_own_twin(scheme: str, collected_model: Any, replay_batch: Any) -> None:
    model = collected_model(scheme)
    data = replay_batch(model)
    losses = critic_losses(model.critic.trained_q, data, model._critic_targets(data))
    critics = (model.critic, model.critic.twin)
    for twin in range(2):
        for i in range(N_AGENTS):
            model.critic.zero_grad()
            losses[twin, i].backward(retain_graph=True)
            for other, critic in enumerate(critics):
                for weight in critic.mlp.weights:
                    grad = th.zeros_like(weight) if weight.grad is None else weight.grad
                    reached = (grad.abs().sum(dim=(1, 2)) > 0).tolist()
                    assert reached == [other == twin and j == i for j in range(N_AGENTS)], (twin, i, other)
                for j, extractor in enumerate(critic.extractors):
                    touched = any(p.grad is not None and p.grad.abs().sum() > 0 for p in extractor.parameters())
                    assert touched == (scheme == "attention" and other == twin and j == i)


# --- The actors ascend their first critic -----------------------------------------------------------------------


@pytest.mark.parametrize("scheme", ["full", "attention"])
def test_each_actors_gradient_comes_from_its_first_critic_only(scheme: str, collected_model: Any) -> None:
    reference, changed_twin_2, changed_twin_1 = (collected_model(scheme, policy_delay=1) for _ in range(3))
    actor_before = states(reference.actor)
    with th.no_grad():
        for param in changed_twin_2.critic.twin.parameters():
            param.add_(th.randn_like(param))
        for param in changed_twin_1.critic.mlp.parameters():
            param.add_(th.randn_like(param))
    for model in (reference, changed_twin_2, changed_twin_1):
        one_update(model)
    assert moved(actor_before, reference.actor)
    for name, value in reference.actor.state_dict().items():
        assert th.equal(value, changed_twin_2.actor.state_dict()[name]), name
    assert moved(states(reference.actor), changed_twin_1.actor)  # the first critic does steer the actors


# --- Save and load ----------------------------------------------------------------------------------------------


def assert_same_tree(expected: Any, actual: Any, path: str = "") -> None:
    """Equality of (optimiser) state dicts holding tensors, numbers, lists and dicts."""
    if isinstance(expected, dict):
        assert isinstance(actual, dict) and set(expected) == set(actual), path
        for key in expected:
            assert_same_tree(expected[key], actual[key], f"{path}/{key}")
    elif isinstance(expected, list | tuple):
        assert len(expected) == len(actual), path
        for index, (a, b) in enumerate(zip(expected, actual)):
            assert_same_tree(a, b, f"{path}/{index}")
    elif isinstance(expected, th.Tensor):
        assert th.equal(expected, actual), path
    else:
        assert expected == actual, path


@pytest.mark.parametrize("scheme", ["full", "selected", "attention"])
def test_save_and_load_round_trip(scheme: str, tmp_path: Path, collected_model: Any) -> None:
    model = collected_model(scheme, policy_delay=3, target_policy_noise=0.3, target_noise_clip=0.4)
    for _ in range(4):  # past a delayed update, and mid-cycle: the delay's phase is saved too
        model.train(gradient_steps=1, batch_size=BATCH)
    model.save(tmp_path / "matd3.zip")
    loaded = MATD3.load(tmp_path / "matd3.zip")
    assert isinstance(loaded.policy, MATD3Policy) and isinstance(
        loaded.critic.twin.extractors[0], type(model.critic.twin.extractors[0])
    )
    assert (loaded.policy_delay, loaded.target_policy_noise, loaded.target_noise_clip) == (3, 0.3, 0.4)
    assert loaded._n_updates == model._n_updates == 4
    assert_same_tree(model.policy.state_dict(), loaded.policy.state_dict())  # both twins, extractors, targets
    assert any(".twin.extractors." in name for name in loaded.policy.state_dict()) == (scheme == "attention")
    assert_same_tree(model.actor.optimizer.state_dict(), loaded.actor.optimizer.state_dict())
    assert_same_tree(model.critic.optimizer.state_dict(), loaded.critic.optimizer.state_dict())
    obs = model.replay_buffer.observations[:8, 0]
    np.testing.assert_array_equal(model.predict(obs, deterministic=True)[0], loaded.predict(obs, deterministic=True)[0])
    # The loaded model trains on as the saved one would have.
    loaded.replay_buffer = model.replay_buffer
    loaded.set_logger(model.logger)
    for trained in (model, loaded):
        for _ in range(2):
            one_update(trained)
    assert_same_tree(model.policy.state_dict(), loaded.policy.state_dict())


# --- End to end -------------------------------------------------------------------------------------------------


def test_refuses_bad_td3_settings() -> None:
    env = make_simple_spread(n_agents=N_AGENTS)
    with pytest.raises(ValueError, match=r"^policy_delay \(.*\) must be an integer >= 1.*, got 0: use 2"):
        MATD3("MlpPolicy", env, policy_delay=0)
    with pytest.raises(ValueError, match=r"^target_noise_clip \(.*\) must be a number >= 0.*, got -0.1: use 0.5"):
        MATD3("MlpPolicy", env, target_noise_clip=-0.1)


def test_matd3_makes_one_update_per_10_transitions_with_finite_losses() -> None:
    model = MATD3("MlpPolicy", make_simple_spread(n_agents=N_AGENTS), seed=0, **UPDATES_PER_10_TRANSITIONS)
    model.learn(400)
    assert model._n_updates == 30  # one critic update per 10 transitions past learning_starts
    logged = model.logger.name_to_value
    assert np.isfinite(logged["train/critic_loss"]) and np.isfinite(logged["train/agent_2/actor_loss"])


def test_a_team_of_continuous_and_discrete_agents_trains(tmp_path: Path) -> None:
    env = PettingZooToGym(MixedTeam())
    model = MATD3("MlpPolicy", env, seed=0, **UPDATES_PER_10_TRANSITIONS)
    model.learn(400)
    assert model._n_updates == 30
    action, _ = model.predict(env.reset(seed=0)[0], deterministic=True)
    assert -1.0 <= action[0] <= 1.0 and sorted(action[1:].tolist()) == [0.0, 0.0, 1.0]
    model.save(tmp_path / "mixed.zip")
    assert MATD3.load(tmp_path / "mixed.zip").agent_layout == env.agent_layout


def test_the_experiments_runner_trains_matd3_with_algo(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from sb3_maddpg.cli.main import main

    argv = ["run", "--config", "smoke", "--name", "smoke_matd3", "--results", str(tmp_path), "--schemes", "full"]
    assert main([*argv, "--seeds", "1", "--algorithm", "matd3", "--dry-run"]) == 0
    assert '"algorithm": "sb3_maddpg:MATD3"' in capsys.readouterr().out
    assert main([*argv, "--seeds", "1", "--algorithm", "matd3", "--episodes", "20", "--n-checkpoints", "2", "--quiet"]) == 0
    run = tmp_path / "smoke_matd3" / "full" / "seed_000"
    assert json.loads((run / "config.json").read_text())["algorithm"] == "sb3_maddpg:MATD3"
    assert (run / "summary.json").exists()  # trained, checkpoints loaded by MATD3.load and evaluated
    assert main(["report", str(tmp_path), "--no-plots"]) == 0
    assert "| smoke_matd3 (MATD3, N=3" in (tmp_path / "report" / "table_min_dist_sum.md").read_text()


def test_the_target_actions_read_the_current_target_policy_noise() -> None:
    """MATD3's train() reads target_policy_noise as it is at the call, as every other setting."""
    model = MATD3("MlpPolicy", make_simple_spread(n_agents=2), learning_starts=10, batch_size=8, seed=0)
    model.learn(20)
    model.target_policy_noise = 0.7
    obs = th.as_tensor(model.replay_buffer.next_observations[:8, 0])
    th.manual_seed(3)
    smoothed = model_target_actions(model, obs)
    with th.no_grad():
        raw = model.actor_target.sample(obs)
    th.manual_seed(3)
    expected = smooth_target_actions(raw, 0.7, model.target_noise_clip, model._action_parts.continuous)
    assert th.equal(smoothed, expected) and not th.equal(smoothed, raw)
