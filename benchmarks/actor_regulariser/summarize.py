"""
Tables for the actor-regulariser measurement: team return, min-dist sum and action saturation every 100k steps.

Reads the runs in ``results/`` (written by ``sb3-maddpg run``, see README.md) and prints markdown: for each
team size, scheme and regulariser setting, the mean (and standard deviation) over seeds of

- the team return and the min-dist sum of the learning-curve evaluations (100 episodes, deterministic actions);
- ``train/action_saturation`` from SB3's log (fraction of action components with ``|a| > 0.99`` on the update
  batches), the logged row nearest each step.

Usage::

    python benchmarks/actor_regulariser/summarize.py [results] > tables.md
"""

import csv
import statistics
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
STEPS = [0, *range(100_000, 1_000_001, 100_000)]


def read_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def curve(run: Path, key: str) -> dict[int, float]:
    """A learning-curve column by step."""
    return {int(float(row["timesteps"])): float(row[key]) for row in read_rows(run / "learning_curve.csv")}


def saturation(run: Path) -> dict[int, float]:
    """The logged saturation nearest each of STEPS (none at step 0: no update yet)."""
    logged = [
        (int(row["time/total_timesteps"]), float(row["train/action_saturation"]))
        for row in read_rows(run / "progress.csv")
        if row.get("train/action_saturation") and row.get("time/total_timesteps")
    ]
    return {step: min(logged, key=lambda item: abs(item[0] - step))[1] for step in STEPS[1:]} if logged else {}


def cell(values: list[float], digits: int) -> str:
    if not values:
        return ""
    spread = f" ({statistics.stdev(values):.{digits}f})" if len(values) > 1 else ""
    return f"{statistics.mean(values):.{digits}f}{spread}"


def table(results: Path, title: str, read: str, digits: int) -> str:
    lines = [f"### {title}", "", "| N | scheme | regulariser | " + " | ".join(f"{s // 1000}k" for s in STEPS) + " |"]
    lines.append("|---|---|---|" + "---|" * len(STEPS))
    for n_agents in (3, 5):
        for scheme in ("full", "selected"):
            for setting, label in (("reg", "1e-3"), ("noreg", "off")):
                runs = sorted((results / f"n{n_agents}_{setting}" / scheme).glob("seed_*"))
                runs = [run for run in runs if (run / "done").exists()]
                if not runs:
                    continue
                series = [saturation(run) if read == "saturation" else curve(run, read) for run in runs]
                cells = [cell([s[step] for s in series if step in s], digits) for step in STEPS]
                lines.append(f"| {n_agents} | {scheme} | {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    print(table(results, "Team return (higher is better), mean (std) over seeds", "return_mean", 1))
    print()
    print(table(results, "Min-dist sum at the last step (lower is better)", "min_dist_sum", 2))
    print()
    print(table(results, "Action saturation, fraction of components with |a| > 0.99 (update batches)", "saturation", 2))


if __name__ == "__main__":
    main()
