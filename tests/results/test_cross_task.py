"""The table "Which information helps, task by task" (issue 57): normalised per task between random actions and the
better of the scripted reference and the best scheme, complete seeds only, verdicts against ``full`` after Holm within
the task; and the committed table is the committed runs' (regenerated and compared)."""

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sb3_maddpg.analysis.normalised_score import reference_scores
from sb3_maddpg.experiments.results_dir import write_json_atomic
from sb3_maddpg.results.cross_task import TaskStudy, complete_seed_scores, format_cell, task_row
from tests.script_module import load_script

REPO = Path(__file__).resolve().parents[2]


def make_table_module() -> Any:
    return load_script(REPO / "benchmarks" / "cross_task" / "make_table.py")


def write_study(
    root: Path, scores: dict[str, list[float]], random: list[float] | None, metric: str = "return_mean", **stored: Any
) -> None:
    """A results directory of one setting (``stored``: its experiment's fields, a factory's task by default): one run
    per score (seed = index), and its random reference per seed unless ``random`` is None."""
    experiment = root / "task"
    experiment.mkdir(parents=True)
    fields = {"name": "task", "env": "my_pkg:env", "schemes": list(scores), **stored}
    write_json_atomic(experiment / "experiment.json", fields)
    for scheme, values in scores.items():
        for seed, value in enumerate(values):
            run = experiment / scheme / f"seed_{seed:03d}"
            run.mkdir(parents=True)
            summary = {"experiment": "task", "scheme": scheme, "seed": seed, "score": {metric: value}}
            write_json_atomic(run / "summary.json", summary)
            (run / "done").write_text("")
    if random is not None:
        seeds = {str(seed): {"score": {metric: value}} for seed, value in enumerate(random)}
        write_json_atomic(experiment / "references.json", {"policies": {"random": {"seeds": seeds}}})


def test_scores_are_normalised_between_random_and_the_best_scheme_with_holm_verdicts(tmp_path: Path) -> None:
    full = [10.0, 11.0, 12.0, 13.0, 14.0]
    write_study(tmp_path, {"full": full, "independent": [v - 8 for v in full], "actions": [v + 0.5 for v in full]}, [0.0] * 5)
    row = task_row(TaskStudy("task", tmp_path, "task", "return_mean"))
    assert row.seeds == [0, 1, 2, 3, 4] and row.random == 0.0
    assert row.top == 12.5 and row.top_is == "best scheme (actions)"  # the best scheme's mean is 1
    assert row.cells["actions"]["mean"] == pytest.approx(1.0) and row.cells["full"]["mean"] == pytest.approx(12 / 12.5)
    independent = row.cells["independent"]
    assert independent["p"] == pytest.approx(2 / 252) and independent["p_holm"] == pytest.approx(4 / 252)  # family of 2
    assert independent["verdict"] == "below"
    assert row.cells["actions"]["verdict"] == "not separated"  # overlapping runs
    assert "verdict" not in row.cells["full"]
    assert format_cell(independent).endswith("below, p = .008 (Holm = .016)")


def test_a_p_below_a_thousandth_prints_as_the_readme_prints_it() -> None:
    # 7 runs a side without overlap: 2 / C(14, 7) = .00058, which rounds to .001 but the README prints "< .001".
    cell = {"mean": 0.8, "low": 0.7, "high": 0.9, "verdict": "below", "p": 2 / 3432, "p_holm": 0.003}
    assert format_cell(cell) == "0.80 [0.70, 0.90]; below, p < .001 (Holm = .003)"


def test_a_lower_is_better_metric_is_flipped_and_its_top_is_the_scripted_controller(tmp_path: Path) -> None:
    full = [1.0, 1.1, 1.2, 1.3, 1.4]
    write_study(
        tmp_path, {"full": full, "selected": [v - 0.5 for v in full]}, None, "min_dist_sum", env="simple_spread", n_agents=3
    )
    row = task_row(TaskStudy("spread", tmp_path, "task", "min_dist_sum"))
    references = reference_scores(3)
    random, scripted = references["random"]["min_dist_sum"], references["scripted"]["min_dist_sum"]
    assert row.random == random and row.top == scripted and row.top_is == "scripted controller"
    assert "lower is better" in row.label
    expected = np.mean([(v - 0.5 - random) / (scripted - random) for v in full])
    assert row.cells["selected"]["mean"] == pytest.approx(expected)
    assert row.cells["selected"]["mean"] > row.cells["full"]["mean"]  # fewer distance is higher on the scale
    assert row.cells["selected"]["verdict"] == "above" and row.cells["selected"]["p_holm"] == pytest.approx(2 / 252)


def test_a_task_nothing_learns_has_a_row_that_says_so_and_no_cells(tmp_path: Path) -> None:
    write_study(tmp_path, {"full": [-5.0, -6.0], "actions": [-7.0, -8.0]}, [-1.0, -1.0])
    row = task_row(TaskStudy("task", tmp_path, "task", "return_mean"))
    assert row.top_is == "nothing beats random actions yet (-1)" and row.cells == {} and row.seeds == [0, 1]


def test_only_seeds_every_declared_scheme_finished_count(tmp_path: Path) -> None:
    summaries = [{"experiment": "e", "scheme": "full", "seed": seed, "score": {"m": float(seed)}} for seed in (0, 1, 2)] + [
        {"experiment": "e", "scheme": "selected", "seed": 1, "score": {"m": 5.0}}
    ]
    assert complete_seed_scores(summaries, "e", ["full", "selected"], "m") == {"full": {1: 1.0}, "selected": {1: 5.0}}
    assert complete_seed_scores(summaries, "e", ["full", "selected", "actions"], "m") == {
        "full": {},
        "selected": {},
        "actions": {},
    }


def test_a_task_without_a_random_reference_is_refused_with_what_to_run(tmp_path: Path) -> None:
    write_study(tmp_path, {"full": [1.0]}, [0.0])
    (tmp_path / "task" / "references.json").unlink()
    with pytest.raises(ValueError, match=r"no random reference for 'task'.*reference_policies"):
        task_row(TaskStudy("task", tmp_path, "task", "return_mean"))


def test_the_committed_table_is_the_committed_runs() -> None:
    module = make_table_module()
    data, rst = module.table()
    committed = json.loads(module.TABLE_JSON.read_text())
    assert data == committed, "benchmarks/cross_task/table.json is stale: run python benchmarks/cross_task/make_table.py"
    assert rst == module.TABLE_RST.read_text(), "docs/guide/cross_task_table.inc is stale: run the same command"
    exp1 = next(row for row in data if row["experiment"] == "paper_n5i_exp1")
    assert len(exp1["seeds"]) >= 5 and not math.isnan(exp1["cells"]["full"]["mean"])
