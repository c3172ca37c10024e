"""
Hyperparameter search on Optuna (``sb3-maddpg tune``): a sampler of MADDPG's hyperparameters, a pruner fed by
evaluations during training, a study in SQLite that resumes and that several workers share
(:mod:`sb3_maddpg.tuning.search`). Optuna is the ``tune`` extra: ``pip install -e ".[tune]"``.
"""

from sb3_maddpg.tuning.search import TuneSettings, run_study

__all__ = ["TuneSettings", "run_study"]
