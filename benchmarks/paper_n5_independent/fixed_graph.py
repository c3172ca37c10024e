"""Issue 56, item 4: is Exp. 1's reversal the selection by distance? ``selected_fixed`` (Exp. 1's ``selected`` with
each agent's two partners fixed for the run: a ring, agent i selects i - 1 and i + 1) against Exp. 1's ``full`` and
``selected`` (the two nearest agents at each step), with a network per agent. Writes ``fixed_graph.md``.

    python benchmarks/paper_n5_independent/fixed_graph.py --out docs/_static/paper_n5_independent/fixed_graph.md

Declared here before any of its runs is read (2026-12-07, before the fixed graph's first run started):

- **Runs**: every finished ``selected_fixed`` run (``results_fixed_graph/``, seeds 0-4; another seed is refused)
  against Exp. 1's ``full`` and ``selected`` runs at the seeds every Exp. 1 scheme has finished (the report's complete
  seeds).
- **When it is read**: at all 5 fixed-graph runs and Exp. 1's seeds 0-9 (:data:`FINAL_SEEDS`). A page written
  before says it is an interim look, which nothing corrects for.
- **Families**: one per metric (:data:`METRICS_READ`; the min-dist sum is the reading's), each the fixed graph against
  ``full`` and against ``selected``: two tests, Holm-adjusted. The test is the exact two-sided Mann-Whitney U; each
  difference of means carries its 95% Welch t interval.
- **The reading**, on the min-dist sum, each part at Holm p < .05 in the direction its ranks give:

  - *the distance*: the fixed graph beats ``selected`` and is not shown worse than ``full``;
  - *selection itself*: the fixed graph loses to ``full`` and does not beat ``selected``;
  - *both in part*: it beats ``selected`` and loses to ``full``;
  - otherwise *not decided at these runs*.

"Not shown worse" is not "as good": 5 runs may miss a loss to ``full`` that the Welch interval beside it still allows,
and the page shows that interval. What else differs: a ring's partners may be far apart, so the fixed graph shares
fixed agents' information, not near ones'. "The distance" would say that partners chosen anew at each step (and the
stored target's stale ones) hurt, not that any fixed pair is as good as all four others. The runs were not
randomised together: the fixed graph runs from 487a75a, Exp. 1 from b92cd85 (seeds 0-4) and 424c90c (seeds 5-9), the
same training path and settings. It stays a reading of this configuration (tuned, 1.75M steps).
"""

import argparse
import sys
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from sb3_maddpg.experiments.group_state import seed_ranges
from sb3_maddpg.experiments.metrics import METRICS
from sb3_maddpg.experiments.results_dir import link_complete_seeds, load_summaries
from sb3_maddpg.results.aggregates import IntervalEstimate, mean_difference_interval
from sb3_maddpg.results.claims import ALPHA, format_p_value
from sb3_maddpg.results.stats import holm, mann_whitney

HERE = Path(__file__).resolve().parent
FIXED_RESULTS, STUDY_RESULTS = HERE / "results_fixed_graph", HERE / "results"
FIXED_EXPERIMENT, FIXED_SCHEME = "paper_n5i_exp1_fixed_graph", "selected_fixed"
EXPERIMENT = "paper_n5i_exp1"
AGAINST = ("full", "selected")
"""The fixed graph's family: Exp. 1's schemes it is tested against, in the page's order."""
FINAL_SEEDS = {FIXED_SCHEME: tuple(range(5)), **{scheme: tuple(range(10)) for scheme in AGAINST}}
"""The seeds of each scheme at which the reading is the declared one; a page before them is an interim look."""
METRICS_READ = ("min_dist_sum", "success_rate_r0.3")
"""The metrics read, each its own family; the first is the reading's (the study's metric)."""
Runs = dict[str, dict[int, dict[str, float]]]
"""Each scheme's runs' scores (``score`` of its summary) by seed."""


