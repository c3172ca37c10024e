"""critic_sharing as a mapping from agent id to scheme: each critic sees exactly what its own scheme allows."""

import warnings
from pathlib import Path

import pytest
import torch as th
from torch import nn

from sb3_maddpg import MADDPG
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.policies import MultiAgentCritic
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.sharing import (
    AttentionCriticFeatures,
    FullCriticFeatures,
    IndependentCriticFeatures,
    SelectedCriticFeatures,
    kwargs_per_agent,
    schemes_per_agent,
)

N_AGENTS, BATCH = 4, 16
LAYOUT = AgentLayout(tuple(f"agent_{i}" for i in range(N_AGENTS)), (3,) * N_AGENTS, (2,) * N_AGENTS)
MIXED = {"agent_0": "full", "agent_1": "independent", "agent_2": "actions", "agent_3": "selected"}
SELECTION = th.tensor([[1, 2], [3, 0], [0, 3], [2, 1]]).expand(BATCH, N_AGENTS, 2)
# Whose observations and whose actions each critic of MIXED may see (agent 3 selected agents 2 and 1).
VISIBLE = {0: ({0, 1, 2, 3}, {0, 1, 2, 3}), 1: ({1}, {1}), 2: ({2}, {0, 1, 2, 3}), 3: ({3, 2, 1}, {3, 2, 1})}
FAST = dict(
    learning_starts=200, batch_size=32, buffer_size=2_000, transitions_per_update=20, policy_kwargs=dict(net_arch=[16])
)


def test_each_critic_sees_exactly_what_its_own_scheme_allows() -> None:
    th.manual_seed(0)
    schemes = schemes_per_agent(MIXED, LAYOUT.agent_ids)
    critic = MultiAgentCritic(LAYOUT, schemes, kwargs_per_agent({}, LAYOUT.agent_ids), 2, [16], nn.Tanh)
    obs = th.randn(BATCH, LAYOUT.obs_dim, requires_grad=True)
    actions = (th.rand(BATCH, LAYOUT.action_dim) * 2 - 1).requires_grad_(True)
    for i in range(N_AGENTS):
        obs_grad, action_grad = th.autograd.grad(critic(obs, actions, SELECTION)[:, i].sum(), (obs, actions))
        seen_obs, seen_actions = VISIBLE[i]
        for j in range(N_AGENTS):
            assert bool(obs_grad[:, LAYOUT.obs_slices[j]].abs().sum() > 0) == (j in seen_obs), (i, j)
            assert bool(action_grad[:, LAYOUT.action_slices[j]].abs().sum() > 0) == (j in seen_actions), (i, j)


def test_mapping_must_name_exactly_the_team() -> None:
    assert schemes_per_agent("full", LAYOUT.agent_ids) == [FullCriticFeatures] * N_AGENTS
    assert schemes_per_agent(MIXED, LAYOUT.agent_ids)[1] is IndependentCriticFeatures
    assert schemes_per_agent(MIXED, LAYOUT.agent_ids)[3] is SelectedCriticFeatures
    with pytest.raises(ValueError, match=r"it gives no scheme to \['agent_3'\]: give exactly the team's agents"):
        schemes_per_agent({k: v for k, v in MIXED.items() if k != "agent_3"}, LAYOUT.agent_ids)
    with pytest.raises(ValueError, match=r"it names agents not in the team: \['agent_9'\]"):
        schemes_per_agent({**MIXED, "agent_9": "full"}, LAYOUT.agent_ids)
    with pytest.raises(ValueError, match="Unknown critic_sharing 'everything'"):
        MADDPG("MlpPolicy", SimpleSpreadVecEnv(2, n_agents=3), critic_sharing={"agent_0": "everything"})


def test_kwargs_are_shared_or_per_agent() -> None:
    assert kwargs_per_agent({"embed_dim": 8}, LAYOUT.agent_ids) == [{"embed_dim": 8}] * N_AGENTS
    per_agent = kwargs_per_agent({"agent_2": {"embed_dim": 8}}, LAYOUT.agent_ids)
    assert per_agent == [{}, {}, {"embed_dim": 8}, {}]


