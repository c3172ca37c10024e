"""Tests of the batched backend (``sb3-maddpg run --backend batched``): run groups write what the runner writes."""

import csv
import dataclasses
import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.cli.main import main
from sb3_maddpg.experiments import SMOKE, ExperimentConfig, group_recorder, group_state, run_sweep, runner
from sb3_maddpg.experiments.batched import train_group
from sb3_maddpg.experiments.group_plan import BatchedRunRefused, check_batched, plan_groups
from sb3_maddpg.experiments.group_state import group_state_path, parse_seed_ranges, remove_stale_states, seed_ranges
from sb3_maddpg.experiments.results_dir import DONE_FILE, load_summaries
from sb3_maddpg.experiments.tasks import run_task
from sb3_maddpg.results import make_report
from sb3_maddpg.run_group import RunGroup
from sb3_maddpg.run_group.trainer import STATE_VERSION
from tests.settings import NEVER_UPDATED_RUNS


def tiny(**changes: Any) -> ExperimentConfig:
    """The smoke preset's tiny networks, one scheme, three seeds, with model files kept (to load them)."""
    settings: dict[str, Any] = {"name": "tiny", "schemes": ("full",), "seeds": (0, 1, 2), "keep_checkpoints": True}
    return dataclasses.replace(SMOKE, **{**settings, **changes})


WARM_UP_ONLY = tiny(model_kwargs={**SMOKE.model_kwargs, "learning_starts": 10_000})
"""Uniform actions only, no update (learning starts after the budget): both backends' checkpoints are the models'
initial weights, so every evaluation must agree exactly; the training episodes agree in distribution only."""


TIMES = ("time/fps", "time/time_elapsed")
"""The ``progress.csv`` keys of wall time (the rest of a group's rows are the same in every attempt)."""


def read_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def files(directory: Path) -> set[str]:
    return {str(path.relative_to(directory)) for path in directory.rglob("*")}


def keys(value: Any, prefix: str = "") -> set[str]:
    """The nested keys of a JSON value (its structure, not its numbers)."""
    if not isinstance(value, dict):
        return set()
    return {f"{prefix}{key}" for key in value} | {k for key, v in value.items() for k in keys(v, f"{prefix}{key}/")}


class Killed(Exception):
    """A process killed in a test."""


def kill_after_save(monkeypatch: pytest.MonkeyPatch, steps: int) -> None:
    """Make a group's process "killed" right after it saves its state at ``steps`` env steps or later."""

    def save_then_kill(path: Path, state: dict[str, Any]) -> None:
        group_state.save_state(path, state)
        if state["group"]["num_timesteps"] >= steps:
            raise Killed

    monkeypatch.setattr(group_recorder, "save_state", save_then_kill)


