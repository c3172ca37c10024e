"""Tests of run groups as Ray tasks (``sb3-maddpg run --backend batched-ray``): one task per group, a GPU each on
CUDA, the files of ``--backend batched`` without Ray, refusals before Ray starts."""

import dataclasses
import json
import sys
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from sb3_maddpg.cli.main import main
from sb3_maddpg.experiments import SMOKE, ray_tasks, run_sweep
from sb3_maddpg.experiments.backends import Execution
from sb3_maddpg.experiments.batched import train_groups_on_ray
from sb3_maddpg.experiments.group_plan import BatchedRunRefused, plan_groups
from sb3_maddpg.experiments.local_pool import LOST_RUN
from sb3_maddpg.experiments.ray_tasks import RAY_MAX_RETRIES, ray_task_options, run_ray
from sb3_maddpg.experiments.results_dir import SWEEP_LOG, load_summaries
from sb3_maddpg.experiments.setting import RunConfig
from tests.experiments.test_batched_backend import files, keys, read_rows

WARM_UP_ONLY = dataclasses.replace(
    SMOKE,
    name="tiny",
    schemes=("full",),
    seeds=(0, 1),
    keep_checkpoints=True,
    model_kwargs={**SMOKE.model_kwargs, "learning_starts": 10_000},
)
"""Two seeds of tiny runs without updates: both ways of running a group write the models' initial weights, so
every evaluation must agree exactly."""


