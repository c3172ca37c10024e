"""What a run group writes while it trains: each run's checkpoints, learning curve and ``progress.csv`` rows, the
group's progress lines, and its state at each save point."""

import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, cast

import torch as th

from sb3_maddpg.common.progress import ProgressLogCallback, log_line
from sb3_maddpg.common.train_logs import record_losses
from sb3_maddpg.experiments.group_state import save_state, seed_ranges
from sb3_maddpg.experiments.results_dir import CHECKPOINT_DIR, LOG_FILE, run_directory
from sb3_maddpg.experiments.runner import CheckpointAtSteps, curve_callback, log_interval
from sb3_maddpg.experiments.setting import RunConfig
from sb3_maddpg.experiments.tasks import run_task
from sb3_maddpg.run_group import GroupCallback

STATE_FRACTION = 0.1
"""Besides each checkpoint, a group's state is saved every this fraction of the budget (checkpoints are in the last
20% only: without these, a process killed at 70% would lose everything)."""


class _SummedSteps:
    """What :class:`GroupProgress` reads as its "model": the env steps of every run of the group, summed."""

    def __init__(self) -> None:
        self.num_timesteps = 0


class GroupProgress(ProgressLogCallback):
    """
    A group's progress lines: env steps summed over its runs, their rate and the time left, as
    :class:`~sb3_maddpg.common.progress.ProgressLogCallback` says them for one run; each line goes to every run's
    ``train.log`` and, once, to stdout.

    :param label: The group's name in the lines.
    :param n_runs: Runs in the group.
    :param total_timesteps: Each run's budget.
    :param log_paths: Each run's ``train.log``.
    :param echo: Print the lines too.
    """

    def __init__(self, label: str, n_runs: int, total_timesteps: int, log_paths: Sequence[Path], echo: bool) -> None:
        super().__init__(label, n_runs * total_timesteps, None, echo=echo, every_seconds=120.0)
        self.n_runs = n_runs
        self.log_paths = [str(path) for path in log_paths]
        self.steps = _SummedSteps()
        self.team_return: float | None = None
        self.init_callback(cast(Any, self.steps))

    def _recent_return(self) -> str:
        if self.team_return is None:
            return ""
        return f", team return {self.team_return:.1f} (mean of the runs' last episodes)"

    def log(self, line: str) -> None:
        """
        :param line: A line for every run's log file and, once, stdout.
        """
        for path in self.log_paths:
            log_line(line, path, echo=False)
        if self.echo:
            print(line, flush=True)


