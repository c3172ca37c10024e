"""The paper's findings as checkable claims, and their check against a study's runs.

Sakagami and Takadama read their Table 2 as orderings (Section 5.3): under full observability (Exp. 1) MADDPG-fa >
MADDPG > IDDPG > MADDPG-fo and MADDPG-soa > MADDPG; under partial observability (Exp. 2) MADDPG-soa > MADDPG >
MADDPG-fo > MADDPG-fa ~ IDDPG (ranked, but nearly equal: 51.88% and 51.02%), and MADDPG-soa > MADDPG-fo.
:data:`PAPER_CLAIMS` holds each ordering as a pair of schemes with the paper's own evidence (a Mann-Whitney U test
against MADDPG, or only the means). :func:`check_claims` asks each claim of a setting with the same observability, on
one metric: the same two-sided Mann-Whitney U test (exact, :func:`~sb3_maddpg.results.stats.mann_whitney`), its
p Holm-adjusted within its family, the probability that a run of the scheme claimed better beats a run of the other
(95% bootstrap interval), a verdict that follows the adjusted p, and, where the runs do not separate the two, how many
seeds per scheme would at the measured spread (:func:`~sb3_maddpg.results.stats.seeds_to_separate`).

The families are declared before any score is read (:class:`~sb3_maddpg.results.stats.Family`): a claim of a
scheme against the baseline (MADDPG, ``full``) is a test of its setting's family, each scheme against the baseline, and
takes that family's adjustment, as the report's Table 2 does; the claims between two other schemes (e.g. IDDPG >
MADDPG-fo) form a family of their own per setting and metric.
"""

import csv
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from sb3_maddpg.experiments.config import BASELINE_SCHEME, PAPER_NAMES, setting_label
from sb3_maddpg.experiments.defaults import DEFAULT_ENV
from sb3_maddpg.results.aggregates import IntervalEstimate, improvement_interval
from sb3_maddpg.results.stats import (
    FAMILY_TEXT,
    METRICS,
    Cell,
    Metric,
    floor_text,
    holm,
    mann_whitney,
    seeds_to_separate,
    smallest_p_value,
)
from sb3_maddpg.sharing.registry import SCHEME_ALIASES

Observability = Literal["full", "partial"]

ALPHA = 0.05
"""The significance level of a verdict (two-sided Mann-Whitney U, Holm-adjusted within its family)."""

LEANS_CLAIM, LEANS_OTHER = "leans the claim's way", "leans the other way"
"""The verdicts of a claim whose runs lean one way without their adjusted p reaching :data:`ALPHA`."""

UNDECIDED_VERDICTS = ("not separated", LEANS_CLAIM, LEANS_OTHER)
"""The verdicts of a claim the runs do not decide (the adjusted p at :data:`ALPHA` or above)."""

PAPER_TABLE2: dict[Observability, dict[str, tuple[float, float, str]]] = {
    "full": {
        "full": (63.89, 12.28, ""),
        "independent": (44.58, 13.31, "**"),
        "observations": (36.89, 21.56, "**"),
        "actions": (73.63, 9.51, "**"),
        "selected": (71.58, 17.42, "*"),
    },
    "partial": {
        "full": (70.11, 21.58, ""),
        "independent": (51.02, 12.38, "**"),
        "observations": (67.70, 20.78, ""),
        "actions": (51.88, 18.28, "**"),
        "selected": (74.99, 17.51, ""),
    },
}
"""The paper's Table 2 by observability (Exp. 1: ``"full"``, Exp. 2: ``"partial"``) and scheme: mean success rate in %
(every landmark within 0.1 at the last step), its standard deviation over 31 runs, and the marks of the Mann-Whitney U
test against MADDPG (``*`` p < .05, ``**`` p < .01)."""


@dataclass(frozen=True)
class PaperClaim:
    """
    One ordering the paper reads from its Table 2.

    :param observability: ``"full"`` (Exp. 1) or ``"partial"`` (Exp. 2).
    :param better: The scheme claimed better (for ``"~"``: one of the two).
    :param worse: The scheme claimed worse (for ``"~"``: the other).
    :param relation: ``">"``: ``better`` scores better; ``"~"``: the two score alike.
    :param evidence: What the paper has for it.
    """

    observability: Observability
    better: str
    worse: str
    relation: Literal[">", "~"]
    evidence: str

    @property
    def text(self) -> str:
        """E.g. ``"MADDPG-fa > MADDPG"``."""
        return f"{PAPER_NAMES.get(self.better, self.better)} {self.relation} {PAPER_NAMES.get(self.worse, self.worse)}"


