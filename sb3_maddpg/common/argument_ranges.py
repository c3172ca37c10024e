"""The valid range of every numeric constructor argument, declared once: the constructors check against it and the docs'
table of ranges is drawn from it.

SB3 takes most numbers as given: ``buffer_size=-5`` made a one-row buffer and ``learning_starts=-1`` was taken as 0,
both without a word. Each argument here is refused outside its range, with its name, its range and a value to use.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Range:
    """
    The values an argument takes.

    :param meaning: What the argument is, in a few words (for the error and the docs' table).
    :param integer: Whether it must be an integer (``bool`` is not one); else any finite real number.
    :param low: The lowest value, or None for no lower bound.
    :param high: The highest value, or None for none (or one that depends on other arguments: ``high_is``).
    :param low_open: Whether ``low`` itself is excluded.
    :param high_open: Whether ``high`` itself is excluded.
    :param high_is: The upper bound's formula when it depends on other arguments (``"n_agents - 1"``): the check is
        given its value.
    :param none_means: Where ``None`` is valid, what it means; None where it is not.
    :param hint: What to use instead, ending the error (e.g. ``"use 0.95 (the paper's)"``).
    :param schedule: Whether a callable is valid too (a schedule, checked when called, as SB3 does).
    :param per_agent: Whether a sequence is valid too: one value per agent, each in the range.
    :param in_tuple: Whether an ``(n, unit)`` tuple is valid too, its ``n`` in the range (SB3's ``train_freq``).
    """

    meaning: str
    integer: bool = False
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    high_is: str | None = None
    none_means: str | None = None
    hint: str = ""
    schedule: bool = False
    per_agent: bool = False
    in_tuple: bool = False

    def describe(self, high: float | None = None) -> str:
        """
        :param high: The upper bound's value, where it depends on other arguments (``high_is``), to say beside it.
        :return: The range in words, e.g. ``"an integer >= 1"``, ``"a number in (0, 1]"``.
        """
        kind = "an integer" if self.integer else "a number"
        upper = None if self.high is None else f"{self.high:g}" if self.high < 1e6 else f"{self.high:,}"
        if self.high_is is not None:
            upper = self.high_is if high is None else f"{self.high_is} = {high:g}"
        if self.low is not None and upper is not None:
            text = f"{kind} in {'(' if self.low_open else '['}{self.low:g}, {upper}{')' if self.high_open else ']'}"
        elif self.low is not None:
            text = f"{kind} {'>' if self.low_open else '>='} {self.low:g}"
        elif upper is not None:
            text = f"{kind} {'<' if self.high_open else '<='} {upper}"
        else:
            text = f"a finite {kind.split()[1]}" if not self.integer else kind
        return text if self.none_means is None else f"{text}, or None ({self.none_means})"

    def admits(self, value: Any, high: float | None = None) -> bool:
        """
        :param value: A value given for the argument.
        :param high: The upper bound's value, where it depends on other arguments (``high_is``).
        :return: Whether ``value`` is in the range.
        """
        if value is None:
            return self.none_means is not None
        if isinstance(value, bool | np.bool_) or not isinstance(value, int | float | np.integer | np.floating):
            return False
        if self.integer and not isinstance(value, int | np.integer):
            return False
        if not math.isfinite(value):
            return False
        high = self.high if high is None else high
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return False
        return bool(high is None or (value < high if self.high_open else value <= high))

    def check(self, name: str, value: Any, high: float | None = None) -> None:
        """
        Refuse ``value`` outside the range, with the argument's name and range first and what to use last.

        :param name: The argument's name.
        :param value: The value given.
        :param high: The upper bound's value, where it depends on other arguments (``high_is``).
        """
        if self.schedule and callable(value):
            return
        if self.in_tuple and isinstance(value, tuple) and len(value) == 2:
            self.check(name, value[0], high)
            return
        if self.per_agent and isinstance(value, list | tuple | np.ndarray):
            for item in value:
                self.check(name, item, high)
            return
        if self.admits(value, high):
            return
        hint = f": {self.hint}" if self.hint else ""
        raise ValueError(f"{name} ({self.meaning}) must be {self.describe(high)}, got {value!r}{hint}.")


def check_arguments(ranges: Mapping[str, Range], values: Mapping[str, Any]) -> None:
    """
    Refuse the first value outside its argument's range (:meth:`Range.check`).

    :param ranges: Each argument's range, by name.
    :param values: The values given, by name (every name in ``ranges``).
    """
    for name, valid in ranges.items():
        valid.check(name, values[name])


TEAM_ALGORITHM_RANGES: dict[str, Range] = {
    "learning_rate": Range(
        "every actor's and critic's Adam step size, or a schedule: a function of the progress remaining",
        low=0,
        low_open=True,
        hint="use 1e-2 (the paper's), or a schedule",
        schedule=True,
    ),
    "buffer_size": Range(
        "the replay buffer's capacity in joint transitions", integer=True, low=1, hint="use 1_000_000 (the paper's)"
    ),
    "learning_starts": Range(
        "env steps of random actions before the first update, all envs counted",
        integer=True,
        low=0,
        hint="use 0 to update from the first batch on",
    ),
    "batch_size": Range("rows per gradient step", integer=True, low=1, hint="use 1024 (the paper's)"),
    "tau": Range(
        "the Polyak coefficient of the target networks; 1 copies them",
        low=0,
        high=1,
        low_open=True,
        hint="use 0.01 (the paper's)",
    ),
    "gamma": Range("the discount factor", low=0, high=1, hint="use 0.95 (the paper's)"),
    "train_freq": Range(
        "vectorised env steps between updates, or an (n, 'step' | 'episode') tuple of such an n",
        integer=True,
        low=1,
        none_means="derived from transitions_per_update",
        hint="leave it None for the paper's schedule",
        in_tuple=True,
    ),
    "gradient_steps": Range(
        "gradient steps per update; -1: one per transition collected, 0: none",
        integer=True,
        low=-1,
        none_means="earned, one per transitions_per_update transitions",
        hint="leave it None for the paper's schedule",
    ),
    "transitions_per_update": Range(
        "transitions per gradient step, all envs counted", integer=True, low=1, hint="use 100 (the paper's)"
    ),
    "noise_std": Range(
        "the exploration noise's standard deviation in each agent's action units: one, or one per agent",
        low=0,
        hint="use 0.1, or 0 for no noise",
        per_agent=True,
    ),
    "max_grad_norm": Range(
        "the largest norm each agent's actor and critic gradient is clipped to",
        low=0,
        low_open=True,
        none_means="no clipping",
        hint="use 0.5 (Lowe et al.'s value), or None to turn gradient clipping off",
    ),
    "actor_reg_coef": Range(
        "the weight of the penalty on each actor's pre-tanh output",
        low=0,
        hint="use 1e-3 (Lowe et al.'s value) or 0 to turn the actor regulariser off",
    ),
    "stats_window_size": Range("episodes in the rollout logs' means", integer=True, low=1, hint="use 100"),
    "verbose": Range("0: no output, 1: info, 2: debug", integer=True, low=0, high=2, hint="use 0 or 1"),
    "seed": Range(
        "the seed of every random generator",
        integer=True,
        low=0,
        high=2**32 - 1,
        none_means="unseeded",
        hint="use a non-negative integer",
    ),
}
"""The numeric arguments of :class:`~sb3_maddpg.MADDPG` (and so of :class:`~sb3_maddpg.MATD3`)."""

TD3_RANGES: dict[str, Range] = {
    "policy_delay": Range(
        "critic updates per actor and target update",
        integer=True,
        low=1,
        hint="use 2 (TD3's value), or 1 to update the actors at every critic update",
    ),
    "target_policy_noise": Range(
        "the target actions' smoothing noise in the policy's [-1, 1] space", low=0, hint="use 0.2 (TD3's value)"
    ),
    "target_noise_clip": Range(
        "the bound on the target actions' smoothing noise in the policy's [-1, 1] space",
        low=0,
        hint="use 0.5 (TD3's value)",
    ),
}
"""The numeric arguments :class:`~sb3_maddpg.MATD3` adds to MADDPG's."""

SIMPLE_SPREAD_RANGES: dict[str, Range] = {
    "n_envs": Range("worlds stepped at once", integer=True, low=1, hint="use 100 for a study's runs"),
    "n_agents": Range("agents (and landmarks) in each world", integer=True, low=2, hint="use 3 or 5 (the paper's)"),
    "num_agent_neighbors": Range(
        "the other agents each agent observes, nearest first",
        integer=True,
        low=1,
        high_is="n_agents - 1",
        none_means="every other agent: full observability",
        hint="use None, or fewer for partial observability",
    ),
    "num_landmark_neighbors": Range(
        "the landmarks each agent observes, nearest first",
        integer=True,
        low=1,
        high_is="n_agents",
        none_means="every landmark",
        hint="use None, or fewer for partial observability",
    ),
    "max_cycles": Range("env steps per episode", integer=True, low=1, hint="use 25 (the paper's)"),
    "local_ratio": Range(
        "the weight of each agent's own collision penalty in its reward; 0: the shared reward only",
        low=0,
        high=1,
        hint="use 0.5 (mpe2's)",
    ),
    "capture_radius": Range(
        "the distance within which a landmark counts as covered, for the task metrics",
        low=0,
        low_open=True,
        hint="use 0.1",
    ),
}
"""The numeric arguments of simple_spread, as :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` and
:func:`~sb3_maddpg.envs.make_simple_spread` take them."""
