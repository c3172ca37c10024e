"""MPE cooperative navigation (``mpe2.simple_spread_v3``) as a gymnasium env, with its task metrics."""

import math
from typing import Any, Literal

from sb3_maddpg.common.argument_ranges import SIMPLE_SPREAD_RANGES
from sb3_maddpg.envs.adapter import PettingZooToGym
from sb3_maddpg.envs.task_metric import TaskMetric

CAPTURE_RADIUS = 0.1
"""mpe2's distance within which an agent occupies a landmark (``Scenario.CAPTURE_RADIUS``)."""

SIMPLE_SPREAD_TASK_METRICS = (
    TaskMetric("success", "last", "higher", "team", "1 when every landmark is covered, else 0"),
    TaskMetric("coverage", "last", "higher", "team", "fraction of landmarks with an agent within the capture radius"),
    TaskMetric("collisions", "sum", "lower", "team", "agent pairs in contact"),
    TaskMetric("min_dist_sum", "last", "lower", "team", "sum over landmarks of the nearest agent's distance"),
)
"""The metrics simple_spread's envs add to ``info`` (and ``landmark_distances``, a list: see
:class:`SimpleSpreadMetrics`)."""

SIMPLE_SPREAD_POSITION_SLICE = slice(2, 4)
"""Where an agent's position lies in its simple_spread observation (``[velocity (2), position (2), ...]``)."""


class SimpleSpreadMetrics:
    """
    Task metrics for ``simple_spread``, computed from the world state with mpe2's own definitions
    (``Scenario.benchmark_data`` and ``Scenario.is_collision``), vectorised so they cost little per step.

    Returned keys:

    - ``coverage``: fraction of landmarks with some agent closer than ``capture_radius``;
    - ``success``: 1.0 when every landmark is covered, else 0.0;
    - ``collisions``: number of agent pairs in contact (distance below the sum of their sizes);
    - ``min_dist_sum``: sum over landmarks of the distance to the nearest agent;
    - ``landmark_distances``: each landmark's distance to its nearest agent (a list, landmark order), from which
      :func:`~sb3_maddpg.analysis.evaluation.evaluate_team` scores coverage and success at other radii.

    :param capture_radius: Distance within which an agent covers a landmark (mpe2 uses 0.1; small
        training budgets rarely reach it, so a larger radius can be useful for diagnostics).
    """

    def __init__(self, capture_radius: float = CAPTURE_RADIUS) -> None:
        check_simple_spread_arguments(capture_radius=capture_radius)
        self.capture_radius = float(capture_radius)

    def __call__(self, parallel_env: Any) -> dict[str, Any]:
        """
        :param parallel_env: An mpe2 simple_spread env (or a wrapper whose ``unwrapped`` is one).
        :return: The metrics of the current world state.
        """
        world = parallel_env.unwrapped.world
        # Plain Python over position tuples: for MPE's team sizes this is several times cheaper per
        # step than a dozen small numpy calls, and it follows benchmark_data's definitions exactly.
        agents = [(agent.state.p_pos.tolist(), agent.size) for agent in world.agents]
        radius = self.capture_radius
        landmark_distances = [
            min(math.dist(landmark.state.p_pos.tolist(), pos) for pos, _ in agents) for landmark in world.landmarks
        ]
        covered = sum(distance < radius for distance in landmark_distances)
        min_dist_sum = sum(landmark_distances)
        collisions = 0
        for i, (pos_i, size_i) in enumerate(agents):
            for pos_j, size_j in agents[i + 1 :]:
                collisions += math.dist(pos_i, pos_j) < size_i + size_j
        n_landmarks = len(world.landmarks)
        return {
            "coverage": covered / n_landmarks,
            "success": float(covered == n_landmarks),
            "collisions": float(collisions),
            "min_dist_sum": min_dist_sum,
            "landmark_distances": landmark_distances,
        }


def check_simple_spread_arguments(**values: Any) -> None:
    """
    Refuse simple_spread settings that mpe2 would reject or silently misread, naming the argument and its range
    (:data:`~sb3_maddpg.common.argument_ranges.SIMPLE_SPREAD_RANGES`).

    :param values: Any of ``n_envs``, ``n_agents``, ``num_agent_neighbors``, ``num_landmark_neighbors``,
        ``max_cycles``, ``local_ratio`` and ``capture_radius``, by name; the neighbours' bounds need ``n_agents``.
    """
    n_agents = values.get("n_agents")
    bounds = {} if n_agents is None else {"num_agent_neighbors": n_agents - 1, "num_landmark_neighbors": n_agents}
    for name, value in values.items():
        SIMPLE_SPREAD_RANGES[name].check(name, value, bounds.get(name))


def make_simple_spread(
    n_agents: int = 5,
    num_agent_neighbors: int | None = None,
    max_cycles: int = 25,
    local_ratio: float = 0.5,
    capture_radius: float = CAPTURE_RADIUS,
    render_mode: str | None = None,
    team_reward: Literal["sum", "mean"] = "sum",
    continuous_actions: bool = True,
    **mpe_kwargs: Any,
) -> PettingZooToGym:
    """
    Cooperative navigation: ``n_agents`` agents must cover ``n_agents`` landmarks without colliding.

    Returns :class:`PettingZooToGym` over ``mpe2.simple_spread_v3.parallel_env``, with :class:`SimpleSpreadMetrics`
    in ``info`` at every step. Each agent's action is a ``Box(0, 1, (5,))`` (no-op, left, right, down, up; with
    ``continuous_actions=False`` a one-hot choice of one of them, mpe2's ``Discrete(5)``); its observation is
    ``[own velocity, own position, landmark offsets, other agents' offsets, communication]``.

    :param n_agents: Number of agents (and landmarks). The paper uses 5.
    :param num_agent_neighbors: How many nearest other agents each agent observes; ``None`` for all
        (the paper's experiment 1), ``2`` for the paper's partially observable experiment 2.
    :param max_cycles: Episode length; episodes end by truncation after this many steps (paper: 25).
    :param local_ratio: mpe2's weight of the local collision penalty against the shared distance reward.
    :param capture_radius: Distance for a landmark to count as covered in the metrics.
    :param render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
    :param team_reward: How the per-agent rewards are combined into SB3's scalar reward.
    :param continuous_actions: mpe2's continuous actions (the paper's), or its discrete ones (Lowe et al.'s MPE).
    :param mpe_kwargs: Other keyword arguments for ``simple_spread_v3.parallel_env``
        (e.g. ``num_landmark_neighbors``, ``dynamic_rescaling``).
    :return: The gymnasium env.
    """
    from mpe2 import simple_spread_v3  # imported here so that `import sb3_maddpg` stays light

    check_simple_spread_arguments(
        n_agents=n_agents,
        num_agent_neighbors=num_agent_neighbors,
        num_landmark_neighbors=mpe_kwargs.get("num_landmark_neighbors"),
        max_cycles=max_cycles,
        local_ratio=local_ratio,
        capture_radius=capture_radius,
    )
    parallel_env = simple_spread_v3.parallel_env(
        N=n_agents,
        local_ratio=local_ratio,
        max_cycles=max_cycles,
        continuous_actions=continuous_actions,
        render_mode=render_mode,
        num_agent_neighbors=num_agent_neighbors,
        **mpe_kwargs,
    )
    return PettingZooToGym(
        parallel_env,
        metrics_fn=SimpleSpreadMetrics(capture_radius),
        team_reward=team_reward,
        positions=SIMPLE_SPREAD_POSITION_SLICE,
        task_metrics=SIMPLE_SPREAD_TASK_METRICS,
    )