PAPER_CLAIMS: tuple[PaperClaim, ...] = (
    PaperClaim("full", "actions", "full", ">", "73.63 vs 63.89, p < .01"),
    PaperClaim("full", "selected", "full", ">", "71.58 vs 63.89, p < .05"),
    PaperClaim("full", "full", "independent", ">", "63.89 vs 44.58, p < .01"),
    PaperClaim("full", "full", "observations", ">", "63.89 vs 36.89, p < .01"),
    PaperClaim("full", "independent", "observations", ">", "44.58 vs 36.89, means only (not tested)"),
    PaperClaim("partial", "selected", "full", ">", "74.99 vs 70.11, not significant"),
    PaperClaim("partial", "full", "observations", ">", "70.11 vs 67.70, not significant"),
    PaperClaim("partial", "observations", "actions", ">", "67.70 vs 51.88, means only (not tested)"),
    PaperClaim("partial", "full", "actions", ">", "70.11 vs 51.88, p < .01"),
    PaperClaim("partial", "full", "independent", ">", "70.11 vs 51.02, p < .01"),
    PaperClaim("partial", "selected", "observations", ">", "74.99 vs 67.70, means only (not tested)"),
    PaperClaim("partial", "actions", "independent", "~", "51.88 vs 51.02, means only (ranked, nearly equal)"),
)
"""The paper's findings (Section 5.3), each an ordering of two schemes in one setting."""


def observability(experiment: Mapping[str, Any] | None) -> Observability | None:
    """
    :param experiment: A stored experiment config (``experiment.json``).
    :return: ``"full"`` when each agent observes every other agent (the paper's Exp. 1), ``"partial"`` when it observes
        fewer (Exp. 2), ``None`` for another task or an unknown config (no claim of the paper applies).
    """
    if not experiment or experiment.get("env", DEFAULT_ENV) != DEFAULT_ENV:
        return None
    neighbors = experiment.get("num_agent_neighbors")
    return "full" if neighbors is None or neighbors >= experiment["n_agents"] - 1 else "partial"


def paper_scheme_variants(experiment: Mapping[str, Any] | None) -> dict[str, str]:
    """
    :param experiment: A stored experiment config (``experiment.json``).
    :return: Its schemes that are variants of one of the paper's (a name of their own whose ``scheme_model_kwargs``
        give a paper scheme's ``critic_sharing``, e.g. ``selected_next`` of ``selected``), each with that scheme.
    """
    if not experiment:
        return {}
    variants = {}
    for scheme, kwargs in (experiment.get("scheme_model_kwargs") or {}).items():
        sharing = kwargs.get("critic_sharing") if isinstance(kwargs, Mapping) else None
        if scheme in PAPER_NAMES or not isinstance(sharing, str):
            continue
        paper = SCHEME_ALIASES.get(sharing, sharing)
        if paper in PAPER_NAMES:
            variants[scheme] = paper
    return variants


def scheme_text(scheme: str, variants: Mapping[str, str] | None = None) -> str:
    """:return: A scheme as the claims name it: the paper's name, or a variant's with the paper's in brackets."""
    if scheme in (variants or {}):
        return f"{scheme} ({PAPER_NAMES[(variants or {})[scheme]]})"
    return PAPER_NAMES.get(scheme, scheme)


