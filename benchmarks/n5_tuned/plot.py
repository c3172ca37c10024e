"""
The N=5 learning curves for the docs' "Learning at N=5" page: the paper's configuration, the diagnosis's main factors
(``benchmarks/n5_diagnosis``, 1M steps), the configurations that meet the target (``benchmarks/n5_tuned``, 2.5M
steps), among them the tuning study's best trial on the shipped one (``n5_tuned_shared_best``), min-dist sum
against env steps and against gradient steps, with the random team, the scripted controller and the target as levels.
Writes ``docs/_static/learning_n5/min_dist_sum_curves.png``. Usage::

    python benchmarks/n5_tuned/plot.py
"""

from pathlib import Path

from sb3_maddpg.analysis.normalised_score import reference_scores
from sb3_maddpg.experiments.config import algorithm_argument
from sb3_maddpg.experiments.results_dir import load_experiments, load_summaries
from sb3_maddpg.results.plots import plot_experiment_curves

HERE = Path(__file__).resolve().parent
RESULTS = (HERE / "results", HERE.parent / "n5_diagnosis" / "results", HERE.parent / "matd3" / "results")
"""Where the drawn experiments' runs are."""
LABELS = {
    "n5_paper": "the paper's configuration (1 gradient step per 100 transitions)",
    "n5_utd400": "1 step per 400 transitions",
    "n5_utd25": "1 step per 25 transitions",
    "n5_tpu10_maddpg": "1 step per 10 transitions",
    "n5_noise0.3": "exploration noise 0.3",
    "n5_sorted_obs": "nearest-first observations",
    "n5_sorted_obs_utd25": "nearest-first, 1 step per 25",
    "n5_tuned_shared_tpu100": "nearest-first, shared networks, 1 step per 100",
    "n5_tuned_shared": "nearest-first, shared networks, 1 step per 25",
    "n5_tuned_shared_best": "the same with tuning's best: tau 0.02, gamma 0.9, lr 7.7e-4, noise 0.098 (exp1_tuned)",
}
"""The experiments drawn (those with finished runs), by name: their legend labels."""
OUT = HERE.parent.parent / "docs" / "_static" / "learning_n5" / "min_dist_sum_curves.png"


def main() -> Path:
    """:return: The figure's path, after drawing it."""
    summaries, ratios = [], {}
    for results in RESULTS:
        experiments = load_experiments(results)
        for name in set(LABELS) & set(experiments):
            ratios[name] = int(algorithm_argument(experiments[name], "transitions_per_update"))
        summaries += [s for s in load_summaries(results) if s["experiment"] in ratios and s["scheme"] == "full"]
    references = reference_scores(5)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    return plot_experiment_curves(
        summaries,
        "min_dist_sum",
        OUT,
        LABELS,
        transitions_per_update=ratios,
        levels={
            "uniformly random actions": references["random"]["min_dist_sum"],
            "target (0.8)": 0.8,
            "scripted controller": references["scripted"]["min_dist_sum"],
        },
        y_max=3.5,  # the first evaluations, before learning, reach 6
        title="simple_spread N=5, exp1 setting, full sharing: min-dist sum during training (lower is better; 3 seeds)",
    )


if __name__ == "__main__":
    print(main())
