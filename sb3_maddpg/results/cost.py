"""What a study cost: training time per run by setting and scheme, in run-hours and, where recorded, core-hours.

Read from the runs' ``summary.json`` (``train_time_s``, ``eval_time_s``, ``total_timesteps`` and, since 0.3, what
trained them: ``device``, ``torch_threads``, ``runs_trained_together``). A run's training time is its wall time, so it
depends on what ran beside it; a run trained in a run group shares its group's time with the group's other runs, hence
core-hours are ``train hours x threads / runs trained together`` on the CPU, and GPU-hours ``train hours / runs trained
together`` on a GPU.
"""

import csv
import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sb3_maddpg.experiments.config import PAPER_NAMES, ordered_schemes, setting_label

COST_FILE = "cost"
"""The report's cost files' stem: ``cost.md`` and ``cost.csv``."""

HOUR = 3600.0


@dataclasses.dataclass(frozen=True)
class SchemeCost:
    """
    One setting's and scheme's runs' cost.

    :param setting: The experiment's name.
    :param scheme: The sharing scheme.
    :param runs: How many finished runs.
    :param env_steps: Env steps per run (their mean).
    :param train_hours: Each run's training wall time, hours.
    :param eval_hours: Each run's checkpoint evaluations' wall time, hours.
    :param steps_per_s: Each run's env steps per second of training.
    :param trained_together: Each run's runs trained in the same process at once (1 where not recorded): a run group's
        training time is its members' together, so the study's run-hours count it once.
    :param core_hours: Each run's training core-hours on the CPU or GPU-hours on a GPU (see
        :func:`training_core_hours`), or ``None`` when a run does not record what trained it (runs before 0.3) or
        its runs trained on different kinds of device.
    :param unit: ``"core-h"`` or ``"GPU-h"`` (``""`` when ``core_hours`` is ``None``).
    """

    setting: str
    scheme: str
    runs: int
    env_steps: float
    train_hours: tuple[float, ...]
    eval_hours: tuple[float, ...]
    steps_per_s: tuple[float, ...]
    trained_together: tuple[int, ...]
    core_hours: tuple[float, ...] | None
    unit: str = ""

    @property
    def total_hours(self) -> float:
        """The wall time its runs took, training and evaluation, in hours: a run group's training counted once."""
        training = sum(hours / together for hours, together in zip(self.train_hours, self.trained_together))
        return float(training + sum(self.eval_hours))


def training_core_hours(summary: dict[str, Any]) -> tuple[float, str] | None:
    """
    :param summary: A run's summary.
    :return: Its training's cost and unit: on the CPU, core-hours (training hours x torch threads / runs trained
        together, ``"core-h"``); on a GPU, GPU-hours (training hours / runs trained together, ``"GPU-h"``); ``None``
        when the summary does not say what trained it.
    """
    if "torch_threads" not in summary or "device" not in summary:
        return None
    share = float(summary["train_time_s"]) / HOUR / int(summary.get("runs_trained_together", 1))
    if summary["device"] == "cpu":
        return share * int(summary["torch_threads"]), "core-h"
    return share, "GPU-h"


def scheme_costs(summaries: Sequence[dict[str, Any]]) -> list[SchemeCost]:
    """
    :param summaries: Run summaries (see :func:`~sb3_maddpg.experiments.results_dir.load_summaries`).
    :return: One cost per setting (in the order they come) and scheme (the paper's order first).
    """
    costs = []
    for setting in dict.fromkeys(summary["experiment"] for summary in summaries):
        in_setting = [summary for summary in summaries if summary["experiment"] == setting]
        for scheme in ordered_schemes(summary["scheme"] for summary in in_setting):
            runs = [summary for summary in in_setting if summary["scheme"] == scheme]
            core = [training_core_hours(summary) for summary in runs]
            units = {cost[1] for cost in core if cost is not None}
            known = None not in core and len(units) == 1
            costs.append(
                SchemeCost(
                    setting=setting,
                    scheme=scheme,
                    runs=len(runs),
                    env_steps=float(np.mean([summary["total_timesteps"] for summary in runs])),
                    train_hours=tuple(float(summary["train_time_s"]) / HOUR for summary in runs),
                    eval_hours=tuple(float(summary.get("eval_time_s", 0.0)) / HOUR for summary in runs),
                    steps_per_s=tuple(float(summary["train_steps_per_s"]) for summary in runs),
                    trained_together=tuple(int(summary.get("runs_trained_together", 1)) for summary in runs),
                    core_hours=tuple(cost[0] for cost in core if cost is not None) if known else None,
                    unit=units.pop() if known else "",
                )
            )
    return costs


