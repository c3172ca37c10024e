"""The learning curves of `full` with independent networks, and the budget the rule picks (issue 43).

    python benchmarks/paper_n5_independent/curve_summary.py                  # Exp. 1: curve_summary.md
    python benchmarks/paper_n5_independent/curve_summary.py --setting exp2   # Exp. 2: curve_summary_exp2.md

Reads a setting's curve runs (Exp. 1: results/paper_n5_indep_curve, which set the study's budget; Exp. 2:
results/paper_n5i_exp2_curve, which asks whether that budget also meets the rule there), ``full``, 50 points x 50
greedy episodes per seed, and puts each point's min-dist sum on the normalised scale (0 = random actions, 1 = the
scripted controller; higher is better; ``sb3_maddpg.analysis.normalised_score``). The rule: the budget is the shortest
multiple of 250k env steps at which, on every seed, the curve (a running mean over 5 points, +-100k steps) has left
random actions behind (normalised score >= 0.5) and the rest of the 2.5M steps adds less than 0.05 to it ("stopped
improving fast"). The summary also says how the study's budget (1.75M, from Exp. 1's curve) fares under the rule.
"""

import argparse
import csv
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sb3_maddpg.analysis.normalised_score import normalised_score, reference_scores

HERE = Path(__file__).resolve().parent
LEFT_RANDOM, STILL_GAINING, CANDIDATE_STEP, SMOOTHING = 0.5, 0.05, 250_000, 5
FULL_CURVE = 2_500_000
STUDY_BUDGET = 1_750_000
"""The study's budget, which the rule picked from Exp. 1's curve."""


@dataclass(frozen=True)
class CurveSetting:
    """One setting's learning curve: where its runs are, where its summary goes and what it trained.

    :param experiment: the curve's experiment in ``results/``
    :param summary: the summary's file name, beside this script
    :param configuration: what the runs trained, in words (the summary's first lines)
    """

    experiment: str
    summary: str
    configuration: str


SETTINGS = {
    "exp1": CurveSetting(
        "paper_n5_indep_curve",
        "curve_summary.md",
        "exp1_tuned's configuration (N=5, every agent and landmark observed nearest first, one gradient step per 25\n"
        "transitions, tuned learning rate, noise, tau and gamma) with `share_parameters=False`: each agent its own actor\n"
        "and critic, as the paper.",
    ),
    "exp2": CurveSetting(
        "paper_n5i_exp2_curve",
        "curve_summary_exp2.md",
        "exp2_tuned's configuration (N=5, each agent observing its two nearest others, landmarks nearest first, one\n"
        "gradient step per 25 transitions, the paper's other hyperparameters) with `share_parameters=False`, as the\n"
        "study's Exp. 2 (`curve_exp2.json`).",
    ),
}


