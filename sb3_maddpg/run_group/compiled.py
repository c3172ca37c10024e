"""
A run group's device work compiled: each part of a round (the env step of every run's worlds; a gradient step of
every run, its batch drawn inside) as one graph with ``torch.compile(fullgraph=True)``, the time its compiling took
counted.
"""

import time
import warnings
from collections.abc import Callable, Hashable
from typing import Any

import torch as th
from torch.utils._pytree import tree_map


class CompiledPart:
    """
    One part of a round, compiled on its first call with each value of its Python arguments (e.g. whether the actors
    are due: a graph each), or run as it is.

    :param function: The part: tensors in, tensors out; its Python arguments decide the graph.
    :param mode: ``torch.compile``'s mode (``"reduce-overhead"``: CUDA graphs on a GPU), or None for its default;
        ignored when ``compile`` is False.
    :param compile: Whether to compile; False runs ``function`` as it is (eager).
    """

    def __init__(self, function: Callable[..., Any], mode: str | None, compile: bool) -> None:
        self.function = th.compile(function, fullgraph=True, mode=mode) if compile else function
        self.compiled = compile
        self.copies_outputs = compile and captures(mode)
        """Whether the outputs are copied out of the CUDA graphs' memory (a capturing mode)."""
        self.seconds = 0.0
        """Seconds spent in first calls (compiling) so far."""
        self._seen: set[Hashable] = set()

    def __call__(self, *args: Any, key: Hashable = None) -> Any:
        """
        :param args: The part's arguments.
        :param key: The values of its Python arguments (a new key compiles a new graph: its call is timed).
        :return: What the part returns (on CUDA graphs, copied out of the graph's memory, which the next call reuses).
        """
        if not self.compiled:
            return self.function(*args)
        if key in self._seen:
            result = self.function(*args)
        else:  # this key's first call: it compiles
            start = time.perf_counter()
            with warnings.catch_warnings():
                # The worlds' array namespace is looked up through array_api_compat's lru_cache-d helpers (a type's
                # module), which tracing through the cache gets exactly: torch warns of the cache it ignores.
                warnings.filterwarnings(
                    "ignore", message="Dynamo detected a call to a `functools.lru_cache`", category=UserWarning
                )
                result = self.function(*args)
            self.seconds += time.perf_counter() - start
            self._seen.add(key)
        if self.copies_outputs:
            result = tree_map(lambda value: value.clone() if isinstance(value, th.Tensor) else value, result)
        return result


def captures(mode: str | None) -> bool:
    """
    :param mode: A ``torch.compile`` mode, or None (its default).
    :return: Whether the mode replays CUDA graphs (``"reduce-overhead"``, ``"max-autotune"``): on a GPU, its part's
        outputs are the graph's memory, which the next replay reuses.
    """
    if mode is None:
        return False
    from torch._inductor import list_mode_options  # the compiler's own table of what each mode turns on

    return bool(list_mode_options(mode).get("triton.cudagraphs", False))


def mark_static(tensors: list[th.Tensor]) -> None:
    """
    Keep the addresses of tensors a compiled part changes in place (the parameters, Adam's state, the random
    streams' counter): CUDA graphs replay on fixed addresses, and a static tensor is read where it is, not copied in.

    :param tensors: The tensors.
    """
    for tensor in tensors:
        th._dynamo.mark_static_address(tensor)
