"""How many runs a group holds: sized from the replay buffers a group really allocates, bounded by the device's and the
host's memory, and the batched backend splits a setting's seeds into groups that fit (or refuses one that cannot)."""

import dataclasses
from pathlib import Path
from typing import Any

import pytest
import torch as th

import sb3_maddpg.run_group.memory as memory
from sb3_maddpg.experiments import SMOKE, ExperimentConfig, run_sweep
from sb3_maddpg.experiments.group_plan import BatchedRunRefused, check_batched, memory_bound, plan_groups
from sb3_maddpg.experiments.runner import build_model
from sb3_maddpg.experiments.tasks import run_task
from sb3_maddpg.run_group import RunGroup
from sb3_maddpg.run_group.memory import run_buffer_nbytes, runs_that_fit


def tiny(seeds: int = 7, **model_kwargs: Any) -> ExperimentConfig:
    """The smoke preset's tiny networks, ``full`` sharing (and ``selected``, which stores selections), ``seeds`` seeds."""
    return dataclasses.replace(
        SMOKE,
        name="tiny",
        schemes=("full", "selected"),
        seeds=tuple(range(seeds)),
        model_kwargs={**SMOKE.model_kwargs, **model_kwargs},
    )


@pytest.mark.parametrize("scheme", ["full", "selected"])
def test_one_runs_bytes_are_those_its_group_allocates(scheme: str) -> None:
    config = next(run for run in tiny(buffer_size=1_030).runs() if run.scheme == scheme)  # not a whole number of steps
    model = build_model(run_task(config), device="cpu")
    assert RunGroup([model]).buffers.nbytes() == run_buffer_nbytes(model)
    pair = RunGroup([model, build_model(run_task(dataclasses.replace(config, seed=1)), device="cpu")]).buffers.nbytes()
    assert pair <= 2 * run_buffer_nbytes(model) < 1.01 * pair  # the runs share the steps' bookkeeping: a bound


def test_runs_that_fit_take_the_tighter_of_device_and_host(monkeypatch: pytest.MonkeyPatch) -> None:
    model = build_model(run_task(tiny().runs()[0]), device="cpu")
    run_bytes = run_buffer_nbytes(model)
    # On the CPU: 40% of the host (the buffers and a save's copy of their rows).
    on_cpu = runs_that_fit(model, "cpu", host_bytes=100 * run_bytes)
    assert (on_cpu.runs, on_cpu.run_bytes) == (40, run_bytes) and "40% of the host" in on_cpu.limit
    # On a GPU: 80% of the device, and of the host (a save copies the state there), whichever is less.
    monkeypatch.setattr(memory, "device_memory", lambda device: 50 * run_bytes)
    assert runs_that_fit(model, th.device("cuda"), host_bytes=100 * run_bytes).runs == 40
    tight_host = runs_that_fit(model, th.device("cuda"), host_bytes=20 * run_bytes)
    assert tight_host.runs == 16 and "host" in tight_host.limit
    with pytest.raises(ValueError, match=r"One run's replay buffer \(.* GB\) does not fit in 40% of the host's"):
        runs_that_fit(model, "cpu", host_bytes=run_bytes)


def test_a_settings_seeds_are_split_into_groups_that_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    configs = tiny(seeds=7).runs()
    full, selected = (run_buffer_nbytes(build_model(run_task(config), device="cpu")) for config in configs[:2])
    assert full < selected < 1.3 * full  # the selected runs store their selections too
    run_bytes = selected
    monkeypatch.setattr(memory, "host_memory", lambda: int(7.5 * run_bytes))  # 40% of it: 3 runs of either scheme
    lines: list[str] = []
    groups = plan_groups(configs, most_runs=memory_bound("cpu", log=lines.append))
    sizes = [(group[0].scheme, [run.seed for run in group]) for group in groups]
    assert sizes == [
        ("full", [0, 1, 2]),
        ("full", [3, 4, 5]),
        ("full", [6]),
        ("selected", [0, 1, 2]),
        ("selected", [3, 4, 5]),
        ("selected", [6]),
    ]
    assert len(lines) == 2 and lines[0].startswith("tiny/full: groups of at most 3 runs (each run's replay buffer")
    # --runs-per-process wins; seeds that fit in one group stay one group, without a line.
    assert [len(group) for group in plan_groups(configs, 5, memory_bound("cpu"))] == [5, 2, 5, 2]
    monkeypatch.setattr(memory, "host_memory", lambda: 100 * run_bytes)
    assert [len(group) for group in plan_groups(configs, most_runs=memory_bound("cpu", log=lines.append))] == [7, 7]
    assert len(lines) == 2


def test_runs_whose_buffers_cannot_fit_are_refused_before_training(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(memory, "host_memory", lambda: 1_000)
    with pytest.raises(BatchedRunRefused, match=r"tiny/full/seed_000 .*cannot train in a run group.*does not fit"):
        check_batched(tiny().runs(), device="cpu")
    check_batched(tiny().runs(), device=None)  # under Ray the workers' machines hold the buffers: not checked here


def test_a_sweep_says_its_split_and_trains_groups_that_fit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    experiment = dataclasses.replace(tiny(seeds=3), schemes=("full",))
    run_bytes = run_buffer_nbytes(build_model(run_task(experiment.runs()[0]), device="cpu"))
    monkeypatch.setattr(memory, "host_memory", lambda: int(5.5 * run_bytes))  # 40% of it: 2 runs
    result = run_sweep([experiment], tmp_path, backend="batched", device="cpu", verbose=0)
    assert result.ok and len(result.completed) == 3
    log = (tmp_path / "sweep.log").read_text()
    assert "in 2 run group(s) of up to 2 run(s) on cpu" in log
    assert "tiny/full: groups of at most 2 runs (each run's replay buffer" in log


def test_a_sweep_warns_of_groups_asked_for_that_may_not_fit(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    experiment = dataclasses.replace(tiny(seeds=3), schemes=("full",))
    run_bytes = run_buffer_nbytes(build_model(run_task(experiment.runs()[0]), device="cpu"))
    monkeypatch.setattr(memory, "host_memory", lambda: int(5.5 * run_bytes))  # 40% of it: 2 runs
    result = run_sweep([experiment], tmp_path, backend="batched", device="cpu", verbose=0, runs_per_process=3)
    assert result.ok and len(result.completed) == 3  # as asked: one group of 3 (tiny buffers, no harm here)
    log = (tmp_path / "sweep.log").read_text()
    assert "in 1 run group(s) of up to 3 run(s)" in log
    assert "tiny/full: groups of 3 runs (runs_per_process) may not fit in memory: 2 fit by the package's estimate" in log
