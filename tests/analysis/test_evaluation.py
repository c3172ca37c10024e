"""Tests of team evaluation (``evaluate_team``) and its training callback (``TeamEvalCallback``)."""

import csv
import inspect
import math
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from stable_baselines3.common.callbacks import CallbackList, EvalCallback
from stable_baselines3.common.logger import Logger, configure
from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise
from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import EVAL_KEYS, RADIUS_KEYS, SUCCESS_RADII, TeamEvalCallback, evaluate_team, radius_key
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.envs import make_simple_spread
from sb3_maddpg.envs.simple_spread import SIMPLE_SPREAD_TASK_METRICS
from sb3_maddpg.experiments import EXP1

TINY = dict(
    learning_starts=50, batch_size=32, buffer_size=2_000, train_freq=25, policy_kwargs=dict(net_arch=dict(pi=[8], qf=[8]))
)


EVEN_DISTANCES = [0.05, 0.12, 0.2]
ODD_DISTANCES = [0.18, 0.29, 0.31]


class ScriptedEnv(gym.Env):
    """
    A two-agent env with scripted episodes: episode e lasts ``lengths[e % len(lengths)]`` steps, gives
    reward e + 1 per step split 1:3 between the agents, and reports metrics that depend on the step
    (so that last-step and summed metrics differ from any other reading). It declares simple_spread's metrics, as
    simple_spread's envs do (``with_metrics=False``: declared, but its infos lack them).
    """

    observation_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
    action_space = spaces.Box(0.0, 1.0, (2,), np.float32)
    task_metrics = SIMPLE_SPREAD_TASK_METRICS

    def __init__(self, lengths: tuple[int, ...] = (3, 5), with_metrics: bool = True) -> None:
        self.lengths = lengths
        self.with_metrics = with_metrics
        self.episode = -1
        self.t = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.episode += 1
        self.t = 0
        return np.zeros(2, np.float32), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.t += 1
        length = self.lengths[self.episode % len(self.lengths)]
        reward = float(self.episode + 1)
        info: dict[str, Any] = {"agent_rewards": np.array([0.25 * reward, 0.75 * reward], np.float32)}
        if self.with_metrics:
            last = self.t == length
            info.update(
                success=float(last and self.episode % 2 == 0),  # success only at the last step of even episodes
                coverage=0.5 if last else 1.0,  # the last step's coverage differs from every other step's
                collisions=float(self.t),  # summed over the episode: 1 + 2 + ... + length
                min_dist_sum=float(10 * self.episode + self.t),
                # Every landmark covered at every step but the last, whose distances depend on the episode.
                landmark_distances=[0.0, 0.0, 0.0] if not last else EVEN_DISTANCES if self.episode % 2 == 0 else ODD_DISTANCES,
            )
        return np.zeros(2, np.float32), reward, False, self.t == length, info


class ConstantModel:
    """A 'model' whose ``predict`` returns the same action everywhere."""

    def __init__(self, action: np.ndarray) -> None:
        self.action = action

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = False) -> tuple:
        batch = np.asarray(observation).shape[0]
        return np.tile(self.action, (batch, 1)), None


def test_evaluate_team_reads_last_step_and_sums_collisions() -> None:
    env = ScriptedEnv(lengths=(3, 5))
    result = evaluate_team(ConstantModel(np.zeros(2, np.float32)), env, n_episodes=4)
    # Episodes 0..3 last 3, 5, 3, 5 steps and give rewards 1, 2, 3, 4 per step.
    returns = np.array([3 * 1, 5 * 2, 3 * 3, 5 * 4], dtype=float)
    assert result["n_episodes"] == 4
    assert result["success_rate"] == pytest.approx(0.5)  # episodes 0 and 2
    assert result["coverage"] == pytest.approx(0.5)  # the last step's value, not the mean over steps
    assert result["collisions"] == pytest.approx(np.mean([6, 15, 6, 15]))  # summed over each episode
    assert result["min_dist_sum"] == pytest.approx(np.mean([3, 15, 23, 35]))  # 10 * episode + last step
    assert result["return_mean"] == pytest.approx(returns.mean())
    assert result["return_std"] == pytest.approx(returns.std())
    assert result["episode_length"] == pytest.approx(4.0)
    assert result["agent_returns"] == pytest.approx([0.25 * returns.mean(), 0.75 * returns.mean()])


