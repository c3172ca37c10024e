"""Deployment in PettingZoo's terms (issue 34): ``model.predict_agents`` takes a ParallelEnv's ``{agent_id: obs}`` and
gives its ``{agent_id: action}``, what ``predict`` gives on the adapter's joint observation, and drives mpe2 itself;
``predict`` on an observation of another team names the model's team before SB3 names shapes."""

from typing import Any

import numpy as np
import pytest
from mpe2 import simple_spread_v3

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.envs import PettingZooToGym, make_simple_spread
from tests.mixed_team import MixedTeam

SMALL = {"learning_starts": 50, "policy_kwargs": {"net_arch": [16, 16]}}


def lockstep(model: MADDPG, continuous_actions: bool, steps: int = 8) -> list[dict[str, Any]]:
    """
    Run mpe2's simple_spread (N=3) with ``predict_agents`` and, beside it from the same seed, the adapter over another
    mpe2 env with ``predict`` on the adapter's joint observation: both must choose the same actions at every step.

    :return: The actions ``predict_agents`` chose, per step.
    """
    env = simple_spread_v3.parallel_env(N=3, max_cycles=25, continuous_actions=continuous_actions)
    adapter = PettingZooToGym(simple_spread_v3.parallel_env(N=3, max_cycles=25, continuous_actions=continuous_actions))
    observations, _ = env.reset(seed=7)
    joint, _ = adapter.reset(seed=7)
    chosen = []
    for _ in range(steps):
        # The dict in reverse order: the model's agent order is its layout's, not the dict's.
        actions = model.predict_agents(dict(reversed(list(observations.items()))))
        joint_action, _ = model.predict(joint, deterministic=True)
        expected = adapter.agent_actions(joint_action)  # the adapter defines how a joint action splits per agent
        assert list(actions) == env.possible_agents == list(expected)  # in the team's order
        for agent, action in actions.items():
            assert env.action_space(agent).contains(action), (agent, action)  # in the env's units and dtype
            np.testing.assert_array_equal(action, expected[agent])
        chosen.append(actions)
        observations, *_ = env.step(actions)
        joint, *_ = adapter.step(joint_action)
        np.testing.assert_array_equal(np.concatenate([observations[a] for a in env.possible_agents]), joint)
    return chosen


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_predict_agents_drives_mpe2_as_predict_drives_the_adapter(algorithm: type[MADDPG]) -> None:
    model = algorithm("MlpPolicy", make_simple_spread(n_agents=3), seed=0, **SMALL)  # trained or not: the same path
    chosen = lockstep(model, continuous_actions=True)
    for actions in chosen:
        for action in actions.values():
            assert isinstance(action, np.ndarray) and action.dtype == np.float32 and action.shape == (5,)
    # Rescaled from [-1, 1] to mpe2's Box(0, 1): a policy's -1 would be 0 here, its 0 is 0.5; never outside.
    values = np.concatenate([a for actions in chosen for a in actions.values()])
    assert values.min() >= 0.0 and values.max() <= 1.0 and values.std() > 0


def test_predict_agents_gives_a_discrete_team_the_envs_integer_actions() -> None:
    model = MADDPG("MlpPolicy", PettingZooToGym(simple_spread_v3.parallel_env(N=3, continuous_actions=False)), seed=0, **SMALL)
    chosen = lockstep(model, continuous_actions=False)
    assert all(type(action) is int and 0 <= action < 5 for actions in chosen for action in actions.values())


def test_predict_agents_with_a_mixed_team_and_ids_of_any_order() -> None:
    env = PettingZooToGym(MixedTeam(mover_bounds=(-2.0, 3.0)))  # a Box(-2, 3) agent and a Discrete(3) one
    model = MADDPG("MlpPolicy", env, seed=0, **SMALL)
    rng = np.random.default_rng(0)
    for _ in range(5):
        joint = rng.normal(size=2).astype(np.float32)
        actions = model.predict_agents({"chooser": joint[1:], "mover": joint[:1]})
        expected = env.agent_actions(model.predict(joint, deterministic=True)[0])
        assert list(actions) == ["mover", "chooser"] and type(actions["chooser"]) is int
        np.testing.assert_array_equal(actions["mover"], expected["mover"])
        assert actions["chooser"] == expected["chooser"] and -2.0 <= actions["mover"][0] <= 3.0


