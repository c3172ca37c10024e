"""
The exp2 check, summarised: Experiment 2's setting (N=5, the two nearest other agents observed) at the paper's
configuration and at ``exp2_tuned``, `full` sharing, 3 seeds x 1M steps. For each: each seed's score over the last
20% (mean of 20 checkpoint evaluations of 100 episodes), the mean (std), the normalised scores (0 = random, 1 = the
scripted controller) and the learning curve at equal env steps; reads ``results/`` (written by
``benchmarks/n5_exp2/run.sh``) and writes ``summary.md`` beside this file. The tables are ``benchmarks/n5_tuned``'s.
Usage::

    python benchmarks/n5_exp2/summarize.py [results] [summary.md]
"""

import importlib.util
import sys
from pathlib import Path

from sb3_maddpg.analysis.normalised_score import reference_scores

HERE = Path(__file__).resolve().parent
CURVE_STEPS = (200_000, 400_000, 600_000, 800_000, 1_000_000)
_spec = importlib.util.spec_from_file_location("n5_tuned_summarize", HERE.parent / "n5_tuned" / "summarize.py")
assert _spec is not None and _spec.loader is not None
tables = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tables)


def summarise(results: Path) -> str:
    """:return: The Markdown of ``summary.md``."""
    references = reference_scores(5)
    lines = [
        "# N=5, Experiment 2's setting: the paper's configuration and exp2_tuned",
        "",
        "Setting: simple_spread N=5, each agent observes the two nearest other agents (the paper's Experiment 2), `full` "
        "sharing, 100 batched worlds, 1M env steps per run (the setting's budget is 3.75M). "
        + tables.score_reading(references)
        + " "
        f"Issue 21's target (set for Experiment 1's setting): min-dist sum at most {tables.TARGET['min_dist_sum']}, "
        f"success within 0.3 at least {tables.TARGET['success_rate_r0.3']:.0%}.",
    ]
    lines += tables.experiment_sections(results, "n5_exp2_paper", lambda experiment, _: experiment["description"], CURVE_STEPS)
    lines += ["", "Made by `bash benchmarks/n5_exp2/run.sh` (resumable), then `python benchmarks/n5_exp2/summarize.py`."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE / "summary.md"
    out.write_text(summarise(results))
    print(out.read_text())
