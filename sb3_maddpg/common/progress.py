"""Progress that tells the truth: lines with the recent rate and time left, and Ctrl-C as one line, not a traceback."""

import collections
import contextlib
import sys
import time
from collections.abc import Iterator
from typing import TextIO

from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback

INTERRUPTED_EXIT_CODE = 130
"""The exit status of a process ended by Ctrl-C (128 + SIGINT), as shells report it."""


def format_seconds(seconds: float) -> str:
    """
    :param seconds: A duration.
    :return: It as ``"4m05s"`` or ``"1h02m03s"``.
    """
    seconds = round(seconds)
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}h{minutes:02d}m{secs:02d}s" if hours else f"{minutes}m{secs:02d}s"


def log_line(line: str, log_path: str | None, echo: bool) -> None:
    """
    Print a progress line and append it, time-stamped, to a log file.

    :param line: The line.
    :param log_path: A text file the line is appended to, or ``None``.
    :param echo: Print the line too.
    """
    if echo:
        print(line, flush=True)
    if log_path is not None:
        with open(log_path, "a") as file:
            file.write(f"{time.strftime('%Y-%m-%d %H:%M:%S')} {line}\n")


class ProgressLogCallback(BaseCallback):
    """
    Report a run's progress (steps, throughput, recent team return, time left) to stdout and a log file,
    every ``every`` of training or every ``every_seconds`` seconds, whichever comes first.

    Throughput and time left are measured over the last ``window_seconds`` (at least since the previous line), not
    since the start: when the machine's load changes, the next lines say so.

    :param run_id: The name printed with each line.
    :param total_timesteps: The run's budget.
    :param log_path: A text file the lines are appended to, or ``None``.
    :param every: The fraction of training between two lines.
    :param echo: Print the lines too.
    :param every_seconds: Also report when this many seconds have passed since the last line (``None``: never).
    :param window_seconds: The span of recent training the rate is measured over.
    """

    def __init__(
        self,
        run_id: str,
        total_timesteps: int,
        log_path: str | None = None,
        every: float = 0.1,
        echo: bool = True,
        every_seconds: float | None = None,
        window_seconds: float = 30.0,
    ) -> None:
        super().__init__()
        if window_seconds <= 0:
            raise ValueError(f"window_seconds must be positive, got {window_seconds}: use e.g. 30 (seconds).")
        self.run_id = run_id
        self.total_timesteps = total_timesteps
        self.log_path = log_path
        self.interval = max(1, int(total_timesteps * every))
        self.echo = echo
        self.every_seconds = every_seconds
        self.window_seconds = window_seconds
        self._next = self.interval
        self._start = self._last_line = time.perf_counter()
        self._marks: collections.deque[tuple[float, int]] = collections.deque()  # (time, steps) at each line

    def _on_training_start(self) -> None:
        # A continued run (learn(reset_num_timesteps=False)) reports at the next multiple of the interval.
        self._next = (self.num_timesteps // self.interval + 1) * self.interval
        self._start = self._last_line = time.perf_counter()
        self._marks.clear()
        self._marks.append((self._start, self.num_timesteps))

    def recent_rate(self, now: float, steps: int) -> tuple[float, float]:
        """
        :param now: The time (``time.perf_counter()``).
        :param steps: The env steps trained by then.
        :return: Env steps per second over the last ``window_seconds``, measured from the newest line at least that
            old (from the start, if none is), and the span it was measured over, in seconds.
        """
        while len(self._marks) > 1 and now - self._marks[1][0] >= self.window_seconds:
            self._marks.popleft()
        since, steps_then = self._marks[0] if self._marks else (self._start, 0)
        span = now - since
        return (steps - steps_then) / max(span, 1e-9), span

    def _on_step(self) -> bool:
        now = time.perf_counter()
        due_by_time = self.every_seconds is not None and now - self._last_line >= self.every_seconds
        if self.num_timesteps >= self._next or due_by_time:
            while self._next <= self.num_timesteps:
                self._next += self.interval
            self._last_line = now
            rate, span = self.recent_rate(now, self.num_timesteps)
            self._marks.append((now, self.num_timesteps))
            left = (self.total_timesteps - self.num_timesteps) / max(rate, 1e-9)
            self.log(
                f"{self.run_id}: {self.num_timesteps:,}/{self.total_timesteps:,} steps "
                f"({self.num_timesteps / self.total_timesteps:.0%}), {rate:,.0f} steps/s (last {format_seconds(span)}), "
                f"{format_seconds(now - self._start)} elapsed, {format_seconds(left)} left{self._recent_return()}"
            )
        return True

    def _recent_return(self) -> str:
        episodes = getattr(self.model, "ep_info_buffer", None)  # filled by a Monitor or VecMonitor
        if not episodes:
            return ""
        return f", team return {sum(episode['r'] for episode in episodes) / len(episodes):.1f} (last {len(episodes)} episodes)"

    def log(self, line: str) -> None:
        """
        :param line: A line for stdout and the log file.
        """
        log_line(line, self.log_path, self.echo)


def interrupted_line(model: BaseAlgorithm | None = None) -> str:
    """
    :param model: The model whose ``learn`` Ctrl-C stopped, if it was training.
    :return: One line saying how far it got.
    """
    if model is None:
        return "Stopped by Ctrl-C."
    total = getattr(model, "_total_timesteps", 0)
    done = model.num_timesteps
    share = f" ({done / total:.0%})" if total else ""
    return (
        f"Stopped by Ctrl-C at {done:,} of {total:,} training steps{share}. In your own code, catch KeyboardInterrupt "
        "around model.learn(): the model trained so far is usable (evaluate_team, model.save)."
    )


@contextlib.contextmanager
def ctrl_c_ends_quietly(model: BaseAlgorithm | None = None, file: TextIO | None = None) -> Iterator[None]:
    """
    Turn Ctrl-C inside the block into one line (how far training got, for a model) and exit status 130.

    :param model: The model trained inside the block, if any.
    :param file: Where the line goes (default: stdout).
    """
    try:
        yield
    except KeyboardInterrupt:
        print(interrupted_line(model), file=file or sys.stdout, flush=True)
        raise SystemExit(INTERRUPTED_EXIT_CODE) from None
