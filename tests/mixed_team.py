"""A team of one continuous and one discrete agent, for the tests that need both kinds (a real PettingZoo env)."""

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv


class MixedTeam(ParallelEnv):
    """Two agents on a line: ``mover`` (Box(-1, 1, (1,)), or ``mover_bounds``) moves, ``chooser`` (Discrete(3)) picks
    left, stay or right; both are rewarded for ending near 0."""

    metadata = {"name": "mixed_team_v0"}

    def __init__(self, mover_bounds: tuple[float, float] = (-1.0, 1.0)) -> None:
        self.possible_agents = ["mover", "chooser"]
        self.agents: list[str] = []
        self.mover_bounds = mover_bounds

    def observation_space(self, agent: str) -> spaces.Box:
        return spaces.Box(-10.0, 10.0, (1,), np.float32)

    def action_space(self, agent: str) -> spaces.Space:
        return spaces.Box(*self.mover_bounds, (1,), np.float32) if agent == "mover" else spaces.Discrete(3)

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        self.agents, self.t = list(self.possible_agents), 0
        self.position = {agent: np.array([1.0], np.float32) for agent in self.agents}
        return dict(self.position), {agent: {} for agent in self.agents}

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        assert isinstance(actions["chooser"], int) and actions["chooser"] in (0, 1, 2)
        assert actions["mover"].shape == (1,)
        self.position["mover"] = self.position["mover"] + 0.1 * actions["mover"]
        self.position["chooser"] = self.position["chooser"] + 0.1 * (actions["chooser"] - 1)
        self.t += 1
        rewards = {agent: -float(abs(self.position[agent][0])) for agent in self.agents}
        truncated = dict.fromkeys(self.agents, self.t >= 10)
        return dict(self.position), rewards, dict.fromkeys(self.agents, False), truncated, {a: {} for a in self.agents}
