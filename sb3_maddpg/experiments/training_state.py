"""What of a model is training state, which a run's snapshot saves and puts back onto a new model of its config.

A new model of the run's config, built on a new env, has everything else (spaces, layout, classes, schedules) as the
saved one had, so a snapshot (:mod:`~sb3_maddpg.experiments.run_snapshot`) holds only plain data
(:mod:`~sb3_maddpg.common.plain_state`) and tensors: the networks' and optimisers' state dicts (as SB3's ``save``
names them, :func:`model_tensors`), the attributes that change in training (:data:`MODEL_ATTRIBUTES`), and the replay
buffer's and each env layer's attributes but those of the construction (:data:`MADE_BY_CONSTRUCTION`), objects of
state (:data:`STATE_HOLDERS`) taken attribute by attribute.
"""

import contextlib
from collections.abc import Iterator
from typing import Any

import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.running_mean_std import RunningMeanStd
from stable_baselines3.common.save_util import recursive_getattr

from sb3_maddpg.common.update_schedule import UpdateSchedule
from sb3_maddpg.envs.simple_spread_worlds import SimpleSpreadWorlds

STATE_HOLDERS = (SimpleSpreadWorlds, RunningMeanStd, UpdateSchedule)
"""Objects whose attributes are training state, saved attribute by attribute: the simple_spread worlds, a
``VecNormalize``'s running statistics, the update schedule's credit."""

MADE_BY_CONSTRUCTION = frozenset(
    {"venv", "class_attributes", "observation_space", "action_space", "device", "agent_layout", "layout", "selector"}
    | {"task_metrics", "xp", "_renderer", "results_writer"}
)
"""Attributes of an env's layers and of the replay buffer that are not saved: a new env and model of the run's config
have them as the saved ones had (the action space's random stream is saved apart). Any other attribute that is not
plain data stops a snapshot from being saved (said in the run's log)."""

MODEL_ATTRIBUTES = (
    # SB3's counters and the rollout under way (BaseAlgorithm, OffPolicyAlgorithm); the exploration noise has no
    # state to keep, since learn() resets it at its start.
    "num_timesteps",
    "_episode_num",
    "_n_updates",
    "_current_progress_remaining",
    "gradient_steps",
    "_last_obs",
    "_last_episode_starts",
    "_last_original_obs",
    "ep_info_buffer",
    "ep_success_buffer",
    # TeamOffPolicyAlgorithm's: the update schedule's credit, the last log step, the per-agent returns under way.
    "update_rule",
    "_logs_dumped_at",
    "_agent_episode_returns",
)
"""The model's attributes that change in training, besides its networks and optimisers (a model of the run's config
has the others)."""


def model_tensors(model: BaseAlgorithm) -> dict[str, Any]:
    """:return: The state dicts of the model's networks and optimisers, and its other tensors, as SB3's ``save`` names them."""
    modules, variables = model._get_torch_save_params()
    return {
        "modules": {name: recursive_getattr(model, name).state_dict() for name in modules},
        "variables": {name: recursive_getattr(model, name) for name in variables},
    }


def restore_model_tensors(model: BaseAlgorithm, tensors: dict[str, Any]) -> None:
    """
    :param model: A new model of the run's config.
    :param tensors: From :func:`model_tensors` (on the CPU: a state dict's ``load_state_dict`` puts it on the model's
        device).
    """
    modules, variables = model._get_torch_save_params()
    if sorted(tensors["modules"]) != sorted(modules) or sorted(tensors["variables"]) != sorted(variables):
        raise ValueError(f"the snapshot's model has the tensors {sorted(tensors['modules'])}, this run's {sorted(modules)}")
    with torch_errors_as_unreadable("the model's tensors"):  # e.g. networks of other sizes
        for name, state_dict in tensors["modules"].items():
            recursive_getattr(model, name).load_state_dict(state_dict)
        with th.no_grad():
            for name, tensor in tensors["variables"].items():
                if tensor is not None:  # e.g. SAC's log_ent_coef, None when the coefficient is fixed
                    recursive_getattr(model, name).copy_(tensor)


@contextlib.contextmanager
def torch_errors_as_unreadable(name: str) -> Iterator[None]:
    """Turn PyTorch's ``RuntimeError`` for a file it cannot parse or tensors of other shapes into a ``ValueError`` (the
    snapshot is not whole, or not of this code), leaving out running out of memory, which fails the run."""
    try:
        yield
    except th.OutOfMemoryError:
        raise
    except RuntimeError as error:
        raise ValueError(f"{name}: {error}") from error
