"""Quickstart: train a team with MADDPG, evaluate it, save it, load it back and use it.

    python examples/quickstart.py            # 150k steps on 100 batched worlds: about 1.5 minutes on a 2-core CPU
    python examples/quickstart.py --fast     # a few seconds: checks that everything runs (CI)
    python examples/quickstart.py --mpe2     # step mpe2 itself: the same MDP, several times slower

``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``.
"""

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np
import torch as th
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.common.progress import ctrl_c_ends_quietly
from sb3_maddpg.common.torch_threads import add_threads_argument, use_torch_threads
from sb3_maddpg.envs import make_simple_spread_vec_env


def make_env(n_envs: int, n_agents: int, mpe2: bool) -> VecEnv:
    """``n_envs`` simple_spread worlds: batched arrays, or mpe2 itself behind the adapter."""
    return make_simple_spread_vec_env(n_envs, "mpe2" if mpe2 else "batched", n_agents=n_agents)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    parser.add_argument("--n-envs", type=int, default=100, help="worlds stepped together in training")
    parser.add_argument("--mpe2", action="store_true", help="step mpe2 itself instead of the batched env")
    parser.add_argument("--save-path", default=None, help="where to save the model (default: a temporary directory)")
    add_threads_argument(parser)
    args = parser.parse_args()
    use_torch_threads(args.threads)

    # 1. The environment: MPE cooperative navigation with 3 agents and 3 landmarks, 25 steps per episode.
    #    SimpleSpreadVecEnv steps many worlds at once as arrays (an SB3 VecEnv, the same MDP as mpe2's);
    #    its agent_layout says which slice of the joint observation and action is whose.
    n_envs = 4 if args.fast else args.n_envs
    env = VecMonitor(make_env(n_envs, 3, args.mpe2))  # VecMonitor: episode returns in SB3's logs
    print(env.get_attr("agent_layout")[0])

    # 2. The model. Every default is the paper's (Lowe et al.): lr 1e-2, batch 1024, tau 0.01, gamma 0.95,
    #    one gradient step per 100 transitions, learning from step 25,600; those settings need a million steps or more.
    #    For a first team in minutes, start learning earlier and take a gradient step per 25 transitions.
    #    critic_sharing picks what each agent's critic sees during training.
    if args.fast:
        total_timesteps = 600
        overrides = {"learning_starts": 200, "batch_size": 32, "transitions_per_update": 25, "buffer_size": 10_000}
    else:
        total_timesteps = 150_000
        overrides = {"learning_starts": 10_000, "transitions_per_update": 25}
    model = MADDPG("MlpPolicy", env, critic_sharing="full", seed=0, verbose=1, **overrides)
    print(f"updates: {model.update_schedule}")

    # 3. Train, as with any SB3 algorithm (callbacks, progress_bar and tensorboard_log work as usual).
    #    log_interval counts episodes, of every world: 2,000 episodes are 50k steps.
    with ctrl_c_ends_quietly(model):
        model.learn(total_timesteps=total_timesteps, log_interval=4 if args.fast else 2_000)

    # 4. Evaluate the team on the task: success rate (every landmark covered at the last step),
    #    landmark coverage, collisions per episode and the team return. One world per episode: the
    #    100 episodes run side by side (mpe2: one env, episode after episode).
    n_episodes = 5 if args.fast else 100
    eval_env = make_env(1 if args.mpe2 else n_episodes, 3, args.mpe2)
    result = evaluate_team(model, eval_env, n_episodes=n_episodes, deterministic=True, seed=123)
    print(
        f"success {100 * result['success_rate']:.1f}%, coverage {100 * result['coverage']:.1f}%, "
        f"collisions/episode {result['collisions']:.2f}, return {result['return_mean']:.1f}"
    )

    # 5. Save and load. Loading needs no env (the agent layout is saved with the model).
    save_dir = Path(args.save_path).parent if args.save_path else Path(tempfile.mkdtemp())
    path = Path(args.save_path) if args.save_path else save_dir / "maddpg_simple_spread"
    model.save(path)
    del model
    model = MADDPG.load(path)
    print(f"saved to and loaded from {path}.zip")

    # 6. The loaded team acts exactly as before: each agent's actor sees its own observation only.
    again = evaluate_team(model, eval_env, n_episodes=n_episodes, deterministic=True, seed=123)
    assert np.isclose(again["return_mean"], result["return_mean"]), "the loaded model should act as the saved one"

    eval_env.seed(0)
    obs = eval_env.reset()  # [n_worlds, joint observation]
    action, _ = model.predict(obs, deterministic=True)  # joint actions, in the env's units ([0, 1] for mpe2)
    layout = model.agent_layout
    print(f"joint actions {action.shape}, agent 0's part in world 0: {action[0, layout.action_slices[0]].round(2)}")

    # Each agent's actor alone (decentralised execution): actors[i](o_i) -> a_i in the policy's [-1, 1] space.
    own_obs = th.as_tensor(obs[:1, layout.obs_slices[1]], device=model.device)  # where the networks are (CPU or GPU)
    with th.no_grad():
        print("agent 1 alone, world 0:", model.policy.actors[1](own_obs).cpu().numpy().round(2))


if __name__ == "__main__":
    with ctrl_c_ends_quietly():  # Ctrl-C: one line, no traceback
        main()