@dataclass(frozen=True)
class Comparison:
    """
    The fixed graph against one of Exp. 1's schemes on one metric.

    :param against: That scheme.
    :param metric: The metric.
    :param fixed: The fixed graph's per-run scores.
    :param other: The scheme's per-run scores.
    :param difference: mean(fixed) - mean(other) with its 95% Welch t interval.
    :param u_statistic: The fixed graph's U (above ``len(fixed) * len(other) / 2`` when its runs tend to score higher).
    :param p_value: The exact two-sided Mann-Whitney U p.
    :param p_holm: ``p_value`` Holm-adjusted within its metric's family.
    """

    against: str
    metric: str
    fixed: list[float]
    other: list[float]
    difference: IntervalEstimate
    u_statistic: float
    p_value: float
    p_holm: float

    def _fixed_ranks_higher(self) -> bool:
        return self.u_statistic > len(self.fixed) * len(self.other) / 2

    def fixed_better(self) -> bool:
        """:return: The fixed graph scores better at Holm-adjusted p < .05, in the direction its ranks give."""
        return self.p_holm < ALPHA and self._fixed_ranks_higher() == METRICS[self.metric].higher_is_better

    def fixed_worse(self) -> bool:
        """:return: The fixed graph scores worse at Holm-adjusted p < .05, in the direction its ranks give."""
        return self.p_holm < ALPHA and self._fixed_ranks_higher() != METRICS[self.metric].higher_is_better

    def verdict(self) -> str:
        """:return: The verdict words the adjusted p allows."""
        if self.fixed_better():
            return "the fixed graph scores better"
        if self.fixed_worse():
            return "the fixed graph scores worse"
        return f"not separated (p = {format_p_value(self.p_value)})"


def read_runs(fixed_results: Path = FIXED_RESULTS, study_results: Path = STUDY_RESULTS) -> Runs:
    """
    :param fixed_results: The fixed graph's results directory.
    :param study_results: The study's, holding Exp. 1.
    :return: The fixed graph's finished runs and Exp. 1's ``full`` and ``selected`` at its complete seeds.
    :raise SystemExit: When the fixed graph has no finished run or one of another seed than its declared ones, or
        Exp. 1 no complete seed.
    """
    runs: Runs = {FIXED_SCHEME: {}, **{scheme: {} for scheme in AGAINST}}
    for summary in load_summaries(fixed_results):
        if summary["experiment"] == FIXED_EXPERIMENT and summary["scheme"] == FIXED_SCHEME:
            seed = int(summary["seed"])
            if seed not in FINAL_SEEDS[FIXED_SCHEME]:
                raise SystemExit(
                    f"{summary['directory']} is seed {seed}, not one of the declared seeds "
                    f"{seed_ranges(FINAL_SEEDS[FIXED_SCHEME])}: move it out of {fixed_results}, or declare it in "
                    "fixed_graph.py before reading it."
                )
            runs[FIXED_SCHEME][seed] = summary["score"]
    if not runs[FIXED_SCHEME]:
        raise SystemExit(
            f"{fixed_results} holds no finished {FIXED_SCHEME} run: start them (benchmarks/paper_n5_independent/README.md, "
            "Step 2) and read them when they have finished."
        )
    with tempfile.TemporaryDirectory(prefix="fixed_graph_") as view:
        link_complete_seeds(study_results, view, [EXPERIMENT])
        for summary in load_summaries(view):
            if summary["scheme"] in AGAINST:
                runs[summary["scheme"]][int(summary["seed"])] = summary["score"]
    if not all(runs[scheme] for scheme in AGAINST):
        raise SystemExit(f"{study_results} has no seed that every Exp. 1 scheme has finished: nothing to read against.")
    return runs


def is_final(runs: Runs) -> bool:
    """:return: Every scheme has the seeds :data:`FINAL_SEEDS` declares (more Exp. 1 seeds would not count as fewer)."""
    return all(set(seeds) <= set(runs[scheme]) for scheme, seeds in FINAL_SEEDS.items())


def compare(runs: Runs, metric: str) -> list[Comparison]:
    """
    :param runs: The runs' scores (:func:`read_runs`).
    :param metric: The metric: one family, the fixed graph against each of :data:`AGAINST`.
    :return: The family's comparisons, Holm-adjusted within it.
    """
    fixed = [scores[metric] for _, scores in sorted(runs[FIXED_SCHEME].items())]
    tests = []
    for scheme in AGAINST:
        other = [scores[metric] for _, scores in sorted(runs[scheme].items())]
        u_statistic, p_value = mann_whitney(fixed, other)
        tests.append((scheme, other, u_statistic, p_value))
    adjusted = holm([p_value for *_, p_value in tests])
    return [
        Comparison(scheme, metric, fixed, other, mean_difference_interval([fixed, other]), u, p, float(p_holm))
        for (scheme, other, u, p), p_holm in zip(tests, adjusted)
    ]


