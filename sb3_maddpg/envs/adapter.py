"""A gymnasium view of a PettingZoo ParallelEnv: one flat joint observation, one flat joint action."""

import warnings
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Literal, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.package_warnings import SB3MADDPGWarning
from sb3_maddpg.envs.task_metric import TaskMetric

MetricsFn = Callable[[Any], dict[str, float]]
"""A per-environment hook: called with the PettingZoo env after every reset and step, returns task metrics."""

PositionKey = str | tuple[str, ...]
"""A ``Dict`` observation's key holding an agent's position (a tuple of keys for a nested ``Dict``)."""

PositionSource = slice | PositionKey | Mapping[str, slice | PositionKey] | Callable[[Any], Any]
"""Where agents' positions are: see :class:`PettingZooToGym`'s ``positions``."""


class PettingZooToGym(gym.Env):
    """
    Present a PettingZoo ``ParallelEnv`` with a fixed team of agents as one ``gymnasium.Env``,
    so that SB3 (``Monitor``, ``DummyVecEnv``, ``SubprocVecEnv``, callbacks) can drive it.

    - Observation: a flat ``Box``, each agent's (flattened) observation in ``possible_agents`` order.
    - Action: a flat ``Box``, each agent's action in the same order; it is split per agent and cast
      to each agent space's dtype before it reaches the PettingZoo env (mpe2 warns on float64). An agent with a
      ``Discrete(n)`` action space has a slot of ``n`` numbers in [0, 1], a one-hot vector (MADDPG's actions are
      exact one-hots there): the agent takes the action of the largest entry (:meth:`agent_actions`).
    - Reward: the scalar team reward that SB3 logs is the **sum** of the agents' rewards
      (``team_reward="sum"``, the default) or their mean (``team_reward="mean"``). The per-agent
      rewards are in ``info["agent_rewards"]`` (float32 array, layout order).
    - Agents that leave: the team stays fixed for the whole episode. An agent that has left (PettingZoo drops it from
      ``env.agents`` after it terminates or is truncated) is seen as a zero observation with zero reward and gets no
      action; ``info["agent_active"]`` says which agents were in the episode when the step was taken, and the replay
      buffer keeps it, so that the transitions after an agent left train neither its critic nor its actor (a
      truncated agent's last transition bootstraps, and nothing then teaches its critic that the state after it is
      worth 0). No ``supersuit.black_death_v3`` is needed: it changes how episodes end (below).
    - Termination: the episode ends when no agent is left. It is terminated when every agent terminated, and
      truncated otherwise (e.g. at the env's time limit), so that SB3 bootstraps there; no extra step follows. The
      per-agent flags are in ``info["agent_terminations"]`` (terminated at this step or before it) and
      ``info["agent_truncations"]`` (truncated at this step), the agents' own infos in ``info["agent_infos"]``.
    - Positions (for selection by distance, :class:`~sb3_maddpg.common.selection.NearestAgents`): where each agent's
      position is, if the env says so (``positions``): in each agent's observation, as a slice or as a ``Dict``
      observation's key, or from the env's state, as a function; the layout carries it
      (``agent_layout.position_slices``), and a function's positions travel in ``info["agent_positions"]`` (at the
      returned observation) and ``info["agent_positions_before"]`` (at the observation the actions were taken on).
    - Layout: ``agent_layout`` (an :class:`~sb3_maddpg.common.layout.AgentLayout` with agent ids,
      observation and action slices and sizes) is public, and readable through
      ``VecEnv.get_attr("agent_layout")``.
    - Metrics: an optional ``metrics_fn(parallel_env) -> dict`` adds task metrics to ``info``
      after every reset and step (see :class:`~sb3_maddpg.envs.SimpleSpreadMetrics`).

    Agents may differ in observation and action sizes (heterogeneous teams). Observation spaces are ``Box`` spaces, or
    ``Dict`` / ``Tuple`` ones, which are flattened as ``gymnasium.spaces.flatten`` flattens them (a ``Dict``'s parts in
    its keys' order, which gymnasium sorts unless the space was built from an ``OrderedDict``; a ``Tuple``'s in order;
    a ``Discrete`` part one-hot), so that an agent's slice of the joint observation is ``flatten(space, obs)`` and
    nothing needs unflattening; action spaces are ``Box`` or ``Discrete``.

    Why not ``supersuit.black_death_v3`` (3.11): it ends an episode only when every agent is both terminated and
    truncated, so at a time limit the wrapped env goes on for one more step of zero observations and rewards, reported
    as termination: SB3 then stops bootstrapping at the time limit. The adapter warns if it wraps one.

    :param parallel_env: The PettingZoo ``ParallelEnv`` to wrap (an AEC env is refused: use the task's
        ``parallel_env(...)`` or ``pettingzoo.utils.conversions.aec_to_parallel``).
    :param metrics_fn: Optional hook that returns task metrics from the wrapped env.
    :param team_reward: How the agents' rewards are combined into the scalar reward, ``"sum"`` or ``"mean"``.
    :param positions: Where each agent's position is, for selection by distance: a ``slice`` of each agent's flat
        observation (simple_spread: ``slice(2, 4)``, which its envs declare themselves; the other MPE tasks of
        :func:`~sb3_maddpg.envs.make_mpe_env` declare their world's positions); the key of each agent's ``Dict``
        observation (a ``str``, or a tuple of keys for a nested ``Dict``), found wherever gymnasium's flattening puts
        it; a mapping of agent id to either, for agents of different layouts; or a function ``fn(parallel_env)`` that
        returns every agent's position, ``[n_agents, d]`` in ``possible_agents`` order, from the env's state. ``None``
        (the default): the env declares no positions, and ``NearestAgents`` is refused on it.
    """

    def __init__(
        self,
        parallel_env: Any,
        metrics_fn: MetricsFn | None = None,
        team_reward: Literal["sum", "mean"] = "sum",
        positions: PositionSource | None = None,
        task_metrics: Sequence[TaskMetric] = (),
    ) -> None:
        super().__init__()
        if team_reward not in ("sum", "mean"):
            raise ValueError(f"team_reward must be 'sum' or 'mean', got {team_reward!r}.")
        _refuse_aec_env(parallel_env)
        _warn_about_black_death(parallel_env)
        self.parallel_env = parallel_env
        self.metrics_fn = metrics_fn
        self.team_reward = team_reward
        self.task_metrics = tuple(task_metrics)
        if self.task_metrics and metrics_fn is None:
            raise ValueError(
                f"task_metrics declares {[metric.key for metric in self.task_metrics]}, but no metrics_fn adds them to "
                "info: pass metrics_fn=fn, fn(parallel_env) -> {key: value}, beside them."
            )
        agent_ids = tuple(parallel_env.possible_agents)
        self._structured_obs = {  # Dict / Tuple observation spaces, flattened as gymnasium flattens them
            agent: space
            for agent in agent_ids
            if isinstance(space := parallel_env.observation_space(agent), spaces.Dict | spaces.Tuple)
        }
        obs_spaces = [
            _flattened_box(self._structured_obs[agent], agent)
            if agent in self._structured_obs
            else _check_box(parallel_env.observation_space(agent), agent, "observation")
            for agent in agent_ids
        ]
        action_spaces = [_action_slot(parallel_env.action_space(agent), agent) for agent in agent_ids]
        self._discrete = tuple(isinstance(parallel_env.action_space(agent), spaces.Discrete) for agent in agent_ids)
        self._positions_fn = positions if callable(positions) else None
        self.agent_layout = AgentLayout(
            agent_ids=agent_ids,
            obs_sizes=tuple(int(np.prod(space.shape)) for space in obs_spaces),
            action_sizes=tuple(int(np.prod(space.shape)) for space in action_spaces),
            discrete_actions=self._discrete,
            position_slices=None if positions is None or callable(positions) else _position_slices(positions, parallel_env),
            positions_in_info=self._positions_fn is not None,
        )
        self.observation_space = _concatenate_boxes(obs_spaces, np.float32)
        self.action_space = _concatenate_boxes(action_spaces, np.float32)
        self._agent_action_dtypes = tuple(space.dtype for space in action_spaces)
        self._agent_action_shapes = tuple(space.shape for space in action_spaces)
        # Fast path for the common case: flat float32 agent spaces need no cast or reshape.
        self._flat_float32_obs = not self._structured_obs and all(
            space.dtype == np.float32 and len(space.shape) == 1 for space in obs_spaces
        )
        self._flat_float32_actions = not any(self._discrete) and all(
            space.dtype == np.float32 and len(space.shape) == 1 for space in action_spaces
        )
        self.metadata = dict(getattr(parallel_env, "metadata", {}))
        self.render_mode = getattr(parallel_env, "render_mode", None)
        self._episode_over = True
        self._present = np.zeros(len(agent_ids), dtype=bool)  # agents still in the episode
        self._terminated = np.zeros(len(agent_ids), dtype=bool)  # agents that terminated (kept until the episode ends)
        self._positions: np.ndarray | None = None  # the positions function's last answer

    @property
    def n_agents(self) -> int:
        """The number of agents in the team."""
        return self.agent_layout.n_agents

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """
        Reset the PettingZoo env and return the joint observation.

        :param seed: Seed for the PettingZoo env's random generator.
        :param options: Passed to the PettingZoo env's ``reset``.
        :return: The joint observation and an info dict (agent infos and task metrics).
        """
        super().reset(seed=seed)
        observations, agent_infos = self.parallel_env.reset(seed=seed, options=options)
        agent_ids = self.agent_layout.agent_ids
        if set(observations) != set(agent_ids):
            raise RuntimeError(
                f"After reset the env has agents {sorted(observations)}, but its possible_agents are "
                f"{list(agent_ids)}. PettingZooToGym needs the whole team present from the first step: "
                "make the env start every episode with all of possible_agents."
            )
        self._episode_over = False
        self._present[:] = True
        self._terminated[:] = False
        info: dict[str, Any] = {"agent_infos": [agent_infos.get(agent, {}) for agent in agent_ids]}
        if self._positions_fn is not None:
            self._positions = info["agent_positions"] = self._read_positions()
        if self.metrics_fn is not None:
            info.update(self.metrics_fn(self.parallel_env))
        return self._joint_observation(observations), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        """
        Step every agent with its part of the joint action.

        :param action: The flat joint action, agents in layout order.
        :return: Joint observation, team reward, terminated, truncated, info (see the class docstring).
        """
        if self._episode_over:
            raise RuntimeError("The episode is over: call reset() before step().")
        layout = self.agent_layout
        flat_action = np.asarray(action).reshape(-1)
        if flat_action.shape[0] != layout.action_dim:
            raise ValueError(f"Expected a joint action of length {layout.action_dim}, got shape {np.shape(action)}.")
        agent_actions = self.agent_actions(flat_action)
        present = self._present.copy()
        observations, rewards, terminations, truncations, agent_infos = self.parallel_env.step(
            {agent: action for (agent, action), here in zip(agent_actions.items(), present) if here}
        )

        terminated_now = np.array([bool(terminations.get(agent, False)) for agent in layout.agent_ids])
        agent_truncations = np.array([bool(truncations.get(agent, False)) for agent in layout.agent_ids]) & present
        # An agent leaves when it terminates or is truncated, or (against PettingZoo's API) vanishes without a flag.
        vanished = present & ~terminated_now & ~agent_truncations & ~self._observed(observations)
        self._terminated |= (terminated_now & present) | vanished
        self._present &= ~(terminated_now | agent_truncations | vanished)
        agent_terminations = self._terminated.copy()  # terminated at this step or before it
        remaining = getattr(self.parallel_env, "agents", None)
        self._episode_over = not self._present.any() or (remaining is not None and len(remaining) == 0)
        terminated = self._episode_over and bool(agent_terminations.all())
        truncated = self._episode_over and not terminated
        if self._episode_over:
            agent_truncations |= self._present  # agents the env dropped without a flag: the episode stopped for them

        # An agent that left before this step has no reward and no observation here, whatever the env still sends.
        agent_rewards = np.array([rewards.get(agent, 0.0) for agent in layout.agent_ids], dtype=np.float32) * present
        if not present.all():
            observations = {agent: obs for agent, obs in observations.items() if present[layout.index_of(agent)]}
        team = float(agent_rewards.sum()) if self.team_reward == "sum" else float(agent_rewards.mean())
        info: dict[str, Any] = {
            "agent_rewards": agent_rewards,
            "agent_terminations": agent_terminations,
            "agent_truncations": agent_truncations,
            "agent_active": present,
            "agent_infos": [agent_infos.get(agent, {}) for agent in layout.agent_ids],
        }
        if self._positions_fn is not None:
            info["agent_positions_before"] = self._positions
            self._positions = info["agent_positions"] = self._read_positions()
        if self.metrics_fn is not None:
            info.update(self.metrics_fn(self.parallel_env))
        return self._joint_observation(observations), team, terminated, truncated, info

    def agent_actions(self, action: np.ndarray) -> dict[str, Any]:
        """
        Split a joint action into the actions the PettingZoo env takes.

        :param action: A flat joint action, agents in layout order.
        :return: Each agent's action, by agent id: cast to its space's dtype and shape, or, for a discrete agent, the
            index of the largest entry of its slot (an ``int``).
        """
        layout = self.agent_layout
        flat_action = np.asarray(action).reshape(-1)
        if self._flat_float32_actions:
            flat_action = flat_action.astype(np.float32, copy=False)
            return {agent: flat_action[sl] for agent, sl in zip(layout.agent_ids, layout.action_slices)}
        return {
            agent: int(np.argmax(flat_action[sl])) if discrete else flat_action[sl].astype(dtype, copy=False).reshape(shape)
            for agent, sl, dtype, shape, discrete in zip(
                layout.agent_ids, layout.action_slices, self._agent_action_dtypes, self._agent_action_shapes, self._discrete
            )
        }

    def render(self) -> Any:
        """Render through the PettingZoo env (``render_mode`` is the PettingZoo env's)."""
        return self.parallel_env.render()

    def close(self) -> None:
        """Close the PettingZoo env."""
        self.parallel_env.close()

    def _observed(self, observations: dict[str, Any]) -> np.ndarray:
        return np.array([agent in observations for agent in self.agent_layout.agent_ids])

    def _read_positions(self) -> np.ndarray:
        assert self._positions_fn is not None
        positions = np.asarray(self._positions_fn(self.parallel_env), dtype=np.float32)
        n_agents = self.agent_layout.n_agents
        if positions.ndim != 2 or positions.shape[0] != n_agents or positions.shape[1] < 1:
            raise ValueError(
                f"The positions function returned shape {positions.shape}: it must return every agent's position, "
                f"[n_agents, d] = [{n_agents}, d], in possible_agents order (an agent that has left included)."
            )
        return positions

    def _joint_observation(self, observations: dict[str, Any]) -> np.ndarray:
        agent_ids, sizes = self.agent_layout.agent_ids, self.agent_layout.obs_sizes
        if len(observations) < len(agent_ids):  # agents that have left are seen as zeros
            observations = {
                agent: observations[agent] if agent in observations else np.zeros(size, np.float32)
                for agent, size in zip(agent_ids, sizes)
            }
            return np.concatenate([np.asarray(part, dtype=np.float32).reshape(-1) for part in self._flat(observations)])
        if self._flat_float32_obs:
            return np.concatenate([observations[agent] for agent in agent_ids], dtype=np.float32)
        return np.concatenate([np.asarray(part, dtype=np.float32).reshape(-1) for part in self._flat(observations)])

    def _flat(self, observations: dict[str, Any]) -> list[Any]:
        """Each agent's observation, a structured one flattened (a zero placeholder is flat already)."""
        return [
            spaces.flatten(self._structured_obs[agent], observations[agent])
            if agent in self._structured_obs and not isinstance(observations[agent], np.ndarray)
            else observations[agent]
            for agent in self.agent_layout.agent_ids
        ]


