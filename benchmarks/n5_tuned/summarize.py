"""
The N=5 target runs, summarised against issue 21's target, for each experiment: each seed's score over the last 20%
of the paper's 2.5M env steps (mean of 20 checkpoint evaluations of 100 episodes), their mean (std), the normalised
scores, and the learning curve's min-dist sum at equal env steps and at the paper's 25,000 gradient steps; reads
``results/`` (written by ``benchmarks/n5_tuned/run.sh``) and writes ``summary.md`` beside this file.
Unfinished runs show their curve so far. Usage::

    python benchmarks/n5_tuned/summarize.py [results] [summary.md]
"""

import json
import statistics
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sb3_maddpg.analysis.normalised_score import normalised_scores, reference_scores
from sb3_maddpg.experiments.config import algorithm_argument
from sb3_maddpg.experiments.results_dir import curve_value_at, load_summaries, read_curve

HERE = Path(__file__).resolve().parent
CURVE_STEPS = (200_000, 400_000, 600_000, 800_000, 1_000_000, 1_500_000, 2_000_000, 2_500_000)
TARGET = {"min_dist_sum": 0.8, "success_rate_r0.3": 0.30}
"""Issue 21's target at N=5 within 2.5M steps: min-dist sum at most 0.8, success within 0.3 at least 30%."""
PAPER_GRADIENT_STEPS = 25_000
"""The paper's gradient steps in its budget: 2.5M env steps at one per 100 transitions."""
PAPER_AT_BUDGET = {"min_dist_sum": 1.79, "success_rate_r0.3": 0.03}
"""The paper's configuration after the same 2.5M steps (the committed N=5 outlook, 3 seeds)."""
TUNED_PARAMETERS = {"learning_rate": "learning rate", "noise_std": "noise", "tau": "tau", "gamma": "gamma"}
"""The parameters the tuning study (``benchmarks/n5_tuning``) set away from the paper's, by their names in headings."""


def mean_std(values: list[float], digits: int = 3) -> str:
    """:return: ``mean (std)`` of the values, or the one value."""
    if len(values) == 1:
        return f"{values[0]:.{digits}f}"
    return f"{statistics.mean(values):.{digits}f} ({statistics.stdev(values):.{digits}f})"


