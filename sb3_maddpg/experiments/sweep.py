"""A sweep: every run of one or more experiments, resumable, with progress and timing."""

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sb3_maddpg.common.progress import format_seconds, log_line
from sb3_maddpg.experiments.backends import Backend, Execution, SweepPlan, make_backend
from sb3_maddpg.experiments.local_pool import LOST_RUN, OnResult
from sb3_maddpg.experiments.references import write_references
from sb3_maddpg.experiments.results_dir import SWEEP_LOG, is_finished, lock_results, write_experiment
from sb3_maddpg.experiments.runner import never_updated_line, score_line
from sb3_maddpg.experiments.setting import ExperimentConfig, RunConfig


@dataclass
class SweepResult:
    """
    What a sweep did.

    :param total: Runs in the sweep.
    :param skipped: Runs already finished before it started (resumed sweeps skip them).
    :param completed: Runs finished by this sweep (their summaries).
    :param failed: Runs that raised, with their tracebacks, and runs lost with a worker process that died.
    :param wall_time_s: The sweep's wall time.
    """

    total: int
    skipped: int
    completed: list[dict[str, Any]] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    wall_time_s: float = 0.0

    @property
    def ok(self) -> bool:
        """Whether every run is finished."""
        return not self.failed and self.skipped + len(self.completed) == self.total

    @property
    def lost(self) -> list[str]:
        """The failed runs that were lost with a worker process that died (killed, out of memory)."""
        return [run_id for run_id, error in self.failed.items() if error.startswith(LOST_RUN)]

    @property
    def finished(self) -> int:
        """Runs finished, before this sweep or by it."""
        return self.skipped + len(self.completed)


class SweepInterrupted(KeyboardInterrupt):
    """
    Ctrl-C stopped a sweep (a ``KeyboardInterrupt``, logged already with how far the sweep got).

    :param result: What the sweep did until then.
    """

    def __init__(self, result: SweepResult) -> None:
        super().__init__(f"sweep interrupted after {result.finished} of {result.total} run(s)")
        self.result = result


class SweepProgress:
    """
    Print and log one line per finished run: runs done of total, elapsed time and time left.

    :param total: Runs in the sweep.
    :param skipped: Runs finished before it started.
    :param parallel: Runs executing at once (for the time-left estimate).
    :param log_path: A text file the lines are appended to, or ``None``.
    :param echo: Print the lines too.
    """

    def __init__(self, total: int, skipped: int, parallel: int, log_path: str | None = None, echo: bool = True) -> None:
        self.total = total
        self.done = skipped
        self.durations: list[float] = []
        self.parallel = max(1, parallel)
        self.log_path = log_path
        self.echo = echo
        self.start = time.perf_counter()

    def log(self, line: str) -> None:
        """
        :param line: A line for stdout and the sweep log.
        """
        log_line(line, self.log_path, self.echo)

    def update(self, run_id: str, message: str, duration: float | None = None) -> None:
        """
        :param run_id: The run that ended.
        :param message: What happened to it.
        :param duration: The run's wall time, for the time-left estimate (``None`` for a failed run).
        """
        self.done += 1
        if duration is not None:
            self.durations.append(duration)
        elapsed = time.perf_counter() - self.start
        remaining = self.total - self.done
        if self.durations and remaining:
            # The runs left (some already started) share the parallel slots: mean run time x runs left / slots.
            mean_duration = sum(self.durations) / len(self.durations)
            left = f"left ~{format_seconds(mean_duration * remaining / min(self.parallel, remaining))}"
        else:
            left = "left ~0m00s" if not remaining else "left: unknown"
        self.log(f"[{self.done}/{self.total}] {run_id} {message} | elapsed {format_seconds(elapsed)}, {left}")


