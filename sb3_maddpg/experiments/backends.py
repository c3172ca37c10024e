"""Where runs execute: in this process, in a local process pool, or on a Ray cluster; one :class:`Backend` interface
for every way a sweep runs its runs, chosen by name from :data:`BACKENDS`.

Faults: a worker that dies (SIGKILL, the out-of-memory killer) loses only the runs it and the workers beside
it were running; they are reported as failed (local pool) or retried (Ray) and the sweep goes on. A sweep that
is killed takes its pool workers with it; Ctrl-C stops the workers and leaves the runs in progress unfinished,
so that the same command runs them again.
"""

import importlib
import multiprocessing
import os
import signal
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ALL_COMPLETED, FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass, field
from multiprocessing import get_context
from typing import Any, Protocol

from sb3_maddpg.common.install_hint import extra_install_command
from sb3_maddpg.experiments.config import RunConfig
from sb3_maddpg.experiments.results import write_result_files
from sb3_maddpg.experiments.runner import execute_run

OnResult = Callable[[RunConfig, dict[str, Any] | None, str | None], None]
"""Called as each run ends: ``(config, result, None)`` on success, ``(config, None, traceback)`` on failure."""


@dataclass(frozen=True)
class Execution:
    """
    Where and how a sweep's runs execute (:func:`~sb3_maddpg.experiments.sweep.run_sweep`'s parameters of the same
    names).

    :param backend: The backend's name in :data:`BACKENDS`.
    :param workers: Parallel processes (local), or the CPUs of a local Ray instance (0: all).
    :param threads: Torch threads per run (or per run group).
    :param ray_address: The Ray cluster's address; ``None`` starts a local instance.
    :param device: The run groups' device (``"auto"``: CUDA when there is a GPU).
    :param runs_per_process: The most runs per group (``None``: all of a setting and scheme, or as many as fit).
    :param verbose: 1 to print each run's (or group's) progress.
    """

    backend: str = "local"
    workers: int = 1
    threads: int = 1
    ray_address: str | None = None
    device: str = "auto"
    runs_per_process: int | None = None
    verbose: int = 1

    @property
    def ray_cpus(self) -> int | None:
        """The CPUs of a local Ray instance (``None``: all of this machine's)."""
        return self.workers if self.workers > 0 else None


@dataclass
class SweepPlan:
    """
    What a sweep hands its backend, planned once: the runs to do in the units that execute together.

    :param results_dir: The sweep's results directory.
    :param units: Each unit's runs: a run alone, or a run group (whose runs end together).
    :param parallel: Runs executing at once (for the time-left estimate; a Ray backend sets it again once Ray is up).
    :param where: How the sweep log says where the runs execute (e.g. ``"with 2 worker(s) x 1 thread(s)"``).
    :param notes: Lines for the sweep log, said once it is open (e.g. a setting's seeds split to fit the memory).
    """

    results_dir: str
    units: list[list[RunConfig]]
    parallel: int
    where: str
    notes: list[str] = field(default_factory=list)

    @property
    def runs(self) -> list[RunConfig]:
        """Every run to do, in the sweep's order."""
        return [config for unit in self.units for config in unit]


class SweepLog(Protocol):
    """What a backend tells the sweep as it runs (:class:`~sb3_maddpg.experiments.sweep.SweepProgress`)."""

    parallel: int

    def log(self, line: str) -> None:
        """:param line: A line for stdout and the sweep log."""


class Backend(Protocol):
    """
    One way to execute a sweep's runs. The sweep calls, in order: :meth:`check` (before anything is written),
    :meth:`plan` (once), then :meth:`run`.
    """

    name: str
    """Its name in :data:`BACKENDS` and in the sweep log."""

    def check(self, runs: Sequence[RunConfig]) -> None:
        """
        :param runs: The runs to do.
        :raise ValueError: For runs or settings this backend cannot execute (before anything is written).
        """

    def plan(self, runs: Sequence[RunConfig], results_dir: str) -> SweepPlan:
        """
        :param runs: The runs to do (checked).
        :param results_dir: The sweep's results directory.
        :return: The plan to :meth:`run`.
        """

    def run(self, plan: SweepPlan, on_result: OnResult, progress: SweepLog) -> None:
        """
        Execute the plan's runs, each reported as it ends.

        :param plan: What :meth:`plan` returned.
        :param on_result: Called as each run ends.
        :param progress: The sweep's log (a line when a worker dies, how many runs execute at once).
        """


