"""Summarise a run group's runs on a device (``gpu_check.sh``): their speed, their scores, and what the paper's
protocol would take at that speed.

Usage: ``python benchmarks/paper_n5/gpu_summary.py RESULTS/EXPERIMENT``.
"""

import csv
import json
import sys
from pathlib import Path

import numpy as np

PAPER_PROTOCOL_STEPS = 5 * 31 * (2_500_000 + 3_750_000)
"""The paper's two experiments: 5 schemes x 31 seeds, 100,000 and 150,000 episodes of 25 steps."""
N5_STUDY_STEPS = 60 * 1_000_000
"""This study (benchmarks/paper_n5): six schemes x 5 seeds x two settings, 1M steps each."""


def steps_per_second(progress: Path, first: float, last: float) -> float:
    """
    :param progress: A run's SB3 log (``time/total_timesteps``, ``time/time_elapsed``).
    :param first: The first step of the window.
    :param last: The last step of the window.
    :return: The run's env steps per second between the two (``nan`` if the log has too few rows there).
    """
    with progress.open(newline="") as file:
        rows = [
            (float(row["time/total_timesteps"]), float(row["time/time_elapsed"]))
            for row in csv.DictReader(file)
            if row.get("time/time_elapsed") and first <= float(row["time/total_timesteps"]) <= last
        ]
    if len(rows) < 2 or rows[-1][1] <= rows[0][1]:
        return float("nan")
    return (rows[-1][0] - rows[0][0]) / (rows[-1][1] - rows[0][1])


def main(experiment: Path, learning_starts: int = 25_600, checkpoint_fraction: float = 0.2) -> None:
    """
    :param experiment: The experiment's results directory.
    :param learning_starts: The random steps before training (the presets' 25,600).
    :param checkpoint_fraction: The last part of training, where the checkpoints are evaluated.
    """
    summaries = [json.loads(path.read_text()) for path in sorted(experiment.glob("*/seed_*/summary.json"))]
    if not summaries:
        print(f"no finished runs under {experiment}")
        return
    train_s = max(summary["train_time_s"] for summary in summaries)
    steps = int(summaries[0]["total_timesteps"])
    runs = len(summaries)
    devices = ", ".join(sorted({summary.get("device", "?") for summary in summaries}))
    together = sorted({summary.get("runs_trained_together", 1) for summary in summaries})
    progress = sorted(experiment.glob("*/seed_*/progress.csv"))
    if together != [runs]:
        print(f"note: the runs did not all train in one group ({together} together): the sums below assume they did")
    # A group's runs step together: the summed speed is one run's speed times the runs.
    training = runs * np.nanmedian([steps_per_second(p, learning_starts, (1 - checkpoint_fraction) * steps) for p in progress])
    checkpoints = runs * np.nanmedian([steps_per_second(p, (1 - checkpoint_fraction) * steps, steps) for p in progress])
    print(f"{runs} runs of {experiment.name} on {devices}, {together} trained together, {steps:,} env steps each")
    print()
    print("| phase | env steps/s, summed over the runs |")
    print("|---|---|")
    print(f"| the whole training (random steps, updates, checkpoints, curve points) | {runs * steps / train_s:,.0f} |")
    print(f"| training, before the checkpoints (past {learning_starts:,} random steps) | {training:,.0f} |")
    print(f"| the last {checkpoint_fraction:.0%}, training while saving its checkpoints | {checkpoints:,.0f} |")
    print()
    hours = PAPER_PROTOCOL_STEPS / training / 3600
    print(f"At the training speed, the paper's protocol ({PAPER_PROTOCOL_STEPS:,} env steps, 310 runs): {hours:.1f} h,")
    print(f"and this study's 60 runs of 1M steps in {N5_STUDY_STEPS / training / 3600:.2f} h, evaluations not counted.")
    print()
    print("| seed | min-dist sum (lower is better) | success within 0.3 (%) |")
    print("|---|---|---|")
    for summary in summaries:
        score = summary["score"]
        print(f"| {summary['seed']} | {score['min_dist_sum']:.3f} | {100 * score['success_rate_r0.3']:.1f} |")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