def test_evaluate_team_scores_success_and_coverage_at_each_radius() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # an env with every metric gets no warning
        result = evaluate_team(ConstantModel(np.zeros(2, np.float32)), ScriptedEnv(lengths=(3, 5)), n_episodes=4)
    # Last steps: even episodes [0.05, 0.12, 0.2], odd [0.18, 0.29, 0.31]; a landmark at exactly the radius is
    # not covered (mpe2 counts distance < radius).
    expected_coverage = {0.1: (1 / 3 + 0) / 2, 0.15: (2 / 3 + 0) / 2, 0.2: (2 / 3 + 1 / 3) / 2, 0.3: (1 + 2 / 3) / 2}
    expected_success = {0.1: 0.0, 0.15: 0.0, 0.2: 0.0, 0.3: 0.5}
    assert SUCCESS_RADII == (0.1, 0.15, 0.2, 0.3)
    for radius in SUCCESS_RADII:
        assert result[radius_key("coverage", radius)] == pytest.approx(expected_coverage[radius]), radius
        assert result[radius_key("success_rate", radius)] == pytest.approx(expected_success[radius]), radius
    assert radius_key("success_rate", 0.15) == "success_rate_r0.15"
    assert set(RADIUS_KEYS) <= set(EVAL_KEYS)


def test_evaluate_team_without_the_declared_metrics_gives_nan_and_says_how_to_give_them() -> None:
    metrics = r"\['success', 'coverage', 'collisions', 'min_dist_sum', 'landmark_distances'\]"
    with pytest.warns(
        UserWarning, match=rf"no values for the task metrics {metrics}, so they are nan: .*TaskMetric\("
    ) as caught:
        result = evaluate_team(ConstantModel(np.zeros(2, np.float32)), ScriptedEnv(with_metrics=False), n_episodes=2)
    assert {w.filename for w in caught if "task metrics" in str(w.message)} == {__file__}  # the caller's line
    for key in ("success_rate", "coverage", "collisions", "min_dist_sum", *RADIUS_KEYS):
        assert math.isnan(result[key])
    assert result["return_mean"] == pytest.approx((3 * 1 + 5 * 2) / 2)


def test_evaluate_team_spreads_episodes_over_vec_envs() -> None:
    vec_env = DummyVecEnv([lambda: ScriptedEnv(lengths=(2,)), lambda: ScriptedEnv(lengths=(7,))])
    result = evaluate_team(ConstantModel(np.zeros(2, np.float32)), vec_env, n_episodes=5)
    # Episodes spread evenly (2 + 3), so the short env does not fill the count alone.
    assert result["n_episodes"] == 5
    assert result["episode_length"] == pytest.approx((2 * 2 + 3 * 7) / 5)


def simple_spread_by_hand(action: np.ndarray, n_episodes: int, seed: int) -> dict[str, float]:
    """The metrics of a constant-action team, computed with a plain loop over the gymnasium env."""
    env = make_simple_spread(n_agents=3)
    success, coverage, collisions, min_dist = [], [], [], []
    env.reset(seed=seed)
    for episode in range(n_episodes):
        if episode > 0:
            env.reset()
        total_collisions, done = 0.0, False
        while not done:
            _, _, terminated, truncated, info = env.step(action)
            total_collisions += info["collisions"]
            done = terminated or truncated
        success.append(info["success"])
        coverage.append(info["coverage"])
        min_dist.append(info["min_dist_sum"])
        collisions.append(total_collisions)
    return {
        "success_rate": float(np.mean(success)),
        "coverage": float(np.mean(coverage)),
        "collisions": float(np.mean(collisions)),
        "min_dist_sum": float(np.mean(min_dist)),
    }


def test_evaluate_team_on_simple_spread_matches_a_hand_loop() -> None:
    rng = np.random.default_rng(0)
    action = rng.uniform(0, 1, size=15).astype(np.float32)
    result = evaluate_team(ConstantModel(action), make_simple_spread(n_agents=3), n_episodes=6, seed=123)
    expected = simple_spread_by_hand(action, n_episodes=6, seed=123)
    for key, value in expected.items():
        assert result[key] == pytest.approx(value), key
    assert set(EVAL_KEYS) <= set(result)
    assert len(result["agent_returns"]) == 3


def test_evaluate_team_seed_makes_evaluations_repeatable() -> None:
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=3), seed=0, **TINY)
    env = make_simple_spread(n_agents=3)
    first = evaluate_team(model, env, n_episodes=4, seed=7)
    second = evaluate_team(model, env, n_episodes=4, seed=7)
    other = evaluate_team(model, env, n_episodes=4, seed=8)
    assert first == second
    assert first["min_dist_sum"] != other["min_dist_sum"]
    with pytest.raises(ValueError, match="n_episodes"):
        evaluate_team(model, env, n_episodes=0)


