"""A setting in words, derived from its values: the one-line description reports and progress lines show, and the
short label of tables and figures."""

from typing import TYPE_CHECKING, Any

from sb3_maddpg.experiments.defaults import DEFAULT_ALGORITHM, DEFAULT_ENV

if TYPE_CHECKING:
    from sb3_maddpg.experiments.setting import ExperimentConfig


def setting_label(name: str, experiment: dict[str, Any] | None) -> str:
    """
    :param name: The experiment name.
    :param experiment: Its stored config (``ExperimentConfig.to_dict()``), if any.
    :return: A short label, e.g. ``"exp1 (N=5, full obs., 100,000 ep.)"``; an algorithm other than MADDPG is named
        first (``"n3_matd3 (MATD3, N=3, ...)"``), since the scheme columns keep the paper's MADDPG names.
    """
    if not experiment:
        return name
    algorithm = experiment.get("algorithm", DEFAULT_ALGORITHM)
    prefix = "" if algorithm == DEFAULT_ALGORITHM else f"{algorithm.rpartition(':')[2]}, "
    if experiment.get("env", DEFAULT_ENV) != DEFAULT_ENV:
        return f"{name} ({prefix}{experiment['env']}, {experiment['episodes']:,} ep.)"
    neighbors = experiment.get("num_agent_neighbors")
    if neighbors is None:
        observability = "full obs."
    elif neighbors >= experiment["n_agents"] - 1:  # every other agent, in order of distance
        observability = "full obs. nearest first"
    else:
        observability = f"{neighbors} nearest obs."
    return f"{name} ({prefix}N={experiment['n_agents']}, {observability}, {experiment['episodes']:,} ep.)"


def _plural(count: int, noun: str) -> str:
    return f"{count:,} {noun}" + ("" if count == 1 else "s")


def describe_setting(experiment: "ExperimentConfig") -> str:
    """
    The setting's values in words, derived from its fields, so that a changed field changes them.

    :param experiment: An experiment.
    :return: Its task (and the task's keyword arguments), its algorithm when not MADDPG, its team size, for
        simple_spread its observability, its budget and its evaluation schedule, e.g. ``"simple_spread, N=5, full
        observability, 100,000 episodes (2,500,000 steps), 20 checkpoints x 100 episodes over the last 20%, 50 curve
        points x 20 episodes"``.
    """
    task = experiment.env
    if experiment.env_kwargs:
        task += " (" + ", ".join(f"{key}={value}" for key, value in experiment.env_kwargs.items()) + ")"
    parts = [task]
    if experiment.algorithm != DEFAULT_ALGORITHM:
        parts.append(experiment.algorithm.rpartition(":")[2])
    if experiment.env == DEFAULT_ENV:
        neighbors = experiment.num_agent_neighbors
        parts.append(f"N={experiment.n_agents}")
        if neighbors is None:
            parts.append("full observability")
        elif neighbors >= experiment.n_agents - 1:
            parts.append("full observability nearest first")
        else:
            parts.append(f"{_plural(neighbors, 'nearest agent')} observed")
    else:
        parts.append(_plural(experiment.n_agents, "agent"))
    steps = experiment.episodes * experiment.episode_length
    parts.append(f"{_plural(experiment.episodes, 'episode')} ({steps:,} steps)")
    parts.append(
        f"{_plural(experiment.n_checkpoints, 'checkpoint')} x {_plural(experiment.eval_episodes, 'episode')} over the "
        f"last {experiment.checkpoint_fraction:.0%}"
    )
    if experiment.curve_points:
        parts.append(
            f"{_plural(experiment.curve_points, 'curve point')} x {_plural(experiment.curve_eval_episodes, 'episode')}"
        )
    else:
        parts.append("no learning curve")
    return ", ".join(parts)
