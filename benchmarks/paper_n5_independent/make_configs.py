"""Write the study's experiments (exp1.json, exp2.json) at the budget the learning curve chose (issue 43).

    python benchmarks/paper_n5_independent/make_configs.py --steps 1500000

Each is the shared study's experiment (benchmarks/paper_n5/exp1.json, exp2.json: exp1_tuned and exp2_tuned, the
paper's five schemes and selected_next) with independent actors and critics (``share_parameters: false``), renamed,
at ``--steps`` env steps per run (in episodes of 25 steps); everything else as the shared study, so that the two
studies differ in the networks and the budget only. Exp. 2 holds ``full``, ``selected`` and ``selected_next`` (the
2 x 2 of networks and selection rule) unless ``--all-exp2``: its other three schemes come where time allows, added to
the same experiment later (finished runs are kept).

``--fixed-graph`` also writes ``exp1_fixed_graph.json`` (issue 56, item 4): Exp. 1's ``selected`` with each agent's
two partners fixed for the run (a ring, :data:`RING`: agent i selects i - 1 and i + 1), 5 seeds, the same budget
and networks: does ``selected`` trail ``full`` because it selects by distance, a selection that changes from step to
step, or because it selects at all? Its runs are read against ``paper_n5i_exp1``'s ``full`` (the same seeds and
protocol): ``SETTINGS=exp1_fixed_graph bash benchmarks/paper_n5_independent/run.sh``.
"""

import argparse
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
SHARED = HERE.parent / "paper_n5"
FIRST_IN_EXP2 = ["full", "selected", "selected_next"]
RING = [[4, 1], [0, 2], [1, 3], [2, 4], [3, 0]]
"""The fixed graph of N=5: each agent's two ring neighbours, as many partners as ``selected``'s k=2."""


def independent(experiment: dict, name: str, steps: int) -> dict:
    """:return: ``experiment`` with independent networks, renamed, at ``steps`` env steps per run."""
    config = json.loads(json.dumps(experiment))
    config["name"] = name
    config["episodes"] = steps // config["episode_length"]
    config["model_kwargs"]["policy_kwargs"]["share_parameters"] = False
    config["description"] = (
        f"{experiment['name']} (benchmarks/paper_n5) with independent actors and critics, as the paper trains them "
        f"(share_parameters false; otherwise unchanged), {steps:,} env steps per run (issue 43's budget)"
    )
    return config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, required=True, help="env steps per run (curve_summary.md's budget)")
    parser.add_argument("--all-exp2", action="store_true", help="every scheme in Exp. 2 too")
    parser.add_argument("--fixed-graph", action="store_true", help="also exp1_fixed_graph.json (issue 56, item 4)")
    args = parser.parse_args()
    steps = args.steps
    for setting in ("exp1", "exp2"):
        shared = json.loads((SHARED / f"{setting}.json").read_text())
        config = independent(shared, f"paper_n5i_{setting}", steps)
        if setting == "exp2":
            rest = [scheme for scheme in config["schemes"] if scheme not in FIRST_IN_EXP2]
            config["schemes"] = FIRST_IN_EXP2 + (rest if args.all_exp2 else [])
        (HERE / f"{setting}.json").write_text(json.dumps(config, indent=2) + "\n")
        print(f"{setting}.json: {config['episodes']:,} episodes, schemes {config['schemes']}")
        if setting == "exp1" and args.fixed_graph:
            fixed = fixed_graph(config)
            (HERE / "exp1_fixed_graph.json").write_text(json.dumps(fixed, indent=2) + "\n")
            print(f"exp1_fixed_graph.json: {fixed['episodes']:,} episodes, schemes {fixed['schemes']}")


def fixed_graph(exp1: dict) -> dict:
    """:return: ``exp1`` with one scheme, ``selected_fixed``: ``selected`` over the fixed :data:`RING`, seeds 0-4."""
    config = json.loads(json.dumps(exp1))
    config["name"] = f"{exp1['name']}_fixed_graph"
    config["schemes"] = ["selected_fixed"]
    config["seeds"] = [0, 1, 2, 3, 4]
    config["scheme_model_kwargs"] = {"selected_fixed": {"critic_sharing": "selected", "selector": {"neighbors": RING}}}
    config["description"] = (
        f"{exp1['name']}'s selected with a fixed neighbour graph (each agent's two ring neighbours for the whole run) "
        "instead of the two nearest agents at each step; everything else as paper_n5i_exp1 (issue 56, item 4)"
    )
    return config


if __name__ == "__main__":
    main()
