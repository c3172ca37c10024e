"""The task a run trains on: simple_spread (batched or on mpe2), another MPE task, a PettingZoo factory or a gymnasium
id, as a VecEnv, with the task metrics it is scored by."""

import importlib
from collections.abc import Callable

import gymnasium as gym
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv

from sb3_maddpg.evaluation import DeclaredMetric
from sb3_maddpg.experiments.config import DEFAULT_ENV, RunConfig


def env_factory(config: RunConfig) -> Callable[[], gym.Env]:
    """
    :param config: A run on a task other than simple_spread.
    :return: A function that builds one env of the task.
    """
    from sb3_maddpg.envs import MPE_TASKS, PettingZooToGym, make_mpe_env

    name, kwargs = config.env, dict(config.env_kwargs)
    if name in MPE_TASKS:
        return lambda: make_mpe_env(name, max_cycles=config.episode_length, **kwargs)
    if ":" in name:
        module_name, _, function_name = name.partition(":")
        try:
            factory = getattr(importlib.import_module(module_name), function_name)
        except (ImportError, AttributeError) as error:
            raise ValueError(
                f"env={name!r} names no importable function ({error}): give 'module:function' of a PettingZoo parallel "
                "env factory, e.g. 'mpe2.simple_push_v3:parallel_env'."
            ) from None
        return lambda: PettingZooToGym(factory(**kwargs))
    if name in gym.registry:
        return lambda: gym.make(name, **kwargs)
    raise ValueError(
        f"Unknown env {name!r}: use 'simple_spread', an MPE task ({', '.join(MPE_TASKS)}), a PettingZoo factory as "
        "'module:function', or a registered gymnasium id (import the package that registers it)."
    )


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


def describe(config: RunConfig) -> str:
    """:return: The task in a few words, for progress lines."""
    normalized = ", observations normalised" if config.normalize_observations else ""
    if config.env == DEFAULT_ENV:
        return f"{config.n_envs} {config.vec_env} simple_spread env(s){normalized}"
    return f"{config.n_envs} {config.env} env(s){normalized}"