@dataclass(frozen=True)
class ClaimCheck:
    """
    One claim asked of one setting's runs.

    :param claim: The paper's claim.
    :param setting: The experiment whose runs were asked.
    :param better_scores: The per-run scores of ``claim.better`` (displayed units).
    :param worse_scores: Those of ``claim.worse``.
    :param p_value: Exact two-sided Mann-Whitney U p-value of the two (``nan`` with no runs on a side).
    :param improvement: P(a run of ``claim.better`` scores better than one of ``claim.worse``), 95% bootstrap interval.
    :param verdict: By the adjusted p (``p_adjusted``): ``"holds"`` (the claimed order, p < :data:`ALPHA`),
        ``"reverses"`` (the other order, p < :data:`ALPHA`), ``"leans the claim's way"`` or ``"leans the other way"``
        (p >= :data:`ALPHA`, the runs' P(better) above or below 0.5), ``"not separated"`` (p >= :data:`ALPHA` with
        P(better) 0.5; for a ``"~"`` claim whatever the lean: consistent with it, though no evidence that the two are
        alike), ``"does not hold"`` (a ``"~"`` claim whose schemes differ, p < :data:`ALPHA`) or ``"too few runs"`` (so
        few that even completely separated runs would not reach p < :data:`ALPHA`, unadjusted).
    :param seeds_needed: For the undecided verdicts (:data:`UNDECIDED_VERDICTS`), and ``"too few runs"`` with at least
        2 runs a side (a sweep in progress): the seeds per scheme that would separate them at the measured spread, at
        the family's Bonferroni level (:data:`ALPHA` over its size, which Holm's adjustment then passes); ``None`` when
        not estimated (other verdicts, fewer than 2 runs a side) or when even 200 would not.
    :param better_scheme: The scheme asked in ``claim.better``'s place: itself, or a variant of it (see
        :func:`paper_scheme_variants`).
    :param worse_scheme: The scheme asked in ``claim.worse``'s place.
    :param variants: The setting's variants of the paper's schemes (for the claim's text).
    :param p_adjusted: ``p_value`` Holm-adjusted within its family (``nan`` where ``p_value`` is).
    :param family_size: The tests in that family.
    """

    claim: PaperClaim
    setting: str
    better_scores: tuple[float, ...]
    worse_scores: tuple[float, ...]
    p_value: float
    improvement: IntervalEstimate
    verdict: str
    seeds_needed: int | None
    better_scheme: str = ""
    worse_scheme: str = ""
    variants: Mapping[str, str] | None = None
    p_adjusted: float = math.nan
    family_size: int = 1

    @property
    def text(self) -> str:
        """The claim as asked, e.g. ``"MADDPG-soa > MADDPG"`` or ``"selected_next (MADDPG-soa) > MADDPG"``."""
        better, worse = self.better_scheme or self.claim.better, self.worse_scheme or self.claim.worse
        return f"{scheme_text(better, self.variants)} {self.claim.relation} {scheme_text(worse, self.variants)}"

    @property
    def n(self) -> int:
        """The runs of the side with fewer."""
        return min(len(self.better_scores), len(self.worse_scores))

    @property
    def outcome(self) -> str:
        """The verdict, naming the scheme that scores better where a ``~`` claim does not hold (e.g. ``"does not hold
        (MADDPG-fa scores better)"``): two checks with the same outcome say the same thing."""
        if self.verdict != "does not hold":
            return self.verdict
        better, worse = self.better_scheme or self.claim.better, self.worse_scheme or self.claim.worse
        winner = better if self.improvement.value > 0.5 else worse
        return f"does not hold ({scheme_text(winner, self.variants)} scores better)"


def _verdict(claim: PaperClaim, p_adjusted: float, improvement: float, n_better: int, n_worse: int) -> str:
    """The verdict of a claim by its adjusted p (see :class:`ClaimCheck`)."""
    if smallest_p_value(n_better, n_worse) >= ALPHA:
        return "too few runs"
    if claim.relation == "~":
        return "does not hold" if p_adjusted < ALPHA else "not separated"
    if p_adjusted < ALPHA:
        return "holds" if improvement > 0.5 else "reverses"
    if improvement == 0.5:
        return "not separated"
    return LEANS_CLAIM if improvement > 0.5 else LEANS_OTHER


def _seeds_estimated(verdict: str, n: int) -> bool:
    """
    :param verdict: A check's verdict.
    :param n: The runs of its side with fewer.
    :return: Whether it estimates the seeds that would separate its schemes: when not separated, or too few runs with at
        least 2 a side to estimate a spread from.
    """
    return verdict in UNDECIDED_VERDICTS or (verdict == "too few runs" and n >= 2)


