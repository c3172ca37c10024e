"""Critics that learn whom to listen to: shapes, what each critic sees, gradient isolation between critics, the hard
choice of a learned selection, targets, save/load, logged diagnostics and the listening helper."""

import csv
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.logger import configure
from torch import nn

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.inspection import critic_listening
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.policies import MultiAgentCritic
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.sharing import AttentionCriticFeatures, LearnedSelectionCriticFeatures, default_selection_size, resolve_scheme

N_AGENTS, BATCH = 4, 32
# MPE-like observations: [velocity (2), position (2), rest]; agent 3 is larger, so the team is heterogeneous.
LAYOUT = AgentLayout(
    tuple(f"agent_{i}" for i in range(N_AGENTS)), (6, 6, 6, 8), (2, 2, 2, 3), position_slices=(slice(2, 4),) * N_AGENTS
)
SCHEMES = {"attention": AttentionCriticFeatures, "learned_selection": LearnedSelectionCriticFeatures}
FAST = dict(
    learning_starts=200, batch_size=64, buffer_size=5_000, transitions_per_update=20, policy_kwargs=dict(net_arch=[16, 16])
)


def make_critic(scheme: str, **kwargs: object) -> MultiAgentCritic:
    th.manual_seed(0)
    return MultiAgentCritic(LAYOUT, SCHEMES[scheme], {"embed_dim": 8, **kwargs}, 0, [16, 16], nn.ReLU)


def batch() -> tuple[th.Tensor, th.Tensor]:
    th.manual_seed(1)
    return th.randn(BATCH, LAYOUT.obs_dim), th.rand(BATCH, LAYOUT.action_dim) * 2 - 1


def test_names_and_feature_sizes() -> None:
    assert resolve_scheme("attention") is AttentionCriticFeatures
    assert resolve_scheme("learned_selection") is LearnedSelectionCriticFeatures
    assert AttentionCriticFeatures(LAYOUT, 0, embed_dim=8, n_heads=2).features_dim == 16  # [own, attended]
    # Own (6 + 2) and k = 2 chosen agents, each o_j and a_j padded to the largest other agent's: 8 + 3.
    assert LearnedSelectionCriticFeatures(LAYOUT, 0, k=2, embed_dim=8).features_dim == 8 + 2 * 11
    assert LearnedSelectionCriticFeatures(LAYOUT, 3, k=1, embed_dim=8).features_dim == 11 + 8  # agent 3 is the largest
    assert [default_selection_size(n) for n in (2, 3, 4, 5, 8)] == [1, 1, 2, 2, 2]
    obs, actions = batch()
    for scheme in SCHEMES:
        assert make_critic(scheme)(obs, actions).shape == (BATCH, N_AGENTS)


def test_bad_settings_say_what_to_do() -> None:
    with pytest.raises(ValueError, match=r"chooses k of the 3 other agents, got k=4: give critic_sharing_kwargs"):
        LearnedSelectionCriticFeatures(LAYOUT, 0, k=4)
    with pytest.raises(ValueError, match="multiple of n_heads"):
        AttentionCriticFeatures(LAYOUT, 0, embed_dim=10, n_heads=4)
    solo = AgentLayout(("a",), (4,), (2,))
    for scheme in SCHEMES.values():
        with pytest.raises(ValueError, match="needs at least 2 agents, got 1"):
            scheme(solo, 0)


@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_each_critics_loss_moves_only_its_own_parameters(scheme: str) -> None:
    critic = make_critic(scheme)
    obs, actions = batch()
    for i in range(N_AGENTS):
        critic.zero_grad()
        critic(obs, actions)[:, i].sum().backward()
        for j, extractor in enumerate(critic.extractors):
            touched = any(p.grad is not None and p.grad.abs().sum() > 0 for p in extractor.parameters())
            assert touched == (i == j), f"critic {i}'s loss vs extractor {j}"
        for weight in critic.mlp.weights:
            moved = weight.grad.abs().sum(dim=(1, 2)) > 0  # type: ignore[union-attr]
            assert moved.tolist() == [j == i for j in range(N_AGENTS)]


