"""Quickstart: train a team with MADDPG, evaluate it, save it, load it back and use it.

    python examples/quickstart.py            # 150k steps: about 10 minutes on a CPU
    python examples/quickstart.py --fast     # a few seconds: checks that everything runs (CI)

``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``.
"""

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np
import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import make_simple_spread
from sb3_maddpg.evaluation import evaluate_team


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    parser.add_argument("--save-path", default=None, help="where to save the model (default: a temporary directory)")
    args = parser.parse_args()

    # 1. The environment: MPE cooperative navigation with 3 agents and 3 landmarks, 25 steps per episode.
    #    It is a gymnasium env over the PettingZoo ParallelEnv; env.agent_layout says who is where.
    env = make_simple_spread(n_agents=3)
    print(env.agent_layout)

    # 2. The model. Every default is the paper's (Lowe et al.): lr 1e-2, batch 1024, tau 0.01, gamma 0.95,
    #    one update every 100 steps, learning from step 25,600; those settings need millions of steps.
    #    For a first team in minutes, start learning earlier and update every 25 steps.
    #    critic_sharing picks what each agent's critic sees during training.
    if args.fast:
        total_timesteps = 600
        overrides = {"learning_starts": 200, "batch_size": 32, "train_freq": 25, "buffer_size": 10_000}
    else:
        total_timesteps = 150_000
        overrides = {"learning_starts": 10_000, "train_freq": 25}
    model = MADDPG("MlpPolicy", env, critic_sharing="full", seed=0, verbose=1, **overrides)

    # 3. Train, as with any SB3 algorithm (callbacks, progress_bar and tensorboard_log work as usual).
    model.learn(total_timesteps=total_timesteps, log_interval=100)

    # 4. Evaluate the team on the task: success rate (every landmark covered at the last step),
    #    landmark coverage, collisions per episode and the team return.
    eval_env = make_simple_spread(n_agents=3)
    n_episodes = 5 if args.fast else 100
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

    obs, _ = eval_env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)  # the joint action, in the env's units ([0, 1] for mpe2)
    print(f"joint action {action.shape}, agent 0's part: {action[env.agent_layout.action_slices[0]].round(2)}")

    # Each agent's actor alone (decentralised execution): actors[i](o_i) -> a_i in the policy's [-1, 1] space.
    layout = model.agent_layout
    own_obs = th.as_tensor(obs[layout.obs_slices[1]]).unsqueeze(0)
    with th.no_grad():
        print("agent 1 alone:", model.policy.actors[1](own_obs).numpy().round(2))


if __name__ == "__main__":
    main()
