"""Aggregate statistics of per-run scores with interval estimates (Agarwal et al., "Deep Reinforcement Learning at
the Edge of the Statistical Precipice", NeurIPS 2021; rliable and marl-eval compute the same).

- The **interquartile mean** (IQM): the mean of the middle 50% of the runs' scores (``scipy.stats.trim_mean`` with
  25% cut at each end). Unlike the mean it is not pulled by a few outlier runs; unlike the median it uses half the
  runs, so its interval is narrower.
- The **probability of improvement** P(X > Y): the probability that a random run of method X scores higher than a
  random run of method Y, ties counted half (the Mann-Whitney U statistic over ``n x m``), averaged over settings.
- **95% stratified bootstrap confidence intervals** (``scipy.stats.bootstrap``, percentile method as rliable's
  default): runs are resampled with replacement within each setting (stratum) and each method separately. They see
  only the runs' own spread, so from a handful of runs they cover less than 95%.
- **Differences of means** (a method's gap to another, a difference of two gaps) take **Welch's t interval**
  (:func:`mean_difference_interval`), which keeps its coverage at 5 runs a side where a percentile bootstrap is too
  narrow (the interaction of issue 43's 2 x 2: [+0.21, +0.55] by percentile, [+0.12, +0.60] by Welch).
"""

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import bootstrap, t, trim_mean

CONFIDENCE_LEVEL = 0.95
"""The confidence level of every interval."""

N_RESAMPLES = 5000
"""Bootstrap resamples per interval (rliable uses 2,000 to 50,000)."""


Scores = Sequence[float] | np.ndarray
"""Per-run scores of one method in one setting."""


@dataclass(frozen=True)
class IntervalEstimate:
    """
    A point estimate with its bootstrap confidence interval.

    :param value: The statistic of the observed scores.
    :param low: The interval's lower end (``nan`` when it cannot be estimated, e.g. from one run).
    :param high: The interval's upper end.
    """

    value: float
    low: float
    high: float

    def format(self, digits: int = 2) -> str:
        """
        :param digits: Decimals shown.
        :return: E.g. ``"0.62 [0.51, 0.70]"``.
        """
        if math.isnan(self.value):
            return "nan"
        interval = "" if math.isnan(self.low) else f" [{self.low:.{digits}f}, {self.high:.{digits}f}]"
        return f"{self.value:.{digits}f}{interval}"


def iqm(scores: Scores, axis: int | None = -1) -> np.ndarray | float:
    """
    :param scores: Per-run scores (the runs along ``axis``).
    :param axis: The runs' axis (``None``: all values).
    :return: The interquartile mean: ``scipy.stats.trim_mean`` with 25% cut at each end.
    """
    return trim_mean(np.asarray(scores, dtype=float), proportiontocut=0.25, axis=axis)


def probability_of_improvement(x: Scores, y: Scores, axis: int = -1) -> np.ndarray:
    """
    :param x: Scores of method X (runs along ``axis``; leading axes are batches, e.g. bootstrap resamples).
    :param y: Scores of method Y, the same leading axes.
    :param axis: The runs' axis.
    :return: P(X > Y): the fraction of (x, y) pairs with x > y, ties counted half.
    """
    a = np.moveaxis(np.asarray(x, dtype=float), axis, -1)[..., :, None]
    b = np.moveaxis(np.asarray(y, dtype=float), axis, -1)[..., None, :]
    return ((a > b) + 0.5 * (a == b)).mean(axis=(-2, -1))


def bootstrap_interval(data: tuple[np.ndarray, ...], statistic: Callable[..., np.ndarray], seed: int = 0) -> IntervalEstimate:
    """
    A statistic of independent samples with its 95% percentile bootstrap interval, each sample resampled on its own
    (every interval of this module is one of these).

    :param data: The samples (e.g. two methods' per-run scores), each 1-D.
    :param statistic: ``statistic(*samples, axis=-1)``, vectorised over leading resample axes.
    :param seed: Seed of the resampling.
    :return: The statistic of ``data`` and its interval: ``nan`` ends when a sample has fewer than 2 runs, a zero-width
        interval when no sample has any spread.
    """
    value = float(statistic(*data, axis=-1))
    if min(sample.size for sample in data) < 2:  # one run says nothing about the spread
        return IntervalEstimate(value, math.nan, math.nan)
    if all(np.all(sample == sample[0]) for sample in data):  # no spread to resample
        return IntervalEstimate(value, value, value)
    result = bootstrap(
        data,
        statistic,
        n_resamples=N_RESAMPLES,
        vectorized=True,
        paired=False,
        confidence_level=CONFIDENCE_LEVEL,
        method="percentile",
        rng=np.random.default_rng(seed),
    )
    return IntervalEstimate(value, float(result.confidence_interval.low), float(result.confidence_interval.high))


