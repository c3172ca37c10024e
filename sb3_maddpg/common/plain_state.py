"""Plain data as JSON and arrays, read back without running code: the form of a run's snapshot.

Reading a pickle runs whatever code its bytes name, so whoever can write a shared results directory could run code in
every process that resumes a run from it. A snapshot therefore holds only plain data: ``None``, booleans, numbers,
strings, NumPy arrays and scalars, NumPy random generators, and lists, tuples, deques and string-keyed dicts of them.
:func:`encode` turns such a value into JSON and named arrays (for ``np.savez``), and :func:`decode` turns them back
from ``json.load`` and ``np.load(allow_pickle=False)``: nothing the files name is imported or called.
:func:`object_state` and :func:`restore_object_state` take an object's attributes as plain data and put them back on
a new object of the same construction, which keeps what is not plain data (spaces, a layout, the classes).
"""

import numbers
from collections import deque
from collections.abc import Collection, Mapping
from typing import Any

import numpy as np

TAG = "__plain__"
"""The key that marks a JSON object as an encoded value (an array, a tuple, ...), not a dict."""

BIT_GENERATORS: dict[str, type[np.random.BitGenerator]] = {
    cls.__name__: cls for cls in (np.random.PCG64, np.random.PCG64DXSM, np.random.MT19937, np.random.Philox, np.random.SFC64)
}
"""The bit generators a decoded ``np.random.Generator`` may have, by the name their state gives."""


class NotPlainData(TypeError):
    """A value that :func:`encode` cannot write as plain data (an object of another class)."""


def encode(value: Any) -> tuple[Any, dict[str, np.ndarray]]:
    """
    :param value: Plain data (see the module's docstring).
    :return: The value as JSON (arrays replaced by their names), and the arrays by name.
    :raises NotPlainData: For anything else, with where it is in ``value``.
    """
    arrays: dict[str, np.ndarray] = {}
    return _encode(value, "", arrays), arrays


def _encode(value: Any, path: str, arrays: dict[str, np.ndarray]) -> Any:
    # NumPy first: np.float64 is a float, and would come back as Python's.
    if isinstance(value, np.ndarray) and not value.dtype.hasobject:
        name = f"array_{len(arrays)}"  # numbered, not by path: a dict's key may hold a "/"
        arrays[name] = value
        return {TAG: "array", "name": name}
    if isinstance(value, np.generic) and value.dtype.kind in "biuf":
        return {TAG: "scalar", "dtype": value.dtype.str, "value": value.item()}
    if value is None or type(value) in (bool, int, float, str):
        return value
    if isinstance(value, np.random.Generator):
        return {TAG: "generator", "state": _encode(value.bit_generator.state, f"{path}/state", arrays)}
    if type(value) is list:
        return [_encode(item, f"{path}/{index}", arrays) for index, item in enumerate(value)]
    if type(value) in (tuple, deque):
        items = [_encode(item, f"{path}/{index}", arrays) for index, item in enumerate(value)]
        return (
            {TAG: "tuple", "items": items} if type(value) is tuple else {TAG: "deque", "items": items, "maxlen": value.maxlen}
        )
    if type(value) is dict and all(type(key) is str for key in value) and TAG not in value:
        return {key: _encode(item, f"{path}/{key}", arrays) for key, item in value.items()}
    raise NotPlainData(f"{path or 'the value'} ({type(value).__name__}) is not plain data, which a snapshot holds")


