"""The worlds a run group learns in: ``R`` runs of ``E`` simple_spread worlds each, on the group's device."""

from dataclasses import dataclass
from typing import Any, NamedTuple

import torch as th

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.envs.simple_spread import CAPTURE_RADIUS, SIMPLE_SPREAD_POSITION_SLICE
from sb3_maddpg.envs.simple_spread_worlds import ACTION_SIZE, DIM_P
from sb3_maddpg.envs.torch_spread_worlds import TorchSpreadWorlds
from sb3_maddpg.run_group.streams import RunStreams

METRICS = ("coverage", "success", "collisions", "min_dist_sum")
"""The task metrics recorded at the end of every episode (:class:`~sb3_maddpg.envs.SimpleSpreadMetrics`'s)."""


@dataclass(frozen=True)
class SpreadTask:
    """
    simple_spread's settings, as :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` takes them.

    :param n_agents: Agents (and landmarks) per world.
    :param num_agent_neighbors: Nearest other agents each agent observes (``None``: all).
    :param num_landmark_neighbors: Nearest landmarks each agent observes (``None``: all).
    :param max_cycles: Episode length (episodes end by truncation).
    :param local_ratio: Weight of the local collision penalty against the shared distance reward.
    :param capture_radius: Distance within which an agent covers a landmark, in the metrics.
    """

    n_agents: int
    num_agent_neighbors: int | None = None
    num_landmark_neighbors: int | None = None
    max_cycles: int = 25
    local_ratio: float = 0.5
    capture_radius: float = CAPTURE_RADIUS

    @classmethod
    def from_env(cls, env: Any) -> "SpreadTask | None":
        """
        :param env: A model's env (a :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`, possibly wrapped).
        :return: Its settings, or None when the env does not tell them (another VecEnv, another task).
        """
        names = ("n_agents", "num_agent_neighbors", "num_landmark_neighbors", "max_cycles", "local_ratio", "capture_radius")
        try:
            values = [env.get_attr(name, indices=[0])[0] for name in names]
        except (AttributeError, TypeError):
            return None
        return cls(*values)

    def layout(self, obs_size: int) -> AgentLayout:
        """:return: The agent layout of these worlds (as the numpy env's), for agents observing ``obs_size`` each."""
        agent_ids = tuple(f"agent_{i}" for i in range(self.n_agents))
        return AgentLayout(
            agent_ids,
            (obs_size,) * self.n_agents,
            (ACTION_SIZE,) * self.n_agents,
            position_slices=(SIMPLE_SPREAD_POSITION_SLICE,) * self.n_agents,
        )


class RunsStep(NamedTuple):
    """One step of every run's worlds."""

    next_observations: th.Tensor
    """The observations the step led to (an episode's last ones at its end), ``[R, E, obs_dim]``."""
    rewards: th.Tensor
    """Per-agent rewards (float32, as the numpy env's), ``[R, E, n_agents]``."""
    truncated: bool
    """Whether every episode ended at this step (they all have the same length)."""


