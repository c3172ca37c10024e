"""Every mpe2 task as a gymnasium env for MADDPG: one factory, and the task metrics each task has."""

import importlib
import inspect
import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from sb3_maddpg.common.argument_ranges import SIMPLE_SPREAD_RANGES
from sb3_maddpg.envs.adapter import MetricsFn, PettingZooToGym
from sb3_maddpg.envs.simple_spread import SIMPLE_SPREAD_TASK_METRICS, make_simple_spread
from sb3_maddpg.envs.task_metric import TaskMetric

MPE_TASKS: dict[str, str] = {
    "simple": "mpe2.simple_v3",
    "simple_adversary": "mpe2.simple_adversary_v3",
    "simple_crypto": "mpe2.simple_crypto_v3",
    "simple_push": "mpe2.simple_push_v3",
    "simple_reference": "mpe2.simple_reference_v3",
    "simple_speaker_listener": "mpe2.simple_speaker_listener_v4",
    "simple_spread": "mpe2.simple_spread_v3",
    "simple_tag": "mpe2.simple_tag_v3",
    "simple_world_comm": "mpe2.simple_world_comm_v3",
}
"""The nine MPE tasks that :func:`make_mpe_env` builds, each mapped to the mpe2 module that defines it."""


def _distance(entity_a: Any, entity_b: Any) -> float:
    """Euclidean distance between two mpe2 entities (mpe2's ``np.sqrt(np.sum(np.square(delta)))``)."""
    return math.dist(entity_a.state.p_pos.tolist(), entity_b.state.p_pos.tolist())


def _contacts(group_a: Sequence[Any], group_b: Sequence[Any]) -> int:
    """Pairs (one from each group) closer than the sum of their sizes: mpe2's ``Scenario.is_collision``."""
    return sum(_distance(a, b) < a.size + b.size for a in group_a for b in group_b)


def simple_metrics(parallel_env: Any) -> dict[str, float]:
    """
    ``simple``: ``goal_distance``, the agent's distance to the landmark (its reward is minus its square).

    :param parallel_env: An mpe2 ``simple_v3`` env (or a wrapper whose ``unwrapped`` is one).
    :return: The metrics of the current world state.
    """
    world = parallel_env.unwrapped.world
    return {"goal_distance": _distance(world.agents[0], world.landmarks[0])}


def goal_race_metrics(parallel_env: Any) -> dict[str, float]:
    """
    ``simple_adversary`` and ``simple_push``: who is near the goal landmark, good agents or adversary.

    - ``goal_distance``: the nearest good agent's distance to the goal landmark (the good agents' reward term);
    - ``adversary_goal_distance``: the adversary's distance to the goal landmark.

    :param parallel_env: An mpe2 ``simple_adversary_v3`` or ``simple_push_v3`` env (or a wrapper around one).
    :return: The metrics of the current world state.
    """
    agents = parallel_env.unwrapped.world.agents
    good = [agent for agent in agents if not agent.adversary]
    adversaries = [agent for agent in agents if agent.adversary]
    return {
        "goal_distance": min(_distance(agent, agent.goal_a) for agent in good),
        "adversary_goal_distance": min(_distance(agent, agent.goal_a) for agent in adversaries),
    }


def _decodes(listener: Any, message_index: int) -> bool:
    """A listener recovers the message when it speaks (mpe2 ignores silence) and its loudest channel is the message's."""
    channels = listener.state.c.tolist()
    return any(channels) and channels.index(max(channels)) == message_index


def simple_crypto_metrics(parallel_env: Any) -> dict[str, float]:
    """
    ``simple_crypto``: whether Bob and Eve recover Alice's message from what they say.

    The message is a one-hot colour; a listener recovers it when its communication is not silent and its largest
    entry is at the message's index (the first largest, on ties).

    - ``bob_correct``: 1.0 when Bob recovers the message, else 0.0;
    - ``eve_correct``: 1.0 when Eve (the adversary) recovers it, else 0.0.

    :param parallel_env: An mpe2 ``simple_crypto_v3`` env (or a wrapper whose ``unwrapped`` is one).
    :return: The metrics of the current world state.
    """
    agents = parallel_env.unwrapped.world.agents
    message = agents[0].goal_a.color.tolist()
    message_index = message.index(max(message))
    eve = next(agent for agent in agents if agent.adversary)
    bob = next(agent for agent in agents if not agent.adversary and not agent.speaker)
    return {"bob_correct": float(_decodes(bob, message_index)), "eve_correct": float(_decodes(eve, message_index))}


