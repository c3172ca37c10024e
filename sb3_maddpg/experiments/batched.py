"""The batched backend: a sweep's runs trained in run groups (:class:`~sb3_maddpg.run_group.RunGroup`: the seeds of one
setting and scheme in one process, on one device), each run's directory written as the runner writes it.

A group trains to each checkpoint step; there each run is written back into its own MADDPG model, which is saved,
and at the end every run is evaluated and summarised by the runner's own functions
(:func:`~sb3_maddpg.experiments.runner.finish_run`), so that ``evaluate_team`` and ``sb3-maddpg report`` read the
results as any other. A group's training state is saved at each checkpoint and every tenth of the budget, into one
file per group (:func:`~sb3_maddpg.experiments.group_state.group_state_path`), which the same command resumes from.
Which runs train together is :mod:`~sb3_maddpg.experiments.group_plan`'s job, the group's files
:mod:`~sb3_maddpg.experiments.group_state`'s, what it writes while it trains
:mod:`~sb3_maddpg.experiments.group_recorder`'s; this module trains a group and runs a sweep's groups. The groups
train one after another in the sweep's process (:class:`GroupBackend`), or as Ray tasks, one per group
(:class:`GroupRayBackend`).
"""

import dataclasses
import functools
import os
import shutil
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import torch as th
from stable_baselines3.common.logger import configure

from sb3_maddpg.common.progress import log_line
from sb3_maddpg.experiments.backends import Execution, SweepLog, SweepPlan
from sb3_maddpg.experiments.group_plan import (
    check_batched,
    check_runs_per_process,
    memory_bound,
    plan_groups,
    resolve_device,
    too_large_groups,
)
from sb3_maddpg.experiments.group_recorder import GroupRecorder
from sb3_maddpg.experiments.group_state import (
    TRAINED_FILE,
    TrainedRun,
    group_state_path,
    load_state,
    progress_rows_until,
    read_trained,
    remove_stale_states,
    write_trained,
)
from sb3_maddpg.experiments.local_pool import OnResult
from sb3_maddpg.experiments.ray_tasks import (
    ray_device,
    ray_parallel_tasks,
    ray_session,
    ray_task_options,
    submit_ray_tasks,
)
from sb3_maddpg.experiments.results_dir import CHECKPOINT_DIR, LOG_FILE, PROGRESS_FILE, run_directory
from sb3_maddpg.experiments.runner import build_model, finish_run, start_run_directory, training_line
from sb3_maddpg.experiments.setting import RunConfig
from sb3_maddpg.experiments.tasks import run_task
from sb3_maddpg.experiments.training_resources import TrainingResources

# ----- a group, and a sweep of groups -----

COMPILE_FROM_STEPS = 1_000_000
"""Each run's budget from which a CPU group compiles its rounds by default (:func:`compile_pays`)."""


def compile_pays(total_timesteps: int, device: th.device) -> bool:
    """
    Whether a group compiles its rounds by default: where it was measured to pay. On a CPU, compiling costs 25-100 s
    per group and saves about a third of each round at the paper's sizes (``benchmarks/README.md``, 1.5x per round):
    it pays from a few hundred thousand env steps per run, so runs of :data:`COMPILE_FROM_STEPS` or more compile. On a
    GPU the compiled and captured rounds are not measured yet (``benchmarks/device_check.sh``): not by default there.

    :param total_timesteps: Each run's budget (env steps).
    :param device: The group's device.
    :return: Whether to compile.
    """
    return device.type == "cpu" and total_timesteps >= COMPILE_FROM_STEPS


