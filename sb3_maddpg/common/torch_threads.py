"""Torch's CPU threads for a training process: one unless the user asked for more.

The package's networks are small (64 units, batch 1024): one update spreads poorly over threads, and on a CPU shared
with any other busy process several torch threads wait on each other. Measured on a 2-core machine with one other
busy process: 2 threads trained at ~110-300 env steps/s, 1 thread at ~3,200-4,500. So the package's own work runs on
one thread unless the user chose a count: ``learn()`` and ``evaluate_team`` run inside :func:`package_threads`, which
sets one for their duration and gives the caller's count back after; the entry points (the examples, the main job,
``sb3-maddpg run``/``tune``) set it for the whole process (:func:`use_torch_threads`, ``--threads N``). A choice of the
user's (``OMP_NUM_THREADS``, ``MKL_NUM_THREADS``, or ``torch.set_num_threads`` after importing ``sb3_maddpg``) is
always kept.
"""

import argparse
import contextlib
import functools
import os
from collections.abc import Callable, Iterator
from typing import ParamSpec, TypeVar

import torch as th

P = ParamSpec("P")
R = TypeVar("R")

THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""Environment variables that set torch's thread count when the process starts (torch reads them itself)."""

# The count the package last left torch at (at first, torch's own): any other count is the user's doing.
_expected_threads = [th.get_num_threads()]


def threads_set_by_user() -> str | None:
    """
    :return: How the user set torch's thread count, if they did: an environment variable of :data:`THREAD_VARIABLES`,
        or a ``torch.set_num_threads`` call made after ``sb3_maddpg`` was imported; ``None`` if neither.
    """
    for variable in THREAD_VARIABLES:
        if os.environ.get(variable, "").strip():
            return f"{variable}={os.environ[variable].strip()}"
    if th.get_num_threads() != _expected_threads[0]:
        return f"torch.set_num_threads({th.get_num_threads()})"
    return None


def use_torch_threads(threads: int | None = None) -> int:
    """
    Set torch's intra-op CPU threads for this process, as the package's entry points do.

    :param threads: The number of threads; ``None`` keeps what the user set (``OMP_NUM_THREADS``, ``MKL_NUM_THREADS``,
        or ``torch.set_num_threads`` after importing ``sb3_maddpg``) and otherwise uses 1, the fastest choice for these
        small networks on a machine that runs anything else. Use more cores through more worlds (``n_envs``) or runs
        in parallel (``sb3-maddpg run --workers``) rather than more threads per run.
    :return: The number of threads now in force.
    """
    if threads is not None:
        if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
            raise ValueError(
                f"threads must be a positive integer, got {threads!r}: use 1 (the default, best on a shared CPU) or the "
                "number of cores this process may use alone."
            )
        th.set_num_threads(threads)
    elif threads_set_by_user() is None:
        th.set_num_threads(1)
    _expected_threads[0] = th.get_num_threads()
    return _expected_threads[0]


@contextlib.contextmanager
def package_threads() -> Iterator[int]:
    """
    One torch thread inside (the fastest for these small networks on a shared CPU), unless the user chose a count
    (:func:`threads_set_by_user`), which is kept; the count before is restored on the way out, so that the caller's
    own torch work is untouched.

    :return: The number of threads in force inside.
    """
    if threads_set_by_user() is not None:
        yield th.get_num_threads()
        return
    before = th.get_num_threads()
    th.set_num_threads(1)
    try:
        yield 1
    finally:
        th.set_num_threads(before)


def in_package_threads(function: Callable[P, R]) -> Callable[P, R]:
    """
    :param function: A function of the package's own work (e.g. an evaluation).
    :return: The function, run inside :func:`package_threads`.
    """

    @functools.wraps(function)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with package_threads():
            return function(*args, **kwargs)

    return wrapper


def add_threads_argument(parser: argparse.ArgumentParser) -> None:
    """
    Give a command line the package's ``--threads`` option, for :func:`use_torch_threads`.

    :param parser: The command line's parser.
    """
    parser.add_argument(
        "--threads",
        type=int,
        default=None,
        help="torch CPU threads (default: 1, or OMP_NUM_THREADS where set; one is fastest on a shared CPU)",
    )
