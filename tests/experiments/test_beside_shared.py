"""Issue 43's 2 x 2 reading (``benchmarks/paper_n5_independent/beside_shared.py``): its gaps, effects and p-values against
a hand computation, which runs it reads, its reading of which factor turns `selected` around, and the committed page
against the committed runs."""

import json
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from scipy.stats import mannwhitneyu, ttest_ind

from sb3_maddpg.results.stats import holm, mann_whitney
from tests.script_module import load_script

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "benchmarks" / "paper_n5_independent" / "beside_shared.py"
COMMITTED = REPO / "docs" / "_static" / "paper_n5_independent" / "beside_shared.md"


@pytest.fixture(scope="module")
def beside_shared() -> ModuleType:
    return load_script(SCRIPT)


def write_run(
    results: Path,
    experiment: str,
    scheme: str,
    seed: int,
    score: float,
    curve: list[tuple[float, float]] | None = None,
    done: bool = True,
) -> None:
    """A finished run's files as a sweep writes them: its summary (min-dist sum ``score``), curve and done marker."""
    directory = results / experiment / scheme / f"seed_{seed:03d}"
    directory.mkdir(parents=True)
    summary = {"experiment": experiment, "scheme": scheme, "seed": seed, "score": {"min_dist_sum": score}}
    (directory / "summary.json").write_text(json.dumps(summary))
    rows = curve or [(0.0, 3.0)]
    (directory / "learning_curve.csv").write_text("timesteps,min_dist_sum\n" + "".join(f"{s},{v}\n" for s, v in rows))
    if done:
        (directory / "done").write_text("")


def write_study(results: Path, experiment: str, runs: dict[str, list[float]]) -> None:
    for scheme, scores in runs.items():
        for seed, score in enumerate(scores):
            write_run(results, experiment, scheme, seed, score)


SHARED = {
    "full": [0.5, 0.6, 0.55, 0.52, 0.58],
    "selected": [2.0, 2.5, 3.0, 2.2, 2.8],
    "selected_next": [0.6, 0.5, 0.7, 0.62, 0.66],
}


def studies(tmp_path: Path, independent: dict[str, list[float]]) -> dict[str, Path]:
    write_study(tmp_path / "shared", "paper_n5_exp1", SHARED)
    write_study(tmp_path / "independent", "paper_n5i_exp1", independent)
    return {"shared": tmp_path / "shared", "independent": tmp_path / "independent"}


def setting_scores(module: ModuleType, paths: dict[str, Path]) -> dict[str, dict[str, dict[int, float]]]:
    experiments = {"shared": "paper_n5_exp1", "independent": "paper_n5i_exp1"}
    return {networks: module.read_scores(paths[networks], experiments[networks], "min_dist_sum") for networks in paths}


def test_gaps_effects_and_tests_match_a_hand_computation(beside_shared: ModuleType, tmp_path: Path) -> None:
    independent = {
        "full": [0.4, 0.45, 0.5, 0.42, 0.48],
        "selected": [0.9, 1.0, 1.1, 0.95, 1.05],
        "selected_next": [0.41, 0.5, 0.44, 0.47, 0.43],
    }
    scores = setting_scores(beside_shared, studies(tmp_path, independent))
    mean = {
        (networks, scheme): np.mean(values)
        for networks, runs in (("shared", SHARED), ("independent", independent))
        for scheme, values in runs.items()
    }

    stored = beside_shared.cell(scores["shared"], "selected")
    assert stored.gap.value == pytest.approx(mean["shared", "selected"] - mean["shared", "full"])
    assert stored.p_value == pytest.approx(mannwhitneyu(SHARED["selected"], SHARED["full"], alternative="two-sided").pvalue)
    assert stored.gap.low < stored.gap.value < stored.gap.high and stored.gap.low > 0  # every stored run is worse
    # The gap's interval is Welch's t interval (a percentile bootstrap from 5 runs is too narrow).
    welch = ttest_ind(SHARED["selected"], SHARED["full"], equal_var=False).confidence_interval(0.95)
    assert (stored.gap.low, stored.gap.high) == (pytest.approx(welch.low), pytest.approx(welch.high))

    interaction = beside_shared.difference(
        [independent["selected"], independent["selected_next"], SHARED["selected"], SHARED["selected_next"]]
    )
    by_hand = (mean["independent", "selected"] - mean["independent", "selected_next"]) - (
        mean["shared", "selected"] - mean["shared", "selected_next"]
    )
    assert interaction.value == pytest.approx(by_hand)
    assert interaction.low <= interaction.value <= interaction.high

    lines = beside_shared.setting_table(scores, "min_dist_sum")
    sharing = (mean["shared", "selected"] - mean["shared", "full"]) - (
        mean["independent", "selected"] - mean["independent", "full"]
    )
    rule_independent = mean["independent", "selected"] - mean["independent", "selected_next"]
    for name, value in (
        (beside_shared.SHARING_FULL, mean["shared", "full"] - mean["independent", "full"]),
        (beside_shared.SHARING_STORED, mean["shared", "selected"] - mean["independent", "selected"]),
        (beside_shared.SHARING, sharing),
        (beside_shared.RULE_INDEPENDENT, rule_independent),
        (beside_shared.INTERACTION, -by_hand),  # the page's interaction: shared minus independent
    ):
        assert any(line.startswith(f"- {name}: {value:+.2f} [") for line in lines), (name, value)
    row = next(line for line in lines if line.startswith("| independent | stored"))
    by_seed = ", ".join(f"{value:.2f}" for value in independent["selected"])
    assert f"| 5 | {by_seed} | {mean['independent', 'selected']:.2f} | {mean['independent', 'full']:.2f} | " in row


