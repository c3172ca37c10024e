"""What each critic sees: the sharing schemes' information isolation, input order and the extractor API."""

import pytest
import torch as th
from torch import nn

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.networks import AgentEnsembleMLP
from sb3_maddpg.common.policies import AgentCritic, MultiAgentCritic
from sb3_maddpg.sharing import (
    SCHEME_ALIASES,
    SHARING_SCHEMES,
    CriticFeaturesExtractor,
    FullCriticFeatures,
    SelectedCriticFeatures,
    resolve_scheme,
)

N_AGENTS, OBS_SIZE, ACTION_SIZE, BATCH = 4, 3, 2, 16
LAYOUT = AgentLayout(tuple(f"agent_{i}" for i in range(N_AGENTS)), (OBS_SIZE,) * N_AGENTS, (ACTION_SIZE,) * N_AGENTS)
# Agent i selects these two agents (fixed per row here; rows may differ in general).
SELECTION = th.tensor([[1, 2], [3, 0], [0, 3], [2, 1]]).expand(BATCH, N_AGENTS, 2)


def visible(scheme: str, i: int) -> tuple[set[int], set[int]]:
    """Whose observations and whose actions critic i may see, from the paper's Table 1."""
    everyone = set(range(N_AGENTS))
    selected = {i, *SELECTION[0, i].tolist()}
    return {
        "independent": ({i}, {i}),
        "full": (everyone, everyone),
        "observations": (everyone, {i}),
        "actions": ({i}, everyone),
        "selected": (selected, selected),
    }[scheme]


def make_critic(scheme: str) -> MultiAgentCritic:
    th.manual_seed(0)
    k = 2 if SHARING_SCHEMES[scheme].uses_selection else 0
    return MultiAgentCritic(LAYOUT, SHARING_SCHEMES[scheme], {}, k, [32, 32], nn.Tanh)


@pytest.mark.parametrize("scheme", list(SHARING_SCHEMES))
@pytest.mark.parametrize("part", ["observation", "action"])
def test_critic_sees_exactly_what_the_scheme_allows(scheme: str, part: str) -> None:
    critic = make_critic(scheme)
    obs, actions = th.randn(BATCH, LAYOUT.obs_dim), th.rand(BATCH, LAYOUT.action_dim) * 2 - 1
    with th.no_grad():
        base = critic(obs, actions, SELECTION)
        for j in range(N_AGENTS):
            obs_j, actions_j = obs.clone(), actions.clone()
            if part == "observation":
                obs_j[:, LAYOUT.obs_slices[j]] += 1.0
            else:
                actions_j[:, LAYOUT.action_slices[j]] = -actions_j[:, LAYOUT.action_slices[j]]
            changed = (critic(obs_j, actions_j, SELECTION) - base).abs().amax(dim=0) > 1e-6
            for i in range(N_AGENTS):
                allowed = j in visible(scheme, i)[0 if part == "observation" else 1]
                assert bool(changed[i]) == allowed, f"{scheme}: critic {i} vs agent {j}'s {part}"


@pytest.mark.parametrize("scheme", list(SHARING_SCHEMES))
def test_gradient_reaches_only_visible_inputs(scheme: str) -> None:
    critic = make_critic(scheme)
    obs = th.randn(BATCH, LAYOUT.obs_dim, requires_grad=True)
    actions = (th.rand(BATCH, LAYOUT.action_dim) * 2 - 1).requires_grad_(True)
    for i in range(N_AGENTS):
        obs_grad, action_grad = th.autograd.grad(critic(obs, actions, SELECTION)[:, i].sum(), (obs, actions))
        seen_obs, seen_actions = visible(scheme, i)
        for j in range(N_AGENTS):
            assert bool(obs_grad[:, LAYOUT.obs_slices[j]].abs().sum() > 0) == (j in seen_obs)
            assert bool(action_grad[:, LAYOUT.action_slices[j]].abs().sum() > 0) == (j in seen_actions)


