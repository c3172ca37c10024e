"""Figures like the paper's: learning curves (Figure 7) and boxplots of per-run scores (Figure 8).

matplotlib is imported inside the functions (with the Agg backend), so the package does not need it.
"""

import os
import zlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sb3_maddpg.experiments.config import PAPER_NAMES, ordered_schemes, setting_label
from sb3_maddpg.experiments.metrics import METRICS, Metric
from sb3_maddpg.experiments.results_dir import read_curve
from sb3_maddpg.results.aggregates import iqm_interval
from sb3_maddpg.results.stats import Cell

COLORS = {
    "full": "tab:blue",
    "independent": "tab:orange",
    "observations": "tab:green",
    "actions": "tab:red",
    "selected": "tab:purple",
    "attention": "tab:brown",
    "learned_selection": "tab:pink",
}
"""One color per scheme, the same in every figure."""

OTHER_COLORS = ("tab:olive", "tab:cyan", "tab:gray")
"""The colors of other schemes (a variant, a user's scheme), each name always the same one (:func:`scheme_color`)."""


def scheme_color(scheme: str) -> str:
    """
    :param scheme: A scheme's name.
    :return: Its color: :data:`COLORS`'s, else one of :data:`OTHER_COLORS` chosen by the name (the same in every
        figure and every run of the report).
    """
    if scheme in COLORS:
        return COLORS[scheme]
    return OTHER_COLORS[zlib.crc32(scheme.encode()) % len(OTHER_COLORS)]


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(figure: Any, path: str | os.PathLike[str]) -> None:
    # No "Software" stamp, so the same results give the same file with the same matplotlib.
    figure.savefig(path, dpi=110, bbox_inches="tight", metadata={"Software": None})


def _title(setting: str, experiments: dict[str, dict[str, Any]] | None) -> str:

    return setting_label(setting, (experiments or {}).get(setting))


Curve = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def iqm_curves(summaries: Sequence[dict[str, Any]], metric: str) -> dict[str, dict[str, Curve]]:
    """
    The runs' learning curves per setting and scheme, as the interquartile mean over runs at each evaluation step
    (the steps every run has) with a 95% bootstrap interval (:func:`~sb3_maddpg.results.aggregates.iqm_interval`).

    :param summaries: Run summaries with ``"directory"`` (from :func:`~sb3_maddpg.experiments.results_dir.load_summaries`).
    :param metric: The curve's column (e.g. ``success_rate``).
    :return: ``{setting: {scheme: (steps, iqm, low, high)}}`` in displayed units (the interval is ``nan`` for one run).
    """
    scale = METRICS.get(metric, Metric(metric, metric)).scale
    grouped: dict[str, dict[str, list[dict[float, float]]]] = {}
    for summary in summaries:
        rows = read_curve(summary["directory"])
        if rows:
            curve = {row["timesteps"]: row[metric] * scale for row in rows}
            grouped.setdefault(summary["experiment"], {}).setdefault(summary["scheme"], []).append(curve)
    result: dict[str, dict[str, Curve]] = {}
    for setting, by_scheme in grouped.items():
        for scheme, curves in by_scheme.items():
            steps = sorted(set.intersection(*(set(curve) for curve in curves)))
            estimates = [iqm_interval([[curve[step] for curve in curves]], seed=index) for index, step in enumerate(steps)]
            result.setdefault(setting, {})[scheme] = (
                np.array(steps),
                np.array([estimate.value for estimate in estimates]),
                np.array([estimate.low for estimate in estimates]),
                np.array([estimate.high for estimate in estimates]),
            )
    return result


def _never_negative(curves: Sequence[Curve]) -> bool:
    """:return: Whether no curve nor band goes below 0 (a band of one run is ``nan``: its curve decides)."""
    return all(float(np.nanmin(np.fmin(curve[1], curve[2]))) >= 0 for curve in curves)