def simple_reference_metrics(parallel_env: Any) -> dict[str, float]:
    """
    ``simple_reference``: ``goal_distance``, the sum over both agents of each one's distance to the landmark it must
    reach (the one only its partner knows; minus each term is that partner's local reward).

    :param parallel_env: An mpe2 ``simple_reference_v3`` env (or a wrapper whose ``unwrapped`` is one).
    :return: The metrics of the current world state.
    """
    agents = parallel_env.unwrapped.world.agents
    # Agent i's goal_a is its partner, goal_b the landmark the partner must reach.
    return {"goal_distance": sum(_distance(agent.goal_a, agent.goal_b) for agent in agents)}


def simple_speaker_listener_metrics(parallel_env: Any) -> dict[str, float]:
    """
    ``simple_speaker_listener``: ``goal_distance``, the listener's distance to the goal landmark (the team's reward is
    minus its square, mpe2's ``benchmark_data``).

    :param parallel_env: An mpe2 ``simple_speaker_listener_v4`` env (or a wrapper whose ``unwrapped`` is one).
    :return: The metrics of the current world state.
    """
    speaker = parallel_env.unwrapped.world.agents[0]
    # The speaker's goal_a is the listener, goal_b the landmark the listener must reach.
    return {"goal_distance": _distance(speaker.goal_a, speaker.goal_b)}


def catch_metrics(parallel_env: Any) -> dict[str, float]:
    """
    ``simple_tag`` and ``simple_world_comm``: ``collisions``, the adversary-good agent pairs in contact at this step
    (catches: the sum of mpe2's ``benchmark_data`` over the adversaries, what the rewards' catch terms count).

    Contacts between two adversaries, or an agent and an obstacle, are not counted. The key is ``collisions`` so
    that :func:`~sb3_maddpg.analysis.evaluation.evaluate_team` sums it over each episode: catches per episode.

    :param parallel_env: An mpe2 ``simple_tag_v3`` or ``simple_world_comm_v3`` env (or a wrapper around one).
    :return: The metrics of the current world state.
    """
    agents = parallel_env.unwrapped.world.agents
    good = [agent for agent in agents if not agent.adversary]
    adversaries = [agent for agent in agents if agent.adversary]
    return {"collisions": float(_contacts(adversaries, good))}


_GOAL_RACE = (
    TaskMetric("goal_distance", "last", "lower", "good agents", "nearest good agent's distance to the goal landmark"),
    TaskMetric("adversary_goal_distance", "last", "lower", "adversaries", "the adversary's distance to the goal landmark"),
)
_CATCHES = (TaskMetric("collisions", "sum", "higher", "adversaries", "adversary-good agent pairs in contact (catches)"),)

MPE_TASK_METRICS: dict[str, tuple[TaskMetric, ...]] = {
    "simple": (TaskMetric("goal_distance", "last", "lower", "team", "the agent's distance to the landmark"),),
    "simple_adversary": _GOAL_RACE,
    "simple_crypto": (
        TaskMetric("bob_correct", "last", "higher", "good agents", "1 when Bob recovers Alice's message, else 0"),
        TaskMetric("eve_correct", "last", "higher", "adversaries", "1 when Eve recovers Alice's message, else 0"),
    ),
    "simple_push": _GOAL_RACE,
    "simple_reference": (
        TaskMetric("goal_distance", "last", "lower", "team", "sum of each agent's distance to its target landmark"),
    ),
    "simple_speaker_listener": (
        TaskMetric("goal_distance", "last", "lower", "team", "the listener's distance to the goal landmark"),
    ),
    "simple_spread": SIMPLE_SPREAD_TASK_METRICS,
    "simple_tag": _CATCHES,
    "simple_world_comm": _CATCHES,
}
"""The scalar metrics each task's env adds to ``info``: key, how an episode is scored, and which way is better for
whom. ``simple_spread`` also adds ``landmark_distances`` (a list; see :class:`~sb3_maddpg.envs.SimpleSpreadMetrics`)."""

