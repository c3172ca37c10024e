"""A sweep: every run of one or more experiments, resumable, with progress and timing."""

import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sb3_maddpg.common.progress import format_seconds, log_line
from sb3_maddpg.experiments.backends import BACKENDS, LOST_RUN, run_local, run_ray
from sb3_maddpg.experiments.config import ExperimentConfig, RunConfig
from sb3_maddpg.experiments.results import SWEEP_LOG, is_finished, lock_results, write_experiment
from sb3_maddpg.experiments.runner import never_updated_line, score_line


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
    on_ray: bool = False,
) -> SweepResult:
    """
    Run every (scheme, seed) of the experiments, skipping runs finished before (resume an
    interrupted sweep by running the same command again).

    One sweep at a time holds a results directory (:func:`~sb3_maddpg.experiments.results.lock_results`). A run
    that fails, or is lost with a worker process that dies, is reported in the result and the sweep goes on;
    Ctrl-C stops the sweep, logs how far it got and raises :class:`SweepInterrupted` (a ``KeyboardInterrupt``).
    Either way the unfinished runs are left for the next sweep.

    :param experiments: The experiments.
    :param results_dir: The results directory (one sub-directory per experiment, scheme and seed).
    :param backend: ``"local"`` (a process pool), ``"ray"``, or ``"batched"`` (run groups in this process, see
        :mod:`~sb3_maddpg.experiments.batched`; the runs it cannot train are refused before anything trains).
    :param workers: Parallel processes (local), or the CPUs of a local Ray instance (0: all).
    :param threads: Torch threads per run.
    :param ray_address: The Ray cluster's address; ``None`` starts a local instance.
    :param verbose: 0 quiet, 1 the sweep's progress (a line per finished run), 2 also each run's progress.
    :param device: The batched backend's device (``"auto"``: CUDA when there is a GPU).
    :param runs_per_process: The batched backend's most runs per group (``None``: all of a setting and scheme).
    :param on_ray: The batched backend's groups as Ray tasks, one per group (a GPU each on a CUDA device; at
        ``ray_address``, or on a local instance of ``workers`` CPUs), instead of one after another in this process.
    :return: What the sweep did.
    :raise ResultsDirectoryLocked: When another sweep is running in ``results_dir``.
    :raise BatchedRunRefused: When the batched backend cannot train a run (nothing has trained then).
    """
    if backend not in BACKENDS:
        raise ValueError(f"Unknown backend {backend!r}; use one of {BACKENDS}.")
    if on_ray and backend != "batched":
        raise ValueError(
            f"on_ray runs the batched backend's groups as Ray tasks, but the backend is {backend!r}: use "
            "backend='batched' with on_ray=True, or backend='ray' for one task per run."
        )
    results_path = Path(results_dir).resolve()
    names = [experiment.name for experiment in experiments]
    if len(set(names)) != len(names):
        raise ValueError(f"Experiment names must be unique, got {names}.")
    execution = Execution(backend, workers, threads, ray_address, device, runs_per_process, on_ray)
    if backend == "batched":
        from sb3_maddpg.experiments.batched import check_batched, plan_groups

        plan_groups([], runs_per_process)  # its argument checks, before anything runs
        check_batched(plan_sweep(experiments, results_path)[0], device=None if on_ray else device)  # Ray: its own check
    with lock_results(results_path):
        return _run_locked_sweep(experiments, results_path, execution, verbose)


@dataclass(frozen=True)
class Execution:
    """Where and how a sweep's runs execute (:func:`run_sweep`'s parameters of the same names)."""

    backend: str
    workers: int
    threads: int
    ray_address: str | None
    device: str
    runs_per_process: int | None
    on_ray: bool = False


