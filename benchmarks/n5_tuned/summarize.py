"""
The N=5 target runs, summarised against issue 21's target: each seed's score over the last 20% of the paper's 2.5M
env steps (mean of 20 checkpoint evaluations of 100 episodes), their mean (std), the normalised scores, and the
learning curve's min-dist sum at equal env steps; reads ``results/`` (written by ``benchmarks/n5_tuned/run.sh``) and
writes ``summary.md`` beside this file. Unfinished runs show their curve so far. Usage::

    python benchmarks/n5_tuned/summarize.py [results] [summary.md]
"""

import csv
import statistics
import sys
from pathlib import Path

from sb3_maddpg.experiments.results import load_summaries
from sb3_maddpg.normalised_score import normalised_scores, reference_scores

HERE = Path(__file__).resolve().parent
CURVE_STEPS = (200_000, 400_000, 1_000_000, 1_500_000, 2_000_000, 2_500_000)
TARGET = {"min_dist_sum": 0.8, "success_rate_r0.3": 0.30}
"""Issue 21's target at N=5 within 2.5M steps: min-dist sum at most 0.8, success within 0.3 at least 30%."""
PAPER_AT_BUDGET = {"min_dist_sum": 1.79, "success_rate_r0.3": 0.03}
"""The paper's configuration after the same 2.5M steps (the committed N=5 outlook, 3 seeds)."""


def curve(path: Path) -> dict[int, float]:
    """:return: A run's learning curve, min-dist sum by env step."""
    with open(path, newline="") as file:
        return {int(float(row["timesteps"])): float(row["min_dist_sum"]) for row in csv.DictReader(file)}


def mean_std(values: list[float], digits: int = 3) -> str:
    """:return: ``mean (std)`` of the values, or the one value."""
    if len(values) == 1:
        return f"{values[0]:.{digits}f}"
    return f"{statistics.mean(values):.{digits}f} ({statistics.stdev(values):.{digits}f})"


def summarise(results: Path) -> str:
    """:return: The Markdown of ``summary.md``."""
    summaries = sorted(load_summaries(results), key=lambda summary: summary["seed"])
    references = reference_scores(5)
    lines = [
        "# N=5 against issue 21's target",
        "",
        "Setting: simple_spread N=5, exp1 (full observability, `full` sharing), agents and landmarks observed nearest "
        "first, one gradient step per 25 transitions, one actor and one critic shared by all agents, the paper's "
        "other hyperparameters, 100 batched worlds, 2.5M env steps (the paper's budget). Score: mean of 20 checkpoint "
        "evaluations (100 episodes each) over the last 20% of training. Min-dist sum: lower is better; success within "
        "0.3 and normalised scores: higher is better (0 = uniformly random actions, 1 = the scripted controller: "
        f"min-dist sum {references['random']['min_dist_sum']:.2f} and {references['scripted']['min_dist_sum']:.2f}). "
        f"Target: min-dist sum at most {TARGET['min_dist_sum']}, success within 0.3 at least "
        f"{TARGET['success_rate_r0.3']:.0%}; the paper's configuration after the same budget: "
        f"{PAPER_AT_BUDGET['min_dist_sum']} and {PAPER_AT_BUDGET['success_rate_r0.3']:.0%}.",
        "",
        "| seed | min-dist sum | success within 0.3 | coverage within 0.3 | team return | normalised (min-dist, return) "
        "| gradient steps | train time |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for summary in summaries:
        score = summary["score"]
        normalised = normalised_scores(score, references)
        gradient_steps = (summary["total_timesteps"] - 25_600) // 25
        lines.append(
            f"| {summary['seed']} | {score['min_dist_sum']:.3f} | {score['success_rate_r0.3']:.1%} | "
            f"{score['coverage_r0.3']:.3f} | {score['return_mean']:.1f} | {normalised['min_dist_sum']:.2f}, "
            f"{normalised['return_mean']:.2f} | {gradient_steps:,} | {summary['train_time_s'] / 60:.0f} min |"
        )
    if summaries:
        scores = [summary["score"] for summary in summaries]
        dist = [score["min_dist_sum"] for score in scores]
        success = [score["success_rate_r0.3"] for score in scores]
        met = statistics.mean(dist) <= TARGET["min_dist_sum"] and statistics.mean(success) >= TARGET["success_rate_r0.3"]
        lines += [
            f"| mean (std) | {mean_std(dist)} | {mean_std([100 * s for s in success], 1)}% | "
            f"{mean_std([score['coverage_r0.3'] for score in scores])} | "
            f"{mean_std([score['return_mean'] for score in scores], 1)} | | | |",
            "",
            f"Target {'met' if met else 'not met'} by the mean over the {len(summaries)} finished seed(s).",
        ]
    lines += ["", "## Learning curve: min-dist sum (20-episode evaluations; lower is better)", ""]
    lines += ["| seed | " + " | ".join(f"{step / 1e6:g}M" for step in CURVE_STEPS) + " |"]
    lines += ["|---|" + "---|" * len(CURVE_STEPS)]
    for path in sorted(results.glob("*/full/seed_*/learning_curve.csv")):
        points = curve(path)
        cells = [f"{points[step]:.2f}" if step in points else "" for step in CURVE_STEPS]
        lines.append(f"| {int(path.parent.name.removeprefix('seed_'))} | " + " | ".join(cells) + " |")
    lines += ["", "Made by `bash benchmarks/n5_tuned/run.sh` (resumable), then `python benchmarks/n5_tuned/summarize.py`."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE / "summary.md"
    out.write_text(summarise(results))
    print(out.read_text())
