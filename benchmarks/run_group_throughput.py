"""
R runs' updates in one process (a run group) against the same work as R separate single-run updates, on the CPU.

One gradient step of every run, at the paper's sizes (64-unit networks, batch 1024): the group's update of R runs at
once, against R updates of a group of one and R calls of ``MADDPG.train(1)`` (the reference path), each on its own
model and batch. All three are timed in the same run, interleaved, and the ratios are of their medians (> 1: the
group is faster). Also the same group compiled (``RunGroup(..., compile=True)``) against ``MADDPG.train``. Sampling is
left out of every path (each gets its batch ready).

    python benchmarks/run_group_throughput.py --n-agents 5 --runs 1 4 16 --repeats 5
"""

import argparse
import statistics
import time
from collections.abc import Callable
from typing import Any

import torch as th
from stable_baselines3.common.logger import Logger

from sb3_maddpg import MADDPG
from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.run_group import RunGroup


def make_model(seed: int, n_agents: int, batch_size: int) -> MADDPG:
    model = MADDPG("MlpPolicy", SimpleSpreadVecEnv(1, n_agents=n_agents), seed=seed, batch_size=batch_size, buffer_size=10)
    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


def random_batch(model: MADDPG, batch_size: int, generator: th.Generator) -> MultiAgentReplayBufferSamples:
    layout = model.agent_layout
    assert layout is not None

    def normal(*shape: int) -> th.Tensor:
        return th.randn(*shape, generator=generator)

    return MultiAgentReplayBufferSamples(
        normal(batch_size, layout.obs_dim),
        normal(batch_size, layout.action_dim).clamp(-1, 1),
        normal(batch_size, layout.obs_dim),
        th.zeros(batch_size, layout.n_agents),
        normal(batch_size, layout.n_agents),
        None,
    )


def stack(batches: list[MultiAgentReplayBufferSamples]) -> MultiAgentReplayBufferSamples:
    """:return: The runs' batches with a run dimension in front, as a group updates on them."""
    return MultiAgentReplayBufferSamples(*(th.stack([b[i] for b in batches]) for i in range(5)), None)  # type: ignore[misc]


def seconds(fn: Callable[[], Any]) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def measure(n_runs: int, n_agents: int, batch_size: int, repeats: int) -> dict[str, float]:
    """Median seconds of one update of every run, by each path."""
    generator = th.Generator().manual_seed(0)
    models = [make_model(seed, n_agents, batch_size) for seed in range(n_runs)]
    batches = [random_batch(models[0], batch_size, generator) for _ in range(n_runs)]
    for model, batch in zip(models, batches):
        model.replay_buffer.sample = lambda *args, _batch=batch, **kwargs: _batch  # type: ignore[method-assign]
    stacked = stack(batches)
    group = RunGroup(models)
    compiled = RunGroup(models, compile=True)
    singles = [RunGroup([model]) for model in models]
    paths: dict[str, Callable[[], Any]] = {
        "group": lambda: group.update(stacked),
        "compiled": lambda: compiled.update(stacked),
        "singles": lambda: [single.update(stack([batch])) for single, batch in zip(singles, batches)],
        "maddpg": lambda: [model.train(gradient_steps=1, batch_size=batch_size) for model in models],
    }
    for path in paths.values():  # warm-up: vmap's first call traces, the compiled group compiles
        path()
        path()
    times: dict[str, list[float]] = {name: [] for name in paths}
    for _ in range(repeats):
        for name, path in paths.items():
            times[name].append(seconds(path))
    return {name: statistics.median(values) for name, values in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-agents", type=int, default=5)
    parser.add_argument("--batch-size", type=int, default=1024)
    parser.add_argument("--runs", type=int, nargs="+", default=[1, 4, 16])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    th.set_num_threads(1)
    print(f"N={args.n_agents}, batch {args.batch_size}, 64-unit networks, one torch thread, median of {args.repeats}\n")
    print(
        "| R | group: one update of R runs (ms) | per run (ms) | R x group of one (ms) | R x MADDPG.train (ms) "
        "| speed-up vs group of one | speed-up vs MADDPG.train | compiled group (ms) | compiled vs MADDPG.train |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for n_runs in args.runs:
        t = measure(n_runs, args.n_agents, args.batch_size, args.repeats)
        print(
            f"| {n_runs} | {t['group'] * 1e3:.1f} | {t['group'] / n_runs * 1e3:.1f} | {t['singles'] * 1e3:.1f} "
            f"| {t['maddpg'] * 1e3:.1f} | {t['singles'] / t['group']:.2f}x | {t['maddpg'] / t['group']:.2f}x "
            f"| {t['compiled'] * 1e3:.1f} | {t['maddpg'] / t['compiled']:.2f}x |",
            flush=True,
        )


if __name__ == "__main__":
    main()
