"""Figures like the paper's: learning curves (Figure 7) and boxplots of per-run scores (Figure 8).

matplotlib is imported inside the functions (with the Agg backend), so the package does not need it.
"""

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sb3_maddpg.experiments.aggregates import iqm_interval
from sb3_maddpg.experiments.config import PAPER_NAMES, ordered_schemes, setting_label
from sb3_maddpg.experiments.results import read_curve
from sb3_maddpg.experiments.stats import METRICS, Cell, Metric

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
    (the steps every run has) with a 95% bootstrap interval (:func:`~sb3_maddpg.experiments.aggregates.iqm_interval`).

    :param summaries: Run summaries with ``"directory"`` (from :func:`~sb3_maddpg.experiments.results.load_summaries`).
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
            color = COLORS.get(scheme)
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
            if min(float(np.min(curve[2])) for curve in curves[setting].values()) >= 0:
                axis.set_ylim(bottom=0.0)  # a score that cannot be negative: its axis starts at 0
    figure.tight_layout()
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

    :param cells: From :func:`~sb3_maddpg.experiments.stats.aggregate`.
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
            patch.set_facecolor(COLORS.get(cell.scheme, "tab:gray"))
            patch.set_alpha(0.35)
        # Deterministic jitter, so the same results draw the same figure.
        jitter = np.random.default_rng(0)
        top = max((max(cell.scores) for cell in row if cell.scores), default=0.0)
        bottom = min((min(cell.scores) for cell in row if cell.scores), default=0.0)
        span = (top - bottom) or 1.0
        for position, cell in zip(positions, row):
            offsets = jitter.uniform(-0.12, 0.12, size=len(cell.scores))
            axis.scatter(position + offsets, cell.scores, s=12, color=COLORS.get(cell.scheme, "tab:gray"), zorder=3)
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
