"""SimpleSpreadVecEnv against mpe2 itself: step by step from mpe2's state, and whole seeded rollouts with auto-reset."""

from typing import Any

import numpy as np
import pytest
from mpe2 import simple_spread_v3
from mpe2._mpe_utils.core import World
from pettingzoo.utils.env_logger import EnvLogger
from stable_baselines3.common.callbacks import EvalCallback
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.logger import configure
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor, VecNormalize

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import TeamEvalCallback, evaluate_team
from sb3_maddpg.envs import SimpleSpreadVecEnv, make_simple_spread, make_simple_spread_vec_env
from sb3_maddpg.envs import simple_spread_worlds as worlds_module

TOLERANCE = 1e-5
"""The largest difference allowed from mpe2 (float32 observations of float64 worlds)."""

METRICS = ("coverage", "success", "collisions", "min_dist_sum", "landmark_distances")

TINY = dict(
    learning_starts=100, batch_size=32, buffer_size=2_000, train_freq=25, policy_kwargs=dict(net_arch=dict(pi=[8], qf=[8]))
)


def mpe2_vec_env(n_envs: int, **kwargs: Any) -> DummyVecEnv:
    """The reference: SB3's DummyVecEnv over the mpe2 adapter, with the same settings."""
    return DummyVecEnv([lambda: make_simple_spread(**kwargs) for _ in range(n_envs)])


def assert_same_step(ours: tuple, reference: tuple, context: str) -> None:
    """Observations, team rewards, dones and every info key the package reads agree within TOLERANCE."""
    obs, rewards, dones, infos = ours
    ref_obs, ref_rewards, ref_dones, ref_infos = reference
    np.testing.assert_allclose(obs, ref_obs, atol=TOLERANCE, rtol=0, err_msg=f"observations, {context}")
    np.testing.assert_allclose(rewards, ref_rewards, atol=TOLERANCE, rtol=0, err_msg=f"team rewards, {context}")
    np.testing.assert_array_equal(dones, ref_dones, err_msg=f"dones, {context}")
    for world, (info, ref_info) in enumerate(zip(infos, ref_infos)):
        where = f"{context}, world {world}"
        np.testing.assert_allclose(info["agent_rewards"], ref_info["agent_rewards"], atol=TOLERANCE, rtol=0, err_msg=where)
        assert info["agent_rewards"].dtype == ref_info["agent_rewards"].dtype == np.float32
        np.testing.assert_array_equal(info["agent_terminations"], ref_info["agent_terminations"], err_msg=where)
        np.testing.assert_array_equal(info["agent_truncations"], ref_info["agent_truncations"], err_msg=where)
        assert info["TimeLimit.truncated"] == ref_info["TimeLimit.truncated"], where
        for key in METRICS:
            assert info[key] == pytest.approx(ref_info[key], abs=TOLERANCE), f"{key}, {where}"
        assert ("terminal_observation" in info) == ("terminal_observation" in ref_info), where
        if "terminal_observation" in ref_info:
            np.testing.assert_allclose(
                info["terminal_observation"], ref_info["terminal_observation"], atol=TOLERANCE, rtol=0, err_msg=where
            )


def test_physics_constants_are_mpe2s() -> None:
    world = World()
    spread_world = simple_spread_v3.raw_env(N=2).world
    assert world.dt == worlds_module.DT
    assert world.damping == worlds_module.DAMPING
    assert world.contact_force == worlds_module.CONTACT_FORCE
    assert world.contact_margin == worlds_module.CONTACT_MARGIN
    assert spread_world.dim_c == worlds_module.DIM_C
    assert all(agent.size == worlds_module.AGENT_SIZE for agent in spread_world.agents)
    assert all(agent.accel is None and agent.max_speed is None and agent.u_noise is None for agent in spread_world.agents)


@pytest.mark.parametrize("num_agent_neighbors", [None, 2])
def test_spaces_and_layout_equal_the_adapters(num_agent_neighbors: int | None) -> None:
    ours = SimpleSpreadVecEnv(2, n_agents=4, num_agent_neighbors=num_agent_neighbors)
    reference = make_simple_spread(n_agents=4, num_agent_neighbors=num_agent_neighbors)
    assert ours.observation_space == reference.observation_space
    assert ours.action_space == reference.action_space
    assert ours.get_attr("agent_layout") == [reference.agent_layout] * 2


