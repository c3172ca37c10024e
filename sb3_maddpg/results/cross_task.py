"""
Which information helps, task by task: each task's schemes on one scale and against ``full``.

Per task (a setting of a results directory and one of its metrics), each run's score is normalised: 0 is random
actions, 1 the better of the task's scripted reference (where it has one: simple_spread's controller) and its best
scheme (the mean of its runs), so that 1 is the best the table has seen on that task. Only the seeds that every scheme
of the setting has finished count (like with like, while a sweep is running). A scheme's cell is its runs' mean
normalised score with a 95% t interval, and its verdict against ``full``: an exact Mann-Whitney U test on the raw
metric, Holm-adjusted within the task (one family: each scheme against ``full``); "above" or "below" only where the
adjusted p is below .05, otherwise "not separated" with the raw p.
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sb3_maddpg.experiments.config import BASELINE_SCHEME, ordered_schemes
from sb3_maddpg.experiments.defaults import DEFAULT_ENV
from sb3_maddpg.experiments.results_dir import load_experiments, load_summaries
from sb3_maddpg.experiments.tasks import metric_info, recorded_metrics
from sb3_maddpg.results.aggregates import mean_difference_interval
from sb3_maddpg.results.claims import format_p_value
from sb3_maddpg.results.normalised_table import setting_references
from sb3_maddpg.results.reference_table import load_references
from sb3_maddpg.results.stats import holm, mann_whitney

LEVEL = 0.05
"""The family-wise level a verdict needs its Holm-adjusted p below."""


@dataclass(frozen=True)
class TaskStudy:
    """
    One row of the table: a setting of a results directory, read by one metric.

    :param label: The task as the table names it.
    :param results_dir: The results directory (``<experiment>/<scheme>/seed_<seed>/summary.json``).
    :param experiment: The setting's name in it.
    :param metric: The score compared (a key of the runs' ``score``).
    """

    label: str
    results_dir: Path
    experiment: str
    metric: str


@dataclass
class TaskRow:
    """
    One task's normalised scores and verdicts.

    :param study: The task.
    :param seeds: The seeds every scheme has finished (the runs read).
    :param label: The metric as the task shows it, with its direction (``"evaders caught, higher is better"``).
    :param random: Random actions' score on the metric (0 on the table's scale).
    :param top: The score that is 1 on the table's scale.
    :param top_is: What ``top`` is: ``"scripted controller"`` or ``"best scheme (<name>)"``.
    :param cells: Per scheme: ``mean``, ``low``, ``high`` (normalised), ``raw`` (the metric's mean), and, but for
        ``full``, ``p`` and ``p_holm`` against ``full`` and ``verdict``.
    """

    study: TaskStudy
    seeds: list[int]
    label: str = ""
    random: float = math.nan
    top: float = math.nan
    top_is: str = ""
    cells: dict[str, dict[str, Any]] = field(default_factory=dict)


def complete_seed_scores(
    summaries: Sequence[dict[str, Any]], experiment: str, schemes: Sequence[str], metric: str
) -> dict[str, dict[int, float]]:
    """
    :param summaries: Run summaries (``experiment``, ``scheme``, ``seed``, ``score``).
    :param experiment: The setting.
    :param schemes: The setting's schemes (its stored config's): a seed counts once every one has finished it.
    :param metric: The score read.
    :return: Per scheme, the metric by seed, on the seeds that every scheme of the setting has finished.
    """
    by_scheme: dict[str, dict[int, float]] = {scheme: {} for scheme in schemes}
    for summary in summaries:
        if summary["experiment"] == experiment and summary["scheme"] in by_scheme:
            by_scheme[summary["scheme"]][int(summary["seed"])] = float(summary["score"][metric])
    common = set.intersection(*(set(seeds) for seeds in by_scheme.values())) if by_scheme else set()
    return {scheme: {seed: by_scheme[scheme][seed] for seed in sorted(common)} for scheme in ordered_schemes(by_scheme)}


def random_and_scripted(study: TaskStudy, seeds: Sequence[int]) -> tuple[float, float | None]:
    """
    :param study: The task.
    :param seeds: The seeds read.
    :return: Random actions' score on the metric and the scripted controller's (``None`` without one): simple_spread's
        measured references, or the random policy the setting evaluated beside its runs (``references.json``, the mean
        over ``seeds``).
    """
    references = setting_references(load_experiments(study.results_dir).get(study.experiment))
    if references is not None:
        return float(references["random"][study.metric]), float(references["scripted"][study.metric])
    stored = load_references(study.results_dir).get(study.experiment, {}).get("random")
    if stored is None:
        raise ValueError(
            f"{study.label}: no random reference for {study.experiment!r} in {study.results_dir}: run it with "
            "reference_policies: {random: {kind: random}} (sb3-maddpg run evaluates it beside the runs)."
        )
    return float(np.mean([stored["seeds"][str(seed)]["score"][study.metric] for seed in seeds])), None


def task_row(study: TaskStudy) -> TaskRow:
    """:return: The task's row (no cells where no seed is finished by every scheme)."""
    stored = load_experiments(study.results_dir).get(study.experiment)
    if stored is None:
        raise ValueError(f"{study.label}: no experiment {study.experiment!r} in {study.results_dir}: run it first.")
    summaries = load_summaries(study.results_dir)
    scores = complete_seed_scores(summaries, study.experiment, stored["schemes"], study.metric)
    seeds = sorted(next(iter(scores.values()), {}))
    runs = [summary for summary in summaries if summary["experiment"] == study.experiment]
    declared = recorded_metrics(runs[0].get("task_metrics")) if runs else None  # the direction the task's env declares
    info = metric_info(study.metric, stored.get("env", DEFAULT_ENV), declared)
    higher = info.higher_is_better
    row = TaskRow(study, seeds, f"{info.label}, {'higher' if higher else 'lower'} is better")
    if not seeds:
        return row
    row.random, scripted = random_and_scripted(study, seeds)
    means = {scheme: float(np.mean(list(values.values()))) for scheme, values in scores.items()}
    best = max(means, key=lambda scheme: means[scheme] if higher else -means[scheme])
    candidates = [(means[best], f"best scheme ({best})")] + ([] if scripted is None else [(scripted, "scripted controller")])
    row.top, row.top_is = max(candidates, key=lambda item: item[0] if higher else -item[0])
    if (row.top - row.random) * (1 if higher else -1) <= 0:  # no scale from random to better: a row without cells
        row.top_is = f"nothing beats random actions yet ({row.random:.3g})"
        return row
    for scheme, values in scores.items():
        normalised = [(value - row.random) / (row.top - row.random) for value in values.values()]
        estimate = mean_difference_interval([normalised])
        row.cells[scheme] = {"mean": estimate.value, "low": estimate.low, "high": estimate.high, "raw": means[scheme]}
    tested = [scheme for scheme in scores if scheme != BASELINE_SCHEME] if BASELINE_SCHEME in scores else []
    raw = [mann_whitney(list(scores[scheme].values()), list(scores[BASELINE_SCHEME].values()))[1] for scheme in tested]
    for scheme, p_value, adjusted in zip(tested, raw, holm(raw)):
        above = (means[scheme] > means[BASELINE_SCHEME]) == higher  # the raw metric's own direction
        verdict = ("above" if above else "below") if adjusted < LEVEL else "not separated"
        row.cells[scheme].update(p=float(p_value), p_holm=float(adjusted), verdict=verdict)
    return row