def score_lines(runs: list[dict[str, Any]], ratio: int, warm_up: int, references: dict[str, dict[str, float]]) -> list[str]:
    """:return: The Markdown table of each seed's score, and their mean (std) against the target."""
    lines = [
        "| seed | min-dist sum | success within 0.3 | coverage within 0.3 | team return | normalised (min-dist, return) "
        "| gradient steps | train time |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for summary in runs:
        score = summary["score"]
        normalised = normalised_scores(score, references)
        gradient_steps = (summary["total_timesteps"] - warm_up) // ratio
        lines.append(
            f"| {summary['seed']} | {score['min_dist_sum']:.3f} | {score['success_rate_r0.3']:.1%} | "
            f"{score['coverage_r0.3']:.3f} | {score['return_mean']:.1f} | {normalised['min_dist_sum']:.2f}, "
            f"{normalised['return_mean']:.2f} | {gradient_steps:,} | {summary['train_time_s'] / 60:.0f} min |"
        )
    if runs:
        scores = [summary["score"] for summary in runs]
        dist = [score["min_dist_sum"] for score in scores]
        success = [score["success_rate_r0.3"] for score in scores]
        met = statistics.mean(dist) <= TARGET["min_dist_sum"] and statistics.mean(success) >= TARGET["success_rate_r0.3"]
        lines += [
            f"| mean (std) | {mean_std(dist)} | {mean_std([100 * s for s in success], 1)}% | "
            f"{mean_std([score['coverage_r0.3'] for score in scores])} | "
            f"{mean_std([score['return_mean'] for score in scores], 1)} | | | |",
            "",
            f"Target {'met' if met else 'not met'} by the mean over the {len(runs)} finished seed(s).",
        ]
    return lines


def curve_lines(results: Path, name: str, ratio: int, warm_up: int, steps: tuple[int, ...] = CURVE_STEPS) -> list[str]:
    """:return: The Markdown table of each seed's learning curve, finished or not, at ``steps`` env steps and at the
    paper's gradient steps."""
    lines = [
        "| seed | "
        + " | ".join(f"{step / 1e6:g}M" for step in steps)
        + f" | at the paper's {PAPER_GRADIENT_STEPS:,} gradient steps |",
        "|---|" + "---|" * (len(steps) + 1),
    ]
    for path in sorted(results.glob(f"{name}/full/seed_*/learning_curve.csv")):
        rows = read_curve(path.parent)
        values = [curve_value_at(rows, step) for step in steps]
        values.append(curve_value_at(rows, warm_up + PAPER_GRADIENT_STEPS * ratio))
        cells = ["" if value is None else f"{value:.2f}" for value in values]
        lines.append(f"| {int(path.parent.name.removeprefix('seed_'))} | " + " | ".join(cells) + " |")
    return lines


def experiment_sections(
    results: Path, first: str, title: Callable[[dict[str, Any], int], str], steps: tuple[int, ...] = CURVE_STEPS
) -> list[str]:
    """
    :param results: A results directory.
    :param first: The experiment shown first; the others follow by name.
    :param title: An experiment's heading from its stored config and its transitions per gradient step.
    :param steps: The env steps of the learning-curve table.
    :return: For each experiment in ``results``: its heading, each seed's score and their mean (std), its curve.
    """
    summaries = sorted(load_summaries(results), key=lambda summary: summary["seed"])
    experiments = {path.parent.name: json.loads(path.read_text()) for path in sorted(results.glob("*/experiment.json"))}
    references = reference_scores(5)
    lines: list[str] = []
    for name in sorted(experiments, key=lambda name: (name != first, name)):
        experiment = experiments[name]
        ratio = int(algorithm_argument(experiment, "transitions_per_update"))
        warm_up = int(algorithm_argument(experiment, "learning_starts"))
        lines += ["", f"## `{name}`: {title(experiment, ratio)}", ""]
        lines += score_lines([summary for summary in summaries if summary["experiment"] == name], ratio, warm_up, references)
        lines += ["", "Learning curve: min-dist sum (20-episode evaluations; lower is better).", ""]
        lines += curve_lines(results, name, ratio, warm_up, steps)
    return lines


def score_reading(references: dict[str, dict[str, float]]) -> str:
    """:return: How to read the scores: what a score is, which direction is better, what 0 and 1 normalised are."""
    return (
        "Score: mean of 20 checkpoint evaluations (100 episodes each) over the last 20% of training. Min-dist sum: lower "
        "is better; success within 0.3 and normalised scores: higher is better (0 = uniformly random actions, 1 = the "
        f"scripted controller: min-dist sum {references['random']['min_dist_sum']:.2f} and "
        f"{references['scripted']['min_dist_sum']:.2f})."
    )


def heading(experiment: dict[str, Any], ratio: int) -> str:
    """:return: An experiment's heading: its update ratio and any values the tuning study set."""
    tuned = [
        f"{label} {experiment['model_kwargs'][key]:.2g}"
        for key, label in TUNED_PARAMETERS.items()
        if key in experiment["model_kwargs"]
    ]
    return f"one gradient step per {ratio} transitions" + (
        f", the tuning study's best trial ({', '.join(tuned)})" if tuned else ""
    )


def summarise(results: Path) -> str:
    """:return: The Markdown of ``summary.md``."""
    references = reference_scores(5)
    lines = [
        "# N=5 against issue 21's target",
        "",
        "Setting: simple_spread N=5, exp1 (full observability, `full` sharing), agents and landmarks observed nearest "
        "first, one actor and one critic shared by all agents, the paper's other hyperparameters unless a heading says "
        "otherwise, 100 batched worlds, "
        "2.5M env steps (the paper's budget); one gradient step per 25 transitions (`n5_tuned_shared`), the same with "
        "the tuning study's best values (`n5_tuned_shared_best`, the shipped `exp1_tuned`), and one step per the "
        "paper's 100 transitions (`n5_tuned_shared_tpu100`). " + score_reading(references) + " "
        f"Target: min-dist sum at most {TARGET['min_dist_sum']}, success within 0.3 at least "
        f"{TARGET['success_rate_r0.3']:.0%}; the paper's configuration after the same budget "
        f"({PAPER_GRADIENT_STEPS:,} gradient steps): {PAPER_AT_BUDGET['min_dist_sum']} and "
        f"{PAPER_AT_BUDGET['success_rate_r0.3']:.0%}.",
    ]
    lines += experiment_sections(results, "n5_tuned_shared", heading)
    lines += ["", "Made by `bash benchmarks/n5_tuned/run.sh` (resumable), then `python benchmarks/n5_tuned/summarize.py`."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE / "summary.md"
    out.write_text(summarise(results))
    print(out.read_text())
