"""Partial observability (the paper's experiment 2): each agent sees only its two nearest other agents.

The actors act on these partial observations, during training and after. The critics, used only in
training, can make up for what an agent cannot see: this script shows, per scheme, how much each
critic sees, then trains and evaluates selected sharing (the paper's best scheme in this setting)
against full sharing.

    python examples/partial_observability.py             # 5 agents, 500k steps per scheme
    python examples/partial_observability.py --fast      # seconds: checks that everything runs (CI)

``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``.
"""

import argparse
import os

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import make_simple_spread
from sb3_maddpg.evaluation import evaluate_team
from sb3_maddpg.selection import NearestAgents


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    parser.add_argument("--steps", type=int, default=500_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    n_agents, eval_episodes, overrides = 5, 100, {}
    if args.fast:
        n_agents, args.steps, eval_episodes = 4, 400, 3
        overrides = {"learning_starts": 200, "batch_size": 32, "train_freq": 50, "buffer_size": 5_000}

    def make_env():
        # num_agent_neighbors=2: the relative positions of the 2 nearest other agents only (mpe2's option).
        return make_simple_spread(n_agents=n_agents, num_agent_neighbors=2)

    full_view = make_simple_spread(n_agents=n_agents).agent_layout.obs_sizes[0]
    partial_view = make_env().agent_layout.obs_sizes[0]
    print(f"each agent observes {partial_view} numbers (fully observable: {full_view})")

    # What critic 0 sees under each scheme (the length of its input vector).
    for scheme in ("independent", "full", "observations", "actions", "selected"):
        model = MADDPG("MlpPolicy", make_env(), critic_sharing=scheme, **overrides)
        print(f"  critic_sharing={scheme!r:>15}: critic input of {model.policy.critics[0].features_extractor.features_dim}")

    # Train: the two nearest agents are selected when each transition is stored, and kept with it.
    for scheme, selection in (("selected", NearestAgents(k=2)), ("full", None)):
        model = MADDPG("MlpPolicy", make_env(), critic_sharing=scheme, selection=selection, seed=args.seed, **overrides)
        model.learn(total_timesteps=args.steps)
        result = evaluate_team(model, make_env(), n_episodes=eval_episodes, seed=10_000)
        print(
            f"{scheme:>9}: success {100 * result['success_rate']:5.1f}%, coverage {100 * result['coverage']:5.1f}%, "
            f"collisions/episode {result['collisions']:.2f}"
        )


if __name__ == "__main__":
    main()
