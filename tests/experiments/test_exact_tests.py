"""The report's tests fit the sample (issue 56): the Mann-Whitney U test is exact over every split of the runs, ties
included, against an enumeration written here; Holm's adjustment within declared families; Welch t intervals of
differences of means against scipy's."""

import itertools
import math
import time

import numpy as np
import pytest
from scipy.stats import mannwhitneyu, permutation_test, rankdata, t, ttest_1samp, ttest_ind

from sb3_maddpg.results.aggregates import mean_difference_interval
from sb3_maddpg.results.stats import (
    Family,
    aggregate,
    declare_families,
    floor_text,
    holm,
    mann_whitney,
    smallest_p_value,
)


def enumerated(x: list[float], y: list[float]) -> tuple[float, float]:
    """U of ``x`` and the two-sided p by brute force: every split of the pooled runs into groups of ``len(x)`` and
    ``len(y)``, U counted pair by pair (ties half), p the share of splits whose U is as far from ``n m / 2``."""
    pooled, n, m = [*x, *y], len(x), len(y)

    def u(group: tuple[int, ...]) -> float:
        rest = [i for i in range(n + m) if i not in group]
        return sum(1.0 if pooled[i] > pooled[j] else 0.5 if pooled[i] == pooled[j] else 0.0 for i in group for j in rest)

    observed = u(tuple(range(n)))
    splits = list(itertools.combinations(range(n + m), n))
    # U is a multiple of 0.5: the distances compare exactly.
    extreme = sum(abs(u(split) - n * m / 2) >= abs(observed - n * m / 2) for split in splits)
    return observed, extreme / len(splits)


SMALL_CASES = [
    ([0.3, 0.9], [0.1, 0.5]),  # 2 against 2: 6 splits
    ([0.4, 0.8, 0.6], [0.1, 0.2]),  # 3 against 2, separated: 10 splits
    ([1.0, 1.0, 2.0], [2.0, 3.0]),  # ties within and across the groups
    ([1.0, 2.0, 2.0, 3.0], [2.0, 2.0, 4.0]),  # four runs tied at 2.0, on both sides
    ([0.0, 0.0, 1.0, 1.0, 2.0], [1.0, 2.0, 2.0, 3.0, 3.0]),  # 5 against 5, tied across
    ([0.5, 0.5, 0.5], [0.5, 0.5]),  # every run the same: no split is less extreme
    ([0.2, 0.7, 0.1, 0.9, 0.4, 0.3], [0.8, 0.6, 0.5, 0.05]),  # interleaved, no ties
]


@pytest.mark.parametrize(("x", "y"), SMALL_CASES)
def test_the_p_value_is_the_share_of_all_splits_as_extreme(x: list[float], y: list[float]) -> None:
    u_statistic, p_value = mann_whitney(x, y)
    expected_u, expected_p = enumerated(x, y)
    assert u_statistic == expected_u
    assert p_value == pytest.approx(expected_p, rel=1e-12)
    # Two-sided: the same p whichever sample comes first.
    assert mann_whitney(y, x)[1] == pytest.approx(p_value, rel=1e-12)


def test_five_runs_apart_give_2_of_252_though_two_of_them_tie() -> None:
    # Every run of x beyond every run of y; two runs of x tie (0.72), as two success rates can in floating point.
    x, y = [0.61, 0.72, 0.55, 0.72, 0.67], [0.41, 0.38, 0.52, 0.45, 0.49]
    assert mann_whitney(x, y) == (25.0, pytest.approx(2 / 252, rel=1e-12))
    # scipy's default turns to its normal approximation on the tie: the issue's .012 where the runs do not overlap.
    assert mannwhitneyu(x, y).pvalue == pytest.approx(0.0119, abs=1e-4)
    assert smallest_p_value(5, 5) == pytest.approx(2 / 252, rel=1e-12)
    assert smallest_p_value(3, 3) == pytest.approx(0.1) and smallest_p_value(4, 4) == pytest.approx(2 / 70)
    assert smallest_p_value(0, 5) == 1.0
    assert all(math.isnan(value) for value in mann_whitney([0.1, math.nan], [0.2, 0.3]))  # no rank for a nan


def test_ties_across_the_groups_are_counted_where_scipy_s_exact_method_is_not() -> None:
    # One run of each side at 5: 2 of the 252 splits reach U = 0.5 and 2 its mirror, so p = 4/252.
    assert mann_whitney([1, 2, 3, 4, 5], [5, 6, 7, 8, 9]) == (0.5, pytest.approx(4 / 252, rel=1e-12))
    # scipy's method="exact" reads the tied U in the distribution without ties: 0.4 here, where 3 of the 10 splits
    # are as extreme (0.3), so it is no exact test under ties.
    x, y = [1.0, 1.0, 2.0], [2.0, 3.0]
    assert enumerated(x, y)[1] == pytest.approx(0.3)
    assert mann_whitney(x, y)[1] == pytest.approx(0.3)
    assert mannwhitneyu(x, y, method="exact").pvalue == pytest.approx(0.4)


