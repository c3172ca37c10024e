"""Exploration noise: the default, refitting to another number of envs, and one add-mask-clip for data collection and
evaluation alike."""

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise, VectorizedActionNoise

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.noise import (
    add_noise,
    default_noise,
    fit_noise_to_envs,
    noise_copy_for_envs,
    per_env_noise,
)
from sb3_maddpg.envs import PettingZooToGym, make_simple_spread
from tests.maddpg.test_discrete_actions import is_one_hot
from tests.mixed_team import MixedTeam

FAST = dict(learning_starts=0, batch_size=16, buffer_size=500, policy_kwargs=dict(net_arch=[8]), seed=0)
MIXED = AgentLayout(("mover", "chooser", "other"), (1, 1, 1), (2, 3, 1), discrete_actions=(False, True, False))


class Recorder(gym.Wrapper):
    """Keeps the observation each action was chosen on, and the action."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.observations: list[np.ndarray] = []
        self.actions: list[np.ndarray] = []

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict]:
        obs, info = self.env.reset(**kwargs)
        self.last = obs
        return obs, info

    def step(self, action: np.ndarray) -> tuple:
        self.observations.append(self.last)
        self.actions.append(np.array(action))
        obs, *rest = self.env.step(action)
        self.last = obs
        return (obs, *rest)


@pytest.mark.filterwarnings("ignore:evaluate_team")
def test_training_and_evaluation_explore_alike_on_a_mixed_team() -> None:
    """A user's noise on every component: both add it to the continuous agent only, and clip alike."""
    env = PettingZooToGym(MixedTeam())  # mover: Box(-1, 1, (1,)); chooser: Discrete(3), a one-hot of 3
    noise = NormalActionNoise(np.zeros(4), np.full(4, 0.7))  # large enough to be clipped at times
    model = MADDPG("MlpPolicy", env, action_noise=noise, **FAST)
    recorder = Recorder(PettingZooToGym(MixedTeam()))
    np.random.seed(0)
    evaluate_team(model, recorder, n_episodes=2, deterministic=False)
    explored = np.asarray(recorder.actions)  # 20 steps
    assert is_one_hot(explored[:, 1:], low=0.0)  # the chooser's one-hot took no noise
    with_noise = explored[:, 0] != model.predict(np.asarray(recorder.observations), deterministic=True)[0][:, 0]
    assert with_noise.all() and (np.abs(explored[:, 0]) == 1.0).any()  # the mover's did, clipped at times

    np.random.seed(0)  # the same draws in training, on the same observations
    model.num_timesteps = model.learning_starts
    for obs, evaluated in zip(recorder.observations, explored):
        model._last_obs = obs[None]
        action, buffer_action = model._sample_action(model.learning_starts, model.action_noise, 1)
        np.testing.assert_allclose(action[0, :1], evaluated[:1], atol=1e-6, rtol=0)
        assert is_one_hot(buffer_action[0, 1:])  # sampled in training, and no noise on it either


def test_add_noise_masks_discrete_components_and_clips() -> None:
    actions = np.array([[0.5, -0.2, -1.0, 1.0, -1.0, 0.9]])
    noise = NormalActionNoise(np.zeros(6), np.full(6, 0.5))
    np.random.seed(1)
    draw = noise()
    np.random.seed(1)
    noisy = add_noise(actions, noise, MIXED.discrete_components())
    np.testing.assert_array_equal(noisy[0, 2:5], actions[0, 2:5])  # the chooser's one-hot
    expected = np.clip(actions + draw, -1, 1)
    np.testing.assert_array_equal(noisy[0, [0, 1, 5]], expected[0, [0, 1, 5]])
    np.random.seed(1)
    np.testing.assert_array_equal(add_noise(actions, noise), expected)  # no mask: every component
    with pytest.raises(ValueError, match=r"noise of shape \(6,\), but the joint actions have shape \(1, 7\)"):
        add_noise(np.zeros((1, 7)), noise)