def test_rates_read_in_percentage_points_with_their_direction(beside_shared: ModuleType) -> None:
    full, stored = [0.70, 0.72, 0.68, 0.74, 0.71], [0.05, 0.02, 0.10, 0.04, 0.03]
    same_in_both = {"full": dict(enumerate(full)), "selected": dict(enumerate(stored)), "selected_next": dict(enumerate(full))}
    lines = beside_shared.setting_table({"shared": same_in_both, "independent": same_in_both}, "success_rate_r0.3")
    assert lines[0] == "Gaps and effects in percentage points; negative is worse."
    gap = 100 * (np.mean(stored) - np.mean(full))
    row = next(line for line in lines if line.startswith("| shared | stored"))
    assert f"| {100 * np.mean(stored):.1f} | {100 * np.mean(full):.1f} | {gap:+.1f} [" in row
    # Worse than `full` and than the next rule in both studies alike: the rule, and no effect of sharing.
    assert lines[-1].startswith("- **which explains the reversal**: the rule:"), lines[-1]


FULL = [0.4, 0.45, 0.5, 0.42, 0.48]
NEXT = [0.41, 0.5, 0.44, 0.47, 0.43]


@pytest.mark.parametrize(
    ("independent", "expected"),
    [
        # as harmful as with shared networks: the rule alone
        ({"full": FULL, "selected": [2.0, 2.5, 3.0, 2.2, 2.8], "selected_next": NEXT}, "the rule:"),
        # more harmful without sharing than with it: still the rule (sharing does not make it larger)
        ({"full": FULL, "selected": [3.0, 3.5, 4.0, 3.2, 3.8], "selected_next": NEXT}, "the rule:"),
        # harmful without sharing, more harmful with it
        ({"full": FULL, "selected": [0.9, 1.0, 1.1, 0.95, 1.05], "selected_next": NEXT}, "both:"),
        # the stored rule among the next rule's runs without sharing: the sharing
        ({"full": FULL, "selected": [0.47, 0.41, 0.5, 0.39, 0.44], "selected_next": NEXT}, "the sharing:"),
        # the stored rule a little worse on average without sharing, within its spread: still the sharing
        ({"full": FULL, "selected": [0.3, 0.9, 0.4, 0.8, 0.5], "selected_next": NEXT}, "the sharing:"),
        # both rules astray without sharing: the rule's effect is 0, and so is sharing's
        (
            {"full": FULL, "selected": [2.0, 2.5, 3.0, 2.2, 2.8], "selected_next": [2.1, 2.9, 2.4, 2.6, 2.5]},
            "not decided",
        ),
    ],
)
def test_reading_names_the_factor_the_reversal_belongs_to(
    beside_shared: ModuleType, tmp_path: Path, independent: dict[str, list[float]], expected: str
) -> None:
    lines = beside_shared.setting_table(setting_scores(beside_shared, studies(tmp_path, independent)), "min_dist_sum")
    assert lines[-1].startswith(f"- **which explains the reversal**: {expected}"), lines[-1]


