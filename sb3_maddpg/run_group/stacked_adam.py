"""
Adam over a run group's stacked parameters, as tensors: the models' optimiser for every run at once, with no optimiser
object in the step (its ``zero_grad`` and bookkeeping are what broke a compiled round into pieces).

The step is torch's own (``torch.optim.adam.adam``, the function ``torch.optim.Adam.step`` calls) in its multi-tensor
form, given the gradients directly. Adam is element-wise, so slice ``[r]`` of each moment is run r's: the same state a
model's own optimiser would hold.
"""

from collections.abc import Sequence
from typing import Any

import torch as th
import torch.optim.adam as adam_module
from torch.optim.adam import adam


class StackedAdam:
    """
    One Adam over stacked parameters ``[R, ...]``: its moments as tensors of the same shapes, its step count and
    learning rate as 0-dim tensors on the parameters' device.

    :param params: The stacked parameters, updated in place by :meth:`step`.
    :param defaults: The models' optimiser settings (``torch.optim.Adam(...).defaults``).
    """

    def __init__(self, params: Sequence[th.Tensor], defaults: dict[str, Any]) -> None:
        self.params = list(params)
        self.defaults = dict(defaults)
        device = self.params[0].device
        self.exp_avgs = [th.zeros_like(p) for p in self.params]
        self.exp_avg_sqs = [th.zeros_like(p) for p in self.params]
        self.max_exp_avg_sqs = [th.zeros_like(p) for p in self.params] if defaults["amsgrad"] else []
        # One count per parameter (torch's layout); on the device, so that a step reads no host value.
        self.steps = [th.zeros((), dtype=th.float32, device=device) for _ in self.params]
        self._lr = float(defaults["lr"])
        self.lr_tensor = th.tensor(self._lr, dtype=th.float32, device=device)
        """The learning rate as a tensor (the capturable form's): a schedule changes its value, not a compiled step."""

    @classmethod
    def of_models(cls, params: Sequence[th.Tensor], optimizers: Sequence[th.optim.Optimizer]) -> "StackedAdam":
        """
        The stacked optimiser of the models' optimisers, their states stacked (models that have not trained have none).

        :param params: The stacked parameters, in the models' parameter order.
        :param optimizers: Each run's optimiser (``torch.optim.Adam``, the same settings in each: checked by the group).
        :return: The optimiser.
        """
        first = optimizers[0]
        if not isinstance(first, th.optim.Adam):
            raise ValueError(
                f"The models' optimiser is {type(first).__name__}, and a run group trains with Adam only (its step is "
                "torch's Adam over the stacked runs): build the models with policy_kwargs optimizer_class=torch.optim.Adam "
                "(the default), or train them one by one with learn()."
            )
        stacked = cls(params, first.defaults)
        states = [opt.state_dict()["state"] for opt in optimizers]
        if not any(states):
            return stacked
        if not all(state.keys() == states[0].keys() for state in states):
            raise ValueError(
                "Some models' optimisers have state and others none (or for other parameters): build the group from "
                "models that have all trained for the same steps, or none at all."
            )
        for index in range(len(stacked.params)):
            steps = {float(state[index]["step"]) for state in states}
            if len(steps) > 1:
                raise ValueError(
                    f"The models' optimisers are at different steps ({sorted(steps)}): build the group from models "
                    "that have trained for the same steps."
                )
        stacked.load_state_dict(
            {
                "state": {
                    index: {
                        key: th.stack([th.as_tensor(state[index][key]) for state in states]) if key != "step" else value
                        for key, value in states[0][index].items()
                    }
                    for index in states[0]
                },
                "param_groups": [{"lr": first.param_groups[0]["lr"]}],
            }
        )
        return stacked

    @staticmethod
    def capturable_on(device: th.device) -> bool:
        """:return: Whether torch runs Adam's capturable form eagerly on ``device`` (a GPU: yes; a CPU or MPS: no)."""
        return device.type in adam_module._get_capturable_supported_devices()

    @property
    def lr(self) -> float:
        """The learning rate (the host form's, and what a model written back gets: exactly the schedule's value)."""
        return self._lr

    def set_lr(self, lr: float) -> None:
        """:param lr: The new learning rate (also written into :attr:`lr_tensor`, in place: no host read)."""
        self._lr = float(lr)
        self.lr_tensor.fill_(lr)

    def step(self, grads: Sequence[th.Tensor], capturable: bool) -> None:
        """
        One Adam step of every run: the parameters move in place.

        :param grads: Each parameter's gradient, stacked as it is.
        :param capturable: Torch's capturable form: the learning rate and the bias corrections read from the device
            (no host value: what a compiled or CUDA-graph-captured step needs). Eager on a CPU, torch allows only the
            other form (the learning rate read on the host), which differs from it by float rounding.
        """
        settings = self.defaults
        # Only when set: torch's Adam function takes it from 2.7 on (AdamW's form).
        extra: dict[str, Any] = {"decoupled_weight_decay": True} if settings.get("decoupled_weight_decay") else {}
        with th.no_grad():
            adam(
                self.params,
                list(grads),
                self.exp_avgs,
                self.exp_avg_sqs,
                self.max_exp_avg_sqs,
                self.steps,
                foreach=True,
                capturable=capturable,
                amsgrad=bool(settings["amsgrad"]),
                beta1=settings["betas"][0],
                beta2=settings["betas"][1],
                lr=self.lr_tensor if capturable else self.lr,
                weight_decay=settings["weight_decay"],
                eps=settings["eps"],
                maximize=bool(settings["maximize"]),
                **extra,
            )

    def run_state(self, run: int) -> dict[int, dict[str, th.Tensor]]:
        """
        :param run: The run.
        :return: Run ``run``'s state, as its own ``torch.optim.Adam`` holds it (``state_dict()["state"]``; empty before
            the first step).
        """
        if float(self.steps[0]) == 0:
            return {}
        return {index: self._entry(index, lambda tensor: tensor[run].clone()) for index in range(len(self.params))}

    def state_dict(self) -> dict[str, Any]:
        """:return: The state in ``torch.optim.Adam``'s layout (the moments stacked ``[R, ...]``), for ``torch.save``."""
        state = {index: self._entry(index, lambda tensor: tensor.clone()) for index in range(len(self.params))}
        return {"state": state if float(self.steps[0]) > 0 else {}, "param_groups": [{**self.defaults, "lr": self.lr}]}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """
        :param state: A state of :meth:`state_dict` (its tensors on any device); an empty one is Adam before its
            first step.
        """
        with th.no_grad():
            for tensor in (*self.exp_avgs, *self.exp_avg_sqs, *self.max_exp_avg_sqs, *self.steps):
                tensor.zero_()
            for index, entry in state["state"].items():
                self.steps[index].fill_(float(entry["step"]))
                self.exp_avgs[index].copy_(entry["exp_avg"])
                self.exp_avg_sqs[index].copy_(entry["exp_avg_sq"])
                if self.max_exp_avg_sqs:
                    self.max_exp_avg_sqs[index].copy_(entry["max_exp_avg_sq"])
        self.set_lr(float(state["param_groups"][0]["lr"]))

    def _entry(self, index: int, take: Any) -> dict[str, th.Tensor]:
        entry = {
            "step": self.steps[index].detach().cpu().clone(),
            "exp_avg": take(self.exp_avgs[index]),
            "exp_avg_sq": take(self.exp_avg_sqs[index]),
        }
        if self.max_exp_avg_sqs:
            entry["max_exp_avg_sq"] = take(self.max_exp_avg_sqs[index])
        return entry
