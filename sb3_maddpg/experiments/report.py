"""The report of a results directory: Table 2 and aggregate estimates as Markdown and CSV, learning curves and boxplots."""

import csv
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sb3_maddpg.experiments.aggregates import improvement_interval, iqm_interval
from sb3_maddpg.experiments.config import BASELINE_SCHEME, PAPER_NAMES, ordered_schemes, setting_label
from sb3_maddpg.experiments.normalised_table import format_normalised_markdown
from sb3_maddpg.experiments.results import load_experiments, load_summaries
from sb3_maddpg.experiments.stats import METRICS, Cell, Metric, aggregate


def _number(value: float, digits: int = 2) -> str:
    return "nan" if math.isnan(value) else f"{value:.{digits}f}"


def format_markdown(
    cells: Sequence[Cell], metric: str, experiments: dict[str, dict[str, Any]] | None = None, baseline: str = BASELINE_SCHEME
) -> str:
    """
    Table 2's layout: a row per setting, a column per method, ``mean (std)`` of the per-run scores with
    the significance marks of the Mann-Whitney U test against the baseline; then the p-values.

    :param cells: From :func:`~sb3_maddpg.experiments.stats.aggregate`.
    :param metric: The score's key.
    :param experiments: The stored experiment configs (for row labels).
    :param baseline: The scheme tested against.
    :return: Markdown text.
    """
    info = METRICS.get(metric, Metric(metric, metric))
    experiments = experiments or {}
    settings = list(dict.fromkeys(cell.setting for cell in cells))
    schemes = ordered_schemes(cell.scheme for cell in cells)
    by_key = {(cell.setting, cell.scheme): cell for cell in cells}
    header = ["setting", *(PAPER_NAMES.get(scheme, scheme) for scheme in schemes)]
    lines = [
        f"### Score: {info.label}, mean (std) over runs",
        "",
        "| " + " | ".join(header) + " |",
        "|" + "|".join("---" for _ in header) + "|",
    ]
    p_lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    run_counts = set()
    for setting in settings:
        row, p_row = [setting_label(setting, experiments.get(setting))], [setting]
        for scheme in schemes:
            cell = by_key.get((setting, scheme))
            if cell is None:
                row.append("")
                p_row.append("")
                continue
            run_counts.add(cell.n)
            row.append(f"{_number(cell.mean)} ({_number(cell.std)}){' ' + cell.stars if cell.stars else ''}")
            p_row.append(
                "baseline" if scheme == baseline else f"{_number(cell.p_value, 4)} (U={_number(cell.u_statistic, 1)})"
            )
        lines.append("| " + " | ".join(row) + " |")
        p_lines.append("| " + " | ".join(p_row) + " |")
    direction = "higher" if info.higher_is_better else "lower"
    counts = ", ".join(str(n) for n in sorted(run_counts))
    lines += [
        "",
        f"Each run's score is the mean {info.label} of the models saved over the last part of training "
        f"({direction} is better); runs per cell: {counts}. `*` p < .05, `**` p < .01: two-sided Mann-Whitney U "
        f"test of the method's per-run scores against {PAPER_NAMES.get(baseline, baseline)}'s (`scipy.stats.mannwhitneyu`).",
        "",
        f"p-values (U statistic) against {PAPER_NAMES.get(baseline, baseline)}:",
        "",
        *p_lines,
        "",
    ]
    return "\n".join(lines)