@pytest.mark.parametrize(
    ("independent", "through"),
    [
        # the stored rule far better without sharing, `full` alike: sharing harms the stored rule itself
        ({"full": FULL, "selected": [0.47, 0.41, 0.5, 0.39, 0.44], "selected_next": NEXT}, "the stored rule itself"),
        # the stored rule as bad without sharing, `full` and the next rule much worse: sharing's gap is `full`'s
        (
            {
                "full": [1.5, 1.6, 1.7, 1.55, 1.65],
                "selected": [2.0, 2.5, 3.0, 2.2, 2.8],
                "selected_next": [2.1, 2.9, 2.4, 2.6, 2.5],
            },
            "through `full`",
        ),
    ],
)
def test_reading_says_which_part_of_the_gap_sharing_widens(
    beside_shared: ModuleType, tmp_path: Path, independent: dict[str, list[float]], through: str
) -> None:
    lines = beside_shared.setting_table(setting_scores(beside_shared, studies(tmp_path, independent)), "min_dist_sum")
    assert lines[-1].startswith("- **which explains the reversal**: the sharing:"), lines[-1]
    assert f"larger ({through}" in lines[-1], lines[-1]


def test_reading_needs_a_reversal_in_the_metrics_direction(beside_shared: ModuleType) -> None:
    lower = {
        "full": dict(enumerate(FULL)),
        "selected": dict(enumerate([0.1, 0.12, 0.09, 0.11, 0.1])),
        "selected_next": dict(enumerate(NEXT)),
    }
    scores = {"shared": lower, "independent": lower}
    # The stored rule's runs score lower than `full`'s: better on the min-dist sum, worse as a success rate.
    assert beside_shared.setting_table(scores, "min_dist_sum")[-1].endswith(
        "not worse than `full` here at Holm-adjusted p < .05"
    )
    assert beside_shared.setting_table(scores, "success_rate_r0.3")[-1].startswith(
        "- **which explains the reversal**: the rule:"
    )


def test_reading_waits_for_cells_whose_test_can_reach_the_level(beside_shared: ModuleType, tmp_path: Path) -> None:
    scores = setting_scores(beside_shared, studies(tmp_path, {"full": [0.4], "selected": [1.0], "selected_next": [0.4]}))
    lines = beside_shared.setting_table(scores, "min_dist_sum")
    assert lines[-1].endswith("too few runs to read: in a cell even completely separated runs could not reach p < .05")
    assert (
        "| independent | stored (Algorithm 3, `selected`) | 1 | 1.00 | 1.00 | 0.40 | +0.60 (too few runs for an interval) "
        "| n/a (1 run) |" in lines
    )


@pytest.mark.parametrize(("runs", "read"), [(3, False), (4, True)])
def test_three_completely_separated_runs_a_cell_are_not_read_four_are(
    beside_shared: ModuleType, runs: int, read: bool
) -> None:
    # Every stored run worse than every `full` run and every next run, in both studies: the rule, once readable.
    cells = {
        "full": [0.4, 0.45, 0.5, 0.42][:runs],
        "selected": [2.0, 2.5, 3.0, 2.2][:runs],
        "selected_next": [0.41, 0.5, 0.44, 0.47][:runs],
    }
    scores = {
        networks: {scheme: dict(enumerate(values)) for scheme, values in cells.items()}
        for networks in ("shared", "independent")
    }
    lines = beside_shared.setting_table(scores, "min_dist_sum")
    assert lines[-1].startswith("- **which explains the reversal**: " + ("the rule:" if read else "too few runs")), lines[-1]
    # Intervals resampled from 3 runs are not shown: they would look surer than 3 runs can be.
    assert any("(too few runs for an interval)" in line for line in lines) is not read


def test_scores_are_the_seeds_all_three_schemes_finished_and_the_window_mean(
    beside_shared: ModuleType, tmp_path: Path
) -> None:
    results = tmp_path / "results"
    curve = [(700_000.0, 9.0), (800_000.0, 1.0), (900_000.0, 2.0), (1_000_000.0, 6.0), (1_100_000.0, 9.0)]
    for scheme in ("full", "selected", "selected_next"):
        for seed in (0, 1):
            write_run(results, "exp", scheme, seed, 0.5, curve)
    write_run(results, "exp", "full", 2, 0.5)  # seed 2 of `full` only
    write_run(results, "exp", "selected", 3, 0.5, done=False)  # still running
    write_run(results, "other", "full", 0, 7.0)  # another setting
    assert beside_shared.read_scores(results, "exp", "min_dist_sum") == {
        scheme: {0: 0.5, 1: 0.5} for scheme in ("full", "selected", "selected_next")
    }
    windowed = beside_shared.read_scores(results, "exp", "min_dist_sum", beside_shared.MATCHED_WINDOW)
    assert windowed["selected"] == {0: pytest.approx(3.0), 1: pytest.approx(3.0)}  # 800k-1M inclusive, nothing else
    with pytest.raises(ValueError, match="no learning-curve point between 2e\\+06 and 3e\\+06"):
        beside_shared.read_scores(results, "exp", "min_dist_sum", (2e6, 3e6))


