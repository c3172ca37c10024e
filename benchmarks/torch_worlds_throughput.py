"""
Step rate of simple_spread's worlds in torch on the CPU (``TorchSpreadWorlds``) against the numpy worlds, in the same run.

Each variant steps E worlds of N agents with pre-generated random float32 actions in [0, 1] and computes what a
trainer reads after every step: observations, per-agent rewards and the task metrics; every 25 steps
(``max_cycles``) all worlds start new episodes.

- ``numpy``: ``SimpleSpreadWorlds`` (float64), each world's new episode drawn from its own numpy generator as
  ``SimpleSpreadVecEnv`` draws them;
- ``torch float64`` / ``torch float32``: ``TorchSpreadWorlds`` on the CPU, new episodes from one ``torch.Generator``;
- ``numpy VecEnv``: ``SimpleSpreadVecEnv`` itself (the numpy worlds plus its per-world ``info`` dicts), for scale.

The variants run interleaved, ``--repeats`` times, and the median of each is reported, in env steps
(transitions, all worlds counted) per second of this process's CPU time (torch with ``--threads`` threads,
one by default, as the package's entry points use); ``ratio`` is over ``numpy``.

Usage::

    python benchmarks/torch_worlds_throughput.py --agents 5 --n-envs 100 1000 --out torch_worlds.md
"""

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch as th

sys.path.insert(0, str(Path(__file__).resolve().parent))

from env_throughput import command_line, machine_info, write_results

MAX_CYCLES = 25
"""Steps per episode (the paper's)."""
ACTION_SIZE = 5


def numpy_runner(n_agents: int, n_envs: int, calls: int, actions: np.ndarray, seed: int) -> Callable[[], tuple[float, float]]:
    """``calls`` steps of the numpy worlds, with observations, rewards, metrics and a reset every 25 steps."""
    from sb3_maddpg.envs.simple_spread import CAPTURE_RADIUS
    from sb3_maddpg.envs.simple_spread_worlds import SimpleSpreadWorlds

    worlds = SimpleSpreadWorlds(n_envs, n_agents)
    generators = [np.random.default_rng(seed + world) for world in range(n_envs)]

    def reset() -> None:
        for world, generator in enumerate(generators):
            worlds.reset_world(world, generator)

    def run() -> tuple[float, float]:
        reset()
        start, start_cpu = time.perf_counter(), time.process_time()
        for call in range(calls):
            distances = worlds.step(actions[call % len(actions)])
            worlds.observations(distances), worlds.rewards(distances), worlds.metrics(distances, CAPTURE_RADIUS)
            if (call + 1) % MAX_CYCLES == 0:
                reset()
        return time.perf_counter() - start, time.process_time() - start_cpu

    return run


def torch_runner(
    n_agents: int, n_envs: int, calls: int, actions: np.ndarray, seed: int, dtype: th.dtype
) -> Callable[[], tuple[float, float]]:
    """``calls`` steps of the torch worlds on the CPU, the same work as :func:`numpy_runner`."""
    from sb3_maddpg.envs.simple_spread import CAPTURE_RADIUS
    from sb3_maddpg.envs.torch_spread_worlds import TorchSpreadWorlds

    worlds = TorchSpreadWorlds(n_envs, n_agents, dtype=dtype)
    generator = th.Generator().manual_seed(seed)
    torch_actions = [th.from_numpy(step_actions) for step_actions in actions]

    def run() -> tuple[float, float]:
        worlds.reset(generator)
        start, start_cpu = time.perf_counter(), time.process_time()
        for call in range(calls):
            distances = worlds.step(torch_actions[call % len(torch_actions)])
            worlds.observations(distances), worlds.rewards(distances), worlds.metrics(distances, CAPTURE_RADIUS)
            if (call + 1) % MAX_CYCLES == 0:
                worlds.reset(generator)
        return time.perf_counter() - start, time.process_time() - start_cpu

    return run


def vec_env_runner(
    n_agents: int, n_envs: int, calls: int, actions: np.ndarray, seed: int
) -> Callable[[], tuple[float, float]]:
    """``calls`` steps of ``SimpleSpreadVecEnv`` (auto-reset every 25 steps, infos included)."""
    from sb3_maddpg.envs import SimpleSpreadVecEnv

    env = SimpleSpreadVecEnv(n_envs, n_agents=n_agents)
    flat_actions = [step_actions.reshape(n_envs, -1) for step_actions in actions]

    def run() -> tuple[float, float]:
        env.seed(seed)
        env.reset()
        start, start_cpu = time.perf_counter(), time.process_time()
        for call in range(calls):
            env.step(flat_actions[call % len(flat_actions)])
        return time.perf_counter() - start, time.process_time() - start_cpu

    return run


