"""Team evaluation: task success, landmark coverage, collisions and returns of a trained team."""

import copy
import csv
import os
import warnings
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.noise import VectorizedActionNoise
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, unwrap_vec_normalize

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.noise import add_noise, noise_copy_for_envs
from sb3_maddpg.common.package_warnings import SB3MADDPGWarning
from sb3_maddpg.common.torch_threads import in_package_threads
from sb3_maddpg.common.user_code import user_stacklevel

TASK_METRICS = ("success", "coverage", "collisions", "min_dist_sum")
"""The task metrics read from ``info`` (see :class:`~sb3_maddpg.envs.SimpleSpreadMetrics`)."""

SUCCESS_RADII = (0.1, 0.15, 0.2, 0.3)
"""Radii at which :func:`evaluate_team` also scores success and coverage: mpe2's capture radius 0.1, the agent
size 0.15, 0.2 and 0.3. Teams trained at small budgets rarely hold every agent within 0.1 of a landmark, so the
larger radii show progress that the paper's success rate at mpe2's radius cannot."""


def radius_key(metric: str, radius: float) -> str:
    """
    :param metric: ``"success_rate"`` or ``"coverage"``.
    :param radius: A radius of :data:`SUCCESS_RADII`.
    :return: The key of that metric at that radius, e.g. ``success_rate_r0.15``.
    """
    return f"{metric}_r{radius:g}"


RADIUS_KEYS = tuple(radius_key(metric, radius) for radius in SUCCESS_RADII for metric in ("success_rate", "coverage"))
"""The keys of success and coverage at each radius of :data:`SUCCESS_RADII`."""

EVAL_KEYS = (
    "success_rate",
    "coverage",
    "collisions",
    "min_dist_sum",
    "return_mean",
    "return_std",
    "episode_length",
    *RADIUS_KEYS,
)
"""The scalar results of :func:`evaluate_team`, in the order they are logged and written."""


SIDE_RETURN_PREFIX = "return_"
"""Each side's return is scored under ``return_<side>``, spaces as underscores (see :func:`side_return_key`)."""


def side_return_key(side: str) -> str:
    """
    :param side: A side of a competitive task, e.g. ``"good agents"`` (see ``sides`` of :func:`evaluate_team`).
    :return: The key of its return, e.g. ``return_good_agents``.
    """
    return SIDE_RETURN_PREFIX + side.replace(" ", "_")


def side_return_label(side: str) -> str:
    """
    :param side: A side of a competitive task.
    :return: How its return is named in text, e.g. ``"adversaries' return"``, ``"prey's return"``.
    """
    return f"{side}'" + ("" if side.endswith("s") else "s") + " return"


def side_returns(result: dict[str, Any]) -> dict[str, float]:
    """
    :param result: What :func:`evaluate_team` returned (or a run's score).
    :return: Each side's return by side (``"good agents"``), in the result's order; empty when no sides were scored.
    """
    return {
        key.removeprefix(SIDE_RETURN_PREFIX).replace("_", " "): float(value)
        for key, value in result.items()
        if key.startswith(SIDE_RETURN_PREFIX) and key not in ("return_mean", "return_std")
    }


def scores_simple_spread(task_metrics: Sequence["DeclaredMetric"]) -> bool:
    """
    :param task_metrics: The task metrics an evaluation declares.
    :return: Whether it scores simple_spread's metrics (simple_spread's own four among those declared): then
        :data:`EVAL_KEYS` apply; else only the declared metrics, the returns and the episode length do.
    """
    return set(TASK_METRICS) <= {metric.key for metric in task_metrics}


def _metric_label(metric: "DeclaredMetric") -> str:
    return metric.key.replace("_", " ") + ("/episode" if metric.per_episode == "sum" else "")


def _direction(metric: "DeclaredMetric") -> str:
    better, team = getattr(metric, "better", None), getattr(metric, "team", "team")
    if better is None:
        return ""
    return f" ({better} is better{'' if team == 'team' else f' for the {team}'})"


