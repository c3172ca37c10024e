"""A gymnasium view of a PettingZoo ParallelEnv: one flat joint observation, one flat joint action."""

from collections.abc import Callable
from typing import Any, Literal, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sb3_maddpg.common.layout import AgentLayout

MetricsFn = Callable[[Any], dict[str, float]]
"""A per-environment hook: called with the PettingZoo env after every reset and step, returns task metrics."""


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
    - Termination: the episode is terminated when every agent is terminated, and truncated
      otherwise when any agent is truncated; the per-agent flags are in ``info["agent_terminations"]``
      and ``info["agent_truncations"]``, the agents' own infos in ``info["agent_infos"]``.
    - Layout: ``agent_layout`` (an :class:`~sb3_maddpg.common.layout.AgentLayout` with agent ids,
      observation and action slices and sizes) is public, and readable through
      ``VecEnv.get_attr("agent_layout")``.
    - Metrics: an optional ``metrics_fn(parallel_env) -> dict`` adds task metrics to ``info``
      after every reset and step (see :class:`~sb3_maddpg.envs.SimpleSpreadMetrics`).

    Agents may differ in observation and action sizes (heterogeneous teams). Observation spaces are ``Box`` spaces, or
    ``Dict`` / ``Tuple`` ones, which are flattened as ``gymnasium.spaces.flatten`` flattens them (a ``Dict``'s parts in
    its keys' order, which gymnasium sorts unless the space was built from an ``OrderedDict``; a ``Tuple``'s in order;
    a ``Discrete`` part one-hot), so that an agent's slice of the joint observation is ``flatten(space, obs)`` and
    nothing needs unflattening; action spaces are ``Box`` or ``Discrete``; agents must not leave mid-episode (wrap such
    an env with ``supersuit.black_death_v3``).

    :param parallel_env: The PettingZoo ``ParallelEnv`` to wrap (an AEC env is refused: use the task's
        ``parallel_env(...)`` or ``pettingzoo.utils.conversions.aec_to_parallel``).
    :param metrics_fn: Optional hook that returns task metrics from the wrapped env.
    :param team_reward: How the agents' rewards are combined into the scalar reward, ``"sum"`` or ``"mean"``.
    """

    def __init__(
        self,
        parallel_env: Any,
        metrics_fn: MetricsFn | None = None,
        team_reward: Literal["sum", "mean"] = "sum",
    ) -> None:
        super().__init__()
        if team_reward not in ("sum", "mean"):
            raise ValueError(f"team_reward must be 'sum' or 'mean', got {team_reward!r}.")
        _refuse_aec_env(parallel_env)
        self.parallel_env = parallel_env
        self.metrics_fn = metrics_fn
        self.team_reward = team_reward
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
        self.agent_layout = AgentLayout(
            agent_ids=agent_ids,
            obs_sizes=tuple(int(np.prod(space.shape)) for space in obs_spaces),
            action_sizes=tuple(int(np.prod(space.shape)) for space in action_spaces),
            discrete_actions=self._discrete,
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
        info: dict[str, Any] = {"agent_infos": [agent_infos.get(agent, {}) for agent in agent_ids]}
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
        observations, rewards, terminations, truncations, agent_infos = self.parallel_env.step(agent_actions)

        agent_terminations = np.array([bool(terminations.get(agent, False)) for agent in layout.agent_ids])
        agent_truncations = np.array([bool(truncations.get(agent, False)) for agent in layout.agent_ids])
        terminated = bool(agent_terminations.all())
        truncated = not terminated and bool(agent_truncations.any())
        finished = agent_terminations | agent_truncations
        if set(observations) != set(layout.agent_ids) or (finished.any() and not (terminated or truncated)):
            missing = [agent for agent in layout.agent_ids if agent not in observations]
            raise RuntimeError(
                "Agents left the episode before the others "
                f"(done: {[a for a, f in zip(layout.agent_ids, finished) if f]}, missing: {missing}). "
                "PettingZooToGym needs a fixed team for the whole episode: wrap the env with "
                "supersuit.black_death_v3(env) so finished agents stay with zero observations."
            )
        self._episode_over = terminated or truncated

        agent_rewards = np.array([rewards[agent] for agent in layout.agent_ids], dtype=np.float32)
        team = float(agent_rewards.sum()) if self.team_reward == "sum" else float(agent_rewards.mean())
        info: dict[str, Any] = {
            "agent_rewards": agent_rewards,
            "agent_terminations": agent_terminations,
            "agent_truncations": agent_truncations,
            "agent_infos": [agent_infos.get(agent, {}) for agent in layout.agent_ids],
        }
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

    def _joint_observation(self, observations: dict[str, Any]) -> np.ndarray:
        agent_ids = self.agent_layout.agent_ids
        if self._flat_float32_obs:
            return np.concatenate([observations[agent] for agent in agent_ids], dtype=np.float32)
        parts = [
            spaces.flatten(self._structured_obs[agent], observations[agent])
            if agent in self._structured_obs
            else observations[agent]
            for agent in agent_ids
        ]
        return np.concatenate([np.asarray(part, dtype=np.float32).reshape(-1) for part in parts])


def _refuse_aec_env(env: Any) -> None:
    """An AEC env (one agent acts at a time) looks like a parallel one until ``reset`` returns None: refuse it first."""
    # Duck-typed, so that this module needs no PettingZoo import: only AEC envs step one agent at a time.
    if callable(getattr(env, "agent_iter", None)) and callable(getattr(env, "last", None)):
        raise TypeError(
            f"PettingZooToGym needs a PettingZoo ParallelEnv, got an AEC env ({type(env).__name__}), where agents act "
            "one at a time: build the parallel version (e.g. simple_adversary_v3.parallel_env(...) instead of .env(...)) "
            "or convert it with pettingzoo.utils.conversions.aec_to_parallel(env)."
        )


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
