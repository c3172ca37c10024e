"""The task a run trains on: simple_spread (batched or on mpe2), another MPE task, a PettingZoo factory or a gymnasium
id, as a VecEnv, with the task metrics it is scored by."""

from collections.abc import Callable

import gymnasium as gym
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv

from sb3_maddpg.analysis.evaluation import SIDE_RETURN_PREFIX, DeclaredMetric, side_return_label
from sb3_maddpg.experiments.config import DEFAULT_ENV, RunConfig
from sb3_maddpg.experiments.stats import METRICS, Metric
from sb3_maddpg.experiments.task_envs import task_env_factory


def env_factory(config: RunConfig) -> Callable[[], gym.Env]:
    """
    :param config: A run on a task other than simple_spread.
    :return: A function that builds one env of the task (:func:`~sb3_maddpg.experiments.task_envs.task_env_factory`).
    """
    return task_env_factory(config.env, config.env_kwargs, config.episode_length)


def make_task_vec_env(config: RunConfig, n_envs: int) -> VecEnv:
    """
    :param config: The run.
    :param n_envs: Envs stepped together.
    :return: The run's task as a VecEnv: simple_spread as the config's ``vec_env`` says, any other in a ``DummyVecEnv``.
    """
    if config.env == DEFAULT_ENV:
        from sb3_maddpg.envs import make_simple_spread_vec_env

        return make_simple_spread_vec_env(
            n_envs,
            config.vec_env,  # type: ignore[arg-type]  # RunConfig checks it
            n_agents=config.n_agents,
            num_agent_neighbors=config.num_agent_neighbors,
            max_cycles=config.episode_length,
            **config.env_kwargs,  # e.g. continuous_actions=False
        )
    return DummyVecEnv([env_factory(config)] * n_envs)


def task_metrics(config: RunConfig) -> tuple[DeclaredMetric, ...]:
    """
    :param config: The run.
    :return: The task metrics its evaluations score besides simple_spread's (an MPE task's own; none otherwise).
    """
    from sb3_maddpg.envs import MPE_TASK_METRICS

    return () if config.env == DEFAULT_ENV else tuple(MPE_TASK_METRICS.get(config.env, ()))


def task_sides(config: RunConfig) -> dict[str, tuple[str, ...]]:
    """
    :param config: The run.
    :return: The sides its evaluations score each return of (:data:`~sb3_maddpg.envs.MPE_TASK_SIDES`, for a
        competitive MPE task), so that no return adds opponents' rewards; empty for a cooperative task or any other.
    """
    from sb3_maddpg.envs import MPE_TASK_SIDES

    return dict(MPE_TASK_SIDES.get(config.env, {}))


def metric_info(metric: str, env: str = DEFAULT_ENV) -> Metric:
    """
    How a report shows a score of a task: its label, scale and direction in that task.

    An MPE task's own metric takes the direction and the side that :data:`~sb3_maddpg.envs.MPE_TASK_METRICS` give it
    (``collisions`` of ``simple_tag`` counts catches: higher is better, for the adversaries; in simple_spread fewer
    collisions are better); a side's return (``return_adversaries``) is higher-is-better for that side; any other
    metric is :data:`~sb3_maddpg.experiments.stats.METRICS`'s.

    :param metric: The score's key.
    :param env: The task (an experiment's ``env``).
    :return: The metric as the report shows it.
    """
    from sb3_maddpg.envs import MPE_TASK_METRICS

    if env != DEFAULT_ENV:
        for declared in MPE_TASK_METRICS.get(env, ()):
            if declared.key == metric:
                per_episode = " per episode" if declared.per_episode == "sum" else ""
                whose = "" if declared.team == "team" else f" ({declared.team})"
                label = f"{metric.replace('_', ' ')}{per_episode}{whose}"
                return Metric(metric, label, 1.0, declared.better == "higher")
    if metric.startswith(SIDE_RETURN_PREFIX) and metric not in METRICS and metric != "return_std":
        side = metric.removeprefix(SIDE_RETURN_PREFIX).replace("_", " ")
        return Metric(metric, f"{side_return_label(side)} per agent", 1.0, True)
    return METRICS.get(metric, Metric(metric, metric))


def describe(config: RunConfig) -> str:
    """:return: The task in a few words, for progress lines."""
    normalized = ", observations normalised" if config.normalize_observations else ""
    if config.env == DEFAULT_ENV:
        return f"{config.n_envs} {config.vec_env} simple_spread env(s){normalized}"
    return f"{config.n_envs} {config.env} env(s){normalized}"
