"""
Tuned hyperparameters, in the spirit of rl-zoo3's hyperparams files (nested here: the env's and the model's keyword
arguments apart): one YAML file per algorithm (``maddpg.yml`` beside this module), one entry per setting, each with
the measurement that put it there in the file's comments.

MADDPG's own defaults stay the paper's, for reproduction; an entry says what to change, in a setting, to learn
better than that. For example, the paper's experiment 1 at its best measured configuration::

    from sb3_maddpg import MADDPG
    from sb3_maddpg.envs import SimpleSpreadVecEnv
    from sb3_maddpg.hyperparams import load_hyperparams

    tuned = load_hyperparams("exp1")
    env = SimpleSpreadVecEnv(n_envs=100, n_agents=tuned.n_agents, **tuned.env_kwargs)
    model = MADDPG("MlpPolicy", env, **tuned.model_kwargs)

The experiments runner's presets ``exp1_tuned`` and ``exp2_tuned`` are these entries applied to ``exp1`` and ``exp2``.
"""

import copy
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

import yaml

HYPERPARAMS_FILES = {"maddpg": "maddpg.yml"}
"""The file of each algorithm's tuned hyperparameters, in this package."""

ENTRY_KEYS = ("n_agents", "n_timesteps", "env_kwargs", "model_kwargs", "description")
"""The keys every entry has, and the only ones it may have."""


@dataclass(frozen=True)
class TunedHyperparams:
    """
    One setting's entry of a hyperparams file.

    :param setting: The setting the entry tunes (a preset name, e.g. ``"exp1"``).
    :param n_agents: The setting's agents (and landmarks).
    :param n_timesteps: The setting's training budget in env steps.
    :param env_kwargs: Keyword arguments for :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` (and the runner's env),
        ``num_agent_neighbors`` included.
    :param model_kwargs: Keyword arguments for the algorithm, over its defaults (the paper's).
    :param description: One line for reports: what the entry changes.
    """

    setting: str
    n_agents: int
    n_timesteps: int
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    model_kwargs: dict[str, Any] = field(default_factory=dict)
    description: str = ""


def read_hyperparams_file(algo: str = "maddpg") -> dict[str, Any]:
    """
    :param algo: The algorithm (a key of :data:`HYPERPARAMS_FILES`).
    :return: The file's entries by setting, as YAML gives them.
    """
    if algo not in HYPERPARAMS_FILES:
        raise ValueError(
            f"No tuned hyperparameters for algorithm {algo!r}: the package has them for {sorted(HYPERPARAMS_FILES)}."
        )
    text = resources.files(__name__).joinpath(HYPERPARAMS_FILES[algo]).read_text(encoding="utf-8")
    entries = yaml.safe_load(text)
    if not isinstance(entries, dict):
        raise ValueError(f"{HYPERPARAMS_FILES[algo]} must map setting names to entries, got {type(entries).__name__}.")
    return entries


def tuned_settings(algo: str = "maddpg") -> list[str]:
    """
    :param algo: The algorithm (a key of :data:`HYPERPARAMS_FILES`).
    :return: The settings the algorithm has tuned hyperparameters for, in the file's order.
    """
    return list(read_hyperparams_file(algo))


def load_hyperparams(setting: str, algo: str = "maddpg") -> TunedHyperparams:
    """
    :param setting: A setting of the file (``"exp1"``, ``"exp2"``; :func:`tuned_settings` lists them).
    :param algo: The algorithm (a key of :data:`HYPERPARAMS_FILES`).
    :return: That setting's entry (a copy: changing it changes nothing else).
    """
    entries = read_hyperparams_file(algo)
    if setting not in entries:
        raise ValueError(
            f"No tuned {algo} hyperparameters for setting {setting!r}: {HYPERPARAMS_FILES[algo]} has {sorted(entries)}. "
            "Tune one with `sb3-maddpg tune --config <setting>`."
        )
    entry = entries[setting]
    if not isinstance(entry, dict) or set(entry) != set(ENTRY_KEYS):
        found = sorted(entry) if isinstance(entry, dict) else type(entry).__name__
        raise ValueError(
            f"{HYPERPARAMS_FILES[algo]}'s entry {setting!r} must have exactly the keys {list(ENTRY_KEYS)}, got {found}."
        )
    return TunedHyperparams(
        setting=setting,
        n_agents=int(entry["n_agents"]),
        n_timesteps=int(entry["n_timesteps"]),
        env_kwargs=copy.deepcopy(entry["env_kwargs"]),
        model_kwargs=copy.deepcopy(entry["model_kwargs"]),
        description=str(entry["description"]),
    )
