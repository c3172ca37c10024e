"""Issue 56, item 4's reading (``benchmarks/paper_n5_independent/fixed_graph.py``): the fixed neighbour graph against
Exp. 1's ``full`` and ``selected``, its family Holm-adjusted, and the reading its docstring declares."""

import json
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest
from scipy.stats import ttest_ind

from sb3_maddpg.results.stats import mann_whitney
from tests.script_module import load_script

REPO = Path(__file__).resolve().parent.parent.parent
SCRIPT = REPO / "benchmarks" / "paper_n5_independent" / "fixed_graph.py"
EXP1_CONFIG = REPO / "benchmarks" / "paper_n5_independent" / "results" / "paper_n5i_exp1" / "experiment.json"


@pytest.fixture(scope="module")
def fixed_graph() -> ModuleType:
    return load_script(SCRIPT)


def runs(fixed: list[float], full: list[float], selected: list[float], metric: str = "min_dist_sum") -> dict:
    """Scores by scheme and seed, as :func:`read_runs` returns them."""
    by_scheme = {"selected_fixed": fixed, "full": full, "selected": selected}
    return {scheme: {seed: {metric: score} for seed, score in enumerate(scores)} for scheme, scores in by_scheme.items()}


FULL = [0.50, 0.52, 0.54, 0.56, 0.58]
SELECTED = [1.0, 1.1, 1.2, 1.3, 1.4]


def test_the_family_is_two_tests_holm_adjusted_with_welch_intervals(fixed_graph: ModuleType) -> None:
    fixed = [0.51, 0.53, 0.55, 0.57, 0.60]
    family = fixed_graph.compare(runs(fixed, FULL, SELECTED), "min_dist_sum")
    assert [comparison.against for comparison in family] == ["full", "selected"]
    against_full, against_selected = family
    p_full = mann_whitney(fixed, FULL)[1]
    assert against_selected.p_value == pytest.approx(2 / 252)  # no overlap: the floor at 5 a side
    # Holm over two: the smaller p doubled, the larger kept (not below the smaller's adjustment).
    assert against_selected.p_holm == pytest.approx(2 * 2 / 252)
    assert against_full.p_holm == pytest.approx(max(p_full, 2 * 2 / 252))
    welch = ttest_ind(fixed, SELECTED, equal_var=False).confidence_interval()
    assert against_selected.difference.value == pytest.approx(sum(fixed) / 5 - sum(SELECTED) / 5)
    assert (against_selected.difference.low, against_selected.difference.high) == pytest.approx((welch.low, welch.high))
    assert against_selected.verdict() == "the fixed graph scores better"  # lower min-dist sum is better
    assert against_full.verdict() == f"not separated (p = {fixed_graph.format_p_value(p_full)})"
    assert fixed_graph.reading(family).startswith("the distance:")


@pytest.mark.parametrize(
    "fixed, reading",
    [
        ([1.05, 1.15, 1.25, 1.35, 1.45], "selection itself:"),  # as bad as `selected`, worse than `full`
        ([0.70, 0.72, 0.74, 0.76, 0.78], "both in part:"),  # between the two, apart from both
        ([0.5, 0.6, 0.9, 1.2, 1.3], "not decided at these runs:"),  # overlaps both
    ],
)
def test_the_declared_reading(fixed_graph: ModuleType, fixed: list[float], reading: str) -> None:
    assert fixed_graph.reading(fixed_graph.compare(runs(fixed, FULL, SELECTED), "min_dist_sum")).startswith(reading)


def test_a_rate_is_better_higher(fixed_graph: ModuleType) -> None:
    """Success within 0.3: higher is better, so the fixed graph's higher runs beat `selected`'s lower ones."""
    rates = runs(
        [0.70, 0.72, 0.74, 0.76, 0.78], [0.71, 0.73, 0.75, 0.77, 0.79], [0.2, 0.25, 0.3, 0.35, 0.4], "success_rate_r0.3"
    )
    against_full, against_selected = fixed_graph.compare(rates, "success_rate_r0.3")
    assert against_selected.fixed_better() and not against_selected.fixed_worse()
    assert not against_full.fixed_better() and not against_full.fixed_worse()
    page = fixed_graph.page(rates, {"success_rate_r0.3": [against_full, against_selected]})
    assert "| success rate within 0.3 (%), higher is better | `selected` | 74.00 vs 30.00 | 44.00 [" in page


def write_run(results: Path, experiment: str, scheme: str, seed: int, score: float, done: bool = True) -> None:
    directory = results / experiment / scheme / f"seed_{seed:03d}"
    directory.mkdir(parents=True)
    summary = {"experiment": experiment, "scheme": scheme, "seed": seed, "score": {"min_dist_sum": score}}
    (directory / "summary.json").write_text(json.dumps(summary))
    if done:
        (directory / "done").write_text("")


