"""How many seeds would separate two methods (sb3_maddpg.experiments.stats.seeds_to_separate): exact where the
answer is forced, close to the textbook power analysis where it is not, and None where nothing separates them."""

import numpy as np
import pytest

from sb3_maddpg.experiments.stats import seeds_to_separate


def test_fully_separated_scores_need_the_fewest_seeds_a_two_sided_test_allows() -> None:
    # Every x below every y: with 3 seeds each the smallest two-sided p is 0.1, with 4 it is 0.029 (< 0.05).
    assert seeds_to_separate([0.1, 0.2, 0.3], [0.7, 0.8, 0.9]) == 4
    # At 0.01, 5 each is the least (p = 0.008 without ties); resampled scores tie, which costs a seed more here.
    assert seeds_to_separate([0.1, 0.2, 0.3], [0.7, 0.8, 0.9], alpha=0.01) in (5, 6)


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
    # significant tests is exactly 0 or 1. With 3 seeds each p = 0.047 (normal approximation with ties), with 2 it is
    # 0.19: the share is 1.0 from 3 seeds on, equal to power=1.0.
    assert seeds_to_separate([0.0, 0.0], [1.0, 1.0], power=1.0) == 3


def test_the_default_power_is_reached_by_a_share_of_exactly_80_percent(monkeypatch: pytest.MonkeyPatch) -> None:
    """A test whose p-values are set: from 7 seeds on exactly 320 of 400 simulated experiments are significant (the
    share 0.8 equals the default power), below 7 one fewer (0.7975)."""

    class Result:
        def __init__(self, pvalue: np.ndarray) -> None:
            self.pvalue = pvalue

    def mannwhitneyu(xs: np.ndarray, ys: np.ndarray, alternative: str, axis: int) -> Result:
        n_simulations, n = xs.shape
        significant = 320 if n >= 7 else 319
        return Result(np.where(np.arange(n_simulations) < significant, 0.0, 1.0))

    monkeypatch.setattr("scipy.stats.mannwhitneyu", mannwhitneyu)
    assert 320 / 400 == 0.8  # the share is the power exactly, not a float near it
    # Doubling reaches it at 8; bisecting finds 7 (6 falls short).
    assert seeds_to_separate([0.1, 0.2], [0.3, 0.4], n_simulations=400) == 7