_ADVERSARIES_AND_AGENTS: dict[str, tuple[str, ...]] = {"adversaries": ("adversary",), "good agents": ("agent",)}

MPE_TASK_SIDES: dict[str, dict[str, tuple[str, ...]]] = {
    "simple_adversary": _ADVERSARIES_AND_AGENTS,
    "simple_crypto": {"adversaries": ("eve",), "good agents": ("alice", "bob")},
    "simple_push": _ADVERSARIES_AND_AGENTS,
    "simple_tag": _ADVERSARIES_AND_AGENTS,
    "simple_world_comm": {"adversaries": ("leadadversary", "adversary"), "good agents": ("agent",)},
}
"""The sides of each competitive MPE task: side -> the names of its agents (an agent id ``<name>_<index>``, e.g.
``adversary_0``, belongs to the side that lists ``<name>``). The sides match :class:`TaskMetric`'s ``team`` and mpe2's
``adversary`` flag; the cooperative tasks (``simple``, ``simple_reference``, ``simple_speaker_listener``,
``simple_spread``) have one team and no entry. Pass them to :func:`~sb3_maddpg.analysis.evaluation.evaluate_team` as ``sides``
to score each side's return rather than a sum over opponents."""


_METRICS_FNS: dict[str, MetricsFn] = {
    "simple": simple_metrics,
    "simple_adversary": goal_race_metrics,
    "simple_crypto": simple_crypto_metrics,
    "simple_push": goal_race_metrics,
    "simple_reference": simple_reference_metrics,
    "simple_speaker_listener": simple_speaker_listener_metrics,
    "simple_tag": catch_metrics,
    "simple_world_comm": catch_metrics,
}

# Set by make_mpe_env itself, so not accepted among a task's keyword arguments.
_FACTORY_ARGUMENTS = ("continuous_actions", "max_cycles", "render_mode")


def make_mpe_env(
    task: str,
    continuous_actions: bool = True,
    max_cycles: int = 25,
    team_reward: Literal["sum", "mean"] = "sum",
    render_mode: str | None = None,
    **task_kwargs: Any,
) -> PettingZooToGym:
    """
    Build one of the nine MPE tasks of :data:`~sb3_maddpg.envs.mpe_tasks.MPE_TASKS` as a :class:`PettingZooToGym` env
    for MADDPG, with the task's metrics in ``info`` at every reset and step
    (see :data:`~sb3_maddpg.envs.mpe_tasks.MPE_TASK_METRICS`).

    Agents come in mpe2's ``possible_agents`` order; every agent's action is a ``Box(0, 1)``. Episodes end by
    truncation after ``max_cycles`` steps. ``make_mpe_env("simple_spread", **kwargs)`` is
    :func:`~sb3_maddpg.envs.make_simple_spread` ``(**kwargs)``: 5 agents by default (the paper's; mpe2's is 3),
    and mpe2's ``N`` is accepted for ``n_agents``.

    :param task: The task's name, a key of :data:`~sb3_maddpg.envs.mpe_tasks.MPE_TASKS` (e.g. ``"simple_tag"``).
    :param continuous_actions: mpe2's continuous actions (``Box``), or its discrete ones (``Discrete``: one-hot slots in the
        joint action, see :class:`~sb3_maddpg.envs.PettingZooToGym`).
    :param max_cycles: Episode length in steps.
    :param team_reward: How the agents' rewards are combined into SB3's scalar reward, ``"sum"`` or ``"mean"``
        (MADDPG trains each critic on its own agent's reward either way).
    :param render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
    :param task_kwargs: The task's own mpe2 arguments, e.g. ``N=3`` for ``simple_adversary``,
        ``num_good=2, num_adversaries=4`` for ``simple_tag``, ``local_ratio`` for ``simple_reference``;
        for ``simple_spread``, :func:`~sb3_maddpg.envs.make_simple_spread`'s.
    :return: The gymnasium env.
    """
    module_name = _task_module(task)
    SIMPLE_SPREAD_RANGES["max_cycles"].check("max_cycles", max_cycles)  # every MPE task's episode length
    if task == "simple_spread":
        return make_simple_spread(
            max_cycles=max_cycles,
            render_mode=render_mode,
            team_reward=team_reward,
            continuous_actions=continuous_actions,
            **_simple_spread_kwargs(task_kwargs),
        )
    module = importlib.import_module(module_name)  # here, so that `import sb3_maddpg` stays light
    _check_task_kwargs(task, _mpe_arguments(module), task_kwargs)
    parallel_env = module.parallel_env(
        continuous_actions=continuous_actions, max_cycles=max_cycles, render_mode=render_mode, **task_kwargs
    )
    # Positions from the world's state: not every task's observation holds its agent's own position (an adversary of
    # simple_adversary sees only offsets, simple_speaker_listener's speaker no position at all).
    return PettingZooToGym(
        parallel_env,
        metrics_fn=_METRICS_FNS[task],
        team_reward=team_reward,
        positions=mpe_agent_positions,
        task_metrics=MPE_TASK_METRICS[task],
    )


