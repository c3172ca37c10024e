"""Train a team on any MPE task, with continuous or discrete actions, and measure it before and after.

Every mpe2 task builds with ``make_mpe_env`` and is scored by its own metrics (``MPE_TASK_METRICS``): the goal
distances of ``simple``, ``simple_push`` or ``simple_speaker_listener``, the catches of ``simple_tag``, whether Bob
and Eve decode ``simple_crypto``'s message. In a competitive task each side's return is reported (``MPE_TASK_SIDES``:
the adversaries' and the good agents', never their sum), and ``--group`` names agents whose summed return to report
(e.g. the predators of ``simple_tag``).

    python examples/train_mpe_task.py --task simple_speaker_listener               # 200k steps, continuous
    python examples/train_mpe_task.py --task simple_tag --discrete --group adversary_0,adversary_1,adversary_2
    python examples/train_mpe_task.py --fast                                        # seconds (CI)

``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``.
"""

import argparse
import os

from stable_baselines3.common.vec_env import DummyVecEnv

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import evaluate_team, side_return_key
from sb3_maddpg.common.progress import ctrl_c_ends_quietly
from sb3_maddpg.common.torch_threads import add_threads_argument, use_torch_threads
from sb3_maddpg.envs import MPE_TASK_METRICS, MPE_TASK_SIDES, MPE_TASKS, PettingZooToGym, make_mpe_env


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    parser.add_argument("--task", choices=MPE_TASKS, default="simple_speaker_listener")
    parser.add_argument("--discrete", action="store_true", help="mpe2's discrete actions (one-hot slots)")
    parser.add_argument("--group", default="", help="comma-separated agent ids whose summed return to report")
    parser.add_argument("--scheme", default="full", help="critic_sharing (default: full, MADDPG)")
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--n-envs", type=int, default=8, help="envs stepped together (mpe2 itself, one world each)")
    parser.add_argument("--seed", type=int, default=0)
    add_threads_argument(parser)
    args = parser.parse_args()
    use_torch_threads(args.threads)

    episodes, overrides = 100, {}
    if args.fast:
        args.steps, episodes, args.n_envs = 400, 3, 2
        overrides = {"learning_starts": 200, "batch_size": 32, "transitions_per_update": 20, "buffer_size": 5_000}

    def make_env() -> PettingZooToGym:
        return make_mpe_env(args.task, continuous_actions=not args.discrete)

    env = DummyVecEnv([make_env] * args.n_envs)
    print(f"{args.task} ({'discrete' if args.discrete else 'continuous'} actions): {env.get_attr('agent_layout')[0]}")
    model = MADDPG("MlpPolicy", env, critic_sharing=args.scheme, seed=args.seed, **overrides)
    group = tuple(agent for agent in args.group.split(",") if agent)
    metrics = MPE_TASK_METRICS[args.task]
    sides = MPE_TASK_SIDES.get(args.task, {})  # a competitive task's sides: each one's return, not their sum
    returns = [side_return_key(side) for side in sides] or ["return_mean"]

    def measure() -> dict[str, float]:
        result = evaluate_team(
            model, make_env(), n_episodes=episodes, seed=args.seed, task_metrics=metrics, score_agents=group, sides=sides
        )
        keys = [*returns, *(metric.key for metric in metrics), *(["group_return"] if group else [])]
        return {key: result[key] for key in dict.fromkeys(keys)}

    before = measure()
    with ctrl_c_ends_quietly(model):
        model.learn(args.steps)
    after = measure()
    print(f"{'metric':<24} {'untrained':>10} {'trained':>10}  (better)")
    directions = {metric.key: f"{metric.better}, for {metric.team}" for metric in metrics}
    directions.update(return_mean="higher, team return", group_return="higher, for " + ", ".join(group))
    directions.update({side_return_key(side): f"higher, for the {side}, per agent" for side in sides})
    for key in before:
        print(f"{key:<24} {before[key]:>10.3f} {after[key]:>10.3f}  ({directions.get(key, '')})")
    print(f"{args.steps:,} steps; {episodes} evaluation episodes each, the same ones before and after.")


if __name__ == "__main__":
    with ctrl_c_ends_quietly():  # Ctrl-C: one line, no traceback
        main()
