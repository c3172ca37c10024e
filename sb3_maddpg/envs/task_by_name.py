"""One env of any task, by name: an MPE task, a PettingZoo factory or a gymnasium id, as the experiments' configs name
their tasks (``env="mpe2.simple_push_v3:parallel_env"``), and the team size such an env declares."""

import importlib
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym


def task_env_factory(name: str, env_kwargs: Mapping[str, Any], episode_length: int) -> Callable[[], gym.Env]:
    """
    :param name: A task other than simple_spread: an MPE task's name, ``'module:function'`` of a factory of a PettingZoo
        parallel env (wrapped in the adapter) or of a ready gymnasium env (e.g. ``PettingZooToGym(env, positions=...)``,
        taken as it is), or a registered gymnasium id.
    :param env_kwargs: The task constructor's keyword arguments.
    :param episode_length: Steps per episode (an MPE task's ``max_cycles``).
    :return: A function that builds one env of the task.
    """
    from sb3_maddpg.envs import MPE_TASKS, make_mpe_env

    kwargs = dict(env_kwargs)
    if name in MPE_TASKS:
        return lambda: make_mpe_env(name, max_cycles=episode_length, **kwargs)
    if ":" in name:
        module_name, _, function_name = name.partition(":")
        try:
            factory = getattr(importlib.import_module(module_name), function_name)
        except (ImportError, AttributeError) as error:
            raise ValueError(
                f"env={name!r} names no importable function ({error}): give 'module:function' of a PettingZoo parallel "
                "env factory, e.g. 'mpe2.simple_push_v3:parallel_env'."
            ) from None
        return lambda: _as_gym_env(factory(**kwargs))
    if name in gym.registry:
        return lambda: gym.make(name, **kwargs)
    raise ValueError(
        f"Unknown env {name!r}: use 'simple_spread', an MPE task ({', '.join(MPE_TASKS)}), a PettingZoo factory as "
        "'module:function', or a registered gymnasium id (import the package that registers it)."
    )


def _as_gym_env(env: Any) -> gym.Env:
    """A factory's env as the runs take it: a gymnasium env as it is (e.g. a ``PettingZooToGym`` that declares its
    positions or task metrics), a PettingZoo ParallelEnv wrapped in the adapter."""
    from sb3_maddpg.envs import PettingZooToGym

    return env if isinstance(env, gym.Env) else PettingZooToGym(env)


def check_env_name(env: Any) -> None:
    """
    :param env: A config's ``env``.
    :raise ValueError: If it names no task (not a non-empty string).
    """
    if not isinstance(env, str) or not env.strip():
        raise ValueError(
            f"env must name a task: 'simple_spread', another MPE task, 'module:function' or a gymnasium id, got {env!r}."
        )


def task_team_size(env: str, env_kwargs: dict[str, Any] | None = None) -> int:
    """
    :param env: A task other than simple_spread (see :class:`~sb3_maddpg.experiments.setting.Setting`'s ``env``).
    :param env_kwargs: Its constructor's keyword arguments.
    :return: Its team size, read from one env of the task (its ``agent_layout``).
    """
    check_env_name(env)
    try:
        task = task_env_factory(env, dict(env_kwargs or {}), episode_length=25)()  # any length: only its team is read
    except TypeError as error:  # an argument the task does not take (make_mpe_env names it and the task's own)
        raise ValueError(f"env_kwargs {env_kwargs} do not fit {env!r}: {error}") from None
    try:
        layout = getattr(task.unwrapped, "agent_layout", None)
    finally:
        task.close()
    if layout is None:
        raise ValueError(
            f"env={env!r} has no agent_layout, so MADDPG cannot tell its agents apart: give an MPE task, a PettingZoo "
            "parallel env factory as 'module:function', or a gymnasium id whose env has an agent_layout."
        )
    return int(layout.n_agents)