def _described(value: Any) -> str:
    """:return: What a value is, briefly: ``"module 'mpe2.simple_spread_v3'"``, ``"None"``."""
    name = getattr(value, "__name__", None)
    return repr(value) if name is None else f"{type(value).__name__} {name!r}"


def _refuse_aec_env(env: Any) -> None:
    """
    An AEC env (one agent acts at a time) looks like a parallel one until ``reset`` returns None: refuse it first; and
    what is no env at all (its factory, its module, None) before an ``AttributeError`` on ``possible_agents``.
    """
    if not hasattr(env, "possible_agents"):
        called = " (call it: e.g. simple_spread_v3.parallel_env(...))" if callable(env) else ""
        raise TypeError(
            f"PettingZooToGym needs a PettingZoo ParallelEnv instance, got {_described(env)}, which has no "
            f"possible_agents{called}: pass the env itself, e.g. PettingZooToGym(simple_spread_v3.parallel_env())."
        )
    # Duck-typed, so that this module needs no PettingZoo import: only AEC envs step one agent at a time.
    if callable(getattr(env, "agent_iter", None)) and callable(getattr(env, "last", None)):
        raise TypeError(
            f"PettingZooToGym needs a PettingZoo ParallelEnv, got an AEC env ({type(env).__name__}), where agents act "
            "one at a time: build the parallel version (e.g. simple_adversary_v3.parallel_env(...) instead of .env(...)) "
            "or convert it with pettingzoo.utils.conversions.aec_to_parallel(env)."
        )


