"""The batched backend: a sweep's runs trained in run groups (:class:`~sb3_maddpg.run_group.RunGroup`: the seeds of one
setting and scheme in one process, on one device), each run's directory written as the runner writes it.

A group trains to each checkpoint step; there each run is written back into its own MADDPG model, which is saved,
and at the end every run is evaluated and summarised by the runner's own functions
(:func:`~sb3_maddpg.experiments.runner.finish_run`), so that ``evaluate_team`` and ``sb3-maddpg report`` read the
results as any other. A group's training state is saved at each checkpoint and every tenth of the budget, into one
file per group (:func:`group_state_path`), which the same command resumes from. The groups train one after
another in the sweep's process (:func:`run_batched`), or as Ray tasks, one per group (:func:`run_batched_ray`).
"""

import csv
import dataclasses
import json
import os
import shutil
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, cast

import torch as th
from stable_baselines3.common.logger import configure

from sb3_maddpg.common.progress import ProgressLogCallback, log_line
from sb3_maddpg.common.train_logs import record_losses
from sb3_maddpg.experiments.backends import (
    OnResult,
    collect_ray_tasks,
    ray_parallel_tasks,
    ray_session,
    ray_task_options,
    set_worker_threads,
)
from sb3_maddpg.experiments.config import DEFAULT_ENV, RunConfig
from sb3_maddpg.experiments.results import (
    CHECKPOINT_DIR,
    CONFIG_FILE,
    LOG_FILE,
    PROGRESS_FILE,
    read_json,
    run_directory,
    write_json_atomic,
)
from sb3_maddpg.experiments.runner import (
    CheckpointAtSteps,
    build_model,
    curve_callback,
    finish_run,
    log_interval,
    make_eval_env,
    start_run_directory,
    training_line,
)

STATE_PREFIX = "group_seeds_"
"""A group's state file: ``<results>/<experiment>/<scheme>/group_seeds_<seeds>.pt`` (e.g. ``group_seeds_0-30.pt``)."""

TRAINED_FILE = "trained.json"
"""A run's record that its group's training is over (its checkpoints and train time), written in its directory before
the group's runs are evaluated and deleted once the run is done: a sweep that finds it evaluates the run again, and
does not train it again."""

STATE_FRACTION = 0.1
"""Besides each checkpoint, a group's state is saved every this fraction of the budget (checkpoints are in the last
20% only: without these, a process killed at 70% would lose everything)."""

BATCHED_HINT = "Train such runs with --backend local (e.g. in a second sweep, leaving them out here with --schemes)."


class BatchedRunRefused(ValueError):
    """A run of the sweep cannot train in a run group (the message names it, the cause, and what to do)."""


# ----- which runs train together -----


def group_key(config: RunConfig) -> str:
    """:return: What runs of one group have in common: their whole config but the seed (as JSON)."""
    return json.dumps({key: value for key, value in config.to_dict().items() if key != "seed"}, sort_keys=True)


def plan_groups(
    configs: Sequence[RunConfig],
    runs_per_process: int | None = None,
    most_runs: Callable[[Sequence[RunConfig]], int] | None = None,
) -> list[list[RunConfig]]:
    """
    :param configs: The runs to do.
    :param runs_per_process: The most runs in one group (``None``: all that share a setting and scheme, or as many as
        ``most_runs`` allows).
    :param most_runs: When ``runs_per_process`` is ``None``: the most runs of a setting and scheme one group holds,
        given those runs (e.g. :func:`memory_bound`).
    :return: The groups, each the runs of one setting and scheme (different seeds), in the sweep's order.
    """
    if runs_per_process is not None and runs_per_process < 1:
        raise ValueError(f"runs_per_process must be at least 1, got {runs_per_process}: e.g. 31 (one scheme's seeds).")
    buckets: dict[str, list[RunConfig]] = {}
    for config in configs:
        buckets.setdefault(group_key(config), []).append(config)
    groups = []
    for runs in buckets.values():
        size = runs_per_process or (len(runs) if most_runs is None else max(1, min(len(runs), most_runs(runs))))
        groups += [runs[start : start + size] for start in range(0, len(runs), size)]
    return groups