@dataclass(frozen=True)
class BackendEntry:
    """
    A backend in :data:`BACKENDS`.

    :param target: ``"module:Class"``, imported when the backend is made (a class taking an :class:`Execution`).
    :param help: What it is, for ``sb3-maddpg run --help``.
    """

    target: str
    help: str


BACKENDS: dict[str, BackendEntry] = {
    "local": BackendEntry("sb3_maddpg.experiments.backends:LocalBackend", "a local process pool (--workers)"),
    "ray": BackendEntry("sb3_maddpg.experiments.backends:RayBackend", "one Ray task per run"),
    "batched": BackendEntry(
        "sb3_maddpg.experiments.batched:GroupBackend",
        "a setting and scheme's seeds trained together in this process (run groups, fixed schemes on the batched "
        "simple_spread env; see --device, --runs-per-process)",
    ),
    "batched-ray": BackendEntry(
        "sb3_maddpg.experiments.batched:GroupRayBackend",
        "run groups as Ray tasks, one each (a GPU each with --device cuda, else --threads CPUs); also --backend batched --ray",
    ),
}
"""The backends by name: the one registry that sweeps and ``sb3-maddpg run --backend`` read."""


def make_backend(execution: Execution) -> Backend:
    """
    :param execution: Where and how the runs execute; its ``backend`` names one of :data:`BACKENDS`.
    :return: That backend.
    :raise ValueError: For a name not in :data:`BACKENDS`.
    """
    if execution.backend not in BACKENDS:
        raise ValueError(f"Unknown backend {execution.backend!r}; use one of {tuple(BACKENDS)}.")
    module, _, name = BACKENDS[execution.backend].target.partition(":")
    backend: Backend = getattr(importlib.import_module(module), name)(execution)
    return backend


class RunsBackend:
    """
    What the backends that execute each run alone share: any run is executed (by the runner), one unit per run.

    :param execution: Where and how the runs execute.
    """

    name = "runs"

    def __init__(self, execution: Execution) -> None:
        self.execution = execution

    def check(self, runs: Sequence[RunConfig]) -> None:
        """:param runs: The runs to do (the runner executes any)."""


class LocalBackend(RunsBackend):
    """
    Runs in this process (one worker) or a local process pool (:func:`run_local`).

    :param execution: Where and how the runs execute.
    """

    name = "local"

    def plan(self, runs: Sequence[RunConfig], results_dir: str) -> SweepPlan:
        """
        :param runs: The runs to do.
        :param results_dir: The sweep's results directory.
        :return: One unit per run, ``workers`` at once.
        """
        workers, threads = self.execution.workers, self.execution.threads
        return SweepPlan(results_dir, [[run] for run in runs], workers, f"with {workers} worker(s) x {threads} thread(s)")

    def run(self, plan: SweepPlan, on_result: OnResult, progress: SweepLog) -> None:
        """See :meth:`Backend.run`."""
        execution = self.execution
        run_local(
            plan.runs,
            plan.results_dir,
            on_result,
            workers=execution.workers,
            threads=execution.threads,
            verbose=execution.verbose,
            log=progress.log,
        )


