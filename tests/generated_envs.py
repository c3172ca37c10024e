"""PettingZoo ParallelEnvs built from a generated spec (hypothesis): teams of 1-6 agents of differing sizes, Box, Dict,
Discrete and MultiDiscrete observation and action spaces, agents that leave by termination or truncation at any step,
positions declared or not. Each env is checked by PettingZoo's own ``parallel_api_test`` before a test uses it.

Every Box or Dict observation carries the step it was made at (its first entry, or its ``"clock"`` key, which
gymnasium's flattening puts first), so that a replay-buffer row shows whether every agent's part of it was taken at
the same step.
"""

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces
from hypothesis import strategies as st
from pettingzoo import ParallelEnv

OBSERVATION_KINDS = ("box", "dict", "discrete", "multidiscrete")
ACTION_KINDS = ("box", "discrete", "multidiscrete", "dict")
SUPPORTED_OBSERVATIONS = ("box", "dict")
"""What the adapter takes (Discrete and MultiDiscrete observations, Dict and MultiDiscrete actions it refuses)."""
SUPPORTED_ACTIONS = ("box", "discrete")


@dataclass(frozen=True)
class AgentSpec:
    """
    One agent of a generated team.

    :param observation: Its observation space's kind (:data:`OBSERVATION_KINDS`).
    :param obs_size: Entries of its observation besides the clock and the position.
    :param action: Its action space's kind (:data:`ACTION_KINDS`).
    :param action_size: Its Box action's size, or its Discrete action's number of choices.
    :param leaves_at: The step (1-based) at which it leaves the episode, or None to stay to the end.
    :param leaves_by: ``"termination"`` or ``"truncation"``.
    """

    observation: str
    obs_size: int
    action: str
    action_size: int
    leaves_at: int | None
    leaves_by: str


@dataclass(frozen=True)
class TeamSpec:
    """
    A generated team and its episodes.

    :param agents: The agents, in ``possible_agents`` order.
    :param max_cycles: The time limit: every agent still there is truncated at this step.
    :param positions: Whether each agent's observation holds a 2-d position the env declares.
    """

    agents: tuple[AgentSpec, ...]
    max_cycles: int
    positions: bool

    @property
    def supported(self) -> bool:
        """Whether every agent's spaces are ones the adapter takes."""
        return all(a.observation in SUPPORTED_OBSERVATIONS and a.action in SUPPORTED_ACTIONS for a in self.agents)

    def episode_end(self) -> tuple[int, bool]:
        """:return: The step at which the episode ends and whether it ends by termination (every agent terminated)."""
        terminates = [
            a.leaves_at is not None and a.leaves_at <= self.max_cycles and a.leaves_by == "termination" for a in self.agents
        ]
        ends = [self.max_cycles if a.leaves_at is None else min(a.leaves_at, self.max_cycles) for a in self.agents]
        return max(ends), all(terminates)

    def position_sources(self) -> dict[str, slice | str] | None:
        """:return: Each agent's position in its observation, as the adapter's ``positions`` takes it, or None."""
        if not self.positions:
            return None
        return {f"agent_{i}": "position" if a.observation == "dict" else slice(1, 3) for i, a in enumerate(self.agents)}


def agent_specs(max_cycles: int, supported_only: bool) -> st.SearchStrategy[AgentSpec]:
    """:return: Agents whose departures fall within (or past) ``max_cycles``."""
    return st.builds(
        AgentSpec,
        observation=st.sampled_from(SUPPORTED_OBSERVATIONS if supported_only else OBSERVATION_KINDS),
        obs_size=st.integers(1, 4),
        action=st.sampled_from(SUPPORTED_ACTIONS if supported_only else ACTION_KINDS),
        action_size=st.integers(2, 4),
        leaves_at=st.one_of(st.none(), st.integers(1, max_cycles + 1)),
        leaves_by=st.sampled_from(["termination", "truncation"]),
    )


