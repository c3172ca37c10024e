"""The results directory: its file names, and the functions that find, read and write them.

Layout: ``<results>/sweep.log``, ``<results>/<experiment>/experiment.json`` and one directory per run,
``<results>/<experiment>/<scheme>/seed_<seed>/``, holding the files below; ``done`` is written last.
"""

import csv
import json
import os
import time
from pathlib import Path
from typing import Any

from sb3_maddpg.experiments.config import RunConfig

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
SWEEP_LOG = "sweep.log"
"""The sweeps' progress lines, in ``<results>/``."""


def run_directory(results_dir: str | os.PathLike[str], config: RunConfig) -> Path:
    """
    :param results_dir: The sweep's results directory.
    :param config: The run.
    :return: The run's directory, ``<results_dir>/<experiment>/<scheme>/seed_<seed>``.
    """
    return Path(results_dir) / config.run_id


def is_finished(results_dir: str | os.PathLike[str], config: RunConfig) -> bool:
    """
    Whether the run has finished in ``results_dir``: its ``done`` marker exists (it is written last).

    :param results_dir: The sweep's results directory.
    :param config: The run.
    :return: True if the run is finished; a finished run with another config is an error.
    """
    directory = run_directory(results_dir, config)
    if not (directory / DONE_FILE).exists():
        return False
    with open(directory / CONFIG_FILE) as file:
        stored = RunConfig.from_dict(json.load(file))
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
    path = Path(directory) / DONE_FILE
    tmp_path = path.with_name(f"{DONE_FILE}.tmp")
    tmp_path.write_text(time.strftime("%Y-%m-%dT%H:%M:%S%z\n"))
    os.replace(tmp_path, path)


def collect_result(directory: str | os.PathLike[str]) -> dict[str, Any]:
    """
    :param directory: A finished run's directory.
    :return: Its summary, with ``"files"``: the text of its result files.
    """
    directory = Path(directory)
    with open(directory / SUMMARY_FILE) as file:
        result = json.load(file)
    result["files"] = {name: (directory / name).read_text() for name in RESULT_FILES if (directory / name).exists()}
    return result


def write_result_files(results_dir: str | os.PathLike[str], result: dict[str, Any]) -> None:
    """
    Write a run's result files (from :func:`~sb3_maddpg.experiments.runner.execute_run` on another machine)
    unless the run is already finished there, then its ``done`` marker.

    :param results_dir: The sweep's results directory on this machine.
    :param result: The value ``execute_run`` returned.
    """
    directory = Path(results_dir) / result["run_id"]
    if (directory / DONE_FILE).exists():
        return
    directory.mkdir(parents=True, exist_ok=True)
    for name, text in result["files"].items():
        (directory / name).write_text(text)
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


def load_summaries(results_dir: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """
    :param results_dir: A results directory (``<experiment>/<scheme>/seed_<seed>/summary.json``).
    :return: The summaries of its finished runs, each with ``"directory"`` (the run's directory), in path order.
    """
    summaries = []
    for path in sorted(Path(results_dir).glob(f"*/*/seed_*/{SUMMARY_FILE}")):
        if not (path.parent / DONE_FILE).exists():
            continue
        with open(path) as file:
            summary = json.load(file)
        summary["directory"] = str(path.parent)
        summaries.append(summary)
    return summaries


def write_experiment(results_dir: str | os.PathLike[str], name: str, experiment: dict[str, Any]) -> None:
    """
    :param results_dir: A results directory.
    :param name: The experiment's name.
    :param experiment: Its config as a dict (``ExperimentConfig.to_dict()``), written to ``<name>/experiment.json``.
    """
    directory = Path(results_dir) / name
    directory.mkdir(parents=True, exist_ok=True)
    with open(directory / EXPERIMENT_FILE, "w") as file:
        json.dump(experiment, file, indent=2)


def load_experiments(results_dir: str | os.PathLike[str]) -> dict[str, dict[str, Any]]:
    """
    :param results_dir: A results directory.
    :return: The experiment configs stored in it (``<experiment>/experiment.json``), by name.
    """
    experiments = {}
    for path in sorted(Path(results_dir).glob(f"*/{EXPERIMENT_FILE}")):
        with open(path) as file:
            experiments[path.parent.name] = json.load(file)
    return experiments
