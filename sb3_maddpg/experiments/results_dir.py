"""The results directory: its file names, and the functions that find, read and write them.

Layout: ``<results>/sweep.log``, ``<results>/sweep.lock``, ``<results>/<experiment>/experiment.json`` and one
directory per run, ``<results>/<experiment>/<scheme>/seed_<seed>/``, holding the files below.

A crash (a killed process, a full disk) must leave a state the next sweep can see: every file a resume reads
(``config.json``, ``summary.json``, ``done``, ``experiment.json``) is written whole or not at all (a temporary
file renamed), and ``done`` is written last. A run counts as finished only when its ``done`` marker, its config
and its summary are all there and readable; anything less is run again from scratch.
"""

import contextlib
import csv
import json
import math
import os
import sys
import time
import warnings
from collections.abc import Collection, Iterator, Sequence
from pathlib import Path
from typing import Any

from sb3_maddpg.common.package_warnings import SB3MADDPGWarning
from sb3_maddpg.compat import read_stored_config, with_version
from sb3_maddpg.experiments.setting import RunConfig

try:
    import fcntl
except ImportError:  # Windows: no advisory locks, sweeps are not guarded against each other there
    fcntl = None  # type: ignore[assignment]

CONFIG_FILE = "config.json"
SUMMARY_FILE = "summary.json"
CURVE_FILE = "learning_curve.csv"
CHECKPOINT_EVALS_FILE = "checkpoint_evals.csv"
PROGRESS_FILE = "progress.csv"
LOG_FILE = "train.log"
DONE_FILE = "done"
CHECKPOINT_DIR = "checkpoints"
RESULT_FILES = (CONFIG_FILE, SUMMARY_FILE, CURVE_FILE, CHECKPOINT_EVALS_FILE, PROGRESS_FILE, LOG_FILE)
"""The small text files of a finished run (they travel back from remote workers; model files do not)."""
EXPERIMENT_FILE = "experiment.json"
"""An experiment's config, in ``<results>/<experiment>/``."""
REFERENCES_FILE = "references.json"
"""An experiment's reference policies' scores, in ``<results>/<experiment>/``
(:mod:`~sb3_maddpg.experiments.references`)."""
SWEEP_LOG = "sweep.log"
"""The sweeps' progress lines, in ``<results>/``."""
LOCK_FILE = "sweep.lock"
"""Locked by the sweep that is running in ``<results>/`` (it names that sweep's PID and command)."""


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """
    Write a text file whole or not at all: a temporary file in the same directory, flushed to disk and renamed
    over ``path`` (``os.replace`` is atomic), so a crash leaves the old file or none, never a truncated one.

    :param path: The file.
    :param text: Its new content.
    """
    path = Path(path)
    tmp_path = path.with_name(f".{path.name}.{os.getpid()}.tmp")  # one writer per process; plain open() keeps the umask
    try:
        with open(tmp_path, "w") as file:
            file.write(text)
            file.flush()
            os.fsync(file.fileno())
        os.replace(tmp_path, path)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def strict_json(value: Any) -> Any:
    """
    :param value: JSON-compatible values (dicts, lists, tuples, numbers, strings, ``None``).
    :return: The same with every float that strict JSON cannot hold (NaN, infinities) as ``None``: a metric that does
        not apply is ``null`` in the files, which every JSON parser reads (Python's ``NaN`` is not JSON).
    """
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: strict_json(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict_json(item) for item in value]
    return value


def write_json_atomic(path: str | os.PathLike[str], value: Any) -> None:
    """
    :param path: A JSON file, written with :func:`write_text_atomic` as strict JSON (:func:`strict_json`: NaN as
        ``null``).
    :param value: Its content.
    """
    write_text_atomic(path, json.dumps(strict_json(value), indent=2, allow_nan=False))


NUMERIC_SUMMARY_FIELDS = ("score", "behaviour")
"""The fields of ``summary.json`` that hold numbers only: their ``null`` values are read as NaN."""


def summary_from_json(summary: dict[str, Any]) -> dict[str, Any]:
    """
    :param summary: A run's ``summary.json`` as parsed: strict JSON, ``null`` for a metric that does not apply.
    :return: The summary with every ``null`` of :data:`NUMERIC_SUMMARY_FIELDS` as NaN, as it was computed.
    """
    for field in NUMERIC_SUMMARY_FIELDS:
        values = summary.get(field)
        if isinstance(values, dict):
            summary[field] = {key: math.nan if value is None else value for key, value in values.items()}
    return summary