def test_selection_is_read_per_row() -> None:
    """With selected sharing, a row's stored selection decides what that row's critic sees."""
    critic = make_critic("selected")
    obs, actions = th.randn(2, LAYOUT.obs_dim), th.rand(2, LAYOUT.action_dim)
    selection = th.tensor([[[1, 2], [0, 2], [0, 1], [0, 1]], [[3, 2], [0, 2], [0, 1], [0, 1]]])
    perturbed = obs.clone()
    perturbed[:, LAYOUT.obs_slices[1]] += 1.0
    with th.no_grad():
        delta = (critic(perturbed, actions, selection) - critic(obs, actions, selection))[:, 0].abs()
    assert delta[0] > 1e-6  # row 0: agent 0 selected agent 1
    assert delta[1] == 0  # row 1: agent 0 selected agents 3 and 2


@pytest.mark.parametrize(
    ("scheme", "obs_order", "action_order"),
    [
        ("independent", [2], [2]),
        ("full", [2, 0, 1, 3], [2, 0, 1, 3]),
        ("observations", [2, 0, 1, 3], [2]),
        ("actions", [2], [2, 0, 1, 3]),
        ("selected", [2, 0, 3], [2, 0, 3]),
    ],
)
def test_documented_input_order_own_agent_first(scheme: str, obs_order: list[int], action_order: list[int]) -> None:
    obs = th.arange(LAYOUT.obs_dim, dtype=th.float32).unsqueeze(0)
    actions = -th.arange(1, LAYOUT.action_dim + 1, dtype=th.float32).unsqueeze(0)
    extractor = SHARING_SCHEMES[scheme](LAYOUT, 2, selection_size=2)
    expected = th.cat(
        [obs[:, LAYOUT.obs_slices[j]] for j in obs_order] + [actions[:, LAYOUT.action_slices[j]] for j in action_order], 1
    )
    features = extractor(obs, actions, SELECTION[:1])
    assert extractor.features_dim == expected.shape[1]
    assert th.equal(features, expected)


def test_critic_views_and_q_values_agree() -> None:
    critic = make_critic("full")
    obs, actions = th.randn(BATCH, LAYOUT.obs_dim), th.rand(BATCH, LAYOUT.action_dim)
    with th.no_grad():
        team = critic(obs, actions)
        for i in range(N_AGENTS):
            assert th.allclose(AgentCritic(critic, i)(obs, actions)[:, 0], team[:, i], atol=1e-6)


def test_per_critic_joint_actions() -> None:
    """A [n_agents, batch, action_dim] action tensor gives critic i its own joint action (used by the actor update)."""
    critic = make_critic("full")
    obs = th.randn(BATCH, LAYOUT.obs_dim)
    per_critic = th.rand(N_AGENTS, BATCH, LAYOUT.action_dim)
    with th.no_grad():
        q = critic(obs, per_critic)
        for i in range(N_AGENTS):
            assert th.allclose(q[:, i], critic(obs, per_critic[i])[:, i], atol=1e-6)


def test_ensemble_member_equals_a_plain_mlp() -> None:
    """Agent i's slice of the ensemble computes exactly an ordinary MLP of its own sizes (heterogeneous team)."""
    th.manual_seed(1)
    in_dims, out_dims = [3, 5, 4], [2, 1, 2]
    ensemble = AgentEnsembleMLP(in_dims, out_dims, [8, 8], nn.ReLU, squash_output=True)
    inputs = [th.randn(6, d) for d in in_dims]
    padded = th.stack([nn.functional.pad(x, (0, 5 - x.shape[1])) for x in inputs])
    with th.no_grad():
        out = ensemble(padded)
        for i, (x, d_in, d_out) in enumerate(zip(inputs, in_dims, out_dims)):
            plain = x
            for layer, (weight, bias) in enumerate(zip(ensemble.weights, ensemble.biases)):
                rows = weight[i, :d_in] if layer == 0 else weight[i]
                plain = plain @ rows + bias[i, 0]
                plain = th.relu(plain) if layer < 2 else th.tanh(plain)
            assert th.allclose(out[i, :, :d_out], plain[:, :d_out], atol=1e-6)
            assert th.allclose(ensemble.forward_agent(i, x), plain[:, :d_out], atol=1e-6)
        # Padded input rows start at zero; agent 0's true fan-in sets its initial weight bound.
        assert th.all(ensemble.weights[0][0, 3:] == 0)
        assert ensemble.weights[0][0, :3].abs().max() <= 1 / 3**0.5


