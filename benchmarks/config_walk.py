"""Which of the package's modules a run's config is handed to before ``learn`` (issue 58's measure).

    python benchmarks/config_walk.py

Runs one tiny run of the ``smoke`` preset through the command line (``sb3-maddpg run``, one worker: in this
process) and records, with ``sys.setprofile``, every call of a package function that takes a ``RunConfig`` or its
``RunTask`` (which carries the config) as a parameter (not their own methods, nor generators resumed) until ``learn``
starts: the modules a reader following the run's config from where it is made to the algorithm opens, how often each
is entered, and how often ``run_task``. What handles the config in other forms is not counted: the command line and presets (an
``ExperimentConfig``), and the algorithm (its ``model_kwargs``).
"""

import inspect
import sys
import tempfile
from collections import Counter
from pathlib import Path
from types import FrameType
from typing import Any

import sb3_maddpg
from sb3_maddpg.cli.main import main as command_line
from sb3_maddpg.experiments.setting import RunConfig
from sb3_maddpg.experiments.tasks import RunTask

ROOT = Path(sb3_maddpg.__path__[0])
CARRIERS = (RunConfig, RunTask)
"""What carries a run's config: the config, and its task (``run_task(config)``)."""
GENERATOR_LIKE = inspect.CO_GENERATOR | inspect.CO_COROUTINE | inspect.CO_ASYNC_GENERATOR


def main() -> None:
    entered: Counter[str] = Counter()
    run_task_calls, learning = 0, False

    def profile(frame: FrameType, event: str, arg: Any) -> None:
        nonlocal run_task_calls, learning
        if event != "call" or learning:
            return
        path = Path(frame.f_code.co_filename)
        if frame.f_code.co_name == "learn" and ROOT in path.parents:
            learning = True  # the walk ends here; the tiny run trains and finishes unrecorded
            return
        code = frame.f_code
        if ROOT not in path.parents or code.co_flags & GENERATOR_LIKE:
            return
        parameters = code.co_varnames[: code.co_argcount + code.co_kwonlyargcount]
        given = [frame.f_locals.get(name) for name in parameters]
        if parameters[:1] == ("self",) and isinstance(given[0], CARRIERS):
            return  # the config's and the task's own methods
        if not any(isinstance(value, CARRIERS) for value in given):
            return
        entered[str(path.relative_to(ROOT))] += 1
        run_task_calls += frame.f_code.co_name == "run_task"

    with tempfile.TemporaryDirectory() as results:
        sys.setprofile(profile)
        try:
            argv = ["run", "--config", "smoke", "--schemes", "full", "--seeds", "[0]", "--episodes", "20"]
            command_line([*argv, "--curve-points", "0", "--workers", "1", "--results", results, "--quiet"])
        finally:
            sys.setprofile(None)
    calls = sum(entered.values())
    print(f"{len(entered)} modules before learn, {calls} calls given a run's config; run_task {run_task_calls}x")
    for module, calls in entered.most_common():
        print(f"  {module}: {calls}")


if __name__ == "__main__":
    main()
