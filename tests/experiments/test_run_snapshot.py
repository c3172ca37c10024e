"""A run killed after a snapshot goes on from it: the files of an uninterrupted run, and a fresh start when it cannot."""

import csv
import dataclasses
import json
import os
import pickle
import shutil
from pathlib import Path
from typing import Any

import cloudpickle
import numpy as np
import pytest
import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.cli.main import main
from sb3_maddpg.experiments import SMOKE, RunConfig, run_snapshot, runner
from sb3_maddpg.experiments.results_dir import (
    CHECKPOINT_DIR,
    CHECKPOINT_EVALS_FILE,
    CURVE_FILE,
    LOG_FILE,
    PROGRESS_FILE,
    SUMMARY_FILE,
    read_json,
    run_directory,
)
from sb3_maddpg.experiments.run_snapshot import (
    ARRAYS_FILE,
    SNAPSHOT_DIR,
    STATE_FILE,
    TENSORS_FILE,
    SnapshotCallback,
    snapshot_steps,
)
from sb3_maddpg.experiments.tasks import RunTask, run_task


class Killed(BaseException):
    """Stands for the process dying: nothing in the run catches it."""


def config(**changes: Any) -> RunConfig:
    """
    A smoke run that learns before and after its middle snapshots (updates from step 250 of 1,000). With 5 envs a
    rollout is 10 steps of each and an episode 25: the rollout after the snapshot at 600 steps ends an episode, so the
    logs are written before that rollout's update, with the values the update before the snapshot recorded.
    """
    experiment = dataclasses.replace(SMOKE, keep_checkpoints=True, n_envs=5, **changes)
    return next(run for run in experiment.runs() if run.scheme == "selected" and run.seed == 0)


def run_killed(monkeypatch: pytest.MonkeyPatch, run: RunConfig, results: Path, nth: int) -> None:
    """Run ``run`` into ``results`` and have it die right after its ``nth`` snapshot is written."""

    class DiesAfterSnapshot(SnapshotCallback):
        def _on_rollout_start(self) -> None:
            before = len(self.pending)
            super()._on_rollout_start()
            if len(self.pending) < before and len(snapshot_steps(self.model._total_timesteps)) - len(self.pending) >= nth:
                raise Killed

    with monkeypatch.context() as patch:
        patch.setattr(runner, "SnapshotCallback", DiesAfterSnapshot)
        with pytest.raises(Killed):
            runner.execute_run(run, results, verbose=0)


def rows(path: Path, drop_prefix: str = "time/") -> list[dict[str, str]]:
    with open(path, newline="") as file:
        return [{k: v for k, v in row.items() if not k.startswith(drop_prefix)} for row in csv.DictReader(file)]


def test_snapshots_fall_at_each_tenth_of_the_budget() -> None:
    assert snapshot_steps(1_000) == [100, 200, 300, 400, 500, 600, 700, 800, 900]
    assert snapshot_steps(5) == [1, 2, 3, 4]  # repeats merged, never at step 0


@pytest.mark.parametrize("normalize_observations", [False, True], ids=["raw", "vecnormalize"])
def test_a_run_killed_after_a_snapshot_resumes_to_the_files_of_an_uninterrupted_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, normalize_observations: bool
) -> None:
    run = config(normalize_observations=normalize_observations)  # VecNormalize's running statistics are state too
    whole, resumed = tmp_path / "whole", tmp_path / "resumed"
    runner.execute_run(run, whole, verbose=0)
    # Killed twice: at 200 steps, before learning starts (random actions from the action space's stream), then at
    # 600, after it started and before the checkpoints; the third attempt finishes. The second kill comes after the
    # resumed attempt's own snapshots, whose rows then hold the first attempt's too.
    for nth in (2, 6):
        run_killed(monkeypatch, run, resumed, nth)
        killed = run_directory(resumed, run)
        assert (killed / SNAPSHOT_DIR / STATE_FILE).is_file() and not (killed / SUMMARY_FILE).exists()
    runner.execute_run(run, resumed, verbose=0)

    done, again = run_directory(whole, run), run_directory(resumed, run)
    log = (again / LOG_FILE).read_text()
    assert "resumed from its snapshot at 200 of 1,000 steps" in log and "at 600 of 1,000 steps" in log
    assert not (again / SNAPSHOT_DIR).exists() and not (done / SNAPSHOT_DIR).exists()  # removed when done
    for name in (CURVE_FILE, CHECKPOINT_EVALS_FILE):
        assert (again / name).read_text() == (done / name).read_text(), name
    assert rows(again / PROGRESS_FILE) == rows(done / PROGRESS_FILE)  # every row, timings aside
    first, second = read_json(done / SUMMARY_FILE), read_json(again / SUMMARY_FILE)
    assert first["score"] == second["score"] and first["n_updates"] == second["n_updates"] > 0
    assert first["behaviour"] == second["behaviour"]
    last = sorted((done / CHECKPOINT_DIR).glob("*.zip"))[-1].name
    weights = [MADDPG.load(d / CHECKPOINT_DIR / last).policy.state_dict() for d in (done, again)]
    assert all(th.equal(weights[0][key], weights[1][key]) for key in weights[0])


