"""The learning curve that sets issue 43's budget, and the budget the rule picks (writes curve_summary.md).

    python benchmarks/paper_n5_independent/curve_summary.py

Reads results/paper_n5_indep_curve/full/seed_*/learning_curve.csv (50 points x 50 greedy episodes per seed) and puts
each point's min-dist sum on the normalised scale (0 = random actions, 1 = the scripted controller; higher is better;
``sb3_maddpg.analysis.normalised_score``). The rule: the budget is the shortest multiple of 250k env steps at which, on
every seed, the curve (a running mean over 5 points, +-100k steps) has left random actions behind (normalised score
>= 0.5) and the rest of the 2.5M steps adds less than 0.05 to it ("stopped improving fast").
"""

import csv
import sys
from pathlib import Path

import numpy as np

from sb3_maddpg.analysis.normalised_score import normalised_score, reference_scores

HERE = Path(__file__).resolve().parent
CURVES = HERE / "results" / "paper_n5_indep_curve" / "full"
LEFT_RANDOM, STILL_GAINING, CANDIDATE_STEP, SMOOTHING = 0.5, 0.05, 250_000, 5
FULL_CURVE = 2_500_000


def read_curve(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """:return: The curve's env steps and min-dist sums."""
    with path.open() as file:
        rows = list(csv.DictReader(file))
    return np.array([float(row["timesteps"]) for row in rows]), np.array([float(row["min_dist_sum"]) for row in rows])


def smoothed(values: np.ndarray, width: int = SMOOTHING) -> np.ndarray:
    """A centred running mean (shorter at the ends)."""
    half = width // 2
    return np.array([values[max(0, i - half) : i + half + 1].mean() for i in range(len(values))])


def chosen_budget(steps: np.ndarray, scores: list[np.ndarray]) -> int | None:
    """:return: The rule's budget (see the module docstring), or None if no candidate meets it yet."""
    final = min(len(score) for score in scores) - 1
    for candidate in range(CANDIDATE_STEP, int(steps[final]) + 1, CANDIDATE_STEP):
        at = int(np.searchsorted(steps, candidate))
        if at > final:
            break
        if all(score[at] >= LEFT_RANDOM and score[final] - score[at] < STILL_GAINING for score in scores):
            return candidate
    return None


def main() -> int:
    seeds = sorted(path for path in CURVES.glob("seed_*") if (path / "learning_curve.csv").exists())
    if not seeds:
        print(f"no learning curves under {CURVES}", file=sys.stderr)
        return 1
    references = reference_scores(5)
    random, scripted = references["random"]["min_dist_sum"], references["scripted"]["min_dist_sum"]
    curves = [read_curve(seed / "learning_curve.csv") for seed in seeds]
    length = min(len(steps) for steps, _ in curves)
    steps = curves[0][0][:length]
    raw = [np.array([normalised_score(value, random, scripted) for value in dist[:length]]) for _, dist in curves]
    scores = [smoothed(score) for score in raw]
    complete = steps[-1] >= FULL_CURVE
    budget = chosen_budget(steps, scores) if complete else None
    lines = [
        "# The learning curve of `full` with independent actors and critics (issue 43)",
        "",
        "exp1_tuned's configuration (N=5, every agent and landmark observed nearest first, one gradient step per 25",
        "transitions, tuned learning rate, noise, tau and gamma) with `share_parameters=False`: each agent its own actor",
        f"and critic, as the paper. Seeds {', '.join(seed.name[-1] for seed in seeds)}; each point 50 greedy episodes.",
        f"Normalised min-dist sum: 0 = random actions ({random:.2f}), 1 = the scripted controller ({scripted:.2f}); "
        "higher is better.",
        f"Smoothed: a running mean over {SMOOTHING} points. Made by `python {Path(__file__).relative_to(HERE.parents[1])}`.",
        "",
        "| env steps | " + " | ".join(f"seed {seed.name[-1]}: min-dist / normalised (smoothed)" for seed in seeds) + " |",
        "|---|" + "---|" * len(seeds),
    ]
    for i, step in enumerate(steps):
        if int(step) % 100_000 == 0:
            cells = [f"{dist[i]:.2f} / {raw[s][i]:.2f} ({scores[s][i]:.2f})" for s, (_, dist) in enumerate(curves)]
            lines.append(f"| {int(step):,} | " + " | ".join(cells) + " |")
    lines += [
        "",
        f"The rule: the shortest multiple of {CANDIDATE_STEP:,} steps at which every seed's smoothed normalised score "
        f"is >= {LEFT_RANDOM} and the rest of the curve (to {int(steps[-1]):,} steps) adds less than {STILL_GAINING}.",
        f"**Budget: {budget:,} env steps.**"
        if budget
        else "**No budget meets the rule within the curve.**"
        if complete
        else f"**The curve is still running ({int(steps[-1]):,} of {FULL_CURVE:,} steps): no budget yet.**",
    ]
    (HERE / "curve_summary.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