class RayBackend(RunsBackend):
    """
    Runs as Ray tasks, one per run (:func:`run_ray`).

    :param execution: Where and how the runs execute.
    """

    name = "ray"

    def plan(self, runs: Sequence[RunConfig], results_dir: str) -> SweepPlan:
        """
        :param runs: The runs to do.
        :param results_dir: The sweep's results directory.
        :return: One unit per run; the runs at once are known once Ray is up (``workers=0``: all CPUs).
        """
        workers, threads = self.execution.workers, self.execution.threads
        parallel = max(1, workers) // max(1, threads)
        return SweepPlan(results_dir, [[run] for run in runs], parallel, f"with {workers} worker(s) x {threads} thread(s)")

    def run(self, plan: SweepPlan, on_result: OnResult, progress: SweepLog) -> None:
        """See :meth:`Backend.run`."""
        execution = self.execution

        def on_parallel(slots: int) -> None:
            progress.parallel = slots
            progress.log(f"Ray: {slots} run(s) at once ({execution.threads} CPU(s) each)")

        run_ray(
            plan.runs,
            plan.results_dir,
            on_result,
            address=execution.ray_address,
            threads=execution.threads,
            num_cpus=execution.ray_cpus,
            verbose=execution.verbose,
            on_parallel=on_parallel,
        )


LOST_RUN = "lost: the worker process running it died"
RAY_MAX_RETRIES = 3
"""Ray runs a task again this many times when its worker process or node dies (Ray's default, stated)."""
RAY_MAX_RETRIES_TEXT = f"after Ray's retries (max_retries={RAY_MAX_RETRIES})"
"""How the error of a run lost with its worker process begins."""
LOST_RUN_ERROR = (
    f"{LOST_RUN} (killed by a signal: the out-of-memory killer or a kill -9?); a local process pool also stops "
    "the runs beside it. Nothing of it counts as finished: run the same command again to run it."
)
RAY_LOST_RUN_ERROR = (
    f"{LOST_RUN} on Ray (its worker or node died, or Ray's memory monitor killed it) {RAY_MAX_RETRIES_TEXT}. Nothing "
    "of it counts as finished: run the same command again to run it (with fewer runs per node if memory ran out)."
)


def set_worker_threads(threads: int) -> None:
    """
    Limit a worker's intra-op threads (torch and the BLAS libraries) so parallel workers don't fight for cores.

    :param threads: Threads per worker.
    """
    for variable in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[variable] = str(threads)
    import torch as th

    th.set_num_threads(threads)


def _init_pool_worker(threads: int | None, parent_pid: int) -> None:
    """
    Set up a local pool's worker process: its threads, Ctrl-C left to the pool's owner, and an exit with it.

    :param threads: Torch threads, or ``None`` to leave them to the work it runs.
    :param parent_pid: The process that owns the pool (a sweep, a tuning study).
    """
    # Ctrl-C in a terminal reaches the whole process group: the owner handles it (and stops the workers).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # A worker outliving a killed owner would go on with work that the next command redoes (a run into a directory
    # that the next sweep is redoing, a trial that the resumed study retries) and hold a core meanwhile.
    threading.Thread(target=_exit_with_parent, args=(parent_pid,), daemon=True, name="exit-with-owner").start()
    if threads is not None:
        set_worker_threads(threads)


@contextmanager
def worker_pool(workers: int, threads: int | None) -> Iterator[ProcessPoolExecutor]:
    """
    A local process pool (``spawn`` start method, so that no torch or env state is shared with this process) whose
    workers go with this process: they ignore Ctrl-C, which this process handles; leaving the block by an exception
    (Ctrl-C's ``KeyboardInterrupt``) stops them at once; and a worker whose owner is killed (SIGTERM, SIGKILL) exits.

    :param workers: Worker processes.
    :param threads: Torch threads per worker, or ``None`` to leave them to the work it runs.
    :return: The pool, shut down on leaving.
    """
    children_before = set(multiprocessing.active_children())
    pool = ProcessPoolExecutor(
        max_workers=workers, mp_context=get_context("spawn"), initializer=_init_pool_worker, initargs=(threads, os.getpid())
    )
    try:
        yield pool
    except BaseException:  # Ctrl-C (KeyboardInterrupt): the workers ignore it, stop them now
        for process in set(multiprocessing.active_children()) - children_before:
            process.terminate()
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _exit_with_parent(parent_pid: int, interval_s: float = 0.5) -> None:
    while os.getppid() == parent_pid:
        time.sleep(interval_s)
    os._exit(1)


