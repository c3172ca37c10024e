"""Issue 43's independent-network study read beside the shared one (writes beside_shared.md): Table 2 of both studies
under the paper's, the paper's claims asked of both (each verdict, and what the two say together; at each study's
budget and at a matched one), the 2 x 2 of
networks (shared, independent) x the target's selection rule (stored, next), each as the gap of its `selected` runs
against `full` in the same study, in both N=5 settings, and whether each study's runs were still improving when they
stopped (each run's learning curve over its last 20% against the 20% before).

    python benchmarks/paper_n5_independent/beside_shared.py --out docs/_static/paper_n5_independent/beside_shared.md

The shared study (``benchmarks/paper_n5``: one actor and one critic for the five agents, 1M env steps) found the
paper's `selected` (Algorithm 3: the target's two nearest agents stored with the transition) far worse than `full`,
and `selected_next` (the target's agents selected again from the next observation) not told apart from it. Two
explanations compete: the stored rule itself, or the shared networks feeding one critic's guesses to every agent. This
study's independent networks (1.75M env steps) tell them apart:

- a **cell** is the gap of one selection rule's runs against `full`'s, in one study (mean over runs, in the metric's
  units, percentage points for rates: positive is worse for the min-dist sum, better for a success rate), with a 95%
  Welch t interval (each scheme's runs with their own variance; a percentile bootstrap from 5 runs is too narrow) and
  the two-sided Mann-Whitney U test the paper uses, exact, its p Holm-adjusted within the study's family (each scheme
  against `full` in that setting, metric and budget, as the study's report adjusts it);
- **the rule's effect** (stored minus next) within each study, **sharing's effect on the stored rule** (its gap with
  shared networks minus with independent ones) and their **interaction** (the rule's effect with shared networks minus
  with independent ones) are differences of means with the same kind of interval, signed as the gaps are; so are
  sharing's effect on `full`'s score and on the stored rule's (shared minus independent), the two parts of its effect
  on the gap (a sharing that helps `full` more than the stored rule widens the gap too), which compare the two
  studies' levels and so carry their budgets' difference except at the matched budget;
- **the reading**, from the two effects that separate the explanations: with shared networks the stored rule must be
  worse than `full` (Holm-adjusted p < .05), else there is no reversal to explain on that metric. Then the reversal
  belongs to *the rule* if the rule's effect with independent networks is harmful (its interval excludes 0 on the worse side);
  to *the sharing* if it is not and sharing's effect on the stored rule's gap is harmful; to *both* (the rule harms
  without sharing, and sharing makes its harm larger) if both are; else it is not decided at these seeds. Where the
  sharing widens the gap, the reading says through which part: the stored rule's own score (its interval excludes 0
  on the worse side), else `full`'s (excludes 0 on the better side), else neither measurably alone. Cells too
  small for the test to reach p < .05 even when completely separated (fewer than 4 runs against 4; the report's
  "too few runs") are not read: their intervals, from 2 or 3 runs, would look sure of what they cannot say.

Table 2 is each study's report's (the seeds every scheme of a setting has finished, as ``report --complete-seeds``),
the two studies' settings under the paper's row of the same observability. The budgets:

Each study is read at its own budget (its protocol score: the checkpoints over the last 20%, 100 episodes each) and at
a matched one: the mean of each run's learning-curve points from 800k to 1M env steps (20 greedy episodes each; 11
points in the shared study, 6 in the independent one), where the shared study's protocol window is. The 2 x 2's runs
are those whose seed `full`, `selected` and `selected_next` have all finished in that study and setting; the paper's
claims are asked again at the matched budget on the same runs as at the studies' own (the seeds every scheme of a
setting has finished). The page reads twelve 2 x 2 tables (2 settings x 3 metrics x 2 budgets): where their readings
disagree, none of them is the answer.

Whether the runs had stopped improving: the budgets are fixed (the shared study's 1M steps from the tuning, the
independent one's 1.75M from the learning curve of Exp. 1's `full`), so the page shows, per study, setting and scheme,
how much each run's learning curve (min-dist sum) still moved from the 20% of its env steps before its last 20% to its
last 20%, on the normalised scale too (``sb3_maddpg.analysis.normalised_score``), counting the runs that moved by the
budget rule's 0.05 or more (the same number, not the same test), and the change against `full`'s: which gaps were
closing as the runs stopped.
"""

import argparse
import itertools
import math
import sys
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sb3_maddpg.analysis.normalised_score import reference_scores
from sb3_maddpg.experiments.metrics import METRICS
from sb3_maddpg.experiments.results_dir import PROGRESS_FILE, link_complete_seeds, load_experiments, load_summaries, read_curve
from sb3_maddpg.experiments.run_snapshot import read_progress_rows
from sb3_maddpg.results.aggregates import IntervalEstimate, mean_difference_interval
from sb3_maddpg.results.claims import (
    ClaimCheck,
    check_claims,
    format_beside_paper,
    format_p_value,
    observability,
    smallest_p_value,
)
from sb3_maddpg.results.stats import aggregate, declare_families, holm, mann_whitney

