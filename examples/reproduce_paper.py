"""Reproduce the paper's experiments with the ``sb3-maddpg`` command line, from a smoke test to full scale.

    python examples/reproduce_paper.py --fast                   # seconds: the pipeline on a tiny budget (CI)
    python examples/reproduce_paper.py --scale small --workers 4           # 40 runs of 150k steps
    python examples/reproduce_paper.py --scale small-partial --workers 8   # partial observability, a tenth of exp2
    python examples/reproduce_paper.py --scale full --workers 32           # the paper: 31 seeds x 5 schemes x 2 settings
    python examples/reproduce_paper.py --scale small --vec-env mpe2 --n-envs 1   # on mpe2 itself, one env

Every run trains on :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` (outside the smoke test, 100 worlds
stepped at once with one gradient step per 100 transitions: the paper's update ratio), or on mpe2 itself
with ``--vec-env mpe2`` (the same MDP, several times slower). Every scale trains each (scheme, seed) run,
saves checkpoints over the last 20% of training, evaluates them, and writes a report: the paper's Table 2
(mean success rate, std, Mann-Whitney U tests against MADDPG), learning curves and boxplots. An
interrupted sweep resumes where it stopped when run again with the same command. The script only
assembles and prints the command-line calls; you can run them yourself (``sb3-maddpg run ...`` is the
same as ``python -m sb3_maddpg run ...``).

``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``.
"""

import argparse
import os
import shlex
import tempfile
from pathlib import Path

from sb3_maddpg.cli.main import main as sb3_maddpg_cli
from sb3_maddpg.common.progress import ctrl_c_ends_quietly

SCALES: dict[str, str] = {
    # The pipeline only: 3 agents, 40 episodes, tiny networks, one seed per scheme.
    "smoke": "--config smoke --seeds 1",
    # The small-scale comparison shown in the docs (benchmarks/paper_small/config.json): experiment 1's protocol
    # with 3 agents, 6,000 episodes (150k steps), 8 seeds, 50 evaluation episodes. That run was measured on mpe2
    # with one env (add --vec-env mpe2 --n-envs 1 for its env path) and before the actor regulariser existed.
    "small": (
        "--config exp1 --name n3_full --n-agents 3 --episodes 6000 --seeds 8 --n-checkpoints 20 --eval-episodes 50 "
        "--curve-points 15 --curve-eval-episodes 20 --no-keep-checkpoints"
    ),
    # Experiment 2's setting (5 agents, each observing its 2 nearest) at a tenth of its budget, 5 seeds.
    "small-partial": "--config exp2 --name exp2_small --episodes 15000 --seeds 5 --n-checkpoints 10 --eval-episodes 50",
    # The paper: N=5, 100,000 (exp1) and 150,000 (exp2) episodes, 31 seeds, 20 and 30 checkpoints.
    "full": "--config exp1 --config exp2",
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    parser.add_argument("--scale", choices=sorted(SCALES), default="small")
    parser.add_argument("--results", default=None, help="results directory (default: runs/paper_<scale>)")
    parser.add_argument("--workers", type=int, default=1, help="runs in parallel (one CPU core each)")
    parser.add_argument("--backend", choices=("local", "ray"), default="local")
    parser.add_argument("--dry-run", action="store_true", help="list the runs without training")
    # Passed on to `sb3-maddpg run` when given; otherwise each experiment's own (exp1, exp2: batched, 100 worlds).
    parser.add_argument("--vec-env", choices=("batched", "mpe2"), default=None, help="batched (default) or mpe2 itself")
    parser.add_argument(
        "--n-envs", type=int, default=None, help="worlds stepped together in training (default: 100; smoke: 4)"
    )
    args = parser.parse_args()

    if args.fast:
        args.scale = "smoke"
        args.results = args.results or str(Path(tempfile.mkdtemp()) / "paper_smoke")
    results = args.results or f"runs/paper_{args.scale}"

    run = ["run", *shlex.split(SCALES[args.scale]), "--results", results]
    run += ["--workers", str(args.workers), "--backend", args.backend]
    if args.vec_env is not None:
        run += ["--vec-env", args.vec_env]
    if args.n_envs is not None:
        run += ["--n-envs", str(args.n_envs)]
    if args.dry_run:
        run.append("--dry-run")
    if args.fast:
        run.append("--quiet")
    report = ["report", results]

    print("$ sb3-maddpg " + shlex.join(run))
    status = sb3_maddpg_cli(run)
    if status != 0 or args.dry_run:
        raise SystemExit(status)
    print("$ sb3-maddpg " + shlex.join(report))
    raise SystemExit(sb3_maddpg_cli(report))


if __name__ == "__main__":
    with ctrl_c_ends_quietly():  # Ctrl-C: one line, no traceback
        main()
