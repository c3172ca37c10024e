"""
MATD3 against MADDPG, summarised: for each setting (N=3, N=5, N=5 at one gradient step per 10 transitions) and
scheme, both algorithms' scores over the last 20% of training from the same sweep, their difference tested, their
learning curves, and the cost.

Reads the finished runs in ``results/`` (written by ``benchmarks/matd3/run.sh``) and ``update_cost.json`` and writes
``summary.md`` beside this file:

- per setting and scheme: each algorithm's seeds, min-dist sum (lower is better), normalised score (0 = random, 1 =
  the scripted controller), success within 0.3 and team return (higher is better), mean (std) over its seeds, its
  measured env steps per second; and the two-sided Mann-Whitney U test of MATD3's min-dist sums against MADDPG's
  (with 3 seeds each, p = 0.1 is the smallest it can give: a direction, not a significant result);
- the learning curves' min-dist sum (mean over seeds) at 20%, 40%, ..., 100% of each setting's env steps;
- the measured cost of a gradient step (``update_cost.py``).

Only settings where both algorithms have a finished run are compared. Usage::

    python benchmarks/matd3/summarize.py [results] [summary.md]
"""

import json
import sys
from pathlib import Path
from typing import Any

from sb3_maddpg.analysis.normalised_score import normalised_scores, reference_scores
from sb3_maddpg.experiments.results_dir import curve_value_at, load_experiments, load_summaries, read_curve
from sb3_maddpg.results.stats import mann_whitney, mean_std

HERE = Path(__file__).resolve().parent
SETTINGS = {
    "n3": ("N=3", "N=3, one gradient step per 100 transitions (the paper's)"),
    "n5": ("N=5", "N=5, one gradient step per 100 transitions (the paper's)"),
    "n5_tpu10": ("N=5, 1 per 10", "N=5, one gradient step per 10 transitions"),
}
"""The sweep's settings, with a short and a long label: experiment ``<setting>_maddpg`` against ``<setting>_matd3``."""
REFERENCE_SETTING = {"n5_tpu10": ("n5", "N=5, 1 per 100")}
"""A setting's curves are shown beside another's (its experiments' prefix, its label) at the same env steps: one step
per 10 transitions beside the paper's one per 100, the comparison that asks whether twin critics fix what more updates
per transition did to MADDPG."""
ALGORITHMS = ("maddpg", "matd3")
CURVE_FRACTIONS = (0.2, 0.4, 0.6, 0.8, 1.0)
"""The learning curves' columns, as fractions of a setting's budget."""


def cell(values: list[float], digits: int = 3, scale: float = 1.0) -> str:
    """:return: ``mean (std)`` of the values (times ``scale``), the one value, or blank for none."""
    if not values:
        return ""
    mean, std = mean_std([scale * value for value in values])
    return f"{mean:.{digits}f}" if len(values) == 1 else f"{mean:.{digits}f} ({std:.{digits}f})"


def algorithm_row(label: str, runs: list[dict[str, Any]], references: dict[str, dict[str, float]]) -> str:
    """:return: One algorithm's row of the score table."""
    scores = [run["score"] for run in runs]
    normalised = [normalised_scores(score, references)["min_dist_sum"] for score in scores]
    return (
        f"| {label} | {', '.join(str(run['seed']) for run in runs)} | "
        f"{cell([score['min_dist_sum'] for score in scores])} | {cell(normalised, 2)} | "
        f"{cell([score['success_rate_r0.3'] for score in scores], 1, 100.0)}% | "
        f"{cell([score['return_mean'] for score in scores], 1)} | "
        f"{cell([run['train_steps_per_s'] for run in runs], 0)} |"
    )


def curve_means(runs: list[dict[str, Any]], steps: list[int]) -> list[str]:
    """:return: The runs' mean learning-curve min-dist sum at each env step, empty where a run has no value there."""
    curves = [read_curve(run["directory"]) for run in runs]
    cells = []
    for step in steps:
        values = [curve_value_at(rows, step) for rows in curves]
        known = [value for value in values if value is not None]
        cells.append(f"{sum(known) / len(known):.2f}" if known and len(known) == len(values) else "")
    return cells


def update_cost_lines(path: Path) -> list[str]:
    """:return: The table of the measured cost of a gradient step, or nothing if it was not measured."""
    if not path.exists():
        return []
    lines = [
        "",
        "## The cost of a gradient step (`update_cost.py`, CPU time per step, one torch thread, batch 1024)",
        "",
        "| N | scheme | MADDPG (ms) | MATD3 (ms, ratio) | MATD3 with `policy_delay=1` (ms, ratio) |",
        "|---|---|---|---|---|",
    ]
    for row in json.loads(path.read_text())["rows"]:
        cells = [f"{row[name]['cpu_ms']:.1f} ({row['ratio'][name]:.2f}x)" for name in ("MATD3", "MATD3 (policy_delay=1)")]
        lines.append(f"| {row['n_agents']} | {row['scheme']} | {row['MADDPG']['cpu_ms']:.1f} | " + " | ".join(cells) + " |")
    return lines


