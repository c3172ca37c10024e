"""What MADDPG.train logs under ``train/``, checked once against a hand computation: the critics' and actors' losses,
the regulariser and the action saturation (each agent's mean over a call's gradient steps, and the team's mean), and
what the learned schemes' critics listen to (each critic's summary, and the mean over the critics that have one).

Each gradient step's batch and the networks it starts from are copied when the step draws its batch; the hand
computation works from those copies, agent by agent, outside the batched code.
"""

import copy
from typing import Any, NamedTuple

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.logger import Logger

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.inspection import critic_listening
from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.networks import AgentEnsembleMLP
from sb3_maddpg.common.policies import AgentCritic, MultiAgentCritic
from sb3_maddpg.envs import PettingZooToGym
from sb3_maddpg.maddpg.policies import MADDPGPolicy
from tests.conftest import BATCH
from tests.mixed_team import MixedTeam

# The fixture's model collects only (no update before learn() ends, which warns); the tests call train() themselves.
pytestmark = pytest.mark.filterwarnings("ignore:learn\\(\\) ended at step")


class Step(NamedTuple):
    """One gradient step's batch and a copy of the networks as the step found them."""

    batch: MultiAgentReplayBufferSamples
    policy: MADDPGPolicy


def record_steps(model: MADDPG, monkeypatch: pytest.MonkeyPatch) -> list[Step]:
    """:return: A list that each gradient step of ``model.train`` appends its :class:`Step` to."""
    steps: list[Step] = []
    sample = model.replay_buffer.sample

    def recording_sample(batch_size: int, env: Any = None) -> MultiAgentReplayBufferSamples:
        data = sample(batch_size, env=env)
        steps.append(Step(data, copy.deepcopy(model.policy)))
        return data

    monkeypatch.setattr(model.replay_buffer, "sample", recording_sample)
    return steps


def train_and_log(model: MADDPG, gradient_steps: int) -> dict[str, Any]:
    """:return: What one ``train`` call of ``gradient_steps`` records (with the critics' summaries, as a log write)."""
    model.set_logger(Logger(folder=None, output_formats=[]))
    model.train(gradient_steps=gradient_steps, batch_size=BATCH)
    model._record_diagnostics()
    return dict(model.logger.name_to_value)


def hand_preactivation(mlp: AgentEnsembleMLP, agent: int, observation: th.Tensor, action_size: int) -> th.Tensor:
    """Actor ``agent``'s output before ``tanh``, layer by layer from its own slice of the ensemble (ReLU between)."""
    x = observation
    for layer, (weight, bias) in enumerate(zip(mlp.weights, mlp.biases)):
        x = x @ (weight[agent, : observation.shape[1]] if layer == 0 else weight[agent]) + bias[agent, 0]
        if layer < mlp.n_layers - 1:
            x = th.relu(x)
    return x[:, :action_size]


@th.no_grad()
def hand_critic_losses(policy: MADDPGPolicy, data: MultiAgentReplayBufferSamples, gamma: float) -> list[float]:
    """Each critic's mean of ``(Q_i(o, a) - r_i - gamma (1 - done_i) Q_i'(o', mu'(o')))^2`` over the batch."""
    layout = policy.agent_layout
    next_actions = th.cat(
        [
            th.tanh(hand_preactivation(policy.actor_target.mlp, j, data.next_observations[:, part], size))
            for j, (part, size) in enumerate(zip(layout.obs_slices, layout.action_sizes))
        ],
        dim=1,
    )
    losses = []
    for i in range(layout.n_agents):
        next_q = AgentCritic(policy.critic_target, i)(data.next_observations, next_actions, data.selections)[:, 0]
        target = data.rewards[:, i] + gamma * (1.0 - data.dones[:, i]) * next_q
        q = AgentCritic(policy.critic, i)(data.observations, data.actions, data.selections)[:, 0]
        losses.append(float(((q - target) ** 2).mean()))
    return losses


class HandActorTerms(NamedTuple):
    """One step's actor terms by hand, one value per agent each."""

    policy_loss: list[float]
    reg_loss: list[float]
    saturation: list[float]
    saturation_of_row_0: list[float]
    """The saturation of the batch's first row alone (what an average over the wrong dimension would log)."""


@th.no_grad()
def hand_actor_terms(
    actor_policy: MADDPGPolicy, critic: MultiAgentCritic, data: MultiAgentReplayBufferSamples, reg_coef: float
) -> HandActorTerms:
    """
    ``-mean Q_i`` with a_i from actor i and the other actions from the batch, ``reg_coef`` times the mean squared
    pre-``tanh`` output, and the fraction of a_i's components with ``|a| > 0.99`` (all continuous agents).

    :param actor_policy: The networks whose actors act (as the step found them).
    :param critic: The critics the actors ascend (those after the step's critic update).
    """
    layout = actor_policy.agent_layout
    terms = HandActorTerms([], [], [], [])
    for i in range(layout.n_agents):
        pre = hand_preactivation(actor_policy.actor.mlp, i, data.observations[:, layout.obs_slices[i]], layout.action_sizes[i])
        actions = data.actions.clone()
        actions[:, layout.action_slices[i]] = th.tanh(pre)
        terms.policy_loss.append(-float(AgentCritic(critic, i)(data.observations, actions, data.selections).mean()))
        terms.reg_loss.append(reg_coef * float(pre.pow(2).mean()))
        saturated = th.tanh(pre).abs() > 0.99
        terms.saturation.append(int(saturated.sum()) / saturated.numel())
        terms.saturation_of_row_0.append(int(saturated[0].sum()) / saturated.shape[1])
    return terms


