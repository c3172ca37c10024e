"""The report's normalised scores: each simple_spread setting's runs between random actions (0) and the scripted
controller (1), see :mod:`sb3_maddpg.analysis.normalised_score`."""

from collections.abc import Sequence
from typing import Any

import numpy as np

from sb3_maddpg.analysis.normalised_score import REFERENCE_EPISODES, normalised_scores, reference_scores
from sb3_maddpg.experiments.config import PAPER_NAMES, ordered_schemes, setting_label
from sb3_maddpg.experiments.defaults import DEFAULT_ENV, EPISODE_LENGTH


def setting_references(experiment: dict[str, Any] | None) -> dict[str, dict[str, float]] | None:
    """
    :param experiment: A stored experiment config.
    :return: Its task's references (:func:`~sb3_maddpg.analysis.normalised_score.reference_scores`), or ``None``
        where there are none: another task than simple_spread, or its discrete actions (the controller drives continuous ones).
    """
    if not experiment or experiment.get("env", DEFAULT_ENV) != DEFAULT_ENV:
        return None
    env_kwargs = experiment.get("env_kwargs") or {}
    if env_kwargs.get("continuous_actions", True) is False:
        return None
    return reference_scores(
        int(experiment["n_agents"]),
        float(env_kwargs.get("local_ratio", 0.5)),
        int(experiment.get("episode_length", EPISODE_LENGTH)),
    )


def format_normalised_markdown(summaries: Sequence[dict[str, Any]], experiments: dict[str, dict[str, Any]]) -> str | None:
    """
    :param summaries: Run summaries (``experiment``, ``scheme``, ``score``).
    :param experiments: The stored experiment configs.
    :return: A Markdown table of each setting's and method's mean min-dist sum and team return with their normalised
        scores, or ``None`` if no setting has references.
    """
    lines = [
        "### Normalised scores: 0 = uniformly random actions, 1 = the scripted controller (higher is better)",
        "",
        f"Means over runs; each reference measured over {REFERENCE_EPISODES} episodes of the same task "
        "(`sb3_maddpg.analysis.normalised_score`).",
        "",
        "| setting | method | runs | min-dist sum | normalised | team return | normalised |",
        "|---|---|---|---|---|---|---|",
    ]
    reference_lines = ["", "| setting | random: min-dist sum, return | controller: min-dist sum, return |", "|---|---|---|"]
    found = False
    for setting in dict.fromkeys(summary["experiment"] for summary in summaries):
        references = setting_references(experiments.get(setting))
        if references is None:
            continue
        found = True
        runs = [summary for summary in summaries if summary["experiment"] == setting]
        label = setting_label(setting, experiments.get(setting))
        for scheme in ordered_schemes(summary["scheme"] for summary in runs):
            scores = [summary["score"] for summary in runs if summary["scheme"] == scheme]
            mean = {metric: float(np.mean([score[metric] for score in scores])) for metric in ("min_dist_sum", "return_mean")}
            normalised = normalised_scores(mean, references)
            lines.append(
                f"| {label} | {PAPER_NAMES.get(scheme, scheme)} | {len(scores)} | {mean['min_dist_sum']:.3f} | "
                f"{normalised['min_dist_sum']:.2f} | {mean['return_mean']:.1f} | {normalised['return_mean']:.2f} |"
            )
        random, scripted = references["random"], references["scripted"]
        reference_lines.append(
            f"| {label} | {random['min_dist_sum']:.3f}, {random['return_mean']:.1f} | "
            f"{scripted['min_dist_sum']:.3f}, {scripted['return_mean']:.1f} |"
        )
    return "\n".join(lines + reference_lines) + "\n" if found else None
