"""
Training throughput: how fast MADDPG learns on simple_spread, against the bare rate of the env it drives.

For every team size N and sharing scheme, at the paper's configuration (MADDPG's defaults: batch 1024,
an update every 100 env steps, one gradient step, 64-unit networks, buffer of 1e6), in a fresh process:

- ``train steps/s``: env steps per second of ``learn()`` past ``learning_starts`` (the buffer is first
  filled with ``learning_starts = batch_size`` random steps, then ``--steps`` steps are timed with
  ``reset_num_timesteps=False``; they include the updates, one per 100 steps);
- ``update ms``: time of one update round, ``model.train(gradient_steps=1, batch_size=1024)``, median of
  ``--updates`` calls after 3 warm-up calls;
- ``rollout ms``: time of one rollout step, ``model._sample_action`` (actors + noise) plus ``env.step``,
  mean over ``--rollout-steps`` steps;
- ``peak RSS MiB``: the process's peak resident memory (``resource.getrusage``) at the end, which
  includes the Python, torch and mpe2 baseline (see the ``baseline`` row).

Rates and times count this process's CPU time (``time.process_time``), as ``env_throughput.py`` does, so
that other processes on a shared machine disturb them less; with ``--threads 1`` on an idle machine CPU
and wall-clock time agree. The JSON also holds the wall-clock figures (``wall_*``) and the table their ratio.

In the same run, ``adapter steps/s`` is the bare rate of the adapter over mpe2 with random float32
actions (``make_simple_spread``, the env that training drives; measured by ``env_throughput.py``'s
``measure_env_rates``, variant ``adapter+metrics``), and ``ratio = train steps/s / adapter steps/s``
(target >= 0.6 with one env).

Usage::

    python benchmarks/throughput.py --agents 3 5 --steps 10000 --threads 1 --out throughput
    # writes throughput.json and throughput.md; --schemes full selected for a subset
"""

import argparse
import json
import multiprocessing
import os
import resource
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from env_throughput import machine_info, measure_env_rates

SCHEMES = ("independent", "full", "observations", "actions", "selected")
PAPER_CONFIG = dict(batch_size=1024, train_freq=100, gradient_steps=1, learning_starts=1024, buffer_size=1_000_000)
"""MADDPG's defaults (Lowe et al.) except learning_starts, set to one batch so that timing starts early."""


def _peak_rss_mib() -> float:
    # Linux reports kilobytes, macOS bytes.
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024 * 1024) if sys.platform == "darwin" else peak / 1024


def measure_config(
    n_agents: int, scheme: str | None, steps: int, updates: int, rollout_steps: int, threads: int, n_envs: int, seed: int
) -> dict[str, Any]:
    """
    Measure one configuration in the current process (call it in a fresh process for a clean peak memory).

    :param n_agents: Team size.
    :param scheme: Sharing scheme, or None for the baseline (imports and env only, for the memory floor).
    :param steps: Env steps of ``learn()`` to time, past ``learning_starts``.
    :param updates: Update rounds to time.
    :param rollout_steps: Rollout steps to time.
    :param threads: ``torch.set_num_threads``.
    :param n_envs: Number of envs (DummyVecEnv).
    :param seed: Seed.
    :return: The measurements.
    """
    import torch as th
    from stable_baselines3.common.env_util import make_vec_env

    from sb3_maddpg import MADDPG
    from sb3_maddpg.envs import make_simple_spread

    th.set_num_threads(threads)
    env = make_vec_env(make_simple_spread, n_envs=n_envs, seed=seed, env_kwargs=dict(n_agents=n_agents))
    result: dict[str, Any] = {"n_agents": n_agents, "scheme": scheme or "baseline", "threads": threads, "n_envs": n_envs}
    if scheme is None:
        env.reset()
        result["peak_rss_mib"] = _peak_rss_mib()
        return result

    model = MADDPG("MlpPolicy", env, critic_sharing=scheme, seed=seed, **PAPER_CONFIG)  # nets: 64 units (default)
    model.learn(total_timesteps=PAPER_CONFIG["learning_starts"])  # fill the buffer with random steps

    start, start_cpu = time.perf_counter(), time.process_time()
    model.learn(total_timesteps=steps, reset_num_timesteps=False)
    result["train_steps_per_s"] = steps / (time.process_time() - start_cpu)
    result["wall_train_steps_per_s"] = steps / (time.perf_counter() - start)

    batch_size = PAPER_CONFIG["batch_size"]
    for _ in range(3):
        model.train(gradient_steps=1, batch_size=batch_size)
    times, wall_times = [], []
    for _ in range(updates):
        start, start_cpu = time.perf_counter(), time.process_time()
        model.train(gradient_steps=1, batch_size=batch_size)
        times.append(time.process_time() - start_cpu)
        wall_times.append(time.perf_counter() - start)
    result["update_ms"] = 1e3 * statistics.median(times)
    result["wall_update_ms"] = 1e3 * statistics.median(wall_times)

    model.policy.set_training_mode(False)
    start, start_cpu = time.perf_counter(), time.process_time()
    for _ in range(rollout_steps):
        action, _ = model._sample_action(model.learning_starts, model.action_noise, env.num_envs)
        model._last_obs, _, _, _ = env.step(action)
    result["rollout_ms"] = 1e3 * (time.process_time() - start_cpu) / rollout_steps
    result["wall_rollout_ms"] = 1e3 * (time.perf_counter() - start) / rollout_steps
    result["peak_rss_mib"] = _peak_rss_mib()
    env.close()
    return result


