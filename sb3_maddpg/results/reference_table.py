"""Reference policies' scores beside the schemes': read from ``references.json`` (written by
:func:`~sb3_maddpg.experiments.references.write_references`), as rows with 95% t intervals over seeds, Markdown and CSV.
"""

import csv
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sb3_maddpg.experiments.reference_specs import REFERENCE_KINDS

if TYPE_CHECKING:
    from sb3_maddpg.experiments.metrics import Metric


def load_references(results_dir: str | os.PathLike[str]) -> dict[str, dict[str, Any]]:
    """
    :param results_dir: A results directory.
    :return: Each experiment's reference policies as :func:`write_references` wrote them (its ``policies``), by
        experiment; experiments without any are left out.
    """
    from sb3_maddpg.experiments.results_dir import REFERENCES_FILE, read_json

    found = {}
    for path in sorted(Path(results_dir).glob(f"*/{REFERENCES_FILE}")):
        stored = read_json(path)
        if isinstance(stored, dict) and isinstance(stored.get("policies"), dict):
            found[path.parent.name] = stored["policies"]
    return found


def seed_interval(values: Sequence[float]) -> tuple[float, float, float]:
    """
    :param values: One value per seed (a run's score, or a reference's mean over that seed's episodes).
    :return: Their mean and its 95% t interval (:func:`~sb3_maddpg.results.aggregates.mean_difference_interval`;
        ``nan`` ends from fewer than 2 seeds).
    """
    from sb3_maddpg.results.aggregates import mean_difference_interval

    if not values:
        return math.nan, math.nan, math.nan
    estimate = mean_difference_interval([values])
    return estimate.value, estimate.low, estimate.high


def reference_rows(
    summaries: Sequence[dict[str, Any]],
    references: Mapping[str, Mapping[str, Any]],
    metrics: Sequence[str],
    infos: Mapping[str, Mapping[str, "Metric"]],
) -> list[dict[str, Any]]:
    """
    One row per setting that has reference policies and per scheme or reference policy: each metric's mean over seeds
    and its 95% t interval; the references on the seeds the setting's runs here have (each seed's episodes are a
    run's), the schemes over their runs.

    :param summaries: Run summaries (``experiment``, ``scheme``, ``seed``, ``score``).
    :param references: Each setting's reference policies (:func:`load_references`).
    :param metrics: The report's metrics.
    :param infos: Each metric as each setting's task shows it: metric -> setting -> its ``Metric`` (scale, label).
    :return: Rows with ``setting``, ``kind`` (``"scheme"`` or ``"reference"``), ``name``, ``seeds`` (the seeds) and,
        per metric, ``(mean, low, high)`` in displayed units, or ``None`` where the metric is not scored.
    """
    from sb3_maddpg.experiments.config import ordered_schemes

    rows = []
    for setting, policies in references.items():
        runs = [summary for summary in summaries if summary["experiment"] == setting]
        if not runs:
            continue
        shown = [metric for metric in metrics if setting in infos.get(metric, {})]
        seeds = sorted({int(summary["seed"]) for summary in runs})
        groups: list[tuple[str, str, dict[int, Mapping[str, float]]]] = [
            (
                "scheme",
                scheme,
                {int(summary["seed"]): summary["score"] for summary in runs if summary["scheme"] == scheme},
            )
            for scheme in ordered_schemes(summary["scheme"] for summary in runs)
        ]
        groups += [
            ("reference", name, {seed: entry["seeds"][str(seed)]["score"] for seed in seeds if str(seed) in entry["seeds"]})
            for name, entry in policies.items()
        ]
        for kind, name, scores in groups:
            row: dict[str, Any] = {"setting": setting, "kind": kind, "name": name, "seeds": sorted(scores)}
            for metric in shown:
                scale = infos[metric][setting].scale
                values = [float(score[metric]) * scale for score in scores.values() if score.get(metric) is not None]
                values = [value for value in values if not math.isnan(value)]
                row[metric] = seed_interval(values) if values else None
            rows.append(row)
    return rows


def _interval_text(estimate: tuple[float, float, float] | None) -> str:
    if estimate is None:
        return ""
    mean, low, high = estimate
    return f"{mean:.2f}" + ("" if math.isnan(low) else f" [{low:.2f}, {high:.2f}]")


def format_references_markdown(
    rows: Sequence[dict[str, Any]],
    metrics: Sequence[str],
    infos: Mapping[str, Mapping[str, "Metric"]],
    experiments: Mapping[str, dict[str, Any]],
) -> str | None:
    """
    :param rows: From :func:`reference_rows`.
    :param metrics: The report's metrics.
    :param infos: Each metric as each setting's task shows it.
    :param experiments: The stored experiment configs (for setting labels and the episodes per evaluation).
    :return: Markdown: per setting, a row per scheme and per reference policy, a column per metric, each ``mean [95%
        interval]`` over seeds; ``None`` when no setting has reference policies.
    """
    from sb3_maddpg.experiments.config import PAPER_NAMES, setting_label

    if not rows:
        return None
    lines = ["### Reference policies beside the schemes", ""]
    for setting in dict.fromkeys(row["setting"] for row in rows):
        chosen = [row for row in rows if row["setting"] == setting]
        shown = [metric for metric in metrics if metric in chosen[0]]
        experiment = experiments.get(setting) or {}
        header = ["policy", "seeds"] + [
            f"{infos[m][setting].label} ({'higher' if infos[m][setting].higher_is_better else 'lower'} is better)"
            for m in shown
        ]
        lines += [
            f"#### {setting_label(setting, experiment)}",
            "",
            "| " + " | ".join(header) + " |",
            "|" + "|".join("---" for _ in header) + "|",
        ]
        for row in chosen:
            if row["kind"] == "reference":
                name = f"reference: {row['name']}"
            else:  # the paper's name of a scheme, with the scheme's where they differ
                paper = PAPER_NAMES.get(row["name"], row["name"])
                name = paper if paper == row["name"] else f"{paper} (`{row['name']}`)"
            cells = [name, ", ".join(map(str, row["seeds"]))] + [_interval_text(row[m]) for m in shown]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    episodes = {str((experiments.get(row["setting"]) or {}).get("eval_episodes", "?")) for row in rows}
    lines += [
        "Each cell: the mean over seeds and its 95% t interval (one value per seed). A scheme's value for a seed is its "
        "run's score (the mean of its checkpoints' evaluations); a reference policy's is its mean over the same "
        f"evaluation episodes ({' or '.join(sorted(episodes))} per seed, reset from the run's evaluation seed), on "
        "the seeds the runs here have. Reference policies: "
        + "; ".join(f"{kind}: {text}" for kind, text in REFERENCE_KINDS.items())
        + " (`sb3_maddpg.experiments.references`).",
        "",
    ]
    return "\n".join(lines)


def write_references_csv(rows: Sequence[dict[str, Any]], metrics: Sequence[str], path: str | Path) -> None:
    """
    One row per setting, policy and metric: ``setting, kind, name, metric, seeds, mean, low, high`` (seeds
    ``;``-separated).

    :param rows: From :func:`reference_rows`.
    :param metrics: The report's metrics.
    :param path: The CSV file.
    """

    with open(path, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["setting", "kind", "name", "metric", "seeds", "mean", "low", "high"])
        for row in rows:
            for metric in metrics:
                if row.get(metric) is not None:
                    writer.writerow(
                        [row["setting"], row["kind"], row["name"], metric, ";".join(map(str, row["seeds"]))]
                        + [repr(value) for value in row[metric]]
                    )