REPO = Path(__file__).resolve().parents[2]
STUDIES = {"shared": REPO / "benchmarks/paper_n5/results", "independent": REPO / "benchmarks/paper_n5_independent/results"}
"""Each study's results directory, by how its agents hold their networks."""
SETTINGS = {
    "Exp. 1 (all agents observed)": {"shared": "paper_n5_exp1", "independent": "paper_n5i_exp1"},
    "Exp. 2 (two nearest agents observed)": {"shared": "paper_n5_exp2", "independent": "paper_n5i_exp2"},
}
"""Each setting's experiment in each study."""
STORED, NEXT = "selected", "selected_next"
"""The schemes that run the target's two selection rules."""
RULES = {STORED: "stored (Algorithm 3, `selected`)", NEXT: "next (`selected_next`)"}
"""Each rule's scheme and its name in the tables."""
BASELINE = "full"
MATCHED_WINDOW = (800_000.0, 1_000_000.0)
"""The env steps (inclusive) whose learning-curve points give the matched-budget score."""
READ_METRICS = ("min_dist_sum", "success_rate_r0.3", "success_rate")
"""The metrics read: the min-dist sum and success within 0.3 carry the N=5 comparison; within 0.1 is the paper's."""
SIGNIFICANCE = 0.05
CRITIC_LOSS = "train/critic_loss"
"""The critics' TD loss as training logs it (the mean over the agents of each agent's loss)."""
CRITIC_LOSS_WINDOW = (500_000.0, 1_000_000.0)
"""The env steps (inclusive) over which each run's logged critic loss is averaged: the second half of the shared runs."""
LATE_FRACTIONS = (0.6, 0.8, 1.0)
"""The 20% of a run's env steps before its last 20%, and its last 20% (fractions of its budget; each window open at its
start): the learning-curve means compared to tell whether the run was still improving when it stopped."""
LATE_CHANGE_THRESHOLD = 0.05
"""A change over the last 20% at least this large on the normalised min-dist scale counts as still improving (or, the
other way, as falling back). The same number as the budget rule's (``curve_summary.py``: what a smoothed curve gains from
the budget to 2.5M steps), not the same test: here two adjacent windows of unsmoothed 20-episode points."""
N_AGENTS = 5
"""Both studies' team size (the normalised scale's references depend on it)."""

Scores = dict[str, dict[int, float]]
"""Per scheme, per seed: a run's score."""


def matched_budget_label(window: tuple[float, float]) -> str:
    """:return: How the tables name a matched budget read from these env steps' learning-curve points."""
    return "matched budget (learning-curve points, {:g}M-{:g}M env steps)".format(*(step / 1e6 for step in window))


def read_scores(results: Path, experiment: str, metric: str, window: tuple[float, float] | None = None) -> Scores:
    """
    :param results: A study's results directory.
    :param experiment: The setting's experiment there.
    :param metric: The score read.
    :param window: ``None``: each run's protocol score; else the mean of its learning-curve points in these env steps.
    :return: The scores of `full`, `selected` and `selected_next` on the seeds all three have finished.
    """
    schemes = (BASELINE, *RULES)
    runs: dict[str, dict[int, dict[str, Any]]] = {scheme: {} for scheme in schemes}
    for summary in load_summaries(results):
        if summary["experiment"] == experiment and summary["scheme"] in runs:
            runs[summary["scheme"]][int(summary["seed"])] = summary
    common = sorted(set.intersection(*(set(by_seed) for by_seed in runs.values())))
    return {scheme: {seed: _score(runs[scheme][seed], metric, window) for seed in common} for scheme in schemes}


def _score(summary: dict[str, Any], metric: str, window: tuple[float, float] | None) -> float:
    if window is None:
        return float(summary["score"][metric])
    if metric == CRITIC_LOSS:
        rows = [
            {"timesteps": float(row["time/total_timesteps"]), metric: float(row[metric])}
            for row in read_progress_rows(Path(summary["directory"]) / PROGRESS_FILE)
            if row.get(metric)
        ]
        where = "logged critic loss"
    else:
        rows, where = read_curve(summary["directory"]), "learning-curve point"
    points = [row[metric] for row in rows if window[0] <= row["timesteps"] <= window[1]]
    if not points:
        raise ValueError(f"{summary['directory']} has no {where} between {window[0]:g} and {window[1]:g} env steps.")
    return float(np.mean(points))


def difference(samples: Sequence[Sequence[float]]) -> IntervalEstimate:
    """
    :param samples: Two samples (a - b) or four ((a - b) - (c - d)) of per-run scores.
    :return: The difference of their means with its 95% Welch t interval.
    """
    return mean_difference_interval(samples)


@dataclass(frozen=True)
class Cell:
    """
    One selection rule against `full` in one study.

    :param variant: The rule's runs' scores.
    :param baseline: `full`'s runs' scores on the same seeds.
    :param gap: mean(variant) - mean(baseline) with its interval.
    :param u_statistic: Its U statistic (of the rule's runs: above ``len(variant) * len(baseline) / 2`` when they
        tend to score higher).
    :param p_value: Its exact two-sided p-value.
    :param p_adjusted: ``p_value`` Holm-adjusted within the study's family (see :func:`cell`).
    :param family_size: The tests of that family.
    """

    variant: list[float]
    baseline: list[float]
    gap: IntervalEstimate
    u_statistic: float
    p_value: float
    p_adjusted: float = math.nan
    family_size: int = 1

    @property
    def readable(self) -> bool:
        """Whether the test could reach p < .05 with these many runs (4 against 4 or more; the report's rule)."""
        return smallest_p_value(len(self.variant), len(self.baseline)) < SIGNIFICANCE

    def worse(self, higher_is_better: bool) -> bool:
        """:return: The rule's runs are worse than `full`'s at Holm-adjusted p < .05 (the direction the test's ranks
        give)."""
        return self.p_adjusted < SIGNIFICANCE and harmful(
            self.u_statistic - len(self.variant) * len(self.baseline) / 2, higher_is_better
        )


