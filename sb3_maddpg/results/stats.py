"""Statistics of the paper's Table 2: mean (std) of per-run scores and Mann-Whitney U tests against MADDPG.

- The test is **exact**: its p-value counts every split of the two samples' runs into groups of their sizes (252 at
  5 + 5, 184,756 at 10 + 10), ranks averaged over tied runs (:func:`mann_whitney`). scipy's ``mannwhitneyu`` turns to
  its normal approximation as soon as two runs tie, which at 5 runs a side is off by half (.012 where the exact p is
  2/252 = .0079).
- The tests are corrected by **family** (:class:`Family`), declared before any score is read: a study (the runs of one
  results directory) x a setting x a metric, each of the setting's schemes against the baseline. Holm's step-down
  adjustment (:func:`holm`) keeps the chance of any false finding in a family under the level.
"""

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sb3_maddpg.experiments.config import BASELINE_SCHEME, PAPER_NAMES, ordered_schemes
from sb3_maddpg.experiments.metrics import METRICS, Metric


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
    :param p_value: Its exact two-sided p-value (``nan`` for the baseline or when a side has no runs).
    :param stars: ``"**"`` for p < .01, ``"*"`` for p < .05, else ``""`` (of the raw p, as the paper marks its table).
    :param p_adjusted: The p-value Holm-adjusted within the setting's family (``nan`` where ``p_value`` is).
    :param family_size: The tests in that family (0 for the baseline).
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
    p_adjusted: float = math.nan
    family_size: int = 0

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


EXACT_MAX_RUNS = 50
"""Up to these many runs a side :func:`mann_whitney` is exact; beyond, it takes the normal approximation with tie
correction (its split counts would need ``runs x (2 runs)^2`` numbers; so many runs make the approximation close)."""

POWER_EXACT_MAX_RUNS = 12
"""Up to these many runs a side :func:`seeds_to_separate` simulates the exact test; beyond, the normal approximation
(400 simulated experiments per number of seeds tried: the exact test's cost grows as the fourth power of the runs, 0.1 s
per 400 at 12 a side, 0.6 s at 20)."""


def _doubled_midranks(values: np.ndarray) -> np.ndarray:
    """:return: Twice the ranks of ``values`` along their last axis, tied values sharing the mean of their ranks:
    integers."""
    from scipy.stats import rankdata

    return np.rint(2.0 * rankdata(values, axis=-1)).astype(np.int64)


def _split_counts(doubled_ranks: np.ndarray, n: int) -> np.ndarray:
    """
    :param doubled_ranks: Twice the midranks of the pooled runs.
    :param n: The size of one group.
    :return: ``counts[s]``: how many of the ``C(len(doubled_ranks), n)`` ways to pick a group of ``n`` runs give
        doubled ranks summing to ``s`` (each tied run counted as the run it is: every split is equally likely).
    """
    size = int(doubled_ranks.sum()) + 1
    counts = np.zeros((n + 1, size))  # counts[k, s]: groups of k runs among those seen, doubled rank sum s
    counts[0, 0] = 1.0
    for rank in doubled_ranks:
        # Each group either leaves this run out or takes it; numpy reads the right side before writing the left.
        counts[1:, rank:] += counts[:-1, : size - rank]
    return counts[n]


def _exact_p_value(doubled_ranks: np.ndarray, n: int) -> float:
    """
    :param doubled_ranks: Twice the midranks of the pooled runs, the first ``n`` of them the first sample's.
    :param n: The first sample's size.
    :return: The share of all splits whose U is at least as far from its mean ``n m / 2`` as the observed one.
    """
    m = doubled_ranks.size - n
    counts = _split_counts(doubled_ranks, n)
    # In doubled units: a group's rank sum s gives 2U = s - n(n + 1), whose mean is n m.
    center = n * (n + 1) + n * m
    observed = abs(int(doubled_ranks[:n].sum()) - center)
    extreme = np.abs(np.arange(counts.size) - center) >= observed  # integers: no rounding decides a tie
    return float(counts[extreme].sum() / counts.sum())


