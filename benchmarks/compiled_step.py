"""
A run group compiled (``RunGroup(..., compile=True)``: each part of a round one graph, ``torch.compile(fullgraph=True)``)
against the same group eager, in the same process, on the CPU.

Two sizes: tiny networks (4 units, batch 2, 2 worlds per run), where the kernels cost almost nothing and what is left
is the host's work per op (what a GPU waits on), and the paper's (64-unit networks, batch 1024, 100 worlds per run).
For each number of runs R, both groups take the same batches, interleaved, after warm-up; the ratios are of the
medians (> 1: compiled is faster). Two measures: a gradient step on a given batch, and a round (one env step of every
run's worlds, its transitions stored, then one gradient step on a batch drawn from the buffers: the paper's ratio with
100 worlds per run). Also the compile time (every part's first calls) and MATD3's at one size.

    python benchmarks/compiled_step.py --sizes tiny paper --runs 1 31 --repeats 30
"""

import argparse
import statistics
import time
from typing import Any

import torch as th

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.run_group import RunGroup

SIZES: dict[str, dict[str, Any]] = {
    "tiny": {"net_arch": [4], "batch_size": 2, "worlds": 2},
    "paper": {"net_arch": [64, 64], "batch_size": 1024, "worlds": 100},
}


def make_group(algorithm: type[MADDPG], n_runs: int, n_agents: int, size: str, compile: bool) -> RunGroup:
    settings = SIZES[size]
    models = [
        algorithm(
            "MlpPolicy",
            SimpleSpreadVecEnv(1, n_agents=n_agents),
            seed=seed,
            batch_size=settings["batch_size"],
            buffer_size=20 * settings["worlds"],
            learning_starts=0,
            max_grad_norm=0.5,
            policy_kwargs={"net_arch": settings["net_arch"]},
        )
        for seed in range(n_runs)
    ]
    return RunGroup(models, worlds_per_run=settings["worlds"], compile=compile)


def random_batches(group: RunGroup, count: int) -> list[Any]:
    """``count`` batches of every run, ``[R, batch, ...]`` each field."""
    from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples

    generator = th.Generator().manual_seed(0)
    layout, r, b = group.layout, group.n_runs, group.batch_size

    def normal(*shape: int) -> th.Tensor:
        return th.randn(*shape, generator=generator)

    return [
        MultiAgentReplayBufferSamples(
            normal(r, b, layout.obs_dim),
            normal(r, b, layout.action_dim).clamp(-1, 1),
            normal(r, b, layout.obs_dim),
            th.zeros(r, b, layout.n_agents),
            normal(r, b, layout.n_agents),
            None,
        )
        for _ in range(count)
    ]


def median_seconds(groups: dict[str, RunGroup], work: Any, repeats: int) -> dict[str, float]:
    """Median seconds of ``work(group)`` for each group, interleaved, after a warm-up (which compiles)."""
    times: dict[str, list[float]] = {name: [] for name in groups}
    for i in range(-4, repeats):
        for name, group in groups.items():
            start = time.perf_counter()
            work(group, i)
            if i >= 0:
                times[name].append(time.perf_counter() - start)
    return {name: statistics.median(values) for name, values in times.items()}


def measure(algorithm: type[MADDPG], n_runs: int, n_agents: int, size: str, repeats: int) -> dict[str, float]:
    """Median seconds per gradient step and per round, eager and compiled, and the compile time."""
    groups = {name: make_group(algorithm, n_runs, n_agents, size, name == "compiled") for name in ("eager", "compiled")}
    batches = random_batches(groups["eager"], 4)
    step = median_seconds(groups, lambda group, i: group._step(batches[i % len(batches)]), repeats)

    def one_round(group: RunGroup, i: int) -> None:
        group.collect_step()
        group.train(1)

    for group in groups.values():  # the buffers hold a few steps of each run before the rounds are timed
        for _ in range(4):
            group.collect_step()
    rounds = median_seconds(groups, one_round, repeats)
    return {
        **{f"step_{name}": value for name, value in step.items()},
        **{f"round_{name}": value for name, value in rounds.items()},
        "compile_s": groups["compiled"].compile_seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", default=["tiny", "paper"], choices=sorted(SIZES))
    parser.add_argument("--runs", nargs="+", type=int, default=[1, 31])
    parser.add_argument("--n-agents", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--matd3", action="store_true", help="also MATD3 at the first size and R")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (1: one core, as a sweep worker)")
    args = parser.parse_args()
    th.set_num_threads(args.threads)
    print(f"torch {th.__version__}, {args.threads} thread(s), N={args.n_agents}, median of {args.repeats} steps")
    print(
        "| algorithm | size | R | step: eager ms | compiled ms | eager / compiled "
        "| round: eager ms | compiled ms | eager / compiled | compile s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    cases = [(MADDPG, size, runs) for size in args.sizes for runs in args.runs]
    if args.matd3:
        cases.append((MATD3, args.sizes[0], args.runs[0]))
    for algorithm, size, runs in cases:
        result = measure(algorithm, runs, args.n_agents, size, args.repeats)
        cells = [algorithm.__name__, size, str(runs)]
        for part in ("step", "round"):
            eager, compiled = result[f"{part}_eager"], result[f"{part}_compiled"]
            cells += [f"{eager * 1e3:.2f}", f"{compiled * 1e3:.2f}", f"{eager / compiled:.2f}x"]
        print("| " + " | ".join([*cells, f"{result['compile_s']:.0f}"]) + " |", flush=True)
        th._dynamo.reset()


if __name__ == "__main__":
    main()
