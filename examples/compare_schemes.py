"""Compare the five critic information-sharing schemes on one environment, with the same budget and seeds.

    python examples/compare_schemes.py                       # 5 agents, 1M steps per run, 2 seeds
    python examples/compare_schemes.py --seeds 0 1 2 --steps 2500000 --plot schemes.png
    python examples/compare_schemes.py --fast                # seconds: checks that everything runs (CI)
    python examples/compare_schemes.py --mpe2                # step mpe2 itself: the same MDP, several times slower

Every run trains at the paper's hyperparameters (one gradient step per 100 transitions, learning from
step 25,600) on ``--n-envs`` worlds (100) stepped at once (:class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`),
and is evaluated on the same episodes, one world each.

``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``. For the paper's full
protocol (31 seeds, checkpoints, statistics) use ``python -m sb3_maddpg`` instead.
"""

import argparse
import os
import time

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.common.progress import ctrl_c_ends_quietly
from sb3_maddpg.common.torch_threads import add_threads_argument, use_torch_threads
from sb3_maddpg.envs import make_simple_spread_vec_env

# critic_sharing value -> the paper's name
SCHEMES = {
    "independent": "IDDPG",
    "full": "MADDPG",
    "observations": "MADDPG-fo",
    "actions": "MADDPG-fa",
    "selected": "MADDPG-soa",
}


def make_env(n_envs: int, n_agents: int, neighbors: int | None, mpe2: bool) -> VecEnv:
    """``n_envs`` simple_spread worlds: batched arrays, or mpe2 itself behind the adapter."""
    return make_simple_spread_vec_env(n_envs, "mpe2" if mpe2 else "batched", n_agents=n_agents, num_agent_neighbors=neighbors)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    parser.add_argument("--n-agents", type=int, default=5)
    parser.add_argument("--neighbors", type=int, default=None, help="observe only the k nearest agents (partial obs.)")
    parser.add_argument("--steps", type=int, default=1_000_000, help="training steps per run (all worlds counted)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--eval-episodes", type=int, default=100)
    parser.add_argument("--n-envs", type=int, default=100, help="worlds stepped together in training")
    parser.add_argument("--mpe2", action="store_true", help="step mpe2 itself instead of the batched env")
    parser.add_argument("--plot", default=None, help="save a bar chart of the success rates to this file (needs matplotlib)")
    add_threads_argument(parser)
    args = parser.parse_args()
    use_torch_threads(args.threads)

    overrides: dict = {}
    if args.fast:
        args.n_agents, args.steps, args.seeds, args.eval_episodes, args.n_envs = 3, 400, [0], 3, 4
        overrides = {"learning_starts": 200, "batch_size": 32, "transitions_per_update": 50, "buffer_size": 5_000}
    # One world per evaluation episode: they run side by side (mpe2: one env, episode after episode).
    eval_env = make_env(1 if args.mpe2 else args.eval_episodes, args.n_agents, args.neighbors, args.mpe2)

    results: dict[str, list[dict]] = {scheme: [] for scheme in SCHEMES}
    for scheme in SCHEMES:
        for seed in args.seeds:
            start = time.time()
            env = make_env(args.n_envs, args.n_agents, args.neighbors, args.mpe2)
            model = MADDPG("MlpPolicy", env, critic_sharing=scheme, seed=seed, **overrides)
            with ctrl_c_ends_quietly(model):
                model.learn(total_timesteps=args.steps)
            # The same evaluation episodes (seed) for every scheme and training seed.
            result = evaluate_team(model, eval_env, n_episodes=args.eval_episodes, seed=10_000)
            results[scheme].append(result)
            print(
                f"{scheme:>12} seed {seed}: success {100 * result['success_rate']:5.1f}%  "
                f"coverage {100 * result['coverage']:5.1f}%  return {result['return_mean']:8.2f}  "
                f"({time.time() - start:.0f}s)"
            )

    print(f"\n{args.n_agents} agents, {args.steps:,} steps, seeds {args.seeds}; mean (std) over seeds")
    print(f"{'scheme':>12} {'paper':>11} {'success %':>12} {'coverage %':>12} {'collisions':>11} {'return':>9}")
    for scheme, paper_name in SCHEMES.items():
        success = 100 * np.array([r["success_rate"] for r in results[scheme]])
        coverage = 100 * np.array([r["coverage"] for r in results[scheme]])
        collisions = np.mean([r["collisions"] for r in results[scheme]])
        returns = np.mean([r["return_mean"] for r in results[scheme]])
        print(
            f"{scheme:>12} {paper_name:>11} {success.mean():6.1f} ({success.std():4.1f}) "
            f"{coverage.mean():6.1f} ({coverage.std():4.1f}) {collisions:11.2f} {returns:9.2f}"
        )

    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3.5))
        names = [SCHEMES[s] for s in SCHEMES]
        means = [100 * np.mean([r["success_rate"] for r in results[s]]) for s in SCHEMES]
        stds = [100 * np.std([r["success_rate"] for r in results[s]]) for s in SCHEMES]
        ax.bar(names, means, yerr=stds, capsize=4, color="#3b75af")
        ax.set_ylabel("success rate (%)")
        ax.set_title(f"simple_spread, {args.n_agents} agents, {args.steps:,} steps")
        fig.tight_layout()
        fig.savefig(args.plot)
        print(f"plot saved to {args.plot}")


if __name__ == "__main__":
    with ctrl_c_ends_quietly():  # Ctrl-C: one line, no traceback
        main()
