"""A run's training state, saved at each tenth of its budget so that a killed run resumes where it was, exactly.

A sweep's run used to start again from scratch when its process was killed (a machine's session ending, a lost
worker): an hour of an N=5 run lost at each interruption. At 10%, 20%, ..., 90% of its budget a run on the batched
simple_spread env now writes its whole training state to ``<run>/resume/``: the model's networks and optimisers, its
counters, last observations, episode statistics and the update schedule's credit, its replay buffer, the random
streams of Python, NumPy, PyTorch and the action space, the env's worlds and their own random streams, the per-agent
episode returns, the logger's pending values, the ``progress.csv`` rows, the learning curve and the checkpoints so far.
It is taken at the start of a rollout, where the previous rollout's updates are done, so that
``learn(reset_num_timesteps=False)`` goes on from it as the uninterrupted ``learn`` would: the resumed run's files are
those of an uninterrupted run, bit for bit on the CPU (timings aside; ``tests/experiments/test_run_snapshot.py``). The
directory is replaced whole (written beside it, then renamed) and removed when the run is done; a snapshot of another
config, of other versions, or not whole is not used.

A snapshot is read without pickle, which runs whatever code a file names: a results directory that others can write
(a Ray cluster's storage) must not be able to run code in the processes that resume from it. The tensors (networks,
optimisers, PyTorch's random stream) are ``torch.save``'d and read with ``torch.load(..., weights_only=True)``, the
arrays (replay buffer, worlds, observations) ``np.savez``'d and read with ``np.load(..., allow_pickle=False)``, and the
rest is JSON (:mod:`~sb3_maddpg.common.plain_state`). The model is not read with SB3's ``load`` (which
unpickles): the run builds its model from its config, and the snapshot's state goes back onto it. A directory without
a ``snapshot.json`` of this format is no snapshot: the run starts afresh.
"""

import csv
import dataclasses
import io
import json
import os
import random
import shutil
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from pickle import UnpicklingError  # what torch.load(weights_only=True) raises for a file that names code
from typing import Any

import numpy as np
import stable_baselines3
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from sb3_maddpg.common.plain_state import NotPlainData, decode, encode, object_state, restore_object_state
from sb3_maddpg.envs.simple_spread_vec_env import SimpleSpreadVecEnv
from sb3_maddpg.experiments.training_state import (
    MADE_BY_CONSTRUCTION,
    MODEL_ATTRIBUTES,
    STATE_HOLDERS,
    model_tensors,
    restore_model_tensors,
    torch_errors_as_unreadable,
)
from sb3_maddpg.version import __version__

SNAPSHOT_DIR = "resume"
"""A run's snapshot directory, inside the run's directory."""

SNAPSHOTS_PER_RUN = 10
"""A snapshot at each ``1 / SNAPSHOTS_PER_RUN`` of the budget (the last one at 90%)."""

SNAPSHOT_FORMAT = 2
"""The format of a snapshot's files, in its ``snapshot.json``; another format is not read."""

STATE_FILE, ARRAYS_FILE, TENSORS_FILE = "snapshot.json", "arrays.npz", "tensors.pt"
"""A snapshot's files: the JSON state (written last, the snapshot's mark), its arrays, and its torch tensors."""

NO_SNAPSHOT = "no snapshot"
"""What :func:`load_snapshot` says when a run has none (a first attempt, or one killed before its first)."""