def train_group(
    configs: Sequence[RunConfig],
    results_dir: str | os.PathLike[str],
    device: str = "auto",
    verbose: int = 1,
    compile: bool | None = None,
) -> list[dict[str, Any]]:
    """
    Train a group's runs together (resuming from its state file when there is one for them) and evaluate each, writing
    every run's directory as :func:`~sb3_maddpg.experiments.runner.execute_run` does. A run whose training is over (its
    :data:`~sb3_maddpg.experiments.group_state.TRAINED_FILE`: e.g. the process was killed while the group's runs were
    evaluated) is evaluated only, not trained again.

    :param configs: The runs: one setting and scheme, different seeds (see
        :func:`~sb3_maddpg.experiments.group_plan.plan_groups`).
    :param results_dir: The sweep's results directory.
    :param device: Where the group trains (``"auto"``: CUDA when there is a GPU).
    :param verbose: 1 to print the group's progress lines.
    :param compile: Compile the group's rounds (``RunGroup(..., compile=True)``); None: where it pays
        (:func:`compile_pays`).
    :return: Each run's summary, plus ``"files"`` (as ``execute_run``'s).
    """
    directories = [run_directory(results_dir, config) for config in configs]
    trained = [read_trained(directory, config, verbose >= 1) for config, directory in zip(configs, directories)]
    untrained = [config for config, record in zip(configs, trained) if record is None]
    if untrained:
        fresh = iter(_train_runs(untrained, results_dir, device, verbose, compile))
        trained = [record if record is not None else next(fresh) for record in trained]
    results = []
    for config, directory, record in zip(configs, directories, trained):
        assert record is not None
        saved, train_time, resources = record
        log_path = str(directory / LOG_FILE)

        def log(line: str, path: str = log_path) -> None:  # the run's own train.log
            log_line(line, path, verbose >= 1)

        # Its checkpoints are deleted below, after its done marker: killed before, the run is evaluated again.
        keep = dataclasses.replace(config, keep_checkpoints=True)
        started = time.perf_counter() - train_time
        results.append(finish_run(run_task(keep), directory, saved, started, train_time, log, resources))
        if not config.keep_checkpoints:
            shutil.rmtree(directory / CHECKPOINT_DIR, ignore_errors=True)
        (directory / TRAINED_FILE).unlink(missing_ok=True)
    return results


def _train_runs(
    configs: Sequence[RunConfig],
    results_dir: str | os.PathLike[str],
    device: str,
    verbose: int,
    compile: bool | None,
) -> list[TrainedRun]:
    """
    Train runs together, to their budget (see :func:`train_group`), and record each as trained
    (:func:`~sb3_maddpg.experiments.group_state.write_trained`).

    :return: Each run's checkpoints, ``(env steps, model file)`` in order, train time and resources.
    """
    from sb3_maddpg.run_group import RunGroup

    directories = [run_directory(results_dir, config) for config in configs]
    state_path = group_state_path(results_dir, configs)
    resumed = _start_or_resume(configs, directories, results_dir, state_path, verbose)
    steps = None if resumed is None else int(resumed["group"]["num_timesteps"])
    # On the CPU: they are saved and evaluated; a resumed run's progress.csv keeps its rows up to the state.
    models = [_model_logging_to(config, directory, steps) for config, directory in zip(configs, directories)]
    resolved = resolve_device(device)
    compile = compile_pays(configs[0].total_timesteps, resolved) if compile is None else compile
    if compile:
        th._dynamo.reset()  # the last group's graphs: kept, each new group would be a recompile, up to torch's limit
    group = RunGroup(models, device=resolved, compile=compile)
    if resumed is not None:
        group.load_state_dict(resumed["group"])
    recorder = GroupRecorder(configs, models, group, results_dir, state_path, echo=verbose >= 1)
    try:
        if resumed is None:
            line = f"in a run group of {len(configs)} on {resolved}"
            for config, directory in zip(configs, directories):
                log_line(f"{training_line(run_task(config))}, {line}", str(directory / LOG_FILE), False)
        recorder.start(resumed)
        group.learn(max(0, recorder.total - group.num_timesteps), callback=recorder)
        train_time = recorder.train_time
    finally:
        recorder.close()
    # Each run's record, then the state goes: a crash while the runs are evaluated evaluates them again, whatever
    # group the next attempt puts them in.
    # A group trains on the process's thread count (RunGroup.learn keeps it, as MADDPG.learn does not).
    resources = TrainingResources(resolved.type, th.get_num_threads(), runs_trained_together=len(configs))
    trained = [TrainedRun(saved, train_time, resources) for saved in recorder.saved]
    for config, directory, run in zip(configs, directories, trained):
        write_trained(directory, config, run.saved, train_time, resources)
    state_path.unlink(missing_ok=True)
    return trained


def _start_or_resume(
    configs: Sequence[RunConfig],
    directories: Sequence[Path],
    results_dir: str | os.PathLike[str],
    state_path: Path,
    verbose: int,
) -> dict[str, Any] | None:
    """
    :return: The group's saved state to resume from (:func:`~sb3_maddpg.experiments.group_state.load_state`), or
        ``None`` when there is none to use: then its runs' directories and earlier groups' states are started afresh,
        each run's new ``train.log`` saying why a state was not used (and stdout, once).
    """
    discarded: list[str] = []
    resumed = load_state(state_path, configs, results_dir, discarded.append)
    if resumed is not None:
        return resumed
    remove_stale_states(results_dir, configs)
    for config, directory in zip(configs, directories):
        start_run_directory(config, directory)
        for line in discarded:
            log_line(f"{config.run_id}: {line}", str(directory / LOG_FILE), echo=False)
    if discarded and verbose >= 1:
        print(f"{configs[0].experiment}/{configs[0].scheme}: {discarded[0]}", flush=True)
    return None