def describe_result(result: dict[str, Any], task_metrics: Sequence["DeclaredMetric"] | None = None) -> str:
    """
    :param result: What :func:`evaluate_team` returned.
    :param task_metrics: The task metrics to describe, with their directions (e.g. ``MPE_TASK_METRICS["simple_tag"]``);
        ``None``: those the evaluation declared (``result["task_metrics"]``), else simple_spread's where the result
        holds them (a stored score), else none.
    :return: Its headline numbers on one line, each with its direction. simple_spread: ``"success 12.0% (higher is
        better), coverage 55.3% (higher), collisions/episode 1.25 (lower), min-dist sum 0.38 (lower), return -30.73
        (std 5.21, higher)"``. Another task: its own metrics with their directions and for whom, then each side's
        return in a competitive task (never a sum over opponents), e.g. ``"collisions/episode 1.25 (higher is better
        for the adversaries), adversaries' return 12.50 (per agent, higher is better for them), good agents' return
        -20.10 (per agent, higher is better for them)"``. Metrics that do not apply (NaN) are left out.
    """
    declared = tuple(result.get("task_metrics", ()) if task_metrics is None else task_metrics)
    simple_spread = scores_simple_spread(declared) or (task_metrics is None and not declared and "success_rate" in result)
    parts = []
    if simple_spread:
        if not np.isnan(result.get("success_rate", np.nan)):
            parts.append(f"success {100 * result['success_rate']:.1f}% (higher is better)")
        if not np.isnan(result.get("coverage", np.nan)):
            parts.append(f"coverage {100 * result['coverage']:.1f}% (higher)")
        if not np.isnan(result.get("collisions", np.nan)):
            parts.append(f"collisions/episode {result['collisions']:.2f} (lower)")
        if not np.isnan(result.get("min_dist_sum", np.nan)):
            parts.append(f"min-dist sum {result['min_dist_sum']:.2f} (lower)")
    else:
        for metric in declared:
            value = float(result.get(metric.key, np.nan))
            if not np.isnan(value):
                parts.append(f"{_metric_label(metric)} {value:.2f}{_direction(metric)}")
    sides = side_returns(result)
    for side, value in sides.items():
        parts.append(f"{side_return_label(side)} {value:.2f} (per agent, higher is better for them)")
    if not sides and "return_mean" in result:
        team = "return" if simple_spread else "team return"
        parts.append(f"{team} {result['return_mean']:.2f} (std {result['return_std']:.2f}, higher)")
    if "group_return" in result:
        parts.append(f"group return {result['group_return']:.2f} (higher is better for the scored agents)")
    return ", ".join(parts)


def eval_keys(
    task_metrics: Sequence["DeclaredMetric"] = (), score_agents: Sequence[str] = (), sides: Sequence[str] = ()
) -> tuple[str, ...]:
    """
    :param task_metrics: Task metrics declared (see :func:`evaluate_team`).
    :param score_agents: Agent ids scored as a group.
    :param sides: The sides scored (their names), in a competitive task.
    :return: The scalar keys :func:`evaluate_team` returns with them: simple_spread's :data:`EVAL_KEYS` when it
        scores simple_spread (:func:`scores_simple_spread`), else the task metrics' keys, ``return_mean``,
        ``return_std`` and ``episode_length``; with sides, each side's return (:func:`side_return_key`) instead of
        ``return_mean`` and ``return_std``; and ``group_return`` when a group is scored.
    """
    declared = [metric.key for metric in task_metrics]
    base = list(EVAL_KEYS) if scores_simple_spread(task_metrics) else [*declared, "return_mean", "return_std"]
    if sides:
        at = base.index("return_mean")
        base[at : at + 2] = [side_return_key(side) for side in sides]
    if "episode_length" not in base:
        base.append("episode_length")
    extra = [key for key in declared if key not in base and not (scores_simple_spread(task_metrics) and key in TASK_METRICS)]
    return (*base, *extra, *(("group_return",) if score_agents else ()))