def test_default_noise() -> None:
    box = gym.spaces.Box(0.0, 1.0, (6,))
    noise = default_noise(MIXED, [0.1, 0.3, 0.2], box)
    assert isinstance(noise, NormalActionNoise)
    np.testing.assert_allclose(noise._sigma, [0.2, 0.2, 0, 0, 0, 0.4])  # [-1, 1] is twice [0, 1]; none on one-hots
    np.testing.assert_allclose(default_noise(MIXED, 0.1, box)._sigma, [0.2, 0.2, 0, 0, 0, 0.2])  # type: ignore[union-attr]
    assert default_noise(MIXED, 0.0, box) is None and default_noise(MIXED, [0, 0, 0], box) is None


@pytest.mark.parametrize("noise_std", [[0.1, 0.2], [0.1] * 4, [[0.1, 0.1, 0.1]]])
def test_noise_std_of_the_wrong_length_is_refused(noise_std: Any) -> None:
    with pytest.raises(ValueError, match=r"noise_std has \d+ values, but the team has 3 agents.*one per agent"):
        MADDPG("MlpPolicy", make_simple_spread(n_agents=3), noise_std=noise_std, **FAST)


@pytest.mark.parametrize("noise_std", [-0.1, [0.1, -0.2, 0.1], float("nan"), float("inf")])
def test_negative_or_non_finite_noise_std_is_refused(noise_std: Any) -> None:
    with pytest.raises(ValueError, match=r"^noise_std \(.*\) must be a number >= 0, got .*: use 0.1, or 0 for no noise"):
        MADDPG("MlpPolicy", make_simple_spread(n_agents=3), noise_std=noise_std, **FAST)


@pytest.mark.parametrize("max_grad_norm", [0, -0.5, float("nan")])
def test_max_grad_norm_must_be_positive(max_grad_norm: float) -> None:
    with pytest.raises(ValueError, match=r"^max_grad_norm \(.*\) must be a number > 0, or None .*: use 0.5 .*or None to turn"):
        MADDPG("MlpPolicy", make_simple_spread(n_agents=3), max_grad_norm=max_grad_norm, **FAST)
    MADDPG("MlpPolicy", make_simple_spread(n_agents=3), max_grad_norm=None, **FAST)  # no clipping: allowed


def test_noise_of_another_number_of_envs() -> None:
    base = OrnsteinUhlenbeckActionNoise(np.zeros(2), np.full(2, 0.2))
    vectorised = VectorizedActionNoise(base, 2)
    assert per_env_noise(vectorised) is base and per_env_noise(base) is base
    assert fit_noise_to_envs(vectorised, 4) is base  # SB3's _setup_learn vectorises it again for 4
    assert fit_noise_to_envs(vectorised, 2) is vectorised and fit_noise_to_envs(base, 4) is base
    assert fit_noise_to_envs(None, 4) is None
    copy = noise_copy_for_envs(vectorised, 3)
    assert copy.n_envs == 3 and copy.base_noise is not base and isinstance(copy.base_noise, OrnsteinUhlenbeckActionNoise)
    base.noise_prev = np.ones(2)
    assert np.all(copy.noises[0].noise_prev == 0)  # a copy: the model's own process is not advanced


def test_the_exploration_rule_is_the_same_in_numpy_and_torch() -> None:
    import torch as th

    from sb3_maddpg.common.noise import noisy_actions

    generator = np.random.default_rng(3)
    actions = generator.uniform(-1, 1, (4, 6)).astype(np.float32)
    noise = generator.normal(0, 0.8, (4, 6)).astype(np.float32)
    discrete = np.array([False, False, True, True, True, False])
    on_host = noisy_actions(actions, noise, discrete)
    on_torch = noisy_actions(th.as_tensor(actions), th.as_tensor(noise), discrete)
    assert isinstance(on_torch, th.Tensor) and np.array_equal(on_torch.numpy(), on_host)
    assert np.array_equal(on_host[:, 2:5], actions[:, 2:5])  # no noise on the discrete one-hot
    assert on_host.min() >= -1.0 and on_host.max() <= 1.0 and (np.abs(on_host) == 1.0).any()  # clipped, and it mattered
