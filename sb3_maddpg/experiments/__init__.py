"""The paper's protocol as code: experiment configs and presets, and running them (one run, or sweeps on local
processes, Ray or run groups) into a results directory. Reading a results directory (statistics, the paper's claims,
tables, plots) is :mod:`sb3_maddpg.results`; the command line, :mod:`sb3_maddpg.cli`; tuning, :mod:`sb3_maddpg.tuning`.

Importing it imports no run group, Ray or report code: those load when a sweep uses them.
"""

from sb3_maddpg.experiments.config import (
    BASELINE_SCHEME,
    EXP1,
    EXP1_TUNED,
    EXP2,
    EXP2_TUNED,
    EXPERIMENTS,
    PAPER_NAMES,
    SMOKE,
    load_experiment,
)
from sb3_maddpg.experiments.defaults import SCHEMES
from sb3_maddpg.experiments.presets import read_preset_file
from sb3_maddpg.experiments.results_dir import ResultsDirectoryLocked
from sb3_maddpg.experiments.runner import execute_run
from sb3_maddpg.experiments.setting import AlgorithmConfig, ExperimentConfig, ProtocolConfig, RunConfig, TaskConfig
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
    "AlgorithmConfig",
    "ExperimentConfig",
    "ProtocolConfig",
    "ResultsDirectoryLocked",
    "RunConfig",
    "SweepInterrupted",
    "SweepResult",
    "TaskConfig",
    "execute_run",
    "load_experiment",
    "read_preset_file",
    "run_sweep",
]