def harmful(value: float, higher_is_better: bool) -> bool:
    """
    :param value: A difference of scores, first minus second (or of ranks).
    :param higher_is_better: The scores' direction.
    :return: The difference says the first does worse.
    """
    return value > 0 if not higher_is_better else value < 0


def cell(scores: Scores, scheme: str, family: Mapping[str, float] | None = None) -> Cell:
    """
    :param scores: One study's scores in one setting (:func:`read_scores`).
    :param scheme: The selection rule's scheme.
    :param family: The raw p of each scheme of the study's family in this setting, metric and budget against `full`
        (:func:`family_p_values`: its report's); the cell's own test takes its scheme's place there (the same test
        where the cell's seeds are the report's). ``None``: the cell is a family of its own.
    :return: Its cell against `full`.
    """
    variant, baseline = list(scores[scheme].values()), list(scores[BASELINE].values())
    if not variant:  # no seed finished by all three schemes yet
        return Cell(variant, baseline, IntervalEstimate(math.nan, math.nan, math.nan), math.nan, math.nan)
    u_statistic, p_value = mann_whitney(variant, baseline)
    members = {**(family or {}), scheme: p_value}
    adjusted = dict(zip(members, holm(list(members.values()))))[scheme]
    return Cell(variant, baseline, difference([variant, baseline]), u_statistic, p_value, float(adjusted), len(members))


def family_p_values(
    results: Path, experiment: str, metric: str, window: tuple[float, float] | None = None
) -> dict[str, float]:
    """
    :param results: A study's results directory.
    :param experiment: The setting's experiment there.
    :param metric: The score read.
    :param window: ``None``: each run's protocol score; else the mean of its learning-curve points in these env steps.
    :return: The raw p of each scheme of the setting's family (its stored schemes but `full`) against `full`, on the
        seeds every scheme has finished, as the study's report tests them (``nan`` for one without runs).
    """
    if not (results / experiment / "experiment.json").is_file():  # no stored config: no family declared
        return {}
    runs, configs = complete_seed_runs(results, [experiment])
    if window is not None:
        runs = scored_in_window(runs, metric, window)
    families = declare_families(configs, [metric], BASELINE)
    members = next((family.schemes for family in families if family.setting == experiment), ())
    tested = {cell.scheme: cell.p_value for cell in aggregate(runs, metric, families=families)}
    return {scheme: tested.get(scheme, math.nan) for scheme in members}


RULE_SHARED = "the rule's effect with shared networks (stored minus next)"
RULE_INDEPENDENT = "the rule's effect with independent networks (stored minus next)"
SHARING_FULL = "sharing's effect on `full`'s score (shared minus independent)"
SHARING_STORED = "sharing's effect on the stored rule's score (shared minus independent)"
SHARING = "sharing's effect on the stored rule's gap (shared minus independent)"
INTERACTION = "interaction (the rule's effect, shared minus independent)"


def effect_samples(scores: Mapping[str, Scores]) -> dict[str, list[list[float]]]:
    """
    :param scores: Each study's scores in one setting, by networks.
    :return: Each effect's samples, in :func:`difference`'s order, by its name.
    """

    def runs(networks: str, scheme: str) -> list[float]:
        return list(scores[networks][scheme].values())

    return {
        RULE_SHARED: [runs("shared", STORED), runs("shared", NEXT)],
        RULE_INDEPENDENT: [runs("independent", STORED), runs("independent", NEXT)],
        # The gap's two parts: a sharing that helps `full` more than the stored rule also widens the gap.
        SHARING_FULL: [runs("shared", BASELINE), runs("independent", BASELINE)],
        SHARING_STORED: [runs("shared", STORED), runs("independent", STORED)],
        SHARING: [
            runs("shared", STORED),
            runs("shared", BASELINE),
            runs("independent", STORED),
            runs("independent", BASELINE),
        ],
        INTERACTION: [runs("shared", STORED), runs("shared", NEXT), runs("independent", STORED), runs("independent", NEXT)],
    }


