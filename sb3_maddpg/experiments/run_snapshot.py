"""A run's training state, saved at each tenth of its budget so that a killed run resumes where it was, exactly.

A sweep's run used to start again from scratch when its process was killed (a machine's session ending, a lost
worker): an hour of an N=5 run lost at each interruption. At 10%, 20%, ..., 90% of its budget a run on the batched
simple_spread env now writes its whole training state to ``<run>/resume/``: the model as SB3 saves it (weights,
Adam's moments, counters, the last observations, the exploration noise, the update schedule's credit), its replay
buffer, the random streams of Python, NumPy, PyTorch and the action space, the env's worlds and their own random
stream, the per-agent episode returns, the logger's pending values, the ``progress.csv`` rows, the learning curve and
the checkpoints so far. It is taken at the start of a rollout, where the previous rollout's updates are done, so that
``learn(reset_num_timesteps=False)`` goes on from it as the uninterrupted ``learn`` would: the resumed run's files are
those of an uninterrupted run, bit for bit on the CPU (timings aside; ``tests/experiments/test_run_snapshot.py``). The
directory is replaced whole (written beside it, then renamed) and removed when the run is done; a snapshot of another
config, of other versions, or not whole is not used.
"""

import csv
import os
import pickle
import random
import shutil
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import stable_baselines3
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from sb3_maddpg.envs.simple_spread_vec_env import SimpleSpreadVecEnv
from sb3_maddpg.version import __version__

SNAPSHOT_DIR = "resume"
"""A run's snapshot directory, inside the run's directory."""

SNAPSHOTS_PER_RUN = 10
"""A snapshot at each ``1 / SNAPSHOTS_PER_RUN`` of the budget (the last one at 90%)."""

MODEL_FILE, BUFFER_FILE, STATE_FILE = "model.zip", "replay_buffer.pkl", "state.pkl"

NO_SNAPSHOT = "no snapshot"

UNREADABLE = (pickle.UnpicklingError, EOFError, zipfile.BadZipFile, KeyError, AttributeError, ValueError)
"""Errors that say a snapshot's files are not whole or not of this code (the run starts afresh); any other error while
loading one (e.g. out of memory) fails the run and keeps the snapshot for the next attempt."""
"""What :func:`load_snapshot` says when a run has none (a first attempt, or one killed before its first)."""


@dataclass
class RunProgress:
    """
    What a run has written by a snapshot, besides the model's training state.

    :param config: The run's config (``RunConfig.to_dict()``): a snapshot of another config is not used.
    :param train_time_s: Training time so far, over every attempt, in seconds.
    :param progress_rows: ``progress.csv``'s rows so far (SB3's logger starts the file again in a resumed attempt).
    :param curve: The learning curve's evaluations so far (``TeamEvalCallback.history``).
    :param checkpoints: The checkpoints saved so far: ``(env steps, model file name)``.
    """

    config: dict[str, Any]
    train_time_s: float = 0.0
    progress_rows: list[dict[str, str]] = field(default_factory=list)
    curve: list[dict[str, float]] = field(default_factory=list)
    checkpoints: list[tuple[int, str]] = field(default_factory=list)


def versions() -> dict[str, str]:
    """:return: The versions a snapshot is only resumed under: this package's, SB3's, PyTorch's and NumPy's."""
    return {
        "sb3_maddpg": __version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": th.__version__,
        "numpy": np.__version__,
    }


def can_snapshot(env: VecEnv) -> bool:
    """
    :param env: A run's training env.
    :return: Whether its state can be saved and restored exactly: the batched simple_spread env
        (:class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`, plain arrays and a NumPy generator), possibly wrapped. Envs of
        other objects (mpe2's PettingZoo envs in a ``DummyVecEnv``) pickle but do not come back whole.
    """
    layer = env
    while isinstance(layer, VecEnvWrapper):
        layer = layer.venv
    return isinstance(layer, SimpleSpreadVecEnv)