def test_an_empty_cell_reads_no_runs_yet(beside_shared: ModuleType, tmp_path: Path) -> None:
    write_study(tmp_path / "shared", "paper_n5_exp1", SHARED)
    (tmp_path / "independent").mkdir()
    paths = {"shared": tmp_path / "shared", "independent": tmp_path / "independent"}
    lines = beside_shared.setting_table(setting_scores(beside_shared, paths), "min_dist_sum")
    assert "| independent | next (`selected_next`) | 0 | - | no runs yet | no runs yet | - | - |" in lines
    assert "- the rule's effect with independent networks (stored minus next): no runs yet" in lines


@pytest.mark.skipif(not COMMITTED.exists(), reason="no committed 2 x 2 page")
def test_the_committed_page_is_the_committed_runs_reading(beside_shared: ModuleType) -> None:
    # benchmarks/paper_n5_independent/report.sh writes it: run it in each commit that adds finished runs.
    assert beside_shared.write_beside_shared() == COMMITTED.read_text()


def test_critic_loss_is_the_logged_loss_over_its_window_and_its_ratio_to_full(
    beside_shared: ModuleType, tmp_path: Path
) -> None:
    results = tmp_path / "results"
    logged = {"full": [0.1, 0.2, 0.3], "selected": [0.3, 0.6, 0.9], "selected_next": [0.1, 0.1, 0.1]}
    for scheme, losses in logged.items():
        write_run(results, "exp", scheme, 0, 0.5)
        rows = [(400_000, 5.0), (500_000, losses[0]), (750_000, losses[1]), (1_000_000, losses[2]), (1_200_000, 5.0)]
        progress = "time/total_timesteps,train/critic_loss,eval/min_dist_sum\n" + "".join(f"{s},{v},\n" for s, v in rows)
        progress += "750000,,0.7\n"  # an evaluation's row: no loss logged there
        (results / "exp" / scheme / "seed_000" / "progress.csv").write_text(progress)
    losses = beside_shared.read_scores(results, "exp", beside_shared.CRITIC_LOSS, beside_shared.CRITIC_LOSS_WINDOW)
    assert losses == {scheme: {0: pytest.approx(np.mean(values))} for scheme, values in logged.items()}
    lines = beside_shared.critic_loss_table({"shared": losses, "independent": {scheme: {} for scheme in logged}})
    assert lines[2] == "| shared | 1 | 0.200 (0.200-0.200) | 0.600 (0.600-0.600) | 0.100 (0.100-0.100) | 3.00 |"
    assert lines[3] == "| independent | 0 | no runs yet | | | |"


def copy_experiment(results: Path, source: Path, name: str, schemes: list[str]) -> None:
    """A committed setting's stored config under ``name``, with these schemes."""
    experiment = json.loads(source.read_text())
    experiment.update(name=name, schemes=schemes)
    (results / name).mkdir(parents=True, exist_ok=True)
    (results / name / "experiment.json").write_text(json.dumps(experiment))


def exp1_settings(tmp_path: Path, schemes: list[str]) -> tuple[Path, Path]:
    """Both studies' Exp. 1 stored configs with these schemes (no runs yet): the shared and the independent results."""
    shared, independent = tmp_path / "shared", tmp_path / "independent"
    copy_experiment(shared, REPO / "benchmarks/paper_n5/results/paper_n5_exp1/experiment.json", "paper_n5_exp1", schemes)
    source = REPO / "benchmarks/paper_n5_independent/results/paper_n5i_exp1/experiment.json"
    copy_experiment(independent, source, "paper_n5i_exp1", schemes)
    return shared, independent


