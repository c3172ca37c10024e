"""One run of the protocol: train, save checkpoints over the last 20%, evaluate each, write the run directory."""

import copy
import math
import os
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.logger import configure
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from sb3_maddpg.analysis.behaviour import team_behaviour
from sb3_maddpg.analysis.evaluation import (
    TeamEvalCallback,
    side_return_label,
    side_returns,
    write_rows,
)
from sb3_maddpg.common.progress import ProgressLogCallback, format_seconds
from sb3_maddpg.compat import with_version
from sb3_maddpg.experiments.config import PAPER_NAMES, load_algorithm
from sb3_maddpg.experiments.results_dir import (
    CHECKPOINT_DIR,
    CHECKPOINT_EVALS_FILE,
    CONFIG_FILE,
    CURVE_FILE,
    LOG_FILE,
    PROGRESS_FILE,
    SUMMARY_FILE,
    collect_result,
    is_finished,
    mark_done,
    run_directory,
    write_json_atomic,
)
from sb3_maddpg.experiments.run_snapshot import (
    NO_SNAPSHOT,
    RunProgress,
    SnapshotCallback,
    load_snapshot,
    read_progress_rows,
    remove_snapshot,
    restore_logger_values,
    snapshot_steps,
)
from sb3_maddpg.experiments.setting import RunConfig
from sb3_maddpg.experiments.tasks import RunTask, metric_record, run_task
from sb3_maddpg.experiments.training_resources import TrainingResources
from sb3_maddpg.sharing.registry import resolve_scheme


def statistics_path(model_path: str | os.PathLike[str]) -> Path:
    """:return: Where a checkpoint's observation statistics are saved: ``model_<steps>_steps.vecnormalize.pkl``."""
    return Path(model_path).with_suffix(".vecnormalize.pkl")


def load_observation_statistics(eval_env: VecEnv, model_path: str | os.PathLike[str]) -> None:
    """
    Give an evaluation env (:meth:`~sb3_maddpg.experiments.tasks.RunTask.make_eval_env`'s, with
    ``normalize_observations``) a checkpoint's observation statistics, so that the checkpoint is evaluated on the
    observations it was trained on.

    :param eval_env: The evaluation env (a ``VecNormalize``).
    :param model_path: The checkpoint's model file (its statistics beside it, :func:`statistics_path`).
    """
    if not isinstance(eval_env, VecNormalize):
        raise TypeError(
            "The evaluation env has no VecNormalize: build it with run_task(config).make_eval_env for a normalising run."
        )
    path = statistics_path(model_path)
    if not path.exists():
        raise FileNotFoundError(
            f"{path} is missing: a run that normalises observations saves them beside each checkpoint; train the run "
            "again (its directory is incomplete)."
        )
    eval_env.obs_rms = copy.deepcopy(VecNormalize.load(str(path), eval_env.venv).obs_rms)