def test_attention_listens_to_every_agent() -> None:
    critic = make_critic("attention")
    obs, actions = batch()
    obs.requires_grad_(True)
    actions.requires_grad_(True)
    for i in range(N_AGENTS):
        obs_grad, action_grad = th.autograd.grad(critic(obs, actions)[:, i].sum(), (obs, actions))
        for j in range(N_AGENTS):
            assert obs_grad[:, LAYOUT.obs_slices[j]].abs().sum() > 0
            assert action_grad[:, LAYOUT.action_slices[j]].abs().sum() > 0
        weights = critic.extractors[i].listening_weights(obs, actions)  # type: ignore[operator]
        assert weights.shape == (BATCH, N_AGENTS - 1)
        assert th.allclose(weights.sum(dim=1), th.ones(BATCH))


@th.no_grad()
def test_attention_is_a_hand_computation_over_the_other_agents_only() -> None:
    """[e_i, attended]: each head's softmax(q_h k_h / sqrt(d_h)) over the *other* agents' keys (query from e_i
    alone), its weighted values, the output projection; the listening weights are the heads' mean."""
    n_heads, embed_dim, i = 2, 8, 2
    extractor = make_critic("attention", n_heads=n_heads).extractors[i]
    obs, actions = batch()
    encoder, attention = extractor.encoder, extractor.attention
    others = [0, 1, 3]
    leaky = nn.functional.leaky_relu
    own = leaky(encoder.own(th.cat((obs[:, LAYOUT.obs_slices[i]], actions[:, LAYOUT.action_slices[i]]), dim=1)))
    # Each other agent's own encoder layer, applied to its [o_j, a_j] zero-padded to the largest (agent 3's 8 + 3).
    encoded = []
    for position, j in enumerate(others):
        data = th.cat((obs[:, LAYOUT.obs_slices[j]], actions[:, LAYOUT.action_slices[j]]), dim=1)
        data = th.cat((data, th.zeros(BATCH, 11 - data.shape[1])), dim=1)
        encoded.append(leaky(data @ encoder.other.weights[0][position] + encoder.other.biases[0][position]))
    keys_in = th.stack(encoded, dim=1)  # [batch, 3, embed]
    w_q, w_k, w_v = attention.in_proj_weight.split(embed_dim)
    b_q, b_k, b_v = attention.in_proj_bias.split(embed_dim)
    d_head = embed_dim // n_heads
    q = (own @ w_q.T + b_q).view(BATCH, n_heads, d_head)
    k = (keys_in @ w_k.T + b_k).view(BATCH, 3, n_heads, d_head)
    v = (keys_in @ w_v.T + b_v).view(BATCH, 3, n_heads, d_head)
    heads = th.softmax(th.einsum("bhd,bjhd->bhj", q, k) / d_head**0.5, dim=-1)  # [batch, heads, 3]
    attended = th.einsum("bhj,bjhd->bhd", heads, v).reshape(BATCH, embed_dim) @ attention.out_proj.weight.T
    attended = attended + attention.out_proj.bias
    th.testing.assert_close(extractor(obs, actions), th.cat((own, attended), dim=1))  # type: ignore[operator]
    th.testing.assert_close(extractor.listening_weights(obs, actions), heads.mean(dim=1))  # type: ignore[operator]
    assert extractor.diagnostics() == {}  # type: ignore[operator]  # not recording: nothing kept
    extractor.recording = True
    extractor(obs, actions)  # type: ignore[operator]
    extractor.recording = False
    report = extractor.diagnostics()  # type: ignore[operator]

    def entropy(weights: th.Tensor) -> float:
        return float(-(weights * weights.log()).sum(dim=-1).mean())

    assert report["attention_entropy"] == pytest.approx(entropy(heads.mean(dim=1)), rel=1e-5)
    assert report["head_entropy"] == pytest.approx(entropy(heads), rel=1e-5)
    assert report["head_entropy"] < report["attention_entropy"]  # the heads differ, so their mean is flatter
    positions = th.stack([obs[:, LAYOUT.obs_slices[j]][:, 2:4] for j in others], dim=1)
    nearest = (positions - obs[:, LAYOUT.obs_slices[i]][:, None, 2:4]).norm(dim=-1).argmin(dim=1)
    on_nearest = heads.mean(dim=1)[th.arange(BATCH), nearest].mean()
    assert report["weight_on_nearest"] == pytest.approx(float(on_nearest), rel=1e-5)


