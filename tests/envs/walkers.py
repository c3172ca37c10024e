"""A small real PettingZoo ParallelEnv whose observations need not hold positions: agents walk on a plane."""

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv


class Walkers(ParallelEnv):
    """
    ``n`` agents on a plane; each action is a velocity in [-1, 1]^2 (times 0.1), each reward minus the agent's distance
    to the origin, and the episode is truncated after ``max_cycles`` steps. What an agent observes:

    - ``"dict"``: ``{"vel": 2, "pos": 2, "landmarks": 3}`` (gymnasium flattens it in sorted key order:
      landmarks, pos, vel, so the position lies at 3:5, not where MPE has it);
    - ``"nested"``: ``{"self": {"pos": 2, "vel": 2}, "other": 3}`` (flattened: other, self.pos, self.vel);
    - ``"noise"``: 4 numbers of noise and no position at all (positions only in the env's state: :meth:`positions`).

    :param n_agents: The team's size.
    :param observe: What each agent observes (above).
    :param max_cycles: Steps per episode.
    :param leaves: Agents that leave before the end: agent -> (step, ``"termination"`` or ``"truncation"``).
    """

    metadata = {"name": "walkers_v0", "render_modes": []}

    def __init__(
        self, n_agents: int = 4, observe: str = "dict", max_cycles: int = 10, leaves: dict[str, tuple[int, str]] | None = None
    ) -> None:
        self.possible_agents = [f"walker_{i}" for i in range(n_agents)]
        self.agents: list[str] = []
        self.observe = observe
        self.max_cycles = max_cycles
        self.leaves = dict(leaves or {})
        box = lambda n: spaces.Box(-np.inf, np.inf, (n,), np.float32)  # noqa: E731
        if observe == "dict":
            self._obs_space: spaces.Space = spaces.Dict({"vel": box(2), "pos": box(2), "landmarks": box(3)})
        elif observe == "nested":
            self._obs_space = spaces.Dict({"self": spaces.Dict({"pos": box(2), "vel": box(2)}), "other": box(3)})
        else:
            self._obs_space = box(4)
        self._action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.rng = np.random.default_rng()
        self.pos = np.zeros((n_agents, 2), np.float32)
        self.vel = np.zeros((n_agents, 2), np.float32)
        self.t = 0

    def observation_space(self, agent: str) -> spaces.Space:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Space:
        return self._action_space

    def positions(self) -> np.ndarray:
        """Every agent's position, ``[n_agents, 2]`` (what ``PettingZooToGym(positions=fn)`` reads)."""
        return self.pos.copy()

    def _observe(self, i: int) -> Any:
        landmarks = np.arange(3, dtype=np.float32)
        if self.observe == "dict":
            return {"vel": self.vel[i].copy(), "pos": self.pos[i].copy(), "landmarks": landmarks}
        if self.observe == "nested":
            return {"self": {"pos": self.pos[i].copy(), "vel": self.vel[i].copy()}, "other": landmarks}
        return self.rng.normal(size=4).astype(np.float32)

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self.agents = list(self.possible_agents)
        self.pos = self.rng.uniform(-1, 1, (len(self.possible_agents), 2)).astype(np.float32)
        self.vel[:] = 0.0
        self.t = 0
        return {agent: self._observe(i) for i, agent in enumerate(self.agents)}, {agent: {} for agent in self.agents}

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        self.t += 1
        index = {agent: i for i, agent in enumerate(self.possible_agents)}
        for agent in self.agents:
            self.vel[index[agent]] = 0.1 * np.clip(np.asarray(actions[agent], np.float32), -1, 1)
            self.pos[index[agent]] += self.vel[index[agent]]
        ending = self.t >= self.max_cycles
        observations = {agent: self._observe(index[agent]) for agent in self.agents}
        rewards = {agent: -float(np.linalg.norm(self.pos[index[agent]])) for agent in self.agents}
        leaving = {agent: how for agent, (at, how) in self.leaves.items() if at == self.t and agent in self.agents}
        terminations = {agent: leaving.get(agent) == "termination" for agent in self.agents}
        truncations = {agent: ending or leaving.get(agent) == "truncation" for agent in self.agents}
        infos: dict[str, dict] = {agent: {} for agent in self.agents}
        self.agents = [agent for agent in self.agents if not (terminations[agent] or truncations[agent])]
        if ending:
            self.agents = []
        return observations, rewards, terminations, truncations, infos


def walkers_with_positions(**kwargs: object) -> object:
    """A factory of a ready gymnasium env (for the CLI's ``module:function``): Walkers that declare their positions."""
    from sb3_maddpg.envs import PettingZooToGym

    return PettingZooToGym(Walkers(observe="noise", **kwargs), positions=lambda env: env.positions())  # type: ignore[arg-type]