def iqm_interval(strata: Sequence[Scores], seed: int = 0) -> IntervalEstimate:
    """
    The IQM of the runs of one method over one or more settings, with a 95% stratified bootstrap interval.

    :param strata: The per-run scores in each setting (one sequence per setting; the IQM is taken over all runs).
    :param seed: Seed of the resampling (the same scores and seed give the same interval).
    :return: The IQM and its interval.
    """
    data = tuple(np.asarray(stratum, dtype=float) for stratum in strata)
    if not data or any(sample.size == 0 for sample in data):
        return IntervalEstimate(math.nan, math.nan, math.nan)

    def statistic(*samples: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.asarray(iqm(np.concatenate([np.moveaxis(sample, axis, -1) for sample in samples], axis=-1), axis=-1))

    return bootstrap_interval(data, statistic, seed)


def improvement_interval(strata_x: Sequence[Scores], strata_y: Sequence[Scores], seed: int = 0) -> IntervalEstimate:
    """
    P(X > Y) averaged over settings, with a 95% stratified bootstrap interval (runs of X and of Y resampled
    separately within each setting).

    :param strata_x: Method X's per-run scores in each setting.
    :param strata_y: Method Y's per-run scores in the same settings, in the same order.
    :param seed: Seed of the resampling.
    :return: The probability of improvement of X over Y and its interval (0.5: neither is better).
    """
    if len(strata_x) != len(strata_y):
        raise ValueError(f"X and Y need scores in the same settings, got {len(strata_x)} and {len(strata_y)} settings.")
    data = tuple(np.asarray(s, dtype=float) for pair in zip(strata_x, strata_y) for s in pair)
    if not data or any(sample.size == 0 for sample in data):
        return IntervalEstimate(math.nan, math.nan, math.nan)

    def statistic(*samples: np.ndarray, axis: int = -1) -> np.ndarray:
        pairs = [probability_of_improvement(samples[i], samples[i + 1], axis=axis) for i in range(0, len(samples), 2)]
        return np.mean(pairs, axis=0)

    return bootstrap_interval(data, statistic, seed)


def mean_difference_interval(samples: Sequence[Scores]) -> IntervalEstimate:
    """
    A difference of the means of independent samples with its 95% Welch t interval: the mean of one sample, ``a -
    b`` of two, ``(a - b) - (c - d)`` of four; its standard error from each sample's own variance, its degrees of
    freedom Welch-Satterthwaite's. For one sample, the one-sample t interval; for two, ``scipy.stats.ttest_ind(a, b,
    equal_var=False).confidence_interval()``.

    :param samples: One, two or four samples of per-run scores.
    :return: The difference and its interval: ``nan`` ends when a sample has fewer than 2 runs, a zero-width interval
        when no sample has any spread.
    """
    arrays = [np.asarray(sample, dtype=float) for sample in samples]
    signs = {1: [1.0], 2: [1.0, -1.0], 4: [1.0, -1.0, -1.0, 1.0]}.get(len(arrays))
    if signs is None:
        raise ValueError(f"mean_difference_interval takes 1, 2 or 4 samples, got {len(arrays)}.")
    value = float(sum(sign * array.mean() for sign, array in zip(signs, arrays)))
    if min(array.size for array in arrays) < 2:  # one run says nothing about the spread
        return IntervalEstimate(value, math.nan, math.nan)
    variances = [array.var(ddof=1) / array.size for array in arrays]  # of each mean; the signs square away
    variance = float(sum(variances))
    if variance == 0.0:
        return IntervalEstimate(value, value, value)
    freedom = variance**2 / sum(v**2 / (array.size - 1) for v, array in zip(variances, arrays))
    half = float(t.ppf(0.5 + CONFIDENCE_LEVEL / 2, freedom)) * math.sqrt(variance)
    return IntervalEstimate(value, value - half, value + half)