class DeclaredMetric(Protocol):
    """A task metric an env adds to ``info`` (e.g. :class:`~sb3_maddpg.envs.TaskMetric`): its key, and whether an
    episode is scored by its ``"last"`` step's value or the ``"sum"`` over its steps."""

    @property
    def key(self) -> str:
        """The key in ``info``."""

    @property
    def per_episode(self) -> str:
        """``"last"`` or ``"sum"``."""


class PredictsActions(Protocol):
    """Anything with SB3's ``predict`` (a model or a policy)."""

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, Any]: ...


@in_package_threads  # one torch thread unless the user chose one (sb3_maddpg.common.torch_threads)
def evaluate_team(
    model: PredictsActions,
    env: gym.Env | VecEnv,
    n_episodes: int = 100,
    deterministic: bool = True,
    seed: int | None = None,
    task_metrics: Sequence[DeclaredMetric] | None = None,
    score_agents: Sequence[str] = (),
    sides: Mapping[str, Sequence[str]] | None = None,
) -> dict[str, Any]:
    """
    Run a team for ``n_episodes`` episodes and measure the task, as the paper's evaluation does.

    It scores the task metrics the env declares (its ``task_metrics``: simple_spread's envs, every MPE task of
    :func:`~sb3_maddpg.envs.make_mpe_env`, or your own through ``PettingZooToGym(env, metrics_fn=...,
    task_metrics=[TaskMetric(...)])``), and only those: an env that declares none gets its returns and episode length.
    Each metric comes from the env's ``info`` at the **last step** of each episode or **summed over the episode**, as
    its :class:`~sb3_maddpg.envs.TaskMetric` says (simple_spread: ``success``, ``coverage``, ``min_dist_sum`` at the
    last step, ``collisions`` summed). Per-agent returns are summed from ``info["agent_rewards"]``. On simple_spread,
    success and coverage at each radius of :data:`SUCCESS_RADII` come from ``info["landmark_distances"]`` at the last
    step (each landmark's distance to its nearest agent; a landmark is covered when that distance is below the radius,
    as in mpe2). A declared metric the env's info never holds is ``nan``, with a warning.

    With a ``VecEnv`` of ``n`` envs the episodes are spread evenly over the envs, as in SB3's
    ``evaluate_policy``, so that the result does not favour short episodes.

    :param model: The trained model (anything with SB3's ``predict``).
    :param env: The evaluation env: a gymnasium env or an SB3 ``VecEnv``. It is reset here and not closed.
    :param n_episodes: Number of episodes.
    :param deterministic: ``True``: the team acts without exploration. ``False``: it acts as in training: ``predict``
        samples (for stochastic policies), and a model with ``action_noise`` (MADDPG, SB3's TD3 and DDPG) gets a copy
        of that noise added in the [-1, 1] action space and clipped there, as in the model's data collection (the
        model's own noise process is not advanced). As in a MADDPG model's training, no noise is added to discrete
        agents' one-hots, so their actions stay the most likely ones here (in training they are sampled).
    :param task_metrics: The task metrics to score from ``info`` (each is returned under its key, the mean over
        episodes of its last-step value or of its sum over the episode); ``None`` (the default): those the env
        declares (its ``task_metrics`` attribute; none if it has none); ``()``: none.
    :param score_agents: Agent ids (of the env's ``agent_layout``) whose summed mean return is returned as
        ``group_return``, e.g. the adversaries of ``simple_tag``.
    :param sides: The sides of a competitive task, e.g. ``MPE_TASK_SIDES["simple_tag"]``: side -> its agents, each an
        agent id or a name ``<name>`` for every id ``<name>_<index>`` (see :func:`resolve_sides`). Each side's return
        (the mean over its agents of their returns, so a side whose agents share a reward scores that reward, however
        many they are) is returned as ``return_<side>`` (:func:`side_return_key`), and the team return
        (``return_mean``, ``return_std``), which would add opponents' returns, is left out.
    :param seed: Seed for the env's first reset, so that two evaluations with the same seed see the
        same episodes (the same initial states); ``None`` to continue the env's own random stream.
    :return: A dict with ``success_rate`` (fraction of episodes in which every landmark is covered at
        the last step), ``coverage`` (mean fraction of landmarks covered at the last step),
        ``collisions`` (mean per episode), ``min_dist_sum`` (mean at the last step), ``return_mean`` and
        ``return_std`` (team return, the env's scalar reward), ``episode_length`` (mean),
        ``agent_returns`` (mean return of each agent, a list), ``n_episodes``, and ``success_rate_r<radius>`` and
        ``coverage_r<radius>`` for each radius of :data:`SUCCESS_RADII` (see :func:`radius_key`). With task metrics
        other than simple_spread's, simple_spread's keys are left out and the dict holds each task metric under its
        key, ``return_mean``, ``return_std`` (or each side's return), ``episode_length``, ``agent_returns``,
        ``n_episodes``, and ``task_metrics``: the metrics declared, so that :func:`describe_result` gives their
        directions. The scalar keys are :func:`eval_keys`'s.
    """
    if n_episodes < 1:
        raise ValueError(f"n_episodes must be at least 1, got {n_episodes}.")
    vec_env: VecEnv = env if isinstance(env, VecEnv) else DummyVecEnv([lambda: env])  # type: ignore[list-item, return-value]
    if task_metrics is None:
        task_metrics = declared_task_metrics(vec_env)
    if seed is not None:
        vec_env.seed(seed)
    tally = EpisodeTally(vec_env.num_envs, n_episodes, task_metrics)
    _play(model, vec_env, tally, deterministic)
    _warn_missing_metrics(tally)
    return _summarise(tally, vec_env, task_metrics, score_agents, sides)