def mann_whitney(x: Sequence[float], y: Sequence[float]) -> tuple[float, float]:
    """
    Two-sided Mann-Whitney U test of ``x`` against ``y``, exact: the p-value is the share of all ``C(n + m, n)`` splits
    of the pooled runs into groups of ``n`` and ``m`` whose U is at least as far from its mean ``n m / 2`` as the
    observed one, tied runs ranked by their mean rank (a permutation test of U; ``scipy.stats.permutation_test`` over
    every split gives the same p, slower: 2.6 s at 10 + 10, where this counts the splits by their rank sums). Beyond
    :data:`EXACT_MAX_RUNS` runs a side: ``scipy.stats.mannwhitneyu``'s normal approximation with tie correction.

    :param x: One sample (e.g. a method's per-run scores).
    :param y: The other (e.g. MADDPG's).
    :return: The U statistic of ``x`` (pairs in which ``x`` scores higher, ties counted half) and the p-value;
        ``(nan, nan)`` if a sample is empty or holds a ``nan`` (no rank for it). Every split of samples whose runs all
        score the same is as extreme as the observed one: ``p = 1``. Completely separated samples of 5 give the smallest
        p of 5 against 5, 2/252 = .0079.
    """
    a, b = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if a.size == 0 or b.size == 0 or np.isnan(a).any() or np.isnan(b).any():
        return math.nan, math.nan
    doubled = _doubled_midranks(np.concatenate([a, b]))
    u_statistic = (int(doubled[: a.size].sum()) - a.size * (a.size + 1)) / 2.0
    if max(a.size, b.size) > EXACT_MAX_RUNS:
        from scipy.stats import mannwhitneyu

        return u_statistic, float(mannwhitneyu(a, b, alternative="two-sided", method="asymptotic").pvalue)
    return u_statistic, _exact_p_value(doubled, a.size)


def smallest_p_value(n_x: int, n_y: int) -> float:
    """
    :param n_x: Runs of one scheme.
    :param n_y: Runs of the other.
    :return: The smallest two-sided p-value :func:`mann_whitney` can give these many runs (every run of one above every
        run of the other): ``2 / C(n_x + n_y, n_x)``, e.g. 0.10 for 3 runs against 3, 0.029 for 4, 0.0079 for 5; 1
        when a side has none.
    """
    if n_x == 0 or n_y == 0:
        return 1.0
    return mann_whitney(range(n_x), range(n_x, n_x + n_y))[1]


def holm(p_values: Sequence[float]) -> np.ndarray:
    """
    Holm's step-down adjustment of a family's p-values: the k-th smallest of m is multiplied by ``m - k + 1``, and an
    adjusted p is never below that of a smaller raw p. Rejecting where the adjusted p is below a level keeps the chance
    of any false rejection in the family under it, whatever the tests' dependence.

    :param p_values: The family's raw p-values; ``nan`` for a test declared in it but not made (a side without runs):
        it counts in the family, as a p of 1, and stays ``nan``.
    :return: The adjusted p-values, in the same order.
    """
    raw = np.asarray(p_values, dtype=float)
    filled = np.where(np.isnan(raw), 1.0, raw)
    order = np.argsort(filled, kind="stable")
    steps = (filled.size - np.arange(filled.size)) * filled[order]
    adjusted = np.empty_like(filled)
    adjusted[order] = np.minimum(1.0, np.maximum.accumulate(steps))
    return np.where(np.isnan(raw), math.nan, adjusted)


@dataclass(frozen=True)
class Family:
    """
    A family of tests, Holm-adjusted together (:func:`holm`): in one study (the runs of one results directory), one
    setting and one metric, each of the setting's schemes against the baseline. Declared from the setting's stored
    config, before any score is read: a scheme it runs counts in the family even while it has no finished runs.

    :param setting: The experiment's name.
    :param metric: The score's key.
    :param baseline: The scheme the others are tested against.
    :param schemes: The schemes tested against it.
    """

    setting: str
    metric: str
    baseline: str
    schemes: tuple[str, ...]

    @property
    def size(self) -> int:
        """The number of tests."""
        return len(self.schemes)


FAMILY_TEXT = (
    "A family is one study x one setting x one metric: each of the setting's methods against {baseline}, declared "
    "from the setting's stored config before any score is read; Holm's step-down adjustment within it keeps the "
    "chance of any false finding in the family below the level."
)
"""How the report and the claims pages say what a family is (``baseline``: its name)."""


def declare_families(
    experiments: Mapping[str, Mapping[str, Any]], metrics: Iterable[str], baseline: str = BASELINE_SCHEME
) -> list[Family]:
    """
    :param experiments: The study's stored experiment configs, by name (their ``schemes``).
    :param metrics: The metrics the study is read on.
    :param baseline: The scheme the others are tested against.
    :return: Each setting's and metric's family: its schemes but the baseline, in the config's order.
    """
    metrics = list(metrics)
    return [
        Family(setting, metric, baseline, tuple(scheme for scheme in experiment.get("schemes", ()) if scheme != baseline))
        for setting, experiment in experiments.items()
        for metric in metrics
    ]


