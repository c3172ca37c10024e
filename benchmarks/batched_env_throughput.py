"""
Env step rate of the batched simple_spread (``SimpleSpreadVecEnv``) against mpe2, in the same run.

- ``mpe2``: ``make_simple_spread(n_agents=N)`` (the adapter over mpe2, with its metrics), one env, stepped
  with the flat joint action: the fastest mpe2 gets per core (``DummyVecEnv`` only adds its own loop);
- ``batched E``: ``SimpleSpreadVecEnv(E, n_agents=N)``, E worlds per ``step``, auto-reset and metrics included.

Both use pre-generated random float32 actions in [0, 1]. The variants run interleaved, ``--repeats``
times, and the median of each is reported, in env steps (transitions, all worlds counted) per second of
this process's CPU time, as ``env_throughput.py`` does; ``ratio`` is batched over mpe2.

Usage::

    python benchmarks/batched_env_throughput.py --agents 3 5 --n-envs 1 16 64 256 --out batched_env.md
"""

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from env_throughput import ACTION_SIZE, adapter_runner, command_line, machine_info, write_results


def batched_runner(n_agents: int, n_envs: int, steps: int, seed: int) -> Callable[[], tuple[float, float]]:
    """A timed run of ``steps`` transitions of the batched env (``steps // n_envs`` vectorised steps)."""
    from sb3_maddpg.envs import SimpleSpreadVecEnv

    env = SimpleSpreadVecEnv(n_envs, n_agents=n_agents)
    n_calls = max(1, steps // n_envs)
    rng = np.random.default_rng(seed)
    actions = list(rng.uniform(0.0, 1.0, size=(min(n_calls, 1000), n_envs, n_agents * ACTION_SIZE)).astype(np.float32))

    def run() -> tuple[float, float]:
        env.seed(seed)
        env.reset()
        start, start_cpu = time.perf_counter(), time.process_time()
        for call in range(n_calls):
            env.step(actions[call % len(actions)])
        return time.perf_counter() - start, time.process_time() - start_cpu

    return run


def measure(n_agents: int, n_envs_list: list[int], steps: int, repeats: int, seed: int = 0) -> dict[str, Any]:
    """
    :param n_agents: Team size.
    :param n_envs_list: Worlds per batched env.
    :param steps: Transitions per timed run.
    :param repeats: Timed runs per variant (interleaved).
    :param seed: Seed of actions and resets.
    :return: ``{"n_agents", "median": {variant: steps/s}, "ratio": {variant: median / mpe2}, "runs", "wall_median"}``.
    """
    rng = np.random.default_rng(seed)
    mpe2_steps = min(steps, 20_000)  # mpe2 is ~100x slower: fewer steps give the same precision
    mpe2_actions = rng.uniform(0.0, 1.0, size=(mpe2_steps, n_agents, ACTION_SIZE)).astype(np.float32)
    runners = {"mpe2": (adapter_runner(n_agents, mpe2_actions, seed, metrics=True), mpe2_steps)}
    for n_envs in n_envs_list:
        runners[f"batched {n_envs}"] = (batched_runner(n_agents, n_envs, steps, seed), max(1, steps // n_envs) * n_envs)
    for run, _ in runners.values():  # warm-up
        run()
    runs: dict[str, list[float]] = {name: [] for name in runners}
    wall: dict[str, list[float]] = {name: [] for name in runners}
    for _ in range(repeats):
        for name, (run, count) in runners.items():
            wall_s, cpu_s = run()
            runs[name].append(count / cpu_s)
            wall[name].append(count / wall_s)
    median = {name: statistics.median(rates) for name, rates in runs.items()}
    return {
        "n_agents": n_agents,
        "median": median,
        "ratio": {name: rate / median["mpe2"] for name, rate in median.items()},
        "runs": runs,
        "wall_median": {name: statistics.median(rates) for name, rates in wall.items()},
    }


def markdown_table(results: list[dict[str, Any]]) -> str:
    """One row per team size: mpe2's rate, then each batched size's rate and its ratio to mpe2."""
    names = [name for name in results[0]["median"] if name != "mpe2"]
    header = "| N | mpe2 (steps/s) | " + " | ".join(
        f"{name.replace('batched ', 'batched E=')} (steps/s, ratio)" for name in names
    )
    lines = [header + " |", "|---|---|" + "---|" * len(names)]
    for result in results:
        cells = [f"{result['median'][name]:,.0f} ({result['ratio'][name]:.0f}x)" for name in names]
        lines.append(f"| {result['n_agents']} | {result['median']['mpe2']:,.0f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].strip(), allow_abbrev=False)
    parser.add_argument("--agents", type=int, nargs="+", default=[3, 5], help="team sizes N")
    parser.add_argument("--n-envs", type=int, nargs="+", default=[1, 16, 64, 256], help="worlds per batched env")
    parser.add_argument("--steps", type=int, default=200_000, help="transitions per timed run (mpe2: at most 20,000)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per variant (median reported)")
    parser.add_argument("--out", type=Path, help="write the results: JSON if the name ends in .json, else markdown")
    args = parser.parse_args(argv)

    results = [measure(n, args.n_envs, args.steps, args.repeats) for n in args.agents]
    info = machine_info()
    table = markdown_table(results)
    print(table)
    print(f"\nmedian of {args.repeats}, env steps per CPU-second; " + ", ".join(f"{k} {v}" for k, v in info.items()))
    if args.out is not None:
        write_results(args.out, command_line(argv), info, table, results)


if __name__ == "__main__":
    main()
