"""Compatibility with older versions of sb3-maddpg, in one place: the version written into every save and stored
config, the one migration of each kind of file keyed on it (:func:`migrate_saved_model`, :func:`migrate_stored_config`),
the import paths that 0.3 moved, and what a file written by an older version implies for what it lacks.

Since 0.3.0, a saved model's attributes and every ``config.json`` and ``experiment.json`` of a results directory hold
:data:`VERSION_KEY`: the sb3-maddpg version that wrote them. A file without it was written before (0.1, 0.2 or 0.3's
development versions), and is read as those wrote it; a file of a newer version than the installed one is refused,
saying to upgrade.

0.3 gave the package SB3's shape (``maddpg/``, ``matd3/``, ``common/``, ``analysis/``); the module paths of 0.2 are
gone (:data:`MOVED_IN_0_3` says where each went), except while a save is read (:func:`old_module_paths`): saved
models and replay buffers name their classes by the paths of the version that wrote them.

SB3's ``load`` builds the model with ``_init_setup_model=False`` and sets the saved attributes over it; an attribute
that a version did not save would keep today's default, and so change how an old model trains. :meth:`MADDPG.load
<sb3_maddpg.MADDPG.load>` fills each missing one with the value its version implies (:func:`attributes_missing_from`),
never over what the save holds or what the caller passes to ``load``.
"""

import importlib
import importlib.abc
import importlib.machinery
import io
import pathlib
import sys
import types
import warnings
import zipfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any

from packaging.version import InvalidVersion, Version
from stable_baselines3.common.save_util import json_to_data, open_path

from sb3_maddpg.common.package_warnings import SB3MADDPGDeprecationWarning
from sb3_maddpg.common.update_schedule import UpdateSchedule
from sb3_maddpg.common.user_code import user_stacklevel
from sb3_maddpg.provenance import COMMIT_KEY, source_commit
from sb3_maddpg.version import __version__

FIRST_VERSIONED = Version("0.3.0.dev0")
"""The first version that wrote :data:`VERSION_KEY`: a file that names an earlier one is read as those wrote it."""

VERSION_KEY = "sb3_maddpg_version"
"""The key of the version that wrote a file: an attribute of a saved model, a key of a stored config."""

STAMP_KEYS = (VERSION_KEY, COMMIT_KEY)
"""The keys :func:`with_version` adds to a stored config: read by :func:`migrate_stored_config`, never a field."""

STORED_BEFORE_0_2 = {"vec_env": "mpe2", "n_envs": 1}
"""The values of the config fields that files written before 0.2 lack: those runs stepped one mpe2 env each."""

SAVED_BEFORE_0_2: dict[str, Callable[[], Any]] = {
    "update_rule": UpdateSchedule.sb3_semantics,  # SB3's train_freq counted vectorised steps
    "actor_reg_coef": lambda: 0.0,  # no actor regulariser
}
"""Models saved by sb3-maddpg < 0.2 (0.1.x): each attribute they lack, and the value that reproduces their training."""

SCHEDULE_OF_0_2_DEV = ("transitions_per_update", "_train_freq_from_ratio", "_earn_gradient_steps", "_update_credit")
"""The attributes in which models saved by 0.2.0's development versions kept the update rule (before
:class:`~sb3_maddpg.common.update_schedule.UpdateSchedule`)."""


RENAMED_IN_0_3 = {"selection": "selector"}
"""Attributes of models saved by sb3-maddpg < 0.3 that 0.3 renamed: old name -> new name."""


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
        SB3MADDPGDeprecationWarning,
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


def written_by(data: Mapping[str, Any], what: str) -> Version | None:
    """
    :param data: A saved model's attributes or a stored config.
    :param what: What ``data`` is, for the error (e.g. ``"The model"``, or a file's path).
    :return: The sb3-maddpg version that wrote it (:data:`VERSION_KEY`), ``None`` for one written before 0.3.0; a
        ``ValueError`` for a version newer than the installed one, whose fields this one may not know.
    """
    stored = data.get(VERSION_KEY)
    if stored is None:
        return None
    try:
        version = Version(str(stored))
    except InvalidVersion:
        raise ValueError(f"{what} says it was written by sb3-maddpg {stored!r}, which is no version number.") from None
    if version > Version(__version__):
        raise ValueError(
            f"{what} was written by sb3-maddpg {version}, newer than the installed {__version__}: upgrade sb3-maddpg "
            "(pip install -U sb3-maddpg) to read it."
        )
    return version


def with_version(stored: dict[str, Any]) -> dict[str, Any]:
    """
    :param stored: A config as written to a results directory (``to_dict()``).
    :return: The same keys, then :data:`VERSION_KEY` with the installed version and
        :data:`~sb3_maddpg.provenance.COMMIT_KEY` with the commit it runs from (:func:`~sb3_maddpg.provenance.source_commit`):
        what :func:`migrate_stored_config` reads back.
    """
    return {**stored, VERSION_KEY: __version__, COMMIT_KEY: source_commit()}


