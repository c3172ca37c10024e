"""The main job: a short MADDPG training on cooperative navigation, with the team measured before and after.

    python examples/train_simple_spread.py               # about 5 minutes on a 2-core CPU
    python examples/train_simple_spread.py --fast        # seconds: checks that everything runs (CI)
    python examples/train_simple_spread.py --steps 300000 --sharing selected

It trains 3 agents on ``simple_spread`` and prints the team's success rate (every landmark covered
at the last step, mpe2's 0.1 radius), landmark coverage, collisions and return of the untrained and
the trained team on the same 100 evaluation episodes. ``SB3_MADDPG_FAST=1`` acts like ``--fast``.

The paper's hyperparameters (one update per 100 steps, learning from step 25,600) need millions of
steps; for a few minutes of CPU this script updates every 25 steps from step 10,000 instead.
Expect the return and coverage to improve clearly; success at the 0.1 radius needs far longer training.
"""

import argparse
import os
import time

import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import make_simple_spread
from sb3_maddpg.evaluation import evaluate_team


def report(label: str, result: dict) -> None:
    print(
        f"{label:>9}: success {100 * result['success_rate']:5.1f}%  coverage {100 * result['coverage']:5.1f}%  "
        f"collisions/episode {result['collisions']:5.2f}  return {result['return_mean']:8.2f} (std {result['return_std']:.2f})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=150_000, help="training env steps")
    parser.add_argument("--agents", type=int, default=3, help="number of agents (and landmarks)")
    parser.add_argument("--sharing", default="full", help="critic_sharing scheme (independent, full, ..., selected)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    args = parser.parse_args()
    th.set_num_threads(1)  # small networks: one thread is fastest and leaves the other core to the env

    steps, n_eval, overrides = args.steps, 100, dict(learning_starts=10_000, train_freq=25)
    if args.fast:
        steps, n_eval, overrides = 800, 4, dict(learning_starts=300, train_freq=25, batch_size=64)
    env = make_simple_spread(n_agents=args.agents)
    eval_env = make_simple_spread(n_agents=args.agents)
    model = MADDPG("MlpPolicy", env, critic_sharing=args.sharing, seed=args.seed, **overrides)

    before = evaluate_team(model, eval_env, n_episodes=n_eval, seed=1000)
    start = time.perf_counter()
    model.learn(total_timesteps=steps)
    elapsed = time.perf_counter() - start
    after = evaluate_team(model, eval_env, n_episodes=n_eval, seed=1000)

    rate = steps / elapsed
    print(f"MADDPG ({args.sharing} sharing), {args.agents} agents, {steps} steps in {elapsed:.0f} s ({rate:.0f} steps/s)")
    report("untrained", before)
    report("trained", after)


if __name__ == "__main__":
    main()
