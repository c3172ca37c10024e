"""
The N=5 tuning study, summarised: every trial of ``results/tune.db`` (written by ``benchmarks/n5_tuning/run.sh``) in
``trials.csv``, and ``summary.md``: the trials ranked by their objective (min-dist sum, lower is better), their
parameters and cost, how many were pruned, and which parameters mattered (Optuna's fANOVA importances, once enough
trials completed). Usage::

    python benchmarks/n5_tuning/summarize.py [tune.db] [summary.md]
"""

import csv
import sys
from pathlib import Path
from typing import Any

import optuna

HERE = Path(__file__).resolve().parent
SEARCHED = ("learning_rate", "noise_std", "tau", "gamma", "actor_reg_coef")
"""The parameters the study searches (run.sh fixes the others)."""


def trial_rows(study: Any) -> list[dict[str, Any]]:
    """:return: One row per trial: number, state, value, last reported value and step, parameters, minutes."""
    rows = []
    for trial in study.trials:
        last_step = max(trial.intermediate_values, default=None)
        minutes = (
            (trial.datetime_complete - trial.datetime_start).total_seconds() / 60
            if trial.datetime_complete and trial.datetime_start
            else None
        )
        rows.append(
            {
                "number": trial.number,
                "state": trial.state.name.lower(),
                "value": trial.value,
                "last_reported": None if last_step is None else trial.intermediate_values[last_step],
                "last_reported_step": last_step,
                **{name: trial.params.get(name) for name in SEARCHED},
                "minutes": minutes,
            }
        )
    return rows


def importances(study: Any) -> dict[str, float]:
    """:return: Each searched parameter's fANOVA importance (empty while too few trials completed)."""
    complete = [trial for trial in study.trials if trial.state == optuna.trial.TrialState.COMPLETE]
    if len(complete) < 4:
        return {}
    return optuna.importance.get_param_importances(study, params=[name for name in SEARCHED if name in complete[0].params])


def fmt(value: Any, digits: int = 3) -> str:
    """:return: A table cell: blank for None, small floats in ``g`` format, others with ``digits`` decimals."""
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.{digits}g}" if abs(value) < 1e-2 and value != 0 else f"{value:.{digits}f}"
    return str(value)


def main(storage_path: Path, summary_path: Path) -> None:
    """
    :param storage_path: The study's SQLite file.
    :param summary_path: Where ``summary.md`` goes (``trials.csv`` beside it).
    """
    storage = f"sqlite:///{storage_path}"
    names = optuna.study.get_all_study_names(storage)
    lines = ["# N=5 tuning study", ""]
    rows_all = []
    for name in names:
        study = optuna.load_study(study_name=name, storage=storage)
        rows = trial_rows(study)
        rows_all += [{"study": name, **row} for row in rows]
        states = [row["state"] for row in rows]
        # Complete trials only: a pruned trial's value is its last report, at a step where the others were better.
        ranked = sorted((row for row in rows if row["state"] == "complete"), key=lambda row: row["value"])
        lines += [
            f"Study `{name}`: {states.count('complete')} complete, {states.count('pruned')} pruned, "
            f"{states.count('running')} running, {states.count('fail')} failed trials. Setting: simple_spread N=5, full "
            "observability with agents and landmarks observed nearest first, `full` sharing, one gradient step per 25 "
            "transitions, one actor and one critic shared by all agents, batch 1024, 64-unit networks (fixed); 400k "
            "env steps per trial, seed 0; objective: min-dist "
            "sum (lower is better) over the last 2 of 8 evaluations of 50 episodes; no trial is pruned before its 4th "
            "evaluation (200k steps). The paper's values of the searched "
            "parameters (learning rate 0.01, noise 0.1, tau 0.01, gamma 0.95, regulariser 0.001) are a trial of the "
            "study (`enqueue_baseline.py`).",
            "",
            "| rank | trial | min-dist sum | " + " | ".join(SEARCHED) + " | minutes |",
            "|---|---|---|" + "---|" * len(SEARCHED) + "---|",
        ]
        for rank, row in enumerate(ranked, start=1):
            cells = " | ".join(fmt(row[name]) for name in SEARCHED)
            lines.append(f"| {rank} | {row['number']} | {row['value']:.3f} | {cells} | {fmt(row['minutes'], 1)} |")
        pruned = [row for row in rows if row["state"] == "pruned"]
        if pruned:
            lines += [
                "",
                "Pruned (last reported min-dist sum at its step). A trial pruned before 200,000 steps was stopped before "
                "the study's warm-up was set to 3 evaluations (at 50,000 steps, its first evaluation, by an off-by-one "
                "fixed on 2026-12-02); its sample runs again as a later trial (`requeue_early_pruned.py`):",
            ]
            lines += [
                f"- trial {row['number']}: {fmt(row['last_reported'])} at {row['last_reported_step']:,} steps"
                for row in pruned
            ]
        weights = importances(study)
        if weights:
            lines += ["", "Importance (fANOVA, share of the objective's variance): "]
            lines.append(", ".join(f"{name} {weight:.2f}" for name, weight in weights.items()))
        lines.append("")
    lines += ["Made by `bash benchmarks/n5_tuning/run.sh` (resumable), then `python benchmarks/n5_tuning/summarize.py`."]
    summary_path.write_text("\n".join(lines) + "\n")
    with open(summary_path.parent / "trials.csv", "w", newline="") as file:
        if rows_all:
            writer = csv.DictWriter(file, fieldnames=list(rows_all[0]))
            writer.writeheader()
            writer.writerows(rows_all)


if __name__ == "__main__":
    db = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results" / "tune.db"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE / "summary.md"
    main(db, out)