def test_learned_selection_sees_exactly_its_k_highest_scored_agents() -> None:
    extractor = make_critic("learned_selection", k=2).extractors[1]
    obs, actions = batch()
    features = extractor(obs, actions)
    _, scores = extractor._scores(obs, actions)  # type: ignore[operator]
    top = scores.topk(2, dim=1).indices
    others = [0, 2, 3]

    def slot(j: int) -> th.Tensor:  # o_j padded to 8 columns, then a_j padded to 3: agent 3 is the largest
        o_j, a_j = obs[:, LAYOUT.obs_slices[j]], actions[:, LAYOUT.action_slices[j]]
        return th.cat((o_j, th.zeros(BATCH, 8 - o_j.shape[1]), a_j, th.zeros(BATCH, 3 - a_j.shape[1])), dim=1)

    # By hand: own [o_1, a_1], then each chosen agent's slot, highest score first.
    expected = [th.cat((obs[:, LAYOUT.obs_slices[1]], actions[:, LAYOUT.action_slices[1]]), dim=1)]
    for rank in range(2):
        expected.append(th.stack([slot(others[int(j)])[row] for row, j in enumerate(top[:, rank])]))
    assert th.equal(features, th.cat(expected, dim=1))  # exactly: the straight-through term adds zero
    chosen = extractor.chosen_agents(obs, actions)  # type: ignore[operator]
    assert chosen.tolist() == [[others[j] for j in row] for row in top.tolist()]
    assert (chosen != 1).all()
    # The rows differ: the choice depends on the data, not only on the parameters.
    assert len({tuple(row) for row in chosen.tolist()}) > 1


def test_learned_selection_gradient_is_the_softmax_mixtures() -> None:
    """Straight-through: the scores' parameters get the gradient Q would have if each chosen slot were replaced by
    the softmax-weighted mixture of every other agent's slot (computed here by hand)."""
    critic = make_critic("learned_selection", k=2)
    extractor = critic.extractors[1]
    obs, actions = batch()
    upstream = th.randn(BATCH, extractor.features_dim)
    (extractor(obs, actions) * upstream).sum().backward()  # type: ignore[operator]
    straight_through = [p.grad.clone() for p in (extractor.query.weight, extractor.key.weight)]  # type: ignore[union-attr]

    extractor.zero_grad()
    own_input, scores = extractor._scores(obs, actions)  # type: ignore[operator]
    slots = extractor._slots(obs, actions)  # type: ignore[operator]
    mixture = th.softmax(scores, dim=1).unsqueeze(1) @ slots  # [batch, 1, slot]
    surrogate = th.cat((own_input, mixture.expand(-1, 2, -1).flatten(1)), dim=1)
    (surrogate * upstream).sum().backward()
    for mine, by_hand in zip(straight_through, (extractor.query.weight.grad, extractor.key.weight.grad)):
        assert mine.abs().sum() > 0
        th.testing.assert_close(mine, by_hand)


@pytest.mark.parametrize("temperature", [0.5, 2.0])
def test_learned_selection_scores_stay_bounded_so_their_gradient_survives(temperature: float) -> None:
    """An unbounded score lets the softmax saturate and the choice freeze; these stay within 1 / temperature."""
    critic = make_critic("learned_selection", k=1, temperature=temperature)
    extractor = critic.extractors[0]
    with th.no_grad():
        for parameter in extractor.parameters():
            parameter.mul_(100.0)  # as if training had grown the weights
    obs, actions = batch()
    scores = extractor._scores(obs, actions)[1]  # type: ignore[operator]
    bound = 1.0 / temperature
    assert scores.abs().max() <= bound + 1e-5
    assert scores.abs().max() > 0.5 * bound  # the bound is the temperature's, not a fixed one
    # So every weight keeps a floor: the smallest possible, one agent at -bound and two at +bound.
    floor = th.softmax(th.tensor([bound, bound, -bound]), dim=0).min()
    assert th.softmax(scores, dim=1).min() >= floor - 1e-6
    critic(obs, actions)[:, 0].sum().backward()
    assert extractor.query.weight.grad.abs().sum() > 1e-3  # type: ignore[union-attr]


def test_learned_selection_refuses_a_temperature_that_is_not_positive() -> None:
    with pytest.raises(ValueError, match="temperature must be positive"):
        LearnedSelectionCriticFeatures(LAYOUT, 0, k=1, temperature=0.0)