@st.composite
def team_specs(draw: st.DrawFn, supported_only: bool = True, max_agents: int = 6) -> TeamSpec:
    """:return: A team of 1 to ``max_agents`` agents, each of its own spaces and departure."""
    max_cycles = draw(st.integers(1, 8))
    agents = draw(st.lists(agent_specs(max_cycles, supported_only), min_size=1, max_size=max_agents))
    return TeamSpec(tuple(agents), max_cycles, draw(st.booleans()))


class GeneratedParallelEnv(ParallelEnv):
    """A ParallelEnv that plays a :class:`TeamSpec`: random observations and rewards, departures as the spec says."""

    metadata = {"name": "generated_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self, spec: TeamSpec) -> None:
        self.spec = spec
        self.possible_agents = [f"agent_{i}" for i in range(len(spec.agents))]
        self.agents: list[str] = []
        self._by_id = dict(zip(self.possible_agents, spec.agents))
        self._rng = np.random.default_rng()
        self._t = 0

    @functools.cache  # noqa: B019  (PettingZoo asks for the same space object every time)
    def observation_space(self, agent: str) -> spaces.Space:
        spec = self._by_id[agent]
        size = spec.obs_size + (2 if self.spec.positions else 0)
        if spec.observation == "box":
            return spaces.Box(-100.0, 100.0, (1 + size,), np.float32)
        if spec.observation == "dict":
            parts = {"clock": spaces.Box(0.0, 100.0, (1,), np.float32)}
            parts["state"] = spaces.Box(-100.0, 100.0, (spec.obs_size,), np.float32)
            if self.spec.positions:
                parts["position"] = spaces.Box(-100.0, 100.0, (2,), np.float32)
            return spaces.Dict(parts)
        if spec.observation == "discrete":
            return spaces.Discrete(spec.obs_size + 1)
        return spaces.MultiDiscrete([spec.obs_size + 1] * 2)

    @functools.cache  # noqa: B019
    def action_space(self, agent: str) -> spaces.Space:
        spec = self._by_id[agent]
        if spec.action == "box":
            return spaces.Box(-1.0, 1.0, (spec.action_size,), np.float32)
        if spec.action == "discrete":
            return spaces.Discrete(spec.action_size)
        if spec.action == "multidiscrete":
            return spaces.MultiDiscrete([spec.action_size] * 2)
        return spaces.Dict({"move": spaces.Box(-1.0, 1.0, (spec.action_size,), np.float32)})

    def _observe(self, agent: str) -> Any:
        space = self.observation_space(agent)
        if isinstance(space, spaces.Box):
            sample = self._rng.uniform(-1.0, 1.0, space.shape).astype(np.float32)
            sample[0] = self._t
            return sample
        if isinstance(space, spaces.Dict):
            sample = {key: self._rng.uniform(-1.0, 1.0, part.shape).astype(np.float32) for key, part in space.items()}
            sample["clock"] = np.array([self._t], np.float32)
            return sample
        space.seed(int(self._rng.integers(2**31)))
        return space.sample()

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        self._rng = np.random.default_rng(seed)
        self._t = 0
        self.agents = list(self.possible_agents)
        return {agent: self._observe(agent) for agent in self.agents}, {agent: {} for agent in self.agents}

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        self._t += 1
        here = list(self.agents)
        leaving = {agent: self._by_id[agent].leaves_at == self._t for agent in here}
        terminations = {a: leaving[a] and self._by_id[a].leaves_by == "termination" for a in here}
        truncations = {a: (leaving[a] and not terminations[a]) or self._t >= self.spec.max_cycles for a in here}
        truncations = {a: truncations[a] and not terminations[a] for a in here}
        observations = {agent: self._observe(agent) for agent in here}
        rewards = {agent: float(self._rng.normal()) for agent in here}
        self.agents = [a for a in here if not (terminations[a] or truncations[a])]
        return observations, rewards, terminations, truncations, {agent: {} for agent in here}