def test_table2_puts_both_studies_complete_seeds_under_the_papers_row(beside_shared: ModuleType, tmp_path: Path) -> None:
    schemes = ["full", "selected", "selected_next"]
    shared, independent = exp1_settings(tmp_path, schemes)
    source = REPO / "benchmarks/paper_n5_independent/results/paper_n5i_exp1/experiment.json"
    copy_experiment(independent, source, "paper_n5_indep_curve", ["full"])  # a learning curve's runs: not a setting here
    write_study(shared, "paper_n5_exp1", {scheme: [0.5, 0.7] for scheme in schemes})
    write_study(independent, "paper_n5i_exp1", {scheme: [0.4] for scheme in schemes})
    write_run(independent, "paper_n5i_exp1", "full", 1, 0.9)  # seed 1 of `full` only: not a complete seed
    write_run(independent, "paper_n5_indep_curve", "full", 0, 0.3)
    lines = beside_shared.table2_beside_shared({"shared": shared, "independent": independent}, "min_dist_sum")
    assert lines[0] == "#### Beside the paper's Table 2: sum of min. distances"
    rows = [line.split(" | ")[0] for line in lines if line.startswith("| paper")]
    assert [row.split(" (")[0] for row in rows] == ["| paper, Exp. 1", "| paper_n5_exp1", "| paper_n5i_exp1"]
    independent_row = next(line for line in lines if line.startswith("| paper_n5i_exp1"))
    assert "(1 run) | 0.40 (0.00) |" in independent_row  # seed 0 only; the curve's run and seed 1 left out
    assert "(2 runs) | 0.60 (0.14) |" in next(line for line in lines if line.startswith("| paper_n5_exp1"))


@pytest.mark.parametrize(
    ("shared", "independent", "together"),
    [
        ("reverses", "reverses", "the same"),
        ("not separated", "not separated", "neither separates"),
        ("holds", "reverses", "opposite"),
        ("does not hold (MADDPG-fa scores better)", "does not hold (IDDPG scores better)", "opposite"),
        ("does not hold (IDDPG scores better)", "does not hold (IDDPG scores better)", "the same"),
        ("reverses", "not separated", "decided with shared only"),
        ("not separated", "holds", "decided with independent only"),
        ("does not hold (IDDPG scores better)", "not separated", "decided with shared only"),
        # leaning either way is no decided verdict (the adjusted p at .05 or above)
        ("leans the claim's way", "leans the other way", "neither separates"),
        ("not separated", "leans the other way", "neither separates"),
        ("reverses", "leans the claim's way", "decided with shared only"),
        ("reverses", "too few runs", "not yet"),
        ("too few runs", "too few runs", "not yet"),
    ],
)
def test_two_outcomes_read_together(beside_shared: ModuleType, shared: str, independent: str, together: str) -> None:
    assert beside_shared.agreement(shared, independent) == together


def test_claims_are_asked_of_both_studies_complete_seeds(beside_shared: ModuleType, tmp_path: Path) -> None:
    shared, independent = exp1_settings(tmp_path, ["full", "selected", "selected_next"])
    write_study(shared, "paper_n5_exp1", SHARED)  # `selected` far worse than `full` on all 5 seeds
    overlapping = {"full": [0.5, 0.7, 0.6, 0.55, 0.65], "selected": [0.52, 0.68, 0.62, 0.57, 0.66]}
    write_study(independent, "paper_n5i_exp1", {**overlapping, "selected_next": [0.9, 1.0, 1.1, 0.95, 1.05]})
    write_run(independent, "paper_n5i_exp1", "full", 5, 9.0)  # seed 5 of `full` only: not a complete seed
    lines = beside_shared.claims_beside_shared({"shared": shared, "independent": independent}, "min_dist_sum")
    assert lines[0] == "#### The paper's claims in both studies: sum of min. distances (lower is better)"
    rows = {line.split(" | ")[1]: line.split(" | ") for line in lines[4:]}
    stored, following = rows["MADDPG-soa > MADDPG"], rows["selected_next (MADDPG-soa) > MADDPG"]
    p_independent = mann_whitney(overlapping["selected"], overlapping["full"])[1]
    # p = 2 / C(10, 5), fully separated; Holm within the family of the setting's two schemes against `full`.
    assert stored[3:8] == ["5, 5", "2.50 vs 0.55", ".008 (Holm .016 of 2)", "reverses", "5, 5"]
    # Holm: the family's other test (selected_next, apart: .016 after x 2) is the smaller, so this one keeps its p.
    shown = f"{p_independent:.3f}"[1:]
    assert stored[8:10] == ["0.61 vs 0.60", f"{shown} (Holm {shown} of 2)"]
    # Undecided, leaning: the runs' P(better) below 0.5 for the claim (selected's distances a little larger).
    assert stored[10:] == ["leans the other way", "decided with shared only |"]
    assert following[6] == "leans the other way" and following[10] == "reverses"
    assert following[11] == "decided with independent only |"


