"""Write the study's experiments (exp1.json, exp2.json) at the budget the learning curve chose (issue 43).

    python benchmarks/paper_n5_independent/make_configs.py --steps 1500000

Each is the shared study's experiment (benchmarks/paper_n5/exp1.json, exp2.json: exp1_tuned and exp2_tuned, the
paper's five schemes and selected_next) with independent actors and critics (``share_parameters: false``), renamed,
at ``--steps`` env steps per run (in episodes of 25 steps); everything else as the shared study, so that the two
studies differ in the networks and the budget only. Exp. 2 holds ``full``, ``selected`` and ``selected_next`` (the
2 x 2 of networks and selection rule) unless ``--all-exp2``: its other three schemes come where time allows, added to
the same experiment later (finished runs are kept).
"""

import argparse
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
SHARED = HERE.parent / "paper_n5"
FIRST_IN_EXP2 = ["full", "selected", "selected_next"]


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


if __name__ == "__main__":
    main()
