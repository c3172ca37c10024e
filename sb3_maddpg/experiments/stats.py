"""Statistics of the paper's Table 2: mean (std) of per-run scores and Mann-Whitney U tests against MADDPG."""

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sb3_maddpg.analysis.evaluation import SUCCESS_RADII, radius_key
from sb3_maddpg.envs.mpe_tasks import MPE_TASK_METRICS
from sb3_maddpg.experiments.config import BASELINE_SCHEME, PAPER_NAMES, ordered_schemes


@dataclass(frozen=True)
class Metric:
    """
    How a score is shown.

    :param key: The key in a run's ``score``.
    :param label: A label for tables and axes.
    :param scale: Factor applied for display (100 for rates shown in %).
    :param higher_is_better: The direction of improvement.
    """

    key: str
    label: str
    scale: float = 1.0
    higher_is_better: bool = True


METRICS: dict[str, Metric] = {
    metric.key: metric
    for metric in (
        Metric("success_rate", "success rate (%)", 100.0),
        Metric("coverage", "landmark coverage (%)", 100.0),
        Metric("min_dist_sum", "sum of min. distances", 1.0, higher_is_better=False),
        Metric("return_mean", "team return", 1.0),
        Metric("collisions", "collisions per episode", 1.0, higher_is_better=False),
        *(
            Metric(radius_key(key, radius), f"{label} within {radius:g} (%)", 100.0)
            for radius in SUCCESS_RADII
            for key, label in (("success_rate", "success rate"), ("coverage", "landmark coverage"))
        ),
        Metric("group_return", "return of the scored agents (score_agents)", 1.0),
    )
}
"""The metrics a report can score runs by: ``success_rate`` (the paper's, at mpe2's 0.1 radius), ``coverage``,
``min_dist_sum``, ``return_mean``, ``collisions``, and success and coverage at each radius of
:data:`~sb3_maddpg.analysis.evaluation.SUCCESS_RADII` (``success_rate_r0.2``: every landmark within 0.2 of an agent),
``group_return`` (the summed return of a run's ``score_agents``), and the other MPE tasks' metrics
(:data:`~sb3_maddpg.envs.MPE_TASK_METRICS`, added below with their direction)."""

for _task_metric in (metric for task, metrics in MPE_TASK_METRICS.items() if task != "simple_spread" for metric in metrics):
    # The other MPE tasks' metrics, with their direction for the team they are written for (collisions keeps
    # simple_spread's: fewer is better, although in simple_tag they are the adversaries' catches).
    METRICS.setdefault(
        _task_metric.key,
        Metric(_task_metric.key, _task_metric.key.replace("_", " "), 1.0, _task_metric.better == "higher"),
    )


@dataclass(frozen=True)
class Cell:
    """
    One cell of Table 2: a method in a setting.

    :param setting: The experiment name.
    :param scheme: The sharing scheme.
    :param method: The paper's name of the scheme.
    :param scores: The per-run scores (displayed units), in seed order.
    :param mean: Their mean.
    :param std: Their sample standard deviation (``ddof=1``; 0 for a single run).
    :param u_statistic: Mann-Whitney U of this method against the baseline (``nan`` for the baseline).
    :param p_value: Its two-sided p-value (``nan`` for the baseline or when a side has no runs).
    :param stars: ``"**"`` for p < .01, ``"*"`` for p < .05, else ``""``.
    """

    setting: str
    scheme: str
    method: str
    scores: tuple[float, ...]
    mean: float
    std: float
    u_statistic: float
    p_value: float
    stars: str

    @property
    def n(self) -> int:
        """The number of runs."""
        return len(self.scores)


def significance_stars(p_value: float) -> str:
    """
    :param p_value: A p-value (``nan`` for no test).
    :return: ``"**"`` if p < .01, ``"*"`` if p < .05, else ``""`` (the paper's marks).
    """
    if math.isnan(p_value):
        return ""
    if p_value < 0.01:
        return "**"
    if p_value < 0.05:
        return "*"
    return ""


def mann_whitney(x: Sequence[float], y: Sequence[float]) -> tuple[float, float]:
    """
    Two-sided Mann-Whitney U test of ``x`` against ``y`` (``scipy.stats.mannwhitneyu``, its default
    method: exact for small samples without ties, else the normal approximation with tie correction).

    :param x: One sample (e.g. a method's per-run scores).
    :param y: The other (e.g. MADDPG's).
    :return: The U statistic of ``x`` and the p-value; ``(nan, nan)`` if a sample is empty, and
        ``p = 1`` when every value of both samples is the same (no evidence of a difference).
    """
    from scipy.stats import mannwhitneyu

    a, b = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if a.size == 0 or b.size == 0:
        return math.nan, math.nan
    if np.all(a == a[0]) and np.all(b == a[0]):
        return a.size * b.size / 2.0, 1.0
    result = mannwhitneyu(a, b, alternative="two-sided")
    return float(result.statistic), float(result.pvalue)