def mpe_agent_positions(parallel_env: Any) -> np.ndarray:
    """
    Every agent's position in an MPE world, from its state: the position source the MPE tasks declare.

    :param parallel_env: An mpe2 parallel env (wrapped or not).
    :return: Positions, ``[n_agents, 2]`` in ``possible_agents`` order.
    """
    by_name = {agent.name: agent.state.p_pos for agent in parallel_env.unwrapped.world.agents}
    return np.array([by_name[agent] for agent in parallel_env.possible_agents], dtype=np.float32)


def _task_module(task: str) -> str:
    """The mpe2 module of ``task``, or an error that lists the tasks."""
    if task not in MPE_TASKS:
        raise ValueError(f"Unknown MPE task {task!r}: make_mpe_env builds one of {', '.join(MPE_TASKS)}.")
    return MPE_TASKS[task]


def _mpe_arguments(module: Any) -> list[str]:
    """The task arguments of an mpe2 module's env, less those that make_mpe_env sets itself."""
    parameters = inspect.signature(module.raw_env).parameters
    return [name for name in parameters if name not in _FACTORY_ARGUMENTS]


def _check_task_kwargs(task: str, accepted: list[str], task_kwargs: dict[str, Any]) -> None:
    """Name an argument the task does not take, and list the ones it does, before mpe2's bare ``TypeError``."""
    unknown = [name for name in task_kwargs if name not in accepted]
    if unknown:
        raise TypeError(
            f"{task} has no argument {', '.join(map(repr, unknown))}: its arguments are {', '.join(accepted)} "
            "(and make_mpe_env's own continuous_actions, max_cycles, team_reward, render_mode)."
        )


def _simple_spread_kwargs(task_kwargs: dict[str, Any]) -> dict[str, Any]:
    """make_simple_spread's keyword arguments from make_mpe_env's, with mpe2's ``N`` read as ``n_agents``."""
    from mpe2 import simple_spread_v3

    own = [
        name
        for name, parameter in inspect.signature(make_simple_spread).parameters.items()
        if parameter.kind is not parameter.VAR_KEYWORD and name not in (*_FACTORY_ARGUMENTS, "team_reward")
    ]
    accepted = own + [name for name in _mpe_arguments(simple_spread_v3) if name not in own]
    _check_task_kwargs("simple_spread", accepted, task_kwargs)
    kwargs = dict(task_kwargs)
    if "N" in kwargs:
        if "n_agents" in kwargs:
            raise TypeError(
                f"simple_spread got both N={kwargs['N']} and n_agents={kwargs['n_agents']}: they are the same "
                "argument (mpe2's name and make_simple_spread's), pass one."
            )
        kwargs["n_agents"] = kwargs.pop("N")
    return kwargs
