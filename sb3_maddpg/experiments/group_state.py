"""A run group's files beside its runs' directories: its training state (one file per group, which the same command
resumes from), each run's record that its training is over (:data:`TRAINED_FILE`), and a resumed run's
``progress.csv`` rows."""

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import torch as th

from sb3_maddpg.common.progress import log_line
from sb3_maddpg.compat import with_version
from sb3_maddpg.experiments.results_dir import CONFIG_FILE, LOG_FILE, read_json, run_directory, write_json_atomic
from sb3_maddpg.experiments.run_snapshot import read_progress_rows, versions
from sb3_maddpg.experiments.setting import RunConfig
from sb3_maddpg.experiments.training_resources import TrainingResources

STATE_PREFIX = "group_seeds_"
"""A group's state file: ``<results>/<experiment>/<scheme>/group_seeds_<seeds>.pt`` (e.g. ``group_seeds_0-30.pt``)."""

TRAINED_FILE = "trained.json"
"""A run's record that its group's training is over (its checkpoints and train time), written in its directory before
the group's runs are evaluated and deleted once the run is done: a sweep that finds it evaluates the run again, and
does not train it again."""


def seed_ranges(seeds: Sequence[int]) -> str:
    """:return: Sorted seeds as ranges, e.g. ``[0, 1, 2, 5]`` as ``"0-2+5"``."""
    parts: list[str] = []
    ordered = sorted(seeds)
    start = previous = ordered[0]
    for seed in [*ordered[1:], None]:
        if seed is not None and seed == previous + 1:
            previous = seed
            continue
        parts.append(str(start) if start == previous else f"{start}-{previous}")
        if seed is not None:
            start = previous = seed
    return "+".join(parts)


def parse_seed_ranges(text: str) -> set[int]:
    """:return: The seeds of :func:`seed_ranges`' text."""
    seeds: set[int] = set()
    for part in text.split("+"):
        low, _, high = part.partition("-")
        seeds.update(range(int(low), int(high or low) + 1))
    return seeds


def group_state_path(results_dir: str | os.PathLike[str], configs: Sequence[RunConfig]) -> Path:
    """
    :param results_dir: The sweep's results directory.
    :param configs: A group's runs (one experiment and scheme).
    :return: The file its training state is saved in, beside its runs' directories.
    """
    first = configs[0]
    return Path(results_dir) / first.experiment / first.scheme / f"{STATE_PREFIX}{seed_ranges([c.seed for c in configs])}.pt"


def remove_stale_states(results_dir: str | os.PathLike[str], configs: Sequence[RunConfig]) -> None:
    """
    Delete the state files of earlier groups that held any of these runs (they are started afresh), and the temporary
    files of saves a killed process left (:func:`save_state`'s ``.group_seeds_<seeds>.pt.<pid>.tmp``).
    """
    seeds = {config.seed for config in configs}
    directory = group_state_path(results_dir, configs).parent
    stale = [(path, path.stem) for path in directory.glob(f"{STATE_PREFIX}*.pt")]
    stale += [(path, path.name[1:].partition(".pt.")[0]) for path in directory.glob(f".{STATE_PREFIX}*.pt.*.tmp")]
    for path, stem in stale:
        try:
            overlaps = bool(parse_seed_ranges(stem[len(STATE_PREFIX) :]) & seeds)
        except ValueError:  # not a name this module writes
            continue
        if overlaps:
            path.unlink(missing_ok=True)


def save_state(path: Path, state: dict[str, Any]) -> None:
    """Write a group's state whole or not at all (a temporary file renamed over the old one), with the versions it is
    only resumed under (:func:`~sb3_maddpg.experiments.run_snapshot.versions`, as a run's snapshot)."""
    tmp_path = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        th.save({**state, "versions": versions()}, tmp_path)
        os.replace(tmp_path, path)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def load_state(
    path: Path,
    configs: Sequence[RunConfig],
    results_dir: str | os.PathLike[str],
    log: Callable[[str], None] | None = None,
) -> dict[str, Any] | None:
    """
    :param path: A group's state file.
    :param configs: The group's runs.
    :param results_dir: The sweep's results directory.
    :param log: Called with a line saying why a state file that exists is not used.
    :return: The state, when it is readable, of these runs with these configs, saved under this package's, SB3's,
        PyTorch's and NumPy's versions, and their directories still hold what it was saved with (config and
        checkpoints); else ``None`` (the group starts afresh).
    """
    if not path.exists():
        return None
    state, why = _read_state(path, configs, results_dir)
    if state is None and log is not None:
        log(f"{path.name} {why}, so the group starts afresh")
    return state


