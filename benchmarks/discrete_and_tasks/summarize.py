"""
Issue 10's measurements, summarised from ``results/`` (written by ``run.sh``): learning-curve evaluations (100
episodes each, deterministic actions, the evaluation env seeded from the run's seed) per seed and their mean.

- simple_spread N=3, full sharing: team return and min-dist sum at 0, 100k, 200k and 300k steps, continuous actions
  beside discrete (Gumbel-softmax), same seeds;
- speaker-listener: the listener's final distance to its goal (lower is better) and the team return;
- simple_tag: the adversaries' summed return (``group_return``) and catches per episode (``collisions``), both
  higher is better for the adversaries, whose critics and actors are trained here with the prey's.

Usage::

    python benchmarks/discrete_and_tasks/summarize.py [results] > results.md
"""

import csv
import statistics
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
TABLES = (
    ("spread_continuous", "spread_discrete", ("return_mean", "min_dist_sum")),
    ("speaker_listener", None, ("goal_distance", "return_mean")),
    ("tag", None, ("group_return", "collisions")),
)


def curves(results: Path, experiment: str, key: str) -> dict[int, dict[int, float]]:
    """``{seed: {step: value}}`` of a learning-curve column, finished runs only."""
    found = {}
    for run in sorted((results / experiment / "full").glob("seed_*")):
        if (run / "done").exists():
            with open(run / "learning_curve.csv", newline="") as file:
                found[int(run.name.removeprefix("seed_"))] = {
                    int(float(r["timesteps"])): float(r[key]) for r in csv.DictReader(file)
                }
    return found


def table(results: Path, experiments: tuple[str, ...], key: str) -> str:
    """:return: Markdown: a row per experiment and seed (and their mean), a column per evaluation step."""
    rows = {experiment: curves(results, experiment, key) for experiment in experiments}
    steps = sorted({step for by_seed in rows.values() for curve in by_seed.values() for step in curve})
    lines = [f"| {key} | seed | " + " | ".join(f"{step // 1000}k" for step in steps) + " |"]
    lines.append("|---|---|" + "---|" * len(steps))
    for experiment, by_seed in rows.items():
        for seed, curve in sorted(by_seed.items()):
            lines.append(
                f"| {experiment} | {seed} | " + " | ".join(f"{curve.get(step, float('nan')):.2f}" for step in steps) + " |"
            )
        if by_seed:
            means = [statistics.mean(curve[step] for curve in by_seed.values() if step in curve) for step in steps]
            lines.append(f"| {experiment} | mean | " + " | ".join(f"**{value:.2f}**" for value in means) + " |")
    return "\n".join(lines)


def main() -> None:
    """Print the tables."""
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    for first, second, keys in TABLES:
        experiments = (first,) if second is None else (first, second)
        for key in keys:
            print(table(results, experiments, key))
            print()


if __name__ == "__main__":
    main()