def floor_text(run_counts: Iterable[int]) -> str:
    """
    :param run_counts: The numbers of runs of a table's cells.
    :return: The smallest two-sided p each number of runs a side can give (every run of one side beyond every run of
        the other), e.g. ``"the smallest two-sided p is .0079 at 5 runs a side"``; ``""`` for no runs.
    """
    floors = [
        f"{f'{smallest_p_value(count, count):.2g}'.lstrip('0')} at {count} run{'' if count == 1 else 's'} a side"
        for count in sorted({count for count in run_counts if count > 0})
    ]
    return f"the smallest two-sided p is {', '.join(floors)}" if floors else ""


def simulated_p_values(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """
    :param xs: Simulated experiments' scores of one method, an experiment per row.
    :param ys: The other method's, as many rows, as many runs a row.
    :return: Each experiment's two-sided Mann-Whitney U p-value: exact (:func:`mann_whitney`'s) up to
        :data:`POWER_EXACT_MAX_RUNS` runs a side, else the normal approximation with tie correction.
    """
    n = xs.shape[1]
    if n > POWER_EXACT_MAX_RUNS:
        from scipy.stats import mannwhitneyu

        return np.asarray(mannwhitneyu(xs, ys, alternative="two-sided", axis=1, method="asymptotic").pvalue)
    doubled = _doubled_midranks(np.concatenate([xs, ys], axis=1))
    return np.array([_exact_p_value(row, n) for row in doubled])


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
    significant tests reaches ``power`` is returned. Each simulated experiment is tested as :func:`mann_whitney` tests
    runs: exactly up to :data:`POWER_EXACT_MAX_RUNS` seeds (resampled scores tie often, where the normal
    approximation is furthest off: 3 seeds of 0 against 3 of 1 give it p = .047, the exact test .10), with the normal
    approximation and its tie correction beyond.

    :param x: One method's per-run scores (at least 2).
    :param y: The other's (at least 2).
    :param alpha: The test's significance level (two-sided).
    :param power: The share of simulated experiments that must find the difference.
    :param max_seeds: The largest ``n`` tried.
    :param n_simulations: Simulated experiments per ``n``.
    :param seed: Seed of the simulations.
    :return: The seeds per method, or None when even ``max_seeds`` do not reach ``power`` (e.g. equal samples).
    """
    a, b = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if a.size < 2 or b.size < 2:
        raise ValueError(f"seeds_to_separate needs at least 2 scores per method, got {a.size} and {b.size}.")
    rng = np.random.default_rng(seed)

    def reaches(n: int) -> bool:
        p_values = simulated_p_values(rng.choice(a, (n_simulations, n)), rng.choice(b, (n_simulations, n)))
        return bool(np.mean(p_values < alpha) >= power)

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
    families: Sequence[Family] | None = None,
) -> list[Cell]:
    """
    Build Table 2 from run summaries: for each setting and scheme, the mean (std) of the per-run
    scores and the exact Mann-Whitney U test of the scheme's scores against the baseline's, Holm-adjusted within the
    setting's family.

    :param summaries: Run summaries (``summary.json``: ``experiment``, ``scheme``, ``seed``, ``score``).
    :param metric: The score to tabulate (a key of :data:`METRICS` or any key of ``score``).
    :param baseline: The scheme tested against (MADDPG, ``"full"``).
    :param families: The declared families (:func:`declare_families`); a setting without one of this metric and
        baseline: the schemes that have runs, but the baseline.
    :return: The cells, settings in order of appearance, schemes in the paper's order (others after).
    """
    info = METRICS.get(metric, Metric(metric, metric))
    groups: dict[str, dict[str, list[tuple[int, float]]]] = {}
    for summary in summaries:
        value = float(summary["score"][metric]) * info.scale
        groups.setdefault(summary["experiment"], {}).setdefault(summary["scheme"], []).append((int(summary["seed"]), value))
    declared = {
        family.setting: family.schemes for family in families or () if family.metric == metric and family.baseline == baseline
    }
    cells = []
    for setting, by_scheme in groups.items():
        order = ordered_schemes(by_scheme)
        reference = [value for _, value in sorted(by_scheme.get(baseline, []))]
        tests = {}
        for scheme in order:
            scores = tuple(value for _, value in sorted(by_scheme[scheme]))
            if scheme != baseline and reference:
                tests[scheme] = mann_whitney(scores, reference)
        members = list(declared.get(setting, [scheme for scheme in order if scheme != baseline]))
        members += [scheme for scheme in tests if scheme not in members]  # run, though not declared: tested too
        adjusted = dict(zip(members, holm([tests.get(scheme, (math.nan, math.nan))[1] for scheme in members])))
        for scheme in order:
            scores = tuple(value for _, value in sorted(by_scheme[scheme]))
            mean, std = mean_std(scores)
            u_statistic, p_value = tests.get(scheme, (math.nan, math.nan))
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
                    p_adjusted=float(adjusted.get(scheme, math.nan)),
                    family_size=0 if scheme == baseline else len(members),
                )
            )
    return cells