def plan_sweep(experiments: Sequence[ExperimentConfig], results_dir: str | os.PathLike[str]) -> tuple[list[RunConfig], int]:
    """
    :param experiments: The experiments of the sweep.
    :param results_dir: The results directory.
    :return: The runs still to do, and how many are finished already.
    """
    todo, finished = [], 0
    for experiment in experiments:
        for config in experiment.runs():
            if is_finished(results_dir, config):
                finished += 1
            else:
                todo.append(config)
    return todo, finished


def run_sweep(
    experiments: Sequence[ExperimentConfig],
    results_dir: str | os.PathLike[str],
    backend: str = "local",
    workers: int = 1,
    threads: int = 1,
    ray_address: str | None = None,
    verbose: int = 2,
    device: str = "auto",
    runs_per_process: int | None = None,
    snapshots: bool = True,
    compile: bool | None = None,
) -> SweepResult:
    """
    Run every (scheme, seed) of the experiments, skipping runs finished before (resume an
    interrupted sweep by running the same command again). An experiment's reference policies are evaluated first, on
    each seed it does not hold yet (:func:`~sb3_maddpg.experiments.references.write_references`).

    One sweep at a time holds a results directory (:func:`~sb3_maddpg.experiments.results_dir.lock_results`). A run
    that fails, or is lost with a worker process that dies, is reported in the result and the sweep goes on;
    Ctrl-C stops the sweep, logs how far it got and raises :class:`SweepInterrupted` (a ``KeyboardInterrupt``).
    Either way the unfinished runs are left for the next sweep. The sweep plans once (which runs are left, then the
    backend's units of them) and hands the plan to its backend (:class:`~sb3_maddpg.experiments.backends.Backend`).

    :param experiments: The experiments.
    :param results_dir: The results directory (one sub-directory per experiment, scheme and seed).
    :param backend: A name in :data:`~sb3_maddpg.experiments.backends.BACKENDS`: ``"local"`` (a process pool),
        ``"ray"``, ``"batched"`` (run groups in this process, see :mod:`~sb3_maddpg.experiments.batched`; the runs it
        cannot train are refused before anything trains) or ``"batched-ray"`` (run groups as Ray tasks).
    :param workers: Parallel processes (local), or the CPUs of a local Ray instance (0: all).
    :param threads: Torch threads per run.
    :param ray_address: The Ray cluster's address; ``None`` starts a local instance.
    :param verbose: 0 quiet, 1 the sweep's progress (a line per finished run), 2 also each run's progress.
    :param device: Where the runs train: each run alone (local, Ray) or each run group (batched), ``"cpu"``,
        ``"cuda"`` or ``"auto"`` (CUDA when there is a GPU); a ``device`` in an experiment's ``model_kwargs`` comes first
        for its runs alone.
    :param runs_per_process: The batched backends' most runs per group (``None``: all of a setting and scheme).
    :param snapshots: Runs alone (local, Ray) save a snapshot at each tenth of their budget, so that a killed run goes
        on from its last one (:mod:`~sb3_maddpg.experiments.run_snapshot`; about two replay buffers of disk per run in
        progress, e.g. 2.7 GB at N=5 with 1M-transition buffers).
    :param compile: The batched backends' run groups compile their rounds (``RunGroup(..., compile=True)``; the
        compile time is said in each group's progress lines); None: where it was measured to pay (CPU groups of runs
        of 1M env steps or more, :func:`~sb3_maddpg.experiments.batched.compile_pays`).
    :return: What the sweep did.
    :raise ResultsDirectoryLocked: When another sweep is running in ``results_dir``.
    :raise BatchedRunRefused: When the batched backend cannot train a run (nothing has trained then).
    :raise ReferencePolicyError: When an experiment's reference policy cannot act in its task (nothing has trained).
    """
    results_path = Path(results_dir).resolve()
    names = [experiment.name for experiment in experiments]
    if len(set(names)) != len(names):
        raise ValueError(f"Experiment names must be unique, got {names}.")
    run_verbose = 1 if verbose >= 2 else 0
    execution = Execution(backend, workers, threads, ray_address, device, runs_per_process, run_verbose, snapshots, compile)
    chosen = make_backend(execution)
    with lock_results(results_path):
        todo, skipped = plan_sweep(experiments, results_path)
        chosen.check(todo)  # before anything is written
        for experiment in experiments:
            write_experiment(results_path, experiment.name, experiment.to_dict())
        plan = chosen.plan(todo, str(results_path))
        progress = SweepProgress(len(todo) + skipped, skipped, plan.parallel, str(results_path / SWEEP_LOG), verbose >= 1)
        for line in (
            f"sweep of {progress.total} runs ({', '.join(names)}) on {chosen.name} {plan.where}: {skipped} finished "
            f"before, {len(todo)} to run",
            *plan.notes,
        ):
            progress.log(line)
        for experiment in experiments:  # once per setting, on its runs' evaluation episodes, before any run
            write_references(experiment, results_path, progress.log)
        return execute_plan(chosen, plan, progress)


