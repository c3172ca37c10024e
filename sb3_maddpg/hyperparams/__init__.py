"""
Tuned hyperparameters, in the spirit of rl-zoo3's hyperparams files, kept beside the preset they tune: the ``tuned``
section of a setting's preset file (``sb3_maddpg/experiments/presets/exp1.yml``, ``exp2.yml``), each with the
measurement that put it there in the file's comments; here as the env's and the model's keyword arguments apart.

MADDPG's own defaults stay the paper's, for reproduction; an entry says what to change, in a setting, to learn
better than that. For example, the paper's experiment 1 at its best measured configuration::

    from sb3_maddpg import MADDPG
    from sb3_maddpg.envs import SimpleSpreadVecEnv
    from sb3_maddpg.hyperparams import load_hyperparams

    tuned = load_hyperparams("exp1")
    env = SimpleSpreadVecEnv(n_envs=100, n_agents=tuned.n_agents, **tuned.env_kwargs)
    model = MADDPG("MlpPolicy", env, **tuned.model_kwargs)

The experiments runner's presets ``exp1_tuned`` and ``exp2_tuned`` are the same sections applied to ``exp1`` and
``exp2``.
"""

import copy
from dataclasses import dataclass, field
from typing import Any

TUNED_ALGORITHMS = ("maddpg",)
"""The algorithms with tuned hyperparameters (the presets' ``algorithm``: MADDPG)."""


@dataclass(frozen=True)
class TunedHyperparams:
    """
    One setting's tuned values (its preset file's ``tuned`` section).

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


def tuned_settings(algo: str = "maddpg") -> list[str]:
    """
    :param algo: The algorithm (one of :data:`TUNED_ALGORITHMS`).
    :return: The settings the algorithm has tuned hyperparameters for, in the presets' order.
    """
    from sb3_maddpg.experiments.config import EXPERIMENTS
    from sb3_maddpg.experiments.presets import TUNED_SUFFIX

    _check_algorithm(algo)
    return [name for name in EXPERIMENTS if name + TUNED_SUFFIX in EXPERIMENTS]


def load_hyperparams(setting: str, algo: str = "maddpg") -> TunedHyperparams:
    """
    :param setting: A setting with tuned values (``"exp1"``, ``"exp2"``; :func:`tuned_settings` lists them).
    :param algo: The algorithm (one of :data:`TUNED_ALGORITHMS`).
    :return: That setting's tuned values (a copy: changing it changes nothing else).
    """
    from sb3_maddpg.experiments.config import EXPERIMENTS
    from sb3_maddpg.experiments.presets import TUNED_SUFFIX

    _check_algorithm(algo)
    if setting not in tuned_settings(algo):
        raise ValueError(
            f"No tuned {algo} hyperparameters for setting {setting!r}: the presets tune {tuned_settings(algo)}. Tune one "
            "with sb3_maddpg.experiments.tune and write its values in the preset's tuned section."
        )
    tuned = EXPERIMENTS[setting + TUNED_SUFFIX]
    return TunedHyperparams(
        setting=setting,
        n_agents=tuned.n_agents,
        n_timesteps=tuned.episodes * tuned.episode_length,
        env_kwargs={"num_agent_neighbors": tuned.num_agent_neighbors, **copy.deepcopy(tuned.env_kwargs)},
        model_kwargs=copy.deepcopy(tuned.model_kwargs),
        description=tuned.note or "",
    )


def _check_algorithm(algo: str) -> None:
    if algo not in TUNED_ALGORITHMS:
        raise ValueError(
            f"No tuned hyperparameters for algorithm {algo!r}: the package has them for {list(TUNED_ALGORITHMS)}."
        )