def read_curve(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """:return: The curve's env steps and min-dist sums."""
    with path.open() as file:
        rows = list(csv.DictReader(file))
    return np.array([float(row["timesteps"]) for row in rows]), np.array([float(row["min_dist_sum"]) for row in rows])


def smoothed(values: np.ndarray, width: int = SMOOTHING) -> np.ndarray:
    """A centred running mean (shorter at the ends)."""
    half = width // 2
    return np.array([values[max(0, i - half) : i + half + 1].mean() for i in range(len(values))])


def at_budget(steps: np.ndarray, scores: list[np.ndarray], budget: int) -> list[tuple[float, float]] | None:
    """:return: Each seed's smoothed normalised score at the first point at or past ``budget`` and what the rest of
    its curve adds to it, or None if the curves end before ``budget``."""
    final = min(len(score) for score in scores) - 1
    at = int(np.searchsorted(steps, budget))
    if at > final:
        return None
    return [(float(score[at]), float(score[final] - score[at])) for score in scores]


def meets_rule(seeds_at_budget: list[tuple[float, float]]) -> bool:
    """:return: Whether every seed has left random actions behind and the rest of its curve adds too little."""
    return all(score >= LEFT_RANDOM and gain < STILL_GAINING for score, gain in seeds_at_budget)


def chosen_budget(steps: np.ndarray, scores: list[np.ndarray]) -> int | None:
    """:return: The rule's budget (see the module docstring), or None if no candidate meets it yet."""
    final = min(len(score) for score in scores) - 1
    for candidate in range(CANDIDATE_STEP, int(steps[final]) + 1, CANDIDATE_STEP):
        seeds_at_budget = at_budget(steps, scores, candidate)
        if seeds_at_budget is None:
            break
        if meets_rule(seeds_at_budget):
            return candidate
    return None


def budget_line(budget: int | None, complete: bool, last_step: int) -> str:
    """:return: The summary's verdict on the rule's budget: the budget (noting when it is only the curve's end, which
    trivially adds nothing after it), none within a complete curve, or none yet while the curve runs."""
    if not complete:
        return f"**The curve is still running ({last_step:,} of {FULL_CURVE:,} steps): no budget yet.**"
    if budget is None:
        return "**No budget meets the rule within the curve.**"
    if budget >= last_step:
        return (
            f"**Budget: {budget:,} env steps.** (The curve's end: the rule cannot tell whether the curve stopped "
            "improving there.)"
        )
    return f"**Budget: {budget:,} env steps.**"


def summary(setting: str, results: Path) -> str:
    """The setting's curve on the normalised scale, the budget the rule picks and how the study's budget fares.

    :param setting: a key of ``SETTINGS``
    :param results: the results directory holding the setting's curve experiment
    :return: The summary's Markdown.
    """
    curve = SETTINGS[setting]
    runs = results / curve.experiment / "full"
    seeds = sorted(path for path in runs.glob("seed_*") if (path / "learning_curve.csv").exists())
    if not seeds:
        raise FileNotFoundError(
            f"no learning curves under {runs}: run `bash benchmarks/paper_n5_independent/run_curve.sh` with "
            f"{setting}'s curve config first"
        )
    references = reference_scores(5)
    random, scripted = references["random"]["min_dist_sum"], references["scripted"]["min_dist_sum"]
    labels = [str(int(seed.name.removeprefix("seed_"))) for seed in seeds]
    curves = [read_curve(seed / "learning_curve.csv") for seed in seeds]
    length = min(len(steps) for steps, _ in curves)
    steps = curves[0][0][:length]
    for label, (seed_steps, _) in zip(labels, curves):
        if not np.array_equal(seed_steps[:length], steps):
            raise ValueError(
                f"seed {label}'s learning curve is evaluated at other env steps than seed {labels[0]}'s under {runs}: "
                "the rule compares the seeds point by point, so their runs must share curve_points and episodes"
            )
    raw = [np.array([normalised_score(value, random, scripted) for value in dist[:length]]) for _, dist in curves]
    scores = [smoothed(score) for score in raw]
    complete = steps[-1] >= FULL_CURVE
    budget = chosen_budget(steps, scores) if complete else None
    command = f"python {Path(__file__).relative_to(HERE.parents[1])}" + ("" if setting == "exp1" else f" --setting {setting}")
    lines = [
        f"# The learning curve of `full` with independent actors and critics, {setting} (issue 43)",
        "",
        curve.configuration,
        f"Seeds {', '.join(labels)}; each point 50 greedy episodes.",
        f"Normalised min-dist sum: 0 = random actions ({random:.2f}), 1 = the scripted controller ({scripted:.2f}); "
        "higher is better.",
        f"Smoothed: a running mean over {SMOOTHING} points. Made by `{command}`.",
        "",
        "| env steps | " + " | ".join(f"seed {label}: min-dist / normalised (smoothed)" for label in labels) + " |",
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
        budget_line(budget, complete, int(steps[-1])),
    ]
    seeds_at_study_budget = at_budget(steps, scores, STUDY_BUDGET) if complete else None
    if seeds_at_study_budget is not None:
        per_seed = "; ".join(
            f"seed {label}: {score:.2f}, the rest adds {gain:+.2f}"
            for label, (score, gain) in zip(labels, seeds_at_study_budget)
        )
        verdict = "meets the rule" if meets_rule(seeds_at_study_budget) else "does not meet the rule"
        lines.append(
            f"The study's budget, {STUDY_BUDGET:,} env steps (the rule's pick on Exp. 1's curve), {verdict} here "
            f"(smoothed normalised score at it: {per_seed})."
        )
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", choices=sorted(SETTINGS), default="exp1", help="whose curve (default: exp1)")
    args = parser.parse_args()
    try:
        text = summary(args.setting, HERE / "results")
    except FileNotFoundError as error:
        print(error, file=sys.stderr)
        return 1
    (HERE / SETTINGS[args.setting].summary).write_text(text)
    print(text, end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
