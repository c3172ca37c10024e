"""Evaluate a saved team and render it as an animated GIF.

    python examples/quickstart.py --save-path runs/team            # train and save a team first
    python examples/render_team.py --model runs/team.zip --output team.gif
    python examples/render_team.py --fast                          # seconds: a tiny team (CI)

Without ``--model`` a tiny untrained-ish team is trained on the spot (useful to check the setup).
``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``. On a machine without a
display, rendering uses ``SDL_VIDEODRIVER=dummy`` (set below if unset).
"""

import argparse
import os
import tempfile
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before pygame (imported by mpe2) is loaded

import imageio.v3 as iio
import numpy as np
from PIL import Image

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import make_simple_spread
from sb3_maddpg.evaluation import evaluate_team


def matching_env_kwargs(model: MADDPG) -> dict:
    """The simple_spread settings (team size, observed neighbours) whose agent layout matches the model's."""
    n_agents = model.agent_layout.n_agents
    for neighbors in [None, *range(1, n_agents - 1)]:
        kwargs = {"n_agents": n_agents, "num_agent_neighbors": neighbors}
        if make_simple_spread(**kwargs).agent_layout == model.agent_layout:
            return kwargs
    raise ValueError(f"The model's agent layout {model.agent_layout} is not a simple_spread team's.")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fast", action="store_true", default=os.environ.get("SB3_MADDPG_FAST", "0") != "0")
    parser.add_argument("--model", default=None, help="a model saved with model.save() (a .zip file)")
    parser.add_argument("--output", default=None, help="the GIF to write (default: team.gif, or a temporary file with --fast)")
    parser.add_argument("--episodes", type=int, default=3, help="episodes in the GIF")
    parser.add_argument("--eval-episodes", type=int, default=100, help="episodes for the success rate")
    parser.add_argument("--fps", type=int, default=10)
    parser.add_argument("--scale", type=float, default=1.0, help="resize the frames (0.5: half size, a smaller file)")
    args = parser.parse_args()

    if args.model is not None:
        model = MADDPG.load(args.model)
    else:
        print("no --model given: training a tiny team (use examples/quickstart.py --save-path for a real one)")
        model = MADDPG(
            "MlpPolicy", make_simple_spread(n_agents=3), learning_starts=200, batch_size=32, train_freq=50, buffer_size=5_000
        )
        model.learn(total_timesteps=400 if args.fast else 20_000)
    if args.fast:
        args.episodes, args.eval_episodes = 1, 3
    output = Path(args.output or (Path(tempfile.mkdtemp()) / "team.gif" if args.fast else "team.gif"))

    env_kwargs = matching_env_kwargs(model)

    # 1. The numbers: the same evaluation as the paper (success = every landmark covered at the last step).
    result = evaluate_team(model, make_simple_spread(**env_kwargs), n_episodes=args.eval_episodes, seed=0)
    print(
        f"{env_kwargs['n_agents']} agents over {result['n_episodes']} episodes: success {100 * result['success_rate']:.1f}%, "
        f"coverage {100 * result['coverage']:.1f}%, collisions/episode {result['collisions']:.2f}"
    )

    # 2. The pictures: render each step of a few episodes with render_mode="rgb_array".
    env = make_simple_spread(**env_kwargs, render_mode="rgb_array")
    frames: list[np.ndarray] = []
    for episode in range(args.episodes):
        obs, _ = env.reset(seed=1_000 + episode)
        frames.append(env.render())
        done = False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            frames.append(env.render())
            done = terminated or truncated
        print(f"episode {episode}: coverage at the end {100 * info['coverage']:.0f}%, success {bool(info['success'])}")
    env.close()

    if args.scale != 1.0:
        height, width = frames[0].shape[:2]
        size = (round(width * args.scale), round(height * args.scale))
        frames = [np.asarray(Image.fromarray(frame).resize(size, Image.Resampling.LANCZOS)) for frame in frames]
    output.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(output, np.stack(frames), duration=1000 / args.fps, loop=0)
    print(f"wrote {len(frames)} frames to {output}")


if __name__ == "__main__":
    main()
