"""The constructor arguments that are not numbers: ``net_arch`` and ``action_noise`` are refused by name when malformed,
with what to write, and taken when well formed."""

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from stable_baselines3.common.noise import NormalActionNoise

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.maddpg.policies import DEFAULT_NET_ARCH, hidden_sizes

SMALL = dict(buffer_size=64, learning_starts=0, batch_size=8)


@pytest.mark.parametrize(
    ("net_arch", "part"),
    [
        ([-1], "'pi'"),
        ([8, 0], "'pi'"),
        ([8.5], "'pi'"),
        ([True], "'pi'"),
        ("64", "'pi'"),
        (dict(pi=[8], qf=[-3]), "'qf'"),
        (dict(pi=[8]), "needs the keys"),
        ({"qf": [8], 1: [2]}, "needs the keys"),
    ],
)
@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_malformed_net_arch_is_refused_by_name(algorithm: type[MADDPG], net_arch: Any, part: str) -> None:
    with pytest.raises(ValueError, match=r"^net_arch.*" + part + r".*e\.g\. net_arch="):
        algorithm("MlpPolicy", SimpleSpreadVecEnv(n_envs=1, n_agents=2), policy_kwargs=dict(net_arch=net_arch), **SMALL)


@pytest.mark.parametrize(
    ("net_arch", "expected"),
    [
        (None, DEFAULT_NET_ARCH),
        ([16, 8], {"pi": [16, 8], "qf": [16, 8]}),
        ((np.int64(4),), {"pi": [4], "qf": [4]}),
        (dict(pi=[4], qf=[6, 6]), {"pi": [4], "qf": [6, 6]}),
        ([], {"pi": [], "qf": []}),  # linear networks
        (np.array([8, 8]), {"pi": [8, 8], "qf": [8, 8]}),
        (dict(pi=[4], qf=[6], vf=[9]), {"pi": [4], "qf": [6]}),  # other keys ignored, as SB3's TD3 does
    ],
)
def test_well_formed_net_arch_builds_those_layers(net_arch: Any, expected: dict[str, list[int]]) -> None:
    assert hidden_sizes(net_arch) == expected
    model = MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs=1, n_agents=2), policy_kwargs=dict(net_arch=net_arch), **SMALL)
    assert model.policy.net_arch == expected
    for part, network in (("pi", model.policy.actor), ("qf", model.policy.critic)):
        widths = [weight.shape[-1] for name, weight in network.named_parameters() if ".weight_" in name]
        assert widths[:-1] == expected[part]  # the last layer is the output: an action or a value


def test_a_save_whose_net_arch_has_other_keys_loads(tmp_path: Path) -> None:
    """Before the check, a dict's keys beyond pi and qf were kept and saved: such a save must still load."""
    env = SimpleSpreadVecEnv(n_envs=1, n_agents=2)
    model = MADDPG("MlpPolicy", env, policy_kwargs=dict(net_arch=dict(pi=[4], qf=[6], vf=[9])), **SMALL)
    model.policy_kwargs["net_arch"] = dict(pi=[4], qf=[6], vf=[9])  # as an older version saved it
    model.save(tmp_path / "older")
    assert MADDPG.load(tmp_path / "older", env=env).policy.net_arch == {"pi": [4], "qf": [6]}


def test_default_net_arch_is_not_shared_with_a_model() -> None:
    """The policy's lists are its own: changing them must not change the paper's defaults."""
    sizes = hidden_sizes(None)
    sizes["pi"].append(1)
    assert DEFAULT_NET_ARCH == {"pi": [64, 64], "qf": [64, 64, 64]}


@pytest.mark.parametrize("noise", ["normal", 0.1, {"sigma": 0.1}])
def test_action_noise_that_is_not_an_action_noise_is_refused(noise: Any) -> None:
    refusal = r"^action_noise must be an SB3 ActionNoise \(or a callable with reset\(\)\) or None, got .*noise_std"
    with pytest.raises(TypeError, match=refusal):
        MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs=1, n_agents=2), action_noise=noise, **SMALL)


class CalledNoise:
    """Noise SB3 can use without being an ActionNoise: it only calls it and its reset()."""

    def __init__(self, size: int) -> None:
        self.size = size

    def __call__(self) -> np.ndarray:
        return np.full(self.size, 0.1, np.float32)

    def reset(self) -> None:
        pass


def test_a_callable_with_reset_is_taken_as_noise() -> None:
    env = SimpleSpreadVecEnv(n_envs=1, n_agents=2)
    model = MADDPG("MlpPolicy", env, action_noise=CalledNoise(env.action_space.shape[0]), **SMALL)
    model.learn(200)  # noisy steps with it: two rounds of 100 transitions
    assert model.num_timesteps == 200


def test_an_action_noise_is_taken() -> None:
    env = SimpleSpreadVecEnv(n_envs=1, n_agents=2)
    size = env.action_space.shape[0]
    noise = NormalActionNoise(np.zeros(size), 0.2 * np.ones(size))
    model = MADDPG("MlpPolicy", env, action_noise=noise, **SMALL)
    assert model.action_noise is noise
