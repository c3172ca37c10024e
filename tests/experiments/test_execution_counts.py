"""A sweep's worker and thread counts are refused by name before anything runs, by ``run_sweep``'s ``Execution`` and
by ``sb3-maddpg run``, its dry run included; the counts each backend takes are taken."""

from pathlib import Path
from typing import Any

import pytest

from sb3_maddpg.cli.main import main
from sb3_maddpg.experiments.backends import BACKENDS, Execution


@pytest.mark.parametrize(
    ("backend", "field", "value", "lowest"),
    [
        ("local", "workers", 0, 1),
        ("local", "workers", -3, 1),
        ("local", "workers", 1.5, 1),
        ("local", "workers", True, 1),
        ("ray", "workers", -1, 0),
        ("batched-ray", "workers", -2, 0),
        ("local", "threads", 0, 1),
        ("batched", "threads", -1, 1),
    ],
)
def test_counts_out_of_range_are_refused_by_name(backend: str, field: str, value: Any, lowest: int) -> None:
    backend_named = f"{backend} backend" if field == "workers" else ""
    with pytest.raises(ValueError, match=rf"^{field} \(.*{backend_named}\) must be an integer >= {lowest}, got "):
        Execution(backend, **{field: value})


@pytest.mark.parametrize("backend", list(BACKENDS))
def test_the_counts_each_backend_takes(backend: str) -> None:
    assert Execution(backend, workers=2, threads=2).workers == 2
    if backend != "local":
        assert Execution(backend, workers=0).ray_cpus is None  # 0: all CPUs


def test_runs_per_process_below_one_is_refused_before_planning() -> None:
    with pytest.raises(ValueError, match=r"^runs_per_process must be at least 1, got 0"):
        Execution("batched", runs_per_process=0)


@pytest.mark.parametrize("options", [["--workers", "0"], ["--workers", "-3"], ["--threads", "0"]])
def test_run_refuses_the_counts_in_a_dry_run(options: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["run", "--config", "smoke", "--results", str(tmp_path / "runs"), "--dry-run", *options]
    assert main(argv) == 2
    error = capsys.readouterr().err
    assert error.startswith(f"sb3-maddpg run: {options[0]} (") and "must be an integer >= 1" in error
    assert not (tmp_path / "runs").exists()


def test_run_names_a_field_by_its_option(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["run", "--config", "smoke", "--results", str(tmp_path), "--dry-run", "--backend", "batched"]
    assert main([*argv, "--runs-per-process", "0"]) == 2
    assert capsys.readouterr().err.startswith("sb3-maddpg run: --runs-per-process must be at least 1, got 0")
