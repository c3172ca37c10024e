"""
What a piece of training would do on a GPU, read on a CPU: the kernels it launches, the host syncs and the host-device
transfers it makes, the float64 it computes.

Run the code on the ``meta`` device (tensors with shapes and no data: every op runs, nothing is computed) inside
:class:`DeviceAudit`. Two of torch's hooks watch it: a ``TorchDispatchMode`` sees every op that reaches a kernel (so it
counts the launches a GPU would make, reads of a device value by the host, copies between the host and the device,
host tensors mixed into device ops, float64 results), and a ``TorchFunctionMode`` sees tensors made from host data
(``torch.tensor``, ``as_tensor``, ``asarray``, ``from_numpy``), which reach no kernel on ``meta`` but are a copy to the
device on a GPU.
"""

from collections import Counter
from collections.abc import Callable
from typing import Any

import torch as th
import torch.optim.adam as adam_module
from torch.overrides import TorchFunctionMode
from torch.utils._python_dispatch import TorchDispatchMode
from torch.utils._pytree import tree_leaves

_FROM_HOST_DATA = {"tensor", "as_tensor", "asarray", "from_numpy", "scalar_tensor"}
"""Torch functions that make a tensor from host data (a copy to the device when the tensor lives there)."""

_SYNC = "_local_scalar_dense"
"""The op of a host read of one value (``.item()``, ``bool()``...): on a GPU, a wait for the stream."""

_VIEWS = {"detach", "alias", "lift_fresh", "_unsafe_view"}
"""Ops that launch no kernel but are not marked as views."""


class DeviceAudit:
    """
    A context in which every op on ``device`` is counted, and every host sync, host-device transfer, host tensor mixed
    into a device op, tensor made from host data and float64 result is recorded (with the op's name).

    :param device: The device whose ops are audited (``"meta"`` on a CPU: nothing is computed).
    """

    def __init__(self, device: th.device | str = "meta") -> None:
        self.device = th.device(device)
        self.launches: Counter[str] = Counter()
        """Ops that would launch a kernel on the device, by name (views and metadata ops excluded)."""
        self.syncs: list[str] = []
        """Host reads of a device value (``.item()``, ``bool()``, ``.tolist()``...): a stream sync each on a GPU."""
        self.transfers: list[str] = []
        """Copies between the host and the device, host tensors in device ops and tensors made from host data."""
        self.float64: list[str] = []
        """Ops on the device that return float64."""
        self._dispatch = _Dispatch(self)
        self._function = _Functions(self)

    @property
    def n_launches(self) -> int:
        """Kernel launches counted so far."""
        return sum(self.launches.values())

    def __enter__(self) -> "DeviceAudit":
        if self.device.type == "meta":
            # The meta device stands for a GPU: torch's capturable Adam (what a GPU step runs) checks its device.
            self._capturable_devices = adam_module._get_capturable_supported_devices
            adam_module._get_capturable_supported_devices = lambda **kwargs: [*self._capturable_devices(**kwargs), "meta"]
        self._function.__enter__()
        self._dispatch.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._dispatch.__exit__(*exc)
        self._function.__exit__(*exc)
        if self.device.type == "meta":
            adam_module._get_capturable_supported_devices = self._capturable_devices

    def problems(self) -> list[str]:
        """:return: Every sync, transfer and float64 op recorded, one line each (empty: the code is device-ready)."""
        return (
            [f"host sync: {name}" for name in self.syncs]
            + [f"host-device transfer: {name}" for name in self.transfers]
            + [f"float64: {name}" for name in self.float64]
        )

    def _on_device(self, tensor: th.Tensor) -> bool:
        return tensor.device.type == self.device.type

    def before(self, name: str, inputs: list[th.Tensor]) -> bool:
        """
        Record what an op's inputs say before it runs (called by the dispatch mode).

        :return: Whether the op is a host read of a device value (then it is not run: on ``meta`` it has no value).
        """
        on_device = [t for t in inputs if self._on_device(t)]
        on_host = [t for t in inputs if t.device.type == "cpu"]
        if on_device and name == _SYNC:
            self.syncs.append(name)
            return True
        if on_device and on_host:
            self.transfers.append(f"{name} ({len(on_host)} host tensor(s) with {len(on_device)} on {self.device})")
        return False

    def after(self, name: str, inputs: list[th.Tensor], outputs: list[th.Tensor], is_view: bool) -> None:
        """Record an op that ran: a launch, a copy between host and device, a float64 result."""
        on_device = [t for t in outputs if self._on_device(t)]
        if not on_device and not any(self._on_device(t) for t in inputs):
            return  # a host op (e.g. an optimiser's step counter on the host): no launch
        if any(t.device.type == "cpu" for t in outputs) and not any(t.device.type == "cpu" for t in inputs):
            self.transfers.append(f"{name} (device to host)")
        if any(t.dtype == th.float64 for t in on_device):
            self.float64.append(name)
        if not is_view:
            self.launches[name] += 1


class _Dispatch(TorchDispatchMode):
    def __init__(self, audit: DeviceAudit) -> None:
        super().__init__()
        self.audit = audit

    def __torch_dispatch__(self, func: Any, types: Any, args: Any = (), kwargs: Any = None) -> Any:
        kwargs = kwargs or {}
        name = str(func.overloadpacket.__name__)
        inputs = [leaf for leaf in tree_leaves((args, kwargs)) if isinstance(leaf, th.Tensor)]
        if self.audit.before(name, inputs):
            return 0  # a stand-in value (meta tensors hold none): the code goes on to be audited
        result = func(*args, **kwargs)
        outputs = [leaf for leaf in tree_leaves(result) if isinstance(leaf, th.Tensor)]
        self.audit.after(name, inputs, outputs, bool(func.is_view) or name in _VIEWS)
        return result


class _Functions(TorchFunctionMode):
    def __init__(self, audit: DeviceAudit) -> None:
        super().__init__()
        self.audit = audit

    def __torch_function__(self, func: Callable[..., Any], types: Any, args: Any = (), kwargs: Any = None) -> Any:
        kwargs = kwargs or {}
        result = func(*args, **kwargs)
        name = getattr(func, "__name__", "")
        if name in _FROM_HOST_DATA and isinstance(result, th.Tensor) and self.audit._on_device(result):
            data = args[0] if args else kwargs.get("data", kwargs.get("obj"))
            if not isinstance(data, th.Tensor) or data.device.type == "cpu":
                self.audit.transfers.append(f"torch.{name} of host data")
        return result
