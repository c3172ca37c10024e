"""The task a run trains on, derived once from its config (:func:`run_task`, :class:`RunTask`): its envs
(simple_spread batched or on mpe2, another MPE task, a PettingZoo factory or a gymnasium id, as VecEnvs), the metrics
it is scored by and their directions, its sides, its evaluation schedule and its description."""

import dataclasses
import functools
import json
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import gymnasium as gym
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecMonitor, VecNormalize

from sb3_maddpg.analysis.evaluation import (
    SIDE_RETURN_PREFIX,
    DeclaredMetric,
    declared_task_metrics,
    eval_keys,
    evaluate_team,
    side_return_label,
)
from sb3_maddpg.envs.task_by_name import task_env_factory
from sb3_maddpg.experiments.defaults import DEFAULT_ENV, EPISODE_LENGTH
from sb3_maddpg.experiments.metrics import METRICS, Metric

if TYPE_CHECKING:
    from sb3_maddpg.experiments.setting import RunConfig


def declared_metrics(env: str, env_kwargs: Mapping[str, Any] | None = None) -> tuple[DeclaredMetric, ...]:
    """
    The one place the experiments read a task's metrics: those its env declares (its ``task_metrics``, see
    :class:`~sb3_maddpg.envs.TaskMetric`), so that any task's own metrics are scored and reported.

    :param env: A task (an experiment's ``env``).
    :param env_kwargs: Its constructor's keyword arguments.
    :return: simple_spread's (what :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` declares, read without building
        it); for any other task, what one env of it declares, built once per task and keyword arguments in a process:
        an MPE task's (:data:`~sb3_maddpg.envs.MPE_TASK_METRICS`), a factory's env's own (e.g.
        :func:`~sb3_maddpg.envs.sisl.pursuit_env`'s evaders caught), none for an env that declares none (its
        evaluations score its returns and episode length).
    """
    if env == DEFAULT_ENV:
        from sb3_maddpg.envs.simple_spread import SIMPLE_SPREAD_TASK_METRICS

        return tuple(SIMPLE_SPREAD_TASK_METRICS)
    return _env_declared_metrics(env, json.dumps(dict(env_kwargs or {}), sort_keys=True, default=repr))


@functools.lru_cache(maxsize=64)
def _env_declared_metrics(env: str, kwargs_json: str) -> tuple[DeclaredMetric, ...]:
    """:return: What one env of ``env`` built with the keyword arguments ``kwargs_json`` declares (cached: one build)."""
    built = task_env_factory(env, json.loads(kwargs_json), EPISODE_LENGTH)()
    try:
        return declared_task_metrics(built)
    finally:
        built.close()


def metric_record(metric: DeclaredMetric) -> dict[str, str]:
    """
    :param metric: A declared task metric.
    :return: It as JSON values (a run's summary records its task's, :func:`recorded_metrics` reads them back).
    """
    fields = ("key", "per_episode", "better", "team", "description")
    return {name: str(getattr(metric, name)) for name in fields if getattr(metric, name, None) is not None}


def recorded_metrics(records: Sequence[Mapping[str, str]] | None) -> tuple[DeclaredMetric, ...] | None:
    """
    :param records: The task metrics a run's summary records (its ``task_metrics``, :func:`metric_record`'s), or
        ``None`` for a summary that records none (written before summaries recorded them).
    :return: The metrics, or ``None`` when none are recorded.
    """
    if records is None:
        return None
    from sb3_maddpg.envs.task_metric import TaskMetric

    return tuple(
        TaskMetric(
            key=record["key"],
            per_episode=record.get("per_episode", "last"),  # type: ignore[arg-type]  # as the env declared it
            better=record.get("better", "higher"),  # type: ignore[arg-type]
            team=record.get("team", "team"),  # type: ignore[arg-type]
            description=record.get("description", ""),
        )
        for record in records
    )


def named_metrics(env: str) -> tuple[DeclaredMetric, ...]:
    """
    :param env: A task's name.
    :return: The metrics an MPE task of that name declares (:data:`~sb3_maddpg.envs.MPE_TASK_METRICS`), none for
        another task: how results whose summaries record no metrics are read, without building an env.
    """
    from sb3_maddpg.envs import MPE_TASK_METRICS

    return tuple(MPE_TASK_METRICS.get(env, ()))