def _model_logging_to(config: RunConfig, directory: Path, steps: int | None) -> Any:
    """
    :param config: A run of the group.
    :param directory: Its directory.
    :param steps: The env steps it resumes at (``None``: a start from scratch).
    :return: Its model on the CPU, logging to its ``progress.csv`` through SB3's logger, which first writes the file's
        rows up to ``steps`` again (SB3's CSV output starts the file afresh).
    """
    rows = progress_rows_until(directory / PROGRESS_FILE, steps) if steps is not None else []  # before SB3 empties it
    model = build_model(run_task(config), device="cpu")
    model.set_logger(configure(str(directory), ["csv"]))
    for row in rows:
        for key, value in row.items():
            model.logger.record(key, value)
        model.logger.dump(int(row.get("time/total_timesteps", 0)))
    return model


def train_groups(
    groups: Sequence[Sequence[RunConfig]],
    results_dir: str,
    on_result: OnResult,
    device: str,
    threads: int,
    verbose: int,
    compile: bool | None = None,
) -> None:
    """
    Train groups one after another in this process; a group that fails fails its runs (each reported with the
    traceback) and the sweep goes on.

    :param groups: The groups (:func:`~sb3_maddpg.experiments.group_plan.plan_groups`).
    :param results_dir: The sweep's results directory.
    :param on_result: Called for each run as its group ends.
    :param device: Where the groups train.
    :param threads: Torch threads.
    :param verbose: 1 to print each group's progress lines.
    :param compile: Compile each group's rounds (None: where it pays, :func:`compile_pays`).
    """
    th.set_num_threads(threads)
    for group in groups:
        try:
            results = train_group(group, results_dir, device=device, verbose=verbose, compile=compile)
        except Exception:
            error = traceback.format_exc()
            for config in group:
                on_result(config, None, error)
        else:
            for config, result in zip(group, results):
                on_result(config, result, None)


def train_groups_on_ray(
    groups: Sequence[Sequence[RunConfig]],
    results_dir: str,
    on_result: OnResult,
    execution: Execution,
    on_parallel: Callable[[int, str], None] | None = None,
) -> None:
    """
    Train groups as Ray tasks, one task per group: on a CUDA device each asks Ray for one GPU (so each GPU of a
    cluster trains one group at a time), else for ``threads`` CPUs. Ray is reached as by
    :func:`~sb3_maddpg.experiments.ray_tasks.run_ray` (``ray_address``, or a local instance), and its tasks are
    collected by the same code: a group lost with its worker or node is run again, up to
    :data:`~sb3_maddpg.experiments.ray_tasks.RAY_MAX_RETRIES` times, and resumes from its state file when it sees
    it (the results directory shared by the nodes); a group's runs are reported when the group ends.

    :param groups: The groups (:func:`~sb3_maddpg.experiments.group_plan.plan_groups`).
    :param results_dir: The sweep's results directory (on a cluster, an absolute path on shared storage).
    :param on_result: Called for each run as its group ends.
    :param execution: Where and how (its device, threads, Ray address and CPUs, verbosity).
    :param on_parallel: Called once Ray is up with the groups that train at once and the device they train on.
    :raise BatchedRunRefused: For a CUDA device on a cluster without GPUs (its tasks would wait forever), before any
        task.
    """
    threads = execution.threads
    with ray_session(execution.ray_address, execution.ray_cpus, execution.verbose) as ray:
        resources = ray.cluster_resources()
        device = ray_device(execution.device, resources.get("GPU", 0))
        if on_parallel is not None:
            on_parallel(ray_parallel_tasks(resources, ray_task_options(threads, device)), device)
        work = functools.partial(_train_group_task, compile=execution.compile)
        submit_ray_tasks(ray, groups, results_dir, work, device, threads, execution.verbose, on_result)


def _train_group_task(
    configs: Sequence[RunConfig], results_dir: str, device: str, threads: int, verbose: int, compile: bool | None = None
) -> list[dict[str, Any]]:
    """A Ray task's work (:data:`~sb3_maddpg.experiments.ray_tasks.TaskWork`, with ``compile`` bound): train one group."""
    return train_group(configs, results_dir, device=device, verbose=verbose, compile=compile)


