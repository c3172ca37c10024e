"""Where a team stands between random actions (0) and the scripted controller (1) on simple_spread.

``(score - random) / (reference - random)`` for the min-dist sum (lower is better) and the team return (higher is
better) alike: 0 is the uniformly random team, 1 the scripted controller
(:class:`~sb3_maddpg.envs.ScriptedSpreadPolicy`), above 1 better than it. The two references depend on the task (the
number of agents, ``local_ratio``, the episode length), not on what the agents observe: the controller reads true
positions. They are measured on :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` over :data:`REFERENCE_EPISODES` seeded
episodes, once per task and process.
"""

import functools
import math

from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.envs import RandomTeamPolicy, ScriptedSpreadPolicy, SimpleSpreadVecEnv

NORMALISED_METRICS = ("min_dist_sum", "return_mean")
"""The scores normalised: the min-dist sum at the last step and the team return."""
REFERENCE_EPISODES = 300
"""Episodes each reference is measured over."""
REFERENCE_SEED = 10_000
"""Seed of the reference episodes (and of the random team's actions)."""


@functools.lru_cache(maxsize=32)
def reference_scores(n_agents: int, local_ratio: float = 0.5, max_cycles: int = 25) -> dict[str, dict[str, float]]:
    """
    :param n_agents: Agents (and landmarks).
    :param local_ratio: mpe2's weight of the collision penalty.
    :param max_cycles: Steps per episode.
    :return: ``{"random": ..., "scripted": ...}``, each :func:`~sb3_maddpg.analysis.evaluation.evaluate_team`'s result over
        :data:`REFERENCE_EPISODES` episodes.
    """
    results = {}
    for name in ("random", "scripted"):
        env = SimpleSpreadVecEnv(REFERENCE_EPISODES, n_agents=n_agents, local_ratio=local_ratio, max_cycles=max_cycles)
        team = (
            RandomTeamPolicy(env.action_space, seed=REFERENCE_SEED) if name == "random" else ScriptedSpreadPolicy.for_env(env)
        )
        results[name] = evaluate_team(team, env, n_episodes=REFERENCE_EPISODES, seed=REFERENCE_SEED)
        env.close()
    return results


def normalised_score(value: float, random: float, reference: float) -> float:
    """
    :param value: A team's score.
    :param random: The random team's.
    :param reference: The scripted controller's.
    :return: ``(value - random) / (reference - random)``: 0 random, 1 the controller (either direction of "better").
    """
    if math.isclose(reference, random):
        return math.nan
    return (value - random) / (reference - random)


def normalised_scores(result: dict[str, float], references: dict[str, dict[str, float]]) -> dict[str, float]:
    """
    :param result: A team's scores (an :func:`~sb3_maddpg.analysis.evaluation.evaluate_team` result or a run's score).
    :param references: From :func:`reference_scores`.
    :return: The normalised score of each of :data:`NORMALISED_METRICS`.
    """
    return {
        metric: normalised_score(result[metric], references["random"][metric], references["scripted"][metric])
        for metric in NORMALISED_METRICS
    }


def describe_normalised(result: dict[str, float], references: dict[str, dict[str, float]]) -> str:
    """
    :param result: A team's scores.
    :param references: From :func:`reference_scores`.
    :return: One line, e.g. ``"normalised score (0 = random, 1 = scripted controller): min-dist sum 0.62 (random
        2.68, controller 0.10), return 0.71 (random -162.4, controller -43.7)"``.
    """
    scores = normalised_scores(result, references)
    random, scripted = references["random"], references["scripted"]
    return (
        "normalised score (0 = random, 1 = scripted controller; higher is better): "
        f"min-dist sum {scores['min_dist_sum']:.2f} (random {random['min_dist_sum']:.2f}, controller "
        f"{scripted['min_dist_sum']:.2f}), return {scores['return_mean']:.2f} (random {random['return_mean']:.1f}, "
        f"controller {scripted['return_mean']:.1f})"
    )