def _execute(config: RunConfig, results_dir: str, threads: int, verbose: int) -> dict[str, Any]:
    return execute_run(config, results_dir, threads=threads, verbose=verbose)


def run_local(
    configs: Sequence[RunConfig],
    results_dir: str,
    on_result: OnResult,
    workers: int = 1,
    threads: int = 1,
    verbose: int = 1,
    log: Callable[[str], None] = print,
) -> None:
    """
    Run on this machine: in this process with one worker, else in a pool of ``workers`` processes
    (``spawn`` start method, so that no torch or env state is shared with the parent).

    A worker process that dies breaks the pool: the runs in progress are reported lost (an error starting with
    :data:`LOST_RUN`) and the runs not started go on in a new pool. Ctrl-C stops the workers at once.

    :param configs: The runs.
    :param results_dir: The sweep's results directory.
    :param on_result: Called as each run ends.
    :param workers: Number of parallel processes.
    :param threads: Torch threads per process.
    :param verbose: 1 to print each run's progress.
    :param log: Where a line saying that a worker died goes.
    """
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}.")
    if workers == 1:
        for config in configs:
            try:
                result = _execute(config, results_dir, threads, verbose)
            except Exception:
                on_result(config, None, traceback.format_exc())
            else:
                on_result(config, result, None)
        return
    queue = deque(configs)
    while queue:
        lost = _run_pool(queue, results_dir, on_result, workers, threads, verbose)
        if lost:
            log(
                f"a worker process died: {len(lost)} run(s) in progress lost ({', '.join(c.run_id for c in lost)}); "
                f"{len(queue)} run(s) not started go on in new worker processes"
            )
        for config in lost:
            on_result(config, None, LOST_RUN_ERROR)


def _run_pool(
    queue: deque[RunConfig], results_dir: str, on_result: OnResult, workers: int, threads: int, verbose: int
) -> list[RunConfig]:
    """
    Run the queue's runs in a new process pool, at most ``workers`` submitted at once (so that every submitted
    run is one in progress), until the queue is empty or a worker process dies.

    :return: The runs in progress when a worker died (the queue keeps the runs not started), or none.
    """
    running: dict[Future[dict[str, Any]], RunConfig] = {}
    with worker_pool(workers, threads) as pool:
        while queue or running:
            pool_broke = False
            try:
                while queue and len(running) < workers:
                    running[pool.submit(_execute, queue[0], results_dir, threads, verbose)] = queue[0]
                    queue.popleft()
            except BrokenProcessPool:  # it broke between two runs
                pool_broke = True
            finished, _ = wait(running, return_when=ALL_COMPLETED if pool_broke else FIRST_COMPLETED)
            if not pool_broke and any(isinstance(future.exception(), BrokenProcessPool) for future in finished):
                pool_broke = True
                finished, _ = wait(running)  # a broken pool fails every run in progress, all at once
            lost = []
            for future in finished:
                config = running.pop(future)
                error = future.exception()
                if isinstance(error, BrokenProcessPool):
                    lost.append(config)
                elif error is None:
                    on_result(config, future.result(), None)
                else:
                    on_result(config, None, "".join(traceback.format_exception(error)))
            if pool_broke:
                return lost
    return []


