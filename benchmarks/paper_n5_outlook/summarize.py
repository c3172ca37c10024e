"""
The N=5 outlook, summarised: learning curves of ``full`` and ``selected`` (k=2) in the paper's experiment-1 setting,
where they start to separate, and what the paper's whole protocol would cost.

Reads the runs in ``results/`` (written by ``benchmarks/paper_n3/run_study.sh``) and writes into ``report/``:

- ``sb3-maddpg report``'s tables and figures for ``min_dist_sum``, ``return_mean``, ``success_rate`` and
  ``success_rate_r0.3``;
- ``outlook.md``: per learning-curve step, each scheme's IQM of the team return over seeds with its 95% bootstrap
  interval, the first step from which the two intervals stay apart (the budget at which the schemes separate at
  this number of seeds, if they do), and the cost of the paper's protocol (310 runs: 155 of 2.5M steps at N=5 full
  observability and 155 of 3.75M steps with two neighbours observed) from the runs' measured throughput: on one
  core of this machine, on 16 cores (one run per core) and on a Ray cluster with a core per run (the longest run).

Usage::

    python benchmarks/paper_n5_outlook/summarize.py [results] [report]
"""

import json
import statistics
import sys
from pathlib import Path

from sb3_maddpg.experiments.results_dir import load_summaries
from sb3_maddpg.results import make_report
from sb3_maddpg.results.plots import iqm_curves

HERE = Path(__file__).resolve().parent
PROTOCOL_STEPS = 155 * 2_500_000 + 155 * 3_750_000
"""Env steps of the paper's whole protocol: 5 schemes x 31 seeds in each of its two experiments."""


def separation_step(first: tuple, second: tuple) -> float | None:  # type: ignore[type-arg]
    """
    :param first: ``(steps, iqm, low, high)`` of one scheme (see ``iqm_curves``).
    :param second: The same of the other, at the same steps.
    :return: The first step from which the two 95% intervals never overlap again, or ``None``.
    """
    steps, _, low_a, high_a = first
    _, _, low_b, high_b = second
    apart = (low_a > high_b) | (low_b > high_a)
    for index in range(len(steps)):
        if apart[index:].all():
            return float(steps[index])
    return None


def _interval(curve: tuple, index: int) -> str:  # type: ignore[type-arg]
    """``iqm [low, high]`` of a curve at one step."""
    return f"{curve[1][index]:.1f} [{curve[2][index]:.1f}, {curve[3][index]:.1f}]"


def outlook(results: Path) -> str:
    """:return: The Markdown of ``outlook.md``."""
    summaries = load_summaries(results)
    curves = iqm_curves(summaries, "return_mean")
    lines = []
    for setting, by_scheme in curves.items():
        schemes = sorted(by_scheme)
        lines += [f"### {setting}: team return, IQM over seeds [95% CI]", ""]
        lines += ["| env steps | " + " | ".join(schemes) + " |", "|---|" + "---|" * len(schemes)]
        steps = by_scheme[schemes[0]][0]
        for index, step in enumerate(steps):
            cells = [_interval(by_scheme[scheme], index) for scheme in schemes]
            lines.append(f"| {int(step):,} | " + " | ".join(cells) + " |")
        if len(schemes) == 2:
            step = separation_step(by_scheme[schemes[0]], by_scheme[schemes[1]])
            verdict = (
                f"stay apart from {int(step):,} env steps on"
                if step is not None
                else "do not stay apart at any step of this budget"
            )
            lines += ["", f"The 95% intervals of {schemes[0]}'s and {schemes[1]}'s team return {verdict}.", ""]
    # Whole runs: training, the learning-curve evaluations and the checkpoint evaluations.
    rates = [summary["total_timesteps"] / summary["wall_time_s"] for summary in summaries]
    if rates:
        rate = statistics.mean(rates)
        one_core_h = PROTOCOL_STEPS / rate / 3600
        longest_run_h = 3_750_000 / min(rates) / 3600
        lines += [
            "### The paper's whole protocol at this throughput",
            "",
            f"Measured: {len(rates)} runs of {json.dumps(sorted({s['scheme'] for s in summaries}))} at {rate:,.0f} env "
            f"steps/s each on average (slowest {min(rates):,.0f}), whole runs (training and every evaluation) over "
            "wall time, two runs at a time on this machine's 2 cores.",
            "",
            "| where | wall time |",
            "|---|---|",
            f"| one core of this machine | {one_core_h:,.0f} h ({one_core_h / 24:.1f} days) |",
            f"| a 16-core machine, one run per core | {one_core_h / 16:,.1f} h |",
            f"| a Ray cluster with a core per run (310 cores) | {longest_run_h:.1f} h (the longest run) |",
            "",
        ]
    return "\n".join(lines)


def main() -> None:
    """Write the report and the outlook."""
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE / "report"
    metrics = ("min_dist_sum", "return_mean", "success_rate", "success_rate_r0.3")
    for path in make_report(results, out, metrics=metrics):
        print(path)
    (out / "outlook.md").write_text(outlook(results))
    print(out / "outlook.md")


if __name__ == "__main__":
    main()
