"""Save and load in SB3's style, for every sharing scheme: parameters, optimisers, replay buffer, selectors."""

import re

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.noise import VectorizedActionNoise
from stable_baselines3.common.save_util import save_to_pkl

from sb3_maddpg import MADDPG, AgentLayout
from sb3_maddpg.common.selection import CallableSelector, FixedGraph, NearestAgents
from sb3_maddpg.maddpg.policies import MADDPGPolicy
from tests.settings import N_AGENTS, RESUMES_WITHOUT_ITS_BUFFER, SELECTS_EVERY_OTHER_AGENT, TRAINS_QUICKLY, make_team

pytestmark = [RESUMES_WITHOUT_ITS_BUFFER]  # a side effect of the tests' short setups (tests/settings.py)

SCHEMES = ("independent", "full", "observations", "actions", "selected")


def reverse_ring(observations: np.ndarray, layout: AgentLayout) -> np.ndarray:
    """Agent i selects agent i - 1 (module level, so that save/load can pickle it by reference)."""
    n = layout.n_agents
    return np.broadcast_to((np.arange(n)[:, None] - 1) % n, (observations.shape[0], n, 1))


def assert_state_dicts_equal(expected, actual, path: str = "") -> None:
    """Recursive equality of (optimiser) state dicts holding tensors, numbers, lists and dicts."""
    if isinstance(expected, dict):
        assert isinstance(actual, dict) and set(expected) == set(actual), path
        for key in expected:
            assert_state_dicts_equal(expected[key], actual[key], f"{path}/{key}")
    elif isinstance(expected, list | tuple):
        assert len(expected) == len(actual), path
        for index, (a, b) in enumerate(zip(expected, actual)):
            assert_state_dicts_equal(a, b, f"{path}/{index}")
    elif isinstance(expected, th.Tensor):
        assert th.equal(expected.cpu(), actual.cpu()), path
    else:
        assert expected == actual, path


def joint_batch(model: MADDPG, n: int = 16) -> tuple[np.ndarray, th.Tensor, th.Tensor, th.Tensor | None]:
    """Observations seen by the model, random [-1, 1] actions, and the selection made from the observations."""
    buffer = model.replay_buffer
    obs = buffer.observations[:n, 0]
    rng = np.random.default_rng(1)
    actions = th.as_tensor(rng.uniform(-1, 1, size=(n, model.agent_layout.action_dim)), dtype=th.float32)
    selection = None
    if model.selector is not None:
        selection = th.as_tensor(model.selector.select(obs, model.agent_layout))
    return obs, th.as_tensor(obs), actions, selection


def assert_same_model(model: MADDPG, loaded: MADDPG, obs: np.ndarray, obs_t, actions_t, selection) -> None:
    np.testing.assert_array_equal(model.predict(obs, deterministic=True)[0], loaded.predict(obs, deterministic=True)[0])
    with th.no_grad():
        q_model = model.policy.q_values(obs_t, actions_t, selection)
        q_loaded = loaded.policy.q_values(obs_t, actions_t, selection)
    assert q_model.shape == (len(obs), N_AGENTS)
    assert th.equal(q_model, q_loaded)
    assert_state_dicts_equal(model.policy.state_dict(), loaded.policy.state_dict())  # targets included
    assert_state_dicts_equal(model.actor.optimizer.state_dict(), loaded.actor.optimizer.state_dict())
    assert_state_dicts_equal(model.critic.optimizer.state_dict(), loaded.critic.optimizer.state_dict())
    assert loaded.agent_layout == model.agent_layout
    assert loaded.critic_sharing == model.critic_sharing
    assert type(loaded.critic.extractors[0]) is type(model.critic.extractors[0])
    assert loaded.num_timesteps == model.num_timesteps and loaded._n_updates == model._n_updates