def declared_task_metrics(env: gym.Env | VecEnv) -> tuple[DeclaredMetric, ...]:
    """
    :param env: An env or a VecEnv.
    :return: The task metrics it declares (its ``task_metrics``; of a VecEnv's first env); none if it declares none.
    """
    try:
        if isinstance(env, VecEnv):
            if not env.has_attr("task_metrics"):  # asked first: a SubprocVecEnv's worker dies on a missing attribute
                return ()
            declared = env.get_attr("task_metrics", indices=[0])[0]
        else:
            declared = env.get_wrapper_attr("task_metrics")
    except (AttributeError, NotImplementedError):
        return ()
    return tuple(declared or ())


class EpisodeTally:
    """
    What :func:`evaluate_team` counts: each env's running sums over its current episode, and each finished episode's
    values, up to each env's share of the episodes (spread evenly, as SB3's ``evaluate_policy`` does).

    :param n_envs: Number of envs.
    :param n_episodes: Number of episodes in all.
    :param task_metrics: The task metrics declared.
    """

    def __init__(self, n_envs: int, n_episodes: int, task_metrics: Sequence[DeclaredMetric]) -> None:
        self.targets = np.array([(n_episodes + i) // n_envs for i in range(n_envs)], dtype=int)
        self.counts = np.zeros(n_envs, dtype=int)
        self.team_returns = np.zeros(n_envs)
        self.lengths = np.zeros(n_envs, dtype=int)
        self.agent_returns: list[np.ndarray | None] = [None] * n_envs
        self.episodes: dict[str, list[Any]] = {key: [] for key in ("return", "length", "agent_returns", *RADIUS_KEYS)}
        self.declared = {metric.key: metric.per_episode for metric in task_metrics}
        self.declared_values: dict[str, list[float]] = {key: [] for key in self.declared}
        self.declared_sums = {key: np.zeros(n_envs) for key, per_episode in self.declared.items() if per_episode == "sum"}

    @property
    def scores_simple_spread(self) -> bool:
        """Whether simple_spread's metrics are declared (then success and coverage are scored at every radius too)."""
        return set(TASK_METRICS) <= set(self.declared)

    @property
    def done(self) -> bool:
        """Whether every env has played its share."""
        return bool((self.counts >= self.targets).all())

    def add_step(self, rewards: np.ndarray, dones: np.ndarray, infos: Sequence[dict[str, Any]]) -> None:
        """
        :param rewards: The team rewards of one step of every env.
        :param dones: Which envs' episodes ended (they were reset).
        :param infos: The envs' infos (the last step's, for an env whose episode ended).
        """
        self.team_returns += rewards
        self.lengths += 1
        for i, info in enumerate(infos):
            for key, sums in self.declared_sums.items():
                sums[i] += float(info.get(key, np.nan))
            if "agent_rewards" in info:
                step_rewards = np.asarray(info["agent_rewards"], dtype=np.float64)
                previous = self.agent_returns[i]
                self.agent_returns[i] = step_rewards if previous is None else previous + step_rewards
            if dones[i]:
                self._end_episode(i, info)

    def _end_episode(self, i: int, info: dict[str, Any]) -> None:
        """Keep env ``i``'s episode if it is within the env's share, and start its next one from zero."""
        if self.counts[i] < self.targets[i]:
            self.episodes["return"].append(float(self.team_returns[i]))
            self.episodes["length"].append(int(self.lengths[i]))
            self.episodes["agent_returns"].append(self.agent_returns[i])
            if self.scores_simple_spread:  # success and coverage at every radius, from the landmarks' distances
                for key, value in _radius_metrics(info.get("landmark_distances")).items():
                    self.episodes[key].append(value)
            for key, per_episode in self.declared.items():
                self.declared_values[key].append(
                    self.declared_sums[key][i] if per_episode == "sum" else float(info.get(key, np.nan))
                )
            self.counts[i] += 1
        self.team_returns[i], self.lengths[i], self.agent_returns[i] = 0.0, 0, None
        for sums in self.declared_sums.values():
            sums[i] = 0.0


def _play(model: PredictsActions, vec_env: VecEnv, tally: EpisodeTally, deterministic: bool) -> None:
    """Let the team act in ``vec_env`` (reset here), with the training's exploration when not deterministic, until
    ``tally`` holds every episode."""
    n_envs = vec_env.num_envs
    observations = vec_env.reset()
    states = None
    episode_starts = np.ones(n_envs, dtype=bool)
    exploration = None if deterministic else _exploration_noise(model, n_envs)
    layout = getattr(model, "agent_layout", None)  # a MADDPG model's: no noise on its discrete agents' one-hots
    discrete = layout.discrete_components() if isinstance(layout, AgentLayout) else None
    while not tally.done:
        actions, states = model.predict(observations, state=states, episode_start=episode_starts, deterministic=deterministic)
        if exploration is not None:
            actions = _add_noise(actions, exploration, vec_env.action_space, discrete)
        observations, rewards, dones, infos = vec_env.step(actions)
        tally.add_step(rewards, dones, infos)
        episode_starts = dones
        if exploration is not None and dones.any():
            exploration.reset(np.flatnonzero(dones))


def _warn_missing_metrics(tally: EpisodeTally) -> None:
    """Warn about declared metrics the env's info never held (they are ``nan``), saying how to give them."""
    missing = [key for key, values in tally.declared_values.items() if np.isnan(values).all()]
    if tally.scores_simple_spread and np.isnan(tally.episodes[RADIUS_KEYS[0]]).all():
        missing.append("landmark_distances")
    if missing:
        warnings.warn(
            f"evaluate_team: the env's info has no values for the task metrics {missing}, so they are nan: return them "
            "from the env's metrics function, e.g. PettingZooToGym(env, metrics_fn=lambda e: {'food_eaten': ...}, "
            "task_metrics=[TaskMetric('food_eaten', 'sum', 'higher', 'team', 'food eaten')]), or score only what it "
            "declares (task_metrics=None, the default).",
            SB3MADDPGWarning,
            stacklevel=user_stacklevel(),
        )


def _summarise(
    tally: EpisodeTally,
    vec_env: VecEnv,
    task_metrics: Sequence[DeclaredMetric],
    score_agents: Sequence[str],
    sides: Mapping[str, Sequence[str]] | None,
) -> dict[str, Any]:
    """:func:`evaluate_team`'s result from its episodes: the means of :func:`eval_keys`'s keys, and the agents'."""
    episodes = tally.episodes
    returns = np.asarray(episodes["return"])
    per_agent = [r for r in episodes["agent_returns"] if r is not None]
    declared = {key: float(np.mean(values)) for key, values in tally.declared_values.items()}
    spread: dict[str, float] = {}
    if tally.scores_simple_spread:  # simple_spread's own names: success_rate for success, and each radius
        spread = {"success_rate": declared["success"], **{key: float(np.mean(episodes[key])) for key in RADIUS_KEYS}}
    everything = {
        **declared,
        **spread,
        "return_mean": float(returns.mean()),
        "return_std": float(returns.std()),
        "episode_length": float(np.mean(episodes["length"])),
        **({"group_return": _group_return(vec_env, per_agent, score_agents)} if score_agents else {}),
        **_side_returns(vec_env, per_agent, len(returns), sides or {}),
    }
    keys = eval_keys(task_metrics, score_agents, tuple(sides or {}))
    result: dict[str, Any] = {key: everything[key] for key in keys}
    result["agent_returns"] = np.mean(per_agent, axis=0).tolist() if len(per_agent) == len(returns) else []
    result["n_episodes"] = len(returns)
    if task_metrics and not scores_simple_spread(task_metrics):  # simple_spread's result reads as it always has
        result["task_metrics"] = tuple(task_metrics)
    return result


def resolve_sides(sides: Mapping[str, Sequence[str]], agent_ids: Sequence[str]) -> dict[str, tuple[str, ...]]:
    """
    :param sides: Side -> its agents: each an agent id (``"adversary_0"``), or a name (``"adversary"``) for every id
        ``<name>_<index>`` (``adversary_0``, ``adversary_1``, ...; not ``leadadversary_0``).
    :param agent_ids: The team's agent ids.
    :return: Side -> its agent ids, in the team's order.
    :raise ValueError: When an agent is on no side or on two, or a side has no agent.
    """

    def member(agent: str, names: Sequence[str]) -> bool:
        return any(agent == name or (agent.startswith(f"{name}_") and agent[len(name) + 1 :].isdigit()) for name in names)

    resolved = {side: tuple(agent for agent in agent_ids if member(agent, names)) for side, names in sides.items()}
    for side, members in resolved.items():
        if not members:
            raise ValueError(
                f"sides: {side!r} ({', '.join(sides[side])}) names no agent of the team {list(agent_ids)}: name its "
                "agents by id or by the name before their index."
            )
    for agent in agent_ids:
        on = [side for side, members in resolved.items() if agent in members]
        if len(on) != 1:
            where = f"on {len(on)} sides ({', '.join(on)})" if on else "on no side"
            raise ValueError(
                f"sides: {agent} is {where}: give every agent of the team {list(agent_ids)} exactly one side (to score "
                "some agents only, use score_agents)."
            )
    return resolved


def _side_returns(
    vec_env: VecEnv, per_agent: list[np.ndarray], n_episodes: int, sides: Mapping[str, Sequence[str]]
) -> dict[str, float]:
    """Each side's return: the mean over episodes of the mean over its agents of their episode returns."""
    if not sides:
        return {}
    if len(per_agent) != n_episodes:
        raise ValueError(
            "sides: the env's info has no per-agent rewards (info['agent_rewards']), so no side's return can be "
            "scored: use an env of sb3_maddpg.envs (PettingZooToGym), or leave sides out."
        )
    agent_ids = list(vec_env.get_attr("agent_layout")[0].agent_ids)
    means = np.mean(per_agent, axis=0)
    return {
        side_return_key(side): float(np.mean([means[agent_ids.index(agent)] for agent in members]))
        for side, members in resolve_sides(sides, agent_ids).items()
    }


def _group_return(vec_env: VecEnv, per_agent: list[np.ndarray], group: Sequence[str]) -> float:
    """The summed mean return of the agents in ``group``."""
    agent_ids = tuple(vec_env.get_attr("agent_layout")[0].agent_ids)
    unknown = sorted(set(group) - set(agent_ids))
    if unknown:
        raise ValueError(f"score_agents names agents not in the team: {unknown}; the team is {list(agent_ids)}.")
    means = np.mean(per_agent, axis=0)
    return float(sum(value for agent, value in zip(agent_ids, means) if agent in group))


def _exploration_noise(model: PredictsActions, n_envs: int) -> VectorizedActionNoise | None:
    """A copy of the model's exploration noise for ``n_envs`` eval envs, or ``None`` when it has none."""
    noise = getattr(model, "action_noise", None)
    return None if noise is None else noise_copy_for_envs(noise, n_envs)


def _add_noise(
    actions: np.ndarray, noise: VectorizedActionNoise, action_space: gym.Space, discrete: np.ndarray | None
) -> np.ndarray:
    """The env's actions explored as in training: :func:`~sb3_maddpg.common.noise.add_noise` in the [-1, 1] space."""
    assert isinstance(action_space, spaces.Box), "exploration noise needs continuous (Box) actions"
    low, high = action_space.low, action_space.high
    scaled = add_noise(2.0 * (actions - low) / (high - low) - 1.0, noise, discrete)
    return (low + 0.5 * (scaled + 1.0) * (high - low)).astype(actions.dtype)


def _radius_metrics(landmark_distances: Any) -> dict[str, float]:
    """Success and coverage at each radius of :data:`SUCCESS_RADII` from the last step's landmark distances."""
    if landmark_distances is None:
        return dict.fromkeys(RADIUS_KEYS, np.nan)
    distances = np.asarray(landmark_distances, dtype=np.float64)
    metrics = {}
    for radius in SUCCESS_RADII:
        covered = distances < radius
        metrics[radius_key("success_rate", radius)] = float(covered.all())
        metrics[radius_key("coverage", radius)] = float(covered.mean())
    return metrics


class TeamEvalCallback(BaseCallback):
    """
    Evaluate the team every ``eval_freq`` calls during training with :func:`evaluate_team` and log
    the results under ``<log_prefix>/`` (``eval/success_rate``, ``eval/coverage``, ``eval/collisions``,
    ``eval/min_dist_sum``, ``eval/return_mean``, ...), e.g. to tensorboard.

    It can run beside SB3's ``EvalCallback`` (in a ``CallbackList``): it logs none of that callback's
    keys (``eval/mean_reward``, ``eval/mean_ep_length``), and with ``log_prefix`` its keys can be moved
    elsewhere. The history of evaluations is kept in :attr:`history` and, with ``log_path``, written
    as a CSV file (one row per evaluation, rewritten after each), a learning curve.

    :param eval_env: The evaluation env (a gymnasium env or a ``VecEnv``), separate from the training env.
    :param eval_freq: Evaluate every ``eval_freq`` calls of the callback (one call per ``env.step``
        of the training ``VecEnv``, i.e. ``n_envs`` env steps, as in ``EvalCallback``).
    :param n_eval_episodes: Episodes per evaluation.
    :param deterministic: Whether the team acts without exploration (see :func:`evaluate_team`).
    :param seed: Seed for each evaluation's first reset (each evaluation then sees the same
        episodes); ``None`` to continue the eval env's random stream.
    :param log_path: Path of a CSV file for the evaluation history, or ``None``.
    :param log_prefix: The logger key prefix.
    :param eval_at_start: Also evaluate the untrained team when training starts (timestep 0).
    :param verbose: 1 to print each evaluation.
    :param task_metrics: The task metrics to score and log; ``None``: those ``eval_env`` declares (see
        :func:`evaluate_team`).
    :param score_agents: Agent ids whose summed return to log as ``group_return`` (see :func:`evaluate_team`).
    :param sides: The sides of a competitive task, each side's return logged as ``return_<side>`` instead of the team
        return (see :func:`evaluate_team`).
    """

    def __init__(
        self,
        eval_env: gym.Env | VecEnv,
        eval_freq: int = 10_000,
        n_eval_episodes: int = 100,
        deterministic: bool = True,
        seed: int | None = None,
        log_path: str | None = None,
        log_prefix: str = "eval",
        eval_at_start: bool = False,
        verbose: int = 0,
        task_metrics: Sequence[DeclaredMetric] | None = None,
        score_agents: Sequence[str] = (),
        sides: Mapping[str, Sequence[str]] | None = None,
    ) -> None:
        super().__init__(verbose=verbose)
        if eval_freq < 1:
            raise ValueError(f"eval_freq must be at least 1, got {eval_freq}.")
        self.eval_env = eval_env
        self.eval_freq = eval_freq
        self.n_eval_episodes = n_eval_episodes
        self.deterministic = deterministic
        self.seed = seed
        self.log_path = log_path
        self.log_prefix = log_prefix
        self.eval_at_start = eval_at_start
        self.task_metrics = declared_task_metrics(eval_env) if task_metrics is None else tuple(task_metrics)
        self.score_agents = tuple(score_agents)
        self.sides = {side: tuple(agents) for side, agents in (sides or {}).items()}
        self.keys = eval_keys(self.task_metrics, self.score_agents, tuple(self.sides))
        self.history: list[dict[str, float]] = []

    def _on_training_start(self) -> None:
        if self.eval_at_start and self.num_timesteps == 0:
            self._evaluate()

    def _on_step(self) -> bool:
        if self.n_calls % self.eval_freq == 0:
            self._evaluate()
        return True

    def _evaluate(self) -> None:
        assert self.model is not None
        if self.model.get_vec_normalize_env() is not None:
            self._sync_normalization()
        result = evaluate_team(
            self.model,
            self.eval_env,
            n_episodes=self.n_eval_episodes,
            deterministic=self.deterministic,
            seed=self.seed,
            task_metrics=self.task_metrics,
            score_agents=self.score_agents,
            sides=self.sides,
        )
        row = {"timesteps": float(self.num_timesteps), **{key: float(result[key]) for key in self.keys}}
        self.history.append(row)
        for key in self.keys:
            self.logger.record(f"{self.log_prefix}/{key}", row[key])
        self.logger.record("time/total_timesteps", self.num_timesteps, exclude="tensorboard")
        self.logger.dump(self.num_timesteps)
        if self.verbose >= 1:
            print(f"Team eval num_timesteps={self.num_timesteps}: {describe_result(result)}")
        if self.log_path is not None:
            write_rows(self.log_path, self.history)

    def _sync_normalization(self) -> None:
        """Copy the training env's VecNormalize statistics to the eval env's, as SB3's EvalCallback does."""
        training = unwrap_vec_normalize(self.training_env)
        evaluation = unwrap_vec_normalize(self.eval_env) if isinstance(self.eval_env, VecEnv) else None
        if evaluation is None:
            raise ValueError(
                "TeamEvalCallback: the training env is normalised by VecNormalize but the eval env is not, so the team "
                "would be evaluated on unnormalised observations: wrap the eval env too, e.g. "
                "VecNormalize(eval_env, training=False, norm_reward=False) (its statistics are copied at each evaluation)."
            )
        assert training is not None
        evaluation.obs_rms = copy.deepcopy(training.obs_rms)
        evaluation.ret_rms = copy.deepcopy(training.ret_rms)


def write_rows(path: str, rows: list[dict[str, Any]]) -> None:
    """
    Write dict rows as a CSV file, replacing the file atomically.

    :param path: The CSV file.
    :param rows: The rows; the columns are every key, in the order first seen (a key a row lacks: an empty cell);
        nothing but the header is written when there are none.
    """
    directory = os.path.dirname(path)
    if directory:
        os.makedirs(directory, exist_ok=True)
    tmp_path = f"{path}.tmp"
    with open(tmp_path, "w", newline="") as file:
        fieldnames = list(dict.fromkeys(key for row in rows for key in row))
        writer = csv.DictWriter(file, fieldnames=fieldnames)
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp_path, path)
