"""
Each run's random numbers, drawn for every run of a group in one call.

A counter-based generator: draw ``c`` of run ``r`` is SplitMix64's stream (Steele et al., 2014) from a state that
hashes the run's seed and ``c``, element ``i`` its ``i``-th output. So a run's numbers depend on its seed and on how
many draws came before, never on the other runs of its group (a run alone and inside a group of any size draw the
same numbers); a draw is a fixed handful of element-wise kernels whatever the number of runs; the counter lives on
the device (no host read, no Python int that changes per draw); and the state is two small integer tensors that mean
the same on any device (a group saved on one device resumes on another).
"""

import math
from collections.abc import Sequence

import torch as th

_GOLDEN = 0x9E3779B97F4A7C15
_MIX_1 = 0xBF58476D1CE4E5B9
_MIX_2 = 0x94D049BB133111EB


def _int64(value: int) -> int:
    """An unsigned 64-bit constant as the signed int64 with the same bits (torch's integers are signed)."""
    value &= (1 << 64) - 1
    return value - (1 << 64) if value >= 1 << 63 else value


GOLDEN, MIX_1, MIX_2 = _int64(_GOLDEN), _int64(_MIX_1), _int64(_MIX_2)


def _shift_right(bits: th.Tensor, shift: int) -> th.Tensor:
    """A logical right shift of int64 bits (torch's ``>>`` is arithmetic: the sign bit would fill in)."""
    return (bits >> shift) & ((1 << (64 - shift)) - 1)


def mix64(bits: th.Tensor) -> th.Tensor:
    """
    SplitMix64's output function on int64 tensors (products wrap modulo 2**64, as the reference's unsigned ones).

    :param bits: Any int64 tensor.
    :return: The mixed bits, the same shape.
    """
    bits = (bits ^ _shift_right(bits, 30)) * MIX_1
    bits = (bits ^ _shift_right(bits, 27)) * MIX_2
    return bits ^ _shift_right(bits, 31)


class RunStreams:
    """
    One random stream per run, every run's draw in one call: ``[R, *shape]``, row r from run r's stream.

    :param seeds: Each run's seed (any int; its low 64 bits count).
    :param device: Where the numbers are drawn.
    """

    def __init__(self, seeds: Sequence[int], device: th.device | str = "cpu") -> None:
        self.device = th.device(device)
        seed_bits = th.tensor([_int64(int(seed)) for seed in seeds], dtype=th.int64, device=self.device)
        self.keys = mix64(seed_bits + GOLDEN)
        """Each run's key, ``[R]`` (int64)."""
        self.counter = th.zeros((), dtype=th.int64, device=self.device)
        """Draws made so far (on the device: it advances without a host read)."""
        self._offsets: dict[int, th.Tensor] = {}
        self._golden = th.tensor(GOLDEN, dtype=th.int64, device=self.device)

    @property
    def n_runs(self) -> int:
        """The number of runs ``R``."""
        return self.keys.shape[0]

    def bits(self, shape: Sequence[int]) -> th.Tensor:
        """
        :param shape: Each run's shape.
        :return: 64 random bits per element, ``[R, *shape]`` (int64); the counter advances by one.
        """
        count = math.prod(shape)
        if th.compiler.is_compiling():
            # In a compiled graph, made inline (a cache is state the graph would guard on), times a tensor: a constant
            # would be folded into index arithmetic, which cannot wrap around as int64 products do.
            offsets = th.arange(1, count + 1, dtype=th.int64, device=self.device) * self._golden
        else:  # SplitMix64's state after i + 1 steps, made once per size
            if count not in self._offsets:
                self._offsets[count] = th.arange(1, count + 1, dtype=th.int64, device=self.device) * GOLDEN
            offsets = self._offsets[count]
        state = mix64(self.keys + (self.counter + 1) * GOLDEN)  # the keys are hashed: one more mix decorrelates
        self.counter += 1
        return mix64(state.unsqueeze(1) + offsets).view(self.n_runs, *shape)

    def uniform(self, shape: Sequence[int], dtype: th.dtype = th.float32) -> th.Tensor:
        """
        :param shape: Each run's shape.
        :param dtype: float32 (24 random bits per number) or float64 (53).
        :return: Uniform numbers in [0, 1), ``[R, *shape]``.
        """
        mantissa = round(-math.log2(th.finfo(dtype).eps)) + 1  # 24 bits for float32, 53 for float64
        return _shift_right(self.bits(shape), 64 - mantissa).to(dtype) * 2.0**-mantissa

    def normal(self, shape: Sequence[int], dtype: th.dtype = th.float32) -> th.Tensor:
        """
        :param shape: Each run's shape.
        :param dtype: The numbers' dtype.
        :return: Standard normal numbers (Box-Muller on two uniforms), ``[R, *shape]``.
        """
        uniform = self.uniform((2, *shape), dtype)
        radius = th.sqrt(-2.0 * th.log1p(-uniform[:, 0]))  # 1 - u in (0, 1]: the log is finite
        return radius * th.cos((2.0 * math.pi) * uniform[:, 1])

    def integers(self, high: th.Tensor, shape: Sequence[int]) -> th.Tensor:
        """
        :param high: The exclusive upper bound, a 0-dim int64 tensor on the device (e.g. a buffer's filled rows), > 0.
        :param shape: Each run's shape.
        :return: Integers uniform in [0, high), ``[R, *shape]`` (int64; the modulo's bias is below high / 2**63).
        """
        return _shift_right(self.bits(shape), 1) % high

    def state_dict(self) -> dict[str, th.Tensor]:
        """:return: The keys and the counter (on the host: they mean the same on any device)."""
        return {"keys": self.keys.cpu().clone(), "counter": self.counter.cpu().clone()}  # a copy, also on the host

    def load_state_dict(self, state: dict[str, th.Tensor]) -> None:
        """:param state: A state of :meth:`state_dict`, of streams of the same seeds."""
        keys = state["keys"]
        if keys.shape != self.keys.shape or (self.keys.device.type != "meta" and not th.equal(keys.cpu(), self.keys.cpu())):
            raise ValueError("This random-stream state is of other seeds: load a state of streams of the same runs.")
        self.counter.copy_(state["counter"])