def test_claims_at_the_matched_budget_read_each_runs_curve_in_the_window(beside_shared: ModuleType, tmp_path: Path) -> None:
    shared, independent = exp1_settings(tmp_path, ["full", "selected", "selected_next"])
    for results, experiment in ((shared, "paper_n5_exp1"), (independent, "paper_n5i_exp1")):
        for seed in range(4):  # equal protocol scores; in 0.8M-1M (inclusive) `selected`'s curve is far behind
            outside = [(700_000.0, 9.0), (1_000_001.0, 9.0)]
            write_run(results, experiment, "full", seed, 0.5, [(800_000.0, 0.4 + 0.01 * seed), (1e6, 0.6), *outside])
            write_run(results, experiment, "selected", seed, 0.5, [(800_000.0, 1.0), (9e5, 1.2 + 0.2 * seed), *outside])
            write_run(results, experiment, "selected_next", seed, 0.5, [(900_000.0, 0.5)])
    paths = {"shared": shared, "independent": independent}
    lines = beside_shared.claims_beside_shared(paths, "min_dist_sum", beside_shared.MATCHED_WINDOW)
    assert lines[0] == (
        "#### The paper's claims in both studies: sum of min. distances (lower is better), "
        "matched budget (learning-curve points, 0.8M-1M env steps)"
    )
    stored = next(line.split(" | ") for line in lines[4:] if line.split(" | ")[1] == "MADDPG-soa > MADDPG")
    # Per run: the mean of its points in the window; full 0.5 + 0.005 * seed, `selected` 1.1 + 0.1 * seed. Four runs
    # apart give .029, which Holm within the family of two (`selected`, `selected_next` against `full`) takes to .057:
    # no verdict, a lean.
    assert stored[3:] == ["4, 4", "1.25 vs 0.51", ".029 (Holm .057 of 2)", "leans the other way"] * 2 + ["neither separates |"]
    own = beside_shared.claims_beside_shared(paths, "min_dist_sum")  # the protocol scores: all 0.5
    assert next(line for line in own if "| MADDPG-soa > MADDPG |" in line).endswith("neither separates |")
    # Seed 4 of `full` only: not a complete seed, left out at the matched budget too (its curve would weigh in).
    write_run(independent, "paper_n5i_exp1", "full", 4, 0.5, [(900_000.0, 5.0)])
    lines = beside_shared.claims_beside_shared(paths, "min_dist_sum", beside_shared.MATCHED_WINDOW)
    row = next(line for line in lines if "| MADDPG-soa >" in line)
    assert "| 4, 4 | 1.25 vs 0.51 | .029 (Holm .057 of 2) | leans the other way | neither separates |" in row
    # A complete seed with no curve point in the window is an error that names the run.
    write_run(independent, "paper_n5i_exp1", "selected", 4, 0.5, [(1_200_000.0, 1.0)])
    write_run(independent, "paper_n5i_exp1", "selected_next", 4, 0.5, [(900_000.0, 0.5)])
    with pytest.raises(ValueError, match=r"selected/seed_004 has no learning-curve point between 800000 and 1e\+06"):
        beside_shared.claims_beside_shared(paths, "min_dist_sum", beside_shared.MATCHED_WINDOW)