def test_a_snapshot_that_cannot_be_used_is_a_fresh_start(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run = config()
    run_killed(monkeypatch, run, tmp_path, nth=2)
    directory = run_directory(tmp_path, run)
    # Another config in the same run directory (a changed preset): its snapshot is not this run's.
    other = dataclasses.replace(run, model_kwargs={**run.model_kwargs, "batch_size": 32})
    run_killed(monkeypatch, other, tmp_path, nth=2)
    log = (directory / LOG_FILE).read_text()
    assert "starting afresh: its snapshot is of another config" in log and "resumed" not in log
    # A snapshot of other versions of the package or its dependencies: a fresh start.
    with monkeypatch.context() as patch:
        patch.setattr(run_snapshot, "versions", lambda: {"sb3_maddpg": "0.0"})
        run_killed(patch, other, tmp_path, nth=2)
    assert "starting afresh: its snapshot was saved under other versions" in (directory / LOG_FILE).read_text()
    # An unreadable snapshot: a fresh start that says why, and the run finishes.
    (directory / SNAPSHOT_DIR / STATE_FILE).write_bytes(b"not JSON")
    summary = runner.execute_run(other, tmp_path, verbose=0)
    assert "starting afresh: its snapshot could not be read (JSONDecodeError" in (directory / LOG_FILE).read_text()
    assert summary["total_timesteps"] == 1_000 and not (directory / SNAPSHOT_DIR).exists()


def test_a_save_killed_between_its_renames_or_failing_leaves_the_last_whole_snapshot(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    run = config()
    run_killed(monkeypatch, run, tmp_path, nth=3)
    directory = run_directory(tmp_path, run)
    # Killed after the last snapshot was moved aside and before the new one took its place: the last one is used.
    (directory / SNAPSHOT_DIR).rename(directory / f"{SNAPSHOT_DIR}.old")
    (directory / f"{SNAPSHOT_DIR}.tmp").mkdir()  # the new one, maybe not whole: not used
    (directory / f"{SNAPSHOT_DIR}.tmp" / STATE_FILE).write_bytes(b"half")

    def full_disk(*args: Any) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr("sb3_maddpg.experiments.run_snapshot.save_snapshot", full_disk)  # and no more can be saved
    runner.execute_run(run, tmp_path, verbose=0)
    log = (directory / LOG_FILE).read_text()
    assert "resumed from its snapshot at 300 of 1,000 steps" in log
    assert "snapshot at 400 steps not saved (OSError: [Errno 28] No space left on device)" in log
    assert (directory / "done").is_file() and not list(directory.glob(f"{SNAPSHOT_DIR}*"))


def test_envs_that_cannot_be_saved_exactly_take_no_snapshot(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: Any) -> None:
        raise AssertionError("a snapshot was saved")

    monkeypatch.setattr("sb3_maddpg.experiments.run_snapshot.save_snapshot", refuse)
    run = config(vec_env="mpe2")  # mpe2's own envs in a DummyVecEnv: they pickle, but do not come back whole
    runner.execute_run(run, tmp_path, verbose=0)
    directory = run_directory(tmp_path, run)
    assert "no snapshots: the training env (VecMonitor) cannot be saved exactly" in (directory / LOG_FILE).read_text()
    assert (directory / "done").is_file()


def test_no_snapshots_when_switched_off(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: Any) -> None:
        raise AssertionError("a snapshot was saved")

    monkeypatch.setattr("sb3_maddpg.experiments.run_snapshot.save_snapshot", refuse)
    runner.execute_run(config(), tmp_path, verbose=0, snapshots=False)
    with pytest.raises(AssertionError, match="a snapshot was saved"):
        runner.execute_run(config(), tmp_path / "on", verbose=0)
    # The command line's switch reaches the runs (one worker: in this process, where the refusal is patched in).
    command = ["run", "--config", "smoke", "--schemes", "full", "--seeds", "1", "--quiet", "--results"]
    assert main([*command, str(tmp_path / "cli_off"), "--no-snapshots"]) == 0
    assert (tmp_path / "cli_off" / "smoke" / "full" / "seed_000" / "done").is_file()
    assert main([*command, str(tmp_path / "cli_on")]) == 1  # the run failed: it tried to save one


def test_a_resumed_run_loads_on_the_device_asked_for(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run = config()
    run_killed(monkeypatch, run, tmp_path, nth=2)
    devices: list[Any] = []
    build_model = runner.build_model

    def recording_build(task: RunTask, **kwargs: Any) -> Any:
        devices.append(kwargs.get("device"))
        return build_model(task, **kwargs)

    monkeypatch.setattr(runner, "build_model", recording_build)
    runner.execute_run(run, tmp_path, verbose=0, device="cpu")
    assert "resumed from its snapshot" in (run_directory(tmp_path, run) / LOG_FILE).read_text()
    assert devices == ["cpu"]  # the model the snapshot goes onto, built where --device says


class Tripwire:
    """Unpickled, it makes a directory: the proof that a file's code ran."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __reduce__(self) -> tuple[Any, ...]:
        return os.mkdir, (str(self.path),)


@pytest.fixture(scope="module")
def killed_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A results directory whose run was killed after its snapshot at 300 steps (learning started at 250)."""
    results = tmp_path_factory.mktemp("killed")
    with pytest.MonkeyPatch.context() as patch:
        run_killed(patch, config(), results, nth=3)
    return results


def copy_of(killed_run: Path, tmp_path: Path) -> Path:
    """:return: The run's directory in a copy of ``killed_run``'s results, under ``tmp_path``."""
    shutil.copytree(killed_run, tmp_path / "results")
    return run_directory(tmp_path / "results", config())


def test_a_snapshot_resumes_without_unpickling(killed_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    directory = copy_of(killed_run, tmp_path)

    def refuse(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("unpickled while resuming")

    class RefusingUnpickler:  # what torch.load without weights_only (and SB3's load of a .pt) subclasses
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            refuse()

    with monkeypatch.context() as patch:
        for module, name in [(pickle, "load"), (pickle, "loads"), (cloudpickle, "load"), (cloudpickle, "loads")]:
            patch.setattr(module, name, refuse)
        patch.setattr(pickle, "Unpickler", RefusingUnpickler)
        model, _, _, why_not = runner.resume_or_start(run_task(config()), directory, "cpu")
    assert why_not == "" and model.num_timesteps == 300 and model._n_updates > 0 and model.replay_buffer.pos > 0


def test_a_snapshot_directory_of_pickles_is_never_unpickled(killed_run: Path, tmp_path: Path) -> None:
    directory = copy_of(killed_run, tmp_path)
    snapshot, ran = directory / SNAPSHOT_DIR, tmp_path / "code_ran"
    shutil.rmtree(snapshot)
    snapshot.mkdir()  # pickles where a snapshot's files would be, and no snapshot.json
    (snapshot / "state.pkl").write_bytes(pickle.dumps(Tripwire(ran)))
    (snapshot / "model.zip").write_bytes(b"")
    summary = runner.execute_run(config(), tmp_path / "results", verbose=0)
    log = (directory / LOG_FILE).read_text()
    assert not ran.exists() and summary["total_timesteps"] == 1_000 and "resumed" not in log


def code_in_tensors(snapshot: Path, ran: Path) -> None:
    th.save({"modules": Tripwire(ran)}, snapshot / TENSORS_FILE)


def code_in_arrays(snapshot: Path, ran: Path) -> None:
    np.savez(snapshot / ARRAYS_FILE, array_0=np.array([Tripwire(ran)], dtype=object))  # pickled by np.savez


def arrays_cut_short(snapshot: Path, ran: Path) -> None:
    (snapshot / ARRAYS_FILE).write_bytes((snapshot / ARRAYS_FILE).read_bytes()[:1000])


def tensors_cut_short(snapshot: Path, ran: Path) -> None:
    (snapshot / TENSORS_FILE).write_bytes((snapshot / TENSORS_FILE).read_bytes()[:1000])


def tensors_missing(snapshot: Path, ran: Path) -> None:
    (snapshot / TENSORS_FILE).unlink()


def edit_state(snapshot: Path, edit: Any) -> None:
    document = json.loads((snapshot / STATE_FILE).read_text())
    edit(document)
    (snapshot / STATE_FILE).write_text(json.dumps(document))


def env_missing(snapshot: Path, ran: Path) -> None:
    edit_state(snapshot, lambda document: document.pop("env"))


def observations_swapped_for_rewards(snapshot: Path, ran: Path) -> None:
    edit_state(snapshot, lambda document: document["replay_buffer"].update(observations=document["replay_buffer"]["rewards"]))


def another_format(snapshot: Path, ran: Path) -> None:
    edit_state(snapshot, lambda document: document.update(format=3))


TAMPERED = {
    # Files that would run code: refused by their readers, the code never run.
    code_in_tensors: "could not be read (UnpicklingError: Weights only load failed",
    code_in_arrays: "could not be read (ValueError: Object arrays cannot be loaded when allow_pickle=False",
    # Files not whole.
    arrays_cut_short: "could not be read (BadZipFile",
    tensors_cut_short: "could not be read (ValueError: ",  # in PyTorch's words
    tensors_missing: "could not be read (FileNotFoundError",
    env_missing: "could not be read (KeyError: 'env')",
    # Values of another kind than the new model's, and a format this version does not read.
    observations_swapped_for_rewards: "could not be read (ValueError: MultiAgentReplayBuffer.observations is an array of "
    "float32[2000, 5, 3] in the snapshot, an array of float32[2000, 5, 54] here)",
    another_format: "its snapshot is of format 3, this version reads format 2",
}
"""Each way of tampering with a snapshot, or of finding one not whole, and what the run says of it."""


@pytest.mark.parametrize("tamper", list(TAMPERED), ids=lambda tamper: tamper.__name__)
def test_a_tampered_or_partial_snapshot_is_a_fresh_start(killed_run: Path, tmp_path: Path, tamper: Any) -> None:
    directory = copy_of(killed_run, tmp_path)
    ran = tmp_path / "code_ran"
    tamper(directory / SNAPSHOT_DIR, ran)
    model, _, _, why_not = runner.resume_or_start(run_task(config()), directory, "cpu")
    assert TAMPERED[tamper] in why_not and not ran.exists()
    assert model.num_timesteps == 0 and not (directory / SNAPSHOT_DIR).exists()  # the run's directory started afresh


def test_a_state_that_is_not_plain_data_is_not_saved_and_training_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # An attribute that holds an object (a schedule here): no snapshot is written, nothing pickled.
    monkeypatch.setattr(run_snapshot, "MODEL_ATTRIBUTES", (*run_snapshot.MODEL_ATTRIBUTES, "lr_schedule"))
    runner.execute_run(config(), tmp_path, verbose=0)
    directory = run_directory(tmp_path, config())
    log = (directory / LOG_FILE).read_text()
    assert "snapshot at 100 steps not saved (NotPlainData: /model/lr_schedule (FloatSchedule) is not plain data" in log
    assert (directory / "done").is_file() and not list(directory.glob(f"{SNAPSHOT_DIR}*"))
