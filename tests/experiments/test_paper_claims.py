"""The paper's claims asked of runs: which setting each applies to, the test and verdict, the direction, the files."""

import csv
import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.stats import mannwhitneyu

from sb3_maddpg.experiments.tasks import metric_info
from sb3_maddpg.results.claims import (
    PAPER_CLAIMS,
    PAPER_TABLE2,
    PaperClaim,
    check_claims,
    format_beside_paper,
    format_claims_markdown,
    format_p_value,
    observability,
    smallest_p_value,
    write_claims_report,
)
from sb3_maddpg.results.stats import aggregate, declare_families, holm, seeds_to_separate

FULL = {"env": "simple_spread", "n_agents": 5, "num_agent_neighbors": 4, "episodes": 100}
PARTIAL = {"env": "simple_spread", "n_agents": 5, "num_agent_neighbors": 2, "episodes": 100}
HIGH = [0.60, 0.62, 0.65, 0.70, 0.66, 0.61, 0.68, 0.63]
LOW = [0.30, 0.35, 0.32, 0.40, 0.38, 0.31, 0.36, 0.33]
MIXED = [0.55, 0.70, 0.40, 0.65, 0.50, 0.60, 0.45, 0.66]  # overlaps HIGH and LOW


def cells(scores: dict[str, dict[str, list[float]]], metric: str = "success_rate"):  # type: ignore[no-untyped-def]
    summaries = [
        {"experiment": setting, "scheme": scheme, "seed": seed, "score": {metric: value}}
        for setting, by_scheme in scores.items()
        for scheme, values in by_scheme.items()
        for seed, value in enumerate(values)
    ]
    return aggregate(summaries, metric)


def checks_by_claim(scores: dict[str, dict[str, list[float]]], experiments: dict[str, Any], metric: str = "success_rate"):  # type: ignore[no-untyped-def]
    infos = {setting: metric_info(metric, "simple_spread") for setting in scores}
    return {(check.setting, check.text): check for check in check_claims(cells(scores, metric), metric, experiments, infos)}


def test_a_setting_is_the_paper_s_exp1_or_exp2_by_what_each_agent_observes() -> None:
    assert observability({"n_agents": 5, "num_agent_neighbors": None}) == "full"
    assert observability(FULL) == "full"  # every other agent, nearest first
    assert observability({"n_agents": 3, "num_agent_neighbors": 2}) == "full"
    assert observability(PARTIAL) == "partial"
    assert observability({"env": "simple_tag", "n_agents": 4}) is None  # another task: no claim applies
    assert observability(None) is None
    # The claims hold the paper's orderings: Exp. 1 fa > MADDPG > IDDPG > fo and soa > MADDPG; Exp. 2 soa > MADDPG >
    # fo > fa ~ IDDPG; each pair's paper means are Table 2's.
    texts = {(claim.observability, claim.text) for claim in PAPER_CLAIMS}
    assert {
        ("full", "MADDPG-fa > MADDPG"),
        ("full", "IDDPG > MADDPG-fo"),
        ("partial", "MADDPG-fa ~ IDDPG"),
        ("partial", "MADDPG-soa > MADDPG-fo"),
    } <= texts
    for claim in PAPER_CLAIMS:
        table = PAPER_TABLE2[claim.observability]
        assert claim.evidence.startswith(f"{table[claim.better][0]:.2f} vs {table[claim.worse][0]:.2f}"), claim
        if "full" in (claim.better, claim.worse):  # the paper tested against MADDPG: its marks say how it came out
            stars = table[claim.worse if claim.better == "full" else claim.better][2]
            expected = {"**": "p < .01", "*": "p < .05", "": "not significant"}[stars]
            assert claim.evidence.endswith(expected), claim