def test_it_agrees_with_scipy_s_permutation_test_over_every_split() -> None:
    rng = np.random.default_rng(3)
    for n, m in ((5, 5), (6, 4), (7, 6)):
        x, y = np.round(rng.normal(0.0, 1.0, n), 1), np.round(rng.normal(0.7, 1.0, m), 1)  # rounded: ties
        ranks = rankdata(np.concatenate([x, y]))

        def distance(a: np.ndarray, b: np.ndarray, axis: int = -1, n: int = n, m: int = m) -> np.ndarray:
            return np.abs(np.sum(a, axis=axis) - n * (n + 1) / 2 - n * m / 2)

        reference = permutation_test(
            (ranks[:n], ranks[n:]), distance, permutation_type="independent", n_resamples=np.inf, alternative="greater"
        )
        assert mann_whitney(x, y)[1] == pytest.approx(reference.pvalue, rel=1e-9), (n, m)


def test_ten_against_ten_is_fast_enough_for_a_report_of_240_tests() -> None:
    rng = np.random.default_rng(0)
    samples = [(rng.normal(size=10).round(2), rng.normal(0.5, 1.0, 10).round(2)) for _ in range(240)]
    start = time.perf_counter()
    p_values = [mann_whitney(x, y)[1] for x, y in samples]
    elapsed = time.perf_counter() - start
    # 184,756 splits each; scipy's permutation_test takes about 2.6 s for one, this about half a millisecond.
    assert elapsed < 10.0, elapsed
    assert all(0.0 < p <= 1.0 for p in p_values)
    assert smallest_p_value(10, 10) == pytest.approx(2 / math.comb(20, 10), rel=1e-12)


def test_holm_steps_down_through_the_family() -> None:
    # Sorted: .005 x 4 = .02, .01 x 3 = .03, .03 x 2 = .06, .04 x 1 = .04 -> never below the one before: .06.
    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert holm([0.3, 0.5]) == pytest.approx([0.6, 0.6])  # 2 x .3 = .6, then 1 x .5 is raised to .6
    assert holm([0.7, 0.9]) == pytest.approx([1.0, 1.0])  # 2 x .7 capped at 1
    assert holm([0.02]) == pytest.approx([0.02])  # a family of one: the raw p
    # A declared test without runs counts in the family (as p = 1) and stays without a p.
    adjusted = holm([0.01, math.nan, 0.02])
    assert adjusted[0] == pytest.approx(0.03) and math.isnan(adjusted[1]) and adjusted[2] == pytest.approx(0.04)
    # Five runs against five, completely separated: the floor .0079 survives a family of 6, not one of 7.
    floor = smallest_p_value(5, 5)
    assert holm([floor] * 6)[0] < 0.05 <= holm([floor] * 7)[0]


def summaries(scores: dict[str, dict[str, list[float]]], metric: str = "min_dist_sum") -> list[dict]:
    return [
        {"experiment": setting, "scheme": scheme, "seed": seed, "score": {metric: value}}
        for setting, by_scheme in scores.items()
        for scheme, values in by_scheme.items()
        for seed, value in enumerate(values)
    ]


FULL = [0.50, 0.52, 0.51, 0.53, 0.49]
APART = [0.70, 0.72, 0.71, 0.73, 0.69]  # every run beyond `full`'s: p = .0079
CLOSE = [0.50, 0.55, 0.48, 0.60, 0.52]