def reading(family: Sequence[Comparison]) -> str:
    """
    :param family: The reading metric's comparisons (:func:`compare`).
    :return: The reading the module's docstring declares.
    """
    by_scheme = {comparison.against: comparison for comparison in family}
    beats_selected, loses_to_full = by_scheme["selected"].fixed_better(), by_scheme["full"].fixed_worse()
    if beats_selected and not loses_to_full:
        return "the distance: the fixed graph beats `selected` and is not shown worse than `full`"
    if loses_to_full and not beats_selected:
        return "selection itself: the fixed graph loses to `full` and does not beat `selected`"
    if beats_selected and loses_to_full:
        return "both in part: the fixed graph beats `selected` and loses to `full`"
    return "not decided at these runs: the fixed graph neither beats `selected` nor loses to `full` at Holm p < .05"


def page(runs: Runs, families: Mapping[str, Sequence[Comparison]]) -> str:
    """
    :param runs: The runs read (:func:`read_runs`).
    :param families: Each metric's comparisons (:func:`compare`), the reading's first.
    :return: The page (Markdown).
    """
    seeds = {scheme: sorted(by_seed) for scheme, by_seed in runs.items()}
    lines = [
        "# Is it the selection by distance? Exp. 1's `selected` over a fixed neighbour graph (issue 56, item 4)",
        "",
        f"`{FIXED_SCHEME}`: Exp. 1's `selected` with each agent's two partners fixed for the run (a ring: agent i "
        "selects i - 1 and i + 1) instead of its two nearest at each step, a network per agent, everything else as "
        f"Exp. 1. Its {len(seeds[FIXED_SCHEME])} runs (seeds {seed_ranges(seeds[FIXED_SCHEME])}) against Exp. 1's "
        + " and ".join(f"`{scheme}` ({len(seeds[scheme])} runs)" for scheme in AGAINST)
        + ", at the seeds every Exp. 1 scheme has finished.",
        "",
        "| metric | against | mean, fixed graph vs it | difference [95% Welch t] | p | Holm p (2) | verdict |",
        "|---|---|---|---|---|---|---|",
    ]
    for metric, family in families.items():
        info = METRICS[metric]
        label = f"{info.label}, {'higher' if info.higher_is_better else 'lower'} is better"
        for comparison in family:
            difference = comparison.difference  # in the page's units (% for rates)
            interval = IntervalEstimate(*(info.scale * end for end in (difference.value, difference.low, difference.high)))
            means = " vs ".join(f"{info.scale * sum(runs) / len(runs):.2f}" for runs in (comparison.fixed, comparison.other))
            lines.append(
                f"| {label} | `{comparison.against}` | {means} | {interval.format()} | {format_p_value(comparison.p_value)} "
                f"| {format_p_value(comparison.p_holm)} | {comparison.verdict()} |"
            )
    first = next(iter(families.values()))
    if not is_final(runs):
        have = ", ".join(f"`{scheme}` {len(runs[scheme])} of {len(seeds)}" for scheme, seeds in FINAL_SEEDS.items())
        lines += [
            "",
            f"**Interim look** (runs: {have}): the declared reading waits for all of them, and nothing corrects for "
            "reading it more than once.",
        ]
    lines += [
        "",
        "p: the exact two-sided Mann-Whitney U test; Holm p: adjusted within the metric's family (the fixed graph "
        "against `full` and against `selected`, declared in `fixed_graph.py` before its runs were read).",
        "",
        f"**{'Reading' if is_final(runs) else 'Interim reading'}** (the min-dist sum, by the rule `fixed_graph.py` "
        f"declares; not shown worse is not shown as good: see the interval): {reading(first)}.",
        "",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, help="write the page here (default: print it)")
    parser.add_argument("--fixed-results", type=Path, default=FIXED_RESULTS, help="the fixed graph's results directory")
    parser.add_argument("--study-results", type=Path, default=STUDY_RESULTS, help="the study's, holding Exp. 1")
    args = parser.parse_args(argv)
    runs = read_runs(args.fixed_results, args.study_results)
    text = page(runs, {metric: compare(runs, metric) for metric in METRICS_READ})
    if args.out is None:
        print(text)
    else:
        args.out.write_text(text)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