@pytest.fixture(scope="module")
def warm_up_results(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The warm-up-only experiment on both backends."""
    results = {}
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "learn\\(\\) ended at step")  # the local runs: no update, on purpose
        for backend in ("local", "batched"):
            path = tmp_path_factory.mktemp(backend)
            result = run_sweep([WARM_UP_ONLY], path, backend=backend, verbose=0, device="cpu")
            assert result.ok and len(result.completed) == 3, result.failed
            results[backend] = path
    return results


@NEVER_UPDATED_RUNS
def test_a_group_writes_the_runners_files(warm_up_results: dict[str, Path], tmp_path: Path) -> None:
    local, batched = warm_up_results["local"], warm_up_results["batched"]
    for config in WARM_UP_ONLY.runs():
        ours, theirs = batched / config.run_id, local / config.run_id
        assert files(ours) == files(theirs), config.run_id  # the same names, checkpoints included
        for name in ("summary.json", "config.json"):
            assert keys(json.loads((ours / name).read_text())) == keys(json.loads((theirs / name).read_text())), name
        for name in ("checkpoint_evals.csv", "learning_curve.csv"):
            assert read_rows(ours / name)[0].keys() == read_rows(theirs / name)[0].keys(), name
        progress = read_rows(ours / "progress.csv")
        assert {"rollout/ep_rew_mean", "eval/min_dist_sum", "time/total_timesteps"} <= progress[0].keys()
        assert "in a run group of 3 on cpu" in (ours / "train.log").read_text()
        # Every checkpoint is a MADDPG file at its step, which evaluate_team scores.
        for path in sorted((ours / "checkpoints").iterdir()):
            model = MADDPG.load(path, device="cpu")
            assert path.name == f"model_{model.num_timesteps}_steps.zip"
        result = evaluate_team(model, run_task(config).make_eval_env(2), n_episodes=2, seed=config.eval_seed)
        assert np.isfinite(result["min_dist_sum"])
        assert not list(ours.parent.glob("group_seeds_*.pt"))  # a finished group's state is deleted
    written = make_report(batched, tmp_path / "report", plots=False)
    assert any(path.name == "table_min_dist_sum.md" for path in written)
    assert len(load_summaries(batched)) == 3


def test_each_summary_records_what_trained_it_for_the_cost_table(warm_up_results: dict[str, Path]) -> None:
    # The local workers train on one torch thread each; the batched backend trains the three seeds in one group.
    for backend, together in (("local", 1), ("batched", 3)):
        for summary in load_summaries(warm_up_results[backend]):
            resources = (summary["device"], summary["torch_threads"], summary["runs_trained_together"])
            assert resources == ("cpu", 1 if backend == "local" else torch.get_num_threads(), together), backend


def test_a_trained_groups_progress_csv_has_the_local_runs_header(tmp_path: Path) -> None:
    experiment = tiny(seeds=(0,), keep_checkpoints=False)  # training on: the train/* keys too
    headers = {}
    for backend in ("local", "batched"):
        assert run_sweep([experiment], tmp_path / backend, backend=backend, verbose=0, device="cpu").ok
        with open(tmp_path / backend / experiment.runs()[0].run_id / "progress.csv", newline="") as file:
            headers[backend] = next(csv.reader(file))
    assert {"train/critic_loss", "train/agent_0/actor_loss", "train/n_updates", "train/learning_rate"} <= set(
        headers["batched"]
    )
    assert sorted(headers["batched"]) == sorted(headers["local"])


def test_never_updated_runs_evaluate_identically_on_batched_and_local(warm_up_results: dict[str, Path]) -> None:
    local, batched = warm_up_results["local"], warm_up_results["batched"]
    finals: dict[str, list[float]] = {"local": [], "batched": []}
    for config in WARM_UP_ONLY.runs():
        # The same seed's initial team, written back from its run of the group: the same evaluations, exactly.
        for name in ("checkpoint_evals.csv", "learning_curve.csv"):
            assert read_rows(batched / config.run_id / name) == read_rows(local / config.run_id / name), name
        for backend, path in warm_up_results.items():
            rows = read_rows(path / config.run_id / "progress.csv")
            finals[backend] += [float(row["rollout/ep_rew_mean"]) for row in rows if row["rollout/ep_rew_mean"]][-1:]
    # The training episodes (uniform actions) come from another random stream (torch's, not mpe2's): the same
    # distribution, checked loosely: the runs' mean team return over their last episodes, within 15%.
    assert np.mean(finals["batched"]) == pytest.approx(np.mean(finals["local"]), rel=0.15)


def test_an_interrupted_group_resumes_from_its_last_checkpoint(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    experiment = tiny(seeds=(0, 1))
    configs = experiment.runs()
    whole = train_group(configs, tmp_path / "whole", device="cpu", verbose=0)

    results = tmp_path / "resumed"
    kill_after_save(monkeypatch, configs[0].checkpoint_steps()[0])
    with pytest.raises(Killed):
        train_group(configs, results, device="cpu", verbose=0)
    monkeypatch.undo()
    state = group_state_path(results, configs)
    assert state.exists() and state.name == "group_seeds_0-1.pt"
    first = results / configs[0].run_id / "checkpoints" / f"model_{configs[0].checkpoint_steps()[0]}_steps.zip"
    stamp = first.stat().st_mtime_ns
    assert not (results / configs[0].run_id / DONE_FILE).exists()

    resumed = train_group(configs, results, device="cpu", verbose=0)
    assert first.stat().st_mtime_ns == stamp  # the finished checkpoint is kept, not trained again
    assert not state.exists()
    for config, ours, theirs in zip(configs, resumed, whole):
        # An exact resume (weights, optimisers, buffers, generators, worlds): the same checkpoints' evaluations.
        assert ours["files"]["checkpoint_evals.csv"] == theirs["files"]["checkpoint_evals.csv"], config.run_id
        assert ours["files"]["learning_curve.csv"] == theirs["files"]["learning_curve.csv"], config.run_id
        directory = results / config.run_id
        curve = [row["rollout/ep_rew_mean"] for row in read_rows(directory / "progress.csv")]
        whole_curve = [row["rollout/ep_rew_mean"] for row in read_rows(tmp_path / "whole" / config.run_id / "progress.csv")]
        assert curve == whole_curve
        assert "resumed at" in (directory / "train.log").read_text()
    # A finished group is skipped by the sweep, as finished runs are.
    again = run_sweep([experiment], results, backend="batched", verbose=0, device="cpu")
    assert again.ok and again.skipped == 2 and not again.completed


def test_a_crash_while_the_runs_are_evaluated_evaluates_them_again_without_training(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Checkpoints not kept: the crash comes where the runner has deleted them before its done marker.
    experiment = tiny(seeds=(0, 1), keep_checkpoints=False)
    whole = tmp_path / "whole"
    assert run_sweep([experiment], whole, backend="batched", verbose=0, device="cpu").ok

    class Killed(BaseException):
        pass

    marked: list[Path] = []
    original_mark_done = runner.mark_done

    def killed_at_the_second_run(directory: Path) -> None:
        marked.append(directory)
        if len(marked) == 2:
            raise Killed
        original_mark_done(directory)

    results = tmp_path / "crashed"
    monkeypatch.setattr(runner, "mark_done", killed_at_the_second_run)
    with pytest.raises(Killed):
        run_sweep([experiment], results, backend="batched", verbose=0, device="cpu")
    monkeypatch.setattr(runner, "mark_done", original_mark_done)
    configs = experiment.runs()
    assert (results / configs[0].run_id / DONE_FILE).exists() and not (results / configs[1].run_id / DONE_FILE).exists()

    def no_training(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("a run whose training is over is trained again")

    monkeypatch.setattr(RunGroup, "learn", no_training)
    again = run_sweep([experiment], results, backend="batched", verbose=0, device="cpu")
    assert again.ok and again.skipped == 1 and len(again.completed) == 1, again.failed
    for config in configs:
        ours, theirs = results / config.run_id, whole / config.run_id
        assert files(ours) == files(theirs), config.run_id  # no checkpoints, no record left
        for name in ("checkpoint_evals.csv", "learning_curve.csv"):
            assert (ours / name).read_text() == (theirs / name).read_text(), (config.run_id, name)
        untimed = [[v for k, v in row.items() if k not in TIMES] for row in read_rows(ours / "progress.csv")]
        assert untimed == [[v for k, v in row.items() if k not in TIMES] for row in read_rows(theirs / "progress.csv")]
        log = (ours / "train.log").read_text()
        assert log.count("in a run group of 2") == 1, log  # trained once
        done_lines = [line for line in log.splitlines() if ": done in" in line]
        assert done_lines and all(f"{config.run_id}: done in" in line for line in done_lines), log  # its own only
        # Evaluated again from the trained record, which keeps what trained it for the cost table.
        assert json.loads((ours / "summary.json").read_text())["runs_trained_together"] == 2
    assert not list((results / configs[0].run_id).parent.glob("group_seeds_*"))


def test_a_state_not_used_says_why_and_stale_temporary_files_are_removed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    configs = tiny(seeds=(0, 1)).runs()
    first_checkpoint = configs[0].checkpoint_steps()[0]

    def restart_says(why: str) -> None:
        capsys.readouterr()
        kill_after_save(monkeypatch, 0)
        with pytest.raises(Killed):
            train_group(configs, tmp_path, device="cpu", verbose=1)
        out = capsys.readouterr().out
        assert f"tiny/full: {why}" in out and "so the group starts afresh" in out, out
        for config in configs:  # and in each run's new train.log
            assert f"{config.run_id}: {why}" in (tmp_path / config.run_id / "train.log").read_text()

    state = group_state_path(tmp_path, configs)
    kill_after_save(monkeypatch, 0)
    with pytest.raises(Killed):
        train_group(configs, tmp_path, device="cpu", verbose=0)
    state.write_bytes(b"not a state")
    restart_says("group_seeds_0-1.pt cannot be read (UnpicklingError: truncated")
    kill_after_save(monkeypatch, first_checkpoint)
    with pytest.raises(Killed):
        train_group(configs, tmp_path, device="cpu", verbose=0)
    for path in (tmp_path / configs[0].run_id / "checkpoints").iterdir():
        path.unlink()
    restart_says("group_seeds_0-1.pt names checkpoints of tiny/full/seed_000 that are missing")
    # A state of an earlier layout (e.g. buffers that stored next observations beside) is not used either.
    saved = torch.load(state, map_location="cpu", weights_only=True)
    saved["group"]["version"] = 1
    torch.save(saved, state)
    restart_says(f"group_seeds_0-1.pt is of another layout (version 1; this package reads version {STATE_VERSION})")
    # Nor one saved under other versions (a resumed group equals an uninterrupted one only under the same).
    saved = torch.load(state, map_location="cpu", weights_only=True)
    saved["versions"]["torch"] = "1.0.0"
    torch.save(saved, state)
    restart_says("group_seeds_0-1.pt was saved under other versions (")
    saved = torch.load(state, map_location="cpu", weights_only=True)
    del saved["versions"]
    torch.save(saved, state)
    restart_says("group_seeds_0-1.pt was saved before group states recorded their versions (before 0.3.0)")
    # A killed save's temporary file goes with the runs' stale states; another group's stays.
    ours, theirs = state.with_name(f".{state.name}.123.tmp"), state.with_name(".group_seeds_5.pt.123.tmp")
    ours.write_bytes(b"")
    theirs.write_bytes(b"")
    remove_stale_states(tmp_path, configs)
    assert not ours.exists() and not state.exists() and theirs.exists()


def test_runs_a_group_cannot_train_are_refused_first(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status = main(["run", "--config", "smoke", "--schemes", "attention", "--results", str(tmp_path), "--backend", "batched"])
    error = capsys.readouterr().err
    assert status == 2
    assert error.startswith(
        "sb3-maddpg run: smoke/attention/seed_000 (and its other seeds) cannot train in a run group (the batched backends): "
        "Model 0's critics use a learned scheme"
    )
    assert 'on the local backend (backend="local")' in error
    assert not (tmp_path / "smoke").exists()  # nothing trained, nothing written
    for changes, cause in (
        ({"vec_env": "mpe2"}, "steps simple_spread's batched worlds only"),
        ({"normalize_observations": True}, "VecNormalize"),
        ({"env_kwargs": {"continuous_actions": False}}, "discrete agents"),
    ):
        with pytest.raises(BatchedRunRefused, match=cause):
            check_batched(dataclasses.replace(tiny(), **changes).runs())
    with pytest.raises(ValueError, match="runs_per_process must be at least 1"):
        plan_groups([], 0)


def test_a_matd3_group_trains_and_writes_matd3_checkpoints(tmp_path: Path) -> None:
    """Run groups take MATD3 (its own update step: twins, smoothing, delay): its runs finish, their checkpoints are
    MATD3 files whose twin critics trained."""
    config = tiny(name="tiny_matd3", seeds=(0, 1), algorithm="sb3_maddpg:MATD3")
    result = run_sweep([config], tmp_path, backend="batched", verbose=0, device="cpu")
    assert result.ok and len(result.completed) == 2, result.failed
    for run in config.runs():
        checkpoints = sorted((tmp_path / run.run_id / "checkpoints").iterdir(), key=lambda path: int(path.stem.split("_")[1]))
        first, last = (MATD3.load(path, device="cpu") for path in (checkpoints[0], checkpoints[-1]))
        assert isinstance(last, MATD3) and last._n_updates > first._n_updates
        assert not torch.equal(first.critic.twin.mlp.weights[0], last.critic.twin.mlp.weights[0])


def test_a_device_the_runs_cannot_train_on_is_refused_before_anything_is_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)  # this machine, as one without CUDA
    for backend in ("batched", "local"):
        for device, cause in (
            ("cuda", r"^CUDA is not available on this machine, .*use device=\"cpu\" or \"auto\" \(or the ray"),
            ("cuda:0", r"^CUDA is not available on this machine"),
            ("gpu", r"^device 'gpu' is not a device torch knows .*: use \"cpu\", \"cuda\" or \"auto\"\.$"),
        ):
            with pytest.raises(BatchedRunRefused, match=cause):
                run_sweep([tiny(seeds=(0,))], tmp_path, backend=backend, verbose=0, device=device)
            assert not (tmp_path / "tiny").exists()  # nothing trained, nothing written
    check_batched([], device="cuda")  # no run to do: nothing to refuse


@pytest.mark.sb3_auto_device  # SB3's own "auto", which a backend ignoring --device would fall back to
def test_runs_alone_train_on_the_device_asked_for(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # This machine, as one with a GPU: SB3's "auto" would pick CUDA, so a run that ignored --device cpu would fail
    # here (no CUDA build) and its summary would not say cpu.
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    result = run_sweep([tiny(seeds=(0,))], tmp_path, backend="local", verbose=0, device="cpu")
    assert result.ok, result.failed
    assert [summary["device"] for summary in load_summaries(tmp_path)] == ["cpu"]
    # A device in the experiment's model_kwargs comes first (a resumed run's: tests/experiments/test_run_snapshot.py).
    seen: list[str] = []
    build_model = runner.build_model
    monkeypatch.setattr(
        runner, "build_model", lambda task, **kwargs: seen.append(kwargs["device"]) or build_model(task, **kwargs)
    )
    pinned = tiny(name="pinned", seeds=(0,), model_kwargs={**SMOKE.model_kwargs, "device": "cpu"})
    assert run_sweep([pinned], tmp_path, backend="local", verbose=0, device="cuda").ok
    assert seen == ["cpu"]


def test_groups_are_one_setting_and_scheme() -> None:
    runs = dataclasses.replace(SMOKE, seeds=(0, 1, 2, 3, 4), schemes=("full", "selected")).runs()
    groups = plan_groups(runs, runs_per_process=2)
    assert [[(c.scheme, c.seed) for c in group] for group in groups] == [
        [("full", 0), ("full", 1)],
        [("full", 2), ("full", 3)],
        [("full", 4)],
        [("selected", 0), ("selected", 1)],
        [("selected", 2), ("selected", 3)],
        [("selected", 4)],
    ]
    assert len(plan_groups(runs)) == 2
    assert seed_ranges([5, 0, 1, 2, 9, 10]) == "0-2+5+9-10"
    assert parse_seed_ranges("0-2+5+9-10") == {0, 1, 2, 5, 9, 10}


def test_a_sweep_plans_once_and_hands_the_plan_to_its_backend(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """plan_sweep, plan_groups and memory_bound run once per sweep; the backend trains the groups it planned."""
    from sb3_maddpg.experiments import batched, sweep

    calls: dict[str, int] = {}

    def counted(module: Any, name: str) -> None:
        original = getattr(module, name)

        def count(*args: Any, **kwargs: Any) -> Any:
            calls[name] = calls.get(name, 0) + 1
            return original(*args, **kwargs)

        monkeypatch.setattr(module, name, count)

    for module, name in ((sweep, "plan_sweep"), (batched, "plan_groups"), (batched, "memory_bound")):
        counted(module, name)
    trained: list[list[int]] = []
    monkeypatch.setattr(batched, "train_groups", lambda groups, *args: trained.extend([c.seed for c in g] for g in groups))
    run_sweep([tiny(seeds=(0, 1, 2))], tmp_path, backend="batched", verbose=0, device="cpu")
    assert calls == {"plan_sweep": 1, "plan_groups": 1, "memory_bound": 1}
    assert trained == [[0, 1, 2]]


def test_compile_trains_the_groups_compiled_and_says_its_compile_time(tmp_path: Path) -> None:
    """``--compile``: the group's gradient step runs compiled (one graph), each run's train.log says how long the
    compiling took, and the runs finish as any batched run."""
    torch._dynamo.reset()
    try:
        arguments = ["run", "--config", "smoke", "--schemes", "full", "--seeds", "[0, 1]", "--results", str(tmp_path)]
        status = main([*arguments, "--backend", "batched", "--device", "cpu", "--compile", "--quiet"])
    finally:
        torch._dynamo.reset()
    assert status == 0
    logs = sorted(tmp_path.rglob("train.log"))
    assert len(logs) == 2
    for log in logs:
        text = log.read_text()
        assert "compiling the rounds at the first steps and updates" in text
        assert "rounds compiled in" in text, text
        assert (log.parent / DONE_FILE).is_file()
    assert ", compiled" in next(tmp_path.rglob("sweep.log")).read_text()


def test_groups_compile_by_default_where_it_was_measured_to_pay() -> None:
    """CPU groups of long runs compile (1M env steps per run and more); short runs, and GPUs (not measured yet), not."""
    from sb3_maddpg.experiments.batched import COMPILE_FROM_STEPS, compile_pays

    cpu, cuda = torch.device("cpu"), torch.device("cuda")
    assert compile_pays(COMPILE_FROM_STEPS, cpu) and compile_pays(2_500_000, cpu)
    assert not compile_pays(COMPILE_FROM_STEPS - 1, cpu) and not compile_pays(2_500_000, cuda)


def test_the_sweep_log_says_whether_groups_compile_by_default(tmp_path: Path) -> None:
    from sb3_maddpg.experiments.backends import Execution, make_backend

    long = tiny(episodes=40_000)  # 1M env steps per run: a CPU group compiles
    assert long.runs()[0].total_timesteps == 1_000_000
    by_default = make_backend(Execution("batched", device="cpu"))
    assert by_default.plan(long.runs(), str(tmp_path)).where.endswith(", compiled")
    assert "compiled" not in by_default.plan(tiny().runs(), str(tmp_path)).where
    assert (
        "compiled"
        not in make_backend(Execution("batched", device="cpu", compile=False)).plan(long.runs(), str(tmp_path)).where
    )
