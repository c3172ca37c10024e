"""Runs in local processes: a pool of worker processes that each execute runs by the runner, one thread budget each.

Faults: a worker that dies (SIGKILL, the out-of-memory killer) loses only the runs it and the workers beside it were
running; they are reported as failed and the sweep goes on. A sweep that is killed takes its pool workers with it;
Ctrl-C stops the workers and leaves the runs in progress unfinished, so that the same command runs them again.
"""

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
from multiprocessing import get_context
from typing import Any

from sb3_maddpg.experiments.runner import execute_run
from sb3_maddpg.experiments.setting import RunConfig

OnResult = Callable[[RunConfig, dict[str, Any] | None, str | None], None]
"""Called as each run ends: ``(config, result, None)`` on success, ``(config, None, traceback)`` on failure."""

LOST_RUN = "lost: the worker process running it died"


LOST_RUN_ERROR = (
    f"{LOST_RUN} (killed by a signal: the out-of-memory killer or a kill -9?); a local process pool also stops "
    "the runs beside it. Nothing of it counts as finished: run the same command again to run it."
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


def _execute(config: RunConfig, results_dir: str, threads: int, verbose: int, snapshots: bool, device: str) -> dict[str, Any]:
    return execute_run(config, results_dir, threads=threads, verbose=verbose, snapshots=snapshots, device=device)


def run_local(
    configs: Sequence[RunConfig],
    results_dir: str,
    on_result: OnResult,
    workers: int = 1,
    threads: int = 1,
    verbose: int = 1,
    log: Callable[[str], None] = print,
    snapshots: bool = True,
    device: str = "auto",
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
    :param snapshots: Each run saves a snapshot at each tenth of its budget (see
        :func:`~sb3_maddpg.experiments.runner.execute_run`), so that a run lost with its worker goes on from it.
    :param device: Where each run trains (SB3's ``device``; ``"auto"``: CUDA when there is a GPU).
    """
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}.")
    if workers == 1:
        for config in configs:
            try:
                result = _execute(config, results_dir, threads, verbose, snapshots, device)
            except Exception:
                on_result(config, None, traceback.format_exc())
            else:
                on_result(config, result, None)
        return
    queue = deque(configs)
    while queue:
        lost = _run_pool(queue, results_dir, on_result, workers, threads, verbose, snapshots, device)
        if lost:
            log(
                f"a worker process died: {len(lost)} run(s) in progress lost ({', '.join(c.run_id for c in lost)}); "
                f"{len(queue)} run(s) not started go on in new worker processes"
            )
        for config in lost:
            on_result(config, None, LOST_RUN_ERROR)


def _run_pool(
    queue: deque[RunConfig],
    results_dir: str,
    on_result: OnResult,
    workers: int,
    threads: int,
    verbose: int,
    snapshots: bool,
    device: str,
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
                    running[pool.submit(_execute, queue[0], results_dir, threads, verbose, snapshots, device)] = queue[0]
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