def read_json(path: str | os.PathLike[str]) -> Any | None:
    """
    :param path: A JSON file.
    :return: Its content, or ``None`` when it is missing or unreadable (e.g. truncated by a crash).
    """
    try:
        with open(path) as file:
            return json.load(file)
    except (OSError, ValueError):
        return None


def run_directory(results_dir: str | os.PathLike[str], config: RunConfig) -> Path:
    """
    :param results_dir: The sweep's results directory.
    :param config: The run.
    :return: The run's directory, ``<results_dir>/<experiment>/<scheme>/seed_<seed>``.
    """
    return Path(results_dir) / config.run_id


def read_summary(directory: str | os.PathLike[str]) -> dict[str, Any] | None:
    """
    :param directory: A run's directory.
    :return: Its summary if the run is finished (``done`` marker and a readable ``summary.json``), else ``None``.
    """
    directory = Path(directory)
    if not (directory / DONE_FILE).exists():
        return None
    summary = read_json(directory / SUMMARY_FILE)
    return summary_from_json(summary) if isinstance(summary, dict) else None


def is_finished(results_dir: str | os.PathLike[str], config: RunConfig) -> bool:
    """
    Whether the run has finished in ``results_dir``: its ``done`` marker (written last), its config and its
    summary are there and readable. A run directory left half-written by a crash is not finished.

    :param results_dir: The sweep's results directory.
    :param config: The run.
    :return: True if the run is finished; a finished run with another config is an error.
    """
    directory = run_directory(results_dir, config)
    stored_config = read_json(directory / CONFIG_FILE)
    if read_summary(directory) is None or not isinstance(stored_config, dict):
        return False
    stored = RunConfig.from_fields(read_stored_config(stored_config, str(directory / CONFIG_FILE)))
    if not stored.same_as(config):
        raise ValueError(
            f"{directory} holds a finished run with another config; use a new results directory for a "
            f"changed experiment (or delete that run).\n  stored:    {stored.to_dict()}\n  requested: {config.to_dict()}"
        )
    return True


def mark_done(directory: str | os.PathLike[str]) -> None:
    """
    Write a run's ``done`` marker, atomically (a temporary file renamed), after every other file of the run.

    :param directory: The run's directory.
    """
    write_text_atomic(Path(directory) / DONE_FILE, time.strftime("%Y-%m-%dT%H:%M:%S%z\n"))


def collect_result(directory: str | os.PathLike[str]) -> dict[str, Any]:
    """
    :param directory: A finished run's directory.
    :return: Its summary, with ``"files"``: the text of its result files.
    """
    directory = Path(directory)
    with open(directory / SUMMARY_FILE) as file:
        result = summary_from_json(json.load(file))
    result["files"] = {name: (directory / name).read_text() for name in RESULT_FILES if (directory / name).exists()}
    return result


def write_result_files(results_dir: str | os.PathLike[str], result: dict[str, Any]) -> None:
    """
    Write a run's result files (from :func:`~sb3_maddpg.experiments.runner.execute_run` on another machine)
    unless the run is already finished there, each atomically, then its ``done`` marker.

    :param results_dir: The sweep's results directory on this machine.
    :param result: The value ``execute_run`` returned.
    """
    directory = Path(results_dir) / result["run_id"]
    if read_summary(directory) is not None:
        return
    directory.mkdir(parents=True, exist_ok=True)
    (directory / DONE_FILE).unlink(missing_ok=True)  # a done marker without a readable summary: written again, last
    for name, text in result["files"].items():
        write_text_atomic(directory / name, text)
    mark_done(directory)


def read_curve(directory: str | os.PathLike[str]) -> list[dict[str, float]]:
    """
    :param directory: A run's directory.
    :return: Its learning curve rows (empty if it has none).
    """
    path = Path(directory) / CURVE_FILE
    if not path.exists():
        return []
    with open(path, newline="") as file:
        return [{key: float(value) for key, value in row.items()} for row in csv.DictReader(file)]


def curve_value_at(
    rows: list[dict[str, float]], step: float, metric: str = "min_dist_sum", tolerance: float = 0.05
) -> float | None:
    """
    A learning curve's value at an env step, for tables that compare runs at equal steps.

    :param rows: A run's learning curve rows (:func:`read_curve`).
    :param step: The env step.
    :param metric: The column to read.
    :param tolerance: How far (as a fraction of ``step``) the nearest evaluation may be from ``step``.
    :return: ``metric`` at the evaluation nearest ``step``, or ``None`` when none is within ``tolerance * step``
        (a run that stopped earlier, or evaluated too sparsely to say).
    """
    if not rows:
        return None
    nearest = min(rows, key=lambda row: abs(row["timesteps"] - step))
    return nearest[metric] if abs(nearest["timesteps"] - step) <= tolerance * step else None