def test_verdicts_follow_the_mann_whitney_test_and_the_metric_direction() -> None:
    scores = {"e1": {"actions": HIGH, "full": LOW, "selected": MIXED, "independent": HIGH, "observations": [0.5]}}
    checks = checks_by_claim(scores, {"e1": FULL})
    # The same p-value as scipy's test of the two samples, and the verdict it implies.
    fa = checks["e1", "MADDPG-fa > MADDPG"]
    assert fa.p_value == pytest.approx(mannwhitneyu(HIGH, LOW, alternative="two-sided").pvalue)
    assert fa.verdict == "holds" and fa.improvement.value == 1.0 and fa.seeds_needed is None
    assert checks["e1", "MADDPG > IDDPG"].verdict == "reverses"  # IDDPG's runs all beat MADDPG's
    soa = checks["e1", "MADDPG-soa > MADDPG"]
    assert soa.p_value < 0.05 and soa.verdict == "holds"
    # One run of fo: nothing to test.
    assert checks["e1", "MADDPG > MADDPG-fo"].verdict == "too few runs"
    # Three runs against three cannot reach p < .05 even when every run of one beats every run of the other; four can.
    assert smallest_p_value(3, 3) == pytest.approx(0.1) and smallest_p_value(4, 4) == pytest.approx(2 / 70)
    three = checks_by_claim({"e1": {"actions": HIGH[:3], "full": LOW[:3]}}, {"e1": FULL})["e1", "MADDPG-fa > MADDPG"]
    assert three.verdict == "too few runs"
    # ... but they say how many seeds would separate them at their spread (a sweep in progress): 4 when every run of
    # one beats every run of the other by far, named in the report's finding; one run a side gives no estimate.
    assert three.seeds_needed == seeds_to_separate(HIGH[:3], LOW[:3]) == 4
    finding = format_claims_markdown([three], "success rate (%)", "higher is better")
    assert "| too few runs (leans the claim's way; ~4 seeds per scheme would likely confirm it at this spread) |" in finding
    assert checks["e1", "MADDPG > MADDPG-fo"].seeds_needed is None
    assert format_claims_markdown([checks["e1", "MADDPG > MADDPG-fo"]], "success", "higher is better").count(
        "| too few runs |"
    )
    # Runs so alike that no number of seeds would separate them say so, as "not separated" does.
    alike = checks_by_claim({"e1": {"actions": MIXED[:3], "full": [0.56, 0.69, 0.41]}}, {"e1": FULL})
    assert alike["e1", "MADDPG-fa > MADDPG"].seeds_needed is None
    assert "| too few runs (more than 200 seeds per scheme would be needed at this spread) |" in format_claims_markdown(
        [alike["e1", "MADDPG-fa > MADDPG"]], "success", "higher is better"
    )
    assert checks_by_claim({"e1": {"actions": HIGH[:4], "full": LOW[:4]}}, {"e1": FULL})[
        "e1", "MADDPG-fa > MADDPG"
    ].verdict == ("holds")
    # Only claims of the setting's observability are asked.
    assert all(check.claim.observability == "full" for check in checks.values())
    # A lower-is-better metric: the scheme claimed better must score lower.
    distances = {"e1": {"actions": LOW, "full": HIGH}}
    assert checks_by_claim(distances, {"e1": FULL}, "min_dist_sum")["e1", "MADDPG-fa > MADDPG"].verdict == "holds"
    assert checks_by_claim(scores, {"e1": FULL}, "min_dist_sum")["e1", "MADDPG-fa > MADDPG"].verdict == "reverses"


def test_runs_that_do_not_separate_say_how_many_seeds_would() -> None:
    rng = np.random.default_rng(0)
    close = {"e2": {"selected": list(0.5 + 0.1 * rng.standard_normal(6)), "full": list(0.48 + 0.1 * rng.standard_normal(6))}}
    check = checks_by_claim(close, {"e2": PARTIAL})["e2", "MADDPG-soa > MADDPG"]
    leaning = "the claim's way" if check.improvement.value > 0.5 else "the other way"
    assert check.p_value >= 0.05 and check.verdict == f"leans {leaning}"
    assert check.seeds_needed is not None and check.seeds_needed > 6  # more than these runs
    markdown = format_claims_markdown([check], "success rate (%)", "higher is better")
    assert f"| leans {leaning} (p = {format_p_value(check.p_value)}; ~{check.seeds_needed} seeds per scheme" in markdown
    # A claim that two schemes score alike is not separated when the runs do not separate them (no evidence that they
    # are alike either), and does not hold when they do, naming the one that scores better in the metric's direction.
    alike = checks_by_claim({"e2": {"actions": MIXED, "independent": [v + 0.01 for v in MIXED]}}, {"e2": PARTIAL})
    assert alike["e2", "MADDPG-fa ~ IDDPG"].verdict == "not separated"
    apart = {"e2": {"actions": LOW, "independent": HIGH}}
    check = checks_by_claim(apart, {"e2": PARTIAL})["e2", "MADDPG-fa ~ IDDPG"]
    assert check.verdict == "does not hold"
    assert "does not hold (IDDPG scores better)" in format_claims_markdown([check], "success", "higher is better")
    check = checks_by_claim(apart, {"e2": PARTIAL}, "min_dist_sum")["e2", "MADDPG-fa ~ IDDPG"]
    markdown = format_claims_markdown([check], "sum of min. distances", "lower is better")
    assert "does not hold (MADDPG-fa scores better)" in markdown and "means here (lower is better)" in markdown
    # A setting without a stored config, or of another task, is not asked.
    assert checks_by_claim(close, {}) == {}
    assert checks_by_claim(close, {"e2": {**PARTIAL, "env": "simple_tag"}}) == {}


