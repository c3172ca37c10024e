"""The report of a results directory: Table 2 as Markdown and CSV, learning curves and boxplots."""

import csv
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sb3_maddpg.experiments.config import BASELINE_SCHEME, PAPER_NAMES, ordered_schemes, setting_label
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


def make_report(
    results_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    metrics: Sequence[str] = ("success_rate",),
    plots: bool = True,
    baseline: str = BASELINE_SCHEME,
) -> list[Path]:
    """
    Write, for each metric, ``table_<metric>.md`` and ``table_<metric>.csv`` (Table 2) and, with ``plots``,
    ``learning_curves_<metric>.png`` (mean with a std band over runs, vs env steps) and
    ``boxplot_<metric>.png`` (per-run scores, like the paper's Figures 7 and 8).

    :param results_dir: The results directory of a sweep.
    :param out_dir: Where to write the report.
    :param metrics: The scores to report (see :data:`~sb3_maddpg.experiments.stats.METRICS`).
    :param plots: Also draw the figures (needs matplotlib).
    :param baseline: The scheme the others are tested against.
    :return: The files written.
    """
    summaries = load_summaries(results_dir)
    if not summaries:
        raise FileNotFoundError(f"No finished runs under {results_dir} (expected <experiment>/<scheme>/seed_*/summary.json).")
    unknown = [metric for metric in metrics if metric not in summaries[0]["score"]]
    if unknown:
        raise ValueError(f"Unknown metric(s) {unknown}; the runs have {sorted(summaries[0]['score'])}.")
    experiments = load_experiments(results_dir)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for metric in metrics:
        cells = aggregate(summaries, metric, baseline=baseline)
        markdown_path, csv_path = out / f"table_{metric}.md", out / f"table_{metric}.csv"
        markdown_path.write_text(format_markdown(cells, metric, experiments, baseline=baseline))
        write_csv(cells, metric, csv_path)
        written += [markdown_path, csv_path]
        if plots:
            from sb3_maddpg.experiments.plots import plot_boxplots, plot_learning_curves

            curve_path, box_path = out / f"learning_curves_{metric}.png", out / f"boxplot_{metric}.png"
            plot_learning_curves(summaries, metric, curve_path, experiments)
            plot_boxplots(cells, metric, box_path, experiments)
            written += [curve_path, box_path]
    return written
