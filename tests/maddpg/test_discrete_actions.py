"""Discrete actions: one-hot slots in the joint action, Gumbel-max exploration and targets, straight-through
Gumbel-softmax in the actor update, and the batched simple_spread against mpe2's discrete mode."""

from pathlib import Path

import numpy as np
import pytest
import torch as th
from mpe2 import simple_spread_v3
from torch import nn

from sb3_maddpg import MADDPG
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.policies import AgentActor, MultiAgentActor
from sb3_maddpg.envs import PettingZooToGym, SimpleSpreadVecEnv, make_simple_spread, make_simple_spread_vec_env
from tests.loss_helpers import team_actor_terms
from tests.mixed_team import MixedTeam
from tests.settings import SELECTS_EVERY_OTHER_AGENT, UPDATES_PER_10_TRANSITIONS

# Agent 0 continuous (2 components), agent 1 discrete (3 actions).
MIXED = AgentLayout(("mover", "chooser"), (4, 4), (2, 3), discrete_actions=(False, True))


def mixed_actor() -> MultiAgentActor:
    th.manual_seed(0)
    return MultiAgentActor(MIXED, [16], nn.ReLU)


def is_one_hot(values: np.ndarray | th.Tensor, low: float = -1.0) -> bool:
    """Every row has one entry 1 and the others ``low``."""
    array = np.asarray(values)
    return bool(np.isin(array, (low, 1.0)).all() and ((array == 1.0).sum(axis=-1) == 1).all())


def test_the_adapter_reads_a_one_hot_slot_as_the_agents_action() -> None:
    env = PettingZooToGym(simple_spread_v3.parallel_env(N=3, continuous_actions=False))
    assert env.agent_layout.discrete_actions == (True, True, True)
    assert env.action_space.shape == (15,) and env.action_space.low.min() == 0 and env.action_space.high.max() == 1
    joint = np.zeros(15, np.float32)
    joint[[2, 5 + 4, 10 + 0]] = 1.0
    assert env.agent_actions(joint) == {"agent_0": 2, "agent_1": 4, "agent_2": 0}
    # Stepping with the one-hots is stepping mpe2 with the integers.
    reference = simple_spread_v3.parallel_env(N=3, continuous_actions=False)
    ours, _ = env.reset(seed=3)
    theirs, _ = reference.reset(seed=3)
    for _ in range(5):
        ours, *_ = env.step(joint)
        theirs, *_ = reference.step({"agent_0": 2, "agent_1": 4, "agent_2": 0})
    np.testing.assert_array_equal(ours, np.concatenate([theirs[a] for a in env.agent_layout.agent_ids]))


def test_greedy_sampled_and_straight_through_actions() -> None:
    actor = mixed_actor()
    obs = th.randn(4096, MIXED.obs_dim)
    with th.no_grad():
        logits = actor._preactivations(obs)[:, 2:]
        greedy = actor(obs)
        sampled = actor.sample(obs)
    assert (greedy[:, :2].abs() < 1).all()  # the continuous agent's tanh
    assert is_one_hot(greedy[:, 2:]) and is_one_hot(sampled[:, 2:])
    assert th.equal(greedy[:, 2:].argmax(dim=1), logits.argmax(dim=1))
    th.testing.assert_close(sampled[:, :2], greedy[:, :2])  # no sampling for continuous agents
    # Gumbel-max: the sampled choices follow the softmax of the logits.
    one_row = obs[:1].expand(20_000, -1)
    with th.no_grad():
        frequencies = (actor.sample(one_row)[:, 2:] > 0).float().mean(dim=0)
    th.testing.assert_close(frequencies, th.softmax(logits[0], dim=0), atol=0.015, rtol=0)
    # Straight-through: one-hot values, and the logits still get a gradient through them.
    actions, preactivations = actor.forward_with_preactivation(obs[:64])
    assert is_one_hot(actions[:, 2:].detach())
    th.testing.assert_close(preactivations[:, 2:], logits[:64])
    grad = th.autograd.grad((actions[:, 2:] * th.randn(64, 3)).sum(), list(actor.parameters()), allow_unused=True)
    assert any(g is not None and g.abs().sum() > 0 for g in grad)
    # One agent's view gives its greedy action.
    th.testing.assert_close(AgentActor(actor, 1)(obs[:8, 4:]), greedy[:8, 2:])
    th.testing.assert_close(AgentActor(actor, 0)(obs[:8, :4]), greedy[:8, :2])