def migrate_stored_config(data: Mapping[str, Any], source: str = "The stored config") -> dict[str, Any]:
    """
    The one reading of a stored experiment or run config (``experiment.json``, ``config.json``) of any version.

    :param data: The file's object.
    :param source: What it is, for an error (e.g. its path).
    :return: Its fields as this version names them, :data:`STAMP_KEYS` removed. A file written before 0.3.0 gets the
        values its version ran with for what it lacks (:data:`STORED_BEFORE_0_2`) and 0.3's names for renamed
        ``model_kwargs`` (:data:`RENAMED_IN_0_3`, in ``scheme_model_kwargs`` too); a file of 0.3.0 or later is this
        version's format. A file of a newer version is refused (:func:`written_by`).
    """
    fields = dict(data)
    version = written_by(fields, source)
    for key in STAMP_KEYS:
        fields.pop(key, None)
    if version is not None and version >= FIRST_VERSIONED:
        return fields
    fields = {**STORED_BEFORE_0_2, **fields}
    if isinstance(fields.get("model_kwargs"), dict):
        fields["model_kwargs"] = renamed_in_0_3(fields["model_kwargs"])
    if isinstance(fields.get("scheme_model_kwargs"), dict):
        fields["scheme_model_kwargs"] = {
            scheme: renamed_in_0_3(kwargs) if isinstance(kwargs, dict) else kwargs
            for scheme, kwargs in fields["scheme_model_kwargs"].items()
        }
    return fields


def migrate_saved_model(data: Mapping[str, Any] | None) -> dict[str, Any]:
    """
    The one reading of a saved model of any version, before SB3's ``load`` sets its attributes.

    :param data: The save's attributes (:func:`read_saved_data`; ``None`` where they cannot be read: ``load`` then
        says why).
    :return: The attributes to set over the saved ones: for a save before 0.3.0, what it lacks (the values its version
        implies: :func:`attributes_missing_from`) and what it holds under an old name under the new one
        (:data:`RENAMED_IN_0_3`); for a save of 0.3.0 or later, none. A save of a newer version is refused
        (:func:`written_by`). :func:`drop_old_attributes` then removes what the loaded model must not keep.
    """
    version = None if data is None else written_by(data, "The model")
    if data is None or (version is not None and version >= FIRST_VERSIONED):
        return {}
    renamed = {new: data[old] for old, new in RENAMED_IN_0_3.items() if old in data}
    return {**attributes_missing_from(dict(data)), **renamed}


def drop_old_attributes(attributes: dict[str, Any]) -> None:
    """
    Remove from a loaded model what its save held that the model must not keep: the version that wrote it (the next
    save writes its own), the attributes a save before 0.3 holds under an old name (:meth:`load
    <sb3_maddpg.common.team_algorithm.TeamOffPolicyAlgorithm.load>` passed their values under the new one) and a 0.2.0
    development save's schedule attributes.

    :param attributes: A loaded model's ``__dict__``.
    """
    for name in (VERSION_KEY, *RENAMED_IN_0_3):
        attributes.pop(name, None)
    pop_0_2_dev_schedule(attributes)


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


MOVED_IN_0_3: dict[str, tuple[str, ...]] = {
    "sb3_maddpg.attention": ("sb3_maddpg.sharing.learned", "sb3_maddpg.analysis.inspection"),
    "sb3_maddpg.matd3_policies": ("sb3_maddpg.matd3.policies",),
    "sb3_maddpg.policies": ("sb3_maddpg.maddpg.policies", "sb3_maddpg.common.policies"),
    **{
        f"sb3_maddpg.{name}": (f"sb3_maddpg.common.{name}",)
        for name in (
            "buffers",
            "env_checks",
            "install_hint",
            "layout",
            "losses",
            "networks",
            "noise",
            "progress",
            "selection",
            "team_algorithm",
            "torch_threads",
            "train_logs",
            "update_schedule",
            "update_step",
            "user_code",
        )
    },
    **{
        f"sb3_maddpg.{name}": (f"sb3_maddpg.analysis.{name}",)
        for name in ("behaviour", "evaluation", "export", "inspection", "normalised_score")
    },
}
"""Module paths of sb3-maddpg 0.2 that 0.3 moved: old path -> the new modules that hold its names (searched in order)."""


class MovedModule(types.ModuleType):
    """
    An old module path, while a save that names it is read: its names are the new modules' own objects, looked up
    when asked for.

    :param name: The old path.
    :param targets: The new modules that hold its names, searched in order.
    """

    def __init__(self, name: str, targets: Sequence[str]) -> None:
        super().__init__(name, f"Moved in sb3-maddpg 0.3 to {' and '.join(targets)}.")
        self._targets = tuple(targets)

    def __getattr__(self, attribute: str) -> Any:
        if attribute.startswith("__"):
            raise AttributeError(attribute)
        for target in self._targets:
            module = importlib.import_module(target)
            if hasattr(module, attribute):
                return getattr(module, attribute)
        raise AttributeError(f"module {self.__name__!r} (moved to {' and '.join(self._targets)}) has no {attribute!r}")


class _MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old module paths of :data:`MOVED_IN_0_3` and makes each a :class:`MovedModule`."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> importlib.machinery.ModuleSpec | None:
        if fullname not in MOVED_IN_0_3:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        return MovedModule(spec.name, MOVED_IN_0_3[spec.name])

    def exec_module(self, module: types.ModuleType) -> None:
        pass


@contextmanager
def old_module_paths() -> Iterator[None]:
    """
    Within: the module paths of 0.2 (:data:`MOVED_IN_0_3`) resolve to the new modules' objects, for reading a save
    (a model or a replay buffer) that names its classes by the paths of the version that wrote it. Outside, they do
    not exist: importing one fails as any missing module does, and nothing is added to ``sys.meta_path`` by
    ``import sb3_maddpg``.
    """
    finder = _MovedModuleFinder()
    sys.meta_path.append(finder)
    try:
        yield
    finally:
        sys.meta_path.remove(finder)
        for old in MOVED_IN_0_3:
            if isinstance(sys.modules.get(old), MovedModule):
                del sys.modules[old]
                parent, _, child = old.rpartition(".")
                if isinstance(vars(sys.modules[parent]).get(child), MovedModule):
                    delattr(sys.modules[parent], child)
