"""
Environment step rate: what the gymnasium adapter and the task metrics cost on top of bare mpe2.

Three ways of stepping ``simple_spread`` with the same pre-generated random float32 actions in [0, 1]:

- ``bare``: ``mpe2.simple_spread_v3.parallel_env(N, continuous_actions=True)`` stepped with a dict
  of per-agent actions, reset when ``env.agents`` is empty;
- ``adapter``: ``PettingZooToGym(parallel_env)`` without metrics, stepped with the flat joint action;
- ``adapter+metrics``: ``make_simple_spread(n_agents=N)`` (adapter + ``SimpleSpreadMetrics``).

The variants run interleaved in one process (bare, adapter, adapter+metrics, then again), each
``--repeats`` times, and the median rate is reported, so that drifts of a busy machine hit all three
alike. Resets are part of the timed loop (every 25 steps, the same for all variants).

Usage::

    python benchmarks/env_throughput.py --steps 20000 --repeats 3 --agents 3 5 --out env_rates.md

Reuse from another benchmark (run from the ``benchmarks`` folder or with it on ``sys.path``)::

    from env_throughput import measure_env_rates
    rates = measure_env_rates(n_agents=5, steps=10_000, repeats=3)["median"]  # steps per second
"""

import argparse
import datetime
import json
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

VARIANTS = ("bare", "adapter", "adapter+metrics")
ACTION_SIZE = 5  # simple_spread's continuous action: Box(0, 1, (5,)) per agent


def _bare_runner(n_agents: int, actions: np.ndarray, seed: int) -> Callable[[], tuple[float, float]]:
    from mpe2 import simple_spread_v3

    env = simple_spread_v3.parallel_env(N=n_agents, continuous_actions=True)
    agents = list(env.possible_agents)
    per_agent = [list(step_actions) for step_actions in actions]  # views, split before timing

    def run() -> tuple[float, float]:
        env.reset(seed=seed)
        start, start_cpu = time.perf_counter(), time.process_time()
        for step_actions in per_agent:
            env.step(dict(zip(agents, step_actions, strict=True)))
            if not env.agents:
                env.reset()
        return time.perf_counter() - start, time.process_time() - start_cpu

    return run


def adapter_runner(n_agents: int, actions: np.ndarray, seed: int, metrics: bool) -> Callable[[], tuple[float, float]]:
    from mpe2 import simple_spread_v3

    from sb3_maddpg.envs import PettingZooToGym, make_simple_spread

    if metrics:
        env = make_simple_spread(n_agents=n_agents)
    else:
        env = PettingZooToGym(simple_spread_v3.parallel_env(N=n_agents, continuous_actions=True))
    joint_actions = list(actions.reshape(len(actions), -1))

    def run() -> tuple[float, float]:
        env.reset(seed=seed)
        start, start_cpu = time.perf_counter(), time.process_time()
        for joint_action in joint_actions:
            _, _, terminated, truncated, _ = env.step(joint_action)
            if terminated or truncated:
                env.reset()
        return time.perf_counter() - start, time.process_time() - start_cpu

    return run


def measure_env_rates(n_agents: int, steps: int = 20_000, repeats: int = 3, seed: int = 0) -> dict[str, Any]:
    """
    Measure simple_spread env steps per second: bare mpe2, the adapter, and the adapter with metrics.

    :param n_agents: Number of agents (and landmarks).
    :param steps: Env steps per timed run.
    :param repeats: Timed runs per variant (interleaved); the median is reported.
    :param seed: Seed of the random actions and of the env resets.
    :return: ``{"n_agents", "steps", "repeats", "median": {variant: steps/s},
        "ratio_vs_bare": {variant: median / bare median}, "runs": {variant: [steps/s, ...]},
        "wall_median", "wall_runs"}``. ``median`` and ``runs`` count steps per second of this
        process's CPU time (``time.process_time``), which other processes on a shared machine
        disturb far less than wall-clock time; the ``wall_*`` entries use ``time.perf_counter``.
        Stepping is single-threaded, so on an idle machine the two agree.
    """
    if steps < 1 or repeats < 1:
        raise ValueError(f"steps and repeats must be positive, got steps={steps}, repeats={repeats}.")
    rng = np.random.default_rng(seed)
    actions = rng.uniform(0.0, 1.0, size=(steps, n_agents, ACTION_SIZE)).astype(np.float32)
    runners = {
        "bare": _bare_runner(n_agents, actions, seed),
        "adapter": adapter_runner(n_agents, actions, seed, metrics=False),
        "adapter+metrics": adapter_runner(n_agents, actions, seed, metrics=True),
    }
    # Warm-up: one short pass of each (imports, caches, first allocations).
    warm_up = {
        "bare": _bare_runner(n_agents, actions[:100], seed),
        "adapter": adapter_runner(n_agents, actions[:100], seed, metrics=False),
        "adapter+metrics": adapter_runner(n_agents, actions[:100], seed, metrics=True),
    }
    for run in warm_up.values():
        run()
    runs: dict[str, list[float]] = {variant: [] for variant in VARIANTS}
    wall_runs: dict[str, list[float]] = {variant: [] for variant in VARIANTS}
    for _ in range(repeats):
        for variant in VARIANTS:
            wall, cpu = runners[variant]()
            runs[variant].append(steps / cpu)
            wall_runs[variant].append(steps / wall)
    median = {variant: statistics.median(rates) for variant, rates in runs.items()}
    return {
        "n_agents": n_agents,
        "steps": steps,
        "repeats": repeats,
        "median": median,
        "ratio_vs_bare": {variant: median[variant] / median["bare"] for variant in VARIANTS},
        "runs": runs,
        "wall_median": {variant: statistics.median(rates) for variant, rates in wall_runs.items()},
        "wall_runs": wall_runs,
    }