def reading(cells: Mapping[tuple[str, str], Cell], effects: Mapping[str, IntervalEstimate], higher_is_better: bool) -> str:
    """
    :param cells: The four cells, by (networks, scheme).
    :param effects: The effects, by name (:data:`RULE_INDEPENDENT`, :data:`SHARING`, ...).
    :param higher_is_better: The metric's direction.
    :return: Which of the rule and the sharing the reversal belongs to, by the rule in the module docstring; where
        sharing widens the gap, through which part (the stored rule's own score, else `full`'s).
    """
    if not all(c.readable for c in cells.values()):
        return "too few runs to read: in a cell even completely separated runs could not reach p < .05"
    if not cells["shared", STORED].worse(higher_is_better):
        return (
            "no reversal to explain: with shared networks the stored rule is not worse than `full` here at Holm-adjusted "
            "p < .05"
        )

    def excludes_zero_harmfully(effect: IntervalEstimate) -> bool:
        return harmful(effect.low, higher_is_better) and harmful(effect.high, higher_is_better)

    def excludes_zero_helpfully(effect: IntervalEstimate) -> bool:
        return harmful(-effect.low, higher_is_better) and harmful(-effect.high, higher_is_better)

    # Which part of the gap sharing widens: the stored rule's own score, or `full`'s (the mechanism proposed for the
    # reversal, the shared critic's guesses, acts on the first only).
    if excludes_zero_harmfully(effects[SHARING_STORED]):
        through = "the stored rule itself scores worse with shared networks"
    elif excludes_zero_helpfully(effects[SHARING_FULL]):
        through = "through `full`: shared networks help `full`, and the stored rule's own score is not measurably worse"
    else:
        through = "neither the stored rule's own score nor `full`'s moves measurably with sharing on its own"
    # "Not harmful" below covers both an interval across 0 and one beyond it on the better side.
    rule, sharing = excludes_zero_harmfully(effects[RULE_INDEPENDENT]), excludes_zero_harmfully(effects[SHARING])
    if rule and sharing:
        return (
            "both: with independent networks too the stored rule does worse than the next one, and sharing makes its "
            f"gap to `full` larger ({through})"
        )
    if rule:
        return (
            "the rule: with independent networks too the stored rule does worse than the next one; sharing does not "
            "make its gap to `full` measurably larger"
        )
    if sharing:
        return (
            "the sharing: with independent networks the stored rule does not do measurably worse than the next one, "
            f"and sharing makes its gap to `full` larger ({through})"
        )
    return (
        "not decided at these seeds: neither the rule's effect without sharing nor sharing's effect is harmful beyond "
        "its interval"
    )


def _number(value: float, scale: float, signed: bool = False) -> str:
    if math.isnan(value):  # an empty cell: nothing to show yet
        return "-"
    digits = 1 if scale != 1.0 else 2
    return f"{value * scale:{'+' if signed else ''}.{digits}f}"


def _mean(values: Sequence[float], scale: float) -> str:
    return _number(float(np.mean(values)), scale) if len(values) else "no runs yet"


def _interval(estimate: IntervalEstimate, scale: float, readable: bool = True) -> str:
    text = _number(estimate.value, scale, signed=True)
    if math.isnan(estimate.value):
        return text
    if math.isnan(estimate.low) or not readable:  # from 3 runs or fewer an interval looks surer than it can be
        return f"{text} (too few runs for an interval)"
    return f"{text} [{_number(estimate.low, scale, signed=True)}, {_number(estimate.high, scale, signed=True)}]"


def _p(c: Cell) -> str:
    """A cell's raw p, and its Holm-adjusted p with the tests of its family."""
    if len(c.variant) < 2:
        return "n/a (1 run)" if c.variant else "-"
    return f"{format_p_value(c.p_value)} (Holm {format_p_value(c.p_adjusted)} of {c.family_size})"