def test_predict_agents_acts_for_the_agents_present_and_refuses_unknown_ones_naming_the_team() -> None:
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=3), seed=0, **SMALL)
    observations = {f"agent_{i}": np.zeros(18, np.float32) for i in range(3)}
    team = r"The team is 3 agents \(agent_0, agent_1, agent_2\) with observations of 18 each"
    # An agent that has left the episode has no observation: the others act, it is seen as zeros, as in training.
    present = {a: o + 1.0 for a, o in observations.items() if a != "agent_2"}
    actions = model.predict_agents(present)
    joint = np.concatenate([present["agent_0"], present["agent_1"], np.zeros(18, np.float32)])
    expected = model.agent_layout.agent_actions(model.predict(joint, deterministic=True)[0])
    assert list(actions) == ["agent_0", "agent_1"]
    for agent in actions:
        np.testing.assert_array_equal(actions[agent], expected[agent])
    with pytest.raises(ValueError, match=rf"^Observations of agents not in the team: \['agent_3'\] .*{team}"):
        model.predict_agents({**observations, "agent_3": np.zeros(18, np.float32)})
    with pytest.raises(ValueError, match=r"^No observation of \['agent_0', 'agent_1', 'agent_2'\]; .*still in the episode"):
        model.predict_agents({f"agent_{i}": np.zeros(30, np.float32) for i in range(3, 5)})
    with pytest.raises(ValueError, match=r"^agent_1's observation has 30 numbers \(shape \(30,\)\), but the team's agent_1"):
        model.predict_agents({**observations, "agent_1": np.zeros(30, np.float32)})


def test_predict_on_an_observation_of_another_team_size_names_the_team_first() -> None:
    """Issue 34: SB3 says only 'Unexpected observation shape (150,) ... (54,)'."""
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=3), seed=0, **SMALL)
    five, _ = make_simple_spread(n_agents=5).reset(seed=0)
    assert five.shape == (150,)
    team = (
        r"the model's team is 3 agents \(agent_0, agent_1, agent_2\) with observations of 18 each and actions of 5 "
        r"each, a joint observation of 54 numbers: an env of another team \(e\.g\. another number of agents\)\? Pass "
        r"this team's joint observation, shape \(54,\) or \(n_envs, 54\)"
    )
    with pytest.raises(ValueError, match=rf"^predict\(\) got an observation of 150 numbers \(shape \(150,\)\), but {team}"):
        model.predict(five)
    with pytest.raises(ValueError, match=rf"^predict\(\) got 2 observations of 150 numbers \(shape \(2, 150\)\), but {team}"):
        model.predict(np.stack([five, five]))
    with pytest.raises(ValueError, match=rf"^predict\(\) got 3 observations of 18 numbers \(shape \(3, 18\)\), but {team}"):
        model.predict(np.zeros((3, 18), np.float32))  # one row per agent: not the joint observation
    with pytest.raises(ValueError, match=rf"^predict\(\) got an observation of shape \(2, 3, 18\), but {team}"):
        model.predict(np.zeros((2, 3, 18), np.float32))
    with pytest.raises(TypeError, match=r"^predict\(\) got a dict of observations .* use model\.predict_agents"):
        model.predict({"agent_0": np.zeros(18, np.float32)})
    with pytest.raises(ValueError, match=r"^predict\(\) got an observation of 150 numbers"):
        model.policy.predict(five)  # the policy alone (e.g. MADDPGPolicy.load) says the same


def test_predict_takes_the_teams_joint_observations_in_any_float_dtype() -> None:
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=3), seed=0, **SMALL)
    observations = np.random.default_rng(0).normal(size=(4, 54))
    batch, _ = model.predict(observations.astype(np.float32))
    assert batch.shape == (4, 15)
    # float64, as np.zeros gives by default: the same actions (SB3's other policies cast it in preprocess_obs)
    np.testing.assert_array_equal(model.predict(observations)[0], batch)
    single, _ = model.predict(observations[0].astype(np.float32))
    np.testing.assert_array_equal(model.predict(observations[0])[0], single)


def test_structured_observations_are_refused_with_the_flattening_to_do() -> None:
    layout = AgentLayout(("a", "b"), (3, 3), (2, 2))
    with pytest.raises(ValueError, match=r"a's observation is a dict: pass it flattened .*gymnasium.spaces.flatten"):
        layout.joint_observation({"a": {"x": np.zeros(3)}, "b": np.zeros(3)})
