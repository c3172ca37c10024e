"""A results directory as marl-eval's JSON, the raw-data format that marl-eval's tools read and BenchMARL and Mava write.

The schema is marl-eval's "Data Structure for Raw Experiment data" (the README of
https://github.com/instadeepai/marl-eval) as its ``JsonLogger`` writes it (``marl_eval/json_tools/json_logger.py``,
adapted from BenchMARL's)::

    {"<env>": {"<task>": {"<algorithm>": {"seed_<seed>": {
        "step_0": {"step_count": <int>, "<metric>": [<float>, ...], ...},
        ...
        "step_<k>": {...},
        "absolute_metrics": {"<metric>": [<float>, ...], ...}
    }}}}}

marl-eval's ``data_process_pipeline`` takes the mean of every list but ``step_count``, and its
``create_matrices_for_rliable`` reads the final scores from each run's last entry, ``absolute_metrics``; its
``DiagnoseData`` checks that every task has the same algorithms, every algorithm the same number of runs, every run the
same number of steps and every step the same metrics, and lower-cases task and metric names.

How a results directory fills it:

- ``<env>``: ``"mpe"`` for an MPE task (simple_spread among them), else the experiment's ``env``;
- ``<task>``: the setting, the experiment's name (a row of Table 2), in lower case;
- ``<algorithm>``: the method as the tables name it (``MADDPG``, ``IDDPG``, ``MADDPG-fo``, ...), or
  ``"<Algorithm> (<scheme>)"`` for an experiment of another algorithm (``MATD3 (full)``);
- ``seed_<seed>``: a run;
- ``step_<k>``: the run's k-th evaluation during training (``learning_curve.csv``; its checkpoints' evaluations when it
  has no learning curve), ``step_count`` its env steps. Each metric is a one-element list, the evaluation's mean over
  its episodes (the results keep no per-episode values; marl-eval's own ``JsonLogger`` writes one-element lists too);
- ``absolute_metrics``: each metric's evaluations of the run's checkpoints (``checkpoint_evals.csv``), one per
  checkpoint, so that their mean is the run's score in ``summary.json``.

The metrics are the runs' evaluation keys, with ``return_mean`` named ``return`` (marl-eval's name for the episode
return) and ``return_std`` left out; a setting keeps the metrics that every evaluation of every one of its runs scored
(a metric that does not apply, NaN in the results, is left out), so the file is strict JSON.
"""

import csv
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sb3_maddpg.experiments.config import PAPER_NAMES
from sb3_maddpg.experiments.defaults import DEFAULT_ALGORITHM, DEFAULT_ENV
from sb3_maddpg.experiments.results_dir import (
    CHECKPOINT_EVALS_FILE,
    CURVE_FILE,
    load_experiments,
    load_summaries,
    write_json_atomic,
)

MARL_EVAL_FILE = "marl_eval.json"
"""The marl-eval file that :func:`~sb3_maddpg.results.report.make_report` writes beside the tables."""

ABSOLUTE_METRICS = "absolute_metrics"
"""A run's last entry in marl-eval's JSON: its final scores."""

NOT_METRICS = ("timesteps", "episodes", "return_std")
"""Columns of the evaluation files that are not per-episode metrics."""

RENAMED = {"return_mean": "return"}
"""Metrics under marl-eval's names."""


def _rows(path: Path) -> list[dict[str, float]]:
    """The rows of an evaluation CSV file as floats (``nan`` for a metric that does not apply); empty if missing."""
    if not path.exists():
        return []
    with open(path, newline="") as file:
        return [{key: float(value) if value else math.nan for key, value in row.items()} for row in csv.DictReader(file)]


def _finite_metrics(rows: Sequence[dict[str, float]]) -> set[str]:
    """The metrics every row scores (finite)."""
    keys = set(rows[0]) - set(NOT_METRICS) if rows else set()
    return {key for key in keys if all(math.isfinite(row.get(key, math.nan)) for row in rows)}


def _algorithm_name(scheme: str, experiment: dict[str, Any]) -> str:
    algorithm = experiment.get("algorithm", DEFAULT_ALGORITHM)
    if algorithm == DEFAULT_ALGORITHM:
        return PAPER_NAMES.get(scheme, scheme)
    return f"{algorithm.rpartition(':')[2]} ({scheme})"


def _env_name(experiment: dict[str, Any]) -> str:
    from sb3_maddpg.envs import MPE_TASKS

    env = str(experiment.get("env", DEFAULT_ENV))
    return "mpe" if env in MPE_TASKS else env.lower()


def marl_eval_data(results_dir: str | os.PathLike[str]) -> dict[str, Any]:
    """
    :param results_dir: A results directory (its finished runs are read).
    :return: Its runs in marl-eval's raw-data format (see the module's description); empty when no run is finished.
    """
    summaries = load_summaries(results_dir)
    experiments = load_experiments(results_dir)
    data: dict[str, Any] = {}
    for setting in dict.fromkeys(summary["experiment"] for summary in summaries):
        experiment = experiments.get(setting) or {}
        runs = [summary for summary in summaries if summary["experiment"] == setting]
        evaluations = {}
        for summary in runs:
            directory = Path(summary["directory"])
            checkpoints = _rows(directory / CHECKPOINT_EVALS_FILE)
            evaluations[summary["run_id"]] = (_rows(directory / CURVE_FILE) or checkpoints, checkpoints)
        metrics = sorted(set.intersection(*(_finite_metrics([*steps, *last]) for steps, last in evaluations.values())))
        task = data.setdefault(_env_name(experiment), {}).setdefault(setting.lower(), {})
        for summary in sorted(runs, key=lambda summary: (summary["scheme"], int(summary["seed"]))):
            steps, checkpoints = evaluations[summary["run_id"]]
            run: dict[str, Any] = {
                f"step_{index}": {
                    "step_count": int(row["timesteps"]),
                    **{RENAMED.get(metric, metric): [row[metric]] for metric in metrics},
                }
                for index, row in enumerate(steps)
            }
            run[ABSOLUTE_METRICS] = {
                RENAMED.get(metric, metric): [row[metric] for row in checkpoints]
                if checkpoints
                else [float(summary["score"][metric])]
                for metric in metrics
            }
            algorithm = task.setdefault(_algorithm_name(summary["scheme"], experiment), {})
            algorithm[f"seed_{int(summary['seed'])}"] = run
    return data


def write_marl_eval(results_dir: str | os.PathLike[str], path: str | os.PathLike[str]) -> Path:
    """
    Write a results directory's runs as marl-eval's JSON (strict JSON, written whole or not at all).

    :param results_dir: A results directory.
    :param path: The JSON file (e.g. ``<report>/marl_eval.json``).
    :return: The file written.
    :raise FileNotFoundError: When no run in ``results_dir`` is finished.
    """
    data = marl_eval_data(results_dir)
    if not data:
        raise FileNotFoundError(f"No finished runs under {results_dir}: nothing to write to {path}.")
    write_json_atomic(path, data)
    return Path(path)
