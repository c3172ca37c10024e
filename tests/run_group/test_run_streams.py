"""Each run's random stream (sb3_maddpg.run_group.streams): SplitMix64 as published, numbers of the right
distributions, a run's numbers its own whatever the group, and a state that resumes exactly."""

import numpy as np
import pytest
import torch as th
from scipy import stats

from sb3_maddpg.run_group import RunStreams
from sb3_maddpg.run_group.streams import GOLDEN, mix64

MASK = (1 << 64) - 1


def splitmix64(state: int, n: int) -> list[int]:
    """The reference algorithm (Steele, Lea and Flood, 2014; Vigna's C code) in Python's unbounded integers."""
    out = []
    for _ in range(n):
        state = (state + 0x9E3779B97F4A7C15) & MASK
        z = state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
        out.append(z ^ (z >> 31))
    return out


def test_mix64_gives_splitmix64s_published_outputs() -> None:
    # The first outputs of SplitMix64 seeded with 1234567, as Vigna's reference implementation prints them.
    published = [6457827717110365317, 3203168211198807973, 9817491932198370423]
    assert splitmix64(1234567, 3) == published
    states = th.tensor([1234567]) + th.arange(1, 4) * GOLDEN
    assert [value & MASK for value in mix64(states).tolist()] == published


def test_a_draw_is_splitmix64s_stream_from_the_runs_state() -> None:
    streams = RunStreams([3, 40])
    state = mix64(streams.keys + GOLDEN)  # the first draw's state of each run
    bits = streams.bits((2, 3))
    for run in range(2):
        expected = splitmix64(int(state[run]) & MASK, 6)
        assert [value & MASK for value in bits[run].flatten().tolist()] == expected
    assert int(streams.counter) == 1


def test_a_run_draws_the_same_numbers_alone_and_in_any_group() -> None:
    alone, grouped = RunStreams([7]), RunStreams([1, 7, 2, 9])
    for shape in [(5,), (2, 3)]:
        assert th.equal(alone.uniform(shape), grouped.uniform(shape)[1:2])
        assert th.equal(alone.normal(shape), grouped.normal(shape)[1:2])
        assert th.equal(alone.integers(th.tensor(13), shape), grouped.integers(th.tensor(13), shape)[1:2])
    other = RunStreams([1, 8, 2, 9])  # one run's seed changed: the others' numbers are not
    grouped, changed = RunStreams([1, 7, 2, 9]).normal((50,)), other.normal((50,))
    assert th.equal(grouped[[0, 2, 3]], changed[[0, 2, 3]]) and not th.equal(grouped[1], changed[1])


@pytest.mark.parametrize("dtype", [th.float32, th.float64])
def test_uniform_and_normal_numbers_follow_their_distributions(dtype: th.dtype) -> None:
    streams = RunStreams([0, 1])
    uniform = streams.uniform((20_000,), dtype)
    assert uniform.dtype == dtype and uniform.min() >= 0 and uniform.max() < 1
    normal = streams.normal((20_000,), dtype)
    for run in range(2):
        assert stats.kstest(uniform[run].double().numpy(), "uniform").pvalue > 0.001
        assert stats.kstest(normal[run].double().numpy(), "norm").pvalue > 0.001
    assert abs(np.corrcoef(uniform[0].numpy(), uniform[1].numpy())[0, 1]) < 0.03  # runs' streams uncorrelated
    assert len(set(streams.uniform((4096,), th.float64)[0].tolist())) == 4096  # 53 bits: no repeats in 4096


def test_integers_cover_every_value_below_the_bound_evenly() -> None:
    draws = RunStreams([5]).integers(th.tensor(7), (70_000,))[0]
    assert draws.min() == 0 and draws.max() == 6
    assert stats.chisquare(th.bincount(draws, minlength=7).numpy()).pvalue > 0.001


def test_a_saved_state_goes_on_with_the_same_numbers() -> None:
    streams = RunStreams([2, 3])
    streams.normal((4,))
    state = streams.state_dict()
    expected = streams.uniform((6,))
    resumed = RunStreams([2, 3])
    resumed.load_state_dict(state)
    assert th.equal(resumed.uniform((6,)), expected)
