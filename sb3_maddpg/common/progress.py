"""Progress that tells the truth: lines with the recent rate and time left, and Ctrl-C as one line, not a traceback."""

import collections
import contextlib
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, TextIO

import numpy as np
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
    Report a run's progress (steps, throughput, recent return, time left) to stdout and a log file,
    every ``every`` of training or every ``every_seconds`` seconds, whichever comes first.

    The return is the mean over the recent episodes (SB3's ``ep_info_buffer``, which a ``Monitor`` or ``VecMonitor``
    fills) of the env's episode return: the team return of a cooperative task. In a competitive task (``sides``
    given) that would add opponents' rewards, so each side's return is said instead: the mean over its agents of
    their episode returns (as :func:`~sb3_maddpg.analysis.evaluation.evaluate_team` scores ``return_<side>``), from
    the per-agent returns a team algorithm adds to each episode's statistics; without those, the line says that its
    return is all agents' combined.

    Throughput and time left are measured over the last ``window_seconds`` (at least since the previous line), not
    since the start: when the machine's load changes, the next lines say so.

    :param run_id: The name printed with each line.
    :param total_timesteps: The run's budget.
    :param log_path: A text file the lines are appended to, or ``None``.
    :param every: The fraction of training between two lines.
    :param echo: Print the lines too.
    :param every_seconds: Also report when this many seconds have passed since the last line (``None``: never).
    :param window_seconds: The span of recent training the rate is measured over.
    :param sides: A competitive task's sides: side -> its agents, by id or by name (as
        :data:`~sb3_maddpg.envs.MPE_TASK_SIDES` and ``evaluate_team``'s ``sides`` give them); ``None`` or empty: the
        agents are one cooperative team.
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
        sides: Mapping[str, Sequence[str]] | None = None,
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
        self.sides = {side: tuple(agents) for side, agents in (sides or {}).items()}
        self._side_agents: dict[str, list[int]] | None = None  # each side's label -> its agents' layout indices

    def _on_training_start(self) -> None:
        # A continued run (learn(reset_num_timesteps=False)) reports at the next multiple of the interval.
        self._next = (self.num_timesteps // self.interval + 1) * self.interval
        self._start = self._last_line = time.perf_counter()
        self._marks.clear()
        self._marks.append((self._start, self.num_timesteps))
        self._side_agents = None
        self._sides_by_label()  # sides that do not match the team are refused now, not at the first line

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

    def _sides_by_label(self) -> dict[str, list[int]]:
        """
        :return: Each side's label (``"adversaries' return"``) -> its agents' indices in the model's layout; empty
            for a cooperative task, or a model without an agent layout (whose episodes have no per-agent returns).
        """
        if self._side_agents is None:
            layout: Any = getattr(self.model, "agent_layout", None)
            self._side_agents = {}
            if self.sides and layout is not None:
                from sb3_maddpg.analysis.evaluation import resolve_sides, side_return_label

                agent_ids = list(layout.agent_ids)
                self._side_agents = {
                    side_return_label(side): [agent_ids.index(agent) for agent in agents]
                    for side, agents in resolve_sides(self.sides, agent_ids).items()
                }
        return self._side_agents

    def _recent_return(self) -> str:
        episodes = getattr(self.model, "ep_info_buffer", None)  # filled by a Monitor or VecMonitor
        if not episodes:
            return ""
        combined = sum(episode["r"] for episode in episodes) / len(episodes)
        if not self.sides:
            return f", team return {combined:.1f} (last {len(episodes)} episodes)"
        per_agent = [episode["agent_returns"] for episode in episodes if "agent_returns" in episode]
        sides = self._sides_by_label()
        if not per_agent or not sides:
            return f", return of all agents combined {combined:.1f} (opponents included; last {len(episodes)} episodes)"
        means = np.mean(per_agent, axis=0)
        returns = ", ".join(f"{label} {np.mean(means[agents]):.1f}" for label, agents in sides.items())
        return f", {returns} (last {len(per_agent)} episodes)"

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
