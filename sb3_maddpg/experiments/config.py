"""Experiment and run configurations: the paper's two experiments, a CI smoke test, and loading a setting by name or
file. The configuration types (and the words that describe a setting) live in :mod:`~sb3_maddpg.experiments.setting`,
the defaults in :mod:`~sb3_maddpg.experiments.defaults`."""

import dataclasses
import importlib
import inspect
import json
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

from sb3_maddpg.experiments.defaults import DEFAULT_ALGORITHM, DEFAULT_ENV, SCHEMES
from sb3_maddpg.experiments.setting import ExperimentConfig, merge_model_kwargs
from sb3_maddpg.hyperparams import load_hyperparams

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm


def load_algorithm(path: str) -> "type[BaseAlgorithm]":
    """
    :param path: ``"module:Class"``, e.g. ``"sb3_maddpg:MADDPG"``.
    :return: The class.
    """
    module_name, _, class_name = path.partition(":")
    if not class_name:
        raise ValueError(f"The algorithm must be given as 'module:Class', got {path!r}.")
    return getattr(importlib.import_module(module_name), class_name)


def algorithm_argument(experiment: Mapping[str, Any], name: str, scheme: str | None = None) -> Any:
    """
    One argument that an experiment's runs give their algorithm, for tables and figures that compare experiments
    (e.g. gradient steps from ``transitions_per_update`` and ``learning_starts``).

    :param experiment: An experiment as stored (``ExperimentConfig.to_dict()``, a results directory's
        ``experiment.json``).
    :param name: The argument, e.g. ``"transitions_per_update"``.
    :param scheme: The scheme whose runs are meant, for an experiment with ``scheme_model_kwargs``; ``None``: the
        experiment's ``model_kwargs`` alone.
    :return: The scheme's ``scheme_model_kwargs`` value, else the experiment's ``model_kwargs`` value, else its
        algorithm's default (MADDPG's: the paper's).
    """
    model_kwargs = dict(experiment.get("model_kwargs") or {})
    if scheme is not None:
        model_kwargs |= (experiment.get("scheme_model_kwargs") or {}).get(scheme, {})
    if name in model_kwargs:
        return model_kwargs[name]
    algorithm_path = experiment.get("algorithm") or DEFAULT_ALGORITHM
    parameter = inspect.signature(load_algorithm(algorithm_path)).parameters.get(name)
    if parameter is None or parameter.default is inspect.Parameter.empty:
        raise ValueError(
            f"{algorithm_path} has no argument {name!r} with a default, and the experiment's model_kwargs do not set it: "
            "name one of the algorithm's constructor arguments."
        )
    return parameter.default


def ordered_schemes(schemes: Iterable[str]) -> list[str]:
    """
    :param schemes: Scheme names, in any order, repeats allowed.
    :return: Each once: the paper's schemes in :data:`~sb3_maddpg.experiments.defaults.SCHEMES` order, then any others
        alphabetically.
    """
    present = set(schemes)
    return [scheme for scheme in SCHEMES if scheme in present] + sorted(present - set(SCHEMES))


def setting_label(name: str, experiment: Mapping[str, Any] | None) -> str:
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


TUNE_OBJECTIVES = {"min_dist_sum": "minimize", "normalised": "maximize", "return_mean": "maximize"}
"""What ``sb3-maddpg tune`` optimises on simple_spread, and in which direction: the min-dist sum at the last step
(lower is better; the default), the normalised score (the mean of the min-dist sum's and the team return's, 0 = random,
1 = the scripted controller; higher is better) or the team return (higher is better). Other tasks':
:func:`~sb3_maddpg.experiments.tune.task_objectives`."""

BASELINE_SCHEME = "full"
"""The scheme every other one is tested against (MADDPG)."""

PAPER_NAMES = {
    "full": "MADDPG",
    "independent": "IDDPG",
    "observations": "MADDPG-fo",
    "actions": "MADDPG-fa",
    "selected": "MADDPG-soa",
}
"""The paper's name of each scheme."""


EXP1 = ExperimentConfig(name="exp1", n_agents=5, num_agent_neighbors=None, episodes=100_000, n_checkpoints=20).described(
    "Experiment 1"
)
"""The paper's experiment 1 (fully observable cooperative navigation)."""

EXP2 = ExperimentConfig(name="exp2", n_agents=5, num_agent_neighbors=2, episodes=150_000, n_checkpoints=30).described(
    "Experiment 2"
)
"""The paper's experiment 2 (each agent observes its two nearest other agents)."""


def tuned_experiment(paper: ExperimentConfig) -> ExperimentConfig:
    """
    :param paper: One of the paper's settings (``EXP1``, ``EXP2``).
    :return: The same setting, protocol and budget at the hyperparameters ``sb3_maddpg/hyperparams/maddpg.yml``
        holds for it, named ``<setting>_tuned``.
    """
    tuned = load_hyperparams(paper.name)
    if tuned.n_agents != paper.n_agents or tuned.n_timesteps != paper.episodes * paper.episode_length:
        raise ValueError(
            f"maddpg.yml's {paper.name!r} entry is for {tuned.n_agents} agents and {tuned.n_timesteps:,} steps, but the "
            f"setting has {paper.n_agents} agents and {paper.episodes * paper.episode_length:,} steps: correct the entry."
        )
    env_kwargs = dict(tuned.env_kwargs)
    num_agent_neighbors = env_kwargs.pop("num_agent_neighbors", paper.num_agent_neighbors)
    return dataclasses.replace(
        paper,
        name=f"{paper.name}_tuned",
        num_agent_neighbors=num_agent_neighbors,
        env_kwargs={**paper.env_kwargs, **env_kwargs},
        model_kwargs=merge_model_kwargs(paper.model_kwargs, tuned.model_kwargs),
    ).described(tuned.description)