@pytest.fixture(scope="module")
def both(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The experiment through ``--backend batched`` in this process and through ``batched-ray`` on a local instance."""
    pytest.importorskip("ray", reason="the Ray test needs ray (installed in CI through the dev extra)")
    config = tmp_path_factory.mktemp("config") / "tiny.json"
    config.write_text(json.dumps(WARM_UP_ONLY.to_dict()))
    results = {}
    for name, extra in (("batched", ["--backend", "batched"]), ("ray", ["--backend", "batched-ray", "--workers", "1"])):
        path = tmp_path_factory.mktemp(name)
        args = ["run", "--config", str(config), "--results", str(path), "--device", "cpu"]
        assert main([*args, "--quiet", *extra]) == 0
        results[name] = path
    return results


@pytest.mark.slow
def test_a_group_on_ray_writes_what_it_writes_in_this_process(both: dict[str, Path]) -> None:
    batched, ray = both["batched"], both["ray"]
    for config in WARM_UP_ONLY.runs():
        ours, theirs = ray / config.run_id, batched / config.run_id
        assert files(ours) == files(theirs), config.run_id  # checkpoints included
        for name in ("summary.json", "config.json"):
            assert keys(json.loads((ours / name).read_text())) == keys(json.loads((theirs / name).read_text())), name
        for name in ("checkpoint_evals.csv", "learning_curve.csv"):  # the same initial teams: the same evaluations
            assert read_rows(ours / name) == read_rows(theirs / name), name
        assert "in a run group of 2 on cpu" in (ours / "train.log").read_text()  # one task trained both seeds
    assert len(load_summaries(ray)) == 2
    log = (ray / SWEEP_LOG).read_text()
    assert "in 1 run group(s) of up to 2 run(s) on cpu, a Ray task each" in log
    assert "Ray: 1 run group(s) at once (1 CPU(s) each) on cpu; a group's runs are reported as it ends" in log
    assert "[2/2] tiny/full/seed_001 done in" in log and "sweep finished: 2 run(s)" in log


def test_a_group_task_asks_for_a_gpu_on_cuda() -> None:
    assert ray_task_options(2, "cuda") == {"num_gpus": 1, "num_cpus": 2, "max_retries": RAY_MAX_RETRIES}
    assert ray_task_options(1, "cuda:0")["num_gpus"] == 1
    assert ray_task_options(3, "cpu") == {"num_cpus": 3, "max_retries": RAY_MAX_RETRIES}  # a run's task as before


class FakeRay:
    """What :func:`train_groups_on_ray` uses of Ray: its tasks' options and arguments recorded, none run."""

    class WorkerCrashedError(Exception):
        pass

    def __init__(self, resources: dict[str, float], crash: bool = False) -> None:
        self.resources = resources
        self.crash = crash
        self.options: list[dict[str, Any]] = []
        self.submitted: list[tuple[Any, ...]] = []
        self.exceptions = types.SimpleNamespace(
            WorkerCrashedError=self.WorkerCrashedError, NodeDiedError=self.WorkerCrashedError, OutOfMemoryError=OSError
        )

    def is_initialized(self) -> bool:
        return True  # "connected": nothing started or shut down

    def cluster_resources(self) -> dict[str, float]:
        return self.resources

    def remote(self, **options: Any) -> Any:
        self.options.append(options)
        return lambda task: types.SimpleNamespace(remote=lambda *args: self._submit(args))

    def _submit(self, args: tuple[Any, ...]) -> int:
        self.submitted.append(args)
        return len(self.submitted) - 1

    def wait(self, pending: list[int], num_returns: int) -> tuple[list[int], list[int]]:
        return pending[:num_returns], pending[num_returns:]

    def get(self, ref: int) -> list[dict[str, Any]]:
        if self.crash:
            raise self.WorkerCrashedError("the worker died")
        return [{"run_id": config.run_id, "files": {"summary.json": "{}"}} for config in self.submitted[ref][0]]


def run_on(
    fake: FakeRay,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    device: str = "auto",
    on_parallel: Callable[[int, str], None] | None = None,
) -> list[tuple[str, Any]]:
    """Four seeds in groups of two through :func:`train_groups_on_ray` on ``fake``: what each run reported."""
    monkeypatch.setitem(sys.modules, "ray", fake)
    reported: list[tuple[str, Any]] = []

    def on_result(config: RunConfig, result: dict[str, Any] | None, error: str | None) -> None:
        reported.append((config.run_id, result if error is None else error))

    configs = dataclasses.replace(WARM_UP_ONLY, seeds=(0, 1, 2, 3)).runs()
    execution = Execution("batched-ray", threads=2, device=device, runs_per_process=2)
    train_groups_on_ray(plan_groups(configs, 2), str(tmp_path), on_result, execution, on_parallel)
    return reported


def test_groups_are_submitted_one_task_each_with_a_gpu(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    slots: list[tuple[int, str]] = []
    fake = FakeRay({"CPU": 16.0, "GPU": 3.0})
    reported = run_on(fake, tmp_path, monkeypatch, on_parallel=lambda n, device: slots.append((n, device)))
    # device "auto" on a cluster with GPUs: CUDA, one GPU per group task; 3 GPUs train 3 groups at once.
    assert fake.options == [{"num_gpus": 1, "num_cpus": 2, "max_retries": RAY_MAX_RETRIES}]
    assert [[c.seed for c in args[0]] for args in fake.submitted] == [[0, 1], [2, 3]]
    assert all(args[2] == "cuda" for args in fake.submitted) and slots == [(3, "cuda")]
    assert [run_id for run_id, _ in reported] == [f"tiny/full/seed_00{seed}" for seed in range(4)]
    assert all((tmp_path / run_id / "done").exists() for run_id, _ in reported)  # the files written here too

    cpu = FakeRay({"CPU": 16.0, "GPU": 3.0})
    run_on(cpu, tmp_path / "cpu", monkeypatch, device="cpu")
    assert cpu.options == [{"num_cpus": 2, "max_retries": RAY_MAX_RETRIES}] and cpu.submitted[0][2] == "cpu"
    auto = FakeRay({"CPU": 4.0})
    run_on(auto, tmp_path / "auto", monkeypatch)
    assert "num_gpus" not in auto.options[0] and auto.submitted[0][2] == "cpu"  # no GPU in the cluster: the CPU

    none = FakeRay({"CPU": 16.0})
    with pytest.raises(BatchedRunRefused, match="under Ray: the Ray cluster has no GPU"):
        run_on(none, tmp_path / "none", monkeypatch, device="cuda")
    assert not none.submitted  # a task that would wait forever for a GPU is never submitted


def test_a_lost_group_fails_each_of_its_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    reported = run_on(FakeRay({"CPU": 4.0}, crash=True), tmp_path, monkeypatch)
    assert len(reported) == 4 and all(error.startswith(LOST_RUN) for _, error in reported)  # counted as lost


def test_refusals_come_before_ray_starts(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray fails: the refusal must come before it
    args = ["run", "--config", "smoke", "--results", str(tmp_path), "--backend", "batched-ray"]
    assert main([*args, "--schemes", "attention"]) == 2
    assert capsys.readouterr().err.startswith(
        "sb3-maddpg run: smoke/attention/seed_000 (and its other seeds) cannot train in a run group"
    )
    with pytest.raises(BatchedRunRefused, match="batched worlds only"):
        run_sweep([dataclasses.replace(WARM_UP_ONLY, vec_env="mpe2")], tmp_path, backend="batched-ray", verbose=0)
    assert not (tmp_path / "smoke").exists() and not (tmp_path / "tiny").exists()  # nothing trained or written

    # --ray-address is Ray's: with a backend that trains on this machine it would be ignored.
    assert main([*args[:-1], "batched", "--ray-address", "auto"]) == 2
    assert "--ray-address is Ray's, but --backend batched trains on this machine" in capsys.readouterr().err


def test_runs_alone_on_ray_take_a_gpu_each_on_cuda_and_are_refused_where_none_is(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    configs = dataclasses.replace(WARM_UP_ONLY, seeds=(0, 1)).runs()

    def submit(fake: FakeRay, device: str) -> list[int]:
        monkeypatch.setitem(sys.modules, "ray", fake)
        at_once: list[int] = []
        run_ray(configs, str(tmp_path / device), lambda *_: None, threads=2, on_parallel=at_once.append, device=device)
        return at_once

    gpus = FakeRay({"CPU": 16.0, "GPU": 3.0})
    assert submit(gpus, "cuda:1") == [3]  # 3 GPUs: 3 runs at once, however many CPUs
    assert gpus.options == [{"num_gpus": 1, "num_cpus": 2, "max_retries": RAY_MAX_RETRIES}]
    assert [args[2] for args in gpus.submitted] == ["cuda", "cuda"]  # the GPU Ray gives the task: its device 0
    cpus = FakeRay({"CPU": 4.0})
    assert submit(cpus, "auto") == [2] and "num_gpus" not in cpus.options[0] and cpus.submitted[0][2] == "cpu"
    for device, cause in (("cuda", "the Ray cluster has no GPU"), ("gpu", "not a device torch knows")):
        none = FakeRay({"CPU": 16.0})
        with pytest.raises(BatchedRunRefused, match=cause):
            submit(none, device)
        assert not none.submitted  # refused before any task: none would wait forever or fail on its node


def test_a_ray_task_trains_its_runs_on_its_device(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[tuple[str, Any]] = []
    monkeypatch.setattr(ray_tasks, "execute_run", lambda config, results, **kwargs: seen.append((config.run_id, kwargs)))
    configs = WARM_UP_ONLY.runs()
    ray_tasks.execute_runs(configs, "results", "cuda", 2, 0)
    ray_tasks.execute_runs_without_snapshots(configs[:1], "results", "cpu", 1, 0)
    assert [kwargs["device"] for _, kwargs in seen] == ["cuda", "cuda", "cpu"]
    assert seen[-1][1]["snapshots"] is False
