"""Runs on Ray: a session (a local instance or a cluster), one task per run or run group, and their results as they
end; a task lost with its worker or node is retried by Ray, then reported as failed.
"""

import os
import traceback
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import torch as th

from sb3_maddpg.common.install_hint import extra_install_command
from sb3_maddpg.experiments.group_plan import BatchedRunRefused
from sb3_maddpg.experiments.local_pool import LOST_RUN, OnResult, set_worker_threads
from sb3_maddpg.experiments.results_dir import write_result_files
from sb3_maddpg.experiments.runner import execute_run
from sb3_maddpg.experiments.setting import RunConfig

RAY_MAX_RETRIES = 3
"""Ray runs a task again this many times when its worker process or node dies (Ray's default, stated)."""


RAY_MAX_RETRIES_TEXT = f"after Ray's retries (max_retries={RAY_MAX_RETRIES})"
"""How the error of a run lost with its worker process begins."""


RAY_LOST_RUN_ERROR = (
    f"{LOST_RUN} on Ray (its worker or node died, or Ray's memory monitor killed it) {RAY_MAX_RETRIES_TEXT}. Nothing "
    "of it counts as finished: run the same command again to run it (with fewer runs per node if memory ran out)."
)


def run_ray(
    configs: Sequence[RunConfig],
    results_dir: str,
    on_result: OnResult,
    address: str | None = None,
    threads: int = 1,
    num_cpus: int | None = None,
    verbose: int = 1,
    on_parallel: Callable[[int], None] | None = None,
    snapshots: bool = True,
    device: str = "auto",
) -> None:
    """
    Run as Ray tasks, one CPU slot per ``threads``: on the cluster at ``address`` (e.g. ``"auto"`` or
    ``"ray://head:10001"``), or on a local Ray instance started here when ``address`` is ``None``.

    Every node needs this package installed. Each task writes its run directory on its own node and
    returns the small result files, which are written here too, so a cluster needs no shared
    filesystem (model checkpoints stay on the nodes). A task whose worker process or node dies is run again
    (up to :data:`RAY_MAX_RETRIES` times), from the run's last snapshot where the retry sees it, else from scratch;
    Ctrl-C cancels the tasks.

    :param configs: The runs.
    :param results_dir: The sweep's results directory (absolute paths are safest on a cluster).
    :param on_result: Called as each run ends.
    :param address: The Ray cluster's address, or ``None`` to start a local instance.
    :param threads: Torch threads (and Ray CPUs) per run.
    :param num_cpus: CPUs of a local instance (``None``: all of this machine's).
    :param verbose: 1 to print each run's progress (Ray forwards the workers' output).
    :param on_parallel: Called once Ray is up with the number of runs that execute at once (the cluster's CPUs
        // ``threads``), e.g. for a time-left estimate.
    :param snapshots: Each run saves a snapshot at each tenth of its budget, which a retried task goes on from when it
        sees it (on the node that wrote it, or on shared storage).
    :param device: Where each run trains: ``"cuda"`` (one GPU per run, the one Ray gives its task), ``"cpu"``, or
        ``"auto"`` (CUDA when the cluster has GPUs), as :func:`ray_device` resolves it.
    :raise BatchedRunRefused: For a device that is not one, or a CUDA device on a cluster without GPUs (its tasks would
        wait forever), before any task.
    """
    with ray_session(address, num_cpus, verbose) as ray:
        resources = ray.cluster_resources()
        device = ray_device(device, resources.get("GPU", 0))
        if on_parallel is not None:
            on_parallel(ray_parallel_tasks(resources, ray_task_options(threads, device)))
        work = execute_runs if snapshots else execute_runs_without_snapshots
        submit_ray_tasks(ray, [[config] for config in configs], results_dir, work, device, threads, verbose, on_result)


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


def ray_device(device: str, gpus: float) -> str:
    """
    :param device: The device asked for: ``"auto"``, ``"cpu"``, ``"cuda"`` or ``"cuda:<index>"``.
    :param gpus: The Ray cluster's GPUs.
    :return: The device a Ray task trains on: ``"cuda"`` (on the GPU Ray gives the task, its ``CUDA_VISIBLE_DEVICES``,
        so ``"cuda:1"`` would name another) when asked for CUDA, or for ``"auto"`` on a cluster with GPUs; else ``"cpu"``.
    :raise BatchedRunRefused: For a device torch does not know, or CUDA on a cluster without GPUs.
    """
    if device == "auto":
        return "cuda" if gpus > 0 else "cpu"
    try:
        kind = th.device(device).type
    except (RuntimeError, TypeError) as error:
        raise BatchedRunRefused(
            f'device {device!r} is not a device torch knows ({error}): use "cpu", "cuda" or "auto".'
        ) from None
    if kind != "cuda":
        return device
    if gpus < 1:
        raise BatchedRunRefused(
            f"The runs cannot train on {device} under Ray: the Ray cluster has no GPU, so a task asking for one would "
            'wait forever. Use device="cpu" (or "auto"), or a cluster with GPU nodes.'
        )
    return "cuda"


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


def execute_runs(
    configs: Sequence[RunConfig], results_dir: str, device: str, threads: int, verbose: int
) -> list[dict[str, Any]]:
    """
    A Ray task's work for runs alone (:func:`submit_ray_tasks`): each run executed by the runner, one after another.

    :param configs: The runs.
    :param results_dir: The sweep's results directory.
    :param device: Where each run trains (see :func:`~sb3_maddpg.experiments.runner.execute_run`).
    :param threads: Torch threads.
    :param verbose: 1 to print each run's progress.
    :return: Each run's result.
    """
    return [execute_run(config, results_dir, threads=threads, verbose=verbose, device=device) for config in configs]


def execute_runs_without_snapshots(
    configs: Sequence[RunConfig], results_dir: str, device: str, threads: int, verbose: int
) -> list[dict[str, Any]]:
    """:func:`execute_runs` with no snapshots saved (``snapshots=False``)."""
    return [
        execute_run(config, results_dir, threads=threads, verbose=verbose, snapshots=False, device=device)
        for config in configs
    ]


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
