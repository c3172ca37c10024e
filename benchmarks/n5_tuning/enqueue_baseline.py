"""
Put the paper's values of the searched parameters into the N=5 tuning study as a trial of its own (once: Optuna skips a
trial already enqueued or run with them), so that the study measures its baseline by its own protocol. Usage::

    python benchmarks/n5_tuning/enqueue_baseline.py [storage]
"""

import sys

import optuna

from sb3_maddpg.tuning.search import default_study_name

FIXED = {"transitions_per_update": 25, "batch_size": 1024, "width": 64}
"""The parameters ``run.sh`` fixes (its ``--fixed-params``)."""

STUDY = default_study_name("n5_sorted_obs_utd25_shared_params", "min_dist_sum", FIXED)
"""The study ``run.sh`` runs (its default name: the setting, the objective and the fixed parameters)."""

PAPER_VALUES = {"learning_rate": 1e-2, "noise_std": 0.1, "tau": 0.01, "gamma": 0.95, "actor_reg_coef": 1e-3}
"""MADDPG's defaults (the paper's, Lowe et al.'s) of the parameters the study searches."""

if __name__ == "__main__":
    storage = sys.argv[1] if len(sys.argv) > 1 else "sqlite:///benchmarks/n5_tuning/results/tune.db"
    study = optuna.create_study(study_name=STUDY, storage=storage, direction="minimize", load_if_exists=True)
    study.enqueue_trial({**PAPER_VALUES, **FIXED}, skip_if_exists=True)
    print(f"enqueued the paper's values in {STUDY!r}: {PAPER_VALUES}")