def test_learned_selection_value_ignores_unchosen_agents() -> None:
    critic = make_critic("learned_selection", k=1)
    extractor = critic.extractors[0]
    obs, actions = batch()
    checked = 0
    with th.no_grad():
        base = critic(obs, actions)[:, 0]
        chosen = extractor.chosen_agents(obs, actions)[:, 0]  # type: ignore[operator]
        # Scale one unchosen agent's data by a tiny factor: the choice stays, and so does Q_0.
        for row in range(BATCH):
            unchosen = next(j for j in (1, 2, 3) if j != chosen[row])
            nudged_obs = obs.clone()
            nudged_obs[row, LAYOUT.obs_slices[unchosen]] *= 1.0 + 1e-4
            if extractor.chosen_agents(nudged_obs, actions)[row, 0] == chosen[row]:  # type: ignore[operator]
                assert critic(nudged_obs, actions)[row, 0] == base[row]
                checked += 1
            # The chosen agent's data does change Q_0.
            moved_obs = obs.clone()
            moved_obs[row, LAYOUT.obs_slices[int(chosen[row])]] += 0.5
            assert critic(moved_obs, actions)[row, 0] != base[row]
    assert checked >= BATCH // 2  # not vacuous: most nudges keep the choice


@pytest.mark.parametrize("k", [1, 2])
def test_diagnostics_come_from_the_critic_update_and_match_a_hand_computation(k: int) -> None:
    critic = make_critic("learned_selection", k=k)
    extractor = critic.extractors[0]
    obs, actions = batch()
    with th.no_grad():
        critic(obs, actions)  # outside the critic update: nothing is recorded
    assert extractor.diagnostics() == {}
    with th.no_grad(), critic.recording_diagnostics():
        critic(obs, actions)
    assert not extractor.recording  # switched off again
    report = extractor.diagnostics()
    # By hand: agent 0's distances to agents 1, 2, 3 from the positions at columns 2:4 of each observation.
    positions = th.stack([obs[:, LAYOUT.obs_slices[j]][:, 2:4] for j in range(N_AGENTS)], dim=1)
    distances = (positions[:, 1:] - positions[:, :1]).norm(dim=-1)
    nearest = distances.argmin(dim=1)
    with th.no_grad():
        weights = extractor.listening_weights(obs, actions)
        chosen = extractor.chosen_agents(obs, actions) - 1  # agents 1..3 are others 0..2
    assert report["weight_on_nearest"] == pytest.approx(float(weights[th.arange(BATCH), nearest].mean()), rel=1e-5)
    k_nearest = [set(row) for row in distances.argsort(dim=1)[:, :k].tolist()]
    assert report["chose_nearest"] == pytest.approx(np.mean([set(c) == n for c, n in zip(chosen.tolist(), k_nearest)]))
    rank_of_chosen = (distances.unsqueeze(1) < distances.gather(1, chosen).unsqueeze(2)).sum(dim=2) + 1
    assert report["chosen_rank"] == pytest.approx(float(rank_of_chosen.float().mean()))
    entropy = -(weights * weights.log()).sum(dim=1).mean()
    assert report["attention_entropy"] == pytest.approx(float(entropy), rel=1e-5)
    first = chosen[:, 0].tolist()
    assert report["top_choice_share"] == pytest.approx(max(first.count(j) for j in range(3)) / BATCH)


