"""
Summarise the Beyond MPE runs: for each study (a ``--name`` of ``run.py``), the trained team against random actions
and against doing nothing, on the same evaluation episodes.

Reads ``results/*.json`` (written by ``run.py``) and writes ``summary.md`` beside this file. The score is the team
return (the sum over the agents of their episode rewards; higher is better), averaged over the evaluation episodes:

- a trained team: one value per training seed (its mean over the evaluation episodes); the mean over the seeds and
  a 95% bootstrap interval over the seeds (``scipy.stats.bootstrap``, percentile method, 10,000 resamples: with 3
  seeds it can be no wider than the seeds' range, a description of these seeds, not a population's);
- a baseline (one fixed policy): its mean over the evaluation episodes and a 95% bootstrap interval over the
  episodes.

Usage::

    python benchmarks/beyond_mpe/summarize.py [results] [summary.md]
"""

import json
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import bootstrap

HERE = Path(__file__).resolve().parent
BASELINES = {"random": "random actions (uniform)", "zero": "doing nothing (zero / no-op action)"}


def interval(values: list[float]) -> tuple[float, float] | None:
    """:return: The 95% percentile bootstrap interval of the mean of the values (None for fewer than 2)."""
    if len(values) < 2 or np.ptp(values) == 0:
        return None if len(values) < 2 else (float(values[0]), float(values[0]))
    result = bootstrap(
        (np.asarray(values, dtype=float),),
        np.mean,
        confidence_level=0.95,
        n_resamples=10_000,
        method="percentile",
        random_state=np.random.default_rng(0),
    )
    return float(result.confidence_interval.low), float(result.confidence_interval.high)


def fmt_interval(bounds: tuple[float, float] | None) -> str:
    return "" if bounds is None else f"[{bounds[0]:.2f}, {bounds[1]:.2f}]"


def study_section(name: str, runs: list[dict[str, Any]]) -> list[str]:
    """:return: One study's lines of ``summary.md``."""
    trained = sorted((run for run in runs if run["kind"] == "trained"), key=lambda run: run["seed"])
    baselines = {run["kind"]: run for run in runs if run["kind"] in BASELINES}
    first = (trained or list(baselines.values()))[0]
    lines = [
        f"## {name}",
        "",
        f"- Env: `pettingzoo.sisl` {first['env']} with `{json.dumps(first['env_kwargs'])}` (PettingZoo "
        f"{first['versions'].get('pettingzoo', '?')}); the other arguments at PettingZoo's defaults.",
        f"- Evaluation: {first['eval_episodes']} episodes, episode e reset with seed {first['eval_seed']} + e, the same "
        "for every policy; the trained team acts deterministically (`model.predict`).",
        "- Score: the team return, the sum over the agents of their rewards over an episode (higher is better).",
    ]
    if trained:
        hyper = trained[0]["hyperparameters"]
        lines.append(f"- Training: {trained[0]['steps']:,} env steps per seed; `{json.dumps(hyper)}`.")
        lines.append(f"- Commit(s) at start: {', '.join(sorted({run['commit'][:12] for run in trained}))}.")
    lines += [
        "",
        "| policy | seeds | per-seed mean team return | mean | 95% interval | over | train wall (s) | steps/s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for kind, label in BASELINES.items():
        if kind in baselines:
            run = baselines[kind]
            lines.append(
                f"| {label} | - | - | {run['mean_return']:.2f} | {fmt_interval(interval(run['returns']))} | "
                f"{len(run['returns'])} episodes | - | - |"
            )
    if trained:
        values = [run["mean_return"] for run in trained]
        algo = trained[0]["hyperparameters"]["algo"].upper()
        walls = ", ".join(f"{run['train_seconds']:.0f}" for run in trained)
        rates = ", ".join(f"{run['steps_per_second']:.0f}" for run in trained)
        lines.append(
            f"| trained ({algo}, `{trained[0]['hyperparameters']['critic_sharing']}`) | "
            f"{', '.join(str(run['seed']) for run in trained)} | {', '.join(f'{v:.2f}' for v in values)} | "
            f"{np.mean(values):.2f} | {fmt_interval(interval(values))} | {len(values)} seeds | {walls} | {rates} |"
        )
        lines.append("")
        for kind, label in BASELINES.items():
            if kind in baselines:
                base = baselines[kind]["mean_return"]
                above = sum(value > base for value in values)
                lines.append(
                    f"- Against {label}: {above} of {len(values)} seeds above it; mean difference "
                    f"{np.mean(values) - base:+.2f}."
                )
        lines.append("")
        lines.append(
            "Training curve (mean return of the training episodes, with exploration, that ended in each tenth "
            "of the budget; mean over seeds):"
        )
        lines.append("")
        steps = [row["steps"] for row in trained[0]["training_curve"]]
        lines.append("| env steps | " + " | ".join(f"{s:,}" for s in steps) + " |")
        lines.append("|---|" + "---|" * len(steps))
        means = []
        for k in range(len(steps)):
            points = [run["training_curve"][k]["mean_return"] for run in trained]
            points = [p for p in points if p is not None]
            means.append(f"{np.mean(points):.1f}" if points else "")
        lines.append("| team return | " + " | ".join(means) + " |")
    lines.append("")
    return lines


def main() -> None:
    results = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    target = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE / "summary.md"
    studies: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for path in sorted(results.glob("*.json")):
        run = json.loads(path.read_text())
        studies[run["name"]].append(run)
    lines = ["# Beyond MPE: results", "", "Written by `python benchmarks/beyond_mpe/summarize.py` from `results/`.", ""]
    for name, runs in studies.items():
        lines += study_section(name, runs)
    target.write_text("\n".join(lines))
    print(target.read_text())


if __name__ == "__main__":
    main()