DEVICES = ["cpu", pytest.param("cuda", marks=pytest.mark.skipif(not th.cuda.is_available(), reason="needs CUDA"))]


@pytest.mark.parametrize("device", DEVICES)
def test_a_mixed_team_trains_saves_and_loads(device: str, tmp_path: Path) -> None:
    # On CUDA, the per-agent gradient clipping sums critics with and without parameters on one device.
    sharing = {"agent_0": "full", "agent_1": "independent", "agent_2": "attention"}
    kwargs = {"agent_2": {"embed_dim": 8, "n_heads": 2}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # selection is not used here, so no selected-sharing warning either
        model = MADDPG(
            "MlpPolicy",
            SimpleSpreadVecEnv(4, n_agents=3),
            critic_sharing=sharing,
            critic_sharing_kwargs=kwargs,
            device=device,
            **FAST,
        )
    extractors = model.critic.extractors
    assert [type(e) for e in extractors] == [FullCriticFeatures, IndependentCriticFeatures, AttentionCriticFeatures]
    assert extractors[2].embed_dim == 8
    assert model.selector is None
    model.learn(600)
    model.save(tmp_path / "mixed.zip")
    loaded = MADDPG.load(tmp_path / "mixed.zip", device=device)
    assert [type(e) for e in loaded.critic.extractors] == [type(e) for e in extractors]
    for mine, theirs in zip(model.critic.parameters(), loaded.critic.parameters()):
        th.testing.assert_close(mine, theirs)
    # A selection is made and stored as soon as one critic reads it.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with_selected = MADDPG(
            "MlpPolicy",
            SimpleSpreadVecEnv(4, n_agents=3),
            critic_sharing={**sharing, "agent_1": "selected"},
            selector=1,
            **FAST,
        )
    assert with_selected.selector is not None and with_selected.selector.k == 1
    with pytest.raises(ValueError, match="selector is used only by schemes that read a selection"):
        MADDPG("MlpPolicy", SimpleSpreadVecEnv(4, n_agents=3), critic_sharing=sharing, selector=1, **FAST)


def test_selected_sharing_pads_unequal_agents_into_equal_slots() -> None:
    layout = AgentLayout(("a", "b", "c"), (3, 5, 4), (2, 1, 2))
    extractor = SelectedCriticFeatures(layout, 0, selection_size=1)
    assert extractor.features_dim == (1 + 1) * (5 + 2)
    obs, actions = th.randn(6, layout.obs_dim), th.rand(6, layout.action_dim)
    selection = th.tensor([[[2], [0], [1]]] * 3 + [[[1], [2], [0]]] * 3)  # agent 0 selects c, then b

    def padded(part: th.Tensor, width: int) -> th.Tensor:
        return nn.functional.pad(part, (0, width - part.shape[1]))

    for rows, other in ((slice(0, 3), 2), (slice(3, 6), 1)):
        expected = th.cat(
            [
                padded(obs[rows, layout.obs_slices[0]], 5),
                padded(obs[rows, layout.obs_slices[other]], 5),
                padded(actions[rows, layout.action_slices[0]], 2),
                padded(actions[rows, layout.action_slices[other]], 2),
            ],
            dim=1,
        )
        th.testing.assert_close(extractor(obs, actions, selection)[rows], expected)


def test_kwargs_that_name_every_agent_go_to_each_one() -> None:
    # Every key an agent id, every value a dict: each critic gets its own, even when they name the whole team.
    every = {agent: {"embed_dim": 4 * (index + 1)} for index, agent in enumerate(LAYOUT.agent_ids)}
    assert kwargs_per_agent(every, LAYOUT.agent_ids) == [{"embed_dim": 4 * (i + 1)} for i in range(N_AGENTS)]
    model = MADDPG(
        "MlpPolicy",
        SimpleSpreadVecEnv(2, n_agents=3),
        critic_sharing="learned_selection",
        critic_sharing_kwargs={"agent_0": {"k": 1}, "agent_1": {"k": 2}, "agent_2": {"k": 1, "embed_dim": 8}},
        **FAST,
    )
    extractors = model.critic.extractors
    assert [extractor.selection_size for extractor in extractors] == [1, 2, 1]
    assert [extractor.embed_dim for extractor in extractors] == [64, 64, 8]
