"""Layer normalisation in the per-agent networks: the hand computation, each agent's own, through MADDPG and MATD3."""

from pathlib import Path

import numpy as np
import pytest
import torch as th
from torch import nn
from torch.nn import functional as F

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.common.networks import AgentEnsembleMLP
from sb3_maddpg.envs import make_mpe_env, make_simple_spread

IN_DIMS, OUT_DIMS, HIDDEN = (3, 5), (2, 4), (6, 7)


def ensemble(share_parameters: bool = False) -> AgentEnsembleMLP:
    th.manual_seed(0)
    dims = (4, 4) if share_parameters else IN_DIMS
    mlp = AgentEnsembleMLP(
        dims, (3, 3) if share_parameters else OUT_DIMS, HIDDEN, nn.Tanh, layer_norm=True, share_parameters=share_parameters
    )
    with th.no_grad():  # scales and shifts away from 1 and 0, so that using them (or not) shows
        for scale, shift in mlp.norms:
            scale.uniform_(0.5, 1.5)
            shift.uniform_(-0.5, 0.5)
    return mlp


def by_hand(mlp: AgentEnsembleMLP, member: int, x: th.Tensor) -> th.Tensor:
    """One agent's network, layer by layer from its own slices: linear, normalise, scale and shift, activation."""
    in_dim = x.shape[1]
    for layer, (weight, bias) in enumerate(zip(mlp.weights, mlp.biases)):
        w = weight[member, :in_dim] if layer == 0 else weight[member]
        x = x @ w + bias[member, 0]
        if layer < mlp.n_layers - 1:
            scale, shift = mlp.norms[layer]
            mean, var = x.mean(dim=1, keepdim=True), x.var(dim=1, unbiased=False, keepdim=True)
            x = th.tanh((x - mean) / th.sqrt(var + 1e-5) * scale[member, 0] + shift[member, 0])
    return x[:, : mlp.out_dims[member]]


def test_each_agent_is_its_linear_layers_normalised_scaled_and_shifted_by_hand() -> None:
    mlp = ensemble()
    inputs = [th.randn(8, d) for d in IN_DIMS]
    joint = mlp(th.stack([F.pad(x, (0, max(IN_DIMS) - x.shape[1])) for x in inputs]))
    for i, x in enumerate(inputs):
        expected = by_hand(mlp, i, x)
        th.testing.assert_close(joint[i, :, : OUT_DIMS[i]], expected, rtol=1e-5, atol=1e-6)
        th.testing.assert_close(mlp.forward_agent(i, x), expected, rtol=1e-5, atol=1e-6)
    # Two hidden layers, each with a scale and a shift per agent; no normalisation of the output layer.
    assert [tuple(p.shape) for pair in mlp.norms for p in pair] == [(2, 1, 6), (2, 1, 6), (2, 1, 7), (2, 1, 7)]


def test_an_agents_output_depends_on_its_own_normalisation_only() -> None:
    mlp = ensemble()
    inputs = th.randn(2, 8, max(IN_DIMS))
    mlp(inputs)[0].sum().backward()
    for scale, shift in mlp.norms:
        assert scale.grad[0].abs().sum() > 0 and shift.grad[0].abs().sum() > 0
        assert th.all(scale.grad[1] == 0) and th.all(shift.grad[1] == 0)
    # Per-agent clipping counts the normalisation's gradients too: agent 1 has none, so its norm is 0.
    assert mlp.squared_grad_norms()[1] == 0 and mlp.squared_grad_norms()[0] > 0


def test_shared_parameters_normalise_with_one_scale_and_shift() -> None:
    mlp = ensemble(share_parameters=True)
    assert all(p.shape == (1, 1, 6) for p in mlp.norms[0])
    x = th.randn(8, 4)
    out = mlp(th.stack([x, x]))
    th.testing.assert_close(out[0], by_hand(mlp, 0, x), rtol=1e-5, atol=1e-6)
    th.testing.assert_close(out[1], out[0])


def test_without_layer_norm_there_are_no_normalisation_parameters() -> None:
    mlp = AgentEnsembleMLP(IN_DIMS, OUT_DIMS, HIDDEN)
    assert mlp.norms == [] and not any("norm" in name for name, _ in mlp.named_parameters())


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_models_with_layer_norm_train_save_and_load(algorithm: type[MADDPG], tmp_path: Path) -> None:
    kwargs = dict(learning_starts=50, batch_size=16, transitions_per_update=10, seed=0)
    model = algorithm(
        "MlpPolicy", make_mpe_env("simple_speaker_listener"), policy_kwargs=dict(net_arch=[16], layer_norm=True), **kwargs
    )
    before = [p.clone() for pair in model.actor.mlp.norms for p in pair]
    model.learn(200)
    # The normalisation is trained (actor and critics), and its targets follow by Polyak averaging.
    assert any(not th.equal(b, p) for b, p in zip(before, (p for pair in model.actor.mlp.norms for p in pair)))
    assert model.critic.mlp.norms and model.critic_target.mlp.norms and model.actor_target.mlp.norms
    model.save(tmp_path / "model")
    loaded = algorithm.load(tmp_path / "model", env=make_mpe_env("simple_speaker_listener"))
    assert loaded.policy.layer_norm
    obs = np.random.default_rng(0).normal(size=(5, model.observation_space.shape[0])).astype(np.float32)
    np.testing.assert_array_equal(loaded.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0])


def test_layer_norm_is_off_by_default_as_in_the_paper() -> None:
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=2), learning_starts=10)
    assert not model.policy.layer_norm and model.actor.mlp.norms == [] and model.critic.mlp.norms == []
