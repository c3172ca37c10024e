"""A task metric an env declares: its key in ``info``, how an episode is scored, and which way is better for whom."""

from dataclasses import dataclass
from typing import Literal


@dataclass(frozen=True)
class TaskMetric:
    """
    One task metric that an env adds to ``info`` at every reset and step, as the env declares it (its
    ``task_metrics``): :func:`~sb3_maddpg.analysis.evaluation.evaluate_team` scores what an env declares, and only that.

    For an env of your own, return the values from :class:`~sb3_maddpg.envs.PettingZooToGym`'s ``metrics_fn`` and
    declare them beside it::

        PettingZooToGym(env, metrics_fn=lambda e: {"food_eaten": e.unwrapped.eaten},
                        task_metrics=[TaskMetric("food_eaten", "sum", "higher", "team", "food eaten per step")])

    :param key: The key in ``info``.
    :param per_episode: How an episode is scored: ``"last"``, the value at the episode's last step, or ``"sum"``,
        the sum over the episode's steps (as :func:`~sb3_maddpg.analysis.evaluation.evaluate_team` does for ``collisions``).
    :param better: ``"lower"`` or ``"higher"``: which way is better for ``team``.
    :param team: Whose objective ``better`` refers to: ``"team"`` (every agent, a cooperative task),
        ``"good agents"`` or ``"adversaries"``.
    :param description: What the number measures.
    """

    key: str
    per_episode: Literal["last", "sum"]
    better: Literal["lower", "higher"]
    team: Literal["team", "good agents", "adversaries"]
    description: str
