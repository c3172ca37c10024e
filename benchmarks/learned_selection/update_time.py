"""
The cost of critics that learn whom to listen to: critic parameters and the time of one update round of ``full``,
``selected``, ``attention`` and ``learned_selection``, as ratios to ``full`` measured in the same run.

For each team size, every scheme is built on the batched simple_spread at the paper's settings (batch 1024, 64-unit
networks; attention with MADDPG's default 64-unit encodings and 4 heads), its buffer filled with ``learning_starts``
random steps, and ``model.train(gradient_steps=1, batch_size=1024)`` timed: the median CPU time (``time.process_time``)
of ``--updates`` rounds after 3 warm-up rounds, one torch thread. The schemes are measured in turns (full, selected,
attention, learned_selection, full, ...) for ``--repeats`` rounds, so that a change of the machine's load falls on
all of them alike.

Usage::

    python benchmarks/learned_selection/update_time.py --agents 3 5 --out benchmarks/learned_selection/update_time.json
    # and --out ....md for the table
"""

import argparse
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from env_throughput import command_line, machine_info, write_results

SCHEMES = ("full", "selected", "attention", "learned_selection")


def selection_size(n_agents: int) -> int:
    """The k of ``selected`` and ``learned_selection``: 1 at N=3 (2 would be every other agent), else 2."""
    return 1 if n_agents <= 3 else 2


def build(n_agents: int, scheme: str, seed: int) -> Any:
    """A model of the scheme with a buffer of one batch of random steps."""
    from sb3_maddpg import MADDPG
    from sb3_maddpg.envs import SimpleSpreadVecEnv

    k = selection_size(n_agents)
    kwargs: dict[str, Any] = {}
    if scheme == "selected":
        kwargs["selector"] = k
    if scheme == "learned_selection":
        kwargs["critic_sharing_kwargs"] = {"k": k}
    model = MADDPG(
        "MlpPolicy",
        SimpleSpreadVecEnv(100, n_agents=n_agents),
        critic_sharing=scheme,
        learning_starts=1_100,
        seed=seed,
        **kwargs,
    )
    model.learn(1_100)  # random steps only: fills the buffer past one batch
    return model


def time_updates(model: Any, updates: int) -> float:
    """:return: The median CPU time of one update round, in ms."""
    for _ in range(3):
        model.train(gradient_steps=1, batch_size=1024)
    times = []
    for _ in range(updates):
        start = time.process_time()
        model.train(gradient_steps=1, batch_size=1024)
        times.append(time.process_time() - start)
    return 1e3 * statistics.median(times)


def measure(n_agents: int, updates: int, repeats: int, seed: int) -> list[dict[str, Any]]:
    """
    :return: One row per scheme: critic parameters, median update ms over the repeats, and both as ratios to full.
    """
    models = {scheme: build(n_agents, scheme, seed) for scheme in SCHEMES}
    times: dict[str, list[float]] = {scheme: [] for scheme in SCHEMES}
    for _ in range(repeats):
        for scheme in SCHEMES:
            times[scheme].append(time_updates(models[scheme], updates))
    params = {scheme: sum(p.numel() for p in model.critic.parameters()) for scheme, model in models.items()}
    update_ms = {scheme: statistics.median(values) for scheme, values in times.items()}
    return [
        {
            "n_agents": n_agents,
            "scheme": scheme,
            "k": selection_size(n_agents) if scheme in ("selected", "learned_selection") else None,
            "critic_parameters": params[scheme],
            "parameters_vs_full": params[scheme] / params["full"],
            "update_ms": update_ms[scheme],
            "update_ms_each_repeat": times[scheme],
            "update_vs_full": update_ms[scheme] / update_ms["full"],
        }
        for scheme in SCHEMES
    ]


def table(results: list[dict[str, Any]]) -> str:
    """:return: The Markdown table."""
    lines = [
        "| N | scheme | k | critic parameters (all agents) | vs full | update round (ms, CPU) | vs full |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in results:
        k = "" if row["k"] is None else str(row["k"])
        lines.append(
            f"| {row['n_agents']} | {row['scheme']} | {k} | {row['critic_parameters']:,} | {row['parameters_vs_full']:.2f} | "
            f"{row['update_ms']:.1f} | {row['update_vs_full']:.2f} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--agents", type=int, nargs="+", default=[3, 5])
    parser.add_argument("--updates", type=int, default=20, help="timed update rounds per repeat")
    parser.add_argument("--repeats", type=int, default=3, help="turns over the schemes")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, nargs="+", default=[], help=".json and/or .md files")
    args = parser.parse_args(argv)

    import torch as th

    th.set_num_threads(1)
    results = []
    for n_agents in args.agents:
        results += measure(n_agents, args.updates, args.repeats, args.seed)
        print(f"N={n_agents} measured", flush=True)
    markdown = table(results)
    print(markdown)
    for out in args.out:
        write_results(out, command_line(argv), machine_info(), markdown, results)


if __name__ == "__main__":
    main()