def test_gradient_of_one_member_stays_in_its_slice() -> None:
    ensemble = AgentEnsembleMLP([3, 3, 3], [1, 1, 1], [8], nn.ReLU)
    out = ensemble(th.randn(3, 10, 3))
    out[1].sum().backward()
    for param in [*ensemble.weights, *ensemble.biases]:
        assert param.grad is not None
        assert param.grad[1].abs().sum() > 0
        assert param.grad[0].abs().sum() == 0 and param.grad[2].abs().sum() == 0


def test_per_member_gradient_clipping() -> None:
    ensemble = AgentEnsembleMLP([3, 3], [1, 1], [8], nn.ReLU)
    out = ensemble(th.randn(2, 10, 3))
    (out[0].sum() * 1000 + out[1].sum() * 1e-3).backward()
    before = ensemble.squared_grad_norms().sqrt()
    ensemble.clip_grad_norm_per_member(0.5)
    after = ensemble.squared_grad_norms().sqrt()
    assert after[0] == pytest.approx(0.5, rel=1e-4)  # the large one is clipped
    assert after[1] == pytest.approx(before[1].item(), rel=1e-6)  # the small one is untouched


def test_scheme_registry_and_aliases() -> None:
    for alias, name in SCHEME_ALIASES.items():
        assert resolve_scheme(alias) is SHARING_SCHEMES[name]
        assert resolve_scheme(alias.upper()) is SHARING_SCHEMES[name]
    assert resolve_scheme(FullCriticFeatures) is FullCriticFeatures
    with pytest.raises(ValueError, match="Unknown critic_sharing 'everything'.*'selected'.*CriticFeaturesExtractor"):
        resolve_scheme("everything")
    with pytest.raises(ValueError, match="Unknown critic_sharing"):
        resolve_scheme(nn.Linear)


def test_selected_sharing_refuses_bad_k() -> None:
    with pytest.raises(ValueError, match="selection_size must be between 1 and 3"):
        SelectedCriticFeatures(LAYOUT, 0, selection_size=4)
    with pytest.raises(ValueError, match="needs the selection"):
        SelectedCriticFeatures(LAYOUT, 0, selection_size=2)(th.zeros(1, LAYOUT.obs_dim), th.zeros(1, LAYOUT.action_dim))
    with pytest.raises(ValueError, match="agent_index 4 is out of range"):
        FullCriticFeatures(LAYOUT, 4)


class MeanOthersActionFeatures(CriticFeaturesExtractor):
    """A user's scheme: own observation and action, plus the mean of the other agents' actions (one learnable scale)."""

    def __init__(self, layout: AgentLayout, agent_index: int, selection_size: int = 0) -> None:
        super().__init__(layout, agent_index, layout.obs_sizes[agent_index] + 2 * layout.action_sizes[agent_index])
        self.scale = nn.Parameter(th.ones(1))

    def forward(self, observations: th.Tensor, actions: th.Tensor, selection: th.Tensor | None = None) -> th.Tensor:
        others = [self.agent_action(actions, j) for j in range(self.layout.n_agents) if j != self.agent_index]
        own = [self.agent_observation(observations, self.agent_index), self.agent_action(actions, self.agent_index)]
        return th.cat([*own, self.scale * th.stack(others).mean(0)], dim=1)


def test_user_scheme_params_get_gradient_from_own_critic_and_are_registered() -> None:
    critic = MultiAgentCritic(LAYOUT, MeanOthersActionFeatures, {}, 0, [16], nn.ReLU)
    obs, actions = th.randn(BATCH, LAYOUT.obs_dim), th.rand(BATCH, LAYOUT.action_dim)
    q = critic(obs, actions)
    assert q.shape == (BATCH, N_AGENTS)
    q[:, 0].sum().backward()
    assert critic.extractors[0].scale.grad is not None and critic.extractors[0].scale.grad.abs() > 0
    assert critic.extractors[1].scale.grad is None or critic.extractors[1].scale.grad.abs() == 0
    # Its parameters are part of the critic (so the optimiser and the targets include them).
    assert any(param is critic.extractors[0].scale for param in critic.parameters())


def test_features_dim_must_be_positive() -> None:
    layout = AgentLayout(("a", "b"), (3, 3), (2, 2))
    with pytest.raises(ValueError, match="features_dim must be positive, got 0"):
        CriticFeaturesExtractor(layout, 0, features_dim=0)
    assert CriticFeaturesExtractor(layout, 1, features_dim=1).features_dim == 1  # the smallest that is allowed
