"""The paper's protocol as code: experiment configs, runs, sweeps (local or Ray), statistics, tables and plots.

Command line: ``sb3-maddpg run --config exp1 ...`` then ``sb3-maddpg report <results>``
(or ``python -m sb3_maddpg.experiments ...``).
"""

from sb3_maddpg.experiments.config import (
    BASELINE_SCHEME,
    EXP1,
    EXP1_TUNED,
    EXP2,
    EXP2_TUNED,
    EXPERIMENTS,
    PAPER_NAMES,
    SCHEMES,
    SMOKE,
    ExperimentConfig,
    RunConfig,
    load_experiment,
)
from sb3_maddpg.experiments.report import make_report
from sb3_maddpg.experiments.results import ResultsDirectoryLocked
from sb3_maddpg.experiments.runner import execute_run
from sb3_maddpg.experiments.stats import aggregate, mann_whitney, significance_stars
from sb3_maddpg.experiments.sweep import SweepInterrupted, SweepResult, run_sweep

__all__ = [
    "BASELINE_SCHEME",
    "EXP1",
    "EXP1_TUNED",
    "EXP2",
    "EXP2_TUNED",
    "EXPERIMENTS",
    "PAPER_NAMES",
    "SCHEMES",
    "SMOKE",
    "ExperimentConfig",
    "ResultsDirectoryLocked",
    "RunConfig",
    "SweepInterrupted",
    "SweepResult",
    "aggregate",
    "execute_run",
    "load_experiment",
    "make_report",
    "mann_whitney",
    "run_sweep",
    "significance_stars",
]