def test_a_claim_one_study_does_not_run_is_asked_of_the_other_only(beside_shared: ModuleType, tmp_path: Path) -> None:
    shared, independent = tmp_path / "shared", tmp_path / "independent"
    source = REPO / "benchmarks/paper_n5/results/paper_n5_exp2/experiment.json"
    runs = {"full": [0.5, 0.6, 0.55, 0.52, 0.58], "actions": [0.9, 1.0, 1.1, 0.95, 1.05], "independent": [0.4] * 5}
    copy_experiment(shared, source, "paper_n5_exp2", list(runs))
    write_study(shared, "paper_n5_exp2", runs)
    source = REPO / "benchmarks/paper_n5_independent/results/paper_n5i_exp2/experiment.json"
    copy_experiment(independent, source, "paper_n5i_exp2", ["full", "independent"])  # runs no `actions`
    write_study(independent, "paper_n5i_exp2", {"full": [0.5], "independent": [0.6]})  # 1 seed: too few runs
    lines = beside_shared.claims_beside_shared({"shared": shared, "independent": independent}, "min_dist_sum")
    rows = {line.split(" | ")[1]: line.split(" | ") for line in lines[4:]}
    assert rows["MADDPG > MADDPG-fa"][7:] == ["0", "", "", "not in this study", "asked of the shared study only |"]
    # A `~` claim that does not hold says which scheme scores better (1.00 against 0.40: IDDPG).
    assert rows["MADDPG-fa ~ IDDPG"][6] == "does not hold (IDDPG scores better)"
    assert rows["MADDPG > IDDPG"][10:] == ["too few runs", "not yet |"]
    (independent / "paper_n5i_exp2" / "independent" / "seed_000" / "done").unlink()  # no complete seed: no runs yet
    lines = beside_shared.claims_beside_shared({"shared": shared, "independent": independent}, "min_dist_sum")
    rows = {line.split(" | ")[1]: line.split(" | ") for line in lines[4:]}
    assert rows["MADDPG > IDDPG"][7:] == ["0", "", "", "no runs yet", "not yet |"]


def test_late_change_compares_the_curves_last_20_percent_with_the_20_percent_before(
    beside_shared: ModuleType, tmp_path: Path
) -> None:
    results = tmp_path / "results"
    budget = 1_000_000
    # Windows (600k, 800k] and (800k, 1M]: the points at 600k and beyond 1M are outside, 800k is the earlier window's.
    curve = [(600_000.0, 50.0), (700_000.0, 1.0), (800_000.0, 2.0), (900_000.0, 0.5), (1_000_000.0, 0.7), (1.1e6, 50.0)]
    write_run(results, "exp", "full", 0, 0.5, curve)
    summary = {**json.loads((results / "exp/full/seed_000/summary.json").read_text()), "total_timesteps": budget}
    summary["directory"] = str(results / "exp/full/seed_000")
    assert beside_shared.late_curve_means(summary) == pytest.approx((1.5, 0.6))
    # The windows are fractions of the run's own budget: at 2M they hold none of these points.
    with pytest.raises(ValueError, match="full/seed_000 has no learning-curve point after 1,200,000 and up to 1,600,000"):
        beside_shared.late_curve_means({**summary, "total_timesteps": 2 * budget})


def late_runs(results: Path, window_means: dict[str, list[tuple[float, float]]]) -> list[dict[str, object]]:
    """Finished 1M-step runs whose curves average these (before, last) over (600k, 800k] and (800k, 1M]."""
    runs = []
    for scheme, pairs in window_means.items():
        for seed, (before, last) in enumerate(pairs):
            write_run(results, "exp", scheme, seed, 0.5, [(700_000.0, before), (900_000.0, last)])
            directory = results / "exp" / scheme / f"seed_{seed:03d}"
            summary = json.loads((directory / "summary.json").read_text())
            runs.append({**summary, "directory": str(directory), "total_timesteps": 1_000_000})
    return runs


def test_late_change_table_counts_runs_still_improving_against_the_threshold(
    beside_shared: ModuleType, tmp_path: Path
) -> None:
    scale = 2.0  # min-dist units per normalised unit: the threshold 0.05 is a change of 0.1
    window_means = {
        # changes -0.3, -0.2, -0.09 (the last 0.045 normalised: below the threshold), -0.25
        "full": [(1.0, 0.7), (1.0, 0.8), (1.0, 0.91), (1.0, 0.75)],
        # changes exactly +0.1 (falling back by the threshold), -0.1 (improving by it), +0.05, +0.15
        "selected": [(0.0, 0.1), (0.1, 0.0), (1.0, 1.05), (1.3, 1.45)],
    }
    runs = late_runs(tmp_path, window_means)
    lines = beside_shared.late_change_table({"shared": runs, "independent": []}, scale)
    full, selected = lines[2].split(" | "), lines[3].split(" | ")
    assert full[1:4] == ["`full`", "4", "1.00 / 0.79"]
    assert full[4].startswith("-0.21 [") and full[5] == "+0.105"  # -(-0.21) / 2
    assert full[6:] == ["3 / 0", "- |"]
    assert selected[1:4] == ["`selected`", "4", "0.60 / 0.65"]
    assert selected[4].startswith("+0.05 [") and selected[5] == "-0.025"
    assert selected[6] == "1 / 2"  # the threshold itself counts, either way
    change_minus_full = float(selected[7].split(" ")[0])
    assert change_minus_full == pytest.approx(0.05 - (-0.21))
    assert lines[4] == "| independent | | 0 | no runs yet | | | | |"
    assert beside_shared.late_windows({"shared": runs, "independent": []}) == "shared: 0.6M-0.8M and 0.8M-1M"