@SELECTS_EVERY_OTHER_AGENT
@pytest.mark.parametrize("scheme", SCHEMES)
def test_save_load(tmp_path, scheme):
    model = MADDPG("MlpPolicy", make_vec_env(make_team, n_envs=2), critic_sharing=scheme, **TRAINS_QUICKLY)
    model.learn(total_timesteps=200)
    assert model._n_updates > 0
    # Optimisers that have stepped hold state (Adam moments): the comparison below is not vacuous.
    assert model.actor.optimizer.state_dict()["state"] and model.critic.optimizer.state_dict()["state"]
    batch = joint_batch(model)
    path = tmp_path / "model.zip"
    model.save(path)

    loaded = MADDPG.load(path)  # env=None: the layout comes from the file
    assert loaded.get_env() is None
    assert_same_model(model, loaded, *batch)

    loaded_with_env = MADDPG.load(path, env=make_vec_env(make_team, n_envs=2))
    assert_same_model(model, loaded_with_env, *batch)
    # Training goes on from where it stopped.
    loaded_with_env.learn(total_timesteps=100, reset_num_timesteps=False)
    assert loaded_with_env.num_timesteps == 300
    assert loaded_with_env._n_updates > model._n_updates


@SELECTS_EVERY_OTHER_AGENT
@pytest.mark.parametrize("scheme", SCHEMES)
def test_replay_buffer_round_trip(tmp_path, scheme):
    model = MADDPG("MlpPolicy", make_vec_env(make_team, n_envs=2), critic_sharing=scheme, **TRAINS_QUICKLY)
    model.learn(total_timesteps=150)
    path = tmp_path / "buffer.pkl"
    model.save_replay_buffer(path)

    other = MADDPG("MlpPolicy", make_vec_env(make_team, n_envs=2), critic_sharing=scheme, **TRAINS_QUICKLY)
    other.load_replay_buffer(path)
    saved, loaded = model.replay_buffer, other.replay_buffer
    assert loaded.pos == saved.pos > 0 and loaded.full == saved.full
    for name in ("observations", "next_observations", "actions", "rewards", "dones", "timeouts", "selections"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(saved, name), err_msg=name)
    assert loaded.rewards.shape == (TRAINS_QUICKLY["buffer_size"] // 2, 2, N_AGENTS)
    assert np.any(loaded.rewards != 0)
    if scheme == "selected":
        assert loaded.selections.shape[-1] == 2 and np.any(loaded.selections[: loaded.pos] != 0)
    assert loaded.layout == saved.layout
    # Learning goes on with the loaded buffer.
    other.learn(total_timesteps=60)
    assert other._n_updates > 0


def test_replay_buffer_of_another_team_is_refused(tmp_path):
    model = MADDPG("MlpPolicy", make_team(n_agents=4), critic_sharing="selected", selector=2, **TRAINS_QUICKLY)
    model.learn(total_timesteps=60)
    model.save_replay_buffer(tmp_path / "buffer.pkl")
    layout = model.agent_layout

    other_team = MADDPG("MlpPolicy", make_team(n_agents=5), critic_sharing="selected", selector=2, **TRAINS_QUICKLY)
    own_buffer = other_team.replay_buffer
    with pytest.raises(ValueError, match="agent layout") as error:
        other_team.load_replay_buffer(tmp_path / "buffer.pkl")
    assert str(layout) in str(error.value) and str(other_team.agent_layout) in str(error.value)
    assert other_team.replay_buffer is own_buffer  # the refused buffer is not kept

    other_k = MADDPG("MlpPolicy", make_team(n_agents=4), critic_sharing="selected", selector=1, **TRAINS_QUICKLY)
    expected = re.escape(f"{layout} with selections of k=2") + ".*" + re.escape(f"{layout} with k=1")
    with pytest.raises(ValueError, match=expected):
        other_k.load_replay_buffer(tmp_path / "buffer.pkl")
    without_selection = MADDPG("MlpPolicy", make_team(n_agents=4), critic_sharing="full", **TRAINS_QUICKLY)
    with pytest.raises(ValueError, match="k=2.*k=0"):
        without_selection.load_replay_buffer(tmp_path / "buffer.pkl")
    env = make_vec_env(make_team, n_envs=2, env_kwargs=dict(n_agents=4))
    two_envs = MADDPG("MlpPolicy", env, critic_sharing="selected", selector=2, **TRAINS_QUICKLY)
    with pytest.raises(ValueError, match=r"from 1 env\(s\).*and 2 env\(s\)"):
        two_envs.load_replay_buffer(tmp_path / "buffer.pkl")

    save_to_pkl(tmp_path / "plain.pkl", ReplayBuffer(10, model.observation_space, model.action_space))
    with pytest.raises(TypeError, match="is a ReplayBuffer, not a MultiAgentReplayBuffer"):
        other_team.load_replay_buffer(tmp_path / "plain.pkl")

    # The same team loads it, and stores new rows with its own selector.
    same = MADDPG("MlpPolicy", make_team(n_agents=4), critic_sharing="selected", selector=NearestAgents(k=2), **TRAINS_QUICKLY)
    same.load_replay_buffer(tmp_path / "buffer.pkl")
    assert same.replay_buffer.pos == 60 and same.replay_buffer.selector is same.selector


def test_callable_selector_survives_save_load(tmp_path):
    selector = CallableSelector(reverse_ring, k=1)
    model = MADDPG("MlpPolicy", make_team(), critic_sharing="selected", selector=selector, **TRAINS_QUICKLY)
    model.learn(total_timesteps=100)
    model.save(tmp_path / "model.zip")
    loaded = MADDPG.load(tmp_path / "model.zip", env=make_team())
    assert isinstance(loaded.selector, CallableSelector)
    assert loaded.selector.fn is reverse_ring and loaded.selector.k == 1
    assert loaded.replay_buffer.selector is loaded.selector
    loaded.learn(total_timesteps=100, reset_num_timesteps=False)
    stored = loaded.replay_buffer.selections[: loaded.replay_buffer.pos, 0]
    np.testing.assert_array_equal(stored, np.broadcast_to([[2], [0], [1]], stored.shape))


@pytest.mark.parametrize("n_envs", [4, 1])
def test_load_with_another_number_of_envs_rebuilds_the_noise(tmp_path, n_envs):
    """The default noise was vectorised for the 2 envs it was saved with: learn() fits it to the new env."""
    model = MADDPG("MlpPolicy", make_vec_env(make_team, n_envs=2), **TRAINS_QUICKLY)
    model.learn(total_timesteps=100)
    assert isinstance(model.action_noise, VectorizedActionNoise) and model.action_noise.n_envs == 2
    model.save(tmp_path / "model.zip")

    loaded = MADDPG.load(tmp_path / "model.zip", env=make_vec_env(make_team, n_envs=n_envs))
    loaded.learn(total_timesteps=100, reset_num_timesteps=False)
    assert loaded.num_timesteps >= 200 and loaded._n_updates > model._n_updates
    noise = loaded.action_noise
    base = noise.base_noise if n_envs > 1 else noise
    if n_envs > 1:
        assert isinstance(noise, VectorizedActionNoise) and noise.n_envs == n_envs
    np.testing.assert_allclose(base._sigma, np.full(N_AGENTS * 5, 0.2))  # noise_std=0.1 of mpe2's [0, 1] actions


def test_load_with_other_layout(tmp_path):
    model = MADDPG("MlpPolicy", make_team(), **TRAINS_QUICKLY)
    model.save(tmp_path / "model.zip")
    # Said before SB3's space check, whose message names neither the agents nor what to do.
    with pytest.raises(ValueError, match=r"team differs from the model's \(the model has 3 agents, the env 4\)"):
        MADDPG.load(tmp_path / "model.zip", env=make_team(n_agents=4))
    loaded = MADDPG.load(tmp_path / "model.zip")
    with pytest.raises(ValueError, match=r"team differs from the model's \(the model has 3 agents, the env 4\)"):
        loaded.set_env(make_team(n_agents=4))


def test_load_with_same_spaces_other_layout(tmp_path):
    model = MADDPG("MlpPolicy", make_team(), **TRAINS_QUICKLY)
    model.save(tmp_path / "model.zip")
    other = make_team()
    layout = other.agent_layout
    other.agent_layout = AgentLayout(("a", "b", "c"), layout.obs_sizes, layout.action_sizes)
    with pytest.raises(ValueError, match=r"team differs from the model's \(other agent ids\)"):
        MADDPG.load(tmp_path / "model.zip", env=other)


def test_building_without_setting_up_keeps_what_the_caller_passed() -> None:
    # SB3's load builds the model this way and sets the saved attributes over it: the constructor replaces nothing.
    kwargs = {name: value for name, value in TRAINS_QUICKLY.items() if name != "train_freq"}
    model = MADDPG("MlpPolicy", make_team(), actor_reg_coef=1e-3, transitions_per_update=50, _init_setup_model=False, **kwargs)
    assert model.actor_reg_coef == 1e-3
    assert model.update_rule.earns_gradient_steps and model.update_rule.transitions_per_update == 50


def test_a_save_holds_the_version_that_wrote_it_and_a_newer_one_is_refused(tmp_path, monkeypatch) -> None:
    from sb3_maddpg import __version__
    from sb3_maddpg.compat import VERSION_KEY, read_saved_data

    model = MADDPG("MlpPolicy", make_team(), **TRAINS_QUICKLY)
    model.save(tmp_path / "model.zip")
    data = read_saved_data(tmp_path / "model.zip")
    assert data is not None and data[VERSION_KEY] == __version__
    assert VERSION_KEY not in model.__dict__  # written into the save, not kept on the model
    loaded = MADDPG.load(tmp_path / "model.zip")
    assert VERSION_KEY not in loaded.__dict__ and loaded.actor_reg_coef == model.actor_reg_coef
    assert loaded.update_rule == model.update_rule
    loaded.save(tmp_path / "again.zip")  # the next save writes the version that made it
    again = read_saved_data(tmp_path / "again.zip")
    assert again is not None and again[VERSION_KEY] == __version__
    # A save of a newer version is refused, saying to upgrade, with an env or without.
    monkeypatch.setattr("sb3_maddpg.common.team_algorithm.__version__", "99.0.0")
    model.save(tmp_path / "newer.zip")
    with pytest.raises(ValueError, match=r"written by sb3-maddpg 99\.0\.0, newer than the installed .*: upgrade"):
        MADDPG.load(tmp_path / "newer.zip")
    with pytest.raises(ValueError, match=r"written by sb3-maddpg 99\.0\.0, newer than the installed .*: upgrade"):
        MADDPG.load(tmp_path / "newer.zip", env=make_team())


def test_a_selector_passed_to_load_wins_over_the_saved_one(tmp_path) -> None:
    model = MADDPG("MlpPolicy", make_team(), critic_sharing="selected", selector=1, **TRAINS_QUICKLY)
    model.save(tmp_path / "model.zip")
    graph = FixedGraph([[2], [0], [1]])
    chosen = MADDPG.load(tmp_path / "model.zip", env=make_team(), selector=graph)
    assert chosen.selector is graph and chosen.replay_buffer.selector is graph and chosen.selection_size == 1


@pytest.mark.parametrize("scheme", ["full", "selected"])
def test_policy_save_load_round_trip(tmp_path, scheme):
    """policy.save() / MADDPGPolicy.load(): SB3's policy-only round trip (no lr_schedule in the file, as TD3's)."""
    kwargs = dict(TRAINS_QUICKLY, selector=1) if scheme == "selected" else TRAINS_QUICKLY
    model = MADDPG("MlpPolicy", make_team(), critic_sharing=scheme, **kwargs)
    model.learn(total_timesteps=100)
    obs, obs_t, actions_t, selection = joint_batch(model)
    path = tmp_path / "policy.pt"
    model.policy.save(str(path))

    policy = MADDPGPolicy.load(str(path))
    assert type(policy) is type(model.policy) and policy.agent_layout == model.agent_layout
    np.testing.assert_array_equal(policy.predict(obs, deterministic=True)[0], model.predict(obs, deterministic=True)[0])
    with th.no_grad():
        assert th.equal(policy.q_values(obs_t, actions_t, selection), model.policy.q_values(obs_t, actions_t, selection))
    assert_state_dicts_equal(model.policy.state_dict(), policy.state_dict())  # targets included