def test_the_report_files_put_the_paper_beside_the_runs_and_list_each_check(tmp_path: Path) -> None:
    scores = {"e1": {"full": LOW, "actions": HIGH}, "e2": {"full": HIGH, "actions": LOW, "independent": MIXED}}
    experiments = {"e1": FULL, "e2": PARTIAL}
    table = cells(scores)
    infos = {setting: metric_info("success_rate", "simple_spread") for setting in scores}
    written = write_claims_report(tmp_path, table, "success_rate", experiments, infos, heading="> warning\n\n")
    assert [path.name for path in written] == ["claims_success_rate.md", "claims_success_rate.csv"]
    markdown = written[0].read_text()
    assert markdown.startswith("> warning")
    assert "| paper, Exp. 1 (full obs.), success % (31 runs) | 63.89 (12.28) |" in markdown
    assert "| paper, Exp. 2 (2 nearest obs.), success % (31 runs) | 70.11 (21.58) |" in markdown
    assert "(8 runs) |" in markdown and "(1 run" not in markdown
    assert "means here (higher is better)" in markdown and "| holds |" in markdown
    single = write_claims_report(
        tmp_path / "single", cells({"e1": {"full": LOW[:1], "actions": HIGH[:1]}}), "success_rate", experiments, infos
    )
    assert ", success rate (%) (1 run) |" in single[0].read_text()  # a sweep's first seed reads as one run
    assert "against MADDPG in the paper's rows, against MADDPG in the others" in markdown
    other = write_claims_report(tmp_path / "other", table, "success_rate", experiments, infos, baseline="actions")
    assert "against MADDPG in the paper's rows, against MADDPG-fa in the others" in other[0].read_text()
    rows = list(csv.DictReader(written[1].open()))
    # e1: fa > MADDPG; e2: MADDPG > fa, MADDPG > IDDPG, fa ~ IDDPG.
    assert [(row["setting"], row["better"], row["worse"]) for row in rows] == [
        ("e1", "actions", "full"),
        ("e2", "full", "actions"),
        ("e2", "full", "independent"),
        ("e2", "actions", "independent"),
    ]
    assert float(rows[0]["mean_better"]) == pytest.approx(100 * np.mean(HIGH))  # rates in %
    assert rows[0]["verdict"] == "holds" and rows[1]["verdict"] == "holds"
    # Nothing to ask: no files.
    assert write_claims_report(tmp_path / "none", table, "success_rate", {}, infos) == []
    assert format_beside_paper(table, "success", {}) is None
    custom = (PaperClaim("full", "full", "actions", ">", "mine"),)
    assert [check.verdict for check in check_claims(table, "success_rate", experiments, infos, custom)] == ["reverses"]