def test_runs_are_the_fixed_graph_s_finished_ones_and_exp1_s_complete_seeds(fixed_graph: ModuleType, tmp_path: Path) -> None:
    fixed, study = tmp_path / "fixed", tmp_path / "study"
    write_run(fixed, "paper_n5i_exp1_fixed_graph", "selected_fixed", 0, 0.6)
    write_run(fixed, "paper_n5i_exp1_fixed_graph", "selected_fixed", 1, 0.7)
    write_run(fixed, "paper_n5i_exp1_fixed_graph", "selected_fixed", 2, 0.8, done=False)  # still running
    experiment = json.loads(EXP1_CONFIG.read_text())
    experiment["schemes"] = ["full", "selected", "actions"]
    (study / "paper_n5i_exp1").mkdir(parents=True)
    (study / "paper_n5i_exp1" / "experiment.json").write_text(json.dumps(experiment))
    for seed in (0, 1):
        write_run(study, "paper_n5i_exp1", "full", seed, 0.5 + seed)
        write_run(study, "paper_n5i_exp1", "selected", seed, 1.0 + seed)
    write_run(study, "paper_n5i_exp1", "actions", 0, 0.55)  # seed 1 of `actions` unfinished: seed 1 is not complete
    read = fixed_graph.read_runs(fixed, study)
    assert read == {
        "selected_fixed": {0: {"min_dist_sum": 0.6}, 1: {"min_dist_sum": 0.7}},
        "full": {0: {"min_dist_sum": 0.5}},
        "selected": {0: {"min_dist_sum": 1.0}},
    }


def test_no_finished_run_is_refused_saying_what_to_do(fixed_graph: ModuleType, tmp_path: Path) -> None:
    with pytest.raises(SystemExit, match="holds no finished selected_fixed run: start them"):
        fixed_graph.read_runs(tmp_path / "nothing", tmp_path)


def test_an_undeclared_seed_or_no_exp1_seed_is_refused(fixed_graph: ModuleType, tmp_path: Path) -> None:
    fixed, study = tmp_path / "fixed", tmp_path / "study"
    write_run(fixed, "paper_n5i_exp1_fixed_graph", "selected_fixed", 0, 0.6)
    experiment = {**json.loads(EXP1_CONFIG.read_text()), "schemes": ["full", "selected"]}
    (study / "paper_n5i_exp1").mkdir(parents=True)
    (study / "paper_n5i_exp1" / "experiment.json").write_text(json.dumps(experiment))
    write_run(study, "paper_n5i_exp1", "full", 0, 0.5)  # `selected` has no seed: no complete seed
    with pytest.raises(SystemExit, match="has no seed that every Exp. 1 scheme has finished"):
        fixed_graph.read_runs(fixed, study)
    write_run(fixed, "paper_n5i_exp1_fixed_graph", "selected_fixed", 5, 0.6)
    with pytest.raises(SystemExit, match="is seed 5, not one of the declared seeds 0-4"):
        fixed_graph.read_runs(fixed, study)


def test_the_page_shows_each_metric_s_family_and_the_reading(fixed_graph: ModuleType) -> None:
    scored = runs([0.51, 0.53, 0.55, 0.57, 0.60], FULL, SELECTED)
    page = fixed_graph.page(scored, {"min_dist_sum": fixed_graph.compare(scored, "min_dist_sum")})
    assert "Its 5 runs (seeds 0-4) against Exp. 1's `full` (5 runs) and `selected` (5 runs)" in page
    assert "| sum of min. distances, lower is better | `selected` | 0.55 vs 1.20 | -0.65 [" in page
    assert f"| .008 | {fixed_graph.format_p_value(2 * 2 / 252)} | the fixed graph scores better |" in page
    assert page.rstrip().endswith("the distance: the fixed graph beats `selected` and is not shown worse than `full`.")
    # Exp. 1 at 5 of its declared 10 seeds: an interim look, which the page says.
    assert "**Interim look** (runs: `selected_fixed` 5 of 5, `full` 5 of 10, `selected` 5 of 10)" in page
    assert "**Interim reading** (the min-dist sum" in page


def test_the_reading_is_the_declared_one_at_the_declared_seeds(fixed_graph: ModuleType) -> None:
    whole = runs([0.51, 0.53, 0.55, 0.57, 0.60], FULL * 2, SELECTED * 2)
    assert fixed_graph.is_final(whole)
    page = fixed_graph.page(whole, {"min_dist_sum": fixed_graph.compare(whole, "min_dist_sum")})
    assert "Interim" not in page and "**Reading** (the min-dist sum" in page
    assert not fixed_graph.is_final(runs([0.51, 0.53, 0.55, 0.57], FULL * 2, SELECTED * 2))  # a fixed-graph run missing


def test_the_committed_page_is_the_committed_runs_reading(fixed_graph: ModuleType) -> None:
    """``report.sh`` writes the page once the fixed graph has a finished run; until then there is none. It reads the
    working tree, so a run finished here fails it until ``report.sh`` has run, as the report's own tests do."""
    page = REPO / "docs" / "_static" / "paper_n5_independent" / "fixed_graph.md"
    finished = list(fixed_graph.FIXED_RESULTS.glob("*/*/seed_*/done"))
    assert page.exists() == bool(finished), "run bash benchmarks/paper_n5_independent/report.sh"
    if finished:
        result = subprocess.run([sys.executable, str(SCRIPT)], capture_output=True, text=True, check=True)
        assert page.read_text() == result.stdout.removesuffix("\n"), "fixed_graph.md is stale: run report.sh"
