"""What PettingZooToGym refuses at construction, before a confusing failure later."""

import pytest
from mpe2 import simple_adversary_v3, simple_spread_v3
from pettingzoo.utils.conversions import aec_to_parallel

from sb3_maddpg.envs import PettingZooToGym


@pytest.mark.parametrize("module", [simple_adversary_v3, simple_spread_v3])
def test_aec_env_is_refused_at_construction(module) -> None:
    # An AEC env used to be accepted, then failed in reset() with "cannot unpack non-iterable NoneType object".
    with pytest.raises(TypeError, match=r"needs a PettingZoo ParallelEnv, got an AEC env.*parallel_env.*aec_to_parallel"):
        PettingZooToGym(module.env(continuous_actions=True))


@pytest.mark.parametrize(
    ("not_an_env", "called"),
    [(simple_spread_v3.parallel_env, "call it"), (simple_spread_v3, None), (None, None)],
    ids=["factory", "module", "None"],
)
def test_what_is_not_an_env_is_refused_by_what_it_is(not_an_env, called) -> None:
    # These failed with an AttributeError on possible_agents, naming neither the argument nor what to pass.
    with pytest.raises(TypeError, match=r"^PettingZooToGym needs a PettingZoo ParallelEnv instance, got ") as refused:
        PettingZooToGym(not_an_env)
    message = str(refused.value)
    assert "pass the env itself" in message and (called is None or called in message)
    if not_an_env is simple_spread_v3:
        assert "module 'mpe2.simple_spread_v3'" in message


def test_aec_to_parallel_env_resets_to_the_joint_shape_and_steps() -> None:
    env = PettingZooToGym(aec_to_parallel(simple_adversary_v3.env(continuous_actions=True)))
    obs, _ = env.reset(seed=0)
    assert obs.shape == env.observation_space.shape
    env.step(env.action_space.sample())