def resolve_device(device: str) -> th.device:
    """
    :param device: ``--device``: ``"auto"``, ``"cpu"``, ``"cuda"`` or ``"cuda:<index>"``.
    :return: The device a group trains on (``"auto"``: CUDA when there is a GPU, else the CPU).
    """
    if device == "auto":
        return th.device("cuda" if th.cuda.is_available() else "cpu")
    return th.device(device)


def memory_bound(device: str, log: Callable[[str], None] | None = None) -> Callable[[Sequence[RunConfig]], int]:
    """
    :param device: The groups' device (``--device``).
    :param log: Called with a line for each setting and scheme whose seeds do not fit in one group.
    :return: For :func:`plan_groups`: the most of given runs (one setting and scheme) that one group holds on that device
        (:func:`~sb3_maddpg.run_group.memory.runs_that_fit`: their replay buffers bound it).
    """
    from sb3_maddpg.run_group.memory import runs_that_fit

    sizes: dict[str, int] = {}  # by group key: each setting and scheme's model is built and said once

    def most_runs(runs: Sequence[RunConfig]) -> int:
        config = runs[0]
        key = group_key(config)
        if key not in sizes:
            model = build_model(config, device="cpu")
            try:
                size = runs_that_fit(model, resolve_device(device))
            finally:
                model.get_env().close()
            if log is not None and size.runs < len(runs):
                log(
                    f"{config.experiment}/{config.scheme}: groups of at most {size.runs} runs (each run's replay buffer "
                    f"{size.run_bytes / 1e9:.2f} GB; bound: {size.limit}); --runs-per-process sets another size"
                )
            sizes[key] = size.runs
        return sizes[key]

    return most_runs


def check_device(device: str) -> None:
    """
    Refuse a device the groups cannot train on here, before anything is written (every group would fail after its
    runs' directories were started afresh).

    :param device: ``--device``: ``"auto"``, ``"cpu"``, ``"cuda"`` or ``"cuda:<index>"``.
    :raise BatchedRunRefused: For a device that is not one, or a CUDA device this machine does not have.
    """
    try:
        resolved = th.device(device) if device != "auto" else None
    except (RuntimeError, TypeError) as error:
        raise BatchedRunRefused(f"--device {device!r} is not a device torch knows ({error}): use cpu, cuda or auto.") from None
    if resolved is None or resolved.type != "cuda":
        return
    if not th.cuda.is_available():
        raise BatchedRunRefused(
            f"CUDA is not available on this machine, so the run groups cannot train on {device}: use --device cpu or "
            "auto (or --ray, to train on a cluster's GPUs)."
        )
    if resolved.index is not None and resolved.index >= th.cuda.device_count():
        raise BatchedRunRefused(
            f"This machine has {th.cuda.device_count()} CUDA device(s), so there is no {device}: use --device cuda "
            f"(device 0), or an index below {th.cuda.device_count()}."
        )


def check_batched(configs: Sequence[RunConfig], device: str | None = None) -> None:
    """
    Refuse, before anything trains, the runs a run group cannot train: the first such run is named, with the cause
    and what to do. One model of each setting and scheme is built and checked as :class:`RunGroup` checks its models,
    and, given a device, for one run's replay buffer fitting in its memory
    (:func:`~sb3_maddpg.run_group.memory.runs_that_fit`).

    :param configs: The runs to do.
    :param device: The groups' device, checked first (:func:`check_device`) when there are runs; ``None``: not
        checked (e.g. under Ray, where the tasks' machines have the GPUs).
    :raise BatchedRunRefused: For the device, or the first run refused.
    """
    from sb3_maddpg.run_group import SpreadTask
    from sb3_maddpg.run_group.checks import check_models
    from sb3_maddpg.run_group.memory import runs_that_fit

    if device is not None and configs:
        check_device(device)
    for group in plan_groups(configs):
        config = group[0]
        if config.env != DEFAULT_ENV or config.vec_env != "batched":
            cause = (
                f"it trains on {config.env} (vec_env {config.vec_env!r}), but a run group steps simple_spread's batched "
                "worlds only (env 'simple_spread', vec_env 'batched')."
            )
        else:
            model = build_model(config, device="cpu")
            try:
                check_models([model])
                cause = "" if SpreadTask.from_env(model.get_env()) is not None else "its env tells no simple_spread task."
                if device is not None and not cause:
                    runs_that_fit(model, resolve_device(device))  # one run's buffers at least
            except (TypeError, ValueError) as error:
                cause = str(error)
            model.get_env().close()
        if cause:
            raise BatchedRunRefused(
                f"{config.run_id} (and its other seeds) cannot train in a run group (--backend batched): {cause} "
                + BATCHED_HINT
            )


