"""Loading models saved by older versions of sb3-maddpg, in one place: what such a save implies for what it lacks.

SB3's ``load`` builds the model with ``_init_setup_model=False`` and sets the saved attributes over it; an attribute
that a version did not save would keep today's default, and so change how an old model trains. :meth:`MADDPG.load
<sb3_maddpg.MADDPG.load>` fills each missing one with the value its version implies (:func:`attributes_missing_from`),
never over what the save holds or what the caller passes to ``load``.
"""

import io
import pathlib
import warnings
import zipfile
from collections.abc import Callable
from typing import Any

from stable_baselines3.common.save_util import json_to_data, open_path

from sb3_maddpg.update_schedule import UpdateSchedule
from sb3_maddpg.user_code import user_stacklevel

SAVED_BEFORE_0_2: dict[str, Callable[[], Any]] = {
    "update_rule": UpdateSchedule.sb3_semantics,  # SB3's train_freq counted vectorised steps
    "actor_reg_coef": lambda: 0.0,  # no actor regulariser
}
"""Models saved by sb3-maddpg < 0.2 (0.1.x): each attribute they lack, and the value that reproduces their training."""

SCHEDULE_OF_0_2_DEV = ("transitions_per_update", "_train_freq_from_ratio", "_earn_gradient_steps", "_update_credit")
"""The attributes in which models saved by 0.2.0's development versions kept the update rule (before
:class:`~sb3_maddpg.update_schedule.UpdateSchedule`)."""


RENAMED_IN_0_3 = {"selection": "selector"}
"""Attributes of models saved by sb3-maddpg < 0.3 that 0.3 renamed: old name -> new name."""


def drop_names_before_0_3(attributes: dict[str, Any]) -> None:
    """
    Remove the attributes a save of sb3-maddpg < 0.3 holds under an old name (:data:`RENAMED_IN_0_3`) from a loaded
    model: :meth:`~sb3_maddpg.team_algorithm.TeamOffPolicyAlgorithm.load` passed their values under the new name.

    :param attributes: A loaded model's ``__dict__``.
    """
    for old in RENAMED_IN_0_3:
        attributes.pop(old, None)


def renamed_in_0_3(kwargs: dict[str, Any]) -> dict[str, Any]:
    """
    :param kwargs: Keyword arguments of the algorithm written before 0.3, e.g. a stored run's ``model_kwargs``.
    :return: A copy with the arguments of :data:`RENAMED_IN_0_3` under their new names (the new name wins if both).
    """
    renamed = dict(kwargs)
    for old, new in RENAMED_IN_0_3.items():
        if old in renamed:
            renamed.setdefault(new, renamed.pop(old))
    return renamed


def renamed_argument(value: Any, old_value: Any, old: str, new: str) -> Any:
    """
    An argument that sb3-maddpg 0.3 renamed, given under either name.

    :param value: The argument given under its new name (None when not given).
    :param old_value: The argument given under the name it had before 0.3 (None when not given); it warns.
    :param old: The old name.
    :param new: The new name.
    :return: The argument given.
    """
    if old_value is None:
        return value
    if value is not None:
        raise TypeError(f"Got both {new}= and {old}=: {old} is the name {new} had before sb3-maddpg 0.3; give {new} only.")
    warnings.warn(
        f"{old}= is renamed {new}= in sb3-maddpg 0.3: use {new}= (the old name will go).",
        FutureWarning,
        stacklevel=user_stacklevel(),
    )
    return old_value


def attributes_missing_from(data: dict[str, Any]) -> dict[str, Any]:
    """
    :param data: A save's attributes (:func:`read_saved_data`).
    :return: The attributes to set on the loaded model that the save lacks: for a 0.2.0 development save, its update
        rule read from its five attributes; for a save before 0.2, those of :data:`SAVED_BEFORE_0_2`.
    """
    if "update_rule" in data:
        return {}
    if all(name in data for name in SCHEDULE_OF_0_2_DEV):
        return {"update_rule": schedule_of_0_2_dev(dict(data))}
    return {name: value() for name, value in SAVED_BEFORE_0_2.items() if name not in data}


def pop_0_2_dev_schedule(attributes: dict[str, Any]) -> UpdateSchedule | None:
    """
    Remove the five attributes of a 0.2.0 development save (see :data:`SCHEDULE_OF_0_2_DEV`) from a loaded model.

    :param attributes: A loaded model's ``__dict__``.
    :return: The schedule they held, or ``None`` when the model was saved otherwise.
    """
    if not all(name in attributes for name in SCHEDULE_OF_0_2_DEV):
        return None
    return schedule_of_0_2_dev(attributes)


def schedule_of_0_2_dev(attributes: dict[str, Any]) -> UpdateSchedule:
    """
    :param attributes: Attributes holding a 0.2.0 development save's update rule; they are removed from it.
    :return: The rule.
    """
    return UpdateSchedule(
        transitions_per_update=attributes.pop("transitions_per_update"),
        derives_train_freq=attributes.pop("_train_freq_from_ratio"),
        earns_gradient_steps=attributes.pop("_earn_gradient_steps"),
        credit=attributes.pop("_update_credit"),
        counted_at=attributes.pop("_credited_timesteps", 0),
    )


def read_saved_data(
    path: str | pathlib.Path | io.BufferedIOBase, custom_objects: dict[str, Any] | None = None
) -> dict[str, Any] | None:
    """
    :param path: A model saved by ``MADDPG.save`` (a path, with or without ``.zip``, or an open file).
    :param custom_objects: As for ``MADDPG.load``.
    :return: The saved attributes (SB3's ``data``), or ``None`` where they cannot be read (``load`` then says why).
    """
    try:
        file = open_path(path, "r", verbose=0, suffix="zip")
    except (OSError, ValueError):
        return None
    position = file.tell() if file.seekable() else None
    try:
        with zipfile.ZipFile(file) as archive:
            data = json_to_data(archive.read("data").decode(), custom_objects=custom_objects)
    except (KeyError, OSError, ValueError, zipfile.BadZipFile):
        return None
    finally:
        if position is not None:
            file.seek(position)
        if file is not path:
            file.close()
    return data
