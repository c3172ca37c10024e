"""Issue 43's budget rule (``benchmarks/paper_n5_independent/curve_summary.py``): the budget it picks on hand-built
curves, where it reads a curve at a budget, what the summary says of the study's budget, and the committed summaries
against the committed curves."""

from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from sb3_maddpg.analysis.normalised_score import reference_scores
from tests.script_module import load_script

REPO = Path(__file__).resolve().parents[2]
HERE = REPO / "benchmarks" / "paper_n5_independent"
SCRIPT = HERE / "curve_summary.py"
GRID = np.arange(0, 2_500_001, 250_000, dtype=float)  # 0, 250k, ..., 2.5M: 11 points


@pytest.fixture(scope="module")
def curve_summary() -> ModuleType:
    return load_script(SCRIPT)


def write_curve(results: Path, experiment: str, seed: int, steps: np.ndarray, normalised: np.ndarray) -> None:
    """A curve run's learning curve whose min-dist sums sit at ``normalised`` on the scale the script uses."""
    references = reference_scores(5)
    random, scripted = references["random"]["min_dist_sum"], references["scripted"]["min_dist_sum"]
    directory = results / experiment / "full" / f"seed_{seed:03d}"
    directory.mkdir(parents=True)
    rows = "".join(f"{step},{random - score * (random - scripted)}\n" for step, score in zip(steps, normalised))
    (directory / "learning_curve.csv").write_text("timesteps,min_dist_sum\n" + rows)


def test_rule_picks_the_shortest_budget_every_seed_meets(curve_summary: ModuleType) -> None:
    # Seed a meets the rule from 1.5M (0.875, the rest adds 0.025); at 1.25M the rest still adds 0.0625.
    seed_a = np.array([0.1, 0.3, 0.6, 0.7, 0.8, 0.8375, 0.875, 0.89, 0.9, 0.9, 0.9])
    # Seed b reaches 0.5 itself at 1.5M (the threshold counts as left behind) and adds 0.03 after it.
    seed_b = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.45, 0.5, 0.52, 0.53, 0.53, 0.53])
    assert curve_summary.chosen_budget(GRID, [seed_a, seed_b]) == 1_500_000
    assert curve_summary.chosen_budget(GRID, [seed_a]) == 1_500_000
    assert curve_summary.chosen_budget(GRID, [seed_b]) == 1_500_000
    # Still gaining 0.06 after every candidate but the last: only the curve's end, where nothing is left to add.
    gaining = np.linspace(0.3, 0.9, len(GRID))
    assert curve_summary.chosen_budget(GRID, [seed_a, gaining]) == 2_500_000
    # Never leaving random actions behind: no budget.
    assert curve_summary.chosen_budget(GRID, [np.full(len(GRID), 0.4)]) is None


def test_at_budget_reads_the_first_point_at_or_past_the_budget(curve_summary: ModuleType) -> None:
    steps = np.array([0.0, 900_000.0, 1_800_000.0, 2_500_000.0])
    scores = [np.array([0.1, 0.6, 0.8, 0.82]), np.array([0.2, 0.5, 0.7, 0.75])]
    read = curve_summary.at_budget(steps, scores, 1_750_000)
    assert read is not None and np.allclose(read, [(0.8, 0.02), (0.7, 0.05)])
    assert curve_summary.at_budget(steps, scores, 1_800_000) == read  # a point at the budget is read there
    assert curve_summary.at_budget(steps, scores, 2_600_000) is None  # the curves end before it
    assert curve_summary.meets_rule([(0.8, 0.02)]) and not curve_summary.meets_rule([(0.8, 0.02), (0.7, 0.06)])
    assert not curve_summary.meets_rule([(0.49, 0.0)])
    assert not curve_summary.meets_rule([(0.8, curve_summary.STILL_GAINING)])  # adding 0.05 is still gaining
    assert curve_summary.meets_rule([(curve_summary.LEFT_RANDOM, 0.0)])  # at 0.5 random actions are left behind


