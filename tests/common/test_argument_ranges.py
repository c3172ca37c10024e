"""Every numeric constructor argument of MADDPG, MATD3 and simple_spread is refused outside its declared range, with
its name and range first, and taken inside it: values generated at and beyond each bound (hypothesis)."""

import inspect
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.common.argument_ranges import (
    SIMPLE_SPREAD_RANGES,
    TD3_RANGES,
    TEAM_ALGORITHM_RANGES,
    Range,
)
from sb3_maddpg.envs import SimpleSpreadVecEnv, make_simple_spread
from sb3_maddpg.experiments.config import EXPERIMENTS
from sb3_maddpg.experiments.setting import PROTOCOL_RANGES, TASK_RANGES, ExperimentConfig
from sb3_maddpg.tuning.search import TUNE_RANGES, TuneSettings

N_AGENTS = 3
SMALL = dict(buffer_size=64, learning_starts=0, batch_size=8, policy_kwargs=dict(net_arch=[8]))
"""A model that is cheap to build, for the values that must be taken."""

OWNERS: list[tuple[Any, dict[str, Range]]] = [
    (MADDPG, TEAM_ALGORITHM_RANGES),
    (MATD3, {**TEAM_ALGORITHM_RANGES, **TD3_RANGES}),
    (SimpleSpreadVecEnv, SIMPLE_SPREAD_RANGES),
    (ExperimentConfig, {**TASK_RANGES, **PROTOCOL_RANGES}),
    (TuneSettings, TUNE_RANGES),
]
CASES = [(owner, name) for owner, ranges in OWNERS for name in ranges]
NUMERIC = (int, float, "int", "float")


def _upper(valid: Range) -> float | None:
    """The upper bound at :data:`N_AGENTS` agents."""
    n_evaluations = TuneSettings.__dataclass_fields__["n_evaluations"].default
    return {"n_agents - 1": N_AGENTS - 1, "n_agents": N_AGENTS, "n_evaluations": n_evaluations}.get(
        valid.high_is or "", valid.high
    )


def out_of_range(valid: Range) -> st.SearchStrategy[Any]:
    """Values the range refuses: past either bound, at an open bound, not finite, bool, a fraction for an integer."""
    refused: list[st.SearchStrategy[Any]] = [st.sampled_from([math.nan, math.inf, -math.inf, True, False])]
    high = _upper(valid)
    if valid.low is not None:
        below = st.floats(max_value=valid.low, exclude_max=not valid.low_open, allow_nan=False, allow_infinity=False)
        refused.append(below.map(lambda x: math.floor(x) - (0 if valid.low_open else 1)) if valid.integer else below)
    if high is not None:
        above = st.floats(min_value=high, exclude_min=not valid.high_open, allow_nan=False, allow_infinity=False)
        refused.append(above.map(lambda x: math.ceil(x) + (0 if valid.high_open else 1)) if valid.integer else above)
    if valid.integer:
        refused.append(st.floats(allow_nan=False, allow_infinity=False).filter(lambda x: x != int(x)))
    if valid.none_means is None:
        refused.append(st.none())
    return st.one_of(refused)


def in_range(valid: Range) -> st.SearchStrategy[Any]:
    """Values the range takes, its closed bounds among them."""
    low = -1e9 if valid.low is None else valid.low
    high = _upper(valid)
    high = 1e9 if high is None else high
    if valid.integer:
        taken: st.SearchStrategy[Any] = st.integers(math.ceil(low) + valid.low_open, int(high) - valid.high_open)
    else:
        taken = st.floats(low, high, exclude_min=valid.low_open, exclude_max=valid.high_open)
    return st.one_of(taken, st.none()) if valid.none_means is not None else taken


def _build(owner: Any, **kwargs: Any) -> Any:
    if owner is ExperimentConfig:  # the config model, as a stored or a preset file's fields reach it
        return ExperimentConfig.from_fields({**EXPERIMENTS["smoke"].to_dict(), **kwargs})
    if owner is TuneSettings:  # one last evaluation: any n_evaluations in range can be built
        return TuneSettings(EXPERIMENTS["smoke"], "study", "sqlite:///unused.db", **{"last_evaluations": 1, **kwargs})
    if owner is SimpleSpreadVecEnv:
        return SimpleSpreadVecEnv(**{"n_envs": 2, "n_agents": N_AGENTS, **kwargs})
    return owner("MlpPolicy", make_simple_spread(n_agents=N_AGENTS), **{**SMALL, **kwargs})