UNREADABLE = (
    UnpicklingError,
    EOFError,
    zipfile.BadZipFile,
    FileNotFoundError,
    KeyError,
    AttributeError,
    IndexError,
    TypeError,
    ValueError,
)
"""Errors that say a snapshot's files are not whole, not of this code, or tampered with (the run starts afresh); any
other error while loading one (e.g. out of memory) fails the run and keeps the snapshot for the next attempt."""


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
        "torch": str(th.__version__),  # a TorchVersion, a str subclass
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
    :return: Each layer's class name and state (:func:`~sb3_maddpg.common.plain_state.object_state`: the
        worlds' arrays and the generators of the simple_spread env, a monitor's episode counts, ...), outermost first:
        what a new env of the same construction takes back with :func:`restore_env_layers`.
    """
    layers, layer = [], env
    while True:
        layers.append({"class": type(layer).__name__, "state": object_state(layer, STATE_HOLDERS, MADE_BY_CONSTRUCTION)})
        if not isinstance(layer, VecEnvWrapper):
            return layers
        layer = layer.venv


def restore_env_layers(env: VecEnv, layers: list[dict[str, Any]]) -> None:
    """
    :param env: A new env, built as the saved one was.
    :param layers: From :func:`env_layers`, decoded.
    :raises ValueError: For layers of other classes than the env's.
    """
    layer: Any = env
    for saved in layers:
        if type(layer).__name__ != saved["class"]:
            raise ValueError(f"the snapshot's env has a {saved['class']} where this run's has a {type(layer).__name__}")
        restore_object_state(layer, saved["state"], STATE_HOLDERS)
        layer = getattr(layer, "venv", None)
    if layer is not None:
        raise ValueError(f"the snapshot's env has fewer layers than this run's ({type(layer).__name__} not saved)")


def random_state() -> dict[str, Any]:
    """:return: The random streams of Python, NumPy (global) and PyTorch (CPU, and CUDA's when present)."""
    state = {"python": random.getstate(), "numpy": np.random.get_state(legacy=False), "torch": th.get_rng_state()}
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


def capture_training_state(model: BaseAlgorithm) -> tuple[dict[str, Any], dict[str, Any]]:
    """
    :param model: A model between two rollouts, with a replay buffer.
    :return: Its training state as plain data (for :func:`~sb3_maddpg.common.plain_state.encode`), and as
        tensors (for ``torch.save``): the state dicts and PyTorch's random streams.
    """
    streams = random_state()
    tensors = {**model_tensors(model), "random": {key: streams.pop(key) for key in ("torch", "cuda") if key in streams}}
    state = {
        "random": streams,
        # The model's build seeds the action space from the model's seed: random actions before learning_starts come
        # from it, so its stream is restored from here.
        "action_space": model.action_space.np_random.bit_generator.state,
        "model": object_state(model, STATE_HOLDERS, names=MODEL_ATTRIBUTES),
        "replay_buffer": object_state(model.replay_buffer, STATE_HOLDERS, MADE_BY_CONSTRUCTION),  # type: ignore[attr-defined]
        "env": env_layers(model.get_env()),  # type: ignore[arg-type]
    }
    return state, tensors


def restore_training_state(model: BaseAlgorithm, state: dict[str, Any], tensors: dict[str, Any]) -> None:
    """
    :param model: A new model of the saved one's config, on a new env.
    :param state: From :func:`capture_training_state`, decoded.
    :param tensors: From :func:`capture_training_state`, loaded (``weights_only=True``).
    :raises ValueError: For a state of another kind than the model's (of other code, or tampered with); ``KeyError``
        for a part missing.
    """
    restore_model_tensors(model, tensors)
    restore_object_state(model, state["model"], STATE_HOLDERS)
    restore_object_state(model.replay_buffer, state["replay_buffer"], STATE_HOLDERS)  # type: ignore[attr-defined]
    # After the build, which seeded the env and the spaces from the model's seed: their saved state goes back on top.
    restore_env_layers(model.get_env(), state["env"])  # type: ignore[arg-type]
    model.action_space.np_random.bit_generator.state = state["action_space"]
    set_random_state({**state["random"], **tensors["random"]})  # last: the build drew the networks from the streams


def read_progress_rows(path: str | os.PathLike[str]) -> list[dict[str, str]]:
    """
    :param path: A ``progress.csv``.
    :return: Its rows (none if there is no file).
    """
    if not os.path.isfile(path):
        return []
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def save_snapshot(run_dir: str | os.PathLike[str], model: BaseAlgorithm, progress: RunProgress) -> Path:
    """
    Write the run's snapshot beside the last one, then put it in its place.

    :param run_dir: The run's directory.
    :param model: The model, between two rollouts.
    :param progress: What the run has written so far.
    :return: The snapshot's directory.
    :raises NotPlainData: For a state that is not plain data (nothing is written then).
    """
    final = Path(run_dir) / SNAPSHOT_DIR
    tmp, old = final.with_name(f"{SNAPSHOT_DIR}.tmp"), final.with_name(f"{SNAPSHOT_DIR}.old")
    state, tensors = capture_training_state(model)
    logger = model.logger
    document, arrays = encode(
        {
            "format": SNAPSHOT_FORMAT,
            "versions": versions(),
            "progress": dataclasses.asdict(progress),
            "logger": [dict(logger.name_to_value), dict(logger.name_to_count), dict(logger.name_to_excluded)],
            **state,
        }
    )
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    th.save(tensors, tmp / TENSORS_FILE)
    np.savez(tmp / ARRAYS_FILE, allow_pickle=False, **arrays)
    (tmp / STATE_FILE).write_text(json.dumps(document))
    if final.exists():
        final.rename(old)
    tmp.rename(final)
    shutil.rmtree(old, ignore_errors=True)
    return final


def load_snapshot(
    run_dir: str | os.PathLike[str], config: dict[str, Any], make_model: Callable[[], BaseAlgorithm]
) -> tuple[BaseAlgorithm, dict[str, Any]] | str:
    """
    Load a run's snapshot onto a new model of the run (on a new env): its networks and optimisers, its counters, its
    replay buffer, the env's worlds and the random streams. Nothing is unpickled.

    :param run_dir: The run's directory.
    :param config: The run's config (``RunConfig.to_dict()``).
    :param make_model: Builds the run's untrained model on a new training env, as the saved one was built (on the
        device the run trains on).
    :return: The model and the rest of the state (``"progress"``: :class:`RunProgress`, ``"logger"``: the logger's
        pending values), or why no snapshot is used (:data:`NO_SNAPSHOT`; of another format or config, of other
        versions, not whole: :data:`UNREADABLE`); any other error (e.g. out of memory) is raised, the snapshot kept.
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
        document = json.loads((directory / STATE_FILE).read_text())
        if document.get("format") != SNAPSHOT_FORMAT:
            return f"its snapshot is of format {document.get('format')}, this version reads format {SNAPSHOT_FORMAT}"
        progress = RunProgress(**decode(document["progress"], {}))
        saved_versions = decode(document["versions"], {})
    except UNREADABLE as error:
        return f"its snapshot could not be read ({type(error).__name__}: {error})"
    if progress.config != config:
        return "its snapshot is of another config"
    if saved_versions != versions():
        return f"its snapshot was saved under other versions ({saved_versions}, now {versions()})"
    model = make_model()
    try:
        state = restore_snapshot(model, directory)
    except UNREADABLE as error:
        model.get_env().close()  # type: ignore[union-attr]
        return f"its snapshot could not be read ({type(error).__name__}: {error})"
    return model, {"progress": progress, "logger": state["logger"]}


def restore_snapshot(model: BaseAlgorithm, directory: Path) -> dict[str, Any]:
    """
    Put a snapshot's training state on a new model of its run.

    :param model: The new model, on a new env.
    :param directory: The snapshot.
    :return: The snapshot's state, decoded.
    :raises UNREADABLE: For files that are not whole, not of this code, or tampered with.
    """
    # Read here (a failing disk is an OSError, which fails the run), parsed there (a file cut short is not whole).
    tensors_bytes = io.BytesIO((directory / TENSORS_FILE).read_bytes())
    with torch_errors_as_unreadable(TENSORS_FILE):
        tensors = th.load(tensors_bytes, map_location="cpu", weights_only=True)
    with np.load(directory / ARRAYS_FILE, allow_pickle=False) as arrays:
        state = decode(json.loads((directory / STATE_FILE).read_text()), arrays)
    restore_training_state(model, state, tensors)
    return state


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
        except (OSError, NotPlainData) as error:  # a full disk, a state not plain data: training goes on, the last stays
            shutil.rmtree(self.run_dir / f"{SNAPSHOT_DIR}.tmp", ignore_errors=True)
            self.log(f"snapshot at {self.model.num_timesteps:,} steps not saved ({type(error).__name__}: {error})")
            return
        if self.on_save is not None:
            self.on_save(self.model.num_timesteps)

    def _on_step(self) -> bool:
        return True