def test_the_table_adjusts_each_setting_s_family_as_declared() -> None:
    experiments = {
        "e1": {"schemes": ["full", "independent", "selected", "actions"]},
        "e2": {"schemes": ["full", "independent", "observations", "actions", "selected", "selected_next"]},
    }
    families = declare_families(experiments, ["min_dist_sum", "success_rate"])
    assert Family("e1", "min_dist_sum", "full", ("independent", "selected", "actions")) in families
    assert len(families) == 4 and {family.size for family in families} == {3, 5}
    # e2 declares five schemes; "observations" and "actions" have no runs yet: they count, untested.
    scores = {
        "e1": {"full": FULL, "independent": APART, "selected": APART, "actions": CLOSE},
        "e2": {"full": FULL, "independent": APART, "selected": APART, "selected_next": CLOSE},
    }
    cells = {(cell.setting, cell.scheme): cell for cell in aggregate(summaries(scores), "min_dist_sum", families=families)}
    for setting, members in (("e1", ["independent", "selected", "actions"]), ("e2", list(experiments["e2"]["schemes"][1:]))):
        raw = [cells[setting, scheme].p_value if (setting, scheme) in cells else math.nan for scheme in members]
        for scheme, adjusted in zip(members, holm(raw)):
            if (setting, scheme) in cells:
                assert cells[setting, scheme].p_adjusted == pytest.approx(adjusted), (setting, scheme)
                assert cells[setting, scheme].family_size == len(members)
    assert cells["e1", "selected"].p_value == pytest.approx(2 / 252)
    assert cells["e1", "selected"].p_adjusted == pytest.approx(3 * 2 / 252)
    assert cells["e2", "selected"].p_adjusted == pytest.approx(5 * 2 / 252)
    assert cells["e1", "selected"].stars == "**"  # the marks stay the raw p's, as the paper's
    assert math.isnan(cells["e1", "full"].p_adjusted) and cells["e1", "full"].family_size == 0
    # Without declared families: the schemes that have runs.
    undeclared = {(c.setting, c.scheme): c for c in aggregate(summaries(scores), "min_dist_sum")}
    assert undeclared["e2", "selected"].family_size == 3
    assert undeclared["e2", "selected"].p_adjusted == pytest.approx(3 * 2 / 252)
    # A family of another metric is not this one's.
    other = declare_families({"e1": {"schemes": ["full", "selected"]}}, ["success_rate"])
    assert {(c.setting, c.scheme): c for c in aggregate(summaries(scores), "min_dist_sum", families=other)}[
        "e1", "selected"
    ].family_size == 3


def test_floor_text_says_the_smallest_p_the_runs_can_give() -> None:
    assert floor_text([5, 5, 5]) == "the smallest two-sided p is .0079 at 5 runs a side"
    assert floor_text([4, 5]) == "the smallest two-sided p is .029 at 4 runs a side, .0079 at 5 runs a side"
    assert floor_text([1]) == "the smallest two-sided p is 1 at 1 run a side"
    assert floor_text([]) == ""


@pytest.mark.parametrize(
    ("a", "b"),
    [([1.0, 2.0, 3.5, 2.2, 1.1], [2.0, 2.5, 4.0, 3.1, 3.3, 2.9]), ([0.52, 0.55, 0.49, 0.51, 0.53], [1.1, 0.98, 1.45, 1.04])],
)
def test_differences_of_means_take_welch_s_interval(a: list[float], b: list[float]) -> None:
    estimate = mean_difference_interval([a, b])
    welch = ttest_ind(a, b, equal_var=False).confidence_interval(0.95)
    assert estimate.value == pytest.approx(np.mean(a) - np.mean(b))
    assert (estimate.low, estimate.high) == (pytest.approx(welch.low), pytest.approx(welch.high))
    single = mean_difference_interval([a])
    one_sample = ttest_1samp(a, 0.0).confidence_interval(0.95)
    assert (single.low, single.high) == (pytest.approx(one_sample.low), pytest.approx(one_sample.high))


def test_a_difference_of_two_differences_adds_the_four_variances() -> None:
    a, b, c, d = [1.0, 1.2, 0.9, 1.1, 1.3], [0.5, 0.6, 0.4, 0.55, 0.45], [0.8, 0.7, 0.9, 0.85, 0.75], [0.6, 0.5, 0.7, 0.65]
    estimate = mean_difference_interval([a, b, c, d])
    means, variances = [np.mean(s) for s in (a, b, c, d)], [np.var(s, ddof=1) / len(s) for s in (a, b, c, d)]
    value = (means[0] - means[1]) - (means[2] - means[3])
    # Welch-Satterthwaite's degrees of freedom for a sum of four independent means' variances.
    freedom = sum(variances) ** 2 / sum(v**2 / (len(s) - 1) for v, s in zip(variances, (a, b, c, d)))
    half = t.ppf(0.975, freedom) * math.sqrt(sum(variances))
    assert estimate.value == pytest.approx(value)
    assert (estimate.low, estimate.high) == (pytest.approx(value - half), pytest.approx(value + half))
    # No spread, or a sample of one run: a point, or no interval.
    assert mean_difference_interval([[1.0, 1.0], [0.5, 0.5]]) == mean_difference_interval([[1.0, 1.0], [0.5, 0.5]]).__class__(
        0.5, 0.5, 0.5
    )
    assert math.isnan(mean_difference_interval([[1.0], [0.5, 0.6]]).low)
    with pytest.raises(ValueError, match="1, 2 or 4 samples, got 3"):
        mean_difference_interval([a, b, c])
