"""A run group's Adam over stacked runs is each run's own Adam: the same steps as ``torch.optim.Adam`` on each run's
slice, in both of torch's forms, its state stacked from trained models and saved and restored whole."""

from typing import Any

import pytest
import torch as th

from sb3_maddpg.run_group import StackedAdam


def runs_and_grads(n_runs: int = 3, steps: int = 4) -> tuple[list[th.Tensor], list[list[th.Tensor]]]:
    generator = th.Generator().manual_seed(0)
    params = [th.randn(n_runs, 2, 5, 3, generator=generator), th.randn(n_runs, 2, 1, 3, generator=generator)]
    grads = [[th.randn(p.shape, generator=generator) for p in params] for _ in range(steps)]
    return params, grads


SETTINGS: list[dict[str, Any]] = [
    {"lr": 3e-3},
    {"lr": 1e-2, "betas": (0.8, 0.9), "eps": 1e-6, "weight_decay": 0.1, "amsgrad": True},
]


@pytest.mark.parametrize("settings", SETTINGS, ids=["defaults", "amsgrad-decay"])
def test_each_runs_slice_steps_as_its_own_torch_adam(settings: dict[str, Any]) -> None:
    params, grads = runs_and_grads()
    stacked = StackedAdam([p.clone() for p in params], th.optim.Adam([th.zeros(1)], **settings).defaults)
    runs = [[p[run].clone() for p in params] for run in range(3)]
    references = [th.optim.Adam(run_params, **settings) for run_params in runs]
    for step_grads in grads:
        stacked.step(step_grads, capturable=False)
        for run, (run_params, reference) in enumerate(zip(runs, references)):
            for param, grad in zip(run_params, step_grads):
                param.grad = grad[run].clone()
            reference.step()
    for run, (run_params, reference) in enumerate(zip(runs, references)):
        for index, param in enumerate(run_params):
            th.testing.assert_close(stacked.params[index][run], param, atol=1e-6, rtol=1e-5)
        expected = reference.state_dict()["state"]
        for index, entry in stacked.run_state(run).items():
            assert entry.keys() == expected[index].keys()
            for key, value in entry.items():
                th.testing.assert_close(value, expected[index][key], atol=1e-6, rtol=1e-5, msg=f"run {run} {index} {key}")


def test_a_state_dict_restores_the_same_steps_and_models_states_stack() -> None:
    params, grads = runs_and_grads()
    defaults = th.optim.Adam([th.zeros(1)], lr=3e-3).defaults
    first = StackedAdam([p.clone() for p in params], defaults)
    for step_grads in grads[:2]:
        first.step(step_grads, capturable=False)
    second = StackedAdam([p.clone() for p in first.params], defaults)
    second.load_state_dict(first.state_dict())
    second.set_lr(first.lr)
    for step_grads in grads[2:]:
        first.step(step_grads, capturable=False)
        second.step(step_grads, capturable=False)
    assert all(th.equal(a, b) for a, b in zip(first.params, second.params))
    # Models' optimisers, one per run, stacked: the moments of run r are model r's.
    models = [[th.nn.Parameter(p[run].clone()) for p in params] for run in range(3)]
    optimizers = [th.optim.Adam(run_params, lr=3e-3) for run_params in models]
    for run, optimizer in enumerate(optimizers):
        for param, grad in zip(models[run], grads[0]):
            param.grad = grad[run]
        optimizer.step()
    stacked = StackedAdam.of_models([th.stack([m[i].detach() for m in models]) for i in range(2)], optimizers)
    for run, optimizer in enumerate(optimizers):
        for index, entry in optimizer.state_dict()["state"].items():
            assert th.equal(stacked.exp_avg_sqs[index][run], entry["exp_avg_sq"])
    assert float(stacked.steps[0]) == 1.0


def test_models_at_different_steps_are_refused() -> None:
    params, grads = runs_and_grads(n_runs=2)
    models = [[th.nn.Parameter(p[run].clone()) for p in params] for run in range(2)]
    optimizers = [th.optim.Adam(run_params) for run_params in models]
    for steps, (run_params, optimizer) in zip((1, 2), zip(models, optimizers)):
        for _ in range(steps):
            for param, grad in zip(run_params, grads[0]):
                param.grad = grad[0]
            optimizer.step()
    with pytest.raises(ValueError, match=r"^The models' optimisers are at different steps \(\[1\.0, 2\.0\]\)"):
        StackedAdam.of_models(params, optimizers)


def test_the_capturable_form_where_torch_runs_it_eagerly_and_an_empty_state_is_adam_before_its_first_step() -> None:
    """Eager on a CPU or MPS, torch refuses the capturable form: a group there takes the host form."""
    assert StackedAdam.capturable_on(th.device("cuda")) and not StackedAdam.capturable_on(th.device("cpu"))
    assert not StackedAdam.capturable_on(th.device("mps"))
    params, grads = runs_and_grads()
    stacked = StackedAdam([p.clone() for p in params], th.optim.Adam([th.zeros(1)]).defaults)
    stacked.step(grads[0], capturable=False)
    stacked.load_state_dict({"state": {}, "param_groups": [{"lr": 1e-3}]})
    assert float(stacked.steps[0]) == 0 and all(not m.any() for m in (*stacked.exp_avgs, *stacked.exp_avg_sqs))