def _warn_about_black_death(env: Any) -> None:
    """SuperSuit's black_death changes how episodes end at a time limit; the adapter handles agents that leave."""
    wrapped = env
    while wrapped is not None:
        if type(wrapped).__name__ == "black_death_par":
            warnings.warn(
                "The env is wrapped in supersuit.black_death_v3, which the adapter does not need (it keeps the team "
                "fixed itself) and which changes how episodes end: at a time limit the wrapped env goes on for one "
                "more step of zero observations reported as termination, so SB3 stops bootstrapping there. Pass the "
                "env without black_death_v3.",
                SB3MADDPGWarning,
                stacklevel=3,
            )
            return
        wrapped = getattr(wrapped, "env", None)


def _position_slices(positions: slice | PositionKey | Mapping[str, Any], env: Any) -> tuple[slice, ...]:
    """Each agent's position slice within its own flat observation, from a slice, a Dict key, or one of them per agent."""
    agent_ids = list(env.possible_agents)
    if isinstance(positions, Mapping):
        unknown = sorted(set(map(str, positions)) - set(map(str, agent_ids)))
        missing = [agent for agent in agent_ids if agent not in positions]
        if unknown or missing:
            raise ValueError(
                f"positions maps agents {sorted(map(str, positions))}, but the env's agents are {agent_ids}: give one "
                "position source (slice or Dict key) per agent of possible_agents."
            )
        return tuple(_position_slice(positions[agent], env.observation_space(agent), agent) for agent in agent_ids)
    return tuple(_position_slice(positions, env.observation_space(agent), agent) for agent in agent_ids)


