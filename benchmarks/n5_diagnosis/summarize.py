"""
The N=5 diagnosis, summarised: each factor against the paper's configuration, same sweep, same seeds.

Reads the finished runs in ``results/`` (written by ``benchmarks/n5_diagnosis/run.sh``) and writes ``summary.md``
beside this file:

- per factor: the seeds finished; the score over the last 20% of training (mean of 20 checkpoint evaluations of 100
  episodes each, then mean and std over seeds) of the min-dist sum (lower is better), success and coverage within
  0.3, the team return, and the normalised scores (0 = random, 1 = the scripted controller); the gradient steps a run
  takes; the measured training throughput and wall time per run;
- per factor, learning curves in numbers: the mean over seeds of the min-dist sum at 200k, 400k, 600k, 800k and 1M env
  steps, and at equal gradient steps (2,500, 5,000, 10,000 and the paper's budget of 25,000 after the 25,600 random
  steps: where a run with more updates per transition gets there first).

Only seeds the paper's configuration has finished too are compared (like with like). One step per 10 transitions is
read from ``benchmarks/matd3/results`` (``BORROWED``): MATD3's comparison ran the same configuration, same code; the
paper's configuration to its full 2.5M steps (24,744 gradient steps) from ``benchmarks/paper_n5_outlook/results``
(its `full` runs; its 25,000-gradient-step cell is its curve's last point, 24,744 steps, within
:func:`~sb3_maddpg.experiments.results_dir.curve_value_at`'s 5%). Usage::

    python benchmarks/n5_diagnosis/summarize.py [results] [summary.md]
"""

import csv
import statistics
import sys
from pathlib import Path
from typing import Any

from sb3_maddpg.analysis.normalised_score import normalised_scores, reference_scores
from sb3_maddpg.experiments.config import algorithm_argument
from sb3_maddpg.experiments.results_dir import curve_value_at, load_experiments, load_summaries, read_curve

HERE = Path(__file__).resolve().parent
BASELINE = "n5_paper"
CURVE_STEPS = (200_000, 400_000, 600_000, 800_000, 1_000_000)
GRADIENT_STEPS = (2_500, 5_000, 10_000, 25_000)
BORROWED = {
    "n5_tpu10_maddpg": (
        HERE.parent / "matd3" / "results",
        "one gradient step per 10 transitions (run by benchmarks/matd3 as `n5_tpu10_maddpg`)",
    ),
    "n5_outlook": (
        HERE.parent / "paper_n5_outlook" / "results",
        "the paper's configuration to the paper's budget (run by benchmarks/paper_n5_outlook as `n5_outlook`)",
    ),
}
"""Factors another sweep ran in this one's configuration, read from its results so as not to run them twice: by
experiment, that sweep's results directory and the factor's label here."""


def mean_std(values: list[float]) -> str:
    """``mean (std)`` of the values, or the one value."""
    if len(values) == 1:
        return f"{values[0]:.3f}"
    return f"{statistics.mean(values):.3f} ({statistics.stdev(values):.3f})"


def behaviour_recorded_right(summary: dict[str, Any]) -> bool:
    """
    :return: Whether a run's recorded behaviour is of its last checkpoint's evaluated episodes: its min-dist sum is
        that evaluation's. Behaviour recorded before 2026-12-02 read nearest-first observations in index order and
        fails this; it is left out.
    """
    if "behaviour" not in summary:
        return False
    with open(Path(summary["directory"]) / "checkpoint_evals.csv", newline="") as file:
        last = list(csv.DictReader(file))[-1]
    return abs(summary["behaviour"]["min_dist_sum"] - float(last["min_dist_sum"])) < 1e-3