def test_logged_losses_and_saturation_are_each_steps_values_by_hand_averaged(
    collected_model: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Three gradient steps: each agent's logged critic loss, actor loss (the policy-gradient part), regulariser and
    saturation are its mean over the steps of the hand values, and the team's the mean over the agents."""
    model = collected_model()
    layout: AgentLayout = model.agent_layout
    with th.no_grad():  # agent 0 deep into saturation, agent 1 in part, agent 2 as initialised
        for index, scale in ((0, 30.0), (1, 8.0)):
            model.actor.mlp.weights[-1][index] *= scale
            model.actor.mlp.biases[-1][index] *= scale
    steps = record_steps(model, monkeypatch)
    logged = train_and_log(model, gradient_steps=3)
    assert len(steps) == 3

    critic_losses = np.array([hand_critic_losses(step.policy, step.batch, model.gamma) for step in steps])
    # The actors ascend the critics as their step's critic update left them: the next step's starting critics.
    critics_after = [step.policy.critic for step in steps[1:]] + [model.critic]
    actor_terms = [
        hand_actor_terms(step.policy, critic, step.batch, model.actor_reg_coef) for step, critic in zip(steps, critics_after)
    ]
    expected = {
        "critic_loss": critic_losses.mean(axis=0),
        "actor_loss": np.mean([terms.policy_loss for terms in actor_terms], axis=0),
        "actor_reg_loss": np.mean([terms.reg_loss for terms in actor_terms], axis=0),
        "action_saturation": np.mean([terms.saturation for terms in actor_terms], axis=0),
    }
    for name, per_agent in expected.items():
        for agent, value in zip(layout.agent_ids, per_agent):
            assert logged[f"train/{agent}/{name}"] == pytest.approx(value, rel=1e-5, abs=1e-7), (name, agent)
        assert logged[f"train/{name}"] == pytest.approx(per_agent.mean(), rel=1e-5, abs=1e-7), name

    # Not vacuous: the steps' batches differ, the regulariser and the policy-gradient part differ, and the
    # saturation of a batch's first row is not the batch's (so an average over another dimension shows).
    assert len({tuple(losses) for losses in critic_losses.tolist()}) == 3
    assert 0.0 < expected["action_saturation"][1] < 1.0
    row_0 = np.mean([terms.saturation_of_row_0 for terms in actor_terms], axis=0)
    assert np.abs(row_0 - expected["action_saturation"]).max() > 0.05


def test_a_discrete_agents_one_hot_never_counts_as_saturated(collected_model: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """A mixed team: the chooser's one-hot (every component at -1 or 1) logs a saturation of 0, the mover's its count."""
    model = collected_model(env=PettingZooToGym(MixedTeam()))
    layout: AgentLayout = model.agent_layout
    mover, chooser = layout.agent_ids
    with th.no_grad():  # the mover's action tanh(4 + small), past 0.99 (tanh(2.65)) in every row
        model.actor.mlp.biases[-1][0] += 4.0
    steps = record_steps(model, monkeypatch)
    logged = train_and_log(model, gradient_steps=1)
    observations = steps[0].batch.observations
    with th.no_grad():
        pre = hand_preactivation(steps[0].policy.actor.mlp, 0, observations[:, layout.obs_slices[0]], 1)
    saturated = int((th.tanh(pre).abs() > 0.99).sum())
    assert saturated == BATCH  # not vacuous: the chooser's one-hots would count as much
    assert logged[f"train/{mover}/action_saturation"] == 1.0
    assert logged[f"train/{chooser}/action_saturation"] == 0.0
    assert logged["train/action_saturation"] == 0.5


def entropy(weights: th.Tensor) -> float:
    """Mean entropy in nats of the distributions along the last dimension."""
    return float(-(weights * weights.log()).sum(dim=-1).mean())


def test_logged_listening_summaries_by_hand_and_the_team_mean_over_the_critics_that_have_them(
    collected_model: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A team of a full, an attention and a learned-selection critic: each listening critic's summaries of the critic
    update's batch (the replayed actions), computed here from its weights and the agents' positions; the team's value
    of a summary is the mean over the critics that report it, and the full critic reports none."""
    sharing = {"agent_0": "full", "agent_1": "attention", "agent_2": "learned_selection"}
    kwargs = {"agent_1": {"embed_dim": 8, "n_heads": 2}, "agent_2": {"embed_dim": 8, "k": 1}}
    model = collected_model(sharing, critic_sharing_kwargs=kwargs)
    steps = record_steps(model, monkeypatch)
    logged = train_and_log(model, gradient_steps=1)
    data, critic = steps[0].batch, steps[0].policy.critic
    obs, actions = data.observations, data.actions
    positions = th.stack([obs[:, part][:, 2:4] for part in model.agent_layout.obs_slices], dim=1)  # MPE: o[2:4]

    def distances(i: int, others: list[int]) -> th.Tensor:
        return (positions[:, others] - positions[:, i : i + 1]).norm(dim=-1)

    rows = th.arange(BATCH)
    with th.no_grad():
        heads = critic.extractors[1]._attend(obs, actions)[2]  # type: ignore[operator]  # [batch, heads, others 0, 2]
        choice_weights = critic.extractors[2].listening_weights(obs, actions)  # type: ignore[operator]  # others 0, 1
    attention_weights = heads.mean(dim=1)
    nearest_to_1 = distances(1, [0, 2]).argmin(dim=1)
    to_2 = distances(2, [0, 1])
    chosen = choice_weights.argmax(dim=1)  # k = 1: the highest score is the highest softmax weight
    chosen_rank = 1 + (to_2 < to_2[rows, chosen].unsqueeze(1)).sum(dim=1)
    expected = {
        "agent_1": {
            "attention_entropy": entropy(attention_weights),
            "head_entropy": entropy(heads),
            "weight_on_nearest": float(attention_weights[rows, nearest_to_1].mean()),
        },
        "agent_2": {
            "attention_entropy": entropy(choice_weights),
            "weight_on_nearest": float(choice_weights[rows, to_2.argmin(dim=1)].mean()),
            "chose_nearest": float((chosen == to_2.argmin(dim=1)).float().mean()),
            "chosen_rank": float(chosen_rank.float().mean()),
            "top_choice_share": max(int((chosen == j).sum()) for j in (0, 1)) / BATCH,
        },
    }
    names = {name for summary in expected.values() for name in summary}
    assert not [key for key in logged if key.startswith("train/agent_0/") and key.split("/")[-1] in names]
    for agent, summary in expected.items():
        for name, value in summary.items():
            assert logged[f"train/{agent}/{name}"] == pytest.approx(value, rel=1e-5), (agent, name)
    for name in names:
        reported = [summary[name] for summary in expected.values() if name in summary]
        assert logged[f"train/{name}"] == pytest.approx(np.mean(reported), rel=1e-5), name
    assert len({float(value) for value in chosen_rank}) == 2  # not vacuous: both agents chosen first in some rows


def test_critic_listening_takes_actions_in_the_env_units(collected_model: Any) -> None:
    """critic_listening scales actions given in the env's units ([0, 1] in MPE) to the critics' [-1, 1]: its weights
    are the critics' on ``2 a - 1``, 0 on the diagonal, and a learned choice is the agent of the highest weight."""
    model = collected_model("learned_selection", critic_sharing_kwargs={"embed_dim": 8, "k": 1})
    data = model.replay_buffer.sample(BATCH)
    env_actions = model.policy.unscale_action(data.actions.numpy())
    listening = critic_listening(model, data.observations.numpy(), env_actions)
    weights = th.as_tensor(listening["weights"])
    assert th.equal(weights.diagonal(dim1=1, dim2=2), th.zeros(BATCH, 3))
    for i, extractor in enumerate(model.critic.extractors):
        others = [j for j in range(3) if j != i]
        with th.no_grad():
            expected = extractor.listening_weights(data.observations, th.as_tensor(2 * env_actions - 1))
        th.testing.assert_close(weights[:, i, others], expected, rtol=1e-5, atol=1e-6)
        assert listening["chosen"][:, i, 0].tolist() == [others[j] for j in expected.argmax(dim=1).tolist()]
    assert model.action_space.low.min() == 0.0 and model.action_space.high.max() == 1.0  # 2 a - 1 is the scaling


def test_critic_listening_keeps_row_i_for_critic_i_in_a_mixed_team(collected_model: Any) -> None:
    """A per-agent mapping of an attention critic and learned selections of different k: ``chosen``'s row i is critic
    i's choice (-1 where it chooses none, or fewer than the largest k), never the next choosing critic's."""
    sharing = {"agent_0": "attention", "agent_1": "learned_selection", "agent_2": "learned_selection"}
    kwargs = {"agent_0": {"embed_dim": 8}, "agent_1": {"embed_dim": 8, "k": 1}, "agent_2": {"embed_dim": 8, "k": 2}}
    model = collected_model(sharing, critic_sharing_kwargs=kwargs)
    data = model.replay_buffer.sample(BATCH)
    chosen = critic_listening(model, data.observations.numpy())["chosen"]
    assert chosen.shape == (BATCH, 3, 2)
    assert (chosen[:, 0] == -1).all() and (chosen[:, 1, 1] == -1).all()  # attention: none; k=1: one of two slots
    actions = th.as_tensor(model.policy.scale_action(model.predict(data.observations.numpy(), deterministic=True)[0]))
    for i, k in ((1, 1), (2, 2)):
        with th.no_grad():
            expected = model.critic.extractors[i].chosen_agents(data.observations, actions.float())
        assert np.array_equal(chosen[:, i, :k], expected.numpy()), i