def machine_info() -> dict[str, str]:
    """The machine and the versions that the rates depend on."""
    cpu_model = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu_model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass

    def version(package: str) -> str:
        try:
            return metadata.version(package)
        except metadata.PackageNotFoundError:
            return "not installed"

    return {
        "nproc": str(len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()),
        "cpu": cpu_model,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "torch": version("torch"),
        "mpe2": version("mpe2"),
        "pettingzoo": version("pettingzoo"),
        "sb3_maddpg": version("sb3_maddpg"),
        "date": datetime.date.today().isoformat(),
    }


def command_line(argv: list[str] | None) -> str:
    """The command that ran this script, for the written results."""
    return "python " + " ".join([Path(sys.argv[0]).as_posix(), *(argv if argv is not None else sys.argv[1:])])


def write_results(out: Path, command: str, info: dict[str, str], table: str, results: list[dict[str, Any]]) -> None:
    """
    Write the results: JSON (command, machine, every figure) if ``out`` ends in .json, else the markdown table.

    :param out: The file.
    :param command: The command that made them.
    :param info: The machine (:func:`machine_info`).
    :param table: The markdown table.
    :param results: Every measurement.
    """
    if out.suffix == ".json":
        out.write_text(json.dumps({"command": command, "machine": info, "results": results}, indent=2) + "\n")
    else:
        machine = ", ".join(f"{key} {value}" for key, value in info.items())
        out.write_text(f"{table}\n\nCommand: `{command}`\n\nMachine: {machine}\n")


def _load_average() -> float:
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")


def markdown_table(results: list[dict[str, Any]]) -> str:
    """A markdown table: median steps per CPU-second per variant, ratio to bare mpe2, and the wall-clock rates."""
    lines = [
        "| N | bare mpe2 (steps/s) | adapter (steps/s, ratio) | adapter + metrics (steps/s, ratio) "
        "| wall-clock steps/s (bare / adapter / +metrics) |",
        "|---|---|---|---|---|",
    ]
    for result in results:
        median, ratio = result["median"], result["ratio_vs_bare"]
        wall = " / ".join(f"{result['wall_median'][variant]:,.0f}" for variant in VARIANTS)
        lines.append(
            f"| {result['n_agents']} | {median['bare']:,.0f} "
            f"| {median['adapter']:,.0f} ({ratio['adapter']:.2f}) "
            f"| {median['adapter+metrics']:,.0f} ({ratio['adapter+metrics']:.2f}) "
            f"| {wall} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].strip(), allow_abbrev=False)
    parser.add_argument("--steps", type=int, default=20_000, help="env steps per timed run")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per variant (median reported)")
    parser.add_argument("--agents", type=int, nargs="+", default=[3, 5], help="team sizes N")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, help="write the results: JSON if the name ends in .json, else markdown")
    args = parser.parse_args(argv)

    load_before = _load_average()
    results = [measure_env_rates(n, steps=args.steps, repeats=args.repeats, seed=args.seed) for n in args.agents]
    info = machine_info()
    # Other processes share the cores: the 1-minute load average says how busy the machine was.
    info["load_avg_1min"] = f"{load_before:.2f} before, {_load_average():.2f} after"
    table = markdown_table(results)
    machine = ", ".join(f"{key} {value}" for key, value in info.items())
    print(table)
    print(f"\n{args.steps} steps x {args.repeats} repeats, median, steps per CPU-second; {machine}")
    if args.out is not None:
        write_results(args.out, command_line(argv), info, table, results)


if __name__ == "__main__":
    main()
