"""What the tests share: tiny settings named by what they are for, and the team most tests train.

Each test file used to define its own ``FAST``/``TINY``; the ones that meant the same now read these (a test that
needs another value says so beside its call, e.g. ``{**TRAINS_QUICKLY, "learning_starts": 100}``).
"""

from typing import Any

import pytest

from sb3_maddpg.envs import PettingZooToGym, make_simple_spread

N_AGENTS = 3
"""The team most tests train: simple_spread with 3 agents."""

TRAINS_QUICKLY: dict[str, Any] = dict(
    learning_starts=50,
    batch_size=32,
    buffer_size=2_000,
    train_freq=10,
    policy_kwargs=dict(net_arch=[16, 16]),
    seed=0,
)
"""Tiny and fast: learning starts after two 25-step episodes, then a gradient step every 10 env steps (SB3's
``train_freq``, counting vectorised steps)."""

UPDATES_PER_10_TRANSITIONS: dict[str, Any] = dict(
    learning_starts=100, batch_size=32, buffer_size=2_000, transitions_per_update=10, policy_kwargs={"net_arch": [16]}
)
"""One hidden layer of 16 units, learning after four episodes, one gradient step per 10 transitions (any n_envs)."""

NEVER_UPDATES: dict[str, Any] = dict(
    learning_starts=1_000, buffer_size=500, batch_size=16, policy_kwargs=dict(net_arch=[8]), seed=0
)
"""A model that a short ``learn`` (under 1,000 steps) fills the buffer with and never updates: for refusals, acting
and wiring."""


def make_team(n_agents: int = N_AGENTS, max_cycles: int = 25) -> PettingZooToGym:
    """
    :param n_agents: Team size.
    :param max_cycles: Episode length.
    :return: simple_spread over mpe2, through the adapter.
    """
    return make_simple_spread(n_agents=n_agents, max_cycles=max_cycles)


# The package's warnings are errors in the tests (pyproject.toml). A test that triggers one on purpose asserts it with
# pytest.warns; a test in which it is a side effect of a short setup says which one it expects, with one of these:
_PACKAGE_WARNING = "sb3_maddpg.common.package_warnings.SB3MADDPGWarning"
FILLS_THE_BUFFER_ONLY = pytest.mark.filterwarnings(
    rf"ignore:learn\(\) ended at step .* without a single gradient update:{_PACKAGE_WARNING}"
)
"""``learn()`` only fills the replay buffer (shorter than ``learning_starts``); the test then updates by hand."""
SELECTS_EVERY_OTHER_AGENT = pytest.mark.filterwarnings(
    rf"ignore:critic_sharing='selected' with k=\d+ selects every other agent:{_PACKAGE_WARNING}"
)
"""A small team whose selection holds every other agent (k = n_agents - 1): the scheme's path, not its point."""
RESUMES_WITHOUT_ITS_BUFFER = pytest.mark.filterwarnings(
    rf"ignore:learn\(reset_num_timesteps=False\) goes on at step:{_PACKAGE_WARNING}"
)
"""A loaded model goes on learning without its replay buffer (the test checks what the save carries)."""
NEVER_UPDATED_RUNS = pytest.mark.filterwarnings(rf"ignore:\d+ run\(s\) never updated:{_PACKAGE_WARNING}")
"""A report of smoke runs too short to update (the test checks the files, not the learning)."""