def test_late_change_intervals_wait_for_four_runs(beside_shared: ModuleType, tmp_path: Path) -> None:
    # Three runs a scheme: no interval shown, as in the 2 x 2's cells (it would look surer than 3 runs can be).
    runs = late_runs(tmp_path, {"full": [(1.0, 0.7), (1.0, 0.8), (1.0, 0.9)], "selected": [(1.0, 1.1)] * 3})
    full, selected = (line.split(" | ") for line in beside_shared.late_change_table({"shared": runs}, 2.0)[2:4])
    assert full[4] == "-0.20 (too few runs for an interval)"
    assert selected[7] == "+0.30 (too few runs for an interval) |"


def test_a_cell_takes_holm_within_its_study_s_family_and_the_reading_the_adjusted_p(beside_shared: ModuleType) -> None:
    # Every stored run far worse than `full`'s, 5 against 5: raw p = 2/252 = .0079 in both studies.
    scores = {
        networks: {"full": dict(enumerate(FULL)), "selected": dict(enumerate(s)), "selected_next": dict(enumerate(NEXT))}
        for networks, s in (("shared", [2.0, 2.5, 3.0, 2.2, 2.8]), ("independent", [2.0, 2.5, 3.0, 2.2, 2.8]))
    }
    # Without a family each cell is its own: the stored rule is worse, and the reading reads the rule.
    assert beside_shared.setting_table(scores, "min_dist_sum")[-1].startswith("- **which explains the reversal**: the rule:")
    # The shared study's family: seven schemes against `full`, the others far from it; the cell's own p takes its
    # scheme's place: 7 x .0079 = .056, so with shared networks the stored rule is not worse at the adjusted level.
    family = {"independent": 0.5, "observations": 0.6, "actions": 0.7, "x": 0.8, "y": 0.9, "selected": 1.0}
    family["selected_next"] = mann_whitney(NEXT, FULL)[1]
    stored = beside_shared.cell(scores["shared"], "selected", family)
    raw = [stored.p_value if scheme == "selected" else p for scheme, p in family.items()]
    assert stored.p_value == pytest.approx(2 / 252) and stored.family_size == 7
    assert stored.p_adjusted == pytest.approx(holm(raw)[list(family).index("selected")]) == pytest.approx(7 * 2 / 252)
    lines = beside_shared.setting_table(scores, "min_dist_sum", {"shared": family})
    assert lines[-1].endswith(
        "no reversal to explain: with shared networks the stored rule is not worse than `full` here at Holm-adjusted p < .05"
    )
    row = next(line for line in lines if line.startswith("| shared | stored"))
    assert row.endswith("| .008 (Holm .056 of 7) |")


def test_a_study_s_family_is_its_report_s(beside_shared: ModuleType, tmp_path: Path) -> None:
    schemes = ["full", "independent", "selected", "selected_next"]
    shared, _ = exp1_settings(tmp_path, schemes)
    runs = {"full": FULL, "independent": [0.6, 0.7, 0.65, 0.62, 0.68], "selected": [2.0, 2.5, 3.0, 2.2, 2.8]}
    write_study(shared, "paper_n5_exp1", {**runs, "selected_next": NEXT})
    write_run(shared, "paper_n5_exp1", "selected", 5, 9.0)  # seed 5 of `selected` only: not a complete seed
    family = beside_shared.family_p_values(shared, "paper_n5_exp1", "min_dist_sum")
    assert list(family) == ["independent", "selected", "selected_next"]
    for scheme, values in {**runs, "selected_next": NEXT}.items():
        if scheme != "full":
            assert family[scheme] == pytest.approx(mann_whitney(values, FULL)[1]), scheme
    assert beside_shared.family_p_values(tmp_path / "nowhere", "paper_n5_exp1", "min_dist_sum") == {}