def test_summary_says_whether_the_study_budget_meets_the_rule(curve_summary: ModuleType, tmp_path: Path) -> None:
    steps = np.arange(0, 2_500_001, 50_000, dtype=float)
    flat = np.where(steps < 500_000, 0.2, 0.8)  # left random actions behind at 500k, then flat
    slow = np.linspace(0.0, 0.4, len(steps))  # never >= 0.5; its running mean is linear but at the end
    for seed, curve in enumerate((flat, flat)):
        write_curve(tmp_path / "meets", "paper_n5i_exp2_curve", seed, steps, curve)
    for seed, curve in enumerate((flat, slow)):
        write_curve(tmp_path / "fails", "paper_n5i_exp2_curve", seed, steps, curve)

    meets = curve_summary.summary("exp2", tmp_path / "meets")
    assert "**Budget: 750,000 env steps.**\n" in meets  # the running mean reaches 0.8 two points past 500k
    assert "The curve's end" not in meets
    assert "The study's budget, 1,750,000 env steps (the rule's pick on Exp. 1's curve), meets the rule here" in meets
    assert "seed 0: 0.80, the rest adds +0.00; seed 1: 0.80, the rest adds +0.00" in meets
    assert "Made by `python benchmarks/paper_n5_independent/curve_summary.py --setting exp2`" in meets

    for seed in (0, 1):
        write_curve(tmp_path / "late", "paper_n5i_exp2_curve", seed, steps, np.linspace(0.0, 1.0, len(steps)))
    late = curve_summary.summary("exp2", tmp_path / "late")
    assert "**Budget: 2,500,000 env steps.** (The curve's end: the rule cannot tell" in late
    assert "meets the rule here" not in late

    fails = curve_summary.summary("exp2", tmp_path / "fails")
    assert "**No budget meets the rule within the curve.**" in fails
    assert "does not meet the rule here" in fails
    assert "seed 1: 0.28, the rest adds +0.11" in fails  # 0.4 x 35/50; the end: 0.4 x 49/50


def test_summary_of_a_running_curve_has_no_budget(curve_summary: ModuleType, tmp_path: Path) -> None:
    steps = np.arange(0, 1_800_001, 50_000, dtype=float)
    write_curve(tmp_path, "paper_n5i_exp2_curve", 0, steps, np.full(len(steps), 0.8))
    text = curve_summary.summary("exp2", tmp_path)
    assert "**The curve is still running (1,800,000 of 2,500,000 steps): no budget yet.**" in text
    assert "The study's budget" not in text


def test_summary_without_curves_names_the_directory_and_the_command(curve_summary: ModuleType, tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"^no learning curves under .*paper_n5i_exp2_curve/full: run `bash"):
        curve_summary.summary("exp2", tmp_path)


@pytest.mark.parametrize("setting", ["exp1", "exp2"])
def test_committed_summary_matches_the_committed_curves(curve_summary: ModuleType, setting: str) -> None:
    curve = curve_summary.SETTINGS[setting]
    committed = HERE / curve.summary
    if not committed.exists():
        pytest.skip(f"{curve.summary} is written once {setting}'s curve runs are committed")
    assert curve_summary.summary(setting, HERE / "results") == committed.read_text(), (
        f"{curve.summary} is stale: run `python benchmarks/paper_n5_independent/curve_summary.py --setting {setting}`"
    )


def test_summary_labels_seeds_by_number_and_refuses_curves_on_other_steps(curve_summary: ModuleType, tmp_path: Path) -> None:
    steps = np.arange(0, 2_500_001, 50_000, dtype=float)
    for seed in (2, 10):
        write_curve(tmp_path / "labels", "paper_n5i_exp2_curve", seed, steps, np.full(len(steps), 0.8))
    text = curve_summary.summary("exp2", tmp_path / "labels")
    assert "Seeds 2, 10;" in text and "| seed 10: min-dist / normalised (smoothed) |" in text
    assert "seed 2: 0.80, the rest adds +0.00; seed 10: 0.80" in text

    write_curve(tmp_path / "grids", "paper_n5i_exp2_curve", 0, steps, np.full(len(steps), 0.8))
    write_curve(tmp_path / "grids", "paper_n5i_exp2_curve", 1, steps + 25_000, np.full(len(steps), 0.8))
    with pytest.raises(ValueError, match=r"^seed 1's learning curve is evaluated at other env steps than seed 0's"):
        curve_summary.summary("exp2", tmp_path / "grids")