def test_team_eval_callback_logs_beside_eval_callback(tmp_path: Any) -> None:
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=3), seed=1, **TINY)
    model.set_logger(configure(str(tmp_path), ["csv"]))
    curve_path = tmp_path / "curve.csv"
    team_eval = TeamEvalCallback(
        make_simple_spread(n_agents=3), eval_freq=100, n_eval_episodes=2, seed=5, log_path=str(curve_path), eval_at_start=True
    )
    sb3_eval = EvalCallback(make_simple_spread(n_agents=3), eval_freq=100, n_eval_episodes=2, warn=False)
    model.learn(300, callback=CallbackList([team_eval, sb3_eval]))

    assert [row["timesteps"] for row in team_eval.history] == [0, 100, 200, 300]
    with open(curve_path, newline="") as file:
        rows = list(csv.DictReader(file))
    assert [float(row["timesteps"]) for row in rows] == [0, 100, 200, 300]
    assert float(rows[-1]["min_dist_sum"]) == pytest.approx(team_eval.history[-1]["min_dist_sum"])
    with open(tmp_path / "progress.csv", newline="") as file:
        progress = list(csv.DictReader(file))
    columns = set(progress[0])
    assert {f"eval/{key}" for key in EVAL_KEYS} <= columns
    assert "eval/mean_reward" in columns  # SB3's EvalCallback still logs its own keys
    logged = [float(row["eval/min_dist_sum"]) for row in progress if row["eval/min_dist_sum"]]
    assert logged == pytest.approx([row["min_dist_sum"] for row in team_eval.history])
    with pytest.raises(ValueError, match="eval_freq"):
        TeamEvalCallback(make_simple_spread(n_agents=3), eval_freq=0)


class RecordingEnv(ScriptedEnv):
    """A ScriptedEnv that keeps every action it is given."""

    def __init__(self) -> None:
        super().__init__(lengths=(4,))
        self.actions: list[np.ndarray] = []

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.actions.append(np.array(action))
        return super().step(action)


def test_evaluate_team_explores_only_when_not_deterministic() -> None:
    model = ConstantModel(np.full(2, 0.5, np.float32))
    model.action_noise = OrnsteinUhlenbeckActionNoise(np.zeros(2), np.full(2, 0.2), dt=1.0)  # type: ignore[attr-defined]
    state_before = model.action_noise.noise_prev.copy()  # type: ignore[attr-defined]
    env = RecordingEnv()
    evaluate_team(model, env, n_episodes=3, deterministic=True)
    assert np.all(np.asarray(env.actions) == 0.5)

    env = RecordingEnv()
    model.action_noise = NormalActionNoise(np.zeros(2), np.full(2, 0.2))  # type: ignore[attr-defined]
    evaluate_team(model, env, n_episodes=400, deterministic=False)
    actions = np.asarray(env.actions)
    # Noise of std 0.2 in the [-1, 1] space is 0.1 in the env's [0, 1] units, clipped to the space.
    assert actions.std(axis=0) == pytest.approx([0.1, 0.1], rel=0.1)
    assert actions.mean(axis=0) == pytest.approx([0.5, 0.5], abs=0.01)
    assert actions.min() >= 0.0 and actions.max() <= 1.0

    # The model's own noise process is not advanced by an evaluation.
    model.action_noise = OrnsteinUhlenbeckActionNoise(np.zeros(2), np.full(2, 0.2), dt=1.0)  # type: ignore[attr-defined]
    model.action_noise.noise_prev = state_before  # type: ignore[attr-defined]
    evaluate_team(model, RecordingEnv(), n_episodes=2, deterministic=False)
    assert np.array_equal(model.action_noise.noise_prev, state_before)  # type: ignore[attr-defined]


def test_evaluate_team_deterministic_flag_changes_a_maddpg_teams_actions() -> None:
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=3), seed=0, noise_std=0.3, **TINY)
    env = make_simple_spread(n_agents=3)
    greedy = evaluate_team(model, env, n_episodes=4, seed=7, deterministic=True)
    assert evaluate_team(model, env, n_episodes=4, seed=7, deterministic=True) == greedy
    exploring = evaluate_team(model, env, n_episodes=4, seed=7, deterministic=False)
    assert exploring["return_mean"] != greedy["return_mean"]


