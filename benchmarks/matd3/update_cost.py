"""
The cost of a gradient step of MATD3 against MADDPG's, in the same process, at the paper's configuration (N=5, batch
1024, 64-unit networks, one torch thread).

Both models are built on the same simple_spread team and fill their buffers with the same random transitions; then
``model.train(gradient_steps=K, batch_size=1024)`` calls of the two models are timed in alternation (so a disturbance
on a shared machine hits both), and the figure is the median per gradient step. ``K = 2`` is one MATD3 update round
(``policy_delay`` critic updates and one actor and target update); MATD3 with ``policy_delay=1`` (an actor update
at every critic update) bounds it from above. Times are this process's CPU time (``time.process_time``); the wall-clock
ones are in the JSON too.

Usage::

    python benchmarks/matd3/update_cost.py --agents 5 --repeats 30 --schemes full selected --out benchmarks/matd3/update_cost
"""

import argparse
import json
import platform
import statistics
import time
import warnings
from pathlib import Path
from typing import Any

import torch as th

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import make_simple_spread_vec_env

VARIANTS = {
    "MADDPG": (MADDPG, {}),
    "MATD3": (MATD3, {}),
    "MATD3 (policy_delay=1)": (MATD3, {"policy_delay": 1}),
}


def build(algorithm: type[MADDPG], kwargs: dict[str, Any], n_agents: int, scheme: str, fill: int) -> MADDPG:
    """A model whose buffer holds ``fill`` random transitions (uniform actions: ``learning_starts`` is beyond them)."""
    env = make_simple_spread_vec_env(n_envs=100, n_agents=n_agents)
    extra = {"selector": 2} if scheme == "selected" else {}
    model = algorithm("MlpPolicy", env, critic_sharing=scheme, learning_starts=10 * fill, seed=0, **extra, **kwargs)
    with warnings.catch_warnings():  # "learn() ended without a single gradient update": only the buffer is wanted
        warnings.simplefilter("ignore", UserWarning)
        model.learn(fill, log_interval=10**9)
    return model


def measure(n_agents: int, scheme: str, repeats: int, steps: int, fill: int) -> dict[str, Any]:
    models = {name: build(cls, kwargs, n_agents, scheme, fill) for name, (cls, kwargs) in VARIANTS.items()}
    cpu: dict[str, list[float]] = {name: [] for name in models}
    wall: dict[str, list[float]] = {name: [] for name in models}
    for repeat in range(repeats + 2):  # two warm-up rounds
        for name, model in models.items():
            wall_start, cpu_start = time.perf_counter(), time.process_time()
            model.train(gradient_steps=steps, batch_size=model.batch_size)
            if repeat >= 2:
                cpu[name].append((time.process_time() - cpu_start) / steps * 1e3)
                wall[name].append((time.perf_counter() - wall_start) / steps * 1e3)
    result: dict[str, Any] = {"n_agents": n_agents, "scheme": scheme, "gradient_steps_per_call": steps, "repeats": repeats}
    for name in models:
        result[name] = {"cpu_ms": statistics.median(cpu[name]), "wall_ms": statistics.median(wall[name])}
    base = result["MADDPG"]["cpu_ms"]
    result["ratio"] = {name: result[name]["cpu_ms"] / base for name in models}
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--agents", type=int, nargs="+", default=[5])
    parser.add_argument("--schemes", nargs="+", default=["full", "selected"])
    parser.add_argument("--repeats", type=int, default=30, help="timed train() calls per model")
    parser.add_argument("--steps", type=int, default=2, help="gradient steps per train() call (2: one MATD3 round)")
    parser.add_argument("--fill", type=int, default=5_000, help="random transitions in each buffer")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--out", default=None, help="write <out>.json and <out>.md")
    args = parser.parse_args()
    th.set_num_threads(args.threads)
    rows = [measure(n, scheme, args.repeats, args.steps, args.fill) for n in args.agents for scheme in args.schemes]
    lines = [
        f"Per gradient step, batch 1024, {args.threads} torch thread(s), median of {args.repeats} train(gradient_steps="
        f"{args.steps}) calls, CPU ms (ratio to MADDPG); torch {th.__version__}, {platform.processor() or platform.machine()}",
        "",
        "| N | scheme | " + " | ".join(VARIANTS) + " |",
        "|---|---|" + "---|" * len(VARIANTS),
    ]
    for row in rows:
        cells = [f"{row[name]['cpu_ms']:.1f} ({row['ratio'][name]:.2f}x)" for name in VARIANTS]
        lines.append(f"| {row['n_agents']} | {row['scheme']} | " + " | ".join(cells) + " |")
    table = "\n".join(lines)
    print(table)
    if args.out:
        Path(f"{args.out}.json").write_text(json.dumps({"threads": args.threads, "rows": rows}, indent=2))
        Path(f"{args.out}.md").write_text(table + "\n")


if __name__ == "__main__":
    main()
