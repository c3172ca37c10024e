"""The version of sb3-maddpg in every save and stored config, and what reading it checks.

0.3.0 is the first version whose files are read. A saved model's attributes and every ``config.json`` and
``experiment.json`` of a results directory hold :data:`VERSION_KEY`, the sb3-maddpg version that wrote them; a stored
config also holds :data:`~sb3_maddpg.provenance.COMMIT_KEY`, the commit it was written from (:func:`with_version`). A
file of a newer version than the installed one is refused, saying to upgrade (:func:`written_by`): it may hold what
this version does not know. A later version that changes a format reads the files of this one by their version.
"""

import io
import pathlib
import zipfile
from collections.abc import Mapping
from typing import Any

from packaging.version import InvalidVersion, Version
from stable_baselines3.common.save_util import json_to_data, open_path

from sb3_maddpg.provenance import COMMIT_KEY, source_commit
from sb3_maddpg.version import __version__

VERSION_KEY = "sb3_maddpg_version"
"""The key of the version that wrote a file: an attribute of a saved model, a key of a stored config."""

STAMP_KEYS = (VERSION_KEY, COMMIT_KEY)
"""The keys :func:`with_version` adds to a stored config: read by :func:`read_stored_config`, never a field."""


def written_by(data: Mapping[str, Any], what: str) -> Version | None:
    """
    :param data: A saved model's attributes, a stored config or a preset file's mapping.
    :param what: What ``data`` is, for the error (e.g. ``"The model"``, or a file's path).
    :return: The sb3-maddpg version that wrote it (:data:`VERSION_KEY`), ``None`` where it names none (a config
        written by hand); a ``ValueError`` for a version newer than the installed one, whose fields this one may not
        know.
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
        what :func:`read_stored_config` reads back.
    """
    return {**stored, VERSION_KEY: __version__, COMMIT_KEY: source_commit()}


def read_stored_config(data: Mapping[str, Any], source: str = "The stored config") -> dict[str, Any]:
    """
    The one reading of a stored experiment or run config (``experiment.json``, ``config.json``).

    :param data: The file's object.
    :param source: What it is, for an error (e.g. its path).
    :return: Its fields, :data:`STAMP_KEYS` removed; a file of a newer version is refused (:func:`written_by`).
    """
    written_by(data, source)
    return {key: value for key, value in data.items() if key not in STAMP_KEYS}


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
