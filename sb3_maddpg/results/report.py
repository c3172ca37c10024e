"""The report of a results directory: Table 2 and aggregate estimates as Markdown and CSV, learning curves and boxplots."""

import csv
import math
import os
import warnings
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sb3_maddpg.analysis.evaluation import side_return_key, side_returns
from sb3_maddpg.common.package_warnings import SB3MADDPGWarning
from sb3_maddpg.experiments.config import BASELINE_SCHEME, PAPER_NAMES, ordered_schemes, setting_label
from sb3_maddpg.experiments.defaults import DEFAULT_ENV
from sb3_maddpg.experiments.metrics import METRICS, Metric
from sb3_maddpg.experiments.results_dir import load_experiments, load_summaries, never_updated_warning, run_updates
from sb3_maddpg.experiments.tasks import declared_sides, metric_info, named_metrics, recorded_metrics
from sb3_maddpg.results.aggregates import improvement_interval, iqm_interval
from sb3_maddpg.results.claims import write_claims_report
from sb3_maddpg.results.cost import write_cost_report
from sb3_maddpg.results.marl_eval import MARL_EVAL_FILE, write_marl_eval
from sb3_maddpg.results.normalised_table import format_normalised_markdown
from sb3_maddpg.results.reference_table import (
    format_references_markdown,
    load_references,
    reference_rows,
    write_references_csv,
)
from sb3_maddpg.results.stats import FAMILY_TEXT, Cell, aggregate, declare_families, floor_text


def _number(value: float, digits: int = 2) -> str:
    return "nan" if math.isnan(value) else f"{value:.{digits}f}"


def _setting_infos(settings: Iterable[str], metric: str, infos: Mapping[str, Metric] | None) -> dict[str, Metric]:
    """Each setting's view of ``metric`` (label, scale, direction): ``infos``'s, else :data:`METRICS`'s."""
    default = METRICS.get(metric, Metric(metric, metric))
    return {setting: (infos or {}).get(setting, default) for setting in dict.fromkeys(settings)}


def _label(metric: str, infos: Mapping[str, Metric]) -> str:
    """The metric's label, or its key when the settings' tasks label it differently."""
    labels = {info.label for info in infos.values()}
    return labels.pop() if len(labels) == 1 else metric


def _better(infos: Mapping[str, Metric]) -> str:
    """``"higher is better"``, or per setting when the settings' tasks differ (``"higher is better in tag, lower in ..."``)."""
    directions = {setting: "higher" if info.higher_is_better else "lower" for setting, info in infos.items()}
    if len(set(directions.values())) <= 1:
        return f"{next(iter(directions.values()), 'higher')} is better"
    by_direction: dict[str, list[str]] = {}
    for setting, direction in directions.items():
        by_direction.setdefault(direction, []).append(setting)
    return ", ".join(f"{direction} is better in {', '.join(settings)}" for direction, settings in by_direction.items())


def format_markdown(
    cells: Sequence[Cell],
    metric: str,
    experiments: dict[str, dict[str, Any]] | None = None,
    baseline: str = BASELINE_SCHEME,
    infos: Mapping[str, Metric] | None = None,
) -> str:
    """
    Table 2's layout: a row per setting, a column per method, ``mean (std)`` of the per-run scores with
    the significance marks of the exact Mann-Whitney U test against the baseline (its raw p, as the paper marks its
    table); then the raw and the Holm-adjusted p-values (each setting's family, see
    :class:`~sb3_maddpg.results.stats.Family`).

    :param cells: From :func:`~sb3_maddpg.results.stats.aggregate`.
    :param metric: The score's key.
    :param experiments: The stored experiment configs (for row labels).
    :param baseline: The scheme tested against.
    :param infos: The metric as each setting's task shows it, by setting (label and direction, see
        :func:`~sb3_maddpg.experiments.tasks.metric_info`); ``None``: :data:`~sb3_maddpg.experiments.metrics.METRICS`'s.
    :return: Markdown text.
    """
    by_setting = _setting_infos((cell.setting for cell in cells), metric, infos)
    metric_label = _label(metric, by_setting)
    experiments = experiments or {}
    settings = list(dict.fromkeys(cell.setting for cell in cells))
    schemes = ordered_schemes(cell.scheme for cell in cells)
    by_key = {(cell.setting, cell.scheme): cell for cell in cells}
    header = ["setting", *(PAPER_NAMES.get(scheme, scheme) for scheme in schemes)]
    lines = [
        f"### Score: {metric_label}, mean (std) over runs",
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
                "baseline"
                if scheme == baseline
                else f"{_number(cell.p_value, 4)}, Holm {_number(cell.p_adjusted, 4)} (U={_number(cell.u_statistic, 1)})"
            )
        lines.append("| " + " | ".join(row) + " |")
        p_lines.append("| " + " | ".join(p_row) + " |")
    counts = ", ".join(str(n) for n in sorted(run_counts))
    baseline_name = PAPER_NAMES.get(baseline, baseline)
    families = sorted({cell.family_size for cell in cells if cell.scheme != baseline})
    lines += [
        "",
        f"Each run's score is the mean {metric_label} of the models saved over the last part of training "
        f"({_better(by_setting)}); runs per cell: {counts}. `*` p < .05, `**` p < .01: the raw p of the two-sided "
        f"Mann-Whitney U test of the method's per-run scores against {baseline_name}'s, as the paper marks its "
        "table. The test is exact: p counts every split of the two methods' runs into groups of their sizes (ties "
        f"ranked by their mean rank); {floor_text(run_counts)}. Holm: p adjusted within its family (tests per family: "
        f"{', '.join(map(str, families)) or 'none'}), the p a finding must have below .05. "
        f"{FAMILY_TEXT.format(baseline=baseline_name)}",
        "",
        f"p-values against {baseline_name}: raw, Holm-adjusted (U statistic):",
        "",
        *p_lines,
        "",
    ]
    return "\n".join(lines)


