"""The report's cost table: training time per run by setting and scheme, core-hours from what trained each run."""

import csv
import math
from pathlib import Path
from typing import Any

import pytest

from sb3_maddpg.experiments.training_resources import TrainingResources
from sb3_maddpg.results.cost import (
    format_cost_markdown,
    scheme_costs,
    training_core_hours,
    write_cost_report,
)


def summary(scheme: str, seed: int, train_s: float, **extra: Any) -> dict[str, Any]:
    return {
        "experiment": "study",
        "scheme": scheme,
        "seed": seed,
        "total_timesteps": 1_000_000,
        "train_time_s": train_s,
        "eval_time_s": 36.0,
        "train_steps_per_s": 1_000_000 / train_s,
        **extra,
    }


def cpu(threads: int, together: int = 1) -> dict[str, Any]:
    return TrainingResources("cpu", threads, together).to_summary()


def test_core_hours_are_training_hours_times_threads_shared_by_the_runs_trained_together() -> None:
    assert training_core_hours(summary("full", 0, 7200.0, **cpu(2))) == (4.0, "core-h")
    assert training_core_hours(summary("full", 0, 7200.0, **cpu(1, together=4))) == (0.5, "core-h")
    # On a GPU the group's hours are shared, threads do not count.
    gpu = TrainingResources("cuda", 16, 8).to_summary()
    assert training_core_hours(summary("full", 0, 7200.0, **gpu)) == (0.25, "GPU-h")
    assert training_core_hours(summary("full", 0, 7200.0)) is None  # a run written before 0.3


def test_costs_per_scheme_hold_each_runs_hours_in_the_papers_order() -> None:
    runs = [
        summary("selected", 0, 3600.0, **cpu(1)),
        summary("full", 0, 1800.0, **cpu(1)),
        summary("full", 1, 5400.0, **cpu(1)),
    ]
    full, selected = scheme_costs(runs)
    assert (full.scheme, full.runs, selected.scheme, selected.runs) == ("full", 2, "selected", 1)
    assert full.train_hours == (0.5, 1.5) and full.core_hours == (0.5, 1.5) and full.unit == "core-h"
    assert full.eval_hours == (0.01, 0.01)
    assert math.isclose(full.total_hours, 2.02)
    assert full.steps_per_s == pytest.approx((555.6, 185.2), abs=0.1)


def test_a_run_groups_training_counts_once_in_the_run_hours_and_is_shared_in_the_core_hours() -> None:
    group = [summary("full", seed, 7200.0, **cpu(1, together=4)) for seed in range(4)]  # 4 runs trained in 2 h
    (cost,) = scheme_costs(group)
    assert cost.train_hours == (2.0,) * 4  # each run's training took the group's 2 h
    assert cost.core_hours == (0.5,) * 4  # one core for 2 h, shared by 4 runs
    assert math.isclose(cost.total_hours, 2.0 + 4 * 0.01)  # the machine was busy 2 h, not 8
    assert "In all: 4 runs, 2.0 run-hours, 2.0 core-h of training." in format_cost_markdown([cost], {})
    (alone,) = scheme_costs(group[:1])
    assert "In all: 1 run, 0.5 run-hours" in format_cost_markdown([alone], {})  # its share of the group


def test_a_scheme_with_a_run_of_unknown_or_other_resources_has_no_core_hours() -> None:
    unknown = scheme_costs([summary("full", 0, 3600.0, **cpu(1)), summary("full", 1, 3600.0)])[0]
    mixed = scheme_costs([summary("full", 0, 3600.0, **cpu(1)), summary("full", 1, 3600.0, device="cuda", torch_threads=1)])[0]
    assert (unknown.core_hours, unknown.unit) == (None, "")
    assert (mixed.core_hours, mixed.unit) == (None, "")


def test_the_markdown_table_says_each_scheme_and_the_studys_total() -> None:
    runs = [
        summary("full", 0, 1800.0, **cpu(1)),
        summary("full", 1, 5400.0, **cpu(1)),
        summary("independent", 0, 3600.0),
    ]
    text = format_cost_markdown(scheme_costs(runs), {})
    lines = text.splitlines()
    full = "| study | MADDPG | 2 | 1,000,000 | 60.0 (30.0-90.0) | 370 (185-556) | 1.000 (0.500-1.500) core-h | "
    full += "36.0 (36.0-36.0) | 2.0 |"
    assert full in lines
    assert "| study | IDDPG | 1 | 1,000,000 | 60.0 | 278 | - | 36.0 | 1.0 |" in lines
    assert lines[-1] == (
        "In all: 3 runs, 3.0 run-hours, 2.0 core-h of training, 1 run(s) not counted in them (no record of what trained "
        "them, or mixed devices)."
    )


def test_the_report_writes_the_table_and_a_csv_of_it(tmp_path: Path) -> None:
    runs = [summary("full", 0, 1800.0, **cpu(2)), summary("full", 1, 5400.0, **cpu(2))]
    written = write_cost_report(tmp_path, runs, {})
    assert [path.name for path in written] == ["cost.md", "cost.csv"]
    (row,) = list(csv.DictReader(written[1].open()))
    assert (row["scheme"], row["method"], row["runs"], row["unit"]) == ("full", "MADDPG", "2", "core-h")
    assert float(row["train_hours_mean"]) == 1.0 and float(row["core_or_gpu_hours_mean"]) == 2.0
    assert (float(row["train_hours_min"]), float(row["train_hours_max"])) == (0.5, 1.5)
    assert float(row["eval_seconds_mean"]) == 36.0
    assert float(row["run_hours_total"]) == pytest.approx(2.02)