def summarise(results: Path, update_cost: Path) -> str:
    """:return: The Markdown of ``summary.md``."""
    summaries = load_summaries(results)
    experiments = load_experiments(results)
    lines = [
        "# MATD3 against MADDPG",
        "",
        "Setting: simple_spread, full observability, the paper's hyperparameters (TD3's `policy_delay=2`, "
        "`target_policy_noise=0.2`, `target_noise_clip=0.5` for MATD3), batched env of 100 worlds, 1M env steps per run "
        "(40,000 episodes) unless a section says otherwise. Score: mean of 20 checkpoint evaluations (100 episodes "
        "each) over the last 20% of training, then mean (std) over the seeds listed. Min-dist sum: lower is better; "
        "normalised score (of the min-dist sum: 0 = uniformly random actions, 1 = the scripted controller), success "
        "within 0.3 and team return: higher is better. p: two-sided Mann-Whitney U of MATD3's min-dist sums against "
        "MADDPG's; with 3 seeds each the smallest p it can give is 0.1, so a p of 0.1 says every MATD3 seed was on one "
        "side of every MADDPG seed, not that the difference is significant.",
    ]
    curve_lines = [
        "",
        "## Learning curves: min-dist sum (20-episode evaluations, mean over the seeds; lower is better)",
    ]
    curve_steps: list[int] = []
    for setting, (short, label) in SETTINGS.items():
        names = [f"{setting}_{algorithm}" for algorithm in ALGORITHMS]
        if not all(any(s["experiment"] == name for s in summaries) for name in names):
            continue
        references = reference_scores(int(experiments[names[0]]["n_agents"]))
        budget = int(experiments[names[0]]["episodes"]) * int(experiments[names[0]]["episode_length"])
        steps = [round(fraction * budget) for fraction in CURVE_FRACTIONS]
        if budget != 1_000_000:
            label += f", {budget // 1000:,}k env steps per run"
        if steps != curve_steps:
            curve_steps = steps
            curve_lines += [
                "",
                "| setting | scheme | algorithm | " + " | ".join(f"{step // 1000}k" for step in steps) + " |",
                "|---|---|---|" + "---|" * len(steps),
            ]
        lines += [
            "",
            f"## {label}",
            "",
            "| scheme | algorithm | seeds | min-dist sum | normalised | success within 0.3 | team return | steps/s |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for scheme in experiments[names[0]]["schemes"]:
            runs = {
                name: sorted(
                    (s for s in summaries if s["experiment"] == name and s["scheme"] == scheme), key=lambda s: s["seed"]
                )
                for name in names
            }
            for name, algorithm in zip(names, ("MADDPG", "MATD3"), strict=True):
                lines.append(f"| {scheme} " + algorithm_row(algorithm, runs[name], references))
                curve_lines.append(
                    f"| {short} | {scheme} | {algorithm} | " + " | ".join(curve_means(runs[name], curve_steps)) + " |"
                )
            if setting in REFERENCE_SETTING:
                reference_setting, reference_label = REFERENCE_SETTING[setting]
                for algorithm in ALGORITHMS:
                    reference_runs = [
                        s for s in summaries if s["experiment"] == f"{reference_setting}_{algorithm}" and s["scheme"] == scheme
                    ]
                    curve_lines.append(
                        f"| {reference_label} | {scheme} | {algorithm.upper()} | "
                        + " | ".join(curve_means(reference_runs, curve_steps))
                        + " |"
                    )
            u, p = mann_whitney(*([run["score"]["min_dist_sum"] for run in runs[name]] for name in reversed(names)))
            lines.append(f"| {scheme} | MATD3 against MADDPG | | U = {u:g}, p = {p:.2f} | | | | |")
    notes = [
        "",
        "Throughput was measured with several runs at a time on a 2-core machine that was also running other work: "
        "read it as a ratio between the algorithms, not as this machine's rate.",
        "",
        "Made by `bash benchmarks/matd3/run.sh` (resumable), then `python benchmarks/matd3/summarize.py`.",
    ]
    return "\n".join(lines + curve_lines + update_cost_lines(update_cost) + notes) + "\n"


if __name__ == "__main__":
    results_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE / "summary.md"
    out.write_text(summarise(results_dir, HERE / "update_cost.json"))
    print(out.read_text())