def _compiled_note(compile: bool | None, groups: Sequence[Sequence[RunConfig]], device: str | None) -> str:
    """
    :param compile: ``--compile`` (None: where it pays, :func:`compile_pays`).
    :param groups: The planned groups.
    :param device: Their device (None under Ray: the workers' is not known here).
    :return: What the sweep log says of compiling (``""``: nothing compiles, or it is not known).
    """
    if compile is not None or device is None:
        return ", compiled" if compile else ""
    budgets = {config.total_timesteps for group in groups for config in group}
    paying = [steps for steps in budgets if compile_pays(steps, resolve_device(device))]
    if not paying:
        return ""
    return ", compiled" if len(paying) == len(budgets) else f", compiled where runs have {COMPILE_FROM_STEPS:,} steps or more"


class GroupBackend:
    """
    Runs in run groups, one group after another in this process (``--backend batched``).

    :param execution: Where and how the groups train.
    """

    name = "batched"
    on_ray = False

    def __init__(self, execution: Execution) -> None:
        self.execution = execution

    def check(self, runs: Sequence[RunConfig]) -> None:
        """
        :param runs: The runs to do.
        :raise BatchedRunRefused: For the device or the first run a group cannot train
            (:func:`~sb3_maddpg.experiments.group_plan.check_batched`).
        """
        check_runs_per_process(self.execution.runs_per_process)
        check_batched(runs, device=None if self.on_ray else self.execution.device)  # Ray: its tasks' machines

    def plan(self, runs: Sequence[RunConfig], results_dir: str) -> SweepPlan:
        """
        :param runs: The runs to do (checked).
        :param results_dir: The sweep's results directory.
        :return: The groups: as many runs of a setting and scheme as fit in the device's memory (``--runs-per-process``
            sets another size, which is warned of when it may not fit).
        """
        notes: list[str] = []  # a setting's seeds split to fit the memory: said once the sweep log is open
        device, runs_per_process = self.execution.device, self.execution.runs_per_process
        fits = memory_bound(device, log=notes.append if runs_per_process is None else None)
        groups = plan_groups(runs, runs_per_process, fits)
        if runs_per_process is not None:
            notes += too_large_groups(groups, fits)
        return self._plan(groups, results_dir, notes)

    def _plan(self, groups: list[list[RunConfig]], results_dir: str, notes: list[str]) -> SweepPlan:
        parallel = max((len(group) for group in groups), default=1)  # a group's runs finish together
        where = f"in {len(groups)} run group(s) of up to {parallel} run(s) on {self.execution.device}"
        where += _compiled_note(self.execution.compile, groups, None if self.on_ray else self.execution.device)
        return SweepPlan(results_dir, groups, parallel, where + (", a Ray task each" if self.on_ray else ""), notes)

    def run(self, plan: SweepPlan, on_result: OnResult, progress: SweepLog) -> None:
        """See :meth:`~sb3_maddpg.experiments.backends.Backend.run`."""
        execution = self.execution
        train_groups(
            plan.units,
            plan.results_dir,
            on_result,
            execution.device,
            execution.threads,
            execution.verbose,
            execution.compile,
        )


class GroupRayBackend(GroupBackend):
    """
    Runs in run groups, each a Ray task (``--backend batched-ray``).

    :param execution: Where and how the groups train.
    """

    name = "batched"  # the sweep log says "a Ray task each"
    on_ray = True

    def plan(self, runs: Sequence[RunConfig], results_dir: str) -> SweepPlan:
        """
        :param runs: The runs to do (checked).
        :param results_dir: The sweep's results directory.
        :return: The groups, all seeds of a setting and scheme (or ``--runs-per-process``) each: the memory of the
            tasks' machines is not known here.
        """
        return self._plan(plan_groups(runs, self.execution.runs_per_process), results_dir, [])

    def run(self, plan: SweepPlan, on_result: OnResult, progress: SweepLog) -> None:
        """See :meth:`~sb3_maddpg.experiments.backends.Backend.run`."""
        group_size = plan.parallel
        each = f"{self.execution.threads} CPU(s)"

        def on_parallel(slots: int, device: str) -> None:
            progress.parallel = slots * group_size  # a group's runs finish together
            progress.log(
                f"Ray: {slots} run group(s) at once ({'a GPU' if device == 'cuda' else each} each) on {device}; a "
                "group's runs are reported as it ends"
            )

        train_groups_on_ray(plan.units, plan.results_dir, on_result, self.execution, on_parallel)