# ----- one group's state file -----


def seed_ranges(seeds: Sequence[int]) -> str:
    """:return: Sorted seeds as ranges, e.g. ``[0, 1, 2, 5]`` as ``"0-2+5"``."""
    parts: list[str] = []
    ordered = sorted(seeds)
    start = previous = ordered[0]
    for seed in [*ordered[1:], None]:
        if seed is not None and seed == previous + 1:
            previous = seed
            continue
        parts.append(str(start) if start == previous else f"{start}-{previous}")
        if seed is not None:
            start = previous = seed
    return "+".join(parts)


def parse_seed_ranges(text: str) -> set[int]:
    """:return: The seeds of :func:`seed_ranges`' text."""
    seeds: set[int] = set()
    for part in text.split("+"):
        low, _, high = part.partition("-")
        seeds.update(range(int(low), int(high or low) + 1))
    return seeds


def group_state_path(results_dir: str | os.PathLike[str], configs: Sequence[RunConfig]) -> Path:
    """
    :param results_dir: The sweep's results directory.
    :param configs: A group's runs (one experiment and scheme).
    :return: The file its training state is saved in, beside its runs' directories.
    """
    first = configs[0]
    return Path(results_dir) / first.experiment / first.scheme / f"{STATE_PREFIX}{seed_ranges([c.seed for c in configs])}.pt"


def remove_stale_states(results_dir: str | os.PathLike[str], configs: Sequence[RunConfig]) -> None:
    """
    Delete the state files of earlier groups that held any of these runs (they are started afresh), and the temporary
    files of saves a killed process left (:func:`save_state`'s ``.group_seeds_<seeds>.pt.<pid>.tmp``).
    """
    seeds = {config.seed for config in configs}
    directory = group_state_path(results_dir, configs).parent
    stale = [(path, path.stem) for path in directory.glob(f"{STATE_PREFIX}*.pt")]
    stale += [(path, path.name[1:].partition(".pt.")[0]) for path in directory.glob(f".{STATE_PREFIX}*.pt.*.tmp")]
    for path, stem in stale:
        try:
            overlaps = bool(parse_seed_ranges(stem[len(STATE_PREFIX) :]) & seeds)
        except ValueError:  # not a name this module writes
            continue
        if overlaps:
            path.unlink(missing_ok=True)


def save_state(path: Path, state: dict[str, Any]) -> None:
    """Write a group's state whole or not at all (a temporary file renamed over the old one)."""
    tmp_path = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        th.save(state, tmp_path)
        os.replace(tmp_path, path)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def load_state(
    path: Path,
    configs: Sequence[RunConfig],
    results_dir: str | os.PathLike[str],
    log: Callable[[str], None] | None = None,
) -> dict[str, Any] | None:
    """
    :param path: A group's state file.
    :param configs: The group's runs.
    :param results_dir: The sweep's results directory.
    :param log: Called with a line saying why a state file that exists is not used.
    :return: The state, when it is readable, of these runs with these configs, and their directories still hold
        what it was saved with (config and checkpoints); else ``None`` (the group starts afresh).
    """
    if not path.exists():
        return None
    state, why = _read_state(path, configs, results_dir)
    if state is None and log is not None:
        log(f"{path.name} {why}, so the group starts afresh")
    return state


