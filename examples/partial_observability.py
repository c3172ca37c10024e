"""Partial observability (the paper's experiment 2): each agent sees only its two nearest other agents.

The actors act on these partial observations, during training and after. The critics, used only in
training, can make up for what an agent cannot see: this script shows, per scheme, how much each
critic sees, then trains and evaluates selected sharing (the paper's best scheme in this setting)
against full sharing.

    python examples/partial_observability.py             # 5 agents, 1M steps per scheme on 100 batched worlds
    python examples/partial_observability.py --fast      # seconds: checks that everything runs (CI)
    python examples/partial_observability.py --mpe2      # step mpe2 itself: the same MDP, several times slower

``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``.
"""

import argparse
import os

from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.common.progress import ctrl_c_ends_quietly
from sb3_maddpg.common.selection import NearestAgents
from sb3_maddpg.common.torch_threads import add_threads_argument, use_torch_threads
from sb3_maddpg.envs import make_simple_spread_vec_env


def make_env(n_envs: int, n_agents: int, neighbors: int | None, mpe2: bool) -> VecEnv:
    """``n_envs`` simple_spread worlds: batched arrays, or mpe2 itself behind the adapter."""
    return make_simple_spread_vec_env(n_envs, "mpe2" if mpe2 else "batched", n_agents=n_agents, num_agent_neighbors=neighbors)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    parser.add_argument("--steps", type=int, default=1_000_000, help="training steps per scheme (all worlds counted)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--n-envs", type=int, default=100, help="worlds stepped together in training")
    parser.add_argument("--mpe2", action="store_true", help="step mpe2 itself instead of the batched env")
    add_threads_argument(parser)
    args = parser.parse_args()
    use_torch_threads(args.threads)

    n_agents, eval_episodes, overrides = 5, 100, {}
    if args.fast:
        n_agents, args.steps, eval_episodes, args.n_envs = 4, 400, 3, 4
        overrides = {"learning_starts": 200, "batch_size": 32, "transitions_per_update": 50, "buffer_size": 5_000}

    def make_partial_env(n_envs: int) -> VecEnv:
        # num_agent_neighbors=2: the relative positions of the 2 nearest other agents only (mpe2's option).
        return make_env(n_envs, n_agents, 2, args.mpe2)

    full_view = make_env(1, n_agents, None, args.mpe2).get_attr("agent_layout")[0].obs_sizes[0]
    partial_view = make_partial_env(1).get_attr("agent_layout")[0].obs_sizes[0]
    print(f"each agent observes {partial_view} numbers (fully observable: {full_view})")

    # What critic 0 sees under each scheme (the length of its input vector).
    for scheme in ("independent", "full", "observations", "actions", "selected"):
        model = MADDPG("MlpPolicy", make_partial_env(1), critic_sharing=scheme, **overrides)
        print(f"  critic_sharing={scheme!r:>15}: critic input of {model.policy.critics[0].features_extractor.features_dim}")

    # Train: the two nearest agents are selected when each transition is stored, and kept with it.
    # One world per evaluation episode: they run side by side (mpe2: one env, episode after episode).
    eval_env = make_partial_env(1 if args.mpe2 else eval_episodes)
    for scheme, selector in (("selected", NearestAgents(k=2)), ("full", None)):
        env = make_partial_env(args.n_envs)
        model = MADDPG("MlpPolicy", env, critic_sharing=scheme, selector=selector, seed=args.seed, **overrides)
        with ctrl_c_ends_quietly(model):
            model.learn(total_timesteps=args.steps)
        result = evaluate_team(model, eval_env, n_episodes=eval_episodes, seed=10_000)
        print(
            f"{scheme:>9}: success {100 * result['success_rate']:5.1f}%, coverage {100 * result['coverage']:5.1f}%, "
            f"collisions/episode {result['collisions']:.2f}"
        )


if __name__ == "__main__":
    with ctrl_c_ends_quietly():  # Ctrl-C: one line, no traceback
        main()