def _read_state(
    path: Path, configs: Sequence[RunConfig], results_dir: str | os.PathLike[str]
) -> tuple[dict[str, Any] | None, str]:
    """:return: :func:`load_state`'s state, or ``None`` and why not (a clause following the file's name)."""
    from sb3_maddpg.run_group.trainer import STATE_VERSION

    try:
        state = th.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # a truncated or foreign file: start afresh
        return None, f"cannot be read ({type(error).__name__}: truncated, or not a state)"
    if not isinstance(state, dict) or state.get("configs") != [config.to_dict() for config in configs]:
        return None, "is of other runs or configs"
    if "versions" not in state:
        return None, "was saved before group states recorded their versions (before 0.3.0)"
    if state["versions"] != versions():  # a resumed group equals an uninterrupted one only under the same versions
        return None, f"was saved under other versions ({state['versions']}, now {versions()})"
    version = state["group"].get("version") if isinstance(state.get("group"), dict) else None
    if version != STATE_VERSION:
        return None, f"is of another layout (version {version}; this package reads version {STATE_VERSION})"
    for config, run in zip(configs, state["runs"]):
        if not _same_config(read_json(run_directory(results_dir, config) / CONFIG_FILE), config):
            return None, f"was saved with another {CONFIG_FILE} of {config.run_id}"
        missing = [file for _, file in run["saved"] if not Path(file).exists()]
        if missing:
            return None, f"names checkpoints of {config.run_id} that are missing ({missing[0]})"
    return state, ""


class TrainedRun(NamedTuple):
    """A run whose training is over: its checkpoints, ``(env steps, model file)`` in order, its training's wall time
    in seconds, and what trained it (``None`` when not recorded)."""

    saved: list[tuple[int, Path]]
    train_time: float
    resources: TrainingResources | None


def write_trained(
    directory: Path, config: RunConfig, saved: Sequence[tuple[int, Path]], train_time: float, resources: TrainingResources
) -> None:
    """
    Record that a run's training is over, before it is evaluated (see :data:`TRAINED_FILE`).

    :param directory: The run's directory.
    :param config: The run.
    :param saved: Its checkpoints, ``(env steps, model file)`` in order.
    :param train_time: Its training's wall time, seconds.
    :param resources: What trained it (its group's device, threads and size).
    """
    record = {
        "config": with_version(config.to_dict()),
        "saved": [[steps, str(path)] for steps, path in saved],
        "train_time": train_time,
        "resources": resources.to_summary(),
    }
    write_json_atomic(directory / TRAINED_FILE, record)


def read_trained(directory: Path, config: RunConfig, echo: bool) -> TrainedRun | None:
    """
    :param directory: A run's directory.
    :param config: The run.
    :param echo: Print why a record is not used, too (it is appended to the run's ``train.log``).
    :return: Its checkpoints, train time and resources (``None`` where unreadable), when its training
        is over (:func:`write_trained`) for this config and its checkpoints are still there; else ``None`` (the run
        trains, again if it had).
    """
    path = directory / TRAINED_FILE
    if not path.exists():
        return None
    record = read_json(path)
    stored = read_json(directory / CONFIG_FILE)
    if not isinstance(record, dict) or not _same_config(record.get("config"), config):
        why = f"its {TRAINED_FILE} is unreadable or of another config"
    elif not _same_config(stored, config):
        why = f"its {CONFIG_FILE} is of another config"
    elif not all(Path(file).exists() for _, file in record["saved"]):
        why = "some of the checkpoints its training saved are missing"
    else:
        try:
            recorded: TrainingResources | None = TrainingResources(**record["resources"])
        except (TypeError, KeyError):  # not ours: the cost table says "-" for this run rather than training it again
            recorded = None
        return TrainedRun([(int(steps), Path(file)) for steps, file in record["saved"]], float(record["train_time"]), recorded)
    log_line(f"{config.run_id}: {why}, so it trains again", str(directory / LOG_FILE), echo)
    return None


def _same_config(stored: Any, config: RunConfig) -> bool:
    """:return: Whether a config read from JSON is ``config`` (JSON has no tuples: compared as configs)."""
    try:
        return isinstance(stored, dict) and RunConfig.from_dict(stored).same_as(config)
    except (TypeError, ValueError, KeyError):  # a foreign or older file
        return False


def progress_rows_until(path: Path, until: int) -> list[dict[str, Any]]:
    """:return: The rows of a ``progress.csv`` up to env step ``until`` (values as numbers), to log them again."""
    rows = [{key: _number(value) for key, value in row.items() if value not in ("", None)} for row in read_progress_rows(path)]
    return [row for row in rows if float(row.get("time/total_timesteps", 0)) <= until]


def _number(text: str) -> Any:
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text