def execute_plan(backend: Backend, plan: SweepPlan, progress: SweepProgress) -> SweepResult:
    """
    Run a sweep's plan on its backend, each run's end logged, and the sweep's end.

    :param backend: The backend that made the plan.
    :param plan: The runs to do.
    :param progress: The sweep's log (its total and the runs finished before).
    :return: What the sweep did.
    :raise SweepInterrupted: On Ctrl-C.
    """
    result = SweepResult(total=progress.total, skipped=progress.done)
    started = time.perf_counter()
    try:
        backend.run(plan, result_logger(result, progress), progress)
    except KeyboardInterrupt:
        progress.log(
            f"sweep interrupted: {result.finished} of {result.total} run(s) finished ({len(result.completed)} by this "
            f"sweep); the runs in progress are left unfinished. Run the same command again to resume."
        )
        raise SweepInterrupted(result) from None
    result.wall_time_s = time.perf_counter() - started
    progress.log(finished_line(result))
    return result


def result_logger(result: SweepResult, progress: SweepProgress) -> OnResult:
    """
    :param result: What the sweep did, so far.
    :param progress: The sweep's log.
    :return: The backend's ``on_result``: each run's end added to ``result`` and logged.
    """

    def on_result(config: RunConfig, summary: dict[str, Any] | None, error: str | None) -> None:
        if summary is None:
            result.failed[config.run_id] = error or ""
            progress.update(config.run_id, f"FAILED:\n{error}")
            return
        summary = {key: value for key, value in summary.items() if key != "files"}
        result.completed.append(summary)
        never_updated = summary.get("n_updates") == 0
        progress.update(
            config.run_id,
            f"done in {format_seconds(summary['wall_time_s'])} ({summary['train_steps_per_s']:,.0f} steps/s, "
            f"{score_line(summary['score'])})"
            + (f"; {never_updated_line(config.model_kwargs.get('learning_starts'))}" if never_updated else ""),
            duration=summary["wall_time_s"],
        )

    return on_result


def finished_line(result: SweepResult) -> str:
    """:return: The sweep log's last line: what the sweep did, in how long."""
    throughput = ""
    if result.completed:
        steps_per_s = sum(s["train_steps_per_s"] for s in result.completed) / len(result.completed)
        throughput = f", mean per-run throughput {steps_per_s:,.0f} env steps/s"
    return (
        f"sweep finished: {len(result.completed)} run(s) in {format_seconds(result.wall_time_s)} "
        f"({result.wall_time_s:.0f} s wall){throughput}, {result.skipped} skipped, {len(result.failed)} failed"
        + (f" ({len(result.lost)} lost with a worker process that died)" if result.lost else "")
        + ("; run the same command again to retry the failed runs" if result.failed else "")
    )


__all__ = [
    "SweepInterrupted",
    "SweepProgress",
    "SweepResult",
    "execute_plan",
    "plan_sweep",
    "run_sweep",
]