def plot_learning_curves(
    summaries: Sequence[dict[str, Any]],
    metric: str,
    path: str | os.PathLike[str],
    experiments: dict[str, dict[str, Any]] | None = None,
) -> Path:
    """
    One panel per setting: the metric of the team evaluations during training against env steps, the interquartile
    mean over runs with its 95% bootstrap band, one line per method (the paper's Figure 7 draws mean and std).

    :param summaries: Run summaries with ``"directory"``.
    :param metric: The curve's column.
    :param path: The PNG file.
    :param experiments: The stored experiment configs (for titles).
    :return: The path.
    """
    plt = _pyplot()
    curves = iqm_curves(summaries, metric)
    settings = list(curves) or ["(no learning curves)"]
    figure, axes = plt.subplots(1, len(settings), figsize=(5.5 * len(settings), 4), squeeze=False)
    for axis, setting in zip(axes[0], settings):
        for scheme in ordered_schemes(set(curves.get(setting, {}))):
            steps, middle, low, high = curves[setting][scheme]
            color = scheme_color(scheme)
            axis.plot(steps, middle, label=PAPER_NAMES.get(scheme, scheme), color=color)
            axis.fill_between(steps, low, high, color=color, alpha=0.2, linewidth=0)
        experiment = (experiments or {}).get(setting)
        if experiment and curves.get(setting):
            # The window the runs' scores are taken over (the checkpoints of the last 20% of training).
            total = experiment["episodes"] * experiment["episode_length"]
            axis.axvspan(total * (1 - experiment["checkpoint_fraction"]), total, color="0.85", alpha=0.5, linewidth=0)
        axis.set_title(_title(setting, experiments), fontsize=10)
        axis.set_xlabel("env steps (shaded: checkpoints scored)" if experiment else "env steps")
        axis.set_ylabel(f"{METRICS.get(metric, Metric(metric, metric)).label}, IQM over runs (band: 95% CI)")
        axis.grid(alpha=0.3)
        if curves.get(setting):
            axis.legend(fontsize=8)
            if _never_negative(list(curves[setting].values())):
                axis.set_ylim(bottom=0.0)  # a score that cannot be negative: its axis starts at 0
    figure.tight_layout()
    _save(figure, path)
    plt.close(figure)
    return Path(path)


def plot_experiment_curves(
    summaries: Sequence[dict[str, Any]],
    metric: str,
    path: str | os.PathLike[str],
    labels: Mapping[str, str],
    transitions_per_update: Mapping[str, int] | None = None,
    learning_starts: int = 25_600,
    levels: Mapping[str, float] | None = None,
    title: str = "",
    y_max: float | None = None,
) -> Path:
    """
    Experiments compared on one panel (a diagnosis's factors): one line per experiment, the interquartile mean of its
    runs' learning curves with the 95% bootstrap band, against env steps; with ``transitions_per_update``, a second
    panel draws the same curves against gradient steps, where runs with more updates per transition get first.

    :param summaries: Run summaries with ``"directory"``; each experiment drawn must have runs of one scheme.
    :param metric: The curves' column (e.g. ``min_dist_sum``).
    :param path: The PNG file.
    :param labels: The experiments to draw, in this order, by name: their legend labels.
    :param transitions_per_update: Each drawn experiment's env transitions per gradient step, for the second panel.
    :param learning_starts: The env steps of random actions before the first gradient step (MADDPG's and MATD3's
        default, the paper's).
    :param levels: Horizontal reference lines, by label (e.g. a random team's and a scripted controller's score).
    :param title: The figure's title.
    :param y_max: The panels' top, to cut early transients off (none: matplotlib's).
    :return: The path.
    """
    plt = _pyplot()
    curves = iqm_curves([summary for summary in summaries if summary["experiment"] in labels], metric)
    for name, by_scheme in curves.items():
        if len(by_scheme) != 1:
            raise ValueError(
                f"Experiment {name!r} has runs of {len(by_scheme)} schemes ({', '.join(sorted(by_scheme))}): pass the "
                "summaries of one scheme per experiment."
            )
    missing = [name for name in labels if name in curves and transitions_per_update and name not in transitions_per_update]
    if missing:
        raise ValueError(f"transitions_per_update has no ratio for {', '.join(missing)}: give every drawn experiment's.")
    panels = 2 if transitions_per_update else 1
    figure, axes = plt.subplots(1, panels, figsize=(6.5 * panels, 4.5), squeeze=False)
    colors = plt.get_cmap("tab10")
    for index, (name, label) in enumerate((name, label) for name, label in labels.items() if name in curves):
        steps, middle, low, high = next(iter(curves[name].values()))
        xs = [steps]
        if transitions_per_update:
            xs.append(np.maximum(steps - learning_starts, 0) / transitions_per_update[name])
        for axis, x in zip(axes[0], xs):
            axis.plot(x, middle, label=label, color=colors(index % 10))
            axis.fill_between(x, low, high, color=colors(index % 10), alpha=0.15, linewidth=0)
    metric_label = METRICS.get(metric, Metric(metric, metric)).label
    never_negative = _never_negative([curve for by_scheme in curves.values() for curve in by_scheme.values()])
    for axis, x_label in zip(axes[0], ("env steps", "gradient steps")):
        for level_index, (level_label, value) in enumerate((levels or {}).items()):
            axis.axhline(value, color="0.4", linestyle=("--", ":", "-.")[level_index % 3], linewidth=1, label=level_label)
        axis.set_xlabel(x_label)
        axis.set_ylabel(f"{metric_label}, IQM over runs (band: 95% CI)")
        if never_negative:
            axis.set_ylim(bottom=0.0)  # a score that cannot be negative: its axis starts at 0
        if y_max is not None:
            axis.set_ylim(top=y_max)
        axis.grid(alpha=0.3)
    if title:
        figure.suptitle(title, fontsize=10)
    figure.tight_layout()
    # Below the panels, so that it hides no curve.
    handles, legend_labels = axes[0][0].get_legend_handles_labels()
    figure.legend(handles, legend_labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=3, fontsize=8)
    _save(figure, path)
    plt.close(figure)
    return Path(path)