@pytest.mark.parametrize(("owner", "name"), CASES, ids=[f"{owner.__name__}.{name}" for owner, name in CASES])
@given(data=st.data())
def test_out_of_range_is_refused_by_name(owner: Any, name: str, data: st.DataObject) -> None:
    ranges = dict(OWNERS)[owner]
    value = data.draw(out_of_range(ranges[name]), label=name)
    with pytest.raises(ValueError) as refused:
        _build(owner, **{name: value})
    message = str(refused.value)
    # The cause first (the argument and what it is), its range, the value given, then what to use.
    assert message.startswith(f"{name} ({ranges[name].meaning}) must be {ranges[name].describe(_upper(ranges[name]))}")
    assert f", got {value!r}: " in message and ranges[name].hint in message


@pytest.mark.parametrize(("owner", "name"), CASES, ids=[f"{owner.__name__}.{name}" for owner, name in CASES])
@given(data=st.data())
def test_in_range_is_taken(owner: Any, name: str, data: st.DataObject) -> None:
    valid = dict(OWNERS)[owner][name]
    value = data.draw(in_range(valid), label=name)
    valid.check(name, value, _upper(valid))  # the rule itself, over the whole range


@pytest.mark.parametrize(("owner", "name"), CASES, ids=[f"{owner.__name__}.{name}" for owner, name in CASES])
def test_each_closed_bound_builds(owner: Any, name: str) -> None:
    """The constructors take each bound that is in the range (a ``<`` for a ``<=`` would refuse it)."""
    valid = dict(OWNERS)[owner][name]
    bounds = [bound for bound, is_open in ((valid.low, valid.low_open), (_upper(valid), valid.high_open)) if not is_open]
    for bound in bounds:
        if bound is None or abs(bound) > 1e6 or (name == "gradient_steps" and bound == -1):
            continue  # no bound; a seed of 2**32 - 1 builds like any other; -1 needs a train_freq (SB3's rule)
        value = int(bound) if valid.integer else float(bound)
        if name == "batch_size" or name == "buffer_size" or name == "stats_window_size":
            value = max(value, 1)
        _build(owner, **{name: value})


def test_forms_beside_a_number_are_taken() -> None:
    """A schedule for the learning rate, one noise per agent, SB3's ``(n, unit)`` train_freq; each item checked."""
    _build(MADDPG, learning_rate=lambda progress: 1e-3 * progress, noise_std=[0.1, 0.0, 0.2], train_freq=(1, "episode"))
    _build(MADDPG, noise_std=np.array([0.1, 0.1, 0.1]))
    with pytest.raises(ValueError, match=r"^noise_std .* got -0\.5"):
        _build(MADDPG, noise_std=[0.1, -0.5, 0.1])
    with pytest.raises(ValueError, match=r"^train_freq .* got 0"):
        _build(MADDPG, train_freq=(0, "step"))


def test_the_issue_s_inputs_are_refused() -> None:
    """The two inputs a new user found taken silently: a negative buffer and a negative learning_starts."""
    with pytest.raises(ValueError, match=r"^buffer_size \(the replay buffer's capacity .*\) must be an integer >= 1"):
        _build(MADDPG, buffer_size=-5, verbose=1)
    with pytest.raises(ValueError, match=r"^learning_starts \(.*\) must be an integer >= 0, got -1"):
        _build(MADDPG, learning_starts=-1)


@pytest.mark.parametrize(("owner", "ranges"), OWNERS, ids=[owner.__name__ for owner, _ in OWNERS])
def test_every_numeric_argument_has_a_range(owner: Any, ranges: dict[str, Range]) -> None:
    """A numeric argument added to a constructor without a range would be taken as given again."""
    numeric = {
        name
        for name, parameter in inspect.signature(owner).parameters.items()
        if not name.startswith("_") and any(kind in str(parameter.annotation) for kind in ("int", "float"))
    }
    inherited = set(TEAM_ALGORITHM_RANGES) if owner is MATD3 else set()
    # selector is a rule (an int k among its forms, checked by the rule); an experiment's seeds are checked one by one.
    assert numeric - {"selector", "seeds"} == set(ranges) | (inherited & numeric) - {"selector"}