def write_csv(cells: Sequence[Cell], metric: str, path: str | os.PathLike[str]) -> None:
    """
    One row per setting and method: ``setting, scheme, method, metric, n, mean, std, u_statistic,
    p_value, stars, scores`` (scores in displayed units, ``;``-separated in seed order).

    :param cells: From :func:`~sb3_maddpg.experiments.stats.aggregate`.
    :param metric: The score's key.
    :param path: The CSV file.
    """
    fields = ["setting", "scheme", "method", "metric", "n", "mean", "std", "u_statistic", "p_value", "stars", "scores"]
    with open(path, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(fields)
        for cell in cells:
            writer.writerow(
                [
                    cell.setting,
                    cell.scheme,
                    cell.method,
                    metric,
                    cell.n,
                    repr(cell.mean),
                    repr(cell.std),
                    "" if math.isnan(cell.u_statistic) else repr(cell.u_statistic),
                    "" if math.isnan(cell.p_value) else repr(cell.p_value),
                    cell.stars,
                    ";".join(repr(score) for score in cell.scores),
                ]
            )


def aggregate_estimates(cells: Sequence[Cell], metric: str, baseline: str = BASELINE_SCHEME) -> list[dict[str, Any]]:
    """
    Per setting and method, and over all settings together (stratified by setting) when there are several: the IQM
    of the per-run scores and the probability that a run of the method beats a run of the baseline, each with a 95%
    stratified bootstrap interval (see :mod:`~sb3_maddpg.experiments.aggregates`). "Beats" follows the metric's
    direction (a lower ``min_dist_sum`` is better).

    :param cells: From :func:`~sb3_maddpg.experiments.stats.aggregate`.
    :param metric: The score's key (for its direction).
    :param baseline: The scheme compared against.
    :return: Rows with ``setting`` (``"all"`` for the stratified aggregate), ``scheme``, ``method``, ``n``, ``mean``,
        ``iqm`` and ``improvement`` (:class:`~sb3_maddpg.experiments.aggregates.IntervalEstimate`; ``None`` for the
        baseline).
    """
    sign = 1.0 if METRICS.get(metric, Metric(metric, metric)).higher_is_better else -1.0
    by_key = {(cell.setting, cell.scheme): cell for cell in cells}
    settings = list(dict.fromkeys(cell.setting for cell in cells))
    groups = [[setting] for setting in settings] + ([settings] if len(settings) > 1 else [])
    rows = []
    for group in groups:
        for scheme in ordered_schemes(cell.scheme for cell in cells if cell.setting in group):
            if not all((setting, scheme) in by_key for setting in group):
                continue  # a method missing in one setting has no stratified aggregate
            strata = [by_key[setting, scheme].scores for setting in group]
            reference = [by_key[setting, baseline].scores for setting in group if (setting, baseline) in by_key]
            improvement = None
            if scheme != baseline and len(reference) == len(group):
                improvement = improvement_interval(
                    [np.multiply(sign, stratum) for stratum in strata], [np.multiply(sign, ref) for ref in reference]
                )
            rows.append(
                {
                    "setting": group[0] if len(group) == 1 else "all",
                    "scheme": scheme,
                    "method": PAPER_NAMES.get(scheme, scheme),
                    "n": sum(len(stratum) for stratum in strata),
                    "mean": float(np.mean(np.concatenate([np.asarray(s, dtype=float) for s in strata]))),
                    "iqm": iqm_interval(strata),
                    "improvement": improvement,
                }
            )
    return rows


def format_aggregates_markdown(
    rows: Sequence[dict[str, Any]],
    metric: str,
    experiments: dict[str, dict[str, Any]] | None = None,
    baseline: str = BASELINE_SCHEME,
) -> str:
    """
    :param rows: From :func:`aggregate_estimates`.
    :param metric: The score's key.
    :param experiments: The stored experiment configs (for setting labels).
    :param baseline: The scheme compared against.
    :return: Markdown: a row per setting and method, IQM [95% CI], mean, and P(better than the baseline) [95% CI].
    """
    info = METRICS.get(metric, Metric(metric, metric))
    baseline_name = PAPER_NAMES.get(baseline, baseline)
    lines = [
        f"### Aggregates: {info.label}, interquartile mean and probability of improvement over {baseline_name}",
        "",
        f"| setting | method | runs | IQM [95% CI] | mean | P(better than {baseline_name}) [95% CI] |",
        "|---|---|---|---|---|---|",
    ]
    for row in rows:
        label = (
            "all settings (stratified)"
            if row["setting"] == "all"
            else setting_label(row["setting"], (experiments or {}).get(row["setting"]))
        )
        if row["improvement"] is not None:
            improvement = row["improvement"].format(2)
        else:
            improvement = "baseline" if row["scheme"] == baseline else f"n/a (no {baseline_name} runs)"
        lines.append(
            f"| {label} | {row['method']} | {row['n']} | {row['iqm'].format(2)} | {_number(row['mean'])} | {improvement} |"
        )
    direction = "higher" if info.higher_is_better else "lower"
    lines += [
        "",
        f"Each run's score is its mean {info.label} over the checkpoints of the last part of training ({direction} is "
        "better). IQM: mean of the middle 50% of the runs' scores. P(better): the chance that a random run of the "
        f"method scores better than a random run of {baseline_name} (ties count half; 0.5: no difference), averaged "
        "over settings. Intervals: 95% stratified bootstrap (percentile, runs resampled within each setting and "
        "method; `scipy.stats.bootstrap`), as in Agarwal et al. (2021). An interval of P(better) that excludes 0.5 "
        f"says the method and {baseline_name} differ at this number of runs.",
        "",
    ]
    return "\n".join(lines)


def write_aggregates_csv(rows: Sequence[dict[str, Any]], metric: str, path: str | os.PathLike[str]) -> None:
    """
    One row per setting (``all``: every setting, stratified) and method: ``setting, scheme, method, metric, n, mean,
    iqm, iqm_low, iqm_high, improvement, improvement_low, improvement_high`` (empty improvement for the baseline).

    :param rows: From :func:`aggregate_estimates`.
    :param metric: The score's key.
    :param path: The CSV file.
    """
    fields = ["setting", "scheme", "method", "metric", "n", "mean", "iqm", "iqm_low", "iqm_high"]
    fields += ["improvement", "improvement_low", "improvement_high"]
    with open(path, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(fields)
        for row in rows:
            iqm, improvement = row["iqm"], row["improvement"]
            estimates = [iqm.value, iqm.low, iqm.high]
            estimates += ["", "", ""] if improvement is None else [improvement.value, improvement.low, improvement.high]
            writer.writerow(
                [row["setting"], row["scheme"], row["method"], metric, row["n"], repr(row["mean"])]
                + [value if value == "" else repr(value) for value in estimates]
            )


DEFAULT_REPORT_METRICS = ("success_rate", "min_dist_sum")
"""What a report shows unless told: simple_spread's success (higher is better; near 0 early in training) and its
min-dist sum (lower is better; informative at every scale). Other tasks: the team return."""


def default_metrics(score: dict[str, float]) -> list[str]:
    """
    :param score: One run's score.
    :return: The metrics of :data:`DEFAULT_REPORT_METRICS` the run has (not NaN), or ``["return_mean"]``.
    """
    present = [metric for metric in DEFAULT_REPORT_METRICS if not math.isnan(score.get(metric, math.nan))]
    return present or ["return_mean"]


def make_report(
    results_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    metrics: Sequence[str] | None = None,
    plots: bool = True,
    baseline: str = BASELINE_SCHEME,
) -> list[Path]:
    """
    Write, for each metric, ``table_<metric>.md`` and ``table_<metric>.csv`` (Table 2: mean (std), Mann-Whitney U),
    ``aggregates_<metric>.md`` and ``aggregates_<metric>.csv`` (IQM and probability of improvement with 95%
    bootstrap intervals), ``normalised.md`` for simple_spread settings (min-dist sum and team return between the
    random team, 0, and the scripted controller, 1) and, with ``plots``, ``learning_curves_<metric>.png`` (IQM over
    runs with a 95% bootstrap band, vs env steps) and ``boxplot_<metric>.png`` (per-run scores, like the paper's
    Figures 7 and 8).

    :param results_dir: The results directory of a sweep.
    :param out_dir: Where to write the report.
    :param metrics: The scores to report (see :data:`~sb3_maddpg.experiments.stats.METRICS`); ``None``: those of
        :func:`default_metrics`.
    :param plots: Also draw the figures (needs matplotlib).
    :param baseline: The scheme the others are tested against.
    :return: The files written.
    """
    summaries = load_summaries(results_dir)
    if not summaries:
        raise FileNotFoundError(f"No finished runs under {results_dir} (expected <experiment>/<scheme>/seed_*/summary.json).")
    if metrics is None:
        metrics = default_metrics(summaries[0]["score"])
    unknown = [metric for metric in metrics if metric not in summaries[0]["score"]]
    if unknown:
        raise ValueError(
            f"Unknown metric(s) {unknown}: the runs in {results_dir} score {sorted(summaries[0]['score'])} (runs written "
            "before 0.2 have no success or coverage at other radii); pick --metric among those."
        )
    experiments = load_experiments(results_dir)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for metric in metrics:
        cells = aggregate(summaries, metric, baseline=baseline)
        markdown_path, csv_path = out / f"table_{metric}.md", out / f"table_{metric}.csv"
        markdown_path.write_text(format_markdown(cells, metric, experiments, baseline=baseline))
        write_csv(cells, metric, csv_path)
        estimates = aggregate_estimates(cells, metric, baseline=baseline)
        aggregates_md, aggregates_csv = out / f"aggregates_{metric}.md", out / f"aggregates_{metric}.csv"
        aggregates_md.write_text(format_aggregates_markdown(estimates, metric, experiments, baseline=baseline))
        write_aggregates_csv(estimates, metric, aggregates_csv)
        written += [markdown_path, csv_path, aggregates_md, aggregates_csv]
        if plots:
            from sb3_maddpg.experiments.plots import plot_boxplots, plot_learning_curves

            curve_path, box_path = out / f"learning_curves_{metric}.png", out / f"boxplot_{metric}.png"
            plot_learning_curves(summaries, metric, curve_path, experiments)
            plot_boxplots(cells, metric, box_path, experiments)
            written += [curve_path, box_path]
    normalised = format_normalised_markdown(summaries, experiments)
    if normalised is not None:
        (out / "normalised.md").write_text(normalised)
        written.append(out / "normalised.md")
    return written