def measure(n_agents: int, n_envs: int, steps: int, repeats: int, seed: int = 0) -> dict[str, Any]:
    """
    :param n_agents: Team size.
    :param n_envs: Worlds.
    :param steps: Transitions per timed run (``steps // n_envs`` steps of all worlds, a multiple of 25).
    :param repeats: Timed runs per variant (interleaved).
    :param seed: Seed of actions and resets.
    :return: ``{"n_agents", "n_envs", "median": {variant: steps/s}, "ratio": {variant: median / numpy}, "runs",
        "wall_median"}``.
    """
    calls = max(MAX_CYCLES, steps // n_envs // MAX_CYCLES * MAX_CYCLES)
    rng = np.random.default_rng(seed)
    actions = rng.uniform(0.0, 1.0, size=(min(calls, 100), n_envs, n_agents, ACTION_SIZE)).astype(np.float32)
    runners = {
        "numpy": numpy_runner(n_agents, n_envs, calls, actions, seed),
        "torch float64": torch_runner(n_agents, n_envs, calls, actions, seed, th.float64),
        "torch float32": torch_runner(n_agents, n_envs, calls, actions, seed, th.float32),
        "numpy VecEnv": vec_env_runner(n_agents, n_envs, calls, actions, seed),
    }
    for run in runners.values():  # warm-up
        run()
    runs: dict[str, list[float]] = {name: [] for name in runners}
    wall: dict[str, list[float]] = {name: [] for name in runners}
    for _ in range(repeats):
        for name, run in runners.items():
            wall_s, cpu_s = run()
            runs[name].append(calls * n_envs / cpu_s)
            wall[name].append(calls * n_envs / wall_s)
    median = {name: statistics.median(rates) for name, rates in runs.items()}
    return {
        "n_agents": n_agents,
        "n_envs": n_envs,
        "median": median,
        "ratio": {name: rate / median["numpy"] for name, rate in median.items()},
        "runs": runs,
        "wall_median": {name: statistics.median(rates) for name, rates in wall.items()},
    }


def markdown_table(results: list[dict[str, Any]]) -> str:
    """One row per (N, E): the numpy worlds' rate, then each other variant's rate and its ratio to numpy."""
    names = [name for name in results[0]["median"] if name != "numpy"]
    header = "| N | E | numpy worlds (steps/s) | " + " | ".join(f"{name} (steps/s, ratio)" for name in names) + " |"
    lines = [header, "|---|---|---|" + "---|" * len(names)]
    for result in results:
        cells = [f"{result['median'][name]:,.0f} ({result['ratio'][name]:.2f}x)" for name in names]
        lines.append(
            f"| {result['n_agents']} | {result['n_envs']} | {result['median']['numpy']:,.0f} | " + " | ".join(cells) + " |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.strip().split("\n\n")[0], allow_abbrev=False)
    parser.add_argument("--agents", type=int, nargs="+", default=[5], help="team sizes N")
    parser.add_argument("--n-envs", type=int, nargs="+", default=[100, 1000], help="worlds E")
    parser.add_argument("--steps", type=int, default=200_000, help="transitions per timed run")
    parser.add_argument("--repeats", type=int, default=5, help="timed runs per variant (median reported)")
    parser.add_argument("--threads", type=int, default=1, help="torch's CPU threads")
    parser.add_argument("--out", type=Path, help="write the results: JSON if the name ends in .json, else markdown")
    args = parser.parse_args(argv)

    th.set_num_threads(args.threads)
    results = [measure(n, e, args.steps, args.repeats) for n in args.agents for e in args.n_envs]
    info = {**machine_info(), "torch threads": str(th.get_num_threads())}
    table = markdown_table(results)
    print(table)
    print(f"\nmedian of {args.repeats}, env steps per CPU-second; " + ", ".join(f"{k} {v}" for k, v in info.items()))
    if args.out is not None:
        write_results(args.out, command_line(argv), info, table, results)


if __name__ == "__main__":
    main()