def check_claims(
    cells: Sequence[Cell],
    metric: str,
    experiments: Mapping[str, Mapping[str, Any]],
    infos: Mapping[str, Metric] | None = None,
    claims: Sequence[PaperClaim] = PAPER_CLAIMS,
    baseline: str = BASELINE_SCHEME,
) -> list[ClaimCheck]:
    """
    Ask each claim of every setting with its observability that has runs of both its schemes, and again with a
    variant of a scheme in its place (:func:`paper_scheme_variants`: e.g. ``selected_next`` for ``selected``). A claim
    against ``baseline`` takes the adjusted p of the cells' family (each scheme against it, see
    :func:`~sb3_maddpg.results.stats.aggregate`); the claims between two other schemes are a family per setting:
    each pair of schemes the setting runs (its stored ``schemes``) that a claim asks, Holm-adjusted together.

    :param cells: One metric's Table 2 (:func:`~sb3_maddpg.results.stats.aggregate`).
    :param metric: Its key (for its direction when ``infos`` does not give it).
    :param experiments: The stored experiment configs, by name (a setting without one is not asked).
    :param infos: The metric as each setting's task shows it (its direction), by setting; for a setting not in it,
        :data:`~sb3_maddpg.experiments.metrics.METRICS`'s view (higher is better for a metric not there).
    :param claims: The claims to ask.
    :param baseline: The scheme ``cells`` test against.
    :return: A check per claim and setting, in the order of ``claims`` then of the settings.
    """
    by_key = {(cell.setting, cell.scheme): cell for cell in cells}
    settings = list(dict.fromkeys(cell.setting for cell in cells))
    asked_pairs: list[tuple[PaperClaim, str, str, str]] = []  # (claim, setting, better, worse), in the page's order
    others: dict[str, list[tuple[str, str]]] = {}  # each setting's family of pairs without the baseline
    for claim in claims:
        for setting in settings:
            experiment = experiments.get(setting)
            if observability(experiment) != claim.observability:
                continue
            variants = paper_scheme_variants(experiment)
            declared = (experiment or {}).get("schemes") or [scheme for s, scheme in by_key if s == setting]

            def asked(scheme: str, of: Mapping[str, str] = variants) -> list[str]:
                return [scheme, *(variant for variant, paper in of.items() if paper == scheme)]

            for better_scheme in asked(claim.better):
                for worse_scheme in asked(claim.worse):
                    pair = (better_scheme, worse_scheme)
                    if baseline not in pair and better_scheme in declared and worse_scheme in declared:
                        others.setdefault(setting, []).append(pair)  # declared by the config, runs or not
                    if (setting, better_scheme) in by_key and (setting, worse_scheme) in by_key:
                        asked_pairs.append((claim, setting, better_scheme, worse_scheme))
    raw = {(s, pair): _p_value(by_key, s, pair) for s, pairs in others.items() for pair in pairs}
    other_adjusted = {
        (s, pair): (float(p), len(pairs))
        for s, pairs in others.items()
        for pair, p in zip(pairs, holm([raw[s, pair] for pair in pairs]))
    }
    checks = []
    for claim, setting, better_scheme, worse_scheme in asked_pairs:
        better, worse = by_key[setting, better_scheme], by_key[setting, worse_scheme]
        if baseline in (better_scheme, worse_scheme):
            other = worse if better_scheme == baseline else better
            adjusted, family_size = other.p_adjusted, other.family_size
        else:
            adjusted, family_size = other_adjusted[setting, (better_scheme, worse_scheme)]
        info = (infos or {}).get(setting) or METRICS.get(metric, Metric(metric, metric))
        variants = paper_scheme_variants(experiments.get(setting))
        checks.append(_check(claim, setting, better, worse, info, variants, adjusted, family_size))
    return checks


def _p_value(by_key: Mapping[tuple[str, str], Cell], setting: str, pair: tuple[str, str]) -> float:
    """The raw p of two schemes' runs in a setting (``nan`` where one has none)."""
    if (setting, pair[0]) not in by_key or (setting, pair[1]) not in by_key:
        return math.nan
    return mann_whitney(by_key[setting, pair[0]].scores, by_key[setting, pair[1]].scores)[1]


def _check(
    claim: PaperClaim,
    setting: str,
    better: Cell,
    worse: Cell,
    info: Metric,
    variants: Mapping[str, str],
    p_adjusted: float,
    family_size: int,
) -> ClaimCheck:
    """One claim asked of two cells of a setting (the claim's schemes or variants of them), with its family's
    adjusted p."""
    sign = 1.0 if info.higher_is_better else -1.0
    _, p_value = mann_whitney(better.scores, worse.scores)
    improvement = improvement_interval([np.multiply(sign, better.scores)], [np.multiply(sign, worse.scores)])
    verdict = _verdict(claim, p_adjusted, improvement.value, better.n, worse.n)
    estimated = _seeds_estimated(verdict, min(better.n, worse.n))
    # The level a test must reach for Holm's adjustment to pass it whatever its rank: Bonferroni's.
    needed = seeds_to_separate(better.scores, worse.scores, alpha=ALPHA / max(family_size, 1)) if estimated else None
    return ClaimCheck(
        claim,
        setting,
        better.scores,
        worse.scores,
        p_value,
        improvement,
        verdict,
        needed,
        better.scheme,
        worse.scheme,
        variants or None,
        p_adjusted,
        family_size,
    )