def _position_slice(source: Any, space: spaces.Space, agent: str) -> slice:
    """One agent's position slice: a slice as given, or where gymnasium's flattening puts a Dict key's part."""
    if isinstance(source, slice):
        return source
    keys = (source,) if isinstance(source, str) else source
    if not isinstance(keys, tuple) or not keys or not all(isinstance(key, str) for key in keys):
        raise TypeError(
            f"positions={source!r} is not a position source: give a slice of each agent's observation, a Dict "
            "observation key (a str, or a tuple of keys for a nested Dict), a mapping of agent id to either, or a "
            "function of the env returning [n_agents, d] positions."
        )
    offset = 0
    for depth, key in enumerate(keys):
        if not isinstance(space, spaces.Dict):
            raise ValueError(
                f"positions={source!r} names a Dict observation key, but agent {agent!r}'s observation space "
                f"{'' if depth == 0 else 'at ' + repr(keys[:depth]) + ' '}is a {type(space).__name__}: give a slice of "
                "its flat observation instead (e.g. positions=slice(2, 4))."
            )
        if key not in space.spaces:
            raise ValueError(
                f"positions={source!r}: agent {agent!r}'s Dict observation has no key {key!r} (its keys: "
                f"{list(space.spaces)}): name the key that holds the agent's position."
            )
        for name, part in space.spaces.items():  # gymnasium flattens a Dict's parts in this order
            if name == key:
                space = part
                break
            offset += spaces.flatdim(part)
    return slice(offset, offset + spaces.flatdim(space))


