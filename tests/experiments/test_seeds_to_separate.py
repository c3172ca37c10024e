"""How many seeds would separate two methods (sb3_maddpg.results.stats.seeds_to_separate): exact where the
answer is forced, close to the textbook power analysis where it is not, and None where nothing separates them."""

import numpy as np
import pytest

from sb3_maddpg.results.stats import seeds_to_separate


def test_fully_separated_scores_need_the_fewest_seeds_a_two_sided_test_allows() -> None:
    # Every x below every y: with 3 seeds each the smallest two-sided p is 0.1, with 4 it is 0.029 (< 0.05).
    assert seeds_to_separate([0.1, 0.2, 0.3], [0.7, 0.8, 0.9]) == 4
    # At 0.01, 5 each: the exact test's p of any 5 against 5 apart is 2/252 = 0.0079, ties within a side or not.
    assert seeds_to_separate([0.1, 0.2, 0.3], [0.7, 0.8, 0.9], alpha=0.01) == 5


def test_equal_scores_are_never_separated() -> None:
    assert seeds_to_separate([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], max_seeds=64) is None


def test_a_medium_effect_needs_about_what_the_textbook_says() -> None:
    """Normal scores 0.8 standard deviations apart: a t-test needs 26 per group at 80% power (Cohen), a Mann-Whitney
    test about 5% more."""
    rng = np.random.default_rng(0)
    needed = seeds_to_separate(rng.normal(0.0, 1.0, 2000), rng.normal(0.8, 1.0, 2000), n_simulations=1000)
    assert needed is not None and 22 <= needed <= 32


def test_too_few_scores_are_refused() -> None:
    with pytest.raises(ValueError, match="at least 2 scores per method, got 1 and 3"):
        seeds_to_separate([1.0], [1.0, 2.0, 3.0])


def test_a_share_of_significant_tests_equal_to_the_power_is_enough() -> None:
    """The power is reached at equality: "reaches ``power``" is ``>=``, not ``>``."""
    # Constant samples: every simulated experiment of n seeds is the same (all 0 against all 1), so the share of
    # significant tests is exactly 0 or 1. The exact test gives 3 seeds each p = 0.1 and 4 p = 0.029: the share is
    # 1.0 from 4 seeds on, equal to power=1.0. (scipy's normal approximation gave 3 seeds p = 0.047, and 3.)
    assert seeds_to_separate([0.0, 0.0], [1.0, 1.0], power=1.0) == 4


def test_the_default_power_is_reached_by_a_share_of_exactly_80_percent(monkeypatch: pytest.MonkeyPatch) -> None:
    """A test whose p-values are set: from 7 seeds on exactly 320 of 400 simulated experiments are significant (the
    share 0.8 equals the default power), below 7 one fewer (0.7975)."""

    def simulated_p_values(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        n_simulations, n = xs.shape
        significant = 320 if n >= 7 else 319
        return np.where(np.arange(n_simulations) < significant, 0.0, 1.0)

    monkeypatch.setattr("sb3_maddpg.results.stats.simulated_p_values", simulated_p_values)
    assert 320 / 400 == 0.8  # the share is the power exactly, not a float near it
    # Doubling reaches it at 8; bisecting finds 7 (6 falls short).
    assert seeds_to_separate([0.1, 0.2], [0.3, 0.4], n_simulations=400) == 7


def test_simulated_experiments_take_the_exact_test_up_to_its_limit_and_the_approximation_beyond() -> None:
    from scipy.stats import mannwhitneyu

    from sb3_maddpg.results.stats import POWER_EXACT_MAX_RUNS, mann_whitney, simulated_p_values

    rng = np.random.default_rng(1)
    for n in (3, POWER_EXACT_MAX_RUNS):  # resampled from few values: ties in most experiments
        xs, ys = rng.choice([0.1, 0.2, 0.3], (20, n)), rng.choice([0.2, 0.3, 0.4], (20, n))
        assert simulated_p_values(xs, ys) == pytest.approx([mann_whitney(x, y)[1] for x, y in zip(xs, ys)])
    n = POWER_EXACT_MAX_RUNS + 1
    xs, ys = rng.choice([0.1, 0.2, 0.3], (20, n)), rng.choice([0.2, 0.3, 0.4], (20, n))
    approximate = mannwhitneyu(xs, ys, alternative="two-sided", axis=1, method="asymptotic").pvalue
    assert simulated_p_values(xs, ys) == pytest.approx(approximate)