def run_ray(
    configs: Sequence[RunConfig],
    results_dir: str,
    on_result: OnResult,
    address: str | None = None,
    threads: int = 1,
    num_cpus: int | None = None,
    verbose: int = 1,
    on_parallel: Callable[[int], None] | None = None,
) -> None:
    """
    Run as Ray tasks, one CPU slot per ``threads``: on the cluster at ``address`` (e.g. ``"auto"`` or
    ``"ray://head:10001"``), or on a local Ray instance started here when ``address`` is ``None``.

    Every node needs this package installed. Each task writes its run directory on its own node and
    returns the small result files, which are written here too, so a cluster needs no shared
    filesystem (model checkpoints stay on the nodes). A task whose worker process or node dies is run again
    (up to :data:`RAY_MAX_RETRIES` times) from scratch; Ctrl-C cancels the tasks.

    :param configs: The runs.
    :param results_dir: The sweep's results directory (absolute paths are safest on a cluster).
    :param on_result: Called as each run ends.
    :param address: The Ray cluster's address, or ``None`` to start a local instance.
    :param threads: Torch threads (and Ray CPUs) per run.
    :param num_cpus: CPUs of a local instance (``None``: all of this machine's).
    :param verbose: 1 to print each run's progress (Ray forwards the workers' output).
    :param on_parallel: Called once Ray is up with the number of runs that execute at once (the cluster's CPUs
        // ``threads``), e.g. for a time-left estimate.
    """
    with ray_session(address, num_cpus, verbose) as ray:
        if on_parallel is not None:
            on_parallel(ray_parallel_runs(ray.cluster_resources(), threads))
        submit_ray_tasks(ray, [[config] for config in configs], results_dir, execute_runs, "cpu", threads, verbose, on_result)


@contextmanager
def ray_session(address: str | None, num_cpus: int | None, verbose: int) -> Iterator[Any]:
    """
    Ray, connected for a sweep: to the cluster at ``address``, or to a local instance started here (and shut down
    on leaving) when ``address`` is ``None``; a Ray already initialised in this process is used as it is.

    :param address: The Ray cluster's address, or ``None`` to start a local instance.
    :param num_cpus: CPUs of a local instance (``None``: all of this machine's).
    :param verbose: 1 to forward the workers' output.
    :return: The ``ray`` module.
    """
    try:
        import ray
    except ImportError as error:  # ModuleNotFoundError: an ImportError the commands report in one line
        raise ModuleNotFoundError(
            f"The Ray backend needs Ray, which is not installed: {extra_install_command('distributed')} (or pip install "
            "'ray[default]')."
        ) from error

    started_here = not ray.is_initialized()
    if started_here:
        # Ray starts its workers at niceness 15 by default: on a machine that also runs anything else, a
        # local instance's workers then crawl (20x slower measured on a busy 2-core machine). A local
        # instance exists for these runs, so its workers get normal priority; a cluster keeps its own settings.
        local = address is None and not os.environ.get("RAY_ADDRESS")  # RAY_ADDRESS: Ray connects to that cluster
        ray.init(
            address=address,
            num_cpus=num_cpus if local else None,
            include_dashboard=False,
            log_to_driver=verbose >= 1,
            configure_logging=False,
            _system_config={"worker_niceness": 0} if local else None,
        )
    try:
        yield ray
    finally:
        if started_here:
            ray.shutdown()


def ray_task_options(threads: int, device: str = "cpu") -> dict[str, Any]:
    """
    :param threads: Torch threads of the task (its Ray CPUs).
    :param device: Where the task trains: a CUDA device asks Ray for one GPU as well, so that each GPU of a
        cluster runs one such task at a time.
    :return: The options of ``ray.remote`` for one task (resources, and :data:`RAY_MAX_RETRIES` retries).
    """
    options: dict[str, Any] = {"num_cpus": threads, "max_retries": RAY_MAX_RETRIES}
    if device.split(":")[0] == "cuda":
        options["num_gpus"] = 1
    return options


def collect_ray_tasks(ray: Any, tasks: dict[Any, list[RunConfig]], results_dir: str, on_result: OnResult) -> None:
    """
    Wait for submitted Ray tasks, each returning the results of its runs (as many as its configs, in their order),
    and report every run as its task ends: its result files written here (for a cluster without shared storage),
    then ``on_result``. A task lost with its worker or node after Ray's retries fails its runs with
    :data:`RAY_LOST_RUN_ERROR`, one that raised with its traceback; Ctrl-C cancels the tasks left.

    :param ray: The ``ray`` module (connected, see :func:`ray_session`).
    :param tasks: Each task's object reference and its runs.
    :param results_dir: The sweep's results directory here.
    :param on_result: Called for each run.
    """
    pending = list(tasks)
    try:
        while pending:
            finished, pending = ray.wait(pending, num_returns=1)
            for ref in finished:
                configs = tasks[ref]
                try:
                    results = ray.get(ref)
                except (ray.exceptions.WorkerCrashedError, ray.exceptions.NodeDiedError, ray.exceptions.OutOfMemoryError):
                    error = f"{RAY_LOST_RUN_ERROR}\n{traceback.format_exc()}"
                    for config in configs:
                        on_result(config, None, error)
                except Exception:
                    error = traceback.format_exc()
                    for config in configs:
                        on_result(config, None, error)
                else:
                    for config, result in zip(configs, results, strict=True):
                        write_result_files(results_dir, result)
                        on_result(config, result, None)
    except KeyboardInterrupt:
        for ref in pending:  # on a cluster, tasks would go on without the sweep
            ray.cancel(ref, force=True)
        raise


