"""The scores a run is scored by and how each is shown: its label, display scale and direction of improvement."""

from dataclasses import dataclass

from sb3_maddpg.analysis.evaluation import SUCCESS_RADII, radius_key
from sb3_maddpg.envs.mpe_tasks import MPE_TASK_METRICS


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
