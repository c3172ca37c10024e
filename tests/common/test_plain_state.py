"""A snapshot's plain data round-trips through JSON and ``np.savez`` exactly, and nothing else is written or read."""

import io
import json
import re
from collections import deque
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from sb3_maddpg.common.plain_state import NotPlainData, decode, encode, object_state, restore_object_state


def through_files(value: Any) -> Any:
    """``value`` encoded, written as a snapshot's files are (JSON, ``np.savez``), read back and decoded."""
    document, arrays = encode(value)
    file = io.BytesIO()
    np.savez(file, allow_pickle=False, **arrays)
    file.seek(0)
    with np.load(file, allow_pickle=False) as loaded:
        return decode(json.loads(json.dumps(document)), loaded)


def test_plain_data_comes_back_with_its_types_dtypes_and_random_streams() -> None:
    generator = np.random.default_rng(3)
    generator.random(5)
    value = {
        "counts": [0, -1, 2**70, True, None, "a/b"],  # a 128-bit generator state needs big ints
        "floats": (0.1, float("inf"), -0.0),
        "scalars": [np.float32(-98.20072), np.int32(25), np.bool_(True), np.uint64(2**64 - 1), np.float64(1 / 3)],
        "arrays": [np.arange(6, dtype=np.int16).reshape(2, 3), np.zeros((2, 0)), np.array(1.5)],
        "episodes": deque([{"r": np.float32(1.25), "l": np.int32(25)}], maxlen=100),
        "generators": [generator, np.random.Generator(np.random.MT19937(7))],
    }
    back = through_files(value)
    assert back["counts"] == value["counts"] and back["floats"] == value["floats"]
    assert type(back["floats"]) is tuple and str(back["floats"][2]) == "-0.0"
    for saved, read in zip(value["scalars"], back["scalars"]):
        assert type(read) is type(saved) and read == saved  # np.float32, not a Python float: means stay float32
    for saved, read in zip(value["arrays"], back["arrays"]):
        assert read.dtype == saved.dtype and read.shape == saved.shape and np.array_equal(read, saved)
    assert back["episodes"] == value["episodes"] and back["episodes"].maxlen == 100
    assert type(back["episodes"][0]["r"]) is np.float32
    for saved, read in zip(value["generators"], back["generators"]):
        assert np.array_equal(read.random(4), saved.random(4))  # the stream goes on where it was


@pytest.mark.parametrize(
    ("value", "where"),
    [
        ({"space": SimpleNamespace()}, "/space (SimpleNamespace)"),
        ([np.array([object()], dtype=object)], "/0 (ndarray)"),  # object arrays are pickled by np.save
        ({1: "a"}, "the value (dict)"),  # JSON keys are strings
        ({"__plain__": "array"}, "the value (dict)"),  # the tag is reserved
        ((i for i in range(2)), "the value (generator)"),
    ],
)
def test_anything_but_plain_data_is_refused_by_where_it_is(value: Any, where: str) -> None:
    with pytest.raises(NotPlainData, match=f"^{re.escape(where)} is not plain data"):
        encode(value)


@pytest.mark.parametrize(
    "document",
    [
        {"__plain__": "scalar", "dtype": "|O", "value": 1},  # an object scalar would be any object
        {"__plain__": "generator", "state": {"bit_generator": "os.system"}},  # only NumPy's bit generators
        {"__plain__": "class", "name": "os.system"},
        {"__plain__": "array", "name": "missing"},
    ],
)
def test_json_that_encode_does_not_write_is_refused(document: dict[str, Any]) -> None:
    with pytest.raises((ValueError, KeyError)):
        decode(document, {})


def test_an_objects_state_goes_back_on_a_new_object_of_its_construction() -> None:
    class Worlds:
        def __init__(self) -> None:
            self.positions = np.zeros((2, 3))

    class Env:
        def __init__(self) -> None:
            self.worlds = Worlds()
            self.space = SimpleNamespace(seed=0)  # made by the construction: left out
            self.steps = 0
            self.flags = np.zeros(2, dtype=bool)
            self.flags.flags.writeable = False  # a constant of the construction: left out
            self.returns = np.array([])  # a placeholder, filled in stepping

    env = Env()
    env.worlds.positions += 1.5
    env.steps, env.returns = 7, np.ones(4, dtype=np.float32)
    env.last_obs = np.ones(2)  # set in stepping, which a new env does not have yet
    state = object_state(env, (Worlds,), made={"space"})
    assert set(state) == {"worlds", "steps", "returns", "last_obs"}
    fresh = Env()
    restore_object_state(fresh, through_files(state), (Worlds,))
    assert np.array_equal(fresh.worlds.positions, env.worlds.positions) and fresh.steps == 7
    assert fresh.returns.dtype == np.float32 and np.array_equal(fresh.last_obs, env.last_obs)
    assert not fresh.flags.flags.writeable

    for name, value in [
        ("steps", "7"),
        ("worlds", np.zeros(2)),
        ("flags", np.zeros(3, dtype=bool)),  # another shape
        ("flags", np.zeros(2, dtype=np.int64)),  # another dtype
        ("__init__", 0),  # would hide the class's method
    ]:
        with pytest.raises(ValueError, match=name):
            restore_object_state(Env(), {name: value}, (Worlds,))