def format_p_value(p_value: float) -> str:
    """
    :param p_value: A p-value.
    :return: It as the claims pages show it: ``".032"``, ``"< .001"``, ``"n/a"`` for none (``nan``). Just below
        :data:`ALPHA`, where three decimals would round up to it, four decimals cut down (0.04988: ``".0498"``), so
        that a verdict at p < .05 never stands beside a printed ".050".
    """
    if math.isnan(p_value):
        return "n/a"
    if p_value < 0.001:
        return "< .001"
    text = f"{p_value:.3f}"
    if p_value < ALPHA <= float(text):
        text = f"{math.floor(p_value * 10_000) / 10_000:.4f}"
    return text.lstrip("0")


def _finding(check: ClaimCheck) -> str:
    """The verdict in words: an undecided one with its raw p, and the seeds that would separate the two where the runs
    do not."""
    if check.verdict == "does not hold":
        return check.outcome
    if not _seeds_estimated(check.verdict, check.n):
        return check.verdict
    raw = f"p = {format_p_value(check.p_value)}" if check.verdict in UNDECIDED_VERDICTS else ""
    if len(set(check.better_scores) | set(check.worse_scores)) == 1:
        outlook = "every run scores the same"
    elif check.seeds_needed is None:
        outlook = "more than 200 seeds per scheme would be needed at this spread"
    else:
        outlook = _seeds_outlook(check)
    return f"{check.verdict} ({'; '.join(part for part in (raw, outlook) if part)})"


def _seeds_outlook(check: ClaimCheck) -> str:
    """Which way the runs lean, where the verdict does not say it, and the seeds per scheme that would likely show it
    (``check.seeds_needed`` is set)."""
    needed = f"~{check.seeds_needed} seeds per scheme"
    if check.claim.relation == "~" or check.improvement.value == 0.5:
        return f"{needed} would tell them apart at this spread"
    lean = "" if check.verdict in UNDECIDED_VERDICTS else f"{LEANS_CLAIM if check.improvement.value > 0.5 else LEANS_OTHER}; "
    if check.improvement.value > 0.5:
        return f"{lean}{needed} would likely confirm it at this spread"
    return f"{lean}{needed} would likely show the reverse at this spread"


