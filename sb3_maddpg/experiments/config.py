"""Experiment and run configurations: the paper's two experiments, a CI smoke test, and loading a setting by name or
file. The configuration types (and the words that describe a setting) live in :mod:`~sb3_maddpg.experiments.setting`,
the defaults in :mod:`~sb3_maddpg.experiments.defaults`."""

import dataclasses
import importlib
import inspect
import json
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

from sb3_maddpg.compat import STAMP_KEYS
from sb3_maddpg.experiments.defaults import DEFAULT_ALGORITHM, DEFAULT_ENV, SCHEMES
from sb3_maddpg.experiments.presets import package_presets, read_preset_file
from sb3_maddpg.experiments.setting import ExperimentConfig

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
:func:`~sb3_maddpg.tuning.search.task_objectives`."""

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


EXPERIMENTS: dict[str, ExperimentConfig] = package_presets()
"""The named presets, read from their YAML files (:mod:`sb3_maddpg.experiments.presets`)."""

EXP1 = EXPERIMENTS["exp1"]
"""The paper's experiment 1 (fully observable cooperative navigation)."""

EXP2 = EXPERIMENTS["exp2"]
"""The paper's experiment 2 (each agent observes its two nearest other agents)."""

EXP1_TUNED = EXPERIMENTS["exp1_tuned"]
"""Experiment 1 at the best configuration measured at N=5 (``exp1.yml``'s ``tuned``)."""

EXP2_TUNED = EXPERIMENTS["exp2_tuned"]
"""Experiment 2 with experiment 1's best changes (``exp2.yml``'s ``tuned``)."""

SMOKE = EXPERIMENTS["smoke"]
"""A pipeline check that runs every scheme in seconds (for CI)."""


def load_experiment(name_or_path: str) -> ExperimentConfig:
    """
    :param name_or_path: A preset name (``exp1``, ``exp2``, ``exp1_tuned``, ``exp2_tuned``, ``n3_full``, ``n3_partial``,
        ``smoke``), the path of a preset file (``.yml`` or ``.yaml``: :mod:`~sb3_maddpg.experiments.presets`; its
        setting, not its tuned preset) or of a stored experiment (``.json``, e.g. a results directory's
        ``experiment.json``: :func:`~sb3_maddpg.compat.read_stored_config`).
    :return: The experiment config; a ``ValueError`` that names the cause and what to give instead if there is none.
    """
    if name_or_path in EXPERIMENTS:
        return EXPERIMENTS[name_or_path]
    if name_or_path.endswith((".yml", ".yaml")):
        return read_preset_file(name_or_path)[0]
    if not name_or_path.endswith(".json"):
        raise ValueError(
            f"Unknown experiment {name_or_path!r}: use one of {sorted(EXPERIMENTS)}, a .yml preset file or a stored "
            ".json experiment."
        )
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
            f"Experiment file {name_or_path!r} is not JSON ({error}): write ExperimentConfig.to_dict() to it with "
            "json.dump, or write a .yml preset file."
        ) from None
    return _experiment_from_file(name_or_path, data)


def _experiment_from_file(path: str, data: Any) -> ExperimentConfig:
    """:func:`load_experiment`'s config from a file's JSON, with the file named in any error."""
    fields = [field.name for field in dataclasses.fields(ExperimentConfig)]
    if not isinstance(data, dict) or "name" not in data:
        others = [name for name in fields if name != "name"]
        raise ValueError(f'Experiment file {path!r} holds no experiment: give a JSON object with a "name" and {others}.')
    unknown = sorted(set(data) - {*fields, *STAMP_KEYS})
    if unknown:
        raise ValueError(f"Experiment file {path!r} has unknown key(s) {unknown}: an experiment's keys are {fields}.")
    try:
        return ExperimentConfig.from_dict(data)
    except (TypeError, ValueError) as error:
        raise ValueError(f"Experiment file {path!r}: {error}") from None