@pytest.mark.parametrize(
    ("n_agents", "num_agent_neighbors", "local_ratio", "max_cycles", "num_landmark_neighbors"),
    [
        (2, None, 0.5, 25, None),
        (3, None, 0.5, 25, None),
        (3, 1, 0.0, 25, None),
        (5, None, 0.5, 25, None),
        (5, 2, 1.0, 25, None),
        (8, 3, 0.3, 10, None),
        (4, None, 0.5, 25, 2),
        (5, 2, 0.5, 25, 5),
    ],
)
def test_seeded_rollouts_replay_mpe2(
    n_agents: int, num_agent_neighbors: int | None, local_ratio: float, max_cycles: int, num_landmark_neighbors: int | None
) -> None:
    """Several whole episodes with auto-reset from one seed, never re-synced: every step equals mpe2's."""
    n_envs, episodes = 3, 3
    kwargs = dict(
        n_agents=n_agents,
        num_agent_neighbors=num_agent_neighbors,
        local_ratio=local_ratio,
        max_cycles=max_cycles,
        num_landmark_neighbors=num_landmark_neighbors,
    )
    ours, reference = SimpleSpreadVecEnv(n_envs, **kwargs), mpe2_vec_env(n_envs, **kwargs)  # type: ignore[arg-type]
    ours.seed(100 + n_agents)
    reference.seed(100 + n_agents)
    np.testing.assert_allclose(ours.reset(), reference.reset(), atol=TOLERANCE, rtol=0)
    for world, (info, ref_info) in enumerate(zip(ours.reset_infos, reference.reset_infos)):
        for key in METRICS:
            assert info[key] == pytest.approx(ref_info[key], abs=TOLERANCE), f"reset {key}, world {world}"
    rng = np.random.default_rng(n_agents)
    done_steps = []
    for step in range(1, episodes * max_cycles + 1):
        actions = rng.uniform(0, 1, (n_envs, 5 * n_agents)).astype(np.float32)
        result = ours.step(actions)
        assert_same_step(result, reference.step(actions), f"step {step}")
        if result[2].any():
            done_steps.append(step)
    assert done_steps == [max_cycles * (episode + 1) for episode in range(episodes)]  # episodes last exactly max_cycles


def crowd(parallel_env: Any, rng: np.random.Generator) -> None:
    """Put every agent of an mpe2 world within 0.25 of the origin, moving: contacts on most steps."""
    for agent in parallel_env.unwrapped.world.agents:
        agent.state.p_pos = rng.uniform(-0.25, 0.25, 2)
        agent.state.p_vel = rng.uniform(-1, 1, 2)


def copy_state(parallel_envs: list[Any], ours: SimpleSpreadVecEnv) -> None:
    """mpe2's world state (positions, velocities, landmarks) into our worlds."""
    for index, parallel_env in enumerate(parallel_envs):
        world = parallel_env.unwrapped.world
        ours.worlds.agent_pos[index] = [agent.state.p_pos for agent in world.agents]
        ours.worlds.agent_vel[index] = [agent.state.p_vel for agent in world.agents]
        ours.worlds.landmark_pos[index] = [landmark.state.p_pos for landmark in world.landmarks]