def test_team_eval_callback_copies_vec_normalize_statistics() -> None:
    def make_env() -> gym.Env:
        return make_simple_spread(n_agents=2)

    train_env = VecNormalize(DummyVecEnv([make_env]), norm_reward=False)
    eval_env = VecNormalize(DummyVecEnv([make_env]), training=False, norm_reward=False)
    model = MADDPG("MlpPolicy", train_env, seed=0, **TINY)
    model.learn(100, callback=TeamEvalCallback(eval_env, eval_freq=50, n_eval_episodes=1))
    # The last evaluation ran at the last step, after which the training statistics did not change.
    assert eval_env.obs_rms.count == train_env.obs_rms.count > 100
    np.testing.assert_array_equal(eval_env.obs_rms.mean, train_env.obs_rms.mean)
    np.testing.assert_array_equal(eval_env.obs_rms.var, train_env.obs_rms.var)
    assert eval_env.obs_rms is not train_env.obs_rms  # a copy: evaluation cannot change training's statistics

    model = MADDPG("MlpPolicy", VecNormalize(DummyVecEnv([make_env]), norm_reward=False), seed=0, **TINY)
    with pytest.raises(ValueError, match="the training env is normalised by VecNormalize but the eval env is not"):
        model.learn(100, callback=TeamEvalCallback(make_env(), eval_freq=50, n_eval_episodes=1))


def test_evaluate_team_scores_declared_task_metrics() -> None:
    from sb3_maddpg.envs import MPE_TASK_METRICS, TaskMetric, make_mpe_env

    # On the scripted env: min_dist_sum scored at the last step, collisions summed, as declared.
    declared = (
        TaskMetric("min_dist_sum", "last", "lower", "team", "scripted"),
        TaskMetric("collisions", "sum", "lower", "team", "scripted"),
    )
    result = evaluate_team(
        ConstantModel(np.zeros(2, np.float32)), ScriptedEnv(lengths=(3, 5)), n_episodes=4, task_metrics=declared
    )
    assert result["min_dist_sum"] == pytest.approx(np.mean([3, 15, 23, 35]))
    assert result["collisions"] == pytest.approx(np.mean([6, 15, 6, 15]))
    # On simple_tag: catches per episode, and no warning about simple_spread's keys.
    env = make_mpe_env("simple_tag", max_cycles=10)
    model = ConstantModel(np.zeros(env.action_space.shape, np.float32))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tag = evaluate_team(model, env, n_episodes=2, task_metrics=MPE_TASK_METRICS["simple_tag"])
    assert tag["collisions"] >= 0.0 and not math.isnan(tag["collisions"])
    with pytest.warns(UserWarning, match=r"no values for the task metrics \['goal_distance'\]"):
        evaluate_team(model, env, n_episodes=1, task_metrics=MPE_TASK_METRICS["simple"])


def test_on_an_env_that_declares_no_metrics_only_returns_and_lengths_are_scored_without_a_warning() -> None:
    """Issue 46: a non-MPE env used to get eleven NaN simple_spread keys and a warning."""
    from sb3_maddpg.envs import PettingZooToGym
    from tests.envs.walkers import Walkers

    env = PettingZooToGym(Walkers(observe="noise", max_cycles=4))
    model = ConstantModel(np.zeros(env.action_space.shape, np.float32))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = evaluate_team(model, env, n_episodes=3, seed=0)
    assert set(result) == {"return_mean", "return_std", "episode_length", "agent_returns", "n_episodes"}
    assert result["episode_length"] == 4.0 and len(result["agent_returns"]) == 4


def test_an_env_of_your_own_declares_a_task_metric_and_gets_it_scored_as_declared() -> None:
    from sb3_maddpg.envs import PettingZooToGym, TaskMetric
    from tests.envs.walkers import Walkers

    steps = TaskMetric("spread", "sum", "higher", "team", "the agents' spread, summed over the episode")
    last = TaskMetric("spread_now", "last", "higher", "team", "the agents' spread at the last step")

    def spread(parallel_env: Any) -> dict[str, float]:
        return {"spread": float(parallel_env.positions().std()), "spread_now": float(parallel_env.positions().std())}

    walkers = Walkers(observe="noise", max_cycles=3)
    env = PettingZooToGym(walkers, metrics_fn=spread, task_metrics=[steps, last])
    model = ConstantModel(np.full(env.action_space.shape, 0.5, np.float32))
    seen: list[float] = []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = evaluate_team(model, env, n_episodes=1, seed=0)
    walkers.reset(seed=0)  # the same episode by hand: the spread after each of its 3 steps
    for _ in range(3):
        walkers.step({agent: np.full(2, 0.5, np.float32) for agent in walkers.possible_agents})
        seen.append(float(walkers.positions().std()))
    assert result["spread"] == pytest.approx(sum(seen)) and result["spread_now"] == pytest.approx(seen[-1])
    assert "success_rate" not in result and result["task_metrics"] == (steps, last)
    with pytest.raises(ValueError, match=r"task_metrics declares \['spread', 'spread_now'\], but no metrics_fn"):
        PettingZooToGym(Walkers(), task_metrics=[steps, last])