def setting_table(
    scores: Mapping[str, Scores], metric: str, families: Mapping[str, Mapping[str, float]] | None = None
) -> list[str]:
    """
    :param scores: Each study's scores in one setting (:func:`read_scores`), by networks.
    :param metric: Their metric.
    :param families: Each study's family in the setting, metric and budget (:func:`family_p_values`), by networks;
        ``None`` or a study not in it: each cell a family of its own.
    :return: The setting's markdown lines: the four cells, the effects and the reading.
    """
    info = METRICS[metric]
    scale = info.scale
    units = "percentage points" if scale == 100.0 else "the metric's units"
    worse_sign = "negative" if info.higher_is_better else "positive"
    cells = {
        (networks, scheme): cell(scores[networks], scheme, (families or {}).get(networks))
        for networks in scores
        for scheme in RULES
    }
    lines = [
        f"Gaps and effects in {units}; {worse_sign} is worse.",
        "",
        "| networks | target's selection | runs | the rule's runs, by seed | their mean | `full`'s mean | gap [95% CI] "
        "| p (Holm) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for (networks, scheme), c in cells.items():
        by_seed = ", ".join(_number(value, scale) for value in c.variant) or "-"
        lines.append(
            f"| {networks} | {RULES[scheme]} | {len(c.variant)} | {by_seed} | {_mean(c.variant, scale)} | "
            f"{_mean(c.baseline, scale)} | {_interval(c.gap, scale, c.readable)} | {_p(c)} |"
        )
    lines.append("")
    effects = {}
    for name, samples in effect_samples(scores).items():
        if any(len(sample) == 0 for sample in samples):
            lines.append(f"- {name}: no runs yet")
            continue
        effects[name] = difference(samples)
        readable = all(smallest_p_value(len(a), len(b)) < SIGNIFICANCE for a, b in zip(samples[::2], samples[1::2]))
        lines.append(f"- {name}: {_interval(effects[name], scale, readable)}")
    lines.append(f"- **which explains the reversal**: {reading(cells, effects, info.higher_is_better)}")
    return lines


def critic_loss_table(scores: Mapping[str, Scores]) -> list[str]:
    """
    :param scores: Each study's runs' mean critic loss in one setting (:func:`read_scores` with :data:`CRITIC_LOSS`).
    :return: The markdown lines: per study, each scheme's mean over runs (its runs' range) and the stored rule's over
        `full`'s.
    """
    schemes = (BASELINE, *RULES)
    lines = [
        "| networks | runs | `full` | stored (`selected`) | next (`selected_next`) | stored / `full` |",
        "|---|---|---|---|---|---|",
    ]
    for networks, by_scheme in scores.items():
        runs = {scheme: list(by_scheme[scheme].values()) for scheme in schemes}
        if not runs[BASELINE]:
            lines.append(f"| {networks} | 0 | no runs yet | | | |")
            continue
        means = {scheme: float(np.mean(values)) for scheme, values in runs.items()}
        cells = [f"{means[scheme]:.3f} ({min(runs[scheme]):.3f}-{max(runs[scheme]):.3f})" for scheme in schemes]
        ratio = means[STORED] / means[BASELINE]
        lines.append(f"| {networks} | {len(runs[BASELINE])} | {' | '.join(cells)} | {ratio:.2f} |")
    return lines


def late_curve_means(summary: Mapping[str, Any], metric: str = "min_dist_sum") -> tuple[float, float]:
    """
    :param summary: A finished run's summary, with its ``"directory"`` and ``"total_timesteps"`` (its budget).
    :param metric: A learning-curve metric.
    :return: The mean of its learning-curve points over the 20% of its env steps before the last 20%, and over the last
        20% (:data:`LATE_FRACTIONS`): how much the run still moved when it stopped is the second minus the first.
    :raises ValueError: A window holds no learning-curve point (the run's directory named).
    """
    # Whole env steps, so that a point on a window's edge falls on the same side whatever the float rounding.
    edges = [round(fraction * float(summary["total_timesteps"])) for fraction in LATE_FRACTIONS]
    rows = read_curve(summary["directory"])
    window_means = []
    for start, end in itertools.pairwise(edges):
        points = [row[metric] for row in rows if start < row["timesteps"] <= end]
        if not points:
            raise ValueError(
                f"{summary['directory']} has no learning-curve point after {start:,} and up to {end:,} env steps; "
                "the late-change check needs the run's curve over its last 40%."
            )
        window_means.append(float(np.mean(points)))
    return window_means[0], window_means[1]


def late_change_table(runs: Mapping[str, Sequence[dict[str, Any]]], scale: float) -> list[str]:
    """
    :param runs: One setting's finished runs (summaries with their directories), by networks.
    :param scale: Min-dist units per unit of the normalised scale (the random team's min-dist sum minus the scripted
        controller's).
    :return: The markdown lines: per study and scheme, the mean of its runs' learning curves (min-dist sum) over the
        20% before the last 20% and over the last 20% (:func:`late_curve_means`), the mean change with its interval and
        on the normalised scale, the runs still improving or falling back by :data:`LATE_CHANGE_THRESHOLD` or more, and the
        change against `full`'s (negative: the scheme gains on `full`).
    """
    lines = [
        "| networks | scheme | runs | min-dist sum, the 20% before / the last 20% | change [95% CI] | normalised "
        "(higher is better) | runs still improving / falling back | change minus `full`'s [95% CI] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for networks, summaries in runs.items():
        window_means: dict[str, list[tuple[float, float]]] = {}
        for summary in sorted(summaries, key=lambda run: (run["scheme"] != BASELINE, run["scheme"], run["seed"])):
            window_means.setdefault(summary["scheme"], []).append(late_curve_means(summary))
        if not window_means:
            lines.append(f"| {networks} | | 0 | no runs yet | | | | |")
            continue
        changes = {scheme: [last - before for before, last in pairs] for scheme, pairs in window_means.items()}
        for scheme, pairs in window_means.items():
            runs_readable = smallest_p_value(len(pairs), len(pairs)) < SIGNIFICANCE  # the cells' rule: 4 runs or more
            change = mean_difference_interval([changes[scheme]])
            normalised = [-value / scale for value in changes[scheme]]
            gaining = sum(value >= LATE_CHANGE_THRESHOLD for value in normalised)
            falling = sum(value <= -LATE_CHANGE_THRESHOLD for value in normalised)
            before, last = np.mean(pairs, axis=0)
            if scheme == BASELINE or BASELINE not in changes:
                change_minus_full = "-"
            else:
                readable = smallest_p_value(len(pairs), len(changes[BASELINE])) < SIGNIFICANCE
                change_minus_full = _interval(difference([changes[scheme], changes[BASELINE]]), 1.0, readable)
            lines.append(
                f"| {networks} | `{scheme}` | {len(pairs)} | {before:.2f} / {last:.2f} | "
                f"{_interval(change, 1.0, runs_readable)} | {-change.value / scale:+.3f} | {gaining} / {falling} | "
                f"{change_minus_full} |"
            )
    return lines


def late_windows(runs: Mapping[str, Sequence[Mapping[str, Any]]]) -> str:
    """
    :param runs: Finished runs' summaries (with ``"total_timesteps"``), by networks.
    :return: Each study's two windows (:data:`LATE_FRACTIONS` of its runs' budgets), e.g. ``"shared: 0.6M-0.8M and
        0.8M-1M"``.
    """
    described = []
    for networks, summaries in runs.items():
        for budget in sorted({float(summary["total_timesteps"]) for summary in summaries}):
            millions = [fraction * budget / 1e6 for fraction in LATE_FRACTIONS]
            described.append(f"{networks}: {millions[0]:g}M-{millions[1]:g}M and {millions[1]:g}M-{millions[2]:g}M")
    return "; ".join(described) or "no runs yet"


def complete_seed_runs(results: Path, experiments: Sequence[str]) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """
    :param results: A study's results directory.
    :param experiments: The experiments read there (the others, e.g. a learning curve's, are left out).
    :return: The summaries of the runs whose seed every scheme of their experiment has finished (each
        ``"directory"`` the run's own, in ``results``, not the temporary view's), and the experiments' stored configs.
    """
    with tempfile.TemporaryDirectory(prefix="beside_shared_") as view:
        stored = load_experiments(results)
        link_complete_seeds(results, view, [experiment for experiment in experiments if experiment in stored])
        runs = load_summaries(view)
        for run in runs:  # the run's own directory, so its curve can be read once the view is gone
            run["directory"] = str(results / Path(run["directory"]).relative_to(view))
        return runs, load_experiments(view)


def table2_beside_shared(studies: Mapping[str, Path], metric: str) -> list[str]:
    """
    :param studies: Each study's results directory, by networks.
    :param metric: The metric tabulated.
    :return: The markdown lines of Table 2: per observability the paper's row, then each study's setting.
    """
    summaries: list[dict[str, Any]] = []
    experiments: dict[str, Any] = {}
    for networks, results in studies.items():
        runs, configs = complete_seed_runs(results, [setting[networks] for setting in SETTINGS.values()])
        summaries += runs
        experiments.update(configs)
    table = format_beside_paper(aggregate(summaries, metric), METRICS[metric].label, experiments)
    # The report's own heading level (###) nests under this page's sections.
    return [] if table is None else ["#" + line if line.startswith("### ") else line for line in table.splitlines()]


DECIDED_VERDICTS = ("holds", "reverses", "does not hold")
"""The claims' verdicts that say something at Holm-adjusted p < .05 (the others: "not separated", "leans ...", "too few
runs")."""
NOT_IN_STUDY = "not in this study"
"""A claim's cell where the study does not run one of its schemes (e.g. Exp. 2's other three, independent networks)."""


def agreement(shared: str, independent: str) -> str:
    """
    :param shared: A claim's outcome with shared networks (:attr:`ClaimCheck.outcome`: the verdict, with the scheme
        that scores better where a ``~`` claim does not hold).
    :param independent: Its outcome with independent networks.
    :return: What the two say together: ``"not yet"`` (too few runs on either side), ``"neither separates"`` (both
        undecided, not separated or leaning either way: no evidence at the adjusted level), ``"the same"`` (one decided
        outcome with both), ``"opposite"`` (decided with both, differently), or ``"decided with shared only"`` /
        ``"decided with independent only"`` (undecided with the other: which may come from the sharing, the budget, or
        the other's runs being too few or too spread; this is no test of a difference).
    """
    if "too few runs" in (shared, independent):
        return "not yet"
    decided = [outcome.startswith(DECIDED_VERDICTS) for outcome in (shared, independent)]
    if not any(decided):
        return "neither separates"
    if all(decided):
        return "the same" if shared == independent else "opposite"
    return "decided with shared only" if decided[0] else "decided with independent only"


def scored_in_window(runs: Sequence[dict[str, Any]], metric: str, window: tuple[float, float]) -> list[dict[str, Any]]:
    """
    :param runs: Finished runs' summaries, each with its ``"directory"``.
    :param metric: A learning-curve metric.
    :param window: The env steps (inclusive) whose learning-curve points are averaged.
    :return: Copies of the summaries whose ``score[metric]`` is that mean (the rest of the score as it was).
    :raises ValueError: A run has no learning-curve point in the window (its directory named).
    """
    return [{**run, "score": {**run["score"], metric: _score(run, metric, window)}} for run in runs]


def study_claims(
    results: Path, networks: str, metric: str, window: tuple[float, float] | None = None
) -> dict[tuple[str, str], ClaimCheck]:
    """
    :param results: A study's results directory.
    :param networks: How its agents hold their networks (its experiments' key in :data:`SETTINGS`).
    :param metric: The metric asked.
    :param window: ``None``: each run's protocol score; else the mean of its learning-curve points in these env steps.
    :return: The paper's claims asked of the study's settings (their complete seeds, as its report asks them), by the
        claim's observability and its text as asked (a variant such as `selected_next` in its scheme's place).
    """
    runs, configs = complete_seed_runs(results, [setting[networks] for setting in SETTINGS.values()])
    if window is not None:
        runs = scored_in_window(runs, metric, window)
    families = declare_families(configs, [metric])  # as the study's report declares them
    checks = check_claims(aggregate(runs, metric, families=families), metric, configs) if runs else []
    return {(check.claim.observability, check.text): check for check in checks}


def study_schemes(results: Path, networks: str) -> dict[str, set[str]]:
    """
    :param results: A study's results directory.
    :param networks: How its agents hold their networks.
    :return: The schemes each of its settings runs (finished or not), by the setting's observability.
    """
    stored = load_experiments(results)
    settings = [stored[setting[networks]] for setting in SETTINGS.values() if setting[networks] in stored]
    return {str(observability(experiment)): set(experiment["schemes"]) for experiment in settings}


def _asked(check: ClaimCheck | None, runs_its_schemes: bool) -> list[str]:
    """A study's cells of a claim: its runs a side, the means, p, the outcome (or why it has none)."""
    if check is None:
        return ["0", "", "", "no runs yet" if runs_its_schemes else NOT_IN_STUDY]
    means = f"{np.mean(check.better_scores):.2f} vs {np.mean(check.worse_scores):.2f}"
    runs = f"{len(check.better_scores)}, {len(check.worse_scores)}"
    adjusted = f"Holm {format_p_value(check.p_adjusted)} of {check.family_size}"
    return [runs, means, f"{format_p_value(check.p_value)} ({adjusted})", check.outcome]


def claims_beside_shared(studies: Mapping[str, Path], metric: str, window: tuple[float, float] | None = None) -> list[str]:
    """
    :param studies: Each study's results directory, by networks (``shared``, ``independent``).
    :param metric: The metric asked.
    :param window: ``None``: each study at its own budget (the runs' protocol scores); else both at a matched one, the
        mean of each run's learning-curve points in these env steps.
    :return: The markdown lines of the paper's claims asked of both studies, a row per claim as asked, with what the
        two outcomes say together (:func:`agreement`; ``"asked of the <networks> study only"`` where the other does
        not run one of its schemes).
    """
    checks = {networks: study_claims(results, networks, metric, window) for networks, results in studies.items()}
    schemes = {networks: study_schemes(results, networks) for networks, results in studies.items()}
    keys = list(dict.fromkeys(key for by_claim in checks.values() for key in by_claim))
    info = METRICS[metric]
    direction = "higher is better" if info.higher_is_better else "lower is better"
    observed = {"full": "Exp. 1", "partial": "Exp. 2"}
    budget = "" if window is None else f", {matched_budget_label(window)}"
    lines = [
        f"#### The paper's claims in both studies: {info.label} ({direction}){budget}",
        "",
        "| setting | claim | paper (success %) | shared: runs | means | p (Holm) | verdict | independent: runs | means "
        "| p (Holm) | verdict | together |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key in keys:
        asked = {networks: checks[networks].get(key) for networks in ("shared", "independent")}
        some = next(check for check in asked.values() if check is not None)
        needed = {some.better_scheme or some.claim.better, some.worse_scheme or some.claim.worse}
        runs_them = {networks: needed <= schemes[networks].get(key[0], set()) for networks in asked}
        cells = [observed[key[0]], key[1], some.claim.evidence]
        for networks, check in asked.items():
            cells += _asked(check, runs_them[networks])
        if not all(runs_them.values()):
            together = f"asked of the {next(networks for networks, runs in runs_them.items() if runs)} study only"
        elif asked["shared"] is None or asked["independent"] is None:
            together = "not yet"
        else:
            together = agreement(asked["shared"].outcome, asked["independent"].outcome)
        lines.append("| " + " | ".join([*cells, together]) + " |")
    return lines


def write_beside_shared(studies: Mapping[str, Path] = STUDIES, metrics: Sequence[str] = READ_METRICS) -> str:
    """
    :param studies: Each study's results directory, by networks (``shared``, ``independent``).
    :param metrics: The metrics read.
    :return: The markdown page: Table 2 of both studies; the paper's claims asked of both, at their own budgets and a
        matched one; per setting, metric and budget, the 2 x 2 with its effects and reading, and the critics' loss; per
        setting, how much each study's runs still moved over their last 20%.
    """
    lines = [
        "# Independent networks beside shared ones at N=5: Table 2, the paper's claims, the 2 x 2 and the runs' last 20%",
        "",
        "Made by `python benchmarks/paper_n5_independent/beside_shared.py` (its docstring states the method). "
        "`paper_n5_exp1`/`paper_n5_exp2`: one actor and one critic shared by the agents, 1M env steps (40,000 "
        "episodes); `paper_n5i_exp1`/`paper_n5i_exp2`: a network per agent, as the paper trains them, 1.75M "
        "(70,000 episodes). Table 2 reads the seeds every scheme of a setting has finished; the 2 x 2 those `full`, "
        "`selected` and `selected_next` have.",
    ]
    for metric in metrics:
        lines += ["", *table2_beside_shared(studies, metric)]
    lines += [
        "",
        "Each of the paper's claims (Section 5.3) asked of both studies as their reports ask it (the seeds every scheme "
        "of a setting has finished; the exact two-sided Mann-Whitney U test, its p Holm-adjusted within the study's "
        "family, the verdicts by the adjusted p at .05, as in the reports' claims pages, which say what a family is; "
        "p: raw, then Holm-adjusted with the tests of its family). *Together*: *the same* decided verdict "
        "with both networks; *opposite* (decided with both, differently); *neither separates* (no decided verdict "
        "with either: not separated, or leaning one way without the adjusted p reaching .05); *decided with shared "
        "only* or *decided with independent only* (undecided with the other); *not yet* (too few runs with either); "
        "*asked of one study only* (the other does not run one of its schemes). A claim decided with one only is no "
        "test that the studies differ: the difference may come from the sharing, from the budget (1M against 1.75M "
        "env steps), or from the other study's runs being too few or too spread to decide it; only a test of the "
        "difference tells "
        "these apart, which the 2 x 2 below makes for `selected` alone (its interaction, and its matched budget). "
        "About 90 claims are asked here (15 a metric and budget), corrected within each study's families, not across "
        "the page.",
        "",
        "Then each claim again with both studies at a matched budget: each run's score is the mean of its "
        "learning-curve points from {:g}M to {:g}M env steps (20 greedy episodes a point, 11 points a run in the "
        "shared study and 6 in the independent one; where the shared study's protocol window is), so that the budget "
        "no longer differs. A claim decided with independent networks at their own budget and not at the matched one "
        "is not shown to come from the networks: it appears only with their longer training (shared networks were "
        "not run that long), and a curve point's 20 episodes measure a run less finely than the protocol's 2,000 at "
        "the end.".format(*(step / 1e6 for step in MATCHED_WINDOW)),
    ]
    for window in (None, MATCHED_WINDOW):
        for metric in metrics:
            lines += ["", *claims_beside_shared(studies, metric, window)]
    lines += [
        "",
        "#### The 2 x 2: networks x the target's selection rule, each rule against `full`",
        "",
        "A gap is mean(the rule's runs) - mean(`full`'s runs) in the same study and setting, with a 95% Welch t "
        "interval (each scheme's runs with their own variance; the effects below are differences of means with the "
        "same kind of interval). p: the exact two-sided Mann-Whitney U test, then Holm-adjusted within the study's "
        "family (each of the setting's schemes against `full`, at that metric and budget, as its report adjusts it) "
        "with the tests of that family; the reading asks the adjusted p. Twelve tables (2 settings x 3 metrics x 2 "
        "budgets), none corrected for the others: where their readings disagree, none of them is the answer. Shared "
        "networks: `benchmarks/paper_n5` (1M env steps); independent: `benchmarks/paper_n5_independent` (1.75M).",
    ]
    budgets = {
        "each study at its own budget (protocol score, last 20%)": None,
        matched_budget_label(MATCHED_WINDOW): MATCHED_WINDOW,
    }
    for setting, experiments in SETTINGS.items():
        for metric in metrics:
            info = METRICS[metric]
            direction = "higher is better" if info.higher_is_better else "lower is better"
            for budget, window in budgets.items():
                scores = {
                    networks: read_scores(studies[networks], experiments[networks], metric, window) for networks in studies
                }
                families = {
                    networks: family_p_values(studies[networks], experiments[networks], metric, window) for networks in studies
                }
                table = setting_table(scores, metric, families)
                lines += ["", f"#### {setting}: {info.label} ({direction}), {budget}", "", *table]
        losses = {
            networks: read_scores(studies[networks], experiments[networks], CRITIC_LOSS, CRITIC_LOSS_WINDOW)
            for networks in studies
        }
        lines += [
            "",
            f"#### {setting}: the critics' loss, {CRITIC_LOSS_WINDOW[0] / 1e6:g}M-{CRITIC_LOSS_WINDOW[1] / 1e6:g}M env steps",
            "",
            "Each run's logged TD loss (the mean over the agents of each agent's loss; with shared networks one critic "
            "gives them all) averaged over these steps; per scheme the mean over runs (their range). A run gone astray "
            "has a high loss whatever sent it there, so the ratio follows the scores: it says how far the stored rule's "
            "critics are from their targets, not why.",
            "",
            *critic_loss_table(losses),
        ]
    references = reference_scores(N_AGENTS)
    scale = references["random"]["min_dist_sum"] - references["scripted"]["min_dist_sum"]
    finished = {
        networks: complete_seed_runs(results, [setting[networks] for setting in SETTINGS.values()])[0]
        for networks, results in studies.items()
    }
    lines += [
        "",
        "#### Were the runs still improving when they stopped?",
        "",
        "Each run's learning curve (min-dist sum, lower is better; 20 greedy episodes a point) averaged over the 20% "
        f"of its env steps before its last 20% and over its last 20% (the protocol's window): {late_windows(finished)}. "
        "A change below 0 is a run still improving; normalised, 1 is the distance from random actions to the scripted "
        f"controller ({scale:.2f} min-dist), higher is better. A run counts as still improving (or falling back) when "
        f"it moved by {LATE_CHANGE_THRESHOLD} or more on that scale: the number of the rule that set the independent "
        "study's budget, though not its test (that rule compares a smoothed curve at the budget with its end at 2.5M "
        "steps; here two adjacent windows of unsmoothed points, so a single run's count partly measures noise). "
        "*Change minus `full`'s*: below 0 the scheme was gaining on `full` as the runs stopped, so where it trails "
        "`full` longer training might narrow its gap, and where it leads widen it (a trend over two windows, not a "
        "forecast; some forty t intervals, none corrected for the others). The runs are Table 2's (the seeds every "
        "scheme of a setting has finished).",
    ]
    for setting, experiments in SETTINGS.items():
        setting_runs = {
            networks: [run for run in finished[networks] if run["experiment"] == experiments[networks]] for networks in studies
        }
        lines += ["", f"##### {setting}", "", *late_change_table(setting_runs, scale)]
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", help="write the page here (default: print it)")
    args = parser.parse_args(argv)
    page = write_beside_shared()
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(page)
    else:
        sys.stdout.write(page)
    return 0


if __name__ == "__main__":
    sys.exit(main())