def write_csv(cells: Sequence[Cell], metric: str, path: str | os.PathLike[str]) -> None:
    """
    One row per setting and method: ``setting, scheme, method, metric, n, mean, std, u_statistic,
    p_value, p_holm, family_size, stars, scores`` (scores in displayed units, ``;``-separated in seed order; ``p_holm``
    the p Holm-adjusted within the setting's family of ``family_size`` tests).

    :param cells: From :func:`~sb3_maddpg.results.stats.aggregate`.
    :param metric: The score's key.
    :param path: The CSV file.
    """
    fields = ["setting", "scheme", "method", "metric", "n", "mean", "std", "u_statistic", "p_value", "p_holm", "family_size"]
    fields += ["stars", "scores"]
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
                    "" if math.isnan(cell.p_adjusted) else repr(cell.p_adjusted),
                    cell.family_size or "",
                    cell.stars,
                    ";".join(repr(score) for score in cell.scores),
                ]
            )


def aggregate_estimates(
    cells: Sequence[Cell], metric: str, baseline: str = BASELINE_SCHEME, infos: Mapping[str, Metric] | None = None
) -> list[dict[str, Any]]:
    """
    Per setting and method, and over all settings together (stratified by setting) when there are several: the IQM
    of the per-run scores and the probability that a run of the method beats a run of the baseline, each with a 95%
    stratified bootstrap interval (see :mod:`~sb3_maddpg.results.aggregates`). "Beats" follows the metric's
    direction in each setting's task (a lower ``min_dist_sum`` is better; more catches, ``collisions`` of ``simple_tag``).

    :param cells: From :func:`~sb3_maddpg.results.stats.aggregate`.
    :param metric: The score's key (for its direction).
    :param baseline: The scheme compared against.
    :param infos: The metric as each setting's task shows it, by setting (see :func:`format_markdown`).
    :return: Rows with ``setting`` (``"all"`` for the stratified aggregate), ``scheme``, ``method``, ``n``, ``mean``,
        ``iqm`` and ``improvement`` (:class:`~sb3_maddpg.results.aggregates.IntervalEstimate`; ``None`` for the
        baseline).
    """
    sign = {
        setting: 1.0 if info.higher_is_better else -1.0
        for setting, info in _setting_infos((cell.setting for cell in cells), metric, infos).items()
    }
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
                    [np.multiply(sign[setting], stratum) for setting, stratum in zip(group, strata)],
                    [np.multiply(sign[setting], ref) for setting, ref in zip(group, reference)],
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
    infos: Mapping[str, Metric] | None = None,
) -> str:
    """
    :param rows: From :func:`aggregate_estimates`.
    :param metric: The score's key.
    :param experiments: The stored experiment configs (for setting labels).
    :param baseline: The scheme compared against.
    :param infos: The metric as each setting's task shows it, by setting (see :func:`format_markdown`).
    :return: Markdown: a row per setting and method, IQM [95% CI], mean, and P(better than the baseline) [95% CI].
    """
    by_setting = _setting_infos((row["setting"] for row in rows if row["setting"] != "all"), metric, infos)
    metric_label = _label(metric, by_setting)
    baseline_name = PAPER_NAMES.get(baseline, baseline)
    lines = [
        f"### Aggregates: {metric_label}, interquartile mean and probability of improvement over {baseline_name}",
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
    lines += [
        "",
        f"Each run's score is its mean {metric_label} over the checkpoints of the last part of training ({_better(by_setting)}"
        "). IQM: mean of the middle 50% of the runs' scores. P(better): the chance that a random run of the "
        f"method scores better than a random run of {baseline_name} (ties count half; 0.5: no difference), averaged "
        "over settings. Intervals: 95% stratified bootstrap (percentile, runs resampled within each setting and "
        "method; `scipy.stats.bootstrap`), as in Agarwal et al. (2021). A percentile interval sees only the runs' "
        "own spread: from a handful of runs it covers less than 95%, so read it as a description of the runs, and "
        "whether two methods differ from the Holm-adjusted p of the table. An interval of P(better) that excludes "
        f"0.5 says the method and {baseline_name} differ at this number of runs, before any correction.",
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


class UnscoredMetricError(ValueError):
    """
    A metric asked of a report that no run of its results directory scores (:func:`make_report`): a user's error,
    which ``sb3-maddpg report`` says in one line with exit status 2.

    :param unscored: The metrics asked that no run scores.
    :param scored: Those the runs score, sorted.
    :param results_dir: The results directory.
    """

    def __init__(self, unscored: Sequence[str], scored: Sequence[str], results_dir: str | os.PathLike[str]) -> None:
        self.unscored, self.scored, self.results_dir = list(unscored), list(scored), str(results_dir)
        super().__init__(
            f"Unknown metric(s) {self.unscored}: the runs in {self.results_dir} score {self.scored} (runs written before "
            "0.2 have no success or coverage at other radii); pick metrics among those."
        )


DEFAULT_REPORT_METRICS = ("success_rate", "min_dist_sum")
"""What a simple_spread report shows unless told: success (higher is better; near 0 early in training) and the
min-dist sum (lower is better; informative at every scale). Other tasks: see :func:`default_metrics`."""


def default_metrics(score: dict[str, float], env: str = DEFAULT_ENV, declared: Sequence[Any] | None = None) -> list[str]:
    """
    The metrics of a task's main table.

    :param score: One run's score.
    :param env: Its task (an experiment's ``env``).
    :param declared: The task metrics its env declares (a run summary's record, :func:`summary_metrics`); ``None``:
        an MPE task's by its name.
    :return: simple_spread: the metrics of :data:`DEFAULT_REPORT_METRICS` the run has (not NaN). Another task: the
        metrics its env declares (an MPE task's :data:`~sb3_maddpg.envs.MPE_TASK_METRICS`, a factory's env's own), then
        each side's return in a competitive task (the team return in a cooperative one; never a sum over opponents),
        then ``group_return`` when the runs score one, those the run has. Else, or when the run has none of them:
        ``["return_mean"]``.
    """
    if env == DEFAULT_ENV:
        candidates: list[str] = list(DEFAULT_REPORT_METRICS)
    else:
        keys = [metric.key for metric in (named_metrics(env) if declared is None else declared)]
        sides = [side_return_key(side) for side in side_returns(score)]
        returns = sides or ([] if declared_sides(env) else ["return_mean"])
        candidates = [*keys, *returns, "group_return"]
    present = [metric for metric in candidates if not math.isnan(score.get(metric, math.nan))]
    return present or ["return_mean"]


def summary_metrics(summaries: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """
    :param summaries: Run summaries.
    :return: Each setting's task metrics as its runs' summaries record them (the first that records any;
        :func:`~sb3_maddpg.experiments.tasks.recorded_metrics`), ``None`` for a setting whose summaries record none.
    """
    recorded: dict[str, Any] = {}
    for summary in summaries:
        if recorded.get(summary["experiment"]) is None:
            recorded[summary["experiment"]] = recorded_metrics(summary.get("task_metrics"))
    return recorded


def format_terminal_table(
    tables: Mapping[str, Sequence[Cell]],
    infos: Mapping[str, Mapping[str, Metric]],
    experiments: dict[str, dict[str, Any]] | None = None,
    baseline: str = BASELINE_SCHEME,
) -> str:
    """
    The report's main table for a terminal: Table 2 for simple_spread, a task's own metrics for another. Per setting, a
    row per method and a column per metric, each ``mean (std)`` over runs with the significance marks of the
    Mann-Whitney U test against the baseline, and each column's direction in the setting's task.

    :param tables: Each metric's cells (:func:`~sb3_maddpg.results.stats.aggregate`), by metric.
    :param infos: Each metric as each setting's task shows it: metric -> setting -> :class:`Metric`.
    :param experiments: The stored experiment configs (for setting labels).
    :param baseline: The scheme tested against.
    :return: Plain text, columns aligned.
    """
    baseline_name = PAPER_NAMES.get(baseline, baseline)
    settings = list(dict.fromkeys(cell.setting for cells in tables.values() for cell in cells))
    lines = []
    for setting in settings:
        cells = {metric: {cell.scheme: cell for cell in table if cell.setting == setting} for metric, table in tables.items()}
        metrics = [metric for metric, by_scheme in cells.items() if by_scheme]
        header = ["method", "runs"]
        for metric in metrics:
            info = infos[metric][setting]
            header.append(f"{info.label}, {'higher' if info.higher_is_better else 'lower'} is better")
        rows = [header]
        for scheme in ordered_schemes(scheme for metric in metrics for scheme in cells[metric]):
            present = [cells[metric][scheme] for metric in metrics if scheme in cells[metric]]
            row = [PAPER_NAMES.get(scheme, scheme), str(max(cell.n for cell in present))]
            for metric in metrics:
                cell = cells[metric].get(scheme)
                mark = f" {cell.stars}" if cell is not None and cell.stars else ""
                row.append("" if cell is None else f"{_number(cell.mean)} ({_number(cell.std)}){mark}")
            rows.append(row)
        widths = [max(len(row[column]) for row in rows) for column in range(len(header))]
        lines += [
            f"{setting_label(setting, (experiments or {}).get(setting))}: mean (std) over runs; * p < .05, ** p < .01: "
            f"exact Mann-Whitney U against {baseline_name} (raw p; Holm-adjusted in table_<metric>.md)",
            *("  ".join(text.ljust(width) for text, width in zip(row, widths)).rstrip() for row in rows),
            "",
        ]
    return "\n".join(lines)


def _scored(summary: dict[str, Any], metric: str) -> bool:
    """Whether a run scores ``metric`` (has it, not NaN: a metric that does not apply to its task is NaN or absent)."""
    value = summary["score"].get(metric)
    return value is not None and not math.isnan(float(value))


def make_report(
    results_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    metrics: Sequence[str] | None = None,
    plots: bool = True,
    baseline: str = BASELINE_SCHEME,
    verbose: int = 1,
) -> list[Path]:
    """
    Write, for each metric, ``table_<metric>.md`` and ``table_<metric>.csv`` (Table 2: mean (std), the exact
    Mann-Whitney U test, its p raw and Holm-adjusted within each setting's family, declared from the stored configs: see
    :class:`~sb3_maddpg.results.stats.Family`), ``aggregates_<metric>.md`` and ``aggregates_<metric>.csv`` (IQM and
    probability of improvement with 95% bootstrap intervals), ``claims_<metric>.md`` and ``claims_<metric>.csv`` for the
    paper's settings (its Table 2 beside these runs' and its findings asked of them, see
    :mod:`~sb3_maddpg.results.claims`), ``normalised.md`` for simple_spread settings (min-dist sum and team
    return between the random team, 0, and the scripted controller, 1), ``references.md`` and ``references.csv`` for
    settings with reference policies (each scheme's and each reference's mean over seeds with its 95% interval, the
    references on the runs' own evaluation episodes: :mod:`~sb3_maddpg.experiments.references`), ``cost.md`` and
    ``cost.csv`` (training time per run by setting and scheme, see :mod:`~sb3_maddpg.results.cost`),
    ``marl_eval.json`` (every run in marl-eval's JSON, see :mod:`~sb3_maddpg.results.marl_eval`) and, with
    ``plots``, ``learning_curves_<metric>.png`` (IQM over runs with a 95% bootstrap band, vs env steps) and
    ``boxplot_<metric>.png`` (per-run scores, like the paper's Figures 7 and 8).

    Each metric takes its label and direction from each setting's task, as its runs' summaries record the metrics its
    env declares (:func:`~sb3_maddpg.experiments.tasks.metric_info`), and a table holds the runs that score it (a
    setting whose task does not have the metric is left out of its table). Runs that never took a gradient update (their
    summary's ``n_updates``, or their ``progress.csv``'s ``train/n_updates``, is 0) are warned about (a
    ``UserWarning``), and the warning heads every table.

    :param results_dir: The results directory of a sweep.
    :param out_dir: Where to write the report.
    :param metrics: The scores to report (see :data:`~sb3_maddpg.experiments.metrics.METRICS`); ``None``: each task's
        main ones (:func:`default_metrics`).
    :param plots: Also draw the figures (needs matplotlib).
    :param baseline: The scheme the others are tested against.
    :param verbose: 1: print the main table (:func:`format_terminal_table`) and the reference policies' to stdout;
        0: nothing.
    :return: The files written.
    :raise FileNotFoundError: When the directory has no finished runs.
    :raise UnscoredMetricError: When no run scores one of ``metrics`` (a ``ValueError``), before anything is written.
    """
    experiments = load_experiments(results_dir)
    summaries = load_summaries(results_dir)
    if not summaries:
        raise FileNotFoundError(f"No finished runs under {results_dir} (expected <experiment>/<scheme>/seed_*/summary.json).")
    envs = {
        summary["experiment"]: (experiments.get(summary["experiment"]) or {}).get("env", DEFAULT_ENV) for summary in summaries
    }
    declared = summary_metrics(summaries)
    if metrics is None:
        firsts = {summary["experiment"]: summary for summary in reversed(summaries)}
        metrics = list(
            dict.fromkeys(
                metric
                for setting in envs
                for metric in default_metrics(firsts[setting]["score"], envs[setting], declared[setting])
            )
        )
    scored = {metric: [summary for summary in summaries if _scored(summary, metric)] for metric in metrics}
    unknown = [metric for metric, runs in scored.items() if not runs]
    if unknown:
        known = sorted({metric for summary in summaries for metric in summary["score"] if _scored(summary, metric)})
        raise UnscoredMetricError(unknown, known, results_dir)
    warning = never_updated_warning([summary["run_id"] for summary in summaries if run_updates(summary) == 0])
    if warning is not None:
        warnings.warn(warning, SB3MADDPGWarning, stacklevel=2)
    heading = "" if warning is None else f"> **Warning**: {warning}\n\n"
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    tables, infos = {}, {}
    # The families come from the stored configs (the schemes each setting runs), whatever the scores turn out to be.
    families = declare_families(experiments, metrics, baseline)
    for metric in metrics:
        cells = aggregate(scored[metric], metric, baseline=baseline, families=families)
        by_setting = {
            setting: metric_info(metric, envs[setting], declared[setting])
            for setting in dict.fromkeys(cell.setting for cell in cells)
        }
        tables[metric], infos[metric] = cells, by_setting
        markdown_path, csv_path = out / f"table_{metric}.md", out / f"table_{metric}.csv"
        markdown_path.write_text(heading + format_markdown(cells, metric, experiments, baseline=baseline, infos=by_setting))
        write_csv(cells, metric, csv_path)
        estimates = aggregate_estimates(cells, metric, baseline=baseline, infos=by_setting)
        aggregates_md, aggregates_csv = out / f"aggregates_{metric}.md", out / f"aggregates_{metric}.csv"
        aggregates_md.write_text(
            heading + format_aggregates_markdown(estimates, metric, experiments, baseline=baseline, infos=by_setting)
        )
        write_aggregates_csv(estimates, metric, aggregates_csv)
        written += [markdown_path, csv_path, aggregates_md, aggregates_csv]
        written += write_claims_report(out, cells, metric, experiments, by_setting, heading, baseline)
        if plots:
            from sb3_maddpg.results.plots import plot_boxplots, plot_learning_curves

            curve_path, box_path = out / f"learning_curves_{metric}.png", out / f"boxplot_{metric}.png"
            plot_learning_curves(scored[metric], metric, curve_path, experiments)
            plot_boxplots(cells, metric, box_path, experiments)
            written += [curve_path, box_path]
    normalised = format_normalised_markdown(summaries, experiments)
    if normalised is not None:
        (out / "normalised.md").write_text(normalised)
        written.append(out / "normalised.md")
    reference_rows_ = reference_rows(summaries, load_references(results_dir), metrics, infos)
    references = format_references_markdown(reference_rows_, metrics, infos, experiments)
    if references is not None:
        (out / "references.md").write_text(heading + references)
        write_references_csv(reference_rows_, metrics, out / "references.csv")
        written += [out / "references.md", out / "references.csv"]
    written += write_cost_report(out, summaries, experiments)
    written.append(write_marl_eval(results_dir, out / MARL_EVAL_FILE))
    if verbose >= 1:
        print(format_terminal_table(tables, infos, experiments, baseline=baseline))
        if references is not None:
            print(references)
    return written