def _run_locked_sweep(
    experiments: Sequence[ExperimentConfig], results_path: Path, execution: Execution, verbose: int
) -> SweepResult:
    """:func:`run_sweep` once it holds the results directory (same parameters)."""
    backend, workers, threads, ray_address = execution.backend, execution.workers, execution.threads, execution.ray_address
    for experiment in experiments:
        write_experiment(results_path, experiment.name, experiment.to_dict())

    todo, skipped = plan_sweep(experiments, results_path)
    result = SweepResult(total=len(todo) + skipped, skipped=skipped)
    # Ray's slots are known once it is up (workers=0 means all CPUs): run_ray reports them through on_parallel.
    parallel = workers if backend == "local" else max(1, workers) // max(1, threads)
    where = f"with {workers} worker(s) x {threads} thread(s)"
    most_runs = None
    group_lines: list[str] = []  # a setting's seeds split to fit the memory: said once the sweep log is open
    if backend == "batched":
        from sb3_maddpg.experiments.batched import memory_bound, plan_groups

        if execution.runs_per_process is None and not execution.on_ray:
            most_runs = memory_bound(execution.device, log=group_lines.append)
        groups = plan_groups(todo, execution.runs_per_process, most_runs)
        if execution.runs_per_process is not None and not execution.on_ray:
            fits = memory_bound(execution.device)
            warned: set[str] = set()
            for group in groups:  # the first (largest) group of each setting and scheme says it
                setting = f"{group[0].experiment}/{group[0].scheme}"
                if setting not in warned and len(group) > fits(group):
                    warned.add(setting)
                    group_lines.append(
                        f"{setting}: groups of {len(group)} runs (--runs-per-process) may not fit in memory: "
                        f"{fits(group)} fit by the package's estimate; lower --runs-per-process if the sweep runs out "
                        "of memory"
                    )
        parallel = max((len(group) for group in groups), default=1)  # a group's runs finish together
        where = f"in {len(groups)} run group(s) of up to {parallel} run(s) on {execution.device}"
        if execution.on_ray:
            where += ", a Ray task each"
    group_size = parallel
    progress = SweepProgress(result.total, skipped, parallel, str(results_path / SWEEP_LOG), echo=verbose >= 1)
    names = ", ".join(experiment.name for experiment in experiments)
    progress.log(f"sweep of {result.total} runs ({names}) on {backend} {where}: {skipped} finished before, {len(todo)} to run")
    for line in group_lines:
        progress.log(line)

    def on_result(config: RunConfig, summary: dict[str, Any] | None, error: str | None) -> None:
        if summary is not None:
            summary = {key: value for key, value in summary.items() if key != "files"}
            result.completed.append(summary)
            score = summary["score"]
            progress.update(
                config.run_id,
                f"done in {format_seconds(summary['wall_time_s'])} ({summary['train_steps_per_s']:,.0f} steps/s, "
                f"{score_line(score)})"
                + (
                    f"; {never_updated_line(config.model_kwargs.get('learning_starts'))}"
                    if summary.get("n_updates") == 0
                    else ""
                ),
                duration=summary["wall_time_s"],
            )
        else:
            result.failed[config.run_id] = error or ""
            progress.update(config.run_id, f"FAILED:\n{error}")

    def on_parallel(slots: int) -> None:
        progress.parallel = slots
        progress.log(f"Ray: {slots} run(s) at once ({threads} CPU(s) each)")

    def on_parallel_groups(slots: int, device: str) -> None:
        progress.parallel = slots * group_size  # a group's runs finish together
        each = "a GPU" if device == "cuda" else f"{threads} CPU(s)"
        progress.log(f"Ray: {slots} run group(s) at once ({each} each) on {device}; a group's runs are reported as it ends")

    started = time.perf_counter()
    run_verbose = 1 if verbose >= 2 else 0
    try:
        if backend == "local":
            run_local(
                todo, str(results_path), on_result, workers=workers, threads=threads, verbose=run_verbose, log=progress.log
            )
        elif backend == "batched" and execution.on_ray:
            from sb3_maddpg.experiments.batched import run_batched_ray

            run_batched_ray(
                todo,
                str(results_path),
                on_result,
                device=execution.device,
                runs_per_process=execution.runs_per_process,
                threads=threads,
                address=ray_address,
                num_cpus=workers if workers > 0 else None,
                verbose=run_verbose,
                on_parallel=on_parallel_groups,
            )
        elif backend == "batched":
            from sb3_maddpg.experiments.batched import run_batched

            run_batched(
                todo,
                str(results_path),
                on_result,
                device=execution.device,
                runs_per_process=execution.runs_per_process,
                threads=threads,
                verbose=run_verbose,
                most_runs=most_runs,
            )
        else:
            run_ray(
                todo,
                str(results_path),
                on_result,
                address=ray_address,
                threads=threads,
                num_cpus=workers if workers > 0 else None,
                verbose=run_verbose,
                on_parallel=on_parallel,
            )
    except KeyboardInterrupt:
        progress.log(
            f"sweep interrupted: {result.finished} of {result.total} run(s) finished ({len(result.completed)} by this "
            f"sweep); the runs in progress are left unfinished. Run the same command again to resume."
        )
        raise SweepInterrupted(result) from None
    result.wall_time_s = time.perf_counter() - started
    if result.completed:
        steps_per_s = sum(s["train_steps_per_s"] for s in result.completed) / len(result.completed)
        throughput = f", mean per-run throughput {steps_per_s:,.0f} env steps/s"
    else:
        throughput = ""
    progress.log(
        f"sweep finished: {len(result.completed)} run(s) in {format_seconds(result.wall_time_s)} "
        f"({result.wall_time_s:.0f} s wall){throughput}, {skipped} skipped, {len(result.failed)} failed"
        + (f" ({len(result.lost)} lost with a worker process that died)" if result.lost else "")
        + ("; run the same command again to retry the failed runs" if result.failed else "")
    )
    return result