def ray_parallel_tasks(resources: dict[str, float], options: dict[str, Any]) -> int:
    """
    :param resources: A Ray cluster's resources (``ray.cluster_resources()``).
    :param options: One task's options (:func:`ray_task_options`).
    :return: The tasks that execute at once: the fewest the cluster's CPUs and GPUs hold (at least 1).
    """
    slots = [int(resources.get(name, 0)) // max(1, int(options[key])) for key, name in RAY_RESOURCES.items() if key in options]
    return max(1, min(slots, default=1))


RAY_RESOURCES = {"num_cpus": "CPU", "num_gpus": "GPU"}
"""The options of :func:`ray_task_options` and the cluster resources they ask for."""


def ray_parallel_runs(resources: dict[str, float], threads: int) -> int:
    """
    :param resources: A Ray cluster's resources (``ray.cluster_resources()``).
    :param threads: CPUs per run.
    :return: The runs that execute at once: the cluster's CPUs // ``threads`` (at least 1).
    """
    return ray_parallel_tasks(resources, ray_task_options(threads))


def execute_runs(
    configs: Sequence[RunConfig], results_dir: str, device: str, threads: int, verbose: int
) -> list[dict[str, Any]]:
    """
    A Ray task's work for runs alone (:func:`submit_ray_tasks`): each run executed by the runner, one after another.

    :param configs: The runs.
    :param results_dir: The sweep's results directory.
    :param device: Unused: each run trains where its config says (the signature of a task's work).
    :param threads: Torch threads.
    :param verbose: 1 to print each run's progress.
    :return: Each run's result.
    """
    return [execute_run(config, results_dir, threads=threads, verbose=verbose) for config in configs]


TaskWork = Callable[[Sequence[RunConfig], str, str, int, int], list[dict[str, Any]]]
"""What one Ray task does with its runs: ``(configs, results_dir, device, threads, verbose) -> results``."""


def submit_ray_tasks(
    ray: Any,
    units: Sequence[Sequence[RunConfig]],
    results_dir: str,
    work: TaskWork,
    device: str,
    threads: int,
    verbose: int,
    on_result: OnResult,
) -> None:
    """
    Submit one Ray task per unit (a run, or a run group), each doing ``work`` on ``threads`` CPUs (and one GPU on a
    CUDA device), and report its runs as it ends (:func:`collect_ray_tasks`).

    :param ray: The ``ray`` module (connected, see :func:`ray_session`).
    :param units: Each task's runs.
    :param results_dir: The sweep's results directory.
    :param work: What a task does with its runs.
    :param device: Where the tasks train (for their resources, :func:`ray_task_options`).
    :param threads: Torch threads (and Ray CPUs) per task.
    :param verbose: 1 to print the tasks' progress (Ray forwards the workers' output).
    :param on_result: Called for each run.
    """
    remote = ray.remote(**ray_task_options(threads, device))(_ray_task)
    tasks = {remote.remote(list(unit), results_dir, device, threads, verbose, work): list(unit) for unit in units}
    collect_ray_tasks(ray, tasks, results_dir, on_result)


def _ray_task(
    configs: Sequence[RunConfig], results_dir: str, device: str, threads: int, verbose: int, work: TaskWork
) -> list[dict[str, Any]]:
    set_worker_threads(threads)
    return work(configs, results_dir, device, threads, verbose)
