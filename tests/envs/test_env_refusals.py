"""What MADDPG refuses in the env it is given, with the cause first and the fix: raw PettingZoo envs (the real mpe2
ones), non-Box action spaces, and an env of another team on load or set_env."""

import gymnasium as gym
import pytest
from mpe2 import simple_spread_v3, simple_tag_v3

from sb3_maddpg import MADDPG
from sb3_maddpg.common.env_checks import pettingzoo_kind
from sb3_maddpg.envs import PettingZooToGym, make_simple_spread


@pytest.mark.parametrize("factory", [simple_spread_v3.parallel_env, simple_tag_v3.parallel_env])
def test_raw_parallel_env_is_told_to_wrap(factory) -> None:
    env = factory(continuous_actions=True)
    hint = r"^MADDPG got a raw PettingZoo ParallelEnv.*PettingZooToGym\(env\).*make_simple_spread"
    with pytest.raises(TypeError, match=hint):
        MADDPG("MlpPolicy", env)
    # And following the hint works.
    assert MADDPG("MlpPolicy", PettingZooToGym(env), learning_starts=0).agent_layout.n_agents == len(env.possible_agents)


@pytest.mark.parametrize("continuous", [True, False])
def test_raw_aec_env_is_told_to_go_parallel_then_wrap(continuous: bool) -> None:
    # Whatever the action type: the old message blamed discrete actions, and its hint gave the same error again.
    env = simple_spread_v3.env(continuous_actions=continuous)
    hint = r"^MADDPG got a raw PettingZoo AECEnv.*parallel_env.*aec_to_parallel.*PettingZooToGym"
    with pytest.raises(TypeError, match=hint):
        MADDPG("MlpPolicy", env)


def test_non_box_action_space_is_printed_as_the_space() -> None:
    with pytest.raises(TypeError, match=r"action space is Discrete\(2\).*PettingZooToGym"):
        MADDPG("MlpPolicy", gym.make("CartPole-v1"))


def test_pettingzoo_kind_tells_the_apis_apart() -> None:
    assert pettingzoo_kind(simple_spread_v3.parallel_env()) == "ParallelEnv"
    assert pettingzoo_kind(simple_spread_v3.env()) == "AECEnv"
    assert pettingzoo_kind(make_simple_spread(n_agents=2)) is None  # the adapter is a gymnasium env


@pytest.fixture(scope="module")
def saved_three_agent_model(tmp_path_factory: pytest.TempPathFactory) -> str:
    path = str(tmp_path_factory.mktemp("model") / "three")
    MADDPG("MlpPolicy", make_simple_spread(n_agents=3), learning_starts=0).save(path)
    return path


@pytest.mark.parametrize(
    ("env_kwargs", "cause"),
    [
        ({"n_agents": 5}, r"the model has 3 agents, the env 5"),
        ({"n_agents": 2}, r"the model has 3 agents, the env 2"),
        ({"n_agents": 3, "num_agent_neighbors": 1}, r"agents of other observation or action sizes"),
    ],
)
def test_load_with_another_team_says_what_each_has(saved_three_agent_model: str, env_kwargs: dict, cause: str) -> None:
    env = make_simple_spread(**env_kwargs)
    pattern = rf"^The env's team differs from the model's \({cause}\): the model was trained for 3 agents .*cannot change"
    with pytest.raises(ValueError, match=pattern):
        MADDPG.load(saved_three_agent_model, env=env)
    with pytest.raises(ValueError, match=pattern):  # set_env says the same
        MADDPG.load(saved_three_agent_model).set_env(env)


def test_load_with_another_team_from_an_open_file(saved_three_agent_model: str) -> None:
    with open(saved_three_agent_model + ".zip", "rb") as file:
        with pytest.raises(ValueError, match=r"the model has 3 agents, the env 4"):
            MADDPG.load(file, env=make_simple_spread(n_agents=4))
        file.seek(0)
        # The check reads the save and rewinds: the load itself still works on the same file.
        assert MADDPG.load(file, env=make_simple_spread(n_agents=3)).agent_layout.n_agents == 3


def test_load_with_agents_in_another_order(saved_three_agent_model: str) -> None:
    env = make_simple_spread(n_agents=3)
    layout = env.agent_layout
    reordered = type(layout)(tuple(reversed(layout.agent_ids)), layout.obs_sizes, layout.action_sizes)
    env.agent_layout = reordered  # the same agents, listed in another order
    with pytest.raises(ValueError, match=r"the same agents in another order.*agent_2, agent_1, agent_0"):
        MADDPG.load(saved_three_agent_model, env=env)


def test_load_with_a_raw_pettingzoo_env_is_told_to_wrap(saved_three_agent_model: str) -> None:
    with pytest.raises(TypeError, match=r"^MADDPG got a raw PettingZoo ParallelEnv"):
        MADDPG.load(saved_three_agent_model, env=simple_spread_v3.parallel_env(continuous_actions=True))
