"""A run group's gradient step traces whole (issue 44): torch._dynamo finds one graph and no break in a whole step of
every run at once (critics' gradients, clipping and Adam step; actors' the same; Polyak updates), for MADDPG and MATD3,
with full and selected sharing; the losses alone too. A compiled group trains as the eager one, to float rounding."""

from typing import Any

import pytest
import torch as th

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.run_group import RunGroup
from tests.run_group.test_run_group import random_batch, stack_batches

dynamo = pytest.importorskip("torch._dynamo")


def tiny_models(algorithm: type[MADDPG], sharing: str, **kwargs: Any) -> list[MADDPG]:
    extra: dict[str, Any] = {"batch_size": 4, "buffer_size": 100, **kwargs}
    if sharing == "selected":
        extra["selector"] = 1
    return [
        algorithm(
            "MlpPolicy",
            SimpleSpreadVecEnv(2, n_agents=3),
            critic_sharing=sharing,
            seed=seed,
            policy_kwargs={"net_arch": [4]},
            **extra,
        )
        for seed in range(2)
    ]


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3], ids=lambda algorithm: algorithm.__name__)
@pytest.mark.parametrize("sharing", ["full", "selected"])
def test_a_groups_gradient_step_traces_as_one_graph_without_a_break(algorithm: type[MADDPG], sharing: str) -> None:
    models = tiny_models(algorithm, sharing, max_grad_norm=0.5)
    group = RunGroup(models, worlds_per_run=2)
    generator = th.Generator().manual_seed(0)
    batch = stack_batches([random_batch(models[0], 4, generator) for _ in models])
    dynamo.reset()
    try:
        steps = [
            lambda: group._traced_step(batch, True),  # critics, actors, targets
            lambda: group._traced_step(batch, False),  # MATD3's delayed steps: the critics only
            lambda: group.networks.critic_losses(batch, 0.95),
            lambda: group.networks.actor_loss_terms(batch, 1e-3),
        ]
        for step in steps:
            explained = dynamo.explain(step)()
            assert (explained.graph_count, explained.graph_break_count) == (1, 0), explained.break_reasons
    finally:
        dynamo.reset()


def test_a_compiled_group_trains_as_the_eager_one() -> None:
    """The same 300 steps of 2 runs (25 gradient steps, selection on): weights and Adam's moments agree to float
    rounding (the compiled step uses Adam's capturable form, the eager one on a CPU its host form)."""
    settings: dict[str, Any] = {"learning_starts": 50, "transitions_per_update": 10, "buffer_size": 1000}
    eager = RunGroup(tiny_models(MADDPG, "selected", **settings), worlds_per_run=2).learn(300)
    dynamo.reset()
    try:
        compiled = RunGroup(tiny_models(MADDPG, "selected", **settings), worlds_per_run=2, compile=True).learn(300)
    finally:
        dynamo.reset()
    assert compiled.n_updates == eager.n_updates == 25 and compiled.compile_seconds > 0
    pairs = list(zip(eager.teams.stacked_parameters().values(), compiled.teams.stacked_parameters().values()))
    for name in ("actor_optimizer", "critic_optimizer"):
        optimizer, other = getattr(eager, name), getattr(compiled, name)
        pairs += list(zip(optimizer.exp_avgs + optimizer.exp_avg_sqs, other.exp_avgs + other.exp_avg_sqs))
    initial = RunGroup(tiny_models(MADDPG, "selected", **settings)).teams.actor.params["mlp.weight_0"]
    assert (eager.teams.actor.params["mlp.weight_0"] - initial).abs().max() > 1e-3  # the steps did something
    for expected, actual in pairs:
        th.testing.assert_close(actual, expected, atol=1e-5, rtol=1e-4)