@pytest.mark.parametrize("scheme", list(SCHEMES))
def test_trains_saves_loads_and_logs_what_critics_listen_to(scheme: str, tmp_path: Path) -> None:
    env = SimpleSpreadVecEnv(n_envs=4, n_agents=3)
    kwargs = {"k": 1} if scheme == "learned_selection" else {"n_heads": 2}
    model = MADDPG("MlpPolicy", env, critic_sharing=scheme, critic_sharing_kwargs={"embed_dim": 8, **kwargs}, seed=0, **FAST)
    target = model.critic_target.extractors[0]
    assert target is not model.critic.extractors[0]  # a target copy, Polyak-averaged
    before = [p.detach().clone() for p in target.parameters()]
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(1_000, log_interval=1)
    assert any(not th.equal(a, b) for a, b in zip(before, target.parameters()))

    with open(tmp_path / "progress.csv", newline="") as file:
        rows = [row for row in csv.DictReader(file) if row.get("train/attention_entropy")]
    assert rows, "the diagnostics are logged"
    last = rows[-1]
    keys = ["attention_entropy", "weight_on_nearest"]
    keys += ["chose_nearest", "chosen_rank", "top_choice_share"] if scheme == "learned_selection" else ["head_entropy"]
    for key in keys:  # per critic, and the team's mean of them
        per_agent = [float(last[f"train/agent_{i}/{key}"]) for i in range(3)]
        assert float(last[f"train/{key}"]) == pytest.approx(np.mean(per_agent), rel=1e-5), key
    if scheme == "attention":
        assert float(last["train/head_entropy"]) <= float(last["train/attention_entropy"]) + 1e-6

    obs = env.reset()
    q_before = model.policy.q_values(th.as_tensor(obs), th.zeros(4, 15))
    model.save(tmp_path / "model.zip")
    loaded = MADDPG.load(tmp_path / "model.zip")
    th.testing.assert_close(loaded.policy.q_values(th.as_tensor(obs), th.zeros(4, 15)), q_before)
    for mine, theirs in zip(model.critic_target.parameters(), loaded.critic_target.parameters()):
        th.testing.assert_close(mine, theirs)

    listening = critic_listening(loaded, obs)
    assert listening["weights"].shape == (4, 3, 3)
    np.testing.assert_allclose(listening["weights"].sum(axis=2), 1.0, rtol=1e-5)
    # Row i is critic i's own weights on the others, for the model's deterministic actions.
    actions = th.as_tensor(loaded.policy.scale_action(loaded.predict(obs, deterministic=True)[0]), dtype=th.float32)
    for i, extractor in enumerate(loaded.critic.extractors):
        with th.no_grad():
            expected = extractor.listening_weights(th.as_tensor(obs), actions)  # type: ignore[operator]
        np.testing.assert_allclose(listening["weights"][:, i, extractor.encoder.others], expected.numpy(), rtol=1e-5)
    # Torch input, even one that requires grad, gives the same answer.
    as_tensor = critic_listening(loaded, th.as_tensor(obs).requires_grad_(True))
    np.testing.assert_array_equal(as_tensor["weights"], listening["weights"])
    if scheme == "learned_selection":
        assert listening["chosen"].shape == (4, 3, 1)
        assert all(listening["chosen"][:, i, 0].tolist().count(i) == 0 for i in range(3))
    else:
        assert listening["chosen"] is None


def test_listening_helper_refuses_other_critics() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs=2, n_agents=3), critic_sharing="full", **FAST)
    with pytest.raises(TypeError, match="critic_sharing='attention' or 'learned_selection'"):
        critic_listening(model, np.zeros((1, model.observation_space.shape[0])))


def test_distance_ranks_follow_positions() -> None:
    extractor = LearnedSelectionCriticFeatures(LAYOUT, 0, k=1, embed_dim=8)
    obs = th.zeros(1, LAYOUT.obs_dim)
    for agent, x in enumerate([0.0, 3.0, 1.0, 2.0]):  # agent 0 at the origin; agent 2 nearest, then 3, then 1
        obs[0, LAYOUT.obs_slices[agent].start + 2] = x
    assert extractor._distance_ranks(obs).tolist() == [[3, 1, 2]]  # others in ascending index: 1, 2, 3
    # An env that declares no positions gets no distance diagnostics (not MPE's 2:4 read from whatever is there)...
    undeclared = AgentLayout(LAYOUT.agent_ids, LAYOUT.obs_sizes, LAYOUT.action_sizes)
    assert LearnedSelectionCriticFeatures(undeclared, 0, k=1, embed_dim=8)._distance_ranks(obs) is None
    # ...unless the extractor is told where they are.
    told = LearnedSelectionCriticFeatures(undeclared, 0, k=1, embed_dim=8, position_slice=slice(2, 4))
    assert told._distance_ranks(obs).tolist() == [[3, 1, 2]]


def test_diagnostics_are_computed_less_than_every_other_update(monkeypatch: pytest.MonkeyPatch) -> None:
    env = SimpleSpreadVecEnv(n_envs=4, n_agents=3)
    model = MADDPG("MlpPolicy", env, critic_sharing="attention", critic_sharing_kwargs={"embed_dim": 8}, seed=0, **FAST)
    calls = {"diagnostics": 0, "updates": 0}
    diagnostics, train = model.critic.diagnostics, model.train

    def counted_diagnostics() -> list[dict[str, float]]:
        calls["diagnostics"] += 1
        return diagnostics()

    def counted_train(*args: object, **kwargs: object) -> None:
        calls["updates"] += 1
        train(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(model.critic, "diagnostics", counted_diagnostics)
    monkeypatch.setattr(model, "train", counted_train)
    model.learn(1_000, log_interval=8)  # 4 envs end their 25-step episodes together: a write every 50 steps
    assert calls["updates"] > 2 * calls["diagnostics"] > 0