@pytest.mark.slow
@pytest.mark.parametrize(("n_agents", "num_agent_neighbors"), [(3, None), (4, 2), (6, None), (6, 1)])
def test_each_step_from_mpe2s_state_matches(n_agents: int, num_agent_neighbors: int | None) -> None:
    """
    From mpe2's own state, copied in before every step, one step gives mpe2's next observation, rewards and
    metrics: over 60 episodes per setting, half of them starting crowded (agents in contact, moving).
    """
    n_envs, episodes, max_cycles = 6, 10, 25
    kwargs = dict(n_agents=n_agents, num_agent_neighbors=num_agent_neighbors, local_ratio=0.4)
    reference = mpe2_vec_env(n_envs, **kwargs)
    ours = SimpleSpreadVecEnv(n_envs, **kwargs)  # type: ignore[arg-type]
    parallel_envs = [env.parallel_env for env in reference.envs]  # type: ignore[attr-defined]
    rng = np.random.default_rng(n_agents)
    contacts = 0
    for episode in range(episodes):
        reference.seed(episode * n_envs)
        reference.reset()
        ours.reset()
        if episode % 2 == 0:
            for parallel_env in parallel_envs:
                crowd(parallel_env, rng)
        for step in range(max_cycles):
            copy_state(parallel_envs, ours)
            actions = rng.uniform(0, 1, (n_envs, 5 * n_agents)).astype(np.float32)
            result = ours.step(actions)
            ref_result = reference.step(actions)
            if step < max_cycles - 1:  # the last step resets both (unrelated generators): compare its terminal obs
                assert_same_step(result, ref_result, f"episode {episode}, step {step}")
                # The physics is mpe2's bit for bit, contacts included (so long rollouts cannot drift apart).
                for index, parallel_env in enumerate(parallel_envs):
                    world = parallel_env.unwrapped.world
                    np.testing.assert_array_equal(ours.worlds.agent_pos[index], [a.state.p_pos for a in world.agents])
                    np.testing.assert_array_equal(ours.worlds.agent_vel[index], [a.state.p_vel for a in world.agents])
            else:
                last = [info["terminal_observation"] for info in result[3]]
                np.testing.assert_allclose(last, [info["terminal_observation"] for info in ref_result[3]], atol=TOLERANCE)
            contacts += sum(info["collisions"] > 0 for info in ref_result[3])
    assert contacts > episodes * n_envs  # the crowded starts did force contacts (two steps per crowded episode on average)


def test_out_of_range_actions_are_clipped_as_mpe2_does() -> None:
    ours, reference = SimpleSpreadVecEnv(2, n_agents=3), mpe2_vec_env(2, n_agents=3)
    ours.seed(3)
    reference.seed(3)
    ours.reset()
    reference.reset()
    rng = np.random.default_rng(0)
    EnvLogger.suppress_output()  # mpe2 warns on every out-of-range action
    try:
        for step in range(30):
            actions = rng.uniform(-1.0, 2.0, (2, 15)).astype(np.float32)
            assert_same_step(ours.step(actions), reference.step(actions), f"step {step}")
    finally:
        EnvLogger.unsuppress_output()


def test_seeding_follows_sb3s_convention_and_unseeded_worlds_differ() -> None:
    env = SimpleSpreadVecEnv(3, n_agents=3)
    assert env.seed(10) == [10, 11, 12]
    first = env.reset()
    single = SimpleSpreadVecEnv(1, n_agents=3)
    single.seed(11)
    np.testing.assert_array_equal(single.reset()[0], first[1])  # world i after seed(s) is an env seeded s + i
    env.seed(10)
    np.testing.assert_array_equal(env.reset(), first)
    env.seed(None)
    assert not np.allclose(env.reset(), first)
    assert not np.allclose(env.reset()[0], env.reset()[1])


def test_rendering_draws_mpe2s_image_of_each_world() -> None:
    ours = SimpleSpreadVecEnv(2, n_agents=3, render_mode="rgb_array")
    reference = make_simple_spread(n_agents=3, render_mode="rgb_array")
    ours.seed(5)
    ours.reset()
    reference.reset(seed=6)
    image = ours.get_images()[1]
    assert image is not None and image.shape == (700, 700, 3)
    np.testing.assert_array_equal(image, reference.render())
    actions = np.full((2, 15), 0.7, np.float32)
    ours.step(actions)
    reference.step(actions[1])
    np.testing.assert_array_equal(ours.env_method("render", indices=[1])[0], reference.render())
    assert ours.render().shape == (2 * 700, 700, 3)  # SB3 tiles the two worlds
    ours.close()


