"""
The experiments' presets in one format, YAML: one file per setting beside this module (``exp1.yml``, ``exp2.yml``,
``n3_full.yml``, ``n3_partial.yml``, ``pursuit.yml``, ``multiwalker.yml``, ``smoke.yml``), and the reading of any preset file
(``sb3-maddpg run --config my_setting.yml``).

A preset file is a mapping of an experiment's fields (:class:`~sb3_maddpg.experiments.setting.ExperimentConfig`'s;
those left out keep their defaults; ``sb3_maddpg_version`` where a tuning study wrote it) with two more keys:
``note``, the few words before the setting's values in its description (a ``description`` written out is kept as it
is instead), and ``tuned``, optional: the fields that tune the setting (``env_kwargs`` and ``model_kwargs`` merged
over the setting's, any other field replaced) and their own ``note``, with the measurement that put them there in the
file's comments; or ``tuned: hyperparams``, the algorithm's tuned entry for the setting
(:mod:`sb3_maddpg.hyperparams`, as ``exp1.yml`` and ``exp2.yml`` say). A file with ``tuned`` gives two presets:
``<name>`` and ``<name>_tuned`` (the setting, its protocol and its budget at the tuned values).
"""

from importlib import resources
from importlib.abc import Traversable
from pathlib import Path
from typing import Any

import yaml

from sb3_maddpg.compat import STAMP_KEYS, written_by
from sb3_maddpg.experiments.setting import ExperimentConfig, merge_model_kwargs
from sb3_maddpg.hyperparams import load_hyperparams

PACKAGE_PRESETS = ("exp1", "exp2", "n3_full", "n3_partial", "pursuit", "multiwalker", "smoke")
"""The package's preset files (``<name>.yml`` beside this module), in the order the command line lists them."""

PRESET_KEYS = ("note", "tuned")
"""The keys of a preset file beside the experiment's fields."""

TUNED_SUFFIX = "_tuned"
"""What a setting's name gets in the preset of its ``tuned`` values."""

FROM_HYPERPARAMS = "hyperparams"
"""``tuned: hyperparams``: the tuned values are the algorithm's entry for the setting in :mod:`sb3_maddpg.hyperparams`."""


def read_preset_file(path: str | Path | Traversable) -> list[ExperimentConfig]:
    """
    Read a preset file. ``sb3-maddpg run --config my.yml`` runs its setting; its tuned preset is for the package's
    own files (``exp1_tuned``) and for code (``read_preset_file("my.yml")[1]``).

    :param path: A preset file (YAML; JSON, a subset of YAML, reads too).
    :return: Its presets: the setting, then ``<name>_tuned`` if the file tunes it; a ``ValueError`` that names the
        file, the cause and what to give instead.
    """
    path = path if isinstance(path, Traversable) else Path(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"No preset file {str(path)!r}: give the path of an existing .yml file.") from None
    except OSError as error:
        raise ValueError(f"Cannot read preset file {str(path)!r} ({error.strerror}): give a readable .yml file.") from None
    except yaml.YAMLError as error:
        where = getattr(error, "problem_mark", None)
        line = f" (line {where.line + 1})" if where is not None else ""
        raise ValueError(f"Preset file {str(path)!r} is not YAML{line}: write it as the package's presets are.") from None
    return presets_of(data, str(path))


def presets_of(data: Any, source: str) -> list[ExperimentConfig]:
    """
    :param data: A preset file's mapping (see the module's docstring).
    :param source: Where it was read, for errors.
    :return: The setting, then ``<name>_tuned`` if ``data`` has ``tuned``.
    """
    fields = list(ExperimentConfig.STORED_KEYS)
    if not isinstance(data, dict) or "name" not in data:
        raise ValueError(
            f"Preset file {source!r} holds no experiment: give a YAML mapping with a name and any of {fields[1:]}."
        )
    _refuse_unknown(data, (*fields, *PRESET_KEYS, *STAMP_KEYS), source)
    written_by(data, f"Preset file {source!r}")  # a newer version's preset is refused
    setting_fields = {key: value for key, value in data.items() if key not in (*PRESET_KEYS, *STAMP_KEYS)}
    try:
        setting = _described(ExperimentConfig.from_fields(setting_fields), setting_fields, data.get("note"))
    except (TypeError, ValueError) as error:
        raise ValueError(f"Preset file {source!r}: {error}") from None
    if "tuned" not in data:
        return [setting]
    tuned = _from_hyperparams(setting, source) if data["tuned"] == FROM_HYPERPARAMS else data["tuned"]
    return [setting, _tuned(setting, tuned, source)]


