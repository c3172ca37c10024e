"""
Tuned hyperparameters, as rl-zoo3 keeps SB3's: one YAML file per algorithm beside this module (``maddpg.yml``), one
entry per setting, each with the measurement that put it there in the file's comments.

MADDPG's own defaults stay the paper's, for reproduction; an entry says what to change, in a setting, to learn
better than that. For example, the paper's experiment 1 at its best measured configuration::

    from sb3_maddpg import MADDPG
    from sb3_maddpg.envs import SimpleSpreadVecEnv
    from sb3_maddpg.hyperparams import load_hyperparams

    tuned = load_hyperparams("exp1")
    env = SimpleSpreadVecEnv(n_envs=100, n_agents=tuned.n_agents, **tuned.env_kwargs)
    model = MADDPG("MlpPolicy", env, **tuned.model_kwargs)

The experiments' presets ``exp1_tuned`` and ``exp2_tuned`` are the settings ``exp1`` and ``exp2`` at these entries
(their preset files say ``tuned: hyperparams``). This module reads its files only: it imports nothing of the study.
"""

import copy
import functools
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

import yaml

TUNED_ALGORITHMS = ("maddpg",)
"""The algorithms with tuned hyperparameters (a ``<algo>.yml`` beside this module each)."""

ENTRY_KEYS = ("n_agents", "n_timesteps", "note", "env_kwargs", "model_kwargs")
"""The keys of an entry, all required."""


@dataclass(frozen=True)
class TunedHyperparams:
    """
    One setting's tuned values (an entry of ``<algo>.yml``).

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


@functools.cache
def _entries(algo: str) -> dict[str, dict[str, Any]]:
    """:return: ``<algo>.yml``'s entries by setting, checked (read once; callers copy)."""
    text = resources.files(__name__).joinpath(f"{algo}.yml").read_text(encoding="utf-8")
    entries = yaml.safe_load(text)
    for setting, entry in entries.items():
        if not isinstance(entry, dict) or sorted(entry) != sorted(ENTRY_KEYS):
            raise ValueError(f"{algo}.yml, entry {setting!r}: an entry has exactly the keys {list(ENTRY_KEYS)}.")
    return entries  # type: ignore[no-any-return]


def tuned_settings(algo: str = "maddpg") -> list[str]:
    """
    :param algo: The algorithm (one of :data:`TUNED_ALGORITHMS`).
    :return: The settings the algorithm has tuned hyperparameters for, in the file's order.
    """
    _check_algorithm(algo)
    return list(_entries(algo))


def load_hyperparams(setting: str, algo: str = "maddpg") -> TunedHyperparams:
    """
    :param setting: A setting with tuned values (``"exp1"``, ``"exp2"``; :func:`tuned_settings` lists them).
    :param algo: The algorithm (one of :data:`TUNED_ALGORITHMS`).
    :return: That setting's tuned values (a copy: changing it changes nothing else).
    """
    _check_algorithm(algo)
    if setting not in tuned_settings(algo):
        raise ValueError(
            f"No tuned {algo} hyperparameters for setting {setting!r}: {algo}.yml tunes {tuned_settings(algo)}. Tune one "
            f"with `sb3-maddpg tune` and add its values to sb3_maddpg/hyperparams/{algo}.yml."
        )
    entry = copy.deepcopy(_entries(algo)[setting])
    return TunedHyperparams(
        setting=setting,
        n_agents=int(entry["n_agents"]),
        n_timesteps=int(entry["n_timesteps"]),
        env_kwargs=entry["env_kwargs"],
        model_kwargs=entry["model_kwargs"],
        description=str(entry["note"]),
    )


def _check_algorithm(algo: str) -> None:
    if algo not in TUNED_ALGORITHMS:
        raise ValueError(
            f"No tuned hyperparameters for algorithm {algo!r}: the package has them for {list(TUNED_ALGORITHMS)}."
        )