class NormalizedObservationPolicy:
    """
    A model that acts on raw observations: each is normalised by an evaluation env's statistics first (for
    :func:`~sb3_maddpg.analysis.behaviour.team_behaviour`, which reads positions from the raw observations).

    :param model: The model (trained on normalised observations).
    :param normalization: The ``VecNormalize`` whose statistics normalise the observations.
    """

    def __init__(self, model: Any, normalization: VecNormalize) -> None:
        self.model = model
        self.normalization = normalization

    def predict(self, observation: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        """
        :param observation: Raw observations.
        :param deterministic: Passed on.
        :return: The model's actions for them, normalised.
        """
        actions, _ = self.model.predict(self.normalization.normalize_obs(observation), deterministic=deterministic)
        return actions, None


class CheckpointAtSteps(BaseCallback):
    """
    Save the model when training reaches given env steps (``<save_dir>/model_<steps>_steps.zip``).

    :param steps: The env steps (``model.num_timesteps``) to save at.
    :param save_dir: The directory of the model files.
    :param saved: The checkpoints an earlier attempt saved, ``(env steps, model file)`` (a resumed run): the steps up
        to the last of them are not saved again.
    """

    def __init__(
        self, steps: list[int], save_dir: str | os.PathLike[str], saved: list[tuple[int, Path]] | None = None
    ) -> None:
        super().__init__()
        self.saved: list[tuple[int, Path]] = list(saved or [])
        reached = max((step for step, _ in self.saved), default=-1)
        self.pending = sorted(step for step in set(steps) if step > reached)
        self.save_dir = Path(save_dir)

    def _on_step(self) -> bool:
        while self.pending and self.num_timesteps >= self.pending[0]:
            self.pending.pop(0)
            path = self.save_dir / f"model_{self.num_timesteps}_steps.zip"
            self.save_dir.mkdir(parents=True, exist_ok=True)
            self.model.save(path)
            normalization = self.model.get_vec_normalize_env()
            if normalization is not None:  # the checkpoint acts on observations normalised by these statistics
                normalization.save(str(statistics_path(path)))
            self.saved.append((self.num_timesteps, path))
        return True


def final_behaviour(task: RunTask, model: Any, eval_env: VecEnv) -> dict[str, float] | None:
    """
    :param task: The run's task (:func:`~sb3_maddpg.experiments.tasks.run_task`).
    :param model: Its last checkpoint.
    :param eval_env: Its evaluation env.
    :return: What the team does at its episodes' end (:func:`~sb3_maddpg.analysis.behaviour.team_behaviour`, over
        ``eval_episodes`` episodes), for simple_spread runs that observe every landmark; else ``None``.
    """
    if not task.scores_behaviour:
        return None
    if isinstance(eval_env, VecNormalize):  # the behaviour reads positions from raw observations
        model, eval_env = NormalizedObservationPolicy(model, eval_env), eval_env.venv
    return team_behaviour(model, eval_env, n_episodes=task.config.eval_episodes, seed=task.eval_seed)


def execute_run(
    config: RunConfig,
    results_dir: str | os.PathLike[str],
    threads: int | None = 1,
    verbose: int = 1,
    snapshots: bool = True,
    device: str = "auto",
) -> dict[str, Any]:
    """
    Train one run and evaluate it, writing its directory; a finished run is not repeated, an interrupted one goes on
    from its last snapshot (each tenth of its budget, see :mod:`~sb3_maddpg.experiments.run_snapshot`: the same
    files as an uninterrupted run), or starts again from scratch when it has none.

    The directory holds ``config.json``, ``progress.csv`` (SB3's training log), ``train.log`` (progress
    lines), ``learning_curve.csv`` (team evaluations during training), ``checkpoint_evals.csv`` (one
    evaluation of ``eval_episodes`` episodes per checkpoint), ``summary.json`` (the run's score: each
    metric's mean over the checkpoints, timings and, for simple_spread, ``behaviour``: what the last checkpoint's
    team does at its episodes' end, see :mod:`sb3_maddpg.analysis.behaviour`), ``checkpoints/`` (model files, unless
    ``keep_checkpoints`` is off) and the ``done`` marker, written last; ``resume/`` (the snapshot) while it trains.

    :param config: The run.
    :param results_dir: The sweep's results directory.
    :param threads: ``torch.set_num_threads`` for this run (``None`` leaves it), so parallel workers don't fight.
    :param verbose: 1 to print progress lines.
    :param snapshots: Save a snapshot at each tenth of the budget (``False``: a killed run starts again from
        scratch; a snapshot left by an earlier attempt is still used).
    :param device: Where the run trains (SB3's ``device``; ``"auto"``: CUDA when there is a GPU); a ``device`` in the
        config's ``model_kwargs`` comes first.
    :return: The summary, plus ``"files"``: the text of the small result files, so that a remote worker's
        results can be written on the machine that collects them (see :func:`write_result_files`).
    """
    directory = run_directory(results_dir, config)
    if is_finished(results_dir, config):
        return collect_result(directory)
    if threads is not None:
        import torch as th

        th.set_num_threads(threads)

    started = time.perf_counter()
    task = run_task(config)  # derived once, here, and handed on: the run's helpers take its task
    model, before, pending_logs, why_not = resume_or_start(task, directory, device)
    model.set_logger(configure(str(directory), ["csv"]))
    restore_logger_values(model, pending_logs)
    progress = ProgressLogCallback(
        config.run_id, config.total_timesteps, str(directory / LOG_FILE), echo=verbose >= 1, sides=task.sides
    )
    saved = [(steps, directory / CHECKPOINT_DIR / name) for steps, name in before.checkpoints]
    checkpoints = CheckpointAtSteps(list(task.checkpoint_steps), directory / CHECKPOINT_DIR, saved)
    callbacks: list[BaseCallback] = [checkpoints, progress]
    curve_env = task.make_eval_env(config.curve_eval_episodes)
    curve = curve_callback(task, curve_env, model.get_env().num_envs, directory)  # type: ignore[union-attr]
    if curve is not None:
        resume_curve(curve, model, before.curve)
        callbacks.append(curve)
    if snapshots:

        def so_far() -> RunProgress:
            rows = before.progress_rows + read_progress_rows(directory / PROGRESS_FILE)
            curve_rows = list(curve.history) if curve is not None else []
            run_time = before.train_time_s + time.perf_counter() - started
            return RunProgress(config.to_dict(), run_time, rows, curve_rows, [(s, p.name) for s, p in checkpoints.saved])

        def on_save(steps: int) -> None:
            progress.log(f"{config.run_id}: snapshot at {steps:,} steps")

        def say(line: str) -> None:
            progress.log(f"{config.run_id}: {line}")

        callbacks.append(SnapshotCallback(snapshot_steps(config.total_timesteps), directory, so_far, on_save, say))
    if why_not not in ("", NO_SNAPSHOT):
        progress.log(f"{config.run_id}: starting afresh: {why_not}")
    progress.log(training_line(task) if model.num_timesteps == 0 else resumed_line(config, model.num_timesteps))
    model.learn(
        config.total_timesteps - model.num_timesteps,
        callback=CallbackList(callbacks),
        log_interval=log_interval(config),
        reset_num_timesteps=model.num_timesteps == 0,
    )
    train_time = before.train_time_s + time.perf_counter() - started
    if before.progress_rows:  # this attempt's logger started progress.csv again: the earlier rows go first
        write_rows(str(directory / PROGRESS_FILE), [*before.progress_rows, *read_progress_rows(directory / PROGRESS_FILE)])
    resources = TrainingResources.here(model.device.type)
    model.get_env().close()  # type: ignore[union-attr]
    del model

    curve_env.close()
    return finish_run(task, directory, checkpoints.saved, started - before.train_time_s, train_time, progress.log, resources)


def resume_or_start(
    task: RunTask, directory: Path, device: str = "auto"
) -> tuple[Any, RunProgress, list[dict[str, Any]], str]:
    """
    :param task: The run's task.
    :param directory: Its directory.
    :param device: Where the model trains (see :func:`execute_run`).
    :return: The model to train (the snapshot's, or a new one in a directory started afresh), what the run had
        written by then, the logger's pending values then, and why no snapshot was used (``""`` when one was).
    """
    config = task.config
    device = config.model_kwargs.get("device", device)
    # The snapshot's state goes onto a new model of the config (never SB3's load, which unpickles).
    resumed = load_snapshot(directory, config.to_dict(), lambda: build_model(task, device=device))
    if isinstance(resumed, str):
        start_run_directory(config, directory)
        return build_model(task, device=device), RunProgress(config.to_dict()), [], resumed
    model, state = resumed
    return model, state["progress"], state["logger"], ""


def resume_curve(curve: TeamEvalCallback, model: Any, history: list[dict[str, float]]) -> None:
    """
    Bring a new learning-curve callback to where a resumed run's was: its evaluations so far, and its calls counted
    so that the next evaluation falls where it would have (the calls are replayed, never evaluating).

    :param curve: The new callback.
    :param model: The resumed model.
    :param history: The evaluations so far.
    """
    if model.num_timesteps == 0:
        return
    curve.init_callback(model)
    curve.history.extend(history)  # its public record, which its CSV file is rewritten from at each evaluation
    if curve.log_path is not None:  # the killed attempt may have written evaluations past the snapshot
        write_rows(curve.log_path, curve.history)
    for _ in range((model.num_timesteps // model.get_env().num_envs) % curve.eval_freq):
        curve.on_step()


def resumed_line(config: RunConfig, steps: int) -> str:
    """:return: A resumed run's first progress line."""
    return f"{config.run_id}: resumed from its snapshot at {steps:,} of {config.total_timesteps:,} steps"


def start_run_directory(config: RunConfig, directory: Path) -> None:
    """
    Start a run's directory afresh: anything an interrupted attempt left is removed, then ``config.json`` is written
    (with the version that wrote it: :func:`~sb3_maddpg.compat.with_version`).

    :param config: The run.
    :param directory: Its directory.
    """
    if directory.exists():
        shutil.rmtree(directory)
    directory.mkdir(parents=True)
    write_json_atomic(directory / CONFIG_FILE, with_version(config.to_dict()))


def build_model(task: RunTask, **kwargs: Any) -> Any:
    """
    :param task: The run's task (:func:`~sb3_maddpg.experiments.tasks.run_task`).
    :param kwargs: More keyword arguments for the algorithm (e.g. ``device``), under the config's ``model_kwargs``.
    :return: The run's untrained model, on a new training env
        (:meth:`~sb3_maddpg.experiments.tasks.RunTask.make_train_env`). Its ``critic_sharing`` is the run's scheme,
        unless its ``model_kwargs`` name one: a variant of a scheme compared beside it in one study (e.g. scheme
        ``"selected_next"`` with ``{"critic_sharing": "selected", "selector": {"k": 2, "target": "next"}}``).
    """
    if not isinstance(task, RunTask):
        raise TypeError(f"build_model takes a run's task, got a {type(task).__name__}: build_model(run_task(config)).")
    config = task.config
    algorithm: Any = load_algorithm(config.algorithm)
    # A deep copy: algorithms may write into their kwargs (e.g. policy_kwargs), and the config must stay as it was.
    options = {**kwargs, **copy.deepcopy(config.model_kwargs), "critic_sharing": run_critic_sharing(config)}
    return algorithm("MlpPolicy", task.make_train_env(), seed=config.seed, **options)


def run_critic_sharing(config: RunConfig) -> Any:
    """
    :param config: The run.
    :return: Its ``critic_sharing``: its ``model_kwargs``'s when they name one (a variant of a scheme), else its scheme;
        a ``ValueError`` that says how to name a variant's when the scheme is no scheme and names none.
    """
    if "critic_sharing" in config.model_kwargs:
        return config.model_kwargs["critic_sharing"]
    try:
        resolve_scheme(config.scheme)
    except ValueError as error:
        raise ValueError(
            f"{error} For a variant of a scheme under a name of its own, give its critic_sharing in the experiment's "
            f'scheme_model_kwargs, e.g. {{"{config.scheme}": {{"critic_sharing": "selected", "selector": {{"k": 2, '
            f'"target": "next"}}}}}}.'
        ) from None
    return config.scheme


def curve_callback(task: RunTask, curve_env: VecEnv, n_envs: int, directory: Path) -> TeamEvalCallback | None:
    """
    :param task: The run's task.
    :param curve_env: Its learning-curve evaluation env.
    :param n_envs: Its training env's worlds (the callback is called once per step of them all).
    :param directory: Its directory.
    :return: The callback that writes its learning curve, or ``None`` when it has none (``curve_points=0``).
    """
    if task.curve_interval == 0:
        return None
    return TeamEvalCallback(
        curve_env,
        eval_freq=max(1, task.curve_interval // n_envs),
        n_eval_episodes=task.config.curve_eval_episodes,
        seed=task.eval_seed,
        log_path=str(directory / CURVE_FILE),
        eval_at_start=True,
        task_metrics=task.metrics,
        score_agents=task.config.score_agents,
        sides=task.sides,
    )


def training_line(task: RunTask) -> str:
    """:return: A run's first progress line: its budget and its task."""
    config = task.config
    budget = f"{config.total_timesteps:,} steps ({config.episodes:,} episodes)"
    return f"{config.run_id}: training {budget} on {task.description}"


def log_interval(config: RunConfig) -> int:
    """:return: The episodes between two rows of a run's ``progress.csv`` (about 100 rows per run)."""
    return max(1, config.episodes // 100)


def finish_run(
    task: RunTask,
    directory: Path,
    saved: list[tuple[int, Path]],
    started: float,
    train_time: float,
    log: Callable[[str], None],
    resources: TrainingResources | None = None,
) -> dict[str, Any]:
    """
    Evaluate a trained run's checkpoints and write the rest of its directory: ``checkpoint_evals.csv``,
    ``summary.json`` and the ``done`` marker, last, once its snapshot is removed.

    :param task: The run's task.
    :param directory: Its directory.
    :param saved: Its checkpoints, ``(env steps, model file)`` in order.
    :param started: When it started (``time.perf_counter()``).
    :param train_time: Its training's wall time, seconds.
    :param log: Where its last progress line goes.
    :param resources: What trained it (recorded in the summary for the report's cost table); ``None``: not recorded.
    :return: The summary, plus ``"files"`` (see :func:`execute_run`).
    """
    config = task.config
    eval_started = time.perf_counter()
    rows, last = evaluate_checkpoints(task, saved)
    write_rows(str(directory / CHECKPOINT_EVALS_FILE), rows)
    eval_time = time.perf_counter() - eval_started
    if not config.keep_checkpoints:
        shutil.rmtree(directory / CHECKPOINT_DIR, ignore_errors=True)

    summary = run_summary(task, rows, last, train_time, eval_time, time.perf_counter() - started, resources)
    write_json_atomic(directory / SUMMARY_FILE, summary)
    log(
        f"{config.run_id}: done in {format_seconds(summary['wall_time_s'])} "
        f"({summary['train_steps_per_s']:,.0f} steps/s), score: {score_line(summary['score'])}"
        + (f"; {never_updated_line(last.get('learning_starts'))}" if last.get("n_updates") == 0 else "")
    )
    remove_snapshot(directory)  # before the marker: a done run is never resumed, and returns as soon as it is marked
    mark_done(directory)
    return collect_result(directory)


def evaluate_checkpoints(task: RunTask, saved: list[tuple[int, Path]]) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """
    :param task: The run's task.
    :param saved: Its checkpoints, ``(env steps, model file)`` in order.
    :return: One row per checkpoint (its steps, episodes and the task's scores: ``checkpoint_evals.csv``), and what
        the last checkpoint tells (empty without checkpoints): its ``n_updates``, ``learning_starts`` and, where the
        task scores it, its ``behaviour``.
    """
    config = task.config
    algorithm: Any = load_algorithm(config.algorithm)
    eval_env = task.make_eval_env(config.eval_episodes)
    rows = []
    for steps, path in saved:
        checkpoint = algorithm.load(path, device="cpu")
        if config.normalize_observations:
            load_observation_statistics(eval_env, path)
        result = task.evaluate(checkpoint, eval_env)
        rows.append({"timesteps": steps, "episodes": steps // config.episode_length, **{k: result[k] for k in task.keys}})
    last: dict[str, Any] = {}
    if saved:
        # The last checkpoint's gradient updates (a run group writes its count back into each model it saves).
        last = {"n_updates": int(checkpoint._n_updates), "learning_starts": int(getattr(checkpoint, "learning_starts", 0))}
        last["behaviour"] = final_behaviour(task, checkpoint, eval_env)
    eval_env.close()
    return rows, last


def run_summary(
    task: RunTask,
    rows: list[dict[str, Any]],
    last: dict[str, Any],
    train_time: float,
    eval_time: float,
    wall_time: float,
    resources: TrainingResources | None = None,
) -> dict[str, Any]:
    """
    :param task: The run's task.
    :param rows: Its checkpoints' evaluations (:func:`evaluate_checkpoints`).
    :param last: What its last checkpoint tells (:func:`evaluate_checkpoints`).
    :param train_time: Its training's wall time, seconds.
    :param eval_time: Its evaluation's wall time, seconds.
    :param wall_time: Its whole wall time, seconds.
    :param resources: What trained it: ``device``, ``torch_threads`` and ``runs_trained_together`` go into the summary
        (the report's cost table reads them); ``None`` leaves them out.
    :return: Its ``summary.json``: the score (each of the task's scores' mean over the checkpoints), the task metrics
        its env declares (``task_metrics``, :func:`~sb3_maddpg.experiments.tasks.metric_record`'s), timings, what
        trained it, and the last checkpoint's ``n_updates`` and ``behaviour`` where known.
    """
    config = task.config
    summary: dict[str, Any] = {
        "run_id": config.run_id,
        "experiment": config.experiment,
        "scheme": config.scheme,
        "method": PAPER_NAMES.get(config.scheme, config.scheme),
        "seed": config.seed,
        "score": {key: sum(row[key] for row in rows) / len(rows) for key in task.keys},
        # What the task's env declares, so that a report labels and directs its metrics without building the env.
        "task_metrics": [metric_record(metric) for metric in task.metrics],
        "n_checkpoints": len(rows),
        "total_timesteps": config.total_timesteps,
        "train_time_s": round(train_time, 2),
        "eval_time_s": round(eval_time, 2),
        "wall_time_s": round(wall_time, 2),
        "train_steps_per_s": round(config.total_timesteps / train_time, 1),
    }
    if resources is not None:
        summary.update(resources.to_summary())
    if "n_updates" in last:
        summary["n_updates"] = last["n_updates"]
    if last.get("behaviour") is not None:
        summary["behaviour"] = last["behaviour"]
    return summary


def score_line(score: dict[str, float]) -> str:
    """
    :param score: A run's score.
    :return: Its headline in a few words: simple_spread's success and coverage, or else each side's return in a
        competitive task, or else the team return.
    """
    if not math.isnan(score.get("success_rate", math.nan)):  # a simple_spread run
        return f"success {100 * score['success_rate']:.1f}%, coverage {100 * score['coverage']:.1f}%"
    sides = side_returns(score)
    if sides:
        return ", ".join(f"{side_return_label(side)} {value:.1f}" for side, value in sides.items())
    return f"team return {score['return_mean']:.1f}"


def never_updated_line(learning_starts: int | None = None) -> str:
    """
    :param learning_starts: The run's ``learning_starts``, if known.
    :return: The warning for a run that took no gradient update, for its progress line and the sweep log.
    """
    starts = f"learning_starts={learning_starts:,}" if learning_starts else "learning_starts"
    return (
        f"WARNING: never updated (0 gradient steps: the budget ended before {starts}), so its score is an untrained "
        "team's; train for longer or lower learning_starts"
    )