def _from_hyperparams(setting: ExperimentConfig, source: str) -> dict[str, Any]:
    """
    :param setting: A preset file's setting, whose file says ``tuned: hyperparams``.
    :param source: Where it was read, for errors.
    :return: Its ``tuned`` mapping from the algorithm's tuned entry for it (:mod:`sb3_maddpg.hyperparams`); a
        ``ValueError`` where the entry is for other agents or another budget.
    """
    algo = setting.algorithm.rpartition(":")[2].lower()
    entry = load_hyperparams(setting.name, algo)
    budget = setting.episodes * setting.episode_length
    if (entry.n_agents, entry.n_timesteps) != (setting.n_agents, budget):
        raise ValueError(
            f"Preset file {source!r}: the tuned {algo} entry {setting.name!r} is for {entry.n_agents} agents and "
            f"{entry.n_timesteps} steps, the setting has {setting.n_agents} and {budget}: make them agree."
        )
    env_kwargs = dict(entry.env_kwargs)
    neighbours = {"num_agent_neighbors": env_kwargs.pop("num_agent_neighbors")} if "num_agent_neighbors" in env_kwargs else {}
    return {"note": entry.description, **neighbours, "env_kwargs": env_kwargs, "model_kwargs": entry.model_kwargs}


def _tuned(setting: ExperimentConfig, tuned: Any, source: str) -> ExperimentConfig:
    """
    :param setting: A preset file's setting.
    :param tuned: Its ``tuned`` mapping.
    :param source: Where it was read, for errors.
    :return: ``<name>_tuned``: the setting with the tuned fields.
    """
    if not isinstance(tuned, dict):
        raise ValueError(f"Preset file {source!r}: tuned must be a mapping of the fields that tune the setting.")
    allowed = [key for key in ExperimentConfig.STORED_KEYS if key not in ("name", "description")]
    _refuse_unknown(tuned, (*allowed, "note"), source, "tuned")
    changes = {key: value for key, value in tuned.items() if key != "note"}
    for key in ("env_kwargs", "model_kwargs"):
        if not isinstance(changes.get(key, {}), dict):
            raise ValueError(f"Preset file {source!r}, tuned: {key} must be a mapping, got {changes[key]!r}.")
    fields = {key: value for key, value in setting.to_dict().items() if key != "description"}
    fields |= changes | {"name": setting.name + TUNED_SUFFIX}
    fields["env_kwargs"] = {**setting.env_kwargs, **changes.get("env_kwargs", {})}
    fields["model_kwargs"] = merge_model_kwargs(setting.model_kwargs, changes.get("model_kwargs", {}))
    try:
        return ExperimentConfig.from_fields(fields).described(tuned.get("note", ""))
    except (TypeError, ValueError) as error:
        raise ValueError(f"Preset file {source!r}, tuned: {error}") from None


def _described(experiment: ExperimentConfig, fields: dict[str, Any], note: Any) -> ExperimentConfig:
    """:return: ``experiment`` described by its note and values, unless its file wrote a description out."""
    return experiment if "description" in fields else experiment.described(str(note or ""))


def _refuse_unknown(data: dict[str, Any], known: tuple[str, ...], source: str, where: str = "") -> None:
    """Refuse the keys of ``data`` that are not ``known``, naming the file (and ``where`` in it) and the known keys."""
    unknown = sorted(set(data) - set(known))
    if unknown:
        inside = f", in {where}," if where else ""
        raise ValueError(f"Preset file {source!r}{inside} has unknown key(s) {unknown}: its keys are {list(known)}.")


def package_presets() -> dict[str, ExperimentConfig]:
    """:return: The package's presets by name: each file's setting, then its tuned preset if it has one."""
    presets: dict[str, ExperimentConfig] = {}
    for name in PACKAGE_PRESETS:
        for preset in read_preset_file(resources.files(__name__).joinpath(f"{name}.yml")):
            presets[preset.name] = preset
    return presets