def seeds_to_separate(
    x: Sequence[float],
    y: Sequence[float],
    alpha: float = 0.05,
    power: float = 0.8,
    max_seeds: int = 200,
    n_simulations: int = 400,
    seed: int = 0,
) -> int | None:
    """
    How many seeds per method a Mann-Whitney U test would need to tell ``x`` from ``y`` at ``alpha`` with probability
    ``power``, if each method's scores were spread as measured: experiments of ``n`` seeds are simulated by drawing
    ``n`` scores with replacement from each sample (a bootstrap power analysis; it trusts the measured spread, so a
    handful of seeds gives a rough answer), and the smallest ``n`` (doubling, then bisecting) whose share of
    significant tests reaches ``power`` is returned.

    :param x: One method's per-run scores (at least 2).
    :param y: The other's (at least 2).
    :param alpha: The test's significance level (two-sided).
    :param power: The share of simulated experiments that must find the difference.
    :param max_seeds: The largest ``n`` tried.
    :param n_simulations: Simulated experiments per ``n``.
    :param seed: Seed of the simulations.
    :return: The seeds per method, or None when even ``max_seeds`` do not reach ``power`` (e.g. equal samples).
    """
    from scipy.stats import mannwhitneyu

    a, b = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if a.size < 2 or b.size < 2:
        raise ValueError(f"seeds_to_separate needs at least 2 scores per method, got {a.size} and {b.size}.")
    rng = np.random.default_rng(seed)

    def reaches(n: int) -> bool:
        xs, ys = rng.choice(a, (n_simulations, n)), rng.choice(b, (n_simulations, n))
        p_values = mannwhitneyu(xs, ys, alternative="two-sided", axis=1).pvalue
        return bool(np.mean(np.nan_to_num(p_values, nan=1.0) < alpha) >= power)

    low, high = 1, 2
    while not reaches(high):
        if high >= max_seeds:
            return None
        low, high = high, min(2 * high, max_seeds)
    while high - low > 1:  # reaches(high), not reaches(low)
        middle = (low + high) // 2
        low, high = (low, middle) if reaches(middle) else (middle, high)
    return high


def mean_std(values: Sequence[float]) -> tuple[float, float]:
    """
    :param values: Per-run scores.
    :return: Their mean and sample standard deviation (``ddof=1``; 0 for one value; ``nan`` for none).
    """
    array = np.asarray(values, dtype=float)
    if array.size == 0:
        return math.nan, math.nan
    std = float(array.std(ddof=1)) if array.size > 1 else 0.0
    return float(array.mean()), std


def aggregate(
    summaries: Sequence[dict[str, Any]],
    metric: str = "success_rate",
    baseline: str = BASELINE_SCHEME,
) -> list[Cell]:
    """
    Build Table 2 from run summaries: for each setting and scheme, the mean (std) of the per-run
    scores and the Mann-Whitney U test of the scheme's scores against the baseline's.

    :param summaries: Run summaries (``summary.json``: ``experiment``, ``scheme``, ``seed``, ``score``).
    :param metric: The score to tabulate (a key of :data:`METRICS` or any key of ``score``).
    :param baseline: The scheme tested against (MADDPG, ``"full"``).
    :return: The cells, settings in order of appearance, schemes in the paper's order (others after).
    """
    info = METRICS.get(metric, Metric(metric, metric))
    groups: dict[str, dict[str, list[tuple[int, float]]]] = {}
    for summary in summaries:
        value = float(summary["score"][metric]) * info.scale
        groups.setdefault(summary["experiment"], {}).setdefault(summary["scheme"], []).append((int(summary["seed"]), value))
    cells = []
    for setting, by_scheme in groups.items():
        order = ordered_schemes(by_scheme)
        reference = [value for _, value in sorted(by_scheme.get(baseline, []))]
        for scheme in order:
            scores = tuple(value for _, value in sorted(by_scheme[scheme]))
            mean, std = mean_std(scores)
            if scheme == baseline or not reference:
                u_statistic, p_value = math.nan, math.nan
            else:
                u_statistic, p_value = mann_whitney(scores, reference)
            cells.append(
                Cell(
                    setting=setting,
                    scheme=scheme,
                    method=PAPER_NAMES.get(scheme, scheme),
                    scores=scores,
                    mean=mean,
                    std=std,
                    u_statistic=u_statistic,
                    p_value=p_value,
                    stars=significance_stars(p_value),
                )
            )
    return cells