def format_claims_markdown(
    checks: Sequence[ClaimCheck],
    metric_label: str,
    better: str,
    experiments: Mapping[str, Mapping[str, Any]] | None = None,
) -> str:
    """
    :param checks: From :func:`check_claims`.
    :param metric_label: The metric's label (e.g. ``"success rate within 0.3 (%)"``).
    :param better: Its direction in words (``"higher is better"``).
    :param experiments: The stored experiment configs (for setting labels).
    :return: Markdown: a row per claim and setting with the paper's evidence, the runs' means, the raw and the
        Holm-adjusted p, P(better) and the verdict, then how to read it.
    """
    lines = [
        f"### The paper's claims, asked of these runs: {metric_label}",
        "",
        f"| setting | claim | paper (success %) | runs | means here ({better}) | p | Holm p (tests in family) "
        "| P(first scores better) [95% CI] | verdict |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for check in checks:
        label = setting_label(check.setting, (experiments or {}).get(check.setting))
        means = f"{np.mean(check.better_scores):.2f} vs {np.mean(check.worse_scores):.2f}"
        runs = f"{len(check.better_scores)}, {len(check.worse_scores)}"
        lines.append(
            f"| {label} | {check.text} | {check.claim.evidence} | {runs} | {means} | {format_p_value(check.p_value)} | "
            f"{adjusted_p_text(check)} | {check.improvement.format(2)} | {_finding(check)} |"
        )
    floor = floor_text(n for check in checks for n in (len(check.better_scores), len(check.worse_scores)))
    lines += [
        "",
        f"Each claim is the paper's reading of its Table 2 (Section 5.3), asked of the setting with the same "
        f"observability (Exp. 1: every other agent observed; Exp. 2: fewer), on {metric_label} ({better}): `A > B` "
        "claims that A scores better, `A ~ B` that the two score alike. p: the exact two-sided Mann-Whitney U test "
        f"(every split of the two schemes' runs counted, ties ranked by their mean rank); {floor}. Holm p: p adjusted "
        f"within its family (the number of its tests in brackets). {FAMILY_TEXT.format(baseline='MADDPG')} A claim "
        "between two other schemes is a test of their own family: the claims between two schemes other than MADDPG "
        f"in the same setting and metric. Verdict at Holm p < {ALPHA:g}: *holds* (the claimed order), *reverses* (the "
        f"other order), *does not hold* (a `~` claim whose schemes differ); at Holm p >= {ALPHA:g}: *leans the "
        "claim's way* or *leans the other way* (where P(first scores better) is above or below 0.5) or *not "
        "separated* (for `~`: consistent with the claim, not evidence that the two are alike), with the raw p and "
        "the seeds per scheme that would separate the two with 80% power at the family's Bonferroni level "
        f"({ALPHA:g} over its tests, which Holm's adjustment then passes) if each scheme's runs were spread as "
        "measured: a bootstrap power analysis, rough from few runs; *too few runs*: even completely separated runs "
        "could not reach the level unadjusted (with 2 or more runs a side, the same estimate of the seeds that would "
        "separate them). P(first scores better): the chance that a random run of the claim's first scheme scores "
        "better than one of its second (0.5: no difference). Each family is corrected on its own, not the page as a "
        "whole.",
        "",
    ]
    return "\n".join(lines)


def adjusted_p_text(check: ClaimCheck) -> str:
    """:return: A check's Holm-adjusted p with the tests of its family, e.g. ``".040 (5)"``."""
    return f"{format_p_value(check.p_adjusted)} ({check.family_size})"


def format_beside_paper(
    cells: Sequence[Cell],
    metric_label: str,
    experiments: Mapping[str, Mapping[str, Any]] | None = None,
    baseline: str = BASELINE_SCHEME,
) -> str | None:
    """
    The paper's Table 2 beside these runs': for each observability, the paper's row, then each setting's with it.

    :param cells: One metric's Table 2 (:func:`~sb3_maddpg.results.stats.aggregate`).
    :param metric_label: The metric's label.
    :param experiments: The stored experiment configs (a setting without one is left out).
    :param baseline: The scheme the cells' marks test against (the paper's marks are against MADDPG).
    :return: Markdown, or None when no setting is one of the paper's (simple_spread with a known observability).
    """
    by_key = {(cell.setting, cell.scheme): cell for cell in cells}
    settings = list(dict.fromkeys(cell.setting for cell in cells))
    roles = {setting: observability((experiments or {}).get(setting)) for setting in settings}
    if not any(roles.values()):
        return None
    # The paper's five, then the settings' variants of them (no paper value).
    variants: dict[str, str] = {}
    for setting in settings:
        if roles[setting]:
            variants.update(paper_scheme_variants((experiments or {}).get(setting)))
    schemes = [*PAPER_TABLE2["full"], *(variant for variant in variants if any(c.scheme == variant for c in cells))]
    header = ["setting", *(scheme_text(scheme, variants) for scheme in schemes)]
    lines = [
        f"### Beside the paper's Table 2: {metric_label}",
        "",
        "| " + " | ".join(header) + " |",
        "|" + "|".join("---" for _ in header) + "|",
    ]
    paper_rows: tuple[tuple[Observability, str], ...] = (
        ("full", "paper, Exp. 1 (full obs.)"),
        ("partial", "paper, Exp. 2 (2 nearest obs.)"),
    )
    for role, paper_label in paper_rows:
        mine = [setting for setting in settings if roles[setting] == role]
        if not mine:
            continue
        paper = PAPER_TABLE2[role]
        row = [f"{mean:.2f} ({std:.2f}){' ' + stars if stars else ''}" for mean, std, stars in paper.values()]
        row += [""] * (len(schemes) - len(paper))
        lines.append(f"| {paper_label}, success % (31 runs) | " + " | ".join(row) + " |")
        for setting in mine:
            here = [by_key.get((setting, scheme)) for scheme in schemes]
            row = [
                "" if cell is None else f"{cell.mean:.2f} ({cell.std:.2f}){' ' + cell.stars if cell.stars else ''}"
                for cell in here
            ]
            runs = sorted({cell.n for cell in here if cell is not None})
            label = setting_label(setting, (experiments or {}).get(setting))
            runs_label = f"{', '.join(map(str, runs))} {'run' if runs == [1] else 'runs'}"
            lines.append(f"| {label}, {metric_label} ({runs_label}) | " + " | ".join(row) + " |")
    lines += [
        "",
        "Mean (std) of the per-run scores; `*` p < .05, `**` p < .01: two-sided Mann-Whitney U against MADDPG in the "
        f"paper's rows, against {PAPER_NAMES.get(baseline, baseline)} in the others (exact, the raw p as the paper "
        "marks its table; the verdicts below follow the Holm-adjusted p). The paper's rows are its success "
        "rate (every landmark within 0.1 at the last step), whatever the metric here.",
        "",
    ]
    return "\n".join(lines)


def write_claims_csv(checks: Sequence[ClaimCheck], metric: str, path: str | os.PathLike[str]) -> None:
    """
    One row per claim, setting and schemes asked (``better`` and ``worse``: the claim's, or variants of them in their
    place): ``setting, observability, better, worse, relation, paper_evidence, metric,
    n_better, n_worse, mean_better, mean_worse, p_value, p_holm, family_size, improvement, improvement_low,
    improvement_high, verdict, seeds_needed`` (empty when not estimated).

    :param checks: From :func:`check_claims`.
    :param metric: The score's key.
    :param path: The CSV file.
    """
    fields = ["setting", "observability", "better", "worse", "relation", "paper_evidence", "metric", "n_better"]
    fields += ["n_worse", "mean_better", "mean_worse", "p_value", "p_holm", "family_size"]
    fields += ["improvement", "improvement_low", "improvement_high"]
    fields += ["verdict", "seeds_needed"]
    with open(path, "w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(fields)
        for check in checks:
            claim, improvement = check.claim, check.improvement
            better, worse = check.better_scheme or claim.better, check.worse_scheme or claim.worse
            what = [check.setting, claim.observability, better, worse, claim.relation, claim.evidence, metric]
            means = [repr(float(np.mean(check.better_scores))), repr(float(np.mean(check.worse_scores)))]
            tests = [repr(check.p_value), repr(check.p_adjusted), check.family_size]
            tests += [repr(improvement.value), repr(improvement.low), repr(improvement.high)]
            needed = "" if check.seeds_needed is None else check.seeds_needed
            writer.writerow([*what, len(check.better_scores), len(check.worse_scores), *means, *tests, check.verdict, needed])


def write_claims_report(
    out_dir: str | os.PathLike[str],
    cells: Sequence[Cell],
    metric: str,
    experiments: Mapping[str, Mapping[str, Any]],
    infos: Mapping[str, Metric] | None = None,
    heading: str = "",
    baseline: str = BASELINE_SCHEME,
) -> list[Path]:
    """
    Write ``claims_<metric>.md`` (the paper's Table 2 beside these runs', then each claim's check) and
    ``claims_<metric>.csv`` (the checks), when a setting is one of the paper's (simple_spread with a known
    observability) and has runs of both schemes of a claim.

    :param out_dir: The report's directory.
    :param cells: One metric's Table 2 (:func:`~sb3_maddpg.results.stats.aggregate`).
    :param metric: Its key.
    :param experiments: The stored experiment configs, by name.
    :param infos: The metric as each setting's task shows it, by setting (label and direction).
    :param heading: Text put before the Markdown (e.g. a warning about the runs).
    :param baseline: The scheme the cells' marks test against.
    :return: The files written (none when no claim could be asked).
    """
    # The claims are asked of simple_spread settings only, so one view of the metric serves them all.
    checks = check_claims(cells, metric, experiments, infos, baseline=baseline)
    if not checks:
        return []
    info = (infos or {}).get(checks[0].setting) or METRICS.get(metric, Metric(metric, metric))
    beside = format_beside_paper(cells, info.label, experiments, baseline) or ""
    better = "higher is better" if info.higher_is_better else "lower is better"
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    markdown_path, csv_path = Path(out_dir) / f"claims_{metric}.md", Path(out_dir) / f"claims_{metric}.csv"
    markdown_path.write_text(heading + beside + "\n" + format_claims_markdown(checks, info.label, better, experiments))
    write_claims_csv(checks, metric, csv_path)
    return [markdown_path, csv_path]
