"""Dict and Tuple observation spaces through the adapter: flattened as gymnasium flattens them, each agent's slice of
the joint observation ``gymnasium.spaces.flatten(space, obs)``, checked on mpe2 behind a PettingZoo wrapper that gives
structured observations, and a model trains and acts on them."""

from typing import Any

import numpy as np
import pytest
from gymnasium import spaces
from mpe2 import simple_spread_v3
from pettingzoo.utils.wrappers import BaseParallelWrapper

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import PettingZooToGym

N = 3
SIZE = 4 + 2 * N + 4 * (N - 1)  # mpe2: velocity and position, landmarks, other agents and their communication


class StructuredObservations(BaseParallelWrapper):
    """mpe2's simple_spread with each observation split into named parts (a Dict) or in order (a Tuple), plus an
    integer part (the step, ``Discrete``)."""

    def __init__(self, env: Any, kind: str) -> None:
        super().__init__(env)
        self.kind, self.t = kind, 0

    def _parts(self, agent: str) -> dict[str, spaces.Space]:
        box = self.env.observation_space(agent)
        return {
            "self": spaces.Box(box.low[:4], box.high[:4], dtype=np.float32),
            "world": spaces.Box(box.low[4:], box.high[4:], dtype=np.float32),
            "step": spaces.Discrete(26),
        }

    def observation_space(self, agent: str) -> spaces.Space:
        parts = self._parts(agent)
        return spaces.Dict(parts) if self.kind == "dict" else spaces.Tuple(tuple(parts.values()))

    def _structure(self, observations: dict[str, np.ndarray]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for agent, obs in observations.items():
            parts = {"self": obs[:4], "world": obs[4:], "step": self.t}
            out[agent] = parts if self.kind == "dict" else tuple(parts.values())
        return out

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        observations, infos = self.env.reset(seed=seed, options=options)
        self.t = 0
        return self._structure(observations), infos

    def step(self, actions: dict) -> tuple:
        observations, *rest = self.env.step(actions)
        self.t += 1
        return (self._structure(observations), *rest)


def make(kind: str) -> PettingZooToGym:
    return PettingZooToGym(StructuredObservations(simple_spread_v3.parallel_env(N=N, continuous_actions=True), kind))


@pytest.mark.parametrize("kind", ["dict", "tuple"])
def test_each_agents_slice_is_its_observation_as_gymnasium_flattens_it(kind: str) -> None:
    env, plain = make(kind), PettingZooToGym(simple_spread_v3.parallel_env(N=N, continuous_actions=True))
    assert env.agent_layout.obs_sizes == (SIZE + 26,) * N  # the step one-hot: Discrete(26)
    obs, _ = env.reset(seed=4)
    plain_obs, _ = plain.reset(seed=4)
    rng = np.random.default_rng(0)
    for step in range(3):
        for agent, part in enumerate(env.agent_layout.obs_slices):
            mine, theirs = obs[part], plain_obs[plain.agent_layout.obs_slices[agent]]
            one_hot = np.eye(26, dtype=np.float32)[step]
            # gymnasium's order: a Dict's keys sorted (self, step, world), a Tuple's in order (self, world, step).
            expected = [theirs[:4], one_hot, theirs[4:]] if kind == "dict" else [theirs[:4], theirs[4:], one_hot]
            np.testing.assert_array_equal(mine, np.concatenate(expected))
            assert env.observation_space.contains(obs)
        action = rng.uniform(0, 1, env.action_space.shape).astype(np.float32)
        obs, *_ = env.step(action)
        plain_obs, *_ = plain.step(action)


def test_a_model_updates_and_acts_in_space_on_dict_observations() -> None:
    env = make("dict")
    model = MADDPG(
        "MlpPolicy", env, learning_starts=50, batch_size=16, transitions_per_update=10, policy_kwargs={"net_arch": [8]}
    )
    model.learn(100)
    assert model._n_updates > 0
    obs, _ = env.reset(seed=1)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action)


def test_a_part_of_variable_size_is_refused_naming_the_agent() -> None:
    class WithText(StructuredObservations):
        def observation_space(self, agent: str) -> spaces.Space:
            return spaces.Dict({"trail": spaces.Sequence(spaces.Box(0, 1, (2,)))})  # of variable length

    with pytest.raises(TypeError, match=r"'agent_0' has a Dict observation space with a part gymnasium cannot flatten"):
        PettingZooToGym(WithText(simple_spread_v3.parallel_env(N=N, continuous_actions=True), "dict"))