def _action_slot(space: spaces.Space, agent: str) -> spaces.Box:
    """An agent's slot in the joint action: its Box, or for ``Discrete(n)`` a Box of ``n`` one-hot entries."""
    if isinstance(space, spaces.Discrete):
        return spaces.Box(0.0, 1.0, (int(space.n),), np.float32)
    return _check_box(space, agent, "action")


def _check_box(space: spaces.Space, agent: str, kind: str) -> spaces.Box:
    if isinstance(space, spaces.Box):
        return space
    if kind == "action" and isinstance(space, spaces.MultiDiscrete):
        fix = "use the env's Discrete or continuous actions (mpe2: continuous_actions=True)"
    else:
        fix = "convert the space to a Box with a PettingZoo or supersuit wrapper"
    raise TypeError(
        f"Agent {agent!r} has a {type(space).__name__} {kind} space; PettingZooToGym supports Box spaces (and Discrete "
        f"actions) only: {fix}."
    )


def _flattened_box(space: spaces.Dict | spaces.Tuple, agent: str) -> spaces.Box:
    """A Dict or Tuple observation space as the Box ``gymnasium.spaces.flatten_space`` makes of it."""
    try:
        box = spaces.flatten_space(space)
    except NotImplementedError:
        box = None
    if not isinstance(box, spaces.Box):  # a part of variable size (Sequence, Graph) flattens to no Box
        raise TypeError(
            f"Agent {agent!r} has a {type(space).__name__} observation space with a part gymnasium cannot flatten to a "
            f"fixed-size Box ({space}): give every agent parts of fixed size (Box, Discrete, MultiDiscrete, MultiBinary)."
        )
    return box


def _concatenate_boxes(boxes: list[spaces.Box], dtype: type[np.floating]) -> spaces.Box:
    low = np.concatenate([np.asarray(box.low, dtype=dtype).reshape(-1) for box in boxes])
    high = np.concatenate([np.asarray(box.high, dtype=dtype).reshape(-1) for box in boxes])
    return spaces.Box(low=low, high=high, dtype=dtype)
