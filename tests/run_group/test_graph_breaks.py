"""A run group's round traces whole (issue 44): torch._dynamo finds one graph and no break in each part a compiled
group runs, for MADDPG and MATD3, with full and selected sharing: the env step of every run's worlds, and a whole
gradient step of every run at once (its batch drawn; critics' gradients, clipping and Adam step; actors' the same;
Polyak updates). A compiled group trains as the eager one, to float rounding."""

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
def test_each_part_of_a_round_traces_as_one_graph_without_a_break(algorithm: type[MADDPG], sharing: str) -> None:
    """The parts a compiled group runs: the env step (warm-up and acting), a gradient step on a given batch (with and
    without the actors: MATD3's delay) and one on a batch drawn from the buffers; the losses alone too."""
    models = tiny_models(algorithm, sharing, max_grad_norm=0.5)
    group = RunGroup(models, worlds_per_run=2, compile=True)  # built for compiling: nothing compiles until called
    generator = th.Generator().manual_seed(0)
    batch = stack_batches([random_batch(models[0], 4, generator) for _ in models])
    for rows in (slice(0, 2), slice(2, 4)):  # the buffers hold the batch's rows, two worlds' at a time
        fields = [None if field is None else field[:, rows] for field in batch]
        group.buffers.add(*fields[:3], fields[4], fields[3], fields[5])
    observations = group._worlds().observations
    dynamo.reset()
    try:
        parts = [
            lambda: group._act_and_move(observations, True),  # warm-up: uniform actions
            lambda: group._act_and_move(observations, False),  # the actors act
            lambda: group._gradient_step(batch, True),  # critics, actors, targets
            lambda: group._gradient_step(batch, False),  # MATD3's delayed steps: the critics only
            lambda: group._sample_and_step(True),  # the batch drawn inside
            lambda: group.networks.critic_losses(batch, 0.95),
            lambda: group.networks.actor_loss_terms(batch, 1e-3),
        ]
        for part in parts:
            explained = dynamo.explain(part)()
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


@pytest.mark.skipif(not th.cuda.is_available(), reason="needs a CUDA device")
@pytest.mark.parametrize("compile", [True, "default"], ids=["captured", "compiled"])
def test_a_compiled_group_on_cuda_trains_as_the_eager_one_on_the_cpu(compile: bool | str) -> None:
    """On CUDA, with the gradient step replayed as CUDA graphs (``True``) or compiled without capture: the same
    training as an eager group on the CPU, to float rounding (MATD3: both kinds of step, and the smoothing noise)."""
    settings: dict[str, Any] = {"learning_starts": 50, "transitions_per_update": 10, "buffer_size": 1000}
    eager = RunGroup(tiny_models(MATD3, "selected", **settings), worlds_per_run=2).learn(300)
    dynamo.reset()
    try:
        on_cuda = RunGroup(tiny_models(MATD3, "selected", **settings), worlds_per_run=2, device="cuda", compile=compile)
        on_cuda.learn(300)
    finally:
        dynamo.reset()
    assert on_cuda.n_updates == eager.n_updates == 25
    for expected, actual in zip(eager.teams.stacked_parameters().values(), on_cuda.teams.stacked_parameters().values()):
        th.testing.assert_close(actual.cpu(), expected, atol=1e-4, rtol=1e-3)
    th.testing.assert_close(on_cuda.episode_stats()["reward"], eager.episode_stats()["reward"], atol=1e-3, rtol=1e-3)


def test_a_captured_step_reads_its_tensors_where_they_are() -> None:
    """What CUDA graphs need (checked on the CPU, where the marking is the same): the weights, Adam's state, the
    random streams and the replay buffers marked static, so that a replay neither copies the buffers into the graph's
    memory nor reads stale weights."""
    group = RunGroup(tiny_models(MADDPG, "selected"), worlds_per_run=2)
    group._mark_static()
    marked = [
        *group.teams.stacked_parameters().values(),
        *group.critic_optimizer.exp_avgs,
        *group.actor_optimizer.steps,
        group.actor_optimizer.lr_tensor,
        group.streams.counter,
        group.buffers.observations,
        group.buffers.selections,
        group.buffers.filled,
    ]
    assert all(hasattr(tensor, "_dynamo_static_input_type") for tensor in marked)