def plot_boxplots(
    cells: Sequence[Cell],
    metric: str,
    path: str | os.PathLike[str],
    experiments: dict[str, dict[str, Any]] | None = None,
) -> Path:
    """
    One panel per setting: a box of the per-run scores of each method, the runs drawn as points, and
    the Mann-Whitney marks against MADDPG above the boxes (the paper's Figure 8).

    :param cells: From :func:`~sb3_maddpg.results.stats.aggregate`.
    :param metric: The score's key.
    :param path: The PNG file.
    :param experiments: The stored experiment configs (for titles).
    :return: The path.
    """
    plt = _pyplot()
    settings = list(dict.fromkeys(cell.setting for cell in cells))
    figure, axes = plt.subplots(1, len(settings), figsize=(5.5 * len(settings), 4), squeeze=False)
    for axis, setting in zip(axes[0], settings):
        row = [cell for cell in cells if cell.setting == setting]
        positions = np.arange(1, len(row) + 1)
        boxes = axis.boxplot(
            [cell.scores for cell in row],
            positions=positions,
            widths=0.6,
            patch_artist=True,
            medianprops={"color": "black"},
            showfliers=False,
        )
        for patch, cell in zip(boxes["boxes"], row):
            patch.set_facecolor(scheme_color(cell.scheme))
            patch.set_alpha(0.35)
        # Deterministic jitter, so the same results draw the same figure.
        jitter = np.random.default_rng(0)
        top = max((max(cell.scores) for cell in row if cell.scores), default=0.0)
        bottom = min((min(cell.scores) for cell in row if cell.scores), default=0.0)
        span = (top - bottom) or 1.0
        for position, cell in zip(positions, row):
            offsets = jitter.uniform(-0.12, 0.12, size=len(cell.scores))
            axis.scatter(position + offsets, cell.scores, s=12, color=scheme_color(cell.scheme), zorder=3)
            if cell.stars:
                axis.text(position, top + 0.04 * span, cell.stars, ha="center", va="bottom", fontsize=12)
        # A score that cannot be negative (a rate, a distance) gets an axis from 0, so all-zero scores sit on it.
        axis.set_ylim(0.0 if bottom >= 0 else bottom - 0.08 * span, top + 0.16 * span)
        axis.set_xticks(positions)
        axis.set_xticklabels([cell.method for cell in row], fontsize=8)
        axis.set_title(_title(setting, experiments), fontsize=10)
        axis.set_ylabel(f"per-run score: {METRICS.get(metric, Metric(metric, metric)).label}")
        axis.grid(axis="y", alpha=0.3)
    figure.tight_layout()
    _save(figure, path)
    plt.close(figure)
    return Path(path)