def _spread(values: Sequence[float], digits: int = 2) -> str:
    """``mean (min-max)``, or the one value."""
    if len(values) == 1:
        return f"{values[0]:.{digits}f}"
    return f"{np.mean(values):.{digits}f} ({min(values):.{digits}f}-{max(values):.{digits}f})"


def _minutes(hours: Sequence[float]) -> list[float]:
    return [value * 60.0 for value in hours]


def format_cost_markdown(costs: Sequence[SchemeCost], experiments: dict[str, dict[str, Any]]) -> str:
    """
    :param costs: :func:`scheme_costs`.
    :param experiments: The stored experiment configs (for the settings' labels).
    :return: A Markdown table of training time per run by setting and scheme, and the study's total.
    """
    lines = [
        "### Cost: training time per run (lower is cheaper)",
        "",
        "Wall time of each run's training, mean (min-max) over its runs; it depends on what ran beside a run as much "
        "as on its scheme. Core-hours (CPU) = training hours x torch threads / runs trained together in one process, "
        "GPU-hours = training hours / runs trained together, where the runs record what trained them (since 0.3; a "
        "resumed run: its last attempt's); `-` where they do not, or where a scheme's runs trained on different kinds "
        "of device. Evaluation: the checkpoint evaluations after training. Run-hours: the wall time the runs took, "
        "a run group's training counted once.",
        "",
        "| setting | method | runs | env steps per run | training min per run | env steps/s | core-h or GPU-h per run | "
        "evaluation s per run | run-hours in all |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for cost in costs:
        label = setting_label(cost.setting, experiments.get(cost.setting))
        core = "-" if cost.core_hours is None else f"{_spread(cost.core_hours, 3)} {cost.unit}"
        lines.append(
            f"| {label} | {PAPER_NAMES.get(cost.scheme, cost.scheme)} | {cost.runs} | {cost.env_steps:,.0f} | "
            f"{_spread(_minutes(cost.train_hours), 1)} | {_spread(cost.steps_per_s, 0)} | {core} | "
            f"{_spread([hours * HOUR for hours in cost.eval_hours], 1)} | "
            f"{cost.total_hours:.1f} |"
        )
    runs = sum(cost.runs for cost in costs)
    total = sum(cost.total_hours for cost in costs)
    totals = [f"{runs} {'run' if runs == 1 else 'runs'}", f"{total:.1f} run-hours"]
    for unit in sorted({cost.unit for cost in costs if cost.core_hours is not None}):
        spent = sum(sum(cost.core_hours or ()) for cost in costs if cost.unit == unit)
        totals.append(f"{spent:.1f} {unit} of training")
    unknown = sum(cost.runs for cost in costs if cost.core_hours is None)
    if unknown and unknown < runs:
        totals.append(f"{unknown} run(s) not counted in them (no record of what trained them, or mixed devices)")
    lines += ["", "In all: " + ", ".join(totals) + "."]
    return "\n".join(lines) + "\n"


def write_cost_csv(costs: Sequence[SchemeCost], path: str | Path) -> None:
    """
    :param costs: :func:`scheme_costs`.
    :param path: Where to write one row per setting and scheme (means over its runs, and sums).
    """
    with open(path, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(
            [
                "setting",
                "scheme",
                "method",
                "runs",
                "env_steps_per_run",
                "train_hours_mean",
                "train_hours_min",
                "train_hours_max",
                "steps_per_s_mean",
                "core_or_gpu_hours_mean",
                "unit",
                "eval_seconds_mean",
                "run_hours_total",
            ]
        )
        for cost in costs:
            writer.writerow(
                [
                    cost.setting,
                    cost.scheme,
                    PAPER_NAMES.get(cost.scheme, cost.scheme),
                    cost.runs,
                    f"{cost.env_steps:.0f}",
                    f"{np.mean(cost.train_hours):.4f}",
                    f"{min(cost.train_hours):.4f}",
                    f"{max(cost.train_hours):.4f}",
                    f"{np.mean(cost.steps_per_s):.1f}",
                    "" if cost.core_hours is None else f"{np.mean(cost.core_hours):.4f}",
                    cost.unit,
                    f"{np.mean(cost.eval_hours) * HOUR:.1f}",
                    f"{cost.total_hours:.4f}",
                ]
            )


def write_cost_report(out: Path, summaries: Sequence[dict[str, Any]], experiments: dict[str, dict[str, Any]]) -> list[Path]:
    """
    Write ``cost.md`` and ``cost.csv`` into a report directory.

    :param out: The report directory.
    :param summaries: The runs' summaries.
    :param experiments: The stored experiment configs.
    :return: The files written.
    """
    costs = scheme_costs(summaries)
    markdown, table = out / f"{COST_FILE}.md", out / f"{COST_FILE}.csv"
    markdown.write_text(format_cost_markdown(costs, experiments))
    write_cost_csv(costs, table)
    return [markdown, table]
