"""
Beyond MPE: train a team on a SISL env (PettingZoo's ``pettingzoo.sisl``) and score it against random actions and
against doing nothing, on the same evaluation episodes.

Every run is one JSON file in ``--results``: a trained team's (``<name>_seed<k>.json``) or a baseline's
(``<name>_random.json``, ``<name>_zero.json``). A file that exists is skipped, so the command resumes where it stopped
(delete a file to rerun it). ``summarize.py`` turns the files into ``summary.md``.

The score of an episode is the team return: the sum over the agents of their rewards, summed over the episode (higher
is better). Evaluation episode ``e`` is reset with seed ``eval_seed + e`` for every policy; the trained team acts
deterministically (``model.predict(obs, deterministic=True)`` on the gymnasium adapter).

Usage (one training process at a time)::

    python benchmarks/beyond_mpe/run.py --env pursuit --name pursuit --seeds 0,1,2 --steps 200000 --transitions-per-update 25
    python benchmarks/beyond_mpe/run.py --env pursuit --name pursuit --baselines
"""

import argparse
import contextlib
import json
import subprocess
import time
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import PettingZooToGym

HERE = Path(__file__).resolve().parent

ENV_PRESETS: dict[str, dict[str, Any]] = {
    # pettingzoo>=1.26 has no waterworld: pettingzoo==1.25.0 with pymunk<7.
    "waterworld": dict(n_pursuers=2, n_coop=1, n_sensors=8, max_cycles=200),
    # pettingzoo 1.27's pursuit_v5 (1.25's pursuit_v4 takes the same arguments): 4 pursuers, 4 evaders on 8 x 8, an
    # evader caught when 2 pursuers stand on it (PettingZoo's default: surrounded on every side).
    "pursuit": dict(x_size=8, y_size=8, n_pursuers=4, n_evaders=4, max_cycles=100, surround=False, n_catch=2),
    "multiwalker": dict(n_walkers=2, max_cycles=200),
}
"""Each env's settings here (PettingZoo's keyword arguments); ``--env-kwargs`` overrides any of them."""

NO_OP = {"pursuit": 4}
"""Each discrete env's no-op action (pursuit: 4, stay); continuous envs do nothing with a zero action."""


def make_parallel_env(env: str, kwargs: dict[str, Any]) -> Any:
    """:return: The SISL env's ``parallel_env`` (whichever version of it this PettingZoo has)."""
    if env == "waterworld":
        from pettingzoo.sisl import waterworld_v4 as module  # pettingzoo<=1.25 only
    elif env == "pursuit":
        try:
            from pettingzoo.sisl import pursuit_v5 as module
        except ImportError:  # pettingzoo<=1.26
            from pettingzoo.sisl import pursuit_v4 as module
    elif env == "multiwalker":
        from pettingzoo.sisl import multiwalker_v9 as module
    else:
        raise ValueError(f"unknown env {env!r}: one of {sorted(ENV_PRESETS)}")
    return module.parallel_env(**kwargs)


def make_env(env: str, kwargs: dict[str, Any]) -> PettingZooToGym:
    """:return: The SISL env as one gymnasium env (team reward: the sum of the agents' rewards)."""
    return PettingZooToGym(make_parallel_env(env, kwargs))


class BaselinePolicy:
    """Random actions (uniform over each agent's action space) or doing nothing (zero, or the no-op), as joint actions."""

    def __init__(self, env: PettingZooToGym, kind: str, no_op: int | None, seed: int) -> None:
        self.kind, self.no_op = kind, no_op
        self.rng = np.random.default_rng(seed)
        self.spaces = [env.parallel_env.action_space(agent) for agent in env.agent_layout.agent_ids]
        self.slices = env.agent_layout.action_slices
        self.size = int(env.action_space.shape[0])

    def act(self) -> np.ndarray:
        action = np.zeros(self.size, dtype=np.float32)
        for space, part in zip(self.spaces, self.slices, strict=True):
            if hasattr(space, "n"):  # Discrete: a one-hot slot
                choice = int(self.rng.integers(space.n)) if self.kind == "random" else self.no_op
                action[part][choice] = 1.0
            elif self.kind == "random":
                action[part] = self.rng.uniform(space.low, space.high).reshape(-1)
        return action


