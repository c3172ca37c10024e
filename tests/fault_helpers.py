"""A test-only algorithm for the sweep fault tests: MADDPG that stalls mid-run, once, so that a test can kill it.

Sweeps load it as ``RunConfig.algorithm="tests.fault_helpers:StallingMADDPG"`` (the repository root must be
importable: pytest run from there, ``PYTHONPATH`` for a subprocess, the driver's directory for Ray workers).
"""

import os
import time
from pathlib import Path
from typing import Any

from sb3_maddpg import MADDPG

STALL_SECONDS = 60.0
"""How long a stalled run waits to be killed before it fails (so that a test that went wrong leaves no process)."""


def stall_once(trigger: str | os.PathLike[str], seconds: float = STALL_SECONDS) -> None:
    """
    If ``trigger`` exists, claim it (rename it to ``<trigger>.claimed``: one process wins), write this process's
    id to ``<trigger>.pid`` and sleep until killed; else return at once.

    :param trigger: The trigger file.
    :param seconds: The longest sleep, after which the run fails.
    """
    trigger = Path(trigger)
    try:
        os.replace(trigger, trigger.with_name(f"{trigger.name}.claimed"))
    except FileNotFoundError:
        return
    pid_path = trigger.with_name(f"{trigger.name}.pid")
    tmp_path = pid_path.with_name(f"{pid_path.name}.tmp")
    tmp_path.write_text(str(os.getpid()))
    os.replace(tmp_path, pid_path)  # the test polls for it: whole or absent
    time.sleep(seconds)
    raise RuntimeError(f"stalled for {seconds} s and nobody killed this process")


def stalled_pid(trigger: str | os.PathLike[str]) -> int | None:
    """
    :param trigger: A trigger file given to :class:`StallingMADDPG`.
    :return: The process id of the run that stalled on it, or ``None`` when none has yet.
    """
    pid_path = Path(f"{trigger}.pid")
    return int(pid_path.read_text()) if pid_path.exists() else None


class StallingMADDPG(MADDPG):
    """
    MADDPG that stalls at its first training step while a trigger file exists (see :func:`stall_once`).

    :param stall_trigger: The trigger file, or ``None`` to train as MADDPG does.
    """

    def __init__(self, *args: Any, stall_trigger: str | None = None, **kwargs: Any) -> None:
        self.stall_trigger = stall_trigger
        super().__init__(*args, **kwargs)

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        if self.stall_trigger is not None:
            stall_once(self.stall_trigger)
        super().train(gradient_steps, batch_size)