class ScriptedTeam(ConstantModel):
    """A ConstantModel as a callback sees a model: no VecNormalize, a logger that writes nowhere."""

    def __init__(self, action: np.ndarray | None = None) -> None:
        super().__init__(np.zeros(2, np.float32) if action is None else action)
        self.num_timesteps = 0
        self.logger = Logger(folder=None, output_formats=[])

    def get_vec_normalize_env(self) -> None:
        return None

    def get_env(self) -> None:
        return None


def test_the_callback_evaluates_the_papers_100_episodes_by_default() -> None:
    """The callback's default is evaluate_team's, the paper's 100 episodes (Experiment 1's evaluation)."""
    assert inspect.signature(TeamEvalCallback).parameters["n_eval_episodes"].default == 100
    assert inspect.signature(evaluate_team).parameters["n_episodes"].default == 100 == EXP1.eval_episodes
    callback = TeamEvalCallback(ScriptedEnv(lengths=(3, 5)), eval_freq=1)
    callback.init_callback(ScriptedTeam())  # type: ignore[arg-type]
    callback.on_step()
    # Episode e of the scripted env lasts 3 steps (e even) or 5 (e odd) with a reward of e + 1 per step.
    returns = [(e + 1) * (3 if e % 2 == 0 else 5) for e in range(100)]
    assert callback.history[-1]["return_mean"] == pytest.approx(np.mean(returns))
    assert callback.history[-1]["episode_length"] == 4.0


def test_the_callback_evaluates_without_exploration_by_default() -> None:
    """As evaluate_team by default: a model with exploration noise acts without it."""
    assert inspect.signature(TeamEvalCallback).parameters["deterministic"].default is True
    assert inspect.signature(evaluate_team).parameters["deterministic"].default is True
    team = ScriptedTeam(np.full(2, 0.5, np.float32))
    team.action_noise = NormalActionNoise(np.zeros(2), np.full(2, 0.2))  # type: ignore[attr-defined]
    env = RecordingEnv()
    callback = TeamEvalCallback(env, eval_freq=1, n_eval_episodes=3)
    callback.init_callback(team)  # type: ignore[arg-type]
    callback.on_step()
    assert len(env.actions) == 3 * 4 and np.all(np.asarray(env.actions) == 0.5)


@pytest.mark.parametrize("verbose", [0, 1])
def test_a_verbose_callback_prints_each_evaluation(verbose: int, capsys: pytest.CaptureFixture[str]) -> None:
    callback = TeamEvalCallback(ScriptedEnv(lengths=(3, 5)), eval_freq=1, n_eval_episodes=2, verbose=verbose)
    callback.init_callback(ScriptedTeam())  # type: ignore[arg-type]
    callback.on_step()
    printed = capsys.readouterr().out
    assert printed.startswith("Team eval num_timesteps=0: ") if verbose else printed == ""


class TwoSidedEnv(ScriptedEnv):
    """A ScriptedEnv whose two agents, ``a`` and ``b``, play on two sides."""

    agent_layout = AgentLayout(("a", "b"), (1, 1), (1, 1))


def test_each_side_scores_its_own_agents_returns_in_place_of_the_team_return() -> None:
    """With sides, each side's return (the mean of its agents' returns) stands where the team return's mean and std
    stood: the other scores keep their order."""
    result = evaluate_team(ConstantModel(np.zeros(2, np.float32)), TwoSidedEnv(), n_episodes=4, sides={"A": ["a"], "B": ["b"]})
    keys = list(EVAL_KEYS)
    at = keys.index("return_mean")
    keys[at : at + 2] = ["return_A", "return_B"]
    assert [key for key in result if key not in ("agent_returns", "n_episodes")] == keys
    # Episodes 0-3 return 3, 10, 9 and 20 (mean 10.5), split 1:3 between a and b.
    assert (result["return_A"], result["return_B"]) == pytest.approx((0.25 * 10.5, 0.75 * 10.5))