def snapshot_steps(total_timesteps: int) -> list[int]:
    """
    :param total_timesteps: The run's budget.
    :return: The env steps at which it is snapshotted: each tenth of the budget, the end excluded.
    """
    return sorted({total_timesteps * k // SNAPSHOTS_PER_RUN for k in range(1, SNAPSHOTS_PER_RUN)} - {0})


def env_layers(env: VecEnv) -> list[dict[str, Any]]:
    """
    :param env: A training env: a ``VecEnv``, possibly wrapped (``VecMonitor``, ``VecNormalize``).
    :return: Each layer's attributes, outermost first, without the wrapped env and the class's attributes (which
        do not pickle): the state that a new env of the same construction takes back with :func:`restore_env_layers`.
    """
    layers, layer = [], env
    while True:
        layers.append({key: value for key, value in vars(layer).items() if key not in ("venv", "class_attributes")})
        if not isinstance(layer, VecEnvWrapper):
            return layers
        layer = layer.venv


def restore_env_layers(env: VecEnv, layers: list[dict[str, Any]]) -> None:
    """
    :param env: A new env, built as the saved one was.
    :param layers: From :func:`env_layers`.
    """
    layer: Any = env
    for attributes in layers:
        layer.__dict__.update(attributes)
        layer = getattr(layer, "venv", None)


def random_state() -> dict[str, Any]:
    """:return: The random streams of Python, NumPy (global) and PyTorch (CPU, and CUDA's when present)."""
    state = {"python": random.getstate(), "numpy": np.random.get_state(), "torch": th.get_rng_state()}
    if th.cuda.is_available():
        state["cuda"] = th.cuda.get_rng_state_all()
    return state


def set_random_state(state: dict[str, Any]) -> None:
    """:param state: From :func:`random_state`."""
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    th.set_rng_state(state["torch"])
    if "cuda" in state and th.cuda.is_available():
        th.cuda.set_rng_state_all(state["cuda"])


def read_progress_rows(path: str | os.PathLike[str]) -> list[dict[str, str]]:
    """
    :param path: A ``progress.csv``.
    :return: Its rows (none if there is no file).
    """
    if not os.path.isfile(path):
        return []
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def write_progress_rows(path: str | os.PathLike[str], rows: list[dict[str, str]]) -> None:
    """
    :param path: The ``progress.csv`` to write.
    :param rows: Its rows, over every attempt; the columns are every key, in the order first seen.
    """
    columns = list(dict.fromkeys(key for row in rows for key in row))
    tmp_path = f"{path}.tmp"
    with open(tmp_path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp_path, path)


def save_snapshot(run_dir: str | os.PathLike[str], model: BaseAlgorithm, progress: RunProgress) -> Path:
    """
    Write the run's snapshot beside the last one, then put it in its place.

    :param run_dir: The run's directory.
    :param model: The model, between two rollouts.
    :param progress: What the run has written so far.
    :return: The snapshot's directory.
    """
    final = Path(run_dir) / SNAPSHOT_DIR
    tmp, old = final.with_name(f"{SNAPSHOT_DIR}.tmp"), final.with_name(f"{SNAPSHOT_DIR}.old")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    model.save(tmp / MODEL_FILE)
    model.save_replay_buffer(tmp / BUFFER_FILE)  # type: ignore[attr-defined]  # off-policy models have one
    logger = model.logger
    state = {
        "progress": progress,
        "versions": versions(),
        "random": random_state(),
        # SB3's load seeds the action space again from the model's seed: random actions before learning_starts
        # come from it, so its stream is restored from here.
        "action_space": model.action_space,
        "env": env_layers(model.get_env()),  # type: ignore[arg-type]
        "agent_episode_returns": getattr(model, "_agent_episode_returns", None),  # not in SB3's save
        "logger": [dict(logger.name_to_value), dict(logger.name_to_count), dict(logger.name_to_excluded)],
    }
    with open(tmp / STATE_FILE, "wb") as file:
        pickle.dump(state, file, protocol=pickle.HIGHEST_PROTOCOL)
    if final.exists():
        final.rename(old)
    tmp.rename(final)
    shutil.rmtree(old, ignore_errors=True)
    return final


def load_snapshot(
    run_dir: str | os.PathLike[str],
    config: dict[str, Any],
    algorithm: type[BaseAlgorithm],
    make_env: Callable[[], VecEnv],
    device: str = "auto",
) -> tuple[BaseAlgorithm, dict[str, Any]] | str:
    """
    Load a run's snapshot: the model on a new env (its worlds restored), its replay buffer, and the random streams.

    :param run_dir: The run's directory.
    :param config: The run's config (``RunConfig.to_dict()``).
    :param algorithm: The run's algorithm class.
    :param make_env: Builds a new training env of the run, as the saved one was built.
    :param device: Where the loaded model trains (SB3's ``device``).
    :return: The model and the rest of the state (``"progress"``: :class:`RunProgress`, ``"logger"``: the logger's
        pending values), or why no snapshot is used (:data:`NO_SNAPSHOT`, another config's, other versions', not
        whole: :data:`UNREADABLE`); any other error (e.g. out of memory) is raised, the snapshot kept.
    """
    directory = Path(run_dir) / SNAPSHOT_DIR
    old = directory.with_name(f"{SNAPSHOT_DIR}.old")
    if not directory.exists() and old.is_dir():  # killed between the two renames of a save: the last whole one
        old.rename(directory)
    for leftover in (directory.with_name(f"{SNAPSHOT_DIR}.tmp"), old):
        shutil.rmtree(leftover, ignore_errors=True)  # a save killed half-way
    if not (directory / STATE_FILE).is_file():
        return NO_SNAPSHOT
    try:
        with open(directory / STATE_FILE, "rb") as file:
            state = pickle.load(file)
    except UNREADABLE as error:
        return f"its snapshot could not be read ({type(error).__name__}: {error})"
    if state["progress"].config != config:
        return "its snapshot is of another config"
    if state.get("versions") != versions():
        return f"its snapshot was saved under other versions ({state.get('versions')}, now {versions()})"
    env = make_env()
    try:
        model = algorithm.load(directory / MODEL_FILE, env=env, device=device, force_reset=False)
        model.load_replay_buffer(directory / BUFFER_FILE)  # type: ignore[attr-defined]
    except UNREADABLE as error:
        env.close()
        return f"its snapshot could not be read ({type(error).__name__}: {error})"
    # After the load, which seeds the env and the spaces from the model's seed: their saved state goes back on top.
    restore_env_layers(model.get_env(), state["env"])  # type: ignore[arg-type]
    model.action_space = state["action_space"]
    if state["agent_episode_returns"] is not None:
        model._agent_episode_returns = state["agent_episode_returns"]  # type: ignore[attr-defined]
    set_random_state(state["random"])  # last: loading the model built networks from the torch stream
    return model, state


def restore_logger_values(model: BaseAlgorithm, values: list[dict[str, Any]]) -> None:
    """
    :param model: A resumed model, with its new logger set.
    :param values: The logger's pending values at the snapshot (``state["logger"]`` of :func:`load_snapshot`).
    """
    if not values:
        return
    value, count, excluded = values
    model.logger.name_to_value.update(value)
    model.logger.name_to_count.update(count)
    model.logger.name_to_excluded.update(excluded)


def remove_snapshot(run_dir: str | os.PathLike[str]) -> None:
    """:param run_dir: A run's directory, whose snapshot is no longer needed (the run is done)."""
    for name in (SNAPSHOT_DIR, f"{SNAPSHOT_DIR}.tmp", f"{SNAPSHOT_DIR}.old"):
        shutil.rmtree(Path(run_dir) / name, ignore_errors=True)


class SnapshotCallback(BaseCallback):
    """
    Save the run's snapshot when training reaches given env steps, at the start of the next rollout (the previous
    rollout's updates done).

    :param steps: The env steps to snapshot at (:func:`snapshot_steps`); those already reached are skipped.
    :param run_dir: The run's directory.
    :param progress: Returns what the run has written so far, when a snapshot is taken.
    :param on_save: Called with each snapshot's env steps (e.g. for a progress line).
    :param log: Where a line goes when no snapshot can be taken (an env that cannot be saved, a failed write).
    """

    def __init__(
        self,
        steps: list[int],
        run_dir: str | os.PathLike[str],
        progress: Callable[[], RunProgress],
        on_save: Callable[[int], None] | None = None,
        log: Callable[[str], None] = print,
    ) -> None:
        super().__init__()
        self.log = log
        self.pending = sorted(steps)
        self.run_dir = Path(run_dir)
        self.progress = progress
        self.on_save = on_save

    def _on_training_start(self) -> None:
        self.pending = [step for step in self.pending if step > self.num_timesteps]
        if self.pending and not can_snapshot(self.model.get_env()):  # type: ignore[arg-type]
            self.log(f"no snapshots: the training env ({type(self.model.get_env()).__name__}) cannot be saved exactly")
            self.pending = []

    def _on_rollout_start(self) -> None:
        if not self.pending or self.model.num_timesteps < self.pending[0]:
            return
        while self.pending and self.model.num_timesteps >= self.pending[0]:
            self.pending.pop(0)
        try:
            save_snapshot(self.run_dir, self.model, self.progress())
        except OSError as error:  # e.g. a full disk: training goes on, the last whole snapshot stays
            shutil.rmtree(self.run_dir / f"{SNAPSHOT_DIR}.tmp", ignore_errors=True)
            self.log(f"snapshot at {self.model.num_timesteps:,} steps not saved ({type(error).__name__}: {error})")
            return
        if self.on_save is not None:
            self.on_save(self.model.num_timesteps)

    def _on_step(self) -> bool:
        return True
