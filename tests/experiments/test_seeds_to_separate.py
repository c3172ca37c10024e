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