def test_maddpg_explores_and_stores_one_hots(tmp_path: Path) -> None:
    env = make_simple_spread(n_agents=3, continuous_actions=False)
    model = MADDPG("MlpPolicy", env, noise_std=0.3, seed=0, **UPDATES_PER_10_TRANSITIONS)
    assert model.action_noise is not None and np.all(model.action_noise._sigma == 0)  # no noise on one-hots
    model.learn(400)
    stored = model.replay_buffer.actions[:400, 0].reshape(400, 3, 5)
    assert is_one_hot(stored)
    # Exploration samples: after the warm-up, the stored choices are not all the greedy ones.
    with th.no_grad():
        greedy = model.actor(th.as_tensor(model.replay_buffer.observations[100:400, 0])).numpy().reshape(300, 3, 5)
    assert (stored[100:].argmax(-1) != greedy.argmax(-1)).any()
    action, _ = model.predict(env.reset(seed=0)[0], deterministic=True)
    assert is_one_hot(action.reshape(3, 5), low=0.0)
    # Discrete components are never counted as saturated.
    assert team_actor_terms(model, model.replay_buffer.sample(32)).saturation.abs().sum() == 0
    model.save(tmp_path / "discrete.zip")
    loaded = MADDPG.load(tmp_path / "discrete.zip")
    np.testing.assert_array_equal(
        loaded.predict(env.reset(seed=1)[0], deterministic=True)[0], model.predict(env.reset(seed=1)[0], deterministic=True)[0]
    )
    assert loaded.agent_layout.discrete_actions == (True, True, True)


def test_critic_targets_use_a_sample_of_the_target_actors() -> None:
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=3, continuous_actions=False), seed=0, **UPDATES_PER_10_TRANSITIONS)
    model.learn(150)
    data = model.replay_buffer.sample(256)
    th.manual_seed(1)
    first = model._critic_targets(data)
    th.manual_seed(2)
    second = model._critic_targets(data)
    assert not th.allclose(first, second)  # sampled next actions
    th.manual_seed(1)
    with th.no_grad():
        next_actions = model.actor_target.sample(data.next_observations)
        expected = data.rewards + (1 - data.dones) * model.gamma * model.critic_target(data.next_observations, next_actions)
    th.testing.assert_close(first, expected)


def test_the_batched_env_replays_mpe2s_discrete_mode() -> None:
    ours = SimpleSpreadVecEnv(3, n_agents=3, continuous_actions=False)
    reference = make_simple_spread_vec_env(3, "mpe2", n_agents=3, continuous_actions=False)
    assert ours.get_attr("agent_layout")[0] == reference.get_attr("agent_layout")[0]
    ours.seed(7)
    reference.seed(7)
    np.testing.assert_allclose(ours.reset(), reference.reset(), atol=1e-5, rtol=0)
    rng = np.random.default_rng(0)
    for _ in range(60):  # more than two episodes, through the auto-resets
        actions = rng.uniform(0, 1, (3, 15)).astype(np.float32)
        obs, rewards, dones, _ = ours.step(actions)
        ref_obs, ref_rewards, ref_dones, _ = reference.step(actions)
        np.testing.assert_allclose(obs, ref_obs, atol=1e-5, rtol=0)
        np.testing.assert_allclose(rewards, ref_rewards, atol=1e-5, rtol=0)
        np.testing.assert_array_equal(dones, ref_dones)


@SELECTS_EVERY_OTHER_AGENT
@pytest.mark.parametrize("scheme", ["full", "selected", "attention"])
def test_discrete_speaker_listener_makes_updates_under_each_scheme(scheme: str) -> None:
    """speaker-listener with discrete actions: heterogeneous, every agent discrete."""
    from sb3_maddpg.common.selection import FixedGraph
    from sb3_maddpg.envs import make_mpe_env

    env = make_mpe_env("simple_speaker_listener", continuous_actions=False)
    selection = FixedGraph([[1], [0]]) if scheme == "selected" else None
    model = MADDPG("MlpPolicy", env, critic_sharing=scheme, selector=selection, seed=0, **UPDATES_PER_10_TRANSITIONS)
    model.learn(300)
    assert model._n_updates > 0


def test_a_continuous_discrete_team_stores_one_hots_acts_and_reloads_layout(tmp_path: Path) -> None:
    env = PettingZooToGym(MixedTeam())
    assert env.agent_layout.discrete_actions == (False, True) and env.agent_layout.action_sizes == (1, 3)
    model = MADDPG("MlpPolicy", env, seed=0, **UPDATES_PER_10_TRANSITIONS)
    model.learn(400)
    stored = model.replay_buffer.actions[:400, 0]
    assert is_one_hot(stored[:, 1:]) and not is_one_hot(stored[:, :1])  # the mover's action is continuous
    action, _ = model.predict(env.reset(seed=0)[0], deterministic=True)
    assert -1.0 <= action[0] <= 1.0 and is_one_hot(action[1:], low=0.0)
    model.save(tmp_path / "mixed.zip")
    assert MADDPG.load(tmp_path / "mixed.zip").agent_layout == env.agent_layout
