"""Helpers for tests that kill processes: wait for a condition, tell whether a process runs, list its workers."""

import time
from collections.abc import Callable
from pathlib import Path


def wait_for(condition: Callable[[], object], what: str, timeout: float = 90.0, interval: float = 0.05) -> None:
    """
    :param condition: Polled until it is true.
    :param what: What is waited for, for the error.
    :param timeout: Seconds before the test fails.
    :param interval: Seconds between polls (longer for a costly condition, on a machine the test's processes need).
    """
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}")
        time.sleep(interval)


def alive(pid: int) -> bool:
    """Whether a process runs (a zombie, dead but not reaped by its parent, does not)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def spawned_workers(pid: int) -> list[int]:
    """
    :param pid: A process.
    :return: Its children that run multiprocessing's ``spawn`` entry point (a process pool's workers; not its resource
        tracker), from Linux's /proc.
    """
    workers = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:  # a thread or a child may end while it is read
            children = (task / "children").read_text().split()
        except FileNotFoundError:
            continue
        for child in children:
            try:
                command = Path(f"/proc/{child}/cmdline").read_bytes()
            except FileNotFoundError:
                continue
            if b"spawn_main" in command:
                workers.append(int(child))
    return workers
