"""Issue 20's device measurement: env steps per second summed over R runs trained in one run group, at N=5.

For each R: R MADDPG runs (the paper's hyperparameters, 100 simple_spread worlds each, ``learning_starts`` past, so
every round trains) in one :class:`~sb3_maddpg.run_group.RunGroup` on ``--device``; after a warm-up, ``--steps`` env
steps of each run are timed (``learn``, with its update ratio of one gradient step per 100 transitions), and one
update round alone. Prints a markdown table: steps/s summed over the runs, per run, the update's time, the device's
peak memory, and the wall time exp1 + exp2 (310 runs: 155 x 2.5M + 155 x 3.75M steps) would take at that rate.

Each R in each ``--modes``: ``eager`` (op by op), ``compiled`` (each part of a round one graph, inductor's default
mode: ``RunGroup(compile="default")``) and ``captured`` (``compile=True``: on CUDA the gradient step replayed as CUDA
graphs); the compile time (in the warm-up, not timed) is a column.

Run on a GPU: ``python benchmarks/run_group_device.py --device cuda --runs 1 10 31 155``. On a CPU (to check the
script): ``python benchmarks/run_group_device.py --device cpu --runs 1 2 --steps 2000 --modes eager compiled``.
"""

import argparse
import time

import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.run_group import RunGroup
from sb3_maddpg.run_group.buffer import buffer_capacity, replay_nbytes

PROTOCOL_STEPS = 155 * 2_500_000 + 155 * 3_750_000
"""Env steps of the paper's two experiments: 5 schemes x 31 seeds each, 100,000 and 150,000 episodes of 25 steps."""


def synchronize(device: th.device) -> None:
    """Wait for the device's queued work, so that a timer reads what it did."""
    if device.type == "cuda":
        th.cuda.synchronize(device)


def buffer_bytes(n_agents: int, buffer_size: int, worlds: int) -> int:
    """:return: One run's replay buffer on the device, as :meth:`~sb3_maddpg.run_group.RunReplayBuffers.nbytes` counts
    it (next observations kept as the following step's rows: see :mod:`sb3_maddpg.run_group.buffer`)."""
    layout = SimpleSpreadVecEnv(1, n_agents=n_agents).agent_layout
    capacity = buffer_capacity(buffer_size, worlds)
    return replay_nbytes(1, capacity, layout.obs_dim, layout.action_dim, n_agents, worlds, episode_length=25)


MODES: dict[str, bool | str] = {"eager": False, "compiled": "default", "captured": True}
"""``RunGroup``'s ``compile`` of each mode."""


def build_group(
    n_runs: int, n_agents: int, worlds: int, buffer_size: int, device: th.device, compile: bool | str = False
) -> RunGroup:
    """:return: A group of ``n_runs`` runs past ``learning_starts`` (its buffers hold that many steps)."""
    models = [
        MADDPG(
            "MlpPolicy",
            SimpleSpreadVecEnv(worlds, n_agents=n_agents),
            learning_starts=2_000,
            buffer_size=buffer_size,
            seed=seed,
        )
        for seed in range(n_runs)
    ]
    th._dynamo.reset()  # the last group's graphs
    group = RunGroup(models, device=device, compile=compile)
    group.learn(4_000)  # fills the buffers past learning_starts and trains a few rounds (the warm-up)
    return group


def measure(
    n_runs: int, n_agents: int, worlds: int, steps: int, buffer_size: int, device: th.device, compile: bool | str = False
) -> dict[str, float]:
    """:return: One row of the table for ``n_runs`` runs."""
    if device.type == "cuda":
        th.cuda.reset_peak_memory_stats(device)
    group = build_group(n_runs, n_agents, worlds, buffer_size, device, compile)
    synchronize(device)
    started = time.perf_counter()
    group.learn(steps)
    synchronize(device)
    learn_seconds = time.perf_counter() - started
    started = time.perf_counter()
    group.train(1)
    synchronize(device)
    update_ms = (time.perf_counter() - started) * 1e3
    summed = n_runs * steps / learn_seconds
    peak_gb = th.cuda.max_memory_allocated(device) / 1e9 if device.type == "cuda" else float("nan")
    return {
        "summed": summed,
        "per_run": summed / n_runs,
        "update_ms": update_ms,
        "peak_gb": peak_gb,
        "compile_s": group.compile_seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="cuda" if th.cuda.is_available() else "cpu")
    parser.add_argument("--runs", type=int, nargs="+", default=[1, 10, 31, 155])
    parser.add_argument("--n-agents", type=int, default=5)
    parser.add_argument("--worlds", type=int, default=100, help="simple_spread worlds per run")
    parser.add_argument("--steps", type=int, default=20_000, help="timed env steps of each run")
    parser.add_argument("--buffer-size", type=int, default=1_000_000, help="each run's replay buffer (the paper's 1M)")
    parser.add_argument("--modes", nargs="+", default=["eager"], choices=list(MODES), help="eager, compiled, captured")
    args = parser.parse_args()
    th.set_num_threads(1)
    device = th.device(args.device)
    print(f"device {device}, N={args.n_agents}, {args.worlds} worlds per run, {args.steps:,} timed steps per run")
    print(
        "| R | mode | env steps/s, summed | per run | one update round (ms) | peak device memory (GB) | compile s "
        "| exp1 + exp2 at this rate |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for n_runs, mode in ((n_runs, mode) for n_runs in args.runs for mode in args.modes):
        needed = n_runs * buffer_bytes(args.n_agents, args.buffer_size, args.worlds)
        if device.type == "cuda":
            th.cuda.empty_cache()  # the last R's blocks, cached by the allocator, are free for this R
        if device.type == "cuda" and needed > th.cuda.mem_get_info(device)[0]:
            # The buffers alone do not fit: the protocol then runs in smaller groups (--runs-per-process).
            print(f"| {n_runs} | {mode} | does not fit: {needed / 1e9:.0f} GB of replay buffers | | | | | |", flush=True)
            continue
        row = measure(n_runs, args.n_agents, args.worlds, args.steps, args.buffer_size, device, MODES[mode])
        hours = PROTOCOL_STEPS / row["summed"] / 3600
        print(
            f"| {n_runs} | {mode} | {row['summed']:,.0f} | {row['per_run']:,.0f} | {row['update_ms']:.1f} | "
            f"{row['peak_gb']:.2f} | {row['compile_s']:.0f} | {hours:.1f} h |",
            flush=True,
        )


if __name__ == "__main__":
    main()