def _read_state(
    path: Path, configs: Sequence[RunConfig], results_dir: str | os.PathLike[str]
) -> tuple[dict[str, Any] | None, str]:
    """:return: :func:`load_state`'s state, or ``None`` and why not (a clause following the file's name)."""
    from sb3_maddpg.run_group.trainer import STATE_VERSION

    try:
        state = th.load(path, map_location="cpu", weights_only=True)
    except Exception as error:  # a truncated or foreign file: start afresh
        return None, f"cannot be read ({type(error).__name__}: truncated, or not a state)"
    if not isinstance(state, dict) or state.get("configs") != [config.to_dict() for config in configs]:
        return None, "is of other runs or configs"
    version = state["group"].get("version") if isinstance(state.get("group"), dict) else None
    if version != STATE_VERSION:
        return None, f"is of another layout (version {version}; this package reads version {STATE_VERSION})"
    for config, run in zip(configs, state["runs"]):
        if not _same_config(read_json(run_directory(results_dir, config) / CONFIG_FILE), config):
            return None, f"was saved with another {CONFIG_FILE} of {config.run_id}"
        missing = [file for _, file in run["saved"] if not Path(file).exists()]
        if missing:
            return None, f"names checkpoints of {config.run_id} that are missing ({missing[0]})"
    return state, ""


def write_trained(directory: Path, config: RunConfig, saved: Sequence[tuple[int, Path]], train_time: float) -> None:
    """
    Record that a run's training is over, before it is evaluated (see :data:`TRAINED_FILE`).

    :param directory: The run's directory.
    :param config: The run.
    :param saved: Its checkpoints, ``(env steps, model file)`` in order.
    :param train_time: Its training's wall time, seconds.
    """
    record = {"config": config.to_dict(), "saved": [[steps, str(path)] for steps, path in saved], "train_time": train_time}
    write_json_atomic(directory / TRAINED_FILE, record)


def read_trained(directory: Path, config: RunConfig, echo: bool) -> tuple[list[tuple[int, Path]], float] | None:
    """
    :param directory: A run's directory.
    :param config: The run.
    :param echo: Print why a record is not used, too (it is appended to the run's ``train.log``).
    :return: Its checkpoints and train time, when its training is over (:func:`write_trained`) for this config and
        its checkpoints are still there; else ``None`` (the run trains, again if it had).
    """
    path = directory / TRAINED_FILE
    if not path.exists():
        return None
    record = read_json(path)
    stored = read_json(directory / CONFIG_FILE)
    if not isinstance(record, dict) or not _same_config(record.get("config"), config):
        why = f"its {TRAINED_FILE} is unreadable or of another config"
    elif not _same_config(stored, config):
        why = f"its {CONFIG_FILE} is of another config"
    elif not all(Path(file).exists() for _, file in record["saved"]):
        why = "some of the checkpoints its training saved are missing"
    else:
        return [(int(steps), Path(file)) for steps, file in record["saved"]], float(record["train_time"])
    log_line(f"{config.run_id}: {why}, so it trains again", str(directory / LOG_FILE), echo)
    return None


def _same_config(stored: Any, config: RunConfig) -> bool:
    """:return: Whether a config read from JSON is ``config`` (JSON has no tuples: compared as configs)."""
    try:
        return isinstance(stored, dict) and RunConfig.from_dict(stored).same_as(config)
    except (TypeError, ValueError, KeyError):  # a foreign or older file
        return False


def read_progress_rows(path: Path, until: int) -> list[dict[str, Any]]:
    """:return: The rows of a ``progress.csv`` up to env step ``until`` (values as numbers), to write them again."""
    if not path.exists():
        return []
    rows = []
    with open(path, newline="") as file:
        for row in csv.DictReader(file):
            values = {key: _number(value) for key, value in row.items() if value not in ("", None)}
            if float(values.get("time/total_timesteps", 0)) <= until:
                rows.append(values)
    return rows


def _number(text: str) -> Any:
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


# ----- what a group writes while it trains -----


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


