"""The paper's protocol as code: experiment configs and presets, and running them (one run, or sweeps on local
processes, Ray or run groups) into a results directory. Reading a results directory (statistics, the paper's claims,
tables, plots) is :mod:`sb3_maddpg.results`; the command line, :mod:`sb3_maddpg.cli`; tuning, :mod:`sb3_maddpg.tuning`.
"""

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # what the names below are, for type checkers and editors; imported when first used
    from sb3_maddpg.experiments.config import (
        BASELINE_SCHEME as BASELINE_SCHEME,
    )
    from sb3_maddpg.experiments.config import (
        EXP1 as EXP1,
    )
    from sb3_maddpg.experiments.config import (
        EXP1_TUNED as EXP1_TUNED,
    )
    from sb3_maddpg.experiments.config import (
        EXP2 as EXP2,
    )
    from sb3_maddpg.experiments.config import (
        EXP2_TUNED as EXP2_TUNED,
    )
    from sb3_maddpg.experiments.config import (
        EXPERIMENTS as EXPERIMENTS,
    )
    from sb3_maddpg.experiments.config import (
        PAPER_NAMES as PAPER_NAMES,
    )
    from sb3_maddpg.experiments.config import (
        SMOKE as SMOKE,
    )
    from sb3_maddpg.experiments.config import (
        load_experiment as load_experiment,
    )
    from sb3_maddpg.experiments.defaults import SCHEMES as SCHEMES
    from sb3_maddpg.experiments.presets import read_preset_file as read_preset_file
    from sb3_maddpg.experiments.results_dir import ResultsDirectoryLocked as ResultsDirectoryLocked
    from sb3_maddpg.experiments.runner import execute_run as execute_run
    from sb3_maddpg.experiments.setting import (
        AlgorithmConfig as AlgorithmConfig,
    )
    from sb3_maddpg.experiments.setting import (
        ExperimentConfig as ExperimentConfig,
    )
    from sb3_maddpg.experiments.setting import (
        ProtocolConfig as ProtocolConfig,
    )
    from sb3_maddpg.experiments.setting import (
        RunConfig as RunConfig,
    )
    from sb3_maddpg.experiments.setting import (
        TaskConfig as TaskConfig,
    )
    from sb3_maddpg.experiments.sweep import (
        SweepInterrupted as SweepInterrupted,
    )
    from sb3_maddpg.experiments.sweep import (
        SweepResult as SweepResult,
    )
    from sb3_maddpg.experiments.sweep import (
        run_sweep as run_sweep,
    )

_HOMES = {
    **dict.fromkeys(
        ["BASELINE_SCHEME", "EXP1", "EXP1_TUNED", "EXP2", "EXP2_TUNED", "EXPERIMENTS", "PAPER_NAMES", "SMOKE"], "config"
    ),
    "load_experiment": "config",
    "SCHEMES": "defaults",
    **dict.fromkeys(["AlgorithmConfig", "ExperimentConfig", "ProtocolConfig", "RunConfig", "TaskConfig"], "setting"),
    "read_preset_file": "presets",
    "ResultsDirectoryLocked": "results_dir",
    "execute_run": "runner",
    **dict.fromkeys(["SweepInterrupted", "SweepResult", "run_sweep"], "sweep"),
}
"""Each public name's module: imported on first use (PEP 562), so that a run imports no run group code."""


def __getattr__(name: str) -> Any:
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)
    globals()[name] = value  # the next lookup finds it directly
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_HOMES})


__all__ = sorted(_HOMES)  # the public names: those with a home (typed above for type checkers)
