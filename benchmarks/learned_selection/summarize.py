"""
Issue 12's measurement, summarised: the report of the runs (Table 2 with Mann-Whitney U against ``full``, the
aggregate estimates, learning curves, boxplots) and what the learned critics listen to over training.

Reads the runs in ``results/`` (written by ``run.sh``) and writes into ``docs/_static/learned_selection/``:

- ``sb3-maddpg report``'s files for ``min_dist_sum``, ``return_mean`` and ``success_rate``;
- ``description.md`` (shown on the docs page after the hand-written ``README.md`` with the reading), with two
  tables. Cost: per setting and scheme, the runs' mean training throughput (env steps/s of the whole run: env steps,
  updates and the learning-curve evaluations, which pull the ratio towards 1; ``update_time.md`` has the updates
  alone) and its ratio to ``full``'s, from the same sweep;
  What the critics listen to: for ``attention`` and ``learned_selection``, the team means of
  ``train/weight_on_nearest``, ``train/attention_entropy`` and (learned selection) ``train/chose_nearest`` and
  ``train/top_choice_share`` from SB3's log, mean over seeds every 100k steps: whether the learned selection
  converges to the k nearest agents, to a choice that ignores the state, or to something else;
- ``listening.png``: the same over training, per setting.

Usage::

    python benchmarks/learned_selection/summarize.py [results] [report]   # defaults: results/, docs/_static/...
"""

import csv
import statistics
import sys
from pathlib import Path

from sb3_maddpg.experiments.results_dir import link_complete_seeds, load_experiments, load_summaries, read_curve
from sb3_maddpg.results import make_report
from sb3_maddpg.sharing import default_selection_size

HERE = Path(__file__).resolve().parent
DIAGNOSTICS = ("weight_on_nearest", "attention_entropy", "head_entropy", "chose_nearest", "top_choice_share")
CURVE_METRICS = {"min_dist_sum": "min-dist sum", "return_mean": "team return"}
LEARNED = ("attention", "learned_selection")
SCHEMES = ("full", "selected", *LEARNED)
METRICS = {
    "min_dist_sum": "min-dist sum (lower is better)",
    "return_mean": "team return (higher is better)",
    "success_rate": "success rate (fraction, higher is better)",
}


def logged(run: Path, key: str) -> list[tuple[int, float]]:
    """``(step, value)`` of a logged key of a run's SB3 log."""
    with open(run / "progress.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    return [
        (int(float(row["time/total_timesteps"])), float(row[key]))
        for row in rows
        if row.get(key) and row.get("time/total_timesteps")
    ]


def series(results: Path, experiment: str, scheme: str, key: str, steps: list[int]) -> list[float | None]:
    """The mean over finished seeds of the logged value nearest each step (``None`` where no run has it)."""
    runs = [Path(s["directory"]) for s in load_summaries(results) if (s["experiment"], s["scheme"]) == (experiment, scheme)]
    logs = [points for points in (logged(run, f"train/{key}") for run in runs) if points]
    values: list[float | None] = []
    for step in steps:
        at_step = [min(points, key=lambda point: abs(point[0] - step))[1] for points in logs]
        values.append(statistics.mean(at_step) if at_step else None)
    return values


def cost_table(results: Path) -> str:
    """:return: Markdown: per setting and scheme, mean training steps/s over the finished runs and the ratio to full."""
    rates: dict[tuple[str, str], list[float]] = {}
    for summary in load_summaries(results):
        rates.setdefault((summary["experiment"], summary["scheme"]), []).append(summary["train_steps_per_s"])
    lines = ["| setting | scheme | runs | train steps/s (mean) | vs full |", "|---|---|---|---|---|"]
    for (experiment, scheme), values in sorted(rates.items()):
        full = rates.get((experiment, "full"))
        ratio = f"{statistics.mean(values) / statistics.mean(full):.2f}" if full else ""
        lines.append(f"| {experiment} | {scheme} | {len(values)} | {statistics.mean(values):,.0f} | {ratio} |")
    return "\n".join(lines) + "\n"


