"""Evaluate a saved team and render it as an animated GIF.

    python examples/quickstart.py --save-path runs/team            # train and save a team first
    python examples/render_team.py --model runs/team.zip --output team.gif
    python examples/render_team.py --fast                          # seconds: a tiny team (CI)
    python examples/render_team.py --mpe2                          # mpe2 itself instead of the batched env

Without ``--model`` a tiny untrained-ish team is trained on the spot (useful to check the setup).
The episodes are evaluated and drawn on :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` (one world per
episode, drawn by mpe2's renderer), or on mpe2 itself with ``--mpe2``: the same pictures.
``SB3_MADDPG_FAST=1`` in the environment has the same effect as ``--fast``. On a machine without a
display, rendering uses ``SDL_VIDEODRIVER=dummy`` (set below if unset).
"""

import argparse
import os
import tempfile
from pathlib import Path
from typing import Any

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before pygame (imported by mpe2) is loaded

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg.common.install_hint import extra_install_command

try:  # the experiments extra's; the package itself does not need them
    import imageio.v3 as iio
    from PIL import Image
except ModuleNotFoundError as error:
    raise SystemExit(
        f"render_team.py needs {(error.name or 'imageio').split('.')[0]}, which is not installed: "
        f"{extra_install_command('experiments')}"
    ) from error

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.common.progress import ctrl_c_ends_quietly
from sb3_maddpg.common.torch_threads import add_threads_argument, use_torch_threads
from sb3_maddpg.envs import SimpleSpreadVecEnv, make_simple_spread_vec_env

EPISODE_STEPS = 25
"""simple_spread's episode length (``max_cycles``)."""


def make_env(n_envs: int, mpe2: bool, **kwargs: Any) -> VecEnv:
    """``n_envs`` simple_spread worlds: batched arrays, or mpe2 itself behind the adapter."""
    return make_simple_spread_vec_env(n_envs, "mpe2" if mpe2 else "batched", **kwargs)


def matching_env_kwargs(model: MADDPG) -> dict:
    """The simple_spread settings (team size, observed neighbours) whose agent layout matches the model's."""
    n_agents = model.agent_layout.n_agents
    for neighbors in [None, *range(1, n_agents - 1)]:
        kwargs = {"n_agents": n_agents, "num_agent_neighbors": neighbors}
        if SimpleSpreadVecEnv(1, **kwargs).agent_layout == model.agent_layout:  # the same layout as mpe2's
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
    parser.add_argument("--n-envs", type=int, default=100, help="worlds stepped together to train the tiny team")
    parser.add_argument("--mpe2", action="store_true", help="step mpe2 itself instead of the batched env")
    add_threads_argument(parser)
    args = parser.parse_args()
    use_torch_threads(args.threads)

    if args.model is not None:
        model = MADDPG.load(args.model)
    else:
        print("no --model given: training a tiny team (use examples/quickstart.py --save-path for a real one)")
        env = make_env(4 if args.fast else args.n_envs, args.mpe2, n_agents=3)
        model = MADDPG("MlpPolicy", env, learning_starts=200, batch_size=32, transitions_per_update=50, buffer_size=5_000)
        with ctrl_c_ends_quietly(model):
            model.learn(total_timesteps=400 if args.fast else 20_000)
    if args.fast:
        args.episodes, args.eval_episodes = 1, 3
    output = Path(args.output or (Path(tempfile.mkdtemp()) / "team.gif" if args.fast else "team.gif"))

    env_kwargs = matching_env_kwargs(model)

    # 1. The numbers: the same evaluation as the paper (success = every landmark covered at the last step),
    #    one world per episode (mpe2: one env, episode after episode).
    eval_env = make_env(1 if args.mpe2 else args.eval_episodes, args.mpe2, **env_kwargs)
    result = evaluate_team(model, eval_env, n_episodes=args.eval_episodes, seed=0)
    print(
        f"{env_kwargs['n_agents']} agents over {result['n_episodes']} episodes: success {100 * result['success_rate']:.1f}%, "
        f"coverage {100 * result['coverage']:.1f}%, collisions/episode {result['collisions']:.2f}"
    )

    # 2. The pictures: every episode at once, world i starting as mpe2's reset(seed=1_000 + i), drawn at each
    #    step with render_mode="rgb_array". The worlds run one step past an episode: a VecEnv resets a world
    #    as soon as its episode ends, and the last picture should show where the team ended up.
    env = make_env(args.episodes, args.mpe2, render_mode="rgb_array", max_cycles=EPISODE_STEPS + 1, **env_kwargs)
    env.seed(1_000)
    obs = env.reset()
    images = [env.get_images()]  # images[step][world]
    for _ in range(EPISODE_STEPS):
        action, _ = model.predict(obs, deterministic=True)
        obs, _, _, infos = env.step(action)
        images.append(env.get_images())
    env.close()
    for episode, info in enumerate(infos):
        print(f"episode {episode}: coverage at the end {100 * info['coverage']:.0f}%, success {bool(info['success'])}")
    frames = [step[episode] for episode in range(args.episodes) for step in images]

    if args.scale != 1.0:
        height, width = frames[0].shape[:2]
        size = (round(width * args.scale), round(height * args.scale))
        frames = [np.asarray(Image.fromarray(frame).resize(size, Image.Resampling.LANCZOS)) for frame in frames]
    output.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(output, np.stack(frames), duration=1000 / args.fps, loop=0)
    print(f"wrote {len(frames)} frames to {output}")


if __name__ == "__main__":
    with ctrl_c_ends_quietly():  # Ctrl-C: one line, no traceback
        main()