def test_a_variant_of_a_paper_scheme_is_asked_its_claims_too(tmp_path: Path) -> None:
    variant = {"critic_sharing": "soa", "selector": {"k": 2, "target": "next"}}  # the paper's alias resolves too
    experiment = {**FULL, "scheme_model_kwargs": {"selected": {"selector": 2}, "selected_next": variant}}
    middle = [0.45, 0.47, 0.50, 0.52, 0.48, 0.46, 0.51, 0.49]  # between LOW and HIGH, overlapping neither
    scores = {"exp1": {"full": middle, "selected": LOW, "selected_next": HIGH, "actions": MIXED}}
    checks = checks_by_claim(scores, {"exp1": experiment})
    stored, next_step = checks["exp1", "MADDPG-soa > MADDPG"], checks["exp1", "selected_next (MADDPG-soa) > MADDPG"]
    assert (stored.better_scheme, next_step.better_scheme) == ("selected", "selected_next")
    assert stored.verdict == "reverses" and next_step.verdict == "holds"
    assert next_step.better_scores == pytest.approx([100 * v for v in HIGH])  # in %, as the table shows them
    assert next_step.worse_scores == pytest.approx([100 * v for v in middle])
    # The variant has its column beside the paper's Table 2 (no paper value), and its rows in the CSV.
    table = cells(scores)
    beside = format_beside_paper(table, "success", {"exp1": experiment})
    assert beside is not None and "| MADDPG-soa | selected_next (MADDPG-soa) |" in beside
    write_claims_report(tmp_path, table, "success_rate", {"exp1": experiment})
    rows = list(csv.DictReader((tmp_path / "claims_success_rate.csv").open()))
    asked = {(row["better"], row["worse"]) for row in rows}
    assert asked == {("actions", "full"), ("selected", "full"), ("selected_next", "full")}


@pytest.mark.parametrize(
    ("p_value", "shown"),
    [
        (0.0, "< .001"),
        (0.000999, "< .001"),  # just below .001: would round to ".001"
        (0.001, ".001"),  # at .001: not below it
        (0.00149, ".001"),
        (0.0123, ".012"),  # three places, no leading zero
        (0.5, ".500"),
        (1.0, "1.000"),
        (math.nan, "n/a"),  # no test
    ],
)
def test_the_claims_table_shows_p_to_three_places_and_below_001_as_less_than(p_value: float, shown: str) -> None:
    check = checks_by_claim({"e1": {"actions": HIGH, "full": LOW}}, {"e1": FULL})["e1", "MADDPG-fa > MADDPG"]
    markdown = format_claims_markdown([dataclasses.replace(check, p_value=p_value)], "success rate (%)", "higher is better")
    (row,) = [line for line in markdown.splitlines() if line.startswith("| ") and "| MADDPG-fa > MADDPG |" in line]
    header = next(line for line in markdown.splitlines() if line.startswith("| setting |"))
    assert header.split(" | ")[5] == "p"
    assert row.split(" | ")[5] == shown, row


APART_HIGH = [0.70, 0.72, 0.71, 0.73, 0.69]
APART_LOW = [0.30, 0.32, 0.31, 0.33, 0.29]


def declared_checks(scores: dict[str, list[float]], experiment: dict[str, Any]):  # type: ignore[no-untyped-def]
    """The claims asked of one setting ``e1`` whose stored config declares the family (its ``schemes``)."""
    runs = [
        {"experiment": "e1", "scheme": scheme, "seed": seed, "score": {"success_rate": value}}
        for scheme, values in scores.items()
        for seed, value in enumerate(values)
    ]
    table = aggregate(runs, "success_rate", families=declare_families({"e1": experiment}, ["success_rate"]))
    infos = {"e1": metric_info("success_rate", "simple_spread")}
    return table, {check.text: check for check in check_claims(table, "success_rate", {"e1": experiment}, infos)}


