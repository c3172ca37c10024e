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
import json
import sys
from pathlib import Path

from sb3_maddpg.experiments.config import algorithm_argument
from sb3_maddpg.experiments.results import load_summaries
from sb3_maddpg.normalised_score import reference_scores

HERE = Path(__file__).resolve().parent
CURVE_STEPS = (200_000, 400_000, 600_000, 800_000, 1_000_000)
_spec = importlib.util.spec_from_file_location("n5_tuned_summarize", HERE.parent / "n5_tuned" / "summarize.py")
assert _spec is not None and _spec.loader is not None
tables = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tables)


def summarise(results: Path) -> str:
    """:return: The Markdown of ``summary.md``."""
    summaries = sorted(load_summaries(results), key=lambda summary: summary["seed"])
    experiments = {path.parent.name: json.loads(path.read_text()) for path in sorted(results.glob("*/experiment.json"))}
    references = reference_scores(5)
    lines = [
        "# N=5, Experiment 2's setting: the paper's configuration and exp2_tuned",
        "",
        "Setting: simple_spread N=5, each agent observes the two nearest other agents (the paper's Experiment 2), `full` "
        "sharing, 100 batched worlds, 1M env steps per run (the setting's budget is 3.75M). Score: mean of 20 checkpoint "
        "evaluations (100 episodes each) over the last 20% of training. Min-dist sum: lower is better; success within "
        "0.3 and normalised scores: higher is better (0 = uniformly random actions, 1 = the scripted controller: "
        f"min-dist sum {references['random']['min_dist_sum']:.2f} and {references['scripted']['min_dist_sum']:.2f}). "
        f"Issue 21's target (set for Experiment 1's setting): min-dist sum at most {tables.TARGET['min_dist_sum']}, "
        f"success within 0.3 at least {tables.TARGET['success_rate_r0.3']:.0%}.",
    ]
    for name in sorted(experiments, key=lambda name: (name != "n5_exp2_paper", name)):
        experiment = experiments[name]
        ratio = int(algorithm_argument(experiment, "transitions_per_update"))
        warm_up = int(algorithm_argument(experiment, "learning_starts"))
        lines += ["", f"## `{name}`: {experiment['description']}", ""]
        runs = [summary for summary in summaries if summary["experiment"] == name]
        lines += tables.score_lines(runs, ratio, warm_up, references)
        lines += ["", "Learning curve: min-dist sum (20-episode evaluations; lower is better).", ""]
        lines += tables.curve_lines(results, name, ratio, warm_up, CURVE_STEPS)
    lines += ["", "Made by `bash benchmarks/n5_exp2/run.sh` (resumable), then `python benchmarks/n5_exp2/summarize.py`."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE / "summary.md"
    out.write_text(summarise(results))
    print(out.read_text())