class SpreadRuns:
    """
    ``n_runs`` runs of ``worlds_per_run`` simple_spread worlds in one
    :class:`~sb3_maddpg.envs.torch_spread_worlds.TorchSpreadWorlds` (run r the r-th block of worlds), each run's new
    episodes drawn from its own random stream; an episode's end resets every world, as
    :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`'s.

    :param task: The worlds' settings.
    :param worlds_per_run: Worlds ``E`` per run.
    :param streams: The runs' random streams (one per run), on the worlds' device.
    :param dtype: The worlds' floating dtype (float64 is mpe2's arithmetic; float32 is faster).
    """

    def __init__(
        self,
        task: SpreadTask,
        worlds_per_run: int,
        streams: RunStreams,
        dtype: th.dtype = th.float32,
    ) -> None:
        self.task = task
        self.n_runs = streams.n_runs
        self.worlds_per_run = worlds_per_run
        self.streams = streams
        device = streams.device
        self.worlds = TorchSpreadWorlds(
            self.n_runs * worlds_per_run,
            task.n_agents,
            task.num_agent_neighbors,
            task.num_landmark_neighbors,
            task.local_ratio,
            device=device,
            dtype=dtype,
        )
        self.steps = 0
        """Steps of the current episodes."""
        self.observations = self.reset()
        """The current observations, ``[R, E, obs_dim]``."""
        self.episodes: list[th.Tensor] = []
        """Per finished round of episodes, each run's mean over its worlds of the episode's team reward (the sum over
        agents, as SB3's ``ep_rew_mean`` of the numpy env) and of each metric of :data:`METRICS` at the last step,
        ``[1 + len(METRICS), R]``; kept on the device until read."""
        self._agent_returns = th.zeros(self.n_runs, worlds_per_run, task.n_agents, device=device)
        self.agent_episodes: list[th.Tensor] = []
        """Per finished round of episodes, each run's mean over its worlds of each agent's episode return, ``[R, N]``
        (as the per-agent ``rollout/<agent_id>/ep_rew_mean`` of a run alone)."""

    @property
    def obs_size(self) -> int:
        """Each agent's observation length."""
        return self.worlds.obs_size

    def _joint(self, observations: th.Tensor) -> th.Tensor:
        return observations.reshape(self.n_runs, self.worlds_per_run, -1)

    def reset(self) -> th.Tensor:
        """:return: New episodes' observations, ``[R, E, obs_dim]``."""
        shape = (self.worlds_per_run, 2 * self.task.n_agents, DIM_P)  # each world's agents, then its landmarks
        self.worlds.reset(self.streams.uniform(shape, self.worlds.dtype).reshape(-1, *shape[1:]))
        self.steps = 0
        return self._joint(self.worlds.observations(self.worlds.distances()))

    def step(self, actions: th.Tensor) -> RunsStep:
        """
        Step every world; at the end of an episode, record it and start new ones (:attr:`observations`).

        :param actions: Joint actions in the policy's [-1, 1] space, ``[R, E, action_dim]``.
        :return: The step's next observations and rewards, and whether the episodes ended.
        """
        return self.record(*self.move(actions))

    def move(self, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """
        The device's part of :meth:`step`: every world's physics step, its rewards and observations (what a compiled
        round runs; nothing here reads or changes a Python value).

        :param actions: Joint actions in the policy's [-1, 1] space, ``[R, E, action_dim]``.
        :return: The next observations ``[R, E, obs_dim]`` and the rewards ``[R, E, n_agents]``.
        """
        n_worlds, n_agents = self.worlds.n_worlds, self.task.n_agents
        # [-1, 1] to mpe2's [0, 1] (SB3's unscale_action), clipped as the numpy env clips.
        env_actions = ((actions.reshape(n_worlds, n_agents, ACTION_SIZE) + 1.0) / 2.0).clamp(0.0, 1.0)
        distances = self.worlds.step(env_actions)
        rewards = self.worlds.rewards(distances).to(th.float32).reshape(self.n_runs, self.worlds_per_run, n_agents)
        return self._joint(self.worlds.observations(distances)), rewards

    def record(self, next_observations: th.Tensor, rewards: th.Tensor) -> RunsStep:
        """
        The bookkeeping part of :meth:`step`, after :meth:`move`: the episodes' returns and step count; at their end,
        their record and new episodes.

        :param next_observations: :meth:`move`'s next observations.
        :param rewards: :meth:`move`'s rewards.
        :return: The step.
        """
        self._agent_returns += rewards
        self.steps += 1
        truncated = self.steps >= self.task.max_cycles
        if truncated:
            metrics = self.worlds.metrics(self.worlds.distances(), self.task.capture_radius)
            per_run = [metrics[name].reshape(self.n_runs, self.worlds_per_run).to(th.float32) for name in METRICS]
            # The team return is the agents' returns summed (derived, not kept beside them).
            self.episodes.append(th.stack([self._agent_returns.sum(dim=-1), *per_run]).mean(dim=-1))
            self.agent_episodes.append(self._agent_returns.mean(dim=1))
            self._agent_returns.zero_()
            self.observations = self.reset()
        else:
            self.observations = next_observations
        return RunsStep(next_observations, rewards, truncated)
