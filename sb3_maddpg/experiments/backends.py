"""Where runs execute: in this process, in a local process pool, or on a Ray cluster."""

import os
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from multiprocessing import get_context
from typing import Any

from sb3_maddpg.experiments.config import RunConfig
from sb3_maddpg.experiments.results import write_result_files
from sb3_maddpg.experiments.runner import execute_run

BACKENDS = ("local", "ray")

OnResult = Callable[[RunConfig, dict[str, Any] | None, str | None], None]
"""Called as each run ends: ``(config, result, None)`` on success, ``(config, None, traceback)`` on failure."""


def set_worker_threads(threads: int) -> None:
    """
    Limit a worker's intra-op threads (torch and the BLAS libraries) so parallel workers don't fight for cores.

    :param threads: Threads per worker.
    """
    for variable in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[variable] = str(threads)
    import torch as th

    th.set_num_threads(threads)


def _execute(config: RunConfig, results_dir: str, threads: int, verbose: int) -> dict[str, Any]:
    return execute_run(config, results_dir, threads=threads, verbose=verbose)


def run_local(
    configs: Sequence[RunConfig],
    results_dir: str,
    on_result: OnResult,
    workers: int = 1,
    threads: int = 1,
    verbose: int = 1,
) -> None:
    """
    Run on this machine: in this process with one worker, else in a pool of ``workers`` processes
    (``spawn`` start method, so that no torch or env state is shared with the parent).

    :param configs: The runs.
    :param results_dir: The sweep's results directory.
    :param on_result: Called as each run ends.
    :param workers: Number of parallel processes.
    :param threads: Torch threads per process.
    :param verbose: 1 to print each run's progress.
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
    with ProcessPoolExecutor(
        max_workers=workers, mp_context=get_context("spawn"), initializer=set_worker_threads, initargs=(threads,)
    ) as pool:
        futures: dict[Future[dict[str, Any]], RunConfig] = {
            pool.submit(_execute, config, results_dir, threads, verbose): config for config in configs
        }
        pending = set(futures)
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                error = future.exception()
                if error is None:
                    on_result(futures[future], future.result(), None)
                else:
                    on_result(futures[future], None, "".join(traceback.format_exception(error)))


def run_ray(
    configs: Sequence[RunConfig],
    results_dir: str,
    on_result: OnResult,
    address: str | None = None,
    threads: int = 1,
    num_cpus: int | None = None,
    verbose: int = 1,
) -> None:
    """
    Run as Ray tasks, one CPU slot per ``threads``: on the cluster at ``address`` (e.g. ``"auto"`` or
    ``"ray://head:10001"``), or on a local Ray instance started here when ``address`` is ``None``.

    Every node needs this package installed. Each task writes its run directory on its own node and
    returns the small result files, which are written here too, so a cluster needs no shared
    filesystem (model checkpoints stay on the nodes).

    :param configs: The runs.
    :param results_dir: The sweep's results directory (absolute paths are safest on a cluster).
    :param on_result: Called as each run ends.
    :param address: The Ray cluster's address, or ``None`` to start a local instance.
    :param threads: Torch threads (and Ray CPUs) per run.
    :param num_cpus: CPUs of a local instance (``None``: all of this machine's).
    :param verbose: 1 to print each run's progress (Ray forwards the workers' output).
    """
    try:
        import ray
    except ImportError as error:
        raise ImportError("The Ray backend needs Ray: pip install 'ray[default]' (or sb3-maddpg[distributed]).") from error

    started_here = not ray.is_initialized()
    if started_here:
        # Ray starts its workers at niceness 15 by default: on a machine that also runs anything else, a
        # local instance's workers then crawl (20x slower measured on a busy 2-core machine). A local
        # instance exists for these runs, so its workers get normal priority; a cluster keeps its own settings.
        system_config = {"worker_niceness": 0} if address is None else None
        ray.init(
            address=address,
            num_cpus=num_cpus if address is None else None,
            include_dashboard=False,
            log_to_driver=verbose >= 1,
            configure_logging=False,
            _system_config=system_config,
        )
    try:
        remote = ray.remote(num_cpus=threads)(_ray_task)
        refs = {remote.remote(config, results_dir, threads, verbose): config for config in configs}
        pending = list(refs)
        while pending:
            finished, pending = ray.wait(pending, num_returns=1)
            for ref in finished:
                try:
                    result = ray.get(ref)
                except Exception:
                    on_result(refs[ref], None, traceback.format_exc())
                else:
                    write_result_files(results_dir, result)
                    on_result(refs[ref], result, None)
    finally:
        if started_here:
            ray.shutdown()


def _ray_task(config: RunConfig, results_dir: str, threads: int, verbose: int) -> dict[str, Any]:
    set_worker_threads(threads)
    return execute_run(config, results_dir, threads=threads, verbose=verbose)