class GroupRecorder(GroupCallback):
    """
    What a group writes while it trains (the :class:`~sb3_maddpg.run_group.GroupCallback` of its ``learn``), through
    SB3's logger and callbacks' public API only: each run's checkpoints
    (:class:`~sb3_maddpg.experiments.runner.CheckpointAtSteps`), learning curve (the runner's
    :class:`~sb3_maddpg.analysis.evaluation.TeamEvalCallback`), ``progress.csv`` rows (about as many as the runner's),
    the group's progress lines, and its state at each save point.

    :param configs: The group's runs.
    :param models: One model per run, the group's runs are written back into.
    :param group: The run group.
    :param results_dir: The sweep's results directory.
    :param state_path: The group's state file.
    :param echo: Print the progress lines.
    """

    def __init__(
        self,
        configs: Sequence[RunConfig],
        models: Sequence[Any],
        group: Any,
        results_dir: str | os.PathLike[str],
        state_path: Path,
        echo: bool,
    ) -> None:
        self.configs = list(configs)
        self.models = list(models)
        self.group = group
        self.state_path = state_path
        self.directories = [run_directory(results_dir, config) for config in configs]
        first = configs[0]
        self.total = first.total_timesteps
        self.worlds = group.worlds_per_run
        self.checkpoints = [
            CheckpointAtSteps(c.checkpoint_steps(), d / CHECKPOINT_DIR) for c, d in zip(configs, self.directories)
        ]
        self.saved_before: list[list[tuple[int, Path]]] = [[] for _ in configs]  # by earlier attempts
        tasks = [run_task(config) for config in configs]
        self.curve_envs = [task.make_eval_env(task.config.curve_eval_episodes) for task in tasks]
        curves = [curve_callback(t, env, self.worlds, d) for t, env, d in zip(tasks, self.curve_envs, self.directories)]
        self.curves = [curve for curve in curves if curve is not None]
        for model, checkpoint, curve in zip(self.models, self.checkpoints, curves):
            checkpoint.init_callback(model)
            if curve is not None:
                curve.init_callback(model)
        seeds = seed_ranges([config.seed for config in configs])
        self.progress = GroupProgress(
            f"{first.experiment}/{first.scheme}/seeds {seeds} ({len(configs)} runs)",
            len(configs),
            self.total,
            [directory / LOG_FILE for directory in self.directories],
            echo,
        )
        self.log_interval = log_interval(first)
        self.rounds_logged = 0
        self.save_points = sorted({*first.checkpoint_steps(), *(round(self.total * k * STATE_FRACTION) for k in range(1, 10))})
        self.saved_at = 0
        self.compile_said = 0.0
        self.elapsed_before = 0.0
        self.started = time.perf_counter()

    @property
    def saved(self) -> list[list[tuple[int, Path]]]:
        """Each run's checkpoints, ``(env steps, model file)`` in order, over every attempt."""
        return [before + checkpoint.saved for before, checkpoint in zip(self.saved_before, self.checkpoints)]

    @property
    def train_time(self) -> float:
        """Seconds the group has trained, over every attempt."""
        return self.elapsed_before + time.perf_counter() - self.started

    def start(self, resumed: dict[str, Any] | None) -> None:
        """
        Begin (or go on with) training: each run's first learning-curve point, or what a saved state recorded.

        :param resumed: The group's saved state, or ``None`` for a start from scratch.
        """
        group = self.group
        for run, model in enumerate(self.models):
            group.write_back(run, model)
        if resumed is not None:
            self.elapsed_before = float(resumed["elapsed"])
            self.rounds_logged = int(resumed["rounds_logged"])
            self.saved_at = group.num_timesteps
            self._resume_callbacks(resumed["runs"], group.num_timesteps // self.worlds)
        self.progress.steps.num_timesteps = group.n_runs * group.num_timesteps
        for callback in (*self.curves, self.progress):
            callback.on_training_start({}, {})  # the curves' first evaluation, at step 0 only
        if resumed is not None:
            self.progress.log(f"{self.progress.run_id}: resumed at {group.num_timesteps:,} steps per run")
        if group.compiled:
            self.progress.log(f"{self.progress.run_id}: compiling the rounds at the first steps and updates (tens of seconds)")

    def _resume_callbacks(self, runs: Sequence[dict[str, Any]], calls: int) -> None:
        """
        Go on with each run's callbacks where the saved state left them, through their public API.

        :param runs: Each run's saved record (:meth:`save`).
        :param calls: The callbacks' calls so far (one per step of the run's worlds).
        """
        self.saved_before = [[(steps, Path(file)) for steps, file in run["saved"]] for run in runs]
        self.checkpoints = [
            CheckpointAtSteps(run["pending"], directory / CHECKPOINT_DIR) for run, directory in zip(runs, self.directories)
        ]
        for checkpoint, model in zip(self.checkpoints, self.models):
            checkpoint.init_callback(model)
        for curve, run in zip(self.curves, runs):
            curve.history.extend(run["curve"])  # its public record, which its CSV file rewrites in full
            # Its schedule (an evaluation at every eval_freq-th call) goes on from the state's step: calls up to the
            # same place modulo eval_freq, none of which evaluates.
            for _ in range(calls % curve.eval_freq):
                curve.on_step()

    def on_step(self, group: Any) -> None:
        """After each step of every run's worlds: checkpoints, curve points, ``progress.csv`` rows, progress lines."""
        steps = group.num_timesteps
        for run, (model, checkpoint) in enumerate(zip(self.models, self.checkpoints)):
            model.num_timesteps = steps
            if checkpoint.pending and steps >= checkpoint.pending[0]:
                group.write_back(run, model)  # the weights of now, as SB3 saves them mid-round
            checkpoint.on_step()
        for run, curve in enumerate(self.curves):
            if (steps // self.worlds) % curve.eval_freq == 0:  # this call evaluates: the run's weights of now
                group.write_back(run, self.models[run])
            curve.on_step()
        rounds = len(group.worlds.episodes)
        if rounds > self.rounds_logged:
            self.rounds_logged = rounds
            if (rounds * self.worlds) // self.log_interval > ((rounds - 1) * self.worlds) // self.log_interval:
                self._dump(group)
        self.progress.steps.num_timesteps = group.n_runs * steps
        self.progress.on_step()

    def _dump(self, group: Any) -> None:
        """One ``progress.csv`` row per run, as SB3's ``_dump_logs`` writes them."""
        last = max(1, -(-100 // self.worlds))  # SB3's ep_info_buffer: the last 100 episodes
        rewards = th.stack(group.worlds.episodes[-last:])[:, 0].mean(0).tolist()
        agent_returns = th.stack(group.worlds.agent_episodes[-last:]).mean(0).tolist()  # [R][N]
        self.progress.team_return = sum(rewards) / len(rewards)
        elapsed = max(self.train_time, 1e-9)
        lr = group.actor_optimizer.lr
        for run, model in enumerate(self.models):
            logger = model.logger
            logger.record("time/episodes", len(group.worlds.episodes) * self.worlds, exclude="tensorboard")
            logger.record("time/fps", int(group.num_timesteps / elapsed))
            logger.record("time/time_elapsed", int(elapsed), exclude="tensorboard")
            logger.record("time/total_timesteps", group.num_timesteps, exclude="tensorboard")
            logger.record("rollout/ep_rew_mean", rewards[run])
            logger.record("rollout/ep_len_mean", float(self.configs[run].episode_length))
            for agent, mean in zip(model.agent_layout.agent_ids, agent_returns[run]):
                logger.record(f"rollout/{agent}/ep_rew_mean", mean)  # as a run alone logs them (train_logs)
            if group.losses:
                record_losses(
                    logger, model.agent_layout.agent_ids, group.n_updates, {k: v[run] for k, v in group.losses.items()}
                )
                logger.record("train/learning_rate", lr)
            logger.dump(group.num_timesteps)

    def on_round_end(self, group: Any) -> None:
        """At the end of each round: the compile time when a step has just compiled; the group's state, when a save
        point has passed since the last save."""
        if group.compile_seconds > self.compile_said:
            self.compile_said = group.compile_seconds
            self.progress.log(f"{self.progress.run_id}: rounds compiled in {group.compile_seconds:.0f} s so far")
        steps = group.num_timesteps
        if any(self.saved_at < point <= steps for point in self.save_points):
            self.save(group)

    def save(self, group: Any) -> None:
        """Write the group's state file (overwriting the last)."""
        self.saved_at = group.num_timesteps
        runs = [
            {"pending": list(checkpoint.pending), "saved": [(steps, str(path)) for steps, path in saved], "curve": []}
            for checkpoint, saved in zip(self.checkpoints, self.saved)
        ]
        for run, curve in zip(runs, self.curves):
            run["curve"] = list(curve.history)
        state = {
            "configs": [config.to_dict() for config in self.configs],
            "group": group.state_dict(copy_buffers=False),  # written at once: no copy of full buffers
            "runs": runs,
            "elapsed": self.train_time,
            "rounds_logged": self.rounds_logged,
        }
        save_state(self.state_path, state)

    def close(self) -> None:
        """Close the evaluation and training envs."""
        for env in self.curve_envs:
            env.close()
        for model in self.models:
            model.get_env().close()