EXP1_TUNED = tuned_experiment(EXP1)
"""Experiment 1 at the best configuration measured at N=5 (``sb3_maddpg/hyperparams/maddpg.yml``)."""

EXP2_TUNED = tuned_experiment(EXP2)
"""Experiment 2 with experiment 1's best changes (``sb3_maddpg/hyperparams/maddpg.yml``)."""

SELECT_NEAREST_AT_N3: dict[str, dict[str, Any]] = {"selected": {"selector": 1}}
"""``selected`` runs of a 3-agent team select the nearest other agent: selecting both (the default ``k=2``) would be
``full`` sharing in another order."""

N3_FULL = ExperimentConfig(
    name="n3_full",
    n_agents=3,
    num_agent_neighbors=None,
    episodes=20_000,
    seeds=tuple(range(10)),
    n_checkpoints=20,
    keep_checkpoints=False,
    scheme_model_kwargs=SELECT_NEAREST_AT_N3,
).described("Experiment 1's setting with 3 agents, 10 seeds, selected with k=1")
"""Experiment 1's setting with 3 agents, at a budget where the package learns on a small machine."""

N3_PARTIAL = dataclasses.replace(N3_FULL, name="n3_partial", num_agent_neighbors=1).described(
    "Experiment 2's setting with 3 agents, 10 seeds, selected with k=1"
)
"""Experiment 2's setting with 3 agents: each agent observes its nearest other agent (of two)."""

TINY_MODEL_KWARGS: dict[str, Any] = {
    "learning_starts": 250,
    "batch_size": 64,
    "buffer_size": 10_000,
    "transitions_per_update": 50,
    "policy_kwargs": {"net_arch": {"pi": [16, 16], "qf": [16, 16]}},
}
"""Tiny networks and an early start for pipeline tests."""

SMOKE = ExperimentConfig(
    name="smoke",
    n_agents=3,
    num_agent_neighbors=None,
    episodes=40,
    seeds=(0, 1),
    n_envs=4,
    n_checkpoints=2,
    eval_episodes=4,
    curve_points=2,
    curve_eval_episodes=2,
    keep_checkpoints=False,
    model_kwargs=TINY_MODEL_KWARGS,
    scheme_model_kwargs=SELECT_NEAREST_AT_N3,  # k=2 of 3 would select everyone, as "full" does
).described("Smoke test, 2 seeds, tiny networks (tests the pipeline, not the methods)")
"""A pipeline check that runs every scheme in seconds (for CI)."""

EXPERIMENTS: dict[str, ExperimentConfig] = {
    config.name: config for config in (EXP1, EXP2, EXP1_TUNED, EXP2_TUNED, N3_FULL, N3_PARTIAL, SMOKE)
}
"""The named presets."""


def load_experiment(name_or_path: str) -> ExperimentConfig:
    """
    :param name_or_path: A preset name (``exp1``, ``exp2``, ``exp1_tuned``, ``exp2_tuned``, ``n3_full``, ``n3_partial``,
        ``smoke``) or the path of a JSON file written from :meth:`~sb3_maddpg.experiments.setting.ExperimentConfig.to_dict`.
    :return: The experiment config; a ``ValueError`` that names the cause and what to give instead if there is none.
    """
    if name_or_path in EXPERIMENTS:
        return EXPERIMENTS[name_or_path]
    if not name_or_path.endswith(".json"):
        raise ValueError(f"Unknown experiment {name_or_path!r}: use one of {sorted(EXPERIMENTS)} or a .json config file.")
    try:
        with open(name_or_path) as file:
            data = json.load(file)
    except FileNotFoundError:
        raise ValueError(
            f"No experiment file {name_or_path!r}: give the path of an existing .json config file, or a preset "
            f"({', '.join(EXPERIMENTS)})."
        ) from None
    except OSError as error:
        raise ValueError(
            f"Cannot read experiment file {name_or_path!r} ({error.strerror}): give a readable .json file."
        ) from None
    except json.JSONDecodeError as error:
        raise ValueError(
            f"Experiment file {name_or_path!r} is not JSON ({error}): write it as ExperimentConfig.to_dict() gives it "
            "(e.g. sb3-maddpg tune --preset-out writes one)."
        ) from None
    return _experiment_from_file(name_or_path, data)


def _experiment_from_file(path: str, data: Any) -> ExperimentConfig:
    """:func:`load_experiment`'s config from a file's JSON, with the file named in any error."""
    fields = [field.name for field in dataclasses.fields(ExperimentConfig)]
    if not isinstance(data, dict) or "name" not in data:
        raise ValueError(f'Experiment file {path!r} holds no experiment: give a JSON object with a "name" and {fields[1:]}.')
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ValueError(f"Experiment file {path!r} has unknown key(s) {unknown}: an experiment's keys are {fields}.")
    try:
        return ExperimentConfig.from_dict(data)
    except (TypeError, ValueError) as error:
        raise ValueError(f"Experiment file {path!r}: {error}") from None