def evaluate(env: PettingZooToGym, act: Any, n_episodes: int, eval_seed: int) -> dict[str, Any]:
    """:return: The team return (the sum of the agents' rewards over the episode) of each evaluation episode."""
    returns, lengths = [], []
    for episode in range(n_episodes):
        obs, _ = env.reset(seed=eval_seed + episode)
        total, steps, done = 0.0, 0, False
        while not done:
            obs, reward, terminated, truncated, _ = env.step(act(obs))
            total += float(reward)
            steps += 1
            done = terminated or truncated
        returns.append(total)
        lengths.append(steps)
    return {
        "returns": returns,
        "mean_return": float(np.mean(returns)),
        "std_return": float(np.std(returns)),
        "mean_length": float(np.mean(lengths)),
    }


class EpisodeLog(BaseCallback):
    """Every training episode's team return and the env steps at its end (from ``VecMonitor``'s ``info["episode"]``)."""

    def __init__(self) -> None:
        super().__init__()
        self.episodes: list[tuple[int, float]] = []

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            if "episode" in info:
                self.episodes.append((int(self.num_timesteps), float(info["episode"]["r"])))
        return True


def curve(episodes: list[tuple[int, float]], steps: int, points: int = 10) -> list[dict[str, float]]:
    """:return: The mean training return of the episodes that ended in each tenth of the budget."""
    rows = []
    for k in range(points):
        lo, hi = steps * k / points, steps * (k + 1) / points
        inside = [ret for t, ret in episodes if lo < t <= hi]
        rows.append({"steps": int(hi), "episodes": len(inside), "mean_return": float(np.mean(inside)) if inside else None})
    return rows


def versions() -> dict[str, str]:
    found = {}
    for package in ("sb3-maddpg", "stable-baselines3", "torch", "pettingzoo", "pymunk", "box2d", "box2d-py", "numpy"):
        with contextlib.suppress(metadata.PackageNotFoundError):
            found[package] = metadata.version(package)
    return found


def commit() -> str:
    try:
        done = subprocess.run(["git", "rev-parse", "HEAD"], cwd=HERE, capture_output=True, text=True, check=True)
        return done.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def train_one(args: argparse.Namespace, env_kwargs: dict[str, Any], seed: int) -> dict[str, Any]:
    start_commit = commit()
    vec_env = VecMonitor(DummyVecEnv([lambda: make_env(args.env, env_kwargs) for _ in range(args.n_envs)]))
    vec_env.seed(seed)
    algorithm = {"maddpg": MADDPG, "matd3": MATD3}[args.algo]
    hyperparameters = dict(
        critic_sharing=args.critic_sharing,
        learning_rate=args.learning_rate,
        buffer_size=args.buffer_size,
        learning_starts=args.learning_starts,
        batch_size=args.batch_size,
        gamma=args.gamma,
        tau=args.tau,
        transitions_per_update=args.transitions_per_update,
        noise_std=args.noise_std,
        policy_kwargs=dict(net_arch=dict(pi=args.pi, qf=args.qf), share_parameters=args.share_parameters),
    )
    model = algorithm("MlpPolicy", vec_env, seed=seed, verbose=0, **hyperparameters)
    log = EpisodeLog()
    began = time.perf_counter()
    model.learn(total_timesteps=args.steps, callback=log)
    train_seconds = time.perf_counter() - began
    eval_env = make_env(args.env, env_kwargs)
    began = time.perf_counter()
    score = evaluate(eval_env, lambda obs: model.predict(obs, deterministic=True)[0], args.eval_episodes, args.eval_seed)
    eval_seconds = time.perf_counter() - began
    if args.save_model:
        model.save(Path(args.results) / f"{args.name}_seed{seed}.zip")
    return {
        "kind": "trained",
        "algo": args.algo,
        "seed": seed,
        "steps": int(model.num_timesteps),
        "hyperparameters": {**hyperparameters, "n_envs": args.n_envs, "algo": args.algo},
        "train_seconds": train_seconds,
        "steps_per_second": model.num_timesteps / train_seconds,
        "eval_seconds": eval_seconds,
        "training_curve": curve(log.episodes, args.steps),
        "commit": start_commit,
        **score,
    }