class GroupRecorder:
    """
    What a group writes while it trains (a :class:`~sb3_maddpg.run_group.GroupCallback`): each run's checkpoints
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
        self.curve_envs = [make_eval_env(config, config.curve_eval_episodes) for config in configs]
        curves = [curve_callback(c, env, self.worlds, d) for c, env, d in zip(configs, self.curve_envs, self.directories)]
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
        self.elapsed_before = 0.0
        self.started = time.perf_counter()

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
            for checkpoint, run in zip(self.checkpoints, resumed["runs"]):
                checkpoint.pending = list(run["pending"])
                checkpoint.saved = [(steps, Path(file)) for steps, file in run["saved"]]
            for curve, run in zip(self.curves, resumed["runs"]):
                curve.history = list(run["curve"])
                curve.n_calls = group.num_timesteps // self.worlds
        self.progress.steps.num_timesteps = group.n_runs * group.num_timesteps
        for callback in (*self.curves, self.progress):
            callback.on_training_start({}, {})  # the curves' first evaluation, at step 0 only
        if resumed is not None:
            self.progress.log(f"{self.progress.run_id}: resumed at {group.num_timesteps:,} steps per run")

    def on_step(self, group: Any) -> None:
        """After each step of every run's worlds: checkpoints, curve points, ``progress.csv`` rows, progress lines."""
        steps = group.num_timesteps
        for run, (model, checkpoint) in enumerate(zip(self.models, self.checkpoints)):
            model.num_timesteps = steps
            if checkpoint.pending and steps >= checkpoint.pending[0]:
                group.write_back(run, model)  # the weights of now, as SB3 saves them mid-round
            checkpoint.on_step()
        for run, curve in enumerate(self.curves):
            if (curve.n_calls + 1) % curve.eval_freq == 0:
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
        lr = group.actor_optimizer.param_groups[0]["lr"]
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
        """At the end of each round: the group's state, when a save point has passed since the last save."""
        steps = group.num_timesteps
        if any(self.saved_at < point <= steps for point in self.save_points):
            self.save(group)

    def save(self, group: Any) -> None:
        """Write the group's state file (overwriting the last)."""
        self.saved_at = group.num_timesteps
        runs = [
            {
                "pending": list(checkpoint.pending),
                "saved": [(steps, str(path)) for steps, path in checkpoint.saved],
                "curve": [],
            }
            for checkpoint in self.checkpoints
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


# ----- a group, and a sweep of groups -----


def train_group(
    configs: Sequence[RunConfig],
    results_dir: str | os.PathLike[str],
    device: str = "auto",
    verbose: int = 1,
    on_save: Callable[[int], None] | None = None,
) -> list[dict[str, Any]]:
    """
    Train a group's runs together (resuming from its state file when there is one for them) and evaluate each,
    writing every run's directory as :func:`~sb3_maddpg.experiments.runner.execute_run` does. A run whose training
    is over (its :data:`TRAINED_FILE`: e.g. the process was killed while the group's runs were evaluated) is
    evaluated only, not trained again.

    :param configs: The runs: one setting and scheme, different seeds (see :func:`plan_groups`).
    :param results_dir: The sweep's results directory.
    :param device: Where the group trains (``"auto"``: CUDA when there is a GPU).
    :param verbose: 1 to print the group's progress lines.
    :param on_save: Called with the env steps of each state saved during training (e.g. a test raises there, to
        simulate a process killed right after a save).
    :return: Each run's summary, plus ``"files"`` (as ``execute_run``'s).
    """
    directories = [run_directory(results_dir, config) for config in configs]
    trained = [read_trained(directory, config, verbose >= 1) for config, directory in zip(configs, directories)]
    untrained = [config for config, record in zip(configs, trained) if record is None]
    if untrained:
        fresh = iter(_train_runs(untrained, results_dir, device, verbose, on_save))
        trained = [record if record is not None else next(fresh) for record in trained]
    results = []
    for config, directory, record in zip(configs, directories, trained):
        assert record is not None
        saved, train_time = record
        log_path = str(directory / LOG_FILE)

        def log(line: str, path: str = log_path) -> None:  # the run's own train.log
            log_line(line, path, verbose >= 1)

        # Its checkpoints are deleted below, after its done marker: killed before, the run is evaluated again.
        keep = dataclasses.replace(config, keep_checkpoints=True)
        results.append(finish_run(keep, directory, saved, time.perf_counter() - train_time, train_time, log))
        if not config.keep_checkpoints:
            shutil.rmtree(directory / CHECKPOINT_DIR, ignore_errors=True)
        (directory / TRAINED_FILE).unlink(missing_ok=True)
    return results


def _train_runs(
    configs: Sequence[RunConfig],
    results_dir: str | os.PathLike[str],
    device: str,
    verbose: int,
    on_save: Callable[[int], None] | None,
) -> list[tuple[list[tuple[int, Path]], float]]:
    """
    Train runs together, to their budget (see :func:`train_group`), and record each as trained (:func:`write_trained`).

    :return: Each run's checkpoints, ``(env steps, model file)`` in order, and train time.
    """
    from sb3_maddpg.run_group import GroupCallback, RunGroup

    directories = [run_directory(results_dir, config) for config in configs]
    state_path = group_state_path(results_dir, configs)
    discarded: list[str] = []
    resumed = load_state(state_path, configs, results_dir, discarded.append)
    old_rows: list[list[dict[str, Any]]] = [[] for _ in configs]
    if resumed is None:
        remove_stale_states(results_dir, configs)
        for config, directory in zip(configs, directories):
            start_run_directory(config, directory)
            for line in discarded:  # why, in the run's new train.log (and once on stdout)
                log_line(f"{config.run_id}: {line}", str(directory / LOG_FILE), echo=False)
        if discarded and verbose >= 1:
            print(f"{configs[0].experiment}/{configs[0].scheme}: {discarded[0]}", flush=True)
    else:
        steps = int(resumed["group"]["num_timesteps"])
        old_rows = [read_progress_rows(directory / PROGRESS_FILE, steps) for directory in directories]
    models = [build_model(config, device="cpu") for config in configs]  # on the CPU: they are saved and evaluated
    for model, directory, rows in zip(models, directories, old_rows):
        model.set_logger(configure(str(directory), ["csv"]))
        for row in rows:  # a resumed run's progress.csv keeps its rows up to the state
            for key, value in row.items():
                model.logger.record(key, value)
            model.logger.dump(int(row.get("time/total_timesteps", 0)))
    resolved = resolve_device(device)
    group = RunGroup(models, device=resolved)
    if resumed is not None:
        group.load_state_dict(resumed["group"])
    recorder = GroupRecorder(configs, models, group, results_dir, state_path, echo=verbose >= 1)

    class Hooks(GroupCallback):
        def on_step(self, group: RunGroup) -> None:
            recorder.on_step(group)

        def on_round_end(self, group: RunGroup) -> None:
            saved_at = recorder.saved_at
            recorder.on_round_end(group)
            if on_save is not None and recorder.saved_at != saved_at:
                on_save(recorder.saved_at)

    try:
        if resumed is None:
            for config, directory in zip(configs, directories):
                log_line(
                    f"{training_line(config)}, in a run group of {len(configs)} on {resolved}",
                    str(directory / LOG_FILE),
                    False,
                )
        recorder.start(resumed)
        group.learn(max(0, recorder.total - group.num_timesteps), callback=Hooks())
        train_time = recorder.train_time
    finally:
        recorder.close()
    # Each run's record, then the state goes: a crash while the runs are evaluated evaluates them again, whatever
    # group the next attempt puts them in.
    trained = [(list(checkpoint.saved), train_time) for checkpoint in recorder.checkpoints]
    for config, directory, (saved, _) in zip(configs, directories, trained):
        write_trained(directory, config, saved, train_time)
    state_path.unlink(missing_ok=True)
    return trained


def run_batched(
    configs: Sequence[RunConfig],
    results_dir: str,
    on_result: OnResult,
    device: str = "auto",
    runs_per_process: int | None = None,
    threads: int = 1,
    verbose: int = 1,
    most_runs: Callable[[Sequence[RunConfig]], int] | None = None,
) -> None:
    """
    Run the sweep's runs in groups (:func:`plan_groups`), one group after another in this process; a group that
    fails fails its runs (each reported with the traceback) and the sweep goes on.

    :param configs: The runs (checked with :func:`check_batched`).
    :param results_dir: The sweep's results directory.
    :param on_result: Called for each run as its group ends.
    :param device: Where the groups train.
    :param runs_per_process: The most runs in one group (``None``: all of a setting and scheme, or as many as fit
        in the device's memory, :func:`memory_bound`).
    :param threads: Torch threads.
    :param verbose: 1 to print each group's progress lines.
    :param most_runs: For :func:`plan_groups` when ``runs_per_process`` is ``None`` (default: :func:`memory_bound` on
        ``device``, saying a split on stdout).
    """
    th.set_num_threads(threads)
    if runs_per_process is None and most_runs is None:
        most_runs = memory_bound(device, log=print if verbose else None)
    for group in plan_groups(configs, runs_per_process, most_runs):
        try:
            results = train_group(group, results_dir, device=device, verbose=verbose)
        except Exception:
            error = traceback.format_exc()
            for config in group:
                on_result(config, None, error)
        else:
            for config, result in zip(group, results):
                on_result(config, result, None)


def run_batched_ray(
    configs: Sequence[RunConfig],
    results_dir: str,
    on_result: OnResult,
    device: str = "auto",
    runs_per_process: int | None = None,
    threads: int = 1,
    address: str | None = None,
    num_cpus: int | None = None,
    verbose: int = 1,
    on_parallel: Callable[[int, str], None] | None = None,
) -> None:
    """
    Run the sweep's groups (:func:`plan_groups`) as Ray tasks, one task per group: on a CUDA device each asks Ray
    for one GPU (so each GPU of a cluster trains one group at a time), else for ``threads`` CPUs. Ray is reached as
    by :func:`~sb3_maddpg.experiments.backends.run_ray` (``address``, or a local instance), and its tasks are
    collected by the same code: a group lost with its worker or node is run again, up to
    :data:`~sb3_maddpg.experiments.backends.RAY_MAX_RETRIES` times, and resumes from its state file when it sees
    it (the results directory shared by the nodes); a group's runs are reported when the group ends.

    :param configs: The runs (checked with :func:`check_batched` before: this submits them as they are).
    :param results_dir: The sweep's results directory (on a cluster, an absolute path on shared storage).
    :param on_result: Called for each run as its group ends.
    :param device: Where the groups train: ``"cuda"`` (each task on the GPU Ray gives it), ``"cpu"``, or ``"auto"``
        (CUDA when the cluster has GPUs).
    :param runs_per_process: The most runs in one group (``None``: all of a setting and scheme).
    :param threads: Torch threads (and Ray CPUs) per group.
    :param address: The Ray cluster's address, or ``None`` to start a local instance.
    :param num_cpus: CPUs of a local instance (``None``: all of this machine's).
    :param verbose: 1 to print each group's progress lines (Ray forwards the workers' output).
    :param on_parallel: Called once Ray is up with the groups that train at once and the device they train on.
    :raise BatchedRunRefused: For a CUDA device on a cluster without GPUs (its tasks would wait forever), before any
        task.
    """
    groups = plan_groups(configs, runs_per_process)
    with ray_session(address, num_cpus, verbose) as ray:
        resources = ray.cluster_resources()
        gpus = resources.get("GPU", 0)
        if device == "auto":
            device = "cuda" if gpus > 0 else "cpu"
        elif device.split(":")[0] == "cuda":
            if gpus < 1:
                raise BatchedRunRefused(
                    f"The run groups cannot train on {device} under Ray: the Ray cluster has no GPU, so a task asking "
                    "for one would wait forever. Use --device cpu (or auto), or a cluster with GPU nodes."
                )
            device = "cuda"  # Ray picks each task's GPU (its CUDA_VISIBLE_DEVICES): "cuda:1" would name another
        options = ray_task_options(threads, device)
        if on_parallel is not None:
            on_parallel(ray_parallel_tasks(resources, options), device)
        remote = ray.remote(**options)(_ray_group_task)
        tasks = {remote.remote(group, results_dir, device, threads, verbose): group for group in groups}
        collect_ray_tasks(ray, tasks, results_dir, on_result)


def _ray_group_task(
    configs: Sequence[RunConfig], results_dir: str, device: str, threads: int, verbose: int
) -> list[dict[str, Any]]:
    set_worker_threads(threads)
    return train_group(configs, results_dir, device=device, verbose=verbose)
