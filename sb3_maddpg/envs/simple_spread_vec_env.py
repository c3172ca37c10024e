"""Batched cooperative navigation: an SB3 VecEnv that steps many simple_spread worlds at once, as mpe2 would."""

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from stable_baselines3.common.vec_env import DummyVecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.envs.simple_spread import (
    CAPTURE_RADIUS,
    SIMPLE_SPREAD_POSITION_SLICE,
    SIMPLE_SPREAD_TASK_METRICS,
    check_simple_spread_arguments,
    make_simple_spread,
)
from sb3_maddpg.envs.simple_spread_worlds import ACTION_SIZE, SimpleSpreadWorlds, WorldDistances

SETTABLE_ATTRIBUTES = ("local_ratio", "capture_radius")
"""Settings ``set_attr`` may change (for every world at once: the worlds share them)."""


class SimpleSpreadVecEnv(VecEnv):
    """
    ``n_envs`` worlds of MPE cooperative navigation (``mpe2.simple_spread_v3``, continuous actions), simulated
    together as arrays: the same MDP as ``DummyVecEnv`` over :func:`~sb3_maddpg.envs.make_simple_spread`,
    92-152x faster to step with 64-256 worlds.

    - Same physics, observations (``num_agent_neighbors``: nearest first, as mpe2), per-agent rewards
      (``local_ratio``), truncation after ``max_cycles`` steps and reset distribution as mpe2, in float64.
    - Same seeding: after ``seed(s)``, world ``i``'s episodes (the first reset and every auto-reset after it)
      are those of an mpe2 env after ``reset(seed=s + i)`` given the same actions (``seed(None)`` draws ``s``
      from NumPy's global generator, as SB3's VecEnvs do); worlds never seeded draw fresh entropy, as mpe2 does.
    - Same spaces, layout and ``info`` as the adapter: ``agent_layout`` (through ``get_attr``),
      ``info["agent_rewards"]`` (float32), ``agent_terminations``, ``agent_truncations``, ``TimeLimit.truncated``,
      ``terminal_observation`` with auto-reset, and the task metrics of
      :class:`~sb3_maddpg.envs.SimpleSpreadMetrics` (``coverage``, ``success``, ``collisions``, ``min_dist_sum``,
      ``landmark_distances``). The adapter's ``agent_infos`` (mpe2's per-agent infos, always empty for
      simple_spread) are left out.
    - Actions outside [0, 1] are clipped, as mpe2's ``ClipOutOfBoundsWrapper`` does (without its warning).

    Every world has the same episode length, so all worlds reset together, every ``max_cycles`` steps; a step
    has no Python loop over worlds or agents, except the reset's draw of each world's new positions from its
    own generator (which is what makes the seeding exact).

    :param n_envs: Number of worlds.
    :param n_agents: Number of agents (and landmarks). The paper uses 5.
    :param num_agent_neighbors: How many nearest other agents each agent observes; ``None`` for all
        (the paper's experiment 1), ``2`` for the paper's partially observable experiment 2.
    :param max_cycles: Episode length; episodes end by truncation after this many steps (paper: 25).
    :param local_ratio: mpe2's weight of the local collision penalty against the shared distance reward.
    :param capture_radius: Distance for a landmark to count as covered in the metrics.
    :param render_mode: ``None`` or ``"rgb_array"`` (mpe2's drawing, one image per world, tiled by ``render()``).
    :param team_reward: How the per-agent rewards are combined into SB3's scalar reward, ``"sum"`` or ``"mean"``.
    :param num_landmark_neighbors: How many nearest landmarks each agent observes; ``None`` for all.
    :param continuous_actions: mpe2's continuous actions, or its discrete ones: each agent's slot of 5 is then read as
        the choice of its largest entry, as :class:`~sb3_maddpg.envs.PettingZooToGym` reads mpe2's ``Discrete(5)``.
    """

    def __init__(
        self,
        n_envs: int = 1,
        n_agents: int = 5,
        num_agent_neighbors: int | None = None,
        max_cycles: int = 25,
        local_ratio: float = 0.5,
        capture_radius: float = CAPTURE_RADIUS,
        render_mode: str | None = None,
        team_reward: Literal["sum", "mean"] = "sum",
        num_landmark_neighbors: int | None = None,
        continuous_actions: bool = True,
    ) -> None:
        check_simple_spread_arguments(
            n_envs=n_envs,
            n_agents=n_agents,
            num_agent_neighbors=num_agent_neighbors,
            num_landmark_neighbors=num_landmark_neighbors,
            max_cycles=max_cycles,
            local_ratio=local_ratio,
            capture_radius=capture_radius,
        )
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array' (worlds are drawn as images), got {render_mode!r}.")
        if team_reward not in ("sum", "mean"):
            raise ValueError(f"team_reward must be 'sum' or 'mean', got {team_reward!r}.")
        self.worlds = SimpleSpreadWorlds(int(n_envs), n_agents, num_agent_neighbors, num_landmark_neighbors, local_ratio)
        """The worlds' state and mpe2's rules on it (positions, velocities and landmarks as ``[n_envs, n_agents, 2]``)."""
        self.n_agents = n_agents
        self.num_agent_neighbors = num_agent_neighbors
        self.num_landmark_neighbors = num_landmark_neighbors
        self.max_cycles = max_cycles
        self.capture_radius = float(capture_radius)
        self.team_reward = team_reward
        self.render_mode = render_mode
        obs_size = self.worlds.obs_size
        self.agent_layout = AgentLayout(
            agent_ids=tuple(f"agent_{i}" for i in range(n_agents)),
            obs_sizes=(obs_size,) * n_agents,
            action_sizes=(ACTION_SIZE,) * n_agents,
            discrete_actions=(not continuous_actions,) * n_agents,
            position_slices=(SIMPLE_SPREAD_POSITION_SLICE,) * n_agents,
        )
        self.task_metrics = SIMPLE_SPREAD_TASK_METRICS  # what its infos hold, as make_simple_spread's env declares
        self.continuous_actions = bool(continuous_actions)
        observation_space = spaces.Box(-np.inf, np.inf, (n_agents * obs_size,), dtype=np.float32)
        action_space = spaces.Box(0.0, 1.0, (n_agents * ACTION_SIZE,), dtype=np.float32)
        super().__init__(int(n_envs), observation_space, action_space)
        self._generators = [seeding.np_random()[0] for _ in range(self.num_envs)]
        self._steps = 0
        self._needs_reset = True
        self._actions: np.ndarray | None = None
        self._cam_ranges = np.ones(self.num_envs)  # mpe2's per-episode zoom, for rendering
        self._renderer: Any = None
        # Shared read-only flags: simple_spread never terminates, and truncates every agent at once.
        self._no_agent = _read_only(np.zeros(n_agents, dtype=bool))
        self._every_agent = _read_only(np.ones(n_agents, dtype=bool))

    @property
    def local_ratio(self) -> float:
        """mpe2's weight of the local collision penalty against the shared distance reward."""
        return self.worlds.local_ratio

    def reset(self) -> VecEnvObs:
        """
        Reset every world; a world given a seed by :meth:`seed` starts a new generator from it, as
        ``mpe2_env.reset(seed=...)`` does, the others continue their own.

        :return: The joint observations ``[n_envs, n_agents * obs_size]``.
        """
        for world, seed in enumerate(self._seeds):
            if seed is not None:
                self._generators[world] = seeding.np_random(seed)[0]
        self._reset_seeds()
        self._reset_options()
        observations, metrics = self._reset_worlds()
        self.reset_infos = self._metric_infos(metrics)
        return observations

    def step_async(self, actions: np.ndarray) -> None:
        """
        :param actions: Joint actions ``[n_envs, n_agents * 5]`` in [0, 1] (agents in layout order).
        """
        if self._needs_reset:
            raise RuntimeError("The worlds have no state yet: call reset() before step(), as with any VecEnv.")
        actions = np.asarray(actions)
        expected = (self.num_envs, self.agent_layout.action_dim)
        if actions.shape != expected and actions.size == self.num_envs * self.agent_layout.action_dim:
            actions = actions.reshape(expected)  # e.g. [n_envs, n_agents, 5]
        if actions.shape != expected:
            raise ValueError(
                f"Expected actions of shape {expected} (n_envs, n_agents * 5), got {actions.shape}: give one joint "
                "action per world."
            )
        actions = actions.astype(np.float32, copy=False)
        if not np.isfinite(actions).all():
            bad = np.flatnonzero(~np.isfinite(actions).all(axis=1)).tolist()
            raise ValueError(
                f"Actions of worlds {bad} contain NaN or infinite values: check the policy's outputs (e.g. for "
                "diverged networks) before stepping."
            )
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        """
        :return: Observations, team rewards, dones and infos; after the last step of an episode the observations
            are those of the next episode and ``info["terminal_observation"]`` holds the last ones.
        """
        if self._actions is None:
            raise RuntimeError("step_wait() needs actions: call step(actions) (or step_async first).")
        actions = self._actions.reshape(self.num_envs, self.n_agents, ACTION_SIZE)
        if self.continuous_actions:
            actions = np.clip(actions, 0.0, 1.0)
        else:
            # The adapter's choice (the largest entry); mpe2's discrete action k then moves as the continuous one-hot
            # of k does, bit for bit (u = a[2] - a[1], a[4] - a[3]).
            actions = np.eye(ACTION_SIZE)[actions.argmax(axis=-1)]
        self._actions = None
        distances = self.worlds.step(actions)
        agent_rewards = self.worlds.rewards(distances).astype(np.float32)
        team_rewards = agent_rewards.sum(axis=1) if self.team_reward == "sum" else agent_rewards.mean(axis=1)
        observations = self._joint_observations(distances)
        metrics = self.worlds.metrics(distances, self.capture_radius)
        self._steps += 1
        truncated = self._steps >= self.max_cycles
        infos = self._metric_infos(metrics)
        truncations = self._every_agent if truncated else self._no_agent
        for info, rewards in zip(infos, agent_rewards):
            info.update(
                agent_rewards=rewards,
                agent_terminations=self._no_agent,
                agent_truncations=truncations,
            )
            info["TimeLimit.truncated"] = truncated
        if truncated:
            for info, last_observation in zip(infos, observations):
                info["terminal_observation"] = last_observation
            observations, reset_metrics = self._reset_worlds()
            self.reset_infos = self._metric_infos(reset_metrics)
        dones = np.full(self.num_envs, truncated)
        return observations, team_rewards, dones, infos

    def _reset_worlds(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        for world, generator in enumerate(self._generators):
            self.worlds.reset_world(world, generator)
        worlds = self.worlds
        if self.render_mode is not None:  # mpe2's zoom for the episode, from its first positions
            self._cam_ranges = np.maximum(
                np.abs(worlds.agent_pos).max(axis=(1, 2)), np.abs(worlds.landmark_pos).max(axis=(1, 2))
            )
        self._steps = 0
        self._needs_reset = False
        distances = worlds.distances()
        return self._joint_observations(distances), worlds.metrics(distances, self.capture_radius)

    def _joint_observations(self, distances: WorldDistances) -> np.ndarray:
        return self.worlds.observations(distances).reshape(self.num_envs, -1)

    def _metric_infos(self, metrics: dict[str, np.ndarray]) -> list[dict[str, Any]]:
        columns = {key: values.tolist() for key, values in metrics.items()}
        return [dict(zip(columns, row)) for row in zip(*columns.values())]

    def close(self) -> None:
        """Release the renderer (pygame), if one was made."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def get_images(self) -> Sequence[np.ndarray | None]:
        """:return: Each world drawn by mpe2's renderer (``render_mode="rgb_array"``), ``[700, 700, 3]`` uint8 each."""
        return self._images(range(self.num_envs))

    def _images(self, indices: VecEnvIndices) -> list[np.ndarray | None]:
        if self.render_mode != "rgb_array":
            raise ValueError("Rendering needs SimpleSpreadVecEnv(..., render_mode='rgb_array').")
        if self._renderer is None:
            from mpe2 import simple_spread_v3

            self._renderer = simple_spread_v3.raw_env(N=self.n_agents, render_mode="rgb_array")
        world = self._renderer.world
        images: list[np.ndarray | None] = []
        for index in self._get_indices(indices):
            # Draw world `index` by putting its state into mpe2's own world.
            for agent, position in zip(world.agents, self.worlds.agent_pos[index]):
                agent.state.p_pos = position.copy()
            for landmark, position in zip(world.landmarks, self.worlds.landmark_pos[index]):
                landmark.state.p_pos = position.copy()
            self._renderer.original_cam_range = self._cam_ranges[index]
            images.append(self._renderer.render())
        return images

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """
        :param attr_name: A setting or property of the worlds (e.g. ``agent_layout``, ``n_agents``, ``render_mode``).
        :param indices: The worlds.
        :return: Its value for each world (the worlds share their settings).
        """
        value = getattr(self, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """
        Change a shared setting of every world: ``local_ratio`` or ``capture_radius``.

        :param attr_name: The setting.
        :param value: Its new value.
        :param indices: Must cover every world (``None``).
        """
        if attr_name not in SETTABLE_ATTRIBUTES:
            raise AttributeError(
                f"SimpleSpreadVecEnv can set only {SETTABLE_ATTRIBUTES}, got {attr_name!r}: build a new env for "
                "other settings."
            )
        if sorted(self._get_indices(indices)) != list(range(self.num_envs)):
            raise ValueError(f"{attr_name} is shared by all worlds of a SimpleSpreadVecEnv: set it with indices=None.")
        if attr_name == "local_ratio":
            check_simple_spread_arguments(local_ratio=value)
            self.worlds.local_ratio = float(value)
        else:
            check_simple_spread_arguments(capture_radius=value)
            self.capture_radius = float(value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        """
        The worlds are arrays, not env objects: the only per-world method is ``render``.

        :param method_name: ``"render"``.
        :param method_args: None.
        :param indices: The worlds.
        :param method_kwargs: None.
        :return: One image per world.
        """
        if method_name == "render" and not method_args and not method_kwargs:
            return self._images(indices)
        raise AttributeError(
            f"SimpleSpreadVecEnv has no per-world method {method_name!r} (its worlds are arrays, not env objects): "
            "use the VecEnv's own reset(), seed(), render(), get_attr() and set_attr()."
        )

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        """:return: False for each world: no gymnasium wrapper is inside (wrap the VecEnv, e.g. in ``VecMonitor``)."""
        return [False for _ in self._get_indices(indices)]


def make_simple_spread_vec_env(n_envs: int = 1, vec_env: Literal["batched", "mpe2"] = "batched", **kwargs: Any) -> VecEnv:
    """
    ``n_envs`` simple_spread worlds as an SB3 ``VecEnv``, the same MDP either way.

    :param n_envs: Worlds.
    :param vec_env: ``"batched"``: :class:`SimpleSpreadVecEnv` (arrays, fast); ``"mpe2"``: ``DummyVecEnv`` over
        :func:`~sb3_maddpg.envs.make_simple_spread` (mpe2 itself through the adapter).
    :param kwargs: The worlds' settings, :func:`~sb3_maddpg.envs.make_simple_spread`'s keyword arguments
        (``n_agents``, ``num_agent_neighbors``, ``max_cycles``, ``local_ratio``, ``render_mode``, ...).
    :return: The VecEnv.
    """
    if vec_env == "batched":
        return SimpleSpreadVecEnv(n_envs, **kwargs)
    if vec_env == "mpe2":
        return DummyVecEnv([lambda: make_simple_spread(**kwargs) for _ in range(n_envs)])
    raise ValueError(f"vec_env must be 'batched' or 'mpe2', got {vec_env!r}.")


def _read_only(array: np.ndarray) -> np.ndarray:
    array.flags.writeable = False
    return array