def declared_sides(env: str) -> dict[str, tuple[str, ...]]:
    """
    :param env: A task (an experiment's ``env``).
    :return: The sides of a competitive MPE task (:data:`~sb3_maddpg.envs.MPE_TASK_SIDES`); empty for any other.
    """
    from sb3_maddpg.envs import MPE_TASK_SIDES

    return {side: tuple(agents) for side, agents in MPE_TASK_SIDES.get(env, {}).items()}


@dataclasses.dataclass(frozen=True)
class RunTask:
    """
    A run's task, derived once from its config (read it as ``run_task(config)``): everything about the task that a run's
    training, evaluation and progress lines need, so that no module derives it again from the env's name.

    :param config: The run.
    :param metrics: The task metrics its evaluations score: those its env declares (:func:`declared_metrics`).
    :param sides: The sides its evaluations score each return of (:data:`~sb3_maddpg.envs.MPE_TASK_SIDES`, for a
        competitive MPE task), so that no return adds opponents' rewards; empty for a cooperative task or any other.
    :param keys: The scores each evaluation gives (:func:`~sb3_maddpg.analysis.evaluation.eval_keys`), in order.
    :param higher_is_better: Each score's direction in this task (:func:`metric_info`).
    :param checkpoint_steps: The env steps at which checkpoints are saved.
    :param curve_interval: The env steps between learning-curve evaluations (0: no curve).
    :param eval_seed: The seed of every evaluation.
    :param scores_behaviour: Whether the last checkpoint's behaviour is scored
        (:func:`~sb3_maddpg.analysis.behaviour.team_behaviour`: simple_spread with every landmark observed).
    :param description: The task in a few words, for progress lines.
    """

    config: "RunConfig"
    metrics: tuple[DeclaredMetric, ...]
    sides: dict[str, tuple[str, ...]]
    keys: tuple[str, ...]
    higher_is_better: dict[str, bool]
    checkpoint_steps: tuple[int, ...]
    curve_interval: int
    eval_seed: int
    scores_behaviour: bool
    description: str

    @classmethod
    def of(cls, config: "RunConfig") -> "RunTask":
        """
        :param config: A run.
        :return: Its task, derived now (:func:`run_task` derives it once per config and keeps it).
        """
        simple_spread = config.env == DEFAULT_ENV
        metrics = declared_metrics(config.env, config.env_kwargs)
        sides = declared_sides(config.env)
        keys = eval_keys(metrics, config.score_agents, tuple(sides))
        landmarks_seen = config.env_kwargs.get("num_landmark_neighbors")
        return cls(
            config=config,
            metrics=metrics,
            sides=sides,
            keys=keys,
            higher_is_better={key: metric_info(key, config.env, metrics).higher_is_better for key in keys},
            checkpoint_steps=tuple(config.checkpoint_steps()),
            curve_interval=config.curve_interval,
            eval_seed=config.eval_seed,
            scores_behaviour=simple_spread and (landmarks_seen is None or landmarks_seen >= config.n_agents),
            description=_describe(config),
        )

    def env_factory(self) -> Callable[[], gym.Env]:
        """
        :return: A function that builds one env of a task other than simple_spread
            (:func:`~sb3_maddpg.envs.task_by_name.task_env_factory`).
        """
        return task_env_factory(self.config.env, self.config.env_kwargs, self.config.episode_length)

    def make_env(self, n_envs: int | None = None) -> VecEnv:
        """
        :param n_envs: Envs stepped together (default: the run's ``n_envs``).
        :return: The task as a new VecEnv: simple_spread as the config's ``vec_env`` says, any other in a ``DummyVecEnv``.
        """
        config = self.config
        n_envs = config.n_envs if n_envs is None else n_envs
        if config.env != DEFAULT_ENV:
            return DummyVecEnv([self.env_factory()] * n_envs)
        from sb3_maddpg.envs import make_simple_spread_vec_env

        return make_simple_spread_vec_env(
            n_envs,
            config.vec_env,  # type: ignore[arg-type]  # the config checks it
            n_agents=config.n_agents,
            num_agent_neighbors=config.num_agent_neighbors,
            max_cycles=config.episode_length,
            **config.env_kwargs,  # e.g. continuous_actions=False
        )

    def evaluate(self, policy: Any, eval_env: VecEnv) -> dict[str, Any]:
        """
        Evaluate a policy as the run's checkpoints are evaluated: ``eval_episodes`` episodes from the run's evaluation
        seed, scored by the task's metrics, sides and scored agents.

        :param policy: A model, a checkpoint or a reference policy (anything with ``predict``).
        :param eval_env: An evaluation env of the task (:meth:`make_eval_env`).
        :return: :func:`~sb3_maddpg.analysis.evaluation.evaluate_team`'s result (:attr:`keys` among its scores).
        """
        config = self.config
        return evaluate_team(
            policy,
            eval_env,
            n_episodes=config.eval_episodes,
            seed=self.eval_seed,
            task_metrics=self.metrics,
            score_agents=config.score_agents,
            sides=self.sides,
        )

    def make_train_env(self) -> VecEnv:
        """
        :return: The run's training env: the task, monitored, and with ``normalize_observations`` in a ``VecNormalize``
            that normalises observations only (the critics learn from the raw per-agent rewards).
        """
        env: VecEnv = VecMonitor(self.make_env())
        if self.config.normalize_observations:
            env = VecNormalize(env, norm_obs=True, norm_reward=False)
        return env

    def make_eval_env(self, n_episodes: int) -> VecEnv:
        """
        :param n_episodes: Episodes per evaluation.
        :return: An evaluation env: on the batched env, one world per episode, so an evaluation takes one episode's
            steps; with ``normalize_observations``, in a ``VecNormalize`` that does not update its statistics (they
            are the training env's, copied at each evaluation, or a checkpoint's:
            :func:`~sb3_maddpg.experiments.runner.load_observation_statistics`).
        """
        batched = self.config.env == DEFAULT_ENV and self.config.vec_env == "batched"
        env = self.make_env(n_episodes if batched else 1)
        if self.config.normalize_observations:
            env = VecNormalize(env, training=False, norm_obs=True, norm_reward=False)
        return env


