"""Tests of the aggregate statistics (IQM, probability of improvement, stratified bootstrap intervals) on fixed arrays,
against computations written independently here (sorting, pair loops, a NumPy bootstrap)."""

import itertools
import math

import numpy as np
import pytest
from scipy.stats import mannwhitneyu

from sb3_maddpg.results.aggregates import (
    CONFIDENCE_LEVEL,
    improvement_interval,
    iqm,
    iqm_interval,
    probability_of_improvement,
)
from sb3_maddpg.results.report import aggregate_estimates, format_aggregates_markdown
from sb3_maddpg.results.stats import aggregate

X = [0.62, 0.71, 0.05, 0.58, 0.66, 0.93, 0.60, 0.69]
Y = [0.41, 0.38, 0.52, 0.45, 0.49, 0.60, 0.44, 0.10]


def hand_iqm(values: list[float]) -> float:
    """The mean of the middle half (n divisible by 4)."""
    ordered = sorted(values)
    quarter = len(ordered) // 4
    return sum(ordered[quarter : len(ordered) - quarter]) / (len(ordered) - 2 * quarter)


def hand_improvement(x: list[float], y: list[float]) -> float:
    wins = sum(1.0 if a > b else 0.5 if a == b else 0.0 for a, b in itertools.product(x, y))
    return wins / (len(x) * len(y))


def numpy_bootstrap(strata: list[np.ndarray], statistic, n: int = 20_000, seed: int = 123) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """A percentile bootstrap resampling each array separately (an independent implementation)."""
    rng = np.random.default_rng(seed)
    resamples = [rng.choice(stratum, size=(n, stratum.size), replace=True) for stratum in strata]
    values = statistic(*resamples)
    alpha = (1 - CONFIDENCE_LEVEL) / 2
    return float(np.quantile(values, alpha)), float(np.quantile(values, 1 - alpha))


def test_iqm_is_the_mean_of_the_middle_half() -> None:
    assert iqm(X) == pytest.approx(hand_iqm(X))  # the outliers 0.05 and 0.93 are cut
    assert iqm(X) != pytest.approx(np.mean(X))
    assert iqm(np.array([X, Y]), axis=-1) == pytest.approx([hand_iqm(X), hand_iqm(Y)])  # batched


def test_probability_of_improvement_counts_pairs_and_ties() -> None:
    assert probability_of_improvement(X, Y) == pytest.approx(hand_improvement(X, Y))
    assert probability_of_improvement(X, Y) == pytest.approx(mannwhitneyu(X, Y).statistic / (len(X) * len(Y)))
    assert probability_of_improvement(Y, X) == pytest.approx(1 - hand_improvement(X, Y))
    ties = [0.0, 0.5, 0.5, 1.0]
    assert probability_of_improvement(ties, [0.5, 0.5]) == pytest.approx(hand_improvement(ties, [0.5, 0.5]))
    assert probability_of_improvement(ties, ties) == pytest.approx(0.5)


def test_iqm_interval_matches_an_independent_bootstrap() -> None:
    estimate = iqm_interval([X])
    assert estimate.value == pytest.approx(hand_iqm(X))
    assert estimate.low <= estimate.value <= estimate.high
    low, high = numpy_bootstrap([np.array(X)], lambda sample: np.array([hand_iqm(list(row)) for row in sample]), n=5000)
    assert estimate.low == pytest.approx(low, abs=0.02) and estimate.high == pytest.approx(high, abs=0.02)
    assert iqm_interval([X], seed=3) == iqm_interval([X], seed=3)  # reproducible


def test_intervals_are_stratified_by_setting() -> None:
    # Two settings on different scales: resampling within each keeps 8 runs of each, so the pooled IQM barely
    # moves; resampling the 16 runs together mixes the settings and widens the interval several times.
    low_setting = [0.10, 0.12, 0.11, 0.09, 0.13, 0.10, 0.12, 0.11]
    high_setting = [0.90, 0.88, 0.91, 0.89, 0.92, 0.90, 0.87, 0.91]
    stratified = iqm_interval([low_setting, high_setting])
    assert stratified.value == pytest.approx(hand_iqm(low_setting + high_setting))
    pooled_low, pooled_high = numpy_bootstrap([np.array(low_setting + high_setting)], lambda s: iqm(s, axis=-1), n=5000)
    assert stratified.high - stratified.low < 0.5 * (pooled_high - pooled_low)

    def mean_improvement(*samples: np.ndarray) -> np.ndarray:
        return (probability_of_improvement(samples[0], samples[1]) + probability_of_improvement(samples[2], samples[3])) / 2

    x2 = [value + 0.02 for value in Y]
    estimate = improvement_interval([X, x2], [Y, Y])
    assert estimate.value == pytest.approx((hand_improvement(X, Y) + hand_improvement(x2, Y)) / 2)
    low, high = numpy_bootstrap([np.array(X), np.array(Y), np.array(x2), np.array(Y)], mean_improvement)
    assert estimate.low == pytest.approx(low, abs=0.03) and estimate.high == pytest.approx(high, abs=0.03)