def test_verdicts_follow_the_holm_adjusted_p_of_the_declared_family(tmp_path: Path) -> None:
    # Every pair's runs completely apart, 5 against 5: raw p = 2/252 = .0079 each.
    scores = {"actions": APART_HIGH, "full": APART_LOW, "observations": APART_LOW, "independent": [v + 1 for v in APART_HIGH]}
    declared = ["full", "independent", "observations", "actions", "selected", "selected_next"]
    _, checks = declared_checks(scores, {**FULL, "schemes": declared})
    # Against MADDPG: a family of the five schemes e1 declares (selected and selected_next have no runs yet):
    # 5 x .0079 = .040 < .05.
    fa = checks["MADDPG-fa > MADDPG"]
    assert fa.p_value == pytest.approx(2 / 252) and fa.p_adjusted == pytest.approx(5 * 2 / 252)
    assert fa.family_size == 5 and fa.verdict == "holds"
    # Between two other schemes: their own family, the claims of Exp. 1 between e1's declared schemes (IDDPG > fo
    # only): a family of one.
    between = checks["IDDPG > MADDPG-fo"]
    assert between.family_size == 1 and between.p_adjusted == between.p_value and between.verdict == "holds"
    # Seven schemes against MADDPG: 7 x .0079 = .056; the same runs only lean, with their raw p, and the seeds are
    # estimated at the family's Bonferroni level .05 / 7.
    wider = {**FULL, "schemes": [*declared, "extra_a", "extra_b"]}
    table, checks = declared_checks(scores, wider)
    fa = checks["MADDPG-fa > MADDPG"]
    assert fa.p_adjusted == pytest.approx(7 * 2 / 252) and fa.verdict == "leans the claim's way"
    assert fa.seeds_needed == seeds_to_separate(fa.better_scores, fa.worse_scores, alpha=0.05 / 7)
    assert checks["MADDPG > IDDPG"].verdict == "leans the other way"
    markdown = format_claims_markdown([fa], "success rate (%)", "higher is better")
    assert "| .008 | .056 (7) |" in markdown
    assert f"| leans the claim's way (p = .008; ~{fa.seeds_needed} seeds per scheme would likely confirm it" in markdown
    assert "the smallest two-sided p is .0079 at 5 runs a side" in markdown
    # The CSV has both p-values and the family's size.
    write_claims_report(tmp_path, table, "success_rate", {"e1": wider}, {"e1": metric_info("success_rate", "simple_spread")})
    row = next(r for r in csv.DictReader((tmp_path / "claims_success_rate.csv").open()) if r["better"] == "actions")
    assert float(row["p_value"]) == pytest.approx(2 / 252) and float(row["p_holm"]) == pytest.approx(7 * 2 / 252)
    assert row["family_size"] == "7" and row["verdict"] == "leans the claim's way"


def test_claims_between_two_other_schemes_are_adjusted_together() -> None:
    # Exp. 2 asks four claims between schemes other than MADDPG where all six run (the variant's too): fo > fa,
    # soa > fo, selected_next (soa) > fo, fa ~ IDDPG.
    scores = {
        "full": APART_LOW,
        "observations": [0.50, 0.52, 0.51, 0.53, 0.49],
        "actions": APART_LOW,
        "independent": APART_HIGH,
        "selected": [0.51, 0.60, 0.45, 0.58, 0.47],
        "selected_next": APART_HIGH,
    }
    variant = {"critic_sharing": "selected", "selector": {"k": 2, "target": "next"}}
    experiment = {**PARTIAL, "schemes": list(scores), "scheme_model_kwargs": {"selected_next": variant}}
    _, checks = declared_checks(scores, experiment)
    between = [
        "MADDPG-fo > MADDPG-fa",
        "MADDPG-soa > MADDPG-fo",
        "selected_next (MADDPG-soa) > MADDPG-fo",
        "MADDPG-fa ~ IDDPG",
    ]
    adjusted = holm([checks[text].p_value for text in between])
    for text, expected in zip(between, adjusted):
        assert checks[text].family_size == 4 and checks[text].p_adjusted == pytest.approx(expected), text
    # fa ~ IDDPG: apart (.0079), 4 x .0079 = .032: does not hold; fo > fa too.
    assert checks["MADDPG-fa ~ IDDPG"].verdict == "does not hold"
    assert checks["MADDPG-fo > MADDPG-fa"].verdict == "holds"
    # soa's runs straddle fo's (P(better) exactly 0.5): neither order.
    assert checks["MADDPG-soa > MADDPG-fo"].verdict == "not separated"


def test_a_p_just_below_the_level_is_never_printed_as_the_level() -> None:
    # 8 runs a side's 0.04988 rounds to ".050" at three decimals, beside a verdict that needs p < .05.
    assert format_p_value(0.049883449883449886) == ".0498"
    assert format_p_value(0.0504) == ".050" and format_p_value(0.05) == ".050"  # at or above the level: as rounded
    assert format_p_value(0.0317) == ".032" and format_p_value(2 / 3432) == "< .001" and format_p_value(math.nan) == "n/a"