def summarise(results: Path) -> str:
    """:return: The Markdown of ``summary.md``."""
    summaries = load_summaries(results)
    experiments = load_experiments(results)
    for name, (elsewhere, label) in BORROWED.items():
        summaries += [s for s in load_summaries(elsewhere) if s["experiment"] == name and s["scheme"] == "full"]
        if name in (borrowed := load_experiments(elsewhere)):
            experiments[name] = {**borrowed[name], "description": label}
    references = reference_scores(5)
    baseline_seeds = {summary["seed"] for summary in summaries if summary["experiment"] == BASELINE}
    order = [BASELINE, *sorted({summary["experiment"] for summary in summaries} - {BASELINE})]
    lines = [
        "# N=5 diagnosis: each factor against the paper's configuration",
        "",
        "Setting: simple_spread N=5, full observability, `full` sharing, batched env of 100 worlds, 1M env steps per run "
        "(40,000 episodes) unless a factor says otherwise; score: mean of 20 checkpoint evaluations (100 episodes "
        "each) over the last 20% of training, "
        f"then mean (std) over the seeds listed (seeds the paper's configuration finished: {sorted(baseline_seeds)}). "
        "Min-dist sum: lower is better; success and coverage within 0.3, return and normalised scores: higher is "
        "better (normalised: 0 = uniformly random actions, 1 = the scripted controller; random min-dist sum "
        f"{references['random']['min_dist_sum']:.2f}, controller {references['scripted']['min_dist_sum']:.2f}).",
        "",
        "| factor | seeds | gradient steps | min-dist sum | normalised | success within 0.3 | coverage within 0.3 "
        "| team return | normalised | steps/s | wall time per run |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    curve_lines = [
        "",
        "## Learning curves in numbers: min-dist sum (mean over the same seeds; lower is better)",
        "",
        "| factor | "
        + " | ".join(f"{step // 1000}k steps" for step in CURVE_STEPS)
        + " | "
        + " | ".join(f"{steps:,} gradient steps" for steps in GRADIENT_STEPS)
        + " |",
        "|---|" + "---|" * (len(CURVE_STEPS) + len(GRADIENT_STEPS)),
    ]
    for name in order:
        runs = [s for s in summaries if s["experiment"] == name and s["seed"] in baseline_seeds]
        if not runs:
            continue
        experiment = experiments.get(name, {})
        ratio = int(algorithm_argument(experiment, "transitions_per_update"))
        warm_up = int(algorithm_argument(experiment, "learning_starts"))
        scores = [run["score"] for run in runs]
        normalised = [normalised_scores(score, references) for score in scores]
        label = experiment.get("description", name).removeprefix("N=5 diagnosis: ").split(";")[0]
        budget = int(experiment.get("episodes", 40_000)) * int(experiment.get("episode_length", 25))
        if budget != 1_000_000:
            label += f" ({budget // 1000:,}k env steps)"
        lines.append(
            f"| {label} | {', '.join(str(run['seed']) for run in runs)} | {(budget - warm_up) // ratio:,} | "
            f"{mean_std([s['min_dist_sum'] for s in scores])} | {mean_std([n['min_dist_sum'] for n in normalised])} | "
            f"{mean_std([s['success_rate_r0.3'] for s in scores])} | {mean_std([s['coverage_r0.3'] for s in scores])} | "
            f"{statistics.mean(s['return_mean'] for s in scores):.1f} | "
            f"{mean_std([n['return_mean'] for n in normalised])} | "
            f"{statistics.mean(run['train_steps_per_s'] for run in runs):,.0f} | "
            f"{statistics.mean(run['wall_time_s'] for run in runs) / 60:.0f} min |"
        )
        curves = [read_curve(run["directory"]) for run in runs]
        cells = []
        for step in [*CURVE_STEPS, *(warm_up + steps * ratio for steps in GRADIENT_STEPS)]:
            values = [value for value in (curve_value_at(rows, step) for rows in curves) if value is not None]
            cells.append(f"{statistics.mean(values):.2f}" if len(values) == len(curves) else "")
        curve_lines.append(f"| {label} | " + " | ".join(cells) + " |")
    behaviour_lines = [
        "",
        "## What the teams do at their episodes' end (last checkpoint, within 0.3; runs whose behaviour is recorded right)",
        "",
        "| factor | runs | landmarks covered (of 5) | crowded landmarks | strays | stray speed | assignment gap |",
        "|---|---|---|---|---|---|---|",
    ]
    for name in order:
        described = [s["behaviour"] for s in summaries if s["experiment"] == name and behaviour_recorded_right(s)]
        if described:
            label = experiments.get(name, {}).get("description", name).removeprefix("N=5 diagnosis: ").split(";")[0]
            means = {key: statistics.mean(b[key] for b in described) for key in described[0]}
            behaviour_lines.append(
                f"| {label} | {len(described)} | {means['covered']:.2f} | {means['crowded']:.2f} | {means['strays']:.2f} | "
                f"{means['stray_speed']:.2f} | {means['assignment_gap']:.2f} |"
            )
    if len(behaviour_lines) == 5:
        behaviour_lines = []
    notes = [
        "",
        "Throughput and wall time were measured with two runs at a time on a 2-core machine that was also running other "
        "work (tests and development): read them as ratios between factors, not as this machine's rate.",
        "",
        "Made by `bash benchmarks/n5_diagnosis/run.sh` (resumable; the row of one gradient step per 10 transitions by "
        "`bash benchmarks/matd3/run.sh`; the paper's configuration to its budget by benchmarks/paper_n5_outlook, whose README "
        "has its command), then `python benchmarks/n5_diagnosis/summarize.py`.",
    ]
    return "\n".join(lines + curve_lines + behaviour_lines + notes) + "\n"


if __name__ == "__main__":
    results_dir = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE / "summary.md"
    out.write_text(summarise(results_dir))
    print(out.read_text())