def decode(value: Any, arrays: Mapping[str, np.ndarray]) -> Any:
    """
    :param value: JSON from :func:`encode`.
    :param arrays: Its arrays (an ``np.load(..., allow_pickle=False)``).
    :return: The value :func:`encode` was given (arrays of the same dtype and shape, scalars of the same dtype).
    :raises ValueError: For JSON that :func:`encode` does not write (``KeyError`` for a missing array or field).
    """
    if isinstance(value, list):
        return [decode(item, arrays) for item in value]
    if not isinstance(value, dict):
        return value
    tag = value.get(TAG)
    if tag is None:
        return {key: decode(item, arrays) for key, item in value.items()}
    if tag == "array":
        return arrays[value["name"]]
    if tag == "scalar":
        dtype = np.dtype(value["dtype"])
        if dtype.kind not in "biuf":
            raise ValueError(f"a scalar of dtype {dtype} is not plain data")
        return dtype.type(value["value"])
    if tag in ("tuple", "deque"):
        items = [decode(item, arrays) for item in value["items"]]
        return tuple(items) if tag == "tuple" else deque(items, maxlen=value["maxlen"])
    if tag == "generator":
        state = decode(value["state"], arrays)
        bit_generator = BIT_GENERATORS[state["bit_generator"]]()
        bit_generator.state = state
        return np.random.Generator(bit_generator)
    raise ValueError(f"unknown {TAG} {tag!r}")


def object_state(
    source: Any, holders: tuple[type, ...], made: Collection[str] = (), names: Collection[str] | None = None
) -> dict[str, Any]:
    """
    :param source: An object.
    :param holders: Classes whose objects are state (e.g. the worlds of an env): such an attribute is taken as its
        own ``object_state``.
    :param made: Attributes left out, which a new object of the same construction has as ``source`` has (spaces, a
        layout); any other that is not plain data is refused by :func:`encode`.
    :param names: The attributes to take (those ``source`` has); ``None``: all of them but ``made``.
    :return: The attributes by name, for :func:`encode`. Read-only arrays are left out: constants of the
        construction, which stay read-only.
    """
    attributes = vars(source)
    chosen = [name for name in attributes if name not in made] if names is None else [n for n in names if n in attributes]
    state = {}
    for name in chosen:
        value = attributes[name]
        if isinstance(value, holders):
            state[name] = object_state(value, holders, made)
        elif not (isinstance(value, np.ndarray) and not value.flags.writeable):
            state[name] = value
    return state


def restore_object_state(target: Any, state: Mapping[str, Any], holders: tuple[type, ...]) -> None:
    """
    Put attributes from :func:`object_state` back on a new object of the same construction.

    :param target: The new object.
    :param state: Its attributes, decoded.
    :param holders: As given to :func:`object_state`.
    :raises ValueError: For a value of another kind than the object's (another type; an array of another dtype or
        shape), or one that would hide the class's attribute (a method): a snapshot of other code, or tampered with.
    """
    attributes = vars(target)
    for name, value in state.items():
        if name not in attributes and hasattr(type(target), name):  # e.g. a method, which plain data would shadow
            raise ValueError(f"{type(target).__name__}.{name} is the class's, not state")
        current = attributes.get(name)  # None: an attribute set in training (e.g. VecNormalize's old_obs)
        if isinstance(current, holders) and isinstance(value, dict):
            restore_object_state(current, value, holders)
        elif not _same_kind(current, value):
            raise ValueError(f"{type(target).__name__}.{name} is {_kind(value)} in the snapshot, {_kind(current)} here")
        else:
            attributes[name] = value


def _same_kind(current: Any, value: Any) -> bool:
    """Whether a saved value may replace an attribute's (``None`` either way: an attribute set later, e.g. ``_last_obs``)."""
    if current is None or value is None:
        return True
    if isinstance(current, np.ndarray) or isinstance(value, np.ndarray):
        # A 0-d array may become a NumPy scalar in an update, and back (VecNormalize's running statistics); an empty
        # array is a placeholder, filled in training (VecNormalize's old_reward).
        arrays = all(isinstance(item, np.ndarray | np.generic) for item in (current, value))
        return arrays and (current.size == 0 or (value.dtype, value.shape) == (current.dtype, current.shape))
    number = (numbers.Number, np.generic)
    if isinstance(current, number):  # a count may become a NumPy scalar after an update
        return isinstance(value, number)
    return isinstance(value, type(current))


def _kind(value: Any) -> str:
    """:return: A value's type, with an array's dtype and shape."""
    if isinstance(value, np.ndarray):
        return f"an array of {value.dtype}{list(value.shape)}"
    return f"a {type(value).__name__}"