def _in_fresh_process(kwargs: dict[str, Any]) -> dict[str, Any]:
    context = multiprocessing.get_context("spawn")
    with context.Pool(1) as pool:
        return pool.apply(measure_config, kwds=kwargs)


def markdown_table(results: list[dict[str, Any]]) -> str:
    """One row per (N, scheme); the baseline rows give the memory floor."""
    lines = [
        "| N | scheme | train steps/s | adapter steps/s | ratio | update ms | rollout ms | peak RSS MiB | wall-clock ratio |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in results:
        if row["scheme"] == "baseline":
            lines.append(
                f"| {row['n_agents']} | baseline (no model) | | {row['adapter_steps_per_s']:,.0f} "
                f"| | | | {row['peak_rss_mib']:.0f} | |"
            )
            continue
        lines.append(
            f"| {row['n_agents']} | {row['scheme']} | {row['train_steps_per_s']:,.0f} | {row['adapter_steps_per_s']:,.0f} "
            f"| {row['ratio']:.2f} | {row['update_ms']:.1f} | {row['rollout_ms']:.3f} | {row['peak_rss_mib']:.0f} "
            f"| {row['wall_ratio']:.2f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].strip(), allow_abbrev=False)
    parser.add_argument("--agents", type=int, nargs="+", default=[3, 5], help="team sizes N")
    parser.add_argument("--schemes", nargs="+", default=list(SCHEMES), choices=SCHEMES)
    parser.add_argument("--steps", type=int, default=10_000, help="env steps of learn() timed per configuration")
    parser.add_argument("--updates", type=int, default=20, help="update rounds timed per configuration")
    parser.add_argument("--rollout-steps", type=int, default=2_000, help="rollout steps timed per configuration")
    parser.add_argument("--env-steps", type=int, default=10_000, help="env steps per timed run of the bare adapter")
    parser.add_argument("--env-repeats", type=int, default=3, help="timed runs of the bare adapter (median)")
    parser.add_argument("--threads", type=int, default=1, help="torch.set_num_threads in every measurement")
    parser.add_argument("--n-envs", type=int, default=1, help="DummyVecEnv size")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--same-process", action="store_true", help="no fresh process per configuration (peak RSS grows)")
    parser.add_argument("--out", type=Path, help="write OUT.json and OUT.md (a suffix on OUT is replaced)")
    args = parser.parse_args(argv)

    load_before = os.getloadavg()[0]
    results: list[dict[str, Any]] = []
    for n_agents in args.agents:
        env_rates = measure_env_rates(n_agents, steps=args.env_steps, repeats=args.env_repeats, seed=args.seed)
        adapter_rate = env_rates["median"]["adapter+metrics"]
        wall_adapter_rate = env_rates.get("wall_median", env_rates["median"])["adapter+metrics"]
        for scheme in [None, *args.schemes]:
            kwargs = dict(
                n_agents=n_agents,
                scheme=scheme,
                steps=args.steps,
                updates=args.updates,
                rollout_steps=args.rollout_steps,
                threads=args.threads,
                n_envs=args.n_envs,
                seed=args.seed,
            )
            row = measure_config(**kwargs) if args.same_process else _in_fresh_process(kwargs)
            row["adapter_steps_per_s"] = adapter_rate
            row["wall_adapter_steps_per_s"] = wall_adapter_rate
            if scheme is not None:
                row["ratio"] = row["train_steps_per_s"] / adapter_rate
                row["wall_ratio"] = row["wall_train_steps_per_s"] / wall_adapter_rate
            results.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)

    info = machine_info()
    info["threads"] = str(args.threads)
    info["n_envs"] = str(args.n_envs)
    info["load_avg_1min"] = f"{load_before:.2f} before, {os.getloadavg()[0]:.2f} after"
    command = "python " + " ".join([Path(sys.argv[0]).as_posix(), *(argv if argv is not None else sys.argv[1:])])
    table = markdown_table(results)
    machine = ", ".join(f"{key} {value}" for key, value in info.items())
    print(table)
    print(f"\n{args.steps} timed learn() steps, {args.updates} updates, {args.rollout_steps} rollout steps; {machine}")
    if args.out is not None:
        stem = args.out.with_suffix("")
        payload = {"command": command, "machine": info, "config": PAPER_CONFIG, "results": results}
        stem.with_suffix(".json").write_text(json.dumps(payload, indent=2) + "\n")
        stem.with_suffix(".md").write_text(f"{table}\n\nCommand: `{command}`\n\nMachine: {machine}\n")


if __name__ == "__main__":
    main()
