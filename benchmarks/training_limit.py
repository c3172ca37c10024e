"""
Training rate at the paper's configuration against its update-bound limit, on the batched env and on mpe2.

For each team size N, scheme and env (``SimpleSpreadVecEnv`` with E worlds, or ``DummyVecEnv`` over mpe2 with
one env, the 0.1 path), in a fresh process, with MADDPG's defaults (batch 1024, one gradient step per 100
transitions whatever E is, 64-unit networks, a buffer of 1e6) and one torch thread:

- ``train steps/s``: transitions per second of ``learn()`` (the buffer first holds ``learning_starts = 1024``
  random transitions; then ``--steps`` transitions are timed, updates included);
- ``update ms``: one update round, ``model.train(gradient_steps=1, batch_size=1024)``, median of ``--updates``
  calls after 3 warm-up calls, in the same process;
- ``limit``: the update-bound rate, ``100 / update round`` transitions per second (what training would reach
  if collecting transitions cost nothing); ``of limit``: train steps/s divided by it;
- ``peak RSS MiB``: the process's peak resident memory; ``buffer GiB``: what the 1e6-transition replay buffer
  holds once full (the OS gives its pages as rows are written).

Times count this process's CPU time (``time.process_time``), as the other benchmarks here do; the JSON also
holds the wall-clock figures. The last column compares each row with mpe2's row of the same N and scheme.

Usage::

    python benchmarks/training_limit.py --agents 3 5 --schemes full selected --n-envs 1 16 100 256 --out training_limit
"""

import argparse
import json
import multiprocessing
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from env_throughput import command_line, machine_info, write_results
from throughput import _peak_rss_mib

LEARNING_STARTS = 1024
"""One batch of random transitions before timing starts (the paper's 25,600 would only delay it)."""


def measure(n_agents: int, scheme: str, vec_env: str, n_envs: int, steps: int, updates: int, seed: int) -> dict[str, Any]:
    """
    One configuration in the current process (call it in a fresh one, for a clean peak memory).

    :param n_agents: Team size.
    :param scheme: Sharing scheme.
    :param vec_env: ``"batched"`` or ``"mpe2"``.
    :param n_envs: Worlds.
    :param steps: Transitions of ``learn()`` to time.
    :param updates: Update rounds to time.
    :param seed: Seed.
    :return: The measurements.
    """
    import torch as th
    from stable_baselines3.common.vec_env import DummyVecEnv

    from sb3_maddpg import MADDPG
    from sb3_maddpg.envs import SimpleSpreadVecEnv, make_simple_spread

    th.set_num_threads(1)
    if vec_env == "batched":
        env: Any = SimpleSpreadVecEnv(n_envs, n_agents=n_agents)
    else:
        env = DummyVecEnv([lambda: make_simple_spread(n_agents=n_agents) for _ in range(n_envs)])
    model = MADDPG("MlpPolicy", env, critic_sharing=scheme, seed=seed, learning_starts=LEARNING_STARTS)
    model.learn(total_timesteps=LEARNING_STARTS)
    start, start_cpu, start_updates = time.perf_counter(), time.process_time(), model._n_updates
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    cpu, wall = time.process_time() - start_cpu, time.perf_counter() - start
    collected = model.num_timesteps - LEARNING_STARTS
    result: dict[str, Any] = {
        "n_agents": n_agents,
        "scheme": scheme,
        "vec_env": vec_env,
        "n_envs": n_envs,
        "timed_transitions": collected,
        "timed_updates": model._n_updates - start_updates,
        "train_steps_per_s": collected / cpu,
        "wall_train_steps_per_s": collected / wall,
    }
    for _ in range(3):
        model.train(gradient_steps=1, batch_size=model.batch_size)
    times, wall_times = [], []
    for _ in range(updates):
        start, start_cpu = time.perf_counter(), time.process_time()
        model.train(gradient_steps=1, batch_size=model.batch_size)
        times.append(time.process_time() - start_cpu)
        wall_times.append(time.perf_counter() - start)
    update_s, wall_update_s = statistics.median(times), statistics.median(wall_times)
    result.update(
        update_ms=1e3 * update_s,
        limit_steps_per_s=model.transitions_per_update / update_s,
        of_limit=result["train_steps_per_s"] * update_s / model.transitions_per_update,
        wall_of_limit=result["wall_train_steps_per_s"] * wall_update_s / model.transitions_per_update,
        peak_rss_mib=_peak_rss_mib(),
        buffer_gib=model.replay_buffer.nbytes() / 2**30,
    )
    env.close()
    return result


def _in_fresh_process(kwargs: dict[str, Any]) -> dict[str, Any]:
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        return pool.apply(measure, kwds=kwargs)


def markdown_table(results: list[dict[str, Any]]) -> str:
    """One row per configuration; the last column is the rate over mpe2's (same N and scheme)."""
    mpe2 = {(row["n_agents"], row["scheme"]): row["train_steps_per_s"] for row in results if row["vec_env"] == "mpe2"}
    lines = [
        "| N | scheme | env | E | train steps/s | update ms | limit (steps/s) | of limit | peak RSS MiB | buffer GiB "
        "| vs mpe2 |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in results:
        reference = mpe2.get((row["n_agents"], row["scheme"]))
        versus = f"{row['train_steps_per_s'] / reference:.1f}x" if reference else ""
        lines.append(
            f"| {row['n_agents']} | {row['scheme']} | {row['vec_env']} | {row['n_envs']} | {row['train_steps_per_s']:,.0f} "
            f"| {row['update_ms']:.1f} | {row['limit_steps_per_s']:,.0f} | {row['of_limit']:.2f} "
            f"| {row['peak_rss_mib']:,.0f} | {row['buffer_gib']:.2f} | {versus} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].strip(), allow_abbrev=False)
    parser.add_argument("--agents", type=int, nargs="+", default=[3, 5], help="team sizes N")
    parser.add_argument("--schemes", nargs="+", default=["full", "selected"])
    parser.add_argument("--n-envs", type=int, nargs="+", default=[1, 16, 100, 256], help="worlds of the batched env")
    parser.add_argument("--mpe2-n-envs", type=int, default=1, help="envs of the mpe2 path (0: leave it out)")
    parser.add_argument("--steps", type=int, default=30_000, help="transitions of learn() timed per configuration")
    parser.add_argument("--updates", type=int, default=20, help="update rounds timed per configuration")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, help="write OUT.json and OUT.md")
    args = parser.parse_args(argv)

    load_before = os.getloadavg()[0]
    envs = [("mpe2", args.mpe2_n_envs)] if args.mpe2_n_envs > 0 else []
    envs += [("batched", n_envs) for n_envs in args.n_envs]
    results = []
    for n_agents in args.agents:
        for scheme in args.schemes:
            for vec_env, n_envs in envs:
                kwargs = dict(
                    n_agents=n_agents, scheme=scheme, vec_env=vec_env, n_envs=n_envs, steps=args.steps, updates=args.updates
                )
                row = _in_fresh_process({**kwargs, "seed": args.seed})
                results.append(row)
                print(json.dumps(row), file=sys.stderr, flush=True)

    info = machine_info()
    info["load_avg_1min"] = f"{load_before:.2f} before, {os.getloadavg()[0]:.2f} after"
    table = markdown_table(results)
    print(table)
    machine = ", ".join(f"{key} {value}" for key, value in info.items())
    print(f"\n{args.steps} timed transitions, {args.updates} timed updates, one torch thread; {machine}")
    if args.out is not None:
        for suffix in (".json", ".md"):
            write_results(args.out.with_suffix(suffix), command_line(argv), info, table, results)


if __name__ == "__main__":
    main()