def test_degenerate_samples_and_bad_input() -> None:
    one_run = iqm_interval([[0.4]])
    assert one_run.value == 0.4 and math.isnan(one_run.low) and math.isnan(one_run.high)
    assert iqm_interval([[0.3, 0.3, 0.3]]) == iqm_interval([[0.3, 0.3, 0.3]]).__class__(0.3, 0.3, 0.3)
    assert math.isnan(iqm_interval([[]]).value)
    with pytest.raises(ValueError, match="same settings"):
        improvement_interval([X], [Y, Y])
    assert iqm_interval([X]).format(2).startswith(f"{hand_iqm(X):.2f} [")


def summaries(scores: dict[str, dict[str, list[float]]], metric: str) -> list[dict]:
    return [
        {"experiment": setting, "scheme": scheme, "seed": seed, "score": {metric: value}}
        for setting, by_scheme in scores.items()
        for scheme, values in by_scheme.items()
        for seed, value in enumerate(values)
    ]


def test_report_estimates_follow_the_metric_direction_and_aggregate_settings() -> None:
    scores = {"a": {"full": Y, "selected": X}, "b": {"full": Y, "selected": X}}
    rows = aggregate_estimates(aggregate(summaries(scores, "success_rate"), "success_rate"), "success_rate")
    by_key = {(row["setting"], row["scheme"]): row for row in rows}
    assert set(by_key) == {
        ("a", "full"),
        ("a", "selected"),
        ("b", "full"),
        ("b", "selected"),
        ("all", "full"),
        ("all", "selected"),
    }
    assert by_key["a", "full"]["improvement"] is None  # the baseline
    assert by_key["a", "selected"]["improvement"].value == pytest.approx(hand_improvement(X, Y))
    assert by_key["all", "selected"]["n"] == 16
    assert by_key["a", "selected"]["iqm"].value == pytest.approx(100 * hand_iqm(X))  # rates are shown in %
    # For a lower-is-better metric, "better" means lower: X's larger distances lose to Y's.
    rows = aggregate_estimates(aggregate(summaries(scores, "min_dist_sum"), "min_dist_sum"), "min_dist_sum")
    selected = next(row for row in rows if row["setting"] == "a" and row["scheme"] == "selected")
    assert selected["improvement"].value == pytest.approx(1 - hand_improvement(X, Y))
    markdown = format_aggregates_markdown(rows, "min_dist_sum")
    assert "all settings (stratified)" in markdown and "lower is better" in markdown and "| baseline |" in markdown


def rliable_modules():  # type: ignore[no-untyped-def]
    """rliable's ``library`` and ``metrics``, or a skip: it is no dependency (and its dependency ``arch`` fails to
    import under pandas 3 with a TypeError, not an ImportError)."""
    try:
        from rliable import library, metrics
    except Exception as error:
        pytest.skip(f"rliable is not importable here: {error!r}")
    return library, metrics


def test_iqm_improvement_and_their_intervals_agree_with_rliable() -> None:
    library, metrics = rliable_modules()
    # rliable's layout: runs x tasks; here two settings of 8 runs.
    x = np.array([X, [value + 0.1 for value in Y]]).T
    y = np.array([Y, X]).T
    ours_iqm = iqm_interval([x[:, 0], x[:, 1]])
    ours_improvement = improvement_interval([x[:, 0], x[:, 1]], [y[:, 0], y[:, 1]])
    assert ours_iqm.value == pytest.approx(metrics.aggregate_iqm(x))
    assert ours_improvement.value == pytest.approx(metrics.probability_of_improvement(x, y))
    # Their stratified percentile bootstrap intervals, from other random draws: alike to a bootstrap's noise.
    _, iqm_intervals = library.get_interval_estimates(
        {"x": x}, lambda scores: np.array([metrics.aggregate_iqm(scores)]), reps=20_000, random_state=np.random.RandomState(0)
    )
    assert (ours_iqm.low, ours_iqm.high) == (
        pytest.approx(iqm_intervals["x"][0, 0], abs=0.02),
        pytest.approx(iqm_intervals["x"][1, 0], abs=0.02),
    )
    _, improvement_intervals = library.get_interval_estimates(
        {"x,y": [x, y]},
        lambda a, b: np.array([metrics.probability_of_improvement(a, b)]),
        reps=2_000,
        random_state=np.random.RandomState(0),
    )
    assert (ours_improvement.low, ours_improvement.high) == (
        pytest.approx(improvement_intervals["x,y"][0, 0], abs=0.04),
        pytest.approx(improvement_intervals["x,y"][1, 0], abs=0.04),
    )