def against_rule_table(results: Path) -> str:
    """
    :param results: A results directory (or a view of its complete seeds).
    :return: Markdown: per setting and metric, the learned critics' scores against ``selected``'s (the paper's k
        nearest rule): mean (std) over runs and the two-sided Mann-Whitney U p-value.
    """
    from scipy.stats import mannwhitneyu

    scores: dict[tuple[str, str], list[dict[str, float]]] = {}
    for summary in load_summaries(results):
        scores.setdefault((summary["experiment"], summary["scheme"]), []).append(summary["score"])
    lines = ["| setting | metric | selected | attention (p) | learned_selection (p) |", "|---|---|---|---|---|"]
    for experiment in sorted({experiment for experiment, _ in scores}):
        rule = scores.get((experiment, "selected"), [])
        if len(rule) < 2:
            continue
        for metric, label in METRICS.items():
            base = [score[metric] for score in rule]
            cells = [_mean_std(base)]
            for scheme in LEARNED:
                runs = [score[metric] for score in scores.get((experiment, scheme), [])]
                if len(runs) < 2:
                    cells.append("")
                    continue
                p_value = mannwhitneyu(runs, base, alternative="two-sided").pvalue
                cells.append(f"{_mean_std(runs)} (p = {p_value:.3f})")
            lines.append(f"| {experiment} | {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _mean_std(values: list[float]) -> str:
    """:return: ``mean (std)`` of at least two values, to three and two significant digits."""
    return f"{statistics.mean(values):.3g} ({statistics.stdev(values):.2g})"


def listening_table(results: Path, experiments: list[str], steps: list[int]) -> str:
    """
    :param results: A results directory (or a view of its complete seeds).
    :param experiments: The settings to show.
    :param steps: The env steps of the columns.
    :return: Markdown: per setting, learned scheme and summary, its mean over seeds at each step.
    """
    lines = ["| setting | scheme | summary | " + " | ".join(f"{step // 1000}k" for step in steps) + " |"]
    lines.append("|---|---|---|" + "---|" * len(steps))
    for experiment in experiments:
        for scheme in LEARNED:
            for key in DIAGNOSTICS:
                values = series(results, experiment, scheme, key, steps)
                if all(value is None for value in values):
                    continue
                cells = ["" if value is None else f"{value:.2f}" for value in values]
                lines.append(f"| {experiment} | {scheme} | {key} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def curve_table(results: Path, experiments: list[str], steps: list[int]) -> str:
    """
    :param results: A results directory (or a view of its complete seeds).
    :param experiments: The settings to show.
    :param steps: The env steps of the columns (learning-curve evaluations at other steps are not shown).
    :return: Markdown: per setting, metric and scheme, the learning curve's mean over the runs at each step.
    """
    curves: dict[tuple[str, str], list[dict[int, dict[str, float]]]] = {}
    for summary in load_summaries(results):
        rows = {int(row["timesteps"]): row for row in read_curve(summary["directory"])}
        curves.setdefault((summary["experiment"], summary["scheme"]), []).append(rows)
    lines = ["| setting | metric | scheme | runs | " + " | ".join(f"{step // 1000}k" for step in steps) + " |"]
    lines.append("|---|---|---|---|" + "---|" * len(steps))
    for experiment in experiments:
        for metric, label in CURVE_METRICS.items():
            for scheme in SCHEMES:
                runs = curves.get((experiment, scheme), [])
                cells = []
                for step in steps:
                    values = [run[step][metric] for run in runs if step in run]
                    cells.append(f"{statistics.mean(values):.3g}" if values else "")
                if runs:
                    lines.append(f"| {experiment} | {label} | {scheme} | {len(runs)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def chance_levels(experiment: Path) -> tuple[float, float]:
    """
    :param experiment: A setting's directory, holding its ``experiment.json``.
    :return: The weight on any one other agent when listening evenly, ``1 / (n - 1)``, and the chance that k others
        drawn at random are the k nearest, ``1 / C(n - 1, k)``.
    """
    import json
    import math

    config = json.loads((experiment / "experiment.json").read_text())
    n_others = config["n_agents"] - 1
    kwargs = config.get("scheme_model_kwargs", {}).get("learned_selection", {}).get("critic_sharing_kwargs", {})
    k = kwargs.get("k", default_selection_size(n_others + 1))
    return 1 / n_others, 1 / math.comb(n_others, k)


def listening_plot(results: Path, experiments: list[str], steps: list[int], path: Path) -> None:
    """
    Draw, per setting, the weight on the nearest agent and how often the choice is the k nearest, over training,
    with their chance levels.

    :param results: A results directory (or a view of its complete seeds).
    :param experiments: The settings, one panel each.
    :param steps: The env steps to draw.
    :param path: The image file to write.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, len(experiments), figsize=(5.5 * len(experiments), 4), squeeze=False)
    for axis, experiment in zip(axes[0], experiments):
        for scheme, key, style in (
            ("attention", "weight_on_nearest", "-"),
            ("learned_selection", "weight_on_nearest", "--"),
            ("learned_selection", "chose_nearest", ":"),
            ("learned_selection", "top_choice_share", "-."),
        ):
            values = series(results, experiment, scheme, key, steps)
            points = [(step, value) for step, value in zip(steps, values) if value is not None]
            if points:
                axis.plot(*zip(*points), style, label=f"{scheme}: {key}")
        uniform, nearest_by_chance = chance_levels(results / experiment)
        axis.axhline(uniform, color="grey", lw=0.8, ls="--", label=f"uniform weight: {uniform:.2f}")
        axis.axhline(nearest_by_chance, color="grey", lw=0.8, ls=":", label=f"k nearest by chance: {nearest_by_chance:.2f}")
        axis.set_title(experiment)
        axis.set_xlabel("env steps")
        axis.set_ylabel("fraction (mean over seeds)")
        axis.set_ylim(0, 1)
        axis.grid(alpha=0.3)
        axis.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def main() -> None:
    """Write the report and the listening summaries of the seeds every scheme has finished."""
    import tempfile

    given = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "results"
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else HERE.parents[1] / "docs" / "_static" / "learned_selection"
    with tempfile.TemporaryDirectory() as view:
        left_out = link_complete_seeds(given, view)
        if left_out:
            print(f"left out until every scheme has their seed: {', '.join(left_out)}")
        if not any(Path(view).iterdir()):
            sys.exit(f"no seed of {given} is finished by every scheme of its setting yet: nothing to report.")
        write(Path(view), out)


def write(results: Path, out: Path) -> None:
    """
    Write the report and the listening summaries.

    :param results: A results directory (or a view of its complete seeds).
    :param out: The report directory.
    """
    for path in make_report(results, out, metrics=("min_dist_sum", "return_mean", "success_rate")):
        print(path)
    experiments = sorted(load_experiments(results))
    total = max(summary["total_timesteps"] for summary in load_summaries(results))
    steps = list(range(max(1, total // 10), total + 1, max(1, total // 10)))
    description = [
        "## Against the k nearest rule",
        "",
        "The learned critics against `selected` (MADDPG-soa, the paper's k nearest rule, which sees as many agents "
        "as `learned_selection`): mean (std) over the runs of each scheme's score, and the two-sided Mann-Whitney U "
        "p-value against `selected`'s runs (`scipy.stats.mannwhitneyu`).",
        "",
        against_rule_table(results),
        "## Learning curves in numbers",
        "",
        "The learning curves' evaluations (deterministic policy, `curve_eval_episodes` episodes each: 20 here, so a "
        "single point is noisy), mean over the runs, every tenth of the budget. Min-dist sum: lower is better; team "
        "return: higher is better.",
        "",
        curve_table(results, experiments, steps),
        "## What the learned critics listen to",
        "",
        "Team means over the critics of the last critic update before each log write, mean over the finished seeds, "
        "at each budget. `attention_entropy` in nats (uniform: log(N-1), 0.69 at N=3, 1.39 at N=5); "
        "`weight_on_nearest`: the weight on the nearest other agent; `chose_nearest`: fraction of states whose "
        "chosen set is the k nearest (chance: 0.5 at N=3 with k=1, 1/6 at N=5 with k=2); `top_choice_share`: "
        "fraction of states whose first choice is the agent chosen first most often (1: the state is ignored). "
        "Each value is one replayed batch (1024 rows) per critic and seed, so the second decimal is noise. For "
        "`attention`, the weights are the mean of its 4 heads': heads that each listen sharply to different agents "
        "would look uniform here. `head_entropy`, each head's own entropy, was added after these runs: where its "
        "row is missing, the runs did not log it.",
        "",
        listening_table(results, experiments, steps),
        "## Cost",
        "",
        "Mean training throughput of the runs (env steps/s of the whole run, evaluations included; the update "
        "alone is in `benchmarks/learned_selection/update_time.md`), one torch thread each, two runs at a time on "
        "a 2-core machine; higher is faster.",
        "",
        cost_table(results),
    ]
    (out / "description.md").write_text("\n".join(description))
    listening_plot(results, experiments, steps, out / "listening.png")
    print(out / "description.md", out / "listening.png", sep="\n")


if __name__ == "__main__":
    main()
