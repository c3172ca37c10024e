"""The main job: MADDPG on cooperative navigation at the paper's hyperparameters, the team measured before and after.

    python examples/train_simple_spread.py               # about 11 minutes on one core (~3,200 steps/s)
    python examples/train_simple_spread.py --fast        # seconds: checks that everything runs (CI)
    python examples/train_simple_spread.py --agents 5 --steps 2500000 --sharing selected
    python examples/train_simple_spread.py --mpe2        # step mpe2 itself: the same MDP, several times slower

It trains 3 agents on ``simple_spread`` with the paper's hyperparameters (Adam 0.01, batch 1024, one
update per 100 transitions, learning from step 25,600), stepping 100 worlds at once in
:class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`, printing its progress every few seconds. Then it
evaluates the untrained and the trained team on the same 100 episodes. ``SB3_MADDPG_FAST=1`` acts
like ``--fast``.
"""

import argparse
import os
import time

from stable_baselines3.common.vec_env import VecEnv, VecMonitor

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import describe_result, evaluate_team
from sb3_maddpg.analysis.normalised_score import describe_normalised, reference_scores
from sb3_maddpg.common.progress import ProgressLogCallback, ctrl_c_ends_quietly
from sb3_maddpg.common.torch_threads import add_threads_argument, use_torch_threads
from sb3_maddpg.envs import make_simple_spread_vec_env

MEANING = (
    "Higher is better for success, coverage and return; lower for collisions and min-dist sum. Return: the team's "
    "reward summed over an episode (25 steps); coverage: landmarks with an agent within 0.1 at the last step; "
    "success: all of them covered (the hardest: 12% and 19% of episodes after the default 2M steps, on two machines); "
    "collisions: agent pairs in contact, summed over the episode; "
    "min-dist sum: each landmark's distance to its nearest agent at the last step, summed; normalised score: 0 for "
    "uniformly random actions, 1 for a scripted controller that assigns agents to landmarks and steers them there "
    "(at N=3 the default 2M steps reach about 0.8 in min-dist sum)."
)


def make_env(n_envs: int, n_agents: int, mpe2: bool) -> VecEnv:
    """``n_envs`` simple_spread worlds: batched arrays, or mpe2 itself behind the adapter."""
    return make_simple_spread_vec_env(n_envs, "mpe2" if mpe2 else "batched", n_agents=n_agents)


def report(label: str, result: dict) -> None:
    print(f"{label:>9}: {describe_result(result)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2_000_000, help="training env steps (all worlds counted)")
    parser.add_argument("--agents", type=int, default=3, help="number of agents (and landmarks)")
    parser.add_argument("--sharing", default="full", help="critic_sharing scheme (independent, full, ..., selected)")
    parser.add_argument("--n-envs", type=int, default=100, help="worlds stepped together")
    parser.add_argument("--mpe2", action="store_true", help="step mpe2 itself instead of the batched env")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    add_threads_argument(parser)
    args = parser.parse_args()
    use_torch_threads(args.threads)

    steps, n_eval, n_envs, overrides = args.steps, 100, args.n_envs, {}
    if args.fast:
        steps, n_eval, n_envs = 1_000, 4, 4
        overrides = dict(learning_starts=300, batch_size=64, policy_kwargs=dict(net_arch=[16, 16]))
    env = VecMonitor(make_env(n_envs, args.agents, args.mpe2))  # VecMonitor: episode returns for the progress lines
    eval_env = make_env(n_eval if not args.mpe2 else 1, args.agents, args.mpe2)
    model = MADDPG("MlpPolicy", env, critic_sharing=args.sharing, seed=args.seed, **overrides)  # type: ignore[arg-type]
    where = "mpe2" if args.mpe2 else "the batched env"
    print(
        f"MADDPG ({args.sharing} sharing), {args.agents} agents, {steps:,} steps on {where} ({n_envs} worlds); "
        f"updates: {model.update_schedule}"
    )

    before = evaluate_team(model, eval_env, n_episodes=n_eval, seed=1000)
    progress = ProgressLogCallback("training", steps, every=1.0, every_seconds=5.0)
    start = time.perf_counter()
    with ctrl_c_ends_quietly(model):
        model.learn(total_timesteps=steps, callback=progress)
    elapsed = time.perf_counter() - start
    after = evaluate_team(model, eval_env, n_episodes=n_eval, seed=1000)

    print(f"{steps:,} steps in {elapsed:.0f} s ({steps / elapsed:,.0f} steps/s); {n_eval} evaluation episodes:")
    report("untrained", before)
    report("trained", after)
    references = reference_scores(args.agents)  # the task's random team and scripted controller, 300 episodes each
    print(f"  trained: {describe_normalised(after, references)}")
    print(MEANING)


if __name__ == "__main__":
    with ctrl_c_ends_quietly():  # Ctrl-C: one line, no traceback
        main()