def row_data(row: TaskRow) -> dict[str, Any]:
    """:return: The row as JSON values (rounded as the table shows them, so that a test compares what is read)."""

    def rounded(value: Any) -> Any:
        if isinstance(value, float):
            return round(value, 4) if math.isfinite(value) else None  # strict JSON; nan where no seed is complete
        return value

    return {
        "task": row.study.label,
        "experiment": row.study.experiment,
        "metric": row.study.metric,
        "label": row.label,
        "seeds": row.seeds,
        "random": rounded(row.random),
        "top": rounded(row.top),
        "top_is": row.top_is,
        "cells": {scheme: {key: rounded(value) for key, value in cell.items()} for scheme, cell in row.cells.items()},
    }


def format_cell(cell: Mapping[str, Any] | None) -> str:
    """:return: ``"0.62 [0.51, 0.70]"``, and against ``full`` its verdict and p (``"below, p = .008 (Holm = .040)"``)."""
    if cell is None:
        return "-"
    interval = "" if math.isnan(cell["low"]) else f" [{cell['low']:.2f}, {cell['high']:.2f}]"
    text = f"{cell['mean']:.2f}{interval}"
    if "verdict" in cell:
        text += f"; {cell['verdict']}, p {_p_text(cell['p'])} (Holm {_p_text(cell['p_holm'])})"
    return text


def _p_text(p_value: float) -> str:
    """
    :param p_value: A p-value.
    :return: ``= .008`` for 0.0079, ``< .001`` below .001: as the claims pages and the README print it.
    """
    text = format_p_value(p_value)
    return text if text.startswith("<") else "= " + text


def format_table_rst(rows: Sequence[TaskRow], schemes: Sequence[str]) -> str:
    """:return: The rows as an RST ``list-table``: a task per row, a scheme per column."""
    header = ["task (metric; 1 =)", "seeds", *schemes]
    lines = [".. list-table::", "   :header-rows: 1", "", "   * - " + "\n     - ".join(header)]
    for row in rows:
        task = f"{row.study.label} ({row.label}; 1 = {row.top_is or 'no complete seed yet'})"
        cells = [format_cell(row.cells.get(scheme)) for scheme in schemes]
        lines.append("   * - " + "\n     - ".join([task, str(len(row.seeds)), *cells]))
    return "\n".join(lines) + "\n"
