"""SIGTERM stops ``sb3-maddpg run`` and ``tune`` as Ctrl-C does: cleanly, saying how far they got, resumable.

A command started in the background from a script (``cmd &``, no job control) inherits SIGINT ignored, so
``kill -INT`` cannot stop it; SIGTERM can: ``kill``'s default, and what a scheduler or a machine's shutdown sends.
Left at its default action, SIGTERM ends the process at once: no line saying how far the sweep got, and a pool's
workers left to notice their owner's death on their own.
"""

import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from types import FrameType

from sb3_maddpg.common.progress import INTERRUPTED_EXIT_CODE

TERMINATED_EXIT_CODE = 128 + signal.SIGTERM
"""The exit status of a command that SIGTERM stopped (143), as shells report a process the signal ended."""


@dataclass
class Termination:
    """Whether SIGTERM arrived inside :func:`sigterm_as_ctrl_c`'s block."""

    received: bool = False

    def exit_status(self, status: int) -> int:
        """
        :param status: The command's exit status.
        :return: It, or :data:`TERMINATED_EXIT_CODE` for the Ctrl-C status of a command that SIGTERM stopped.
        """
        return TERMINATED_EXIT_CODE if self.received and status == INTERRUPTED_EXIT_CODE else status


@contextlib.contextmanager
def sigterm_as_ctrl_c() -> Iterator[Termination]:
    """
    Inside the block, SIGTERM raises ``KeyboardInterrupt`` (as Ctrl-C does) in the main thread; the previous handler
    comes back after it. Outside the main thread (where Python sets no handler) it changes nothing.

    :return: Whether SIGTERM arrived, read after the block.
    """
    termination = Termination()
    if threading.current_thread() is not threading.main_thread():
        yield termination
        return

    def interrupt(signum: int, frame: FrameType | None) -> None:
        termination.received = True
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield termination
    finally:
        signal.signal(signal.SIGTERM, previous)


def run_stoppable(command: Callable[[], int], interrupted: str) -> int:
    """
    Run a command that Ctrl-C or SIGTERM may stop.

    :param command: The command; it handles an interrupt during its own work and returns its exit status.
    :param interrupted: What to print on stderr when the interrupt reaches here instead (before the command's work
        began, or a command that leaves it to its caller).
    :return: The command's exit status, :data:`INTERRUPTED_EXIT_CODE` after Ctrl-C, :data:`TERMINATED_EXIT_CODE`
        after SIGTERM.
    """
    with sigterm_as_ctrl_c() as termination:
        try:
            status = command()
        except KeyboardInterrupt:
            print(interrupted, file=sys.stderr)
            status = INTERRUPTED_EXIT_CODE
    return termination.exit_status(status)