def baseline_one(args: argparse.Namespace, env_kwargs: dict[str, Any], kind: str) -> dict[str, Any]:
    env = make_env(args.env, env_kwargs)
    policy = BaselinePolicy(env, kind, NO_OP.get(args.env), seed=args.eval_seed)
    began = time.perf_counter()
    score = evaluate(env, lambda obs: policy.act(), args.eval_episodes, args.eval_seed)
    return {"kind": kind, "eval_seconds": time.perf_counter() - began, "commit": commit(), **score}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", choices=sorted(ENV_PRESETS), required=True)
    parser.add_argument("--env-kwargs", type=json.loads, default={}, help="JSON, overrides the env preset's settings")
    parser.add_argument("--name", required=True, help="the results' file prefix")
    parser.add_argument("--results", default=str(HERE / "results"))
    parser.add_argument("--baselines", action="store_true", help="evaluate random actions and doing nothing, no training")
    parser.add_argument("--seeds", default="0", help="comma-separated training seeds")
    parser.add_argument("--steps", type=int, default=300_000, help="env steps per run (all envs counted)")
    parser.add_argument("--algo", choices=("maddpg", "matd3"), default="maddpg")
    parser.add_argument("--critic-sharing", default="full")
    parser.add_argument("--n-envs", type=int, default=8)
    parser.add_argument("--learning-rate", type=float, default=1e-3)
    parser.add_argument("--buffer-size", type=int, default=100_000)
    parser.add_argument("--learning-starts", type=int, default=10_000)
    parser.add_argument("--batch-size", type=int, default=1024)
    parser.add_argument("--gamma", type=float, default=0.95)
    parser.add_argument("--tau", type=float, default=0.01)
    parser.add_argument("--transitions-per-update", type=int, default=100)
    parser.add_argument("--noise-std", type=float, default=0.1)
    parser.add_argument("--pi", type=lambda s: [int(x) for x in s.split(",")], default=[64, 64])
    parser.add_argument("--qf", type=lambda s: [int(x) for x in s.split(",")], default=[64, 64, 64])
    parser.add_argument("--share-parameters", action="store_true")
    parser.add_argument("--eval-episodes", type=int, default=50)
    parser.add_argument("--eval-seed", type=int, default=10_000)
    parser.add_argument("--save-model", action="store_true")
    args = parser.parse_args()

    env_kwargs = {**ENV_PRESETS[args.env], **args.env_kwargs}
    results = Path(args.results)
    results.mkdir(parents=True, exist_ok=True)
    common = {
        "env": args.env,
        "env_kwargs": env_kwargs,
        "eval_episodes": args.eval_episodes,
        "eval_seed": args.eval_seed,
        "metric": "team return: the sum over agents of their episode rewards (higher is better)",
        "versions": versions(),
    }
    jobs = [("random", None), ("zero", None)] if args.baselines else [("trained", int(s)) for s in args.seeds.split(",")]
    for kind, seed in jobs:
        path = results / (f"{args.name}_{kind}.json" if seed is None else f"{args.name}_seed{seed}.json")
        if path.exists():
            print(f"{path.name}: done before, skipped")
            continue
        began = time.perf_counter()
        row = baseline_one(args, env_kwargs, kind) if seed is None else train_one(args, env_kwargs, seed)
        row = {"name": args.name, **common, **row, "wall_seconds": time.perf_counter() - began}
        path.write_text(json.dumps(row, indent=1) + "\n")
        extra = f", {row['steps_per_second']:.0f} steps/s" if seed is not None else ""
        print(
            f"{path.name}: mean team return {row['mean_return']:.2f} (std {row['std_return']:.2f}), "
            f"{row['wall_seconds']:.0f} s{extra}",
            flush=True,
        )


if __name__ == "__main__":
    main()