def test_attributes_and_methods() -> None:
    env = SimpleSpreadVecEnv(2, n_agents=3)
    assert env.get_attr("n_agents") == [3, 3]
    assert env.get_attr("max_cycles", indices=1) == [25]
    with pytest.raises(AttributeError):
        env.get_attr("no_such_attribute")
    env.seed(0)
    env.reset()
    actions = np.full((2, 15), 0.5, np.float32)
    shared = env.step(actions)[3][0]["agent_rewards"]
    env.set_attr("local_ratio", 0.0)  # shared reward only: every agent gets the same
    env.seed(0)
    env.reset()
    rewards = env.step(actions)[3][0]["agent_rewards"]
    assert np.all(rewards == rewards[0]) and not np.allclose(rewards, shared)
    env.set_attr("capture_radius", 10.0)
    assert env.step(actions)[3][0]["coverage"] == 1.0
    with pytest.raises(ValueError, match="shared by all worlds"):
        env.set_attr("capture_radius", 0.2, indices=[0])
    with pytest.raises(AttributeError, match="can set only"):
        env.set_attr("n_agents", 4)
    with pytest.raises(ValueError, match="local_ratio"):
        env.set_attr("local_ratio", 1.5)
    with pytest.raises(AttributeError, match="no per-world method 'reset'"):
        env.env_method("reset")
    assert env.env_is_wrapped(VecMonitor) == [False, False]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(n_envs=0), r"^n_envs \(worlds stepped at once\) must be an integer >= 1, got 0: use"),
        (dict(n_agents=1), r"^n_agents \(.*\) must be an integer >= 2.*, got 1"),
        (
            dict(n_agents=3, num_agent_neighbors=3),
            r"^num_agent_neighbors \(.*\) must be an integer in \[1, n_agents - 1 = 2\].*, got 3",
        ),
        (
            dict(n_agents=3, num_landmark_neighbors=4),
            r"^num_landmark_neighbors \(.*\) must be an integer in \[1, n_agents = 3\].*, got 4",
        ),
        (dict(max_cycles=0), r"^max_cycles \(.*\) must be an integer >= 1.*, got 0"),
        (dict(local_ratio=-0.1), r"^local_ratio \(.*\) must be a number in \[0, 1\].*, got -0.1"),
        (dict(capture_radius=0.0), r"^capture_radius \(.*\) must be a number > 0.*, got 0.0"),
        (dict(render_mode="human"), "render_mode must be None or 'rgb_array'"),
        (dict(team_reward="max"), "team_reward must be 'sum' or 'mean'"),
    ],
)
def test_bad_settings_are_refused(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        SimpleSpreadVecEnv(**kwargs)


def test_bad_actions_are_refused() -> None:
    env = SimpleSpreadVecEnv(2, n_agents=3)
    with pytest.raises(RuntimeError, match=r"call reset\(\) before step\(\)"):
        env.step(np.zeros((2, 15), np.float32))
    env.reset()
    with pytest.raises(ValueError, match=r"Expected actions of shape \(2, 15\)"):
        env.step(np.zeros((2, 10), np.float32))
    actions = np.zeros((2, 15), np.float32)
    actions[1, 4] = np.nan
    with pytest.raises(ValueError, match=r"Actions of worlds \[1\] contain NaN"):
        env.step(actions)
    env.step(np.zeros((2, 3, 5), np.float32))  # per-agent shape is accepted


class FixedActions:
    """A 'model' that plays a fixed joint action (for evaluation equivalence)."""

    def __init__(self, action: np.ndarray) -> None:
        self.action = action

    def predict(
        self, observation: np.ndarray, state: Any = None, episode_start: Any = None, deterministic: bool = False
    ) -> tuple:
        return np.tile(self.action, (len(observation), 1)), None


def test_evaluate_team_gives_mpe2s_result() -> None:
    action = np.random.default_rng(1).uniform(0, 1, 15).astype(np.float32)
    ours = evaluate_team(FixedActions(action), SimpleSpreadVecEnv(4, n_agents=3), n_episodes=8, seed=21)
    reference = evaluate_team(FixedActions(action), mpe2_vec_env(4, n_agents=3), n_episodes=8, seed=21)
    for key in ("success_rate", "coverage", "collisions", "min_dist_sum", "return_mean", "return_std", "episode_length"):
        assert ours[key] == pytest.approx(reference[key], abs=1e-4), key
    np.testing.assert_allclose(ours["agent_returns"], reference["agent_returns"], atol=1e-4)


def test_maddpg_trains_under_sb3_wrappers_and_callbacks() -> None:
    """VecMonitor, VecNormalize(norm_reward=False), TeamEvalCallback, EvalCallback and evaluate_policy all run."""
    env = VecNormalize(VecMonitor(SimpleSpreadVecEnv(4, n_agents=3)), norm_reward=False)
    model = MADDPG("MlpPolicy", env, seed=0, **TINY)  # type: ignore[arg-type]
    eval_env = VecNormalize(VecMonitor(SimpleSpreadVecEnv(2, n_agents=3)), norm_reward=False, training=False)
    team_eval = TeamEvalCallback(eval_env, eval_freq=50, n_eval_episodes=2, seed=0)
    sb3_eval = EvalCallback(eval_env, eval_freq=50, n_eval_episodes=2, warn=False)
    model.learn(400, callback=[team_eval, sb3_eval])
    assert model.num_timesteps == 400 and model.replay_buffer.pos == 100
    assert len(team_eval.history) == 2 and np.isfinite(team_eval.history[-1]["return_mean"])
    assert sb3_eval.last_mean_reward < 0
    mean_reward, _ = evaluate_policy(model, eval_env, n_eval_episodes=2)
    assert mean_reward < 0
    # Per-agent rewards reached the buffer.
    rewards = model.replay_buffer.rewards[: model.replay_buffer.pos]
    assert rewards.shape[-1] == 3 and np.all(rewards < 0)
    # VecMonitor saw 16 episodes of exactly 25 steps.
    assert model.ep_info_buffer is not None and len(model.ep_info_buffer) == 400 // 25
    assert all(episode["l"] == 25 for episode in model.ep_info_buffer)


def test_training_on_it_equals_training_on_mpe2() -> None:
    """The same seed gives the same training on both paths: same episodes, same buffer, same networks."""
    models = []
    for env in (SimpleSpreadVecEnv(2, n_agents=3), mpe2_vec_env(2, n_agents=3)):
        model = MADDPG("MlpPolicy", env, seed=4, **TINY)  # type: ignore[arg-type]
        model.learn(300)
        models.append(model)
    ours, reference = models
    rows = reference.replay_buffer.pos
    assert rows == ours.replay_buffer.pos == 150
    for name in ("observations", "next_observations", "actions", "rewards", "timeouts"):
        np.testing.assert_allclose(
            getattr(ours.replay_buffer, name)[:rows], getattr(reference.replay_buffer, name)[:rows], atol=1e-4, err_msg=name
        )
    for param, ref_param in zip(ours.policy.parameters(), reference.policy.parameters()):
        np.testing.assert_allclose(param.detach().numpy(), ref_param.detach().numpy(), atol=1e-4)


def test_many_worlds_write_the_logs_once_per_step(tmp_path: Any) -> None:
    """100 worlds end 100 episodes in one step; SB3 would dump its logs at every 4th of them."""
    model = MADDPG("MlpPolicy", VecMonitor(SimpleSpreadVecEnv(100, n_agents=3)), seed=0, **TINY)  # type: ignore[arg-type]
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(5_000, log_interval=4)  # 50 steps of 100 worlds: two rounds of episodes end
    assert len((tmp_path / "progress.csv").read_text().strip().splitlines()[1:]) == 2
    model.learn(2_500, log_interval=4)  # counting restarts: its only log, at step 2,500, is new (the last one was at 5,000)
    model.learn(2_500, log_interval=4)  # and so is this one, at step 2,500 again
    assert len((tmp_path / "progress.csv").read_text().strip().splitlines()[1:]) == 4


def test_one_factory_for_both_paths() -> None:
    batched = make_simple_spread_vec_env(3, n_agents=4, num_agent_neighbors=2)
    reference = make_simple_spread_vec_env(3, "mpe2", n_agents=4, num_agent_neighbors=2)
    assert isinstance(batched, SimpleSpreadVecEnv) and isinstance(reference, DummyVecEnv)
    assert batched.num_envs == reference.num_envs == 3
    assert batched.get_attr("agent_layout") == reference.get_attr("agent_layout")
    batched.seed(1)
    reference.seed(1)
    np.testing.assert_allclose(batched.reset(), reference.reset(), atol=TOLERANCE)
    with pytest.raises(ValueError, match="vec_env must be 'batched' or 'mpe2'"):
        make_simple_spread_vec_env(1, "jax")  # type: ignore[arg-type]