TASK_ATTRIBUTE = "_task"
"""Where :func:`run_task` keeps a config's task: beside its fields, not one of them (not compared, stored or sent)."""


def run_task(config: "RunConfig") -> RunTask:
    """
    :param config: A run.
    :return: Its task, derived on the first call and kept on the config, so that a run derives it once: the config is
        frozen, so its task cannot go stale.
    """
    task = config.__dict__.get(TASK_ATTRIBUTE)
    if task is None:
        task = RunTask.of(config)
        config.__dict__[TASK_ATTRIBUTE] = task  # not through setattr: the dataclass is frozen, its fields stay so
    return task


def _describe(config: "RunConfig") -> str:
    """:return: The task in a few words, for progress lines."""
    normalized = ", observations normalised" if config.normalize_observations else ""
    if config.env == DEFAULT_ENV:
        return f"{config.n_envs} {config.vec_env} simple_spread env(s){normalized}"
    return f"{config.n_envs} {config.env} env(s){normalized}"


def metric_info(metric: str, env: str = DEFAULT_ENV, declared: Sequence[DeclaredMetric] | None = None) -> Metric:
    """
    How a report shows a score of a task: its label, scale and direction in that task.

    A task's own metric takes the direction and the side its env declares (``collisions`` of ``simple_tag`` counts
    catches: higher is better, for the adversaries; pursuit's ``evaders_caught``: higher is better); simple_spread's
    keep :data:`~sb3_maddpg.experiments.metrics.METRICS`'s (in simple_spread fewer collisions are better); a side's
    return (``return_adversaries``) is higher-is-better for that side; any other metric is
    :data:`~sb3_maddpg.experiments.metrics.METRICS`'s.

    :param metric: The score's key.
    :param env: The task (an experiment's ``env``).
    :param declared: The metrics the task's env declares (:func:`declared_metrics`, or those a run's summary records:
        :func:`recorded_metrics`); ``None``: an MPE task's by its name (:func:`named_metrics`).
    :return: The metric as the report shows it.
    """
    if env != DEFAULT_ENV:
        for metric_declared in named_metrics(env) if declared is None else declared:
            if metric_declared.key == metric:
                per_episode = " per episode" if metric_declared.per_episode == "sum" else ""
                team = getattr(metric_declared, "team", "team")
                whose = "" if team == "team" else f" ({team})"
                label = f"{metric.replace('_', ' ')}{per_episode}{whose}"
                return Metric(metric, label, 1.0, getattr(metric_declared, "better", "higher") == "higher")
    if metric.startswith(SIDE_RETURN_PREFIX) and metric not in METRICS and metric != "return_std":
        side = metric.removeprefix(SIDE_RETURN_PREFIX).replace("_", " ")
        return Metric(metric, f"{side_return_label(side)} per agent", 1.0, True)
    return METRICS.get(metric, Metric(metric, metric))