def load_summaries(results_dir: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """
    :param results_dir: A results directory (``<experiment>/<scheme>/seed_<seed>/summary.json``).
    :return: The summaries of its finished runs, each with ``"directory"`` (the run's directory), in path order.
    """
    summaries = []
    for path in sorted(Path(results_dir).glob(f"*/*/seed_*/{SUMMARY_FILE}")):
        if not (path.parent / DONE_FILE).exists():
            continue
        summary = read_summary(path.parent)
        if summary is None:
            warnings.warn(
                f"{path} is unreadable (a crash while it was written?): left out; a sweep runs it again.", SB3MADDPGWarning
            )
            continue
        summary["directory"] = str(path.parent)
        summaries.append(summary)
    return summaries


def run_updates(summary: dict[str, Any]) -> int | None:
    """
    :param summary: A finished run's summary.
    :return: The gradient updates its training took (its ``n_updates``), ``None`` where it does not say.
    """
    return None if summary.get("n_updates") is None else int(summary["n_updates"])


def never_updated_warning(run_ids: list[str]) -> str | None:
    """
    :param run_ids: The runs that took no gradient update.
    :return: What to say about them (the cause first, then what to do), or ``None`` when there are none.
    """
    if not run_ids:
        return None
    listed = ", ".join(run_ids[:5]) + (f" and {len(run_ids) - 5} more" if len(run_ids) > 5 else "")
    return (
        f"{len(run_ids)} run(s) never updated (0 gradient steps: the training budget ended before learning_starts): "
        f"{listed}. Their scores are untrained teams', so methods that differ only in training look alike; train for "
        'longer or lower learning_starts (e.g. model_kwargs={"learning_starts": 1000}).'
    )


def write_experiment(results_dir: str | os.PathLike[str], name: str, experiment: dict[str, Any]) -> None:
    """
    :param results_dir: A results directory.
    :param name: The experiment's name.
    :param experiment: Its config as a dict (``ExperimentConfig.to_dict()``), written to ``<name>/experiment.json``
        with the version that wrote it (:func:`~sb3_maddpg.compat.with_version`).
    """
    directory = Path(results_dir) / name
    directory.mkdir(parents=True, exist_ok=True)
    write_json_atomic(directory / EXPERIMENT_FILE, with_version(experiment))


def load_experiments(results_dir: str | os.PathLike[str]) -> dict[str, dict[str, Any]]:
    """
    :param results_dir: A results directory.
    :return: The experiment configs stored in it (``<experiment>/experiment.json``), by name, without the version and
        commit that wrote them (:func:`~sb3_maddpg.compat.read_stored_config`).
    """
    experiments = {}
    for path in sorted(Path(results_dir).glob(f"*/{EXPERIMENT_FILE}")):
        with open(path) as file:
            experiments[path.parent.name] = read_stored_config(json.load(file), str(path))
    return experiments


def unknown_experiments_message(results_dir: str | os.PathLike[str], experiments: Sequence[str]) -> str | None:
    """
    :param results_dir: A results directory.
    :param experiments: Experiment names asked for there.
    :return: Which of them the directory does not hold and which it does, in one line with what to do; ``None`` when it
        holds them all.
    """
    stored = load_experiments(results_dir)
    unknown = [name for name in dict.fromkeys(experiments) if name not in stored]
    if not unknown:
        return None
    if not stored:
        return (
            f"no experiment {', '.join(unknown)} in {results_dir}: it holds no experiment; give the results directory "
            "the sweep of that experiment wrote."
        )
    return (
        f"no experiment {', '.join(unknown)} in {results_dir} (it holds: {', '.join(stored)}): name one of those, or "
        "the results directory the sweep of that experiment wrote."
    )


def _refuse_unknown_experiments(results_dir: str | os.PathLike[str], experiments: Sequence[str]) -> None:
    """:raise ValueError: :func:`unknown_experiments_message`'s, when ``results_dir`` lacks one of ``experiments``."""
    message = unknown_experiments_message(results_dir, experiments)
    if message is not None:
        raise ValueError(message)


def link_experiments(results_dir: str | os.PathLike[str], view: str | os.PathLike[str], experiments: Sequence[str]) -> None:
    """
    Link into ``view`` some of the experiments of a results directory, whole, so that a report reads only them (a
    study's settings, not a learning curve's runs beside them).

    :param results_dir: A results directory.
    :param view: A missing directory, made with one symbolic link (absolute) per experiment into ``results_dir``.
    :param experiments: The experiments' names.
    :raise ValueError: When ``results_dir`` holds no experiment of one of the names (the message says which it holds).
    """
    _refuse_unknown_experiments(results_dir, experiments)
    results, view = Path(results_dir).resolve(), Path(view)
    view.mkdir(parents=True)
    for name in dict.fromkeys(experiments):  # a name given twice is linked once
        (view / name).symlink_to(results / name)


def link_complete_seeds(
    results_dir: str | os.PathLike[str],
    view: str | os.PathLike[str],
    experiments: Sequence[str] | None = None,
    seeds: Collection[int] | None = None,
) -> list[str]:
    """
    Link into ``view`` the runs of the seeds that every scheme of their experiment has finished, so that a sweep in
    progress is reported like with like (the same seeds for every scheme). An experiment with no such seed is left
    out whole.

    :param results_dir: A results directory.
    :param view: An empty or missing directory, filled with ``<experiment>/experiment.json``,
        ``<experiment>/references.json`` where there is one, and ``<experiment>/<scheme>/seed_<seed>`` symbolic links
        (absolute) into ``results_dir``.
    :param experiments: Only these experiments (``None``: every experiment there).
    :param seeds: Only these seeds (``None``: every seed), e.g. a study's first five, to read it as it stood then.
    :return: The finished runs of those seeds left out, ``<experiment>/<scheme>/seed_<seed>``.
    :raise ValueError: When ``results_dir`` holds no experiment of one of ``experiments``' names.
    """
    if experiments is not None:
        _refuse_unknown_experiments(results_dir, experiments)
    results, view = Path(results_dir).resolve(), Path(view)
    left_out = []
    for name, experiment in load_experiments(results).items():
        if experiments is not None and name not in experiments:
            continue
        finished = {
            scheme: {
                run.name
                for run in (results / name / scheme).glob("seed_*")
                if (run / DONE_FILE).exists() and (seeds is None or seed_of(run.name) in seeds)
            }
            for scheme in experiment["schemes"]
        }
        common = set.intersection(*finished.values()) if finished else set()
        left_out += [f"{name}/{scheme}/{seed}" for scheme, seeds in finished.items() for seed in sorted(seeds - common)]
        if not common:
            continue
        (view / name).mkdir(parents=True)
        (view / name / EXPERIMENT_FILE).symlink_to(results / name / EXPERIMENT_FILE)
        if (results / name / REFERENCES_FILE).exists():  # the reference policies, reported on the seeds linked
            (view / name / REFERENCES_FILE).symlink_to(results / name / REFERENCES_FILE)
        for scheme in finished:
            (view / name / scheme).mkdir()
            for seed in sorted(common):
                (view / name / scheme / seed).symlink_to(results / name / scheme / seed)
    return left_out


def seed_of(run_name: str) -> int | None:
    """:return: The seed of a run directory's name (``seed_003``: 3), ``None`` for another name."""
    try:
        return int(run_name.removeprefix("seed_"))
    except ValueError:
        return None


class ResultsDirectoryLocked(RuntimeError):
    """Another sweep is running in the results directory."""


@contextlib.contextmanager
def lock_results(results_dir: str | os.PathLike[str]) -> Iterator[None]:
    """
    Hold the results directory for one sweep: an exclusive ``flock`` on ``<results>/sweep.lock``, which names this
    process. The operating system releases it when the process ends, however it ends, so a killed sweep leaves no
    stale lock behind. (Without ``fcntl``, i.e. on Windows, nothing is locked.)

    :param results_dir: The results directory (created if needed).
    :raise ResultsDirectoryLocked: When another sweep holds it (the message names its PID and command).
    """
    path = Path(results_dir) / LOCK_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a+") as file:
        if fcntl is not None:
            try:
                fcntl.flock(file, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                file.seek(0)
                raise ResultsDirectoryLocked(_locked_message(Path(results_dir), file.read())) from None
        file.seek(0)
        file.truncate()
        holder = {"pid": os.getpid(), "started": time.strftime("%Y-%m-%d %H:%M:%S"), "command": " ".join(sys.argv)}
        file.write(json.dumps(holder) + "\n")
        file.flush()
        try:
            yield
        finally:
            file.seek(0)
            file.truncate()  # closing the file releases the lock


def _locked_message(results_dir: Path, holder_text: str) -> str:
    try:
        holder = json.loads(holder_text)
        who = f"PID {holder['pid']}, started {holder['started']}: {holder['command']}"
        stop = f"stop it (kill {holder['pid']}, or Ctrl-C in its terminal; the same command resumes it)"
    except (ValueError, KeyError, TypeError):
        who, stop = "PID unknown", "stop it"
    return (
        f"{results_dir} is in use by another sweep ({who}). Two sweeps in one results directory would run the "
        f"same runs at once. Wait for that sweep to end, {stop}, or give this one another results directory."
    )
