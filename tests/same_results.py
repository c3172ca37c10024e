"""
Fingerprints of short fixed-seed training runs: the replay buffer, every network and optimiser state, the counters,
and one exploring evaluation, hashed bit for bit.

A refactoring that keeps the algorithm's results keeps these hashes (on the same platform and library versions):
``tests/test_same_results.py`` compares against ``tests/data/same_results.json``, recorded before the refactoring
of issue 19 (update schedule, noise and losses out of ``maddpg.py``). Record it again with
``python tests/same_results.py`` only for a change that is meant to change results, and say so.
"""

import hashlib
import json
import platform
import sys
from pathlib import Path
from typing import Any

import numpy as np
import stable_baselines3
import torch as th
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.noise import OrnsteinUhlenbeckActionNoise

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import make_simple_spread
from sb3_maddpg.evaluation import evaluate_team

REFERENCE = Path(__file__).parent / "data" / "same_results.json"
TINY = dict(learning_starts=50, batch_size=16, buffer_size=1_000, policy_kwargs=dict(net_arch=[8]), seed=0)
SCHEMES = ("independent", "full", "observations", "actions", "selected", "attention", "learned_selection")

CONFIGS: dict[str, dict[str, Any]] = {
    # The per-transition rule over 2 envs, and a second learn() that carries the credit over.
    **{f"{scheme}_earned_2envs": dict(scheme=scheme, n_envs=2, transitions_per_update=20) for scheme in SCHEMES},
    # SB3's train_freq semantics.
    "full_sb3_rule": dict(scheme="full", n_envs=1, train_freq=(1, "episode"), gradient_steps=2),
    # A user's noise, no clipping, no regulariser, gradient_steps alone.
    "full_ou_noise": dict(scheme="full", n_envs=1, ou_noise=True, max_grad_norm=None, actor_reg_coef=0.0, gradient_steps=3),
    # Per-agent noise and a discrete team.
    "full_per_agent_noise": dict(scheme="full", n_envs=1, noise_std=[0.1, 0.0, 0.3]),
    "discrete": dict(scheme="full", n_envs=1, continuous_actions=False, noise_std=0.3, transitions_per_update=10),
}


def _digest(value: Any) -> str:
    if isinstance(value, th.Tensor):
        value = value.detach().cpu().numpy()
    array = np.ascontiguousarray(value)
    return hashlib.sha256(str(array.dtype).encode() + str(array.shape).encode() + array.tobytes()).hexdigest()[:16]


def _flatten(state: Any, prefix: str, out: dict[str, str]) -> None:
    if isinstance(state, dict):
        for key in sorted(state, key=str):
            _flatten(state[key], f"{prefix}/{key}", out)
    elif isinstance(state, list | tuple):
        for index, item in enumerate(state):
            _flatten(item, f"{prefix}/{index}", out)
    elif isinstance(state, th.Tensor | np.ndarray):
        out[prefix] = _digest(state)
    else:
        out[prefix] = repr(state)


def run(config: dict[str, Any]) -> dict[str, str]:
    """Train one configuration and fingerprint it."""
    config = dict(config)
    scheme = config.pop("scheme")
    n_envs = config.pop("n_envs")
    env_kwargs = dict(n_agents=3, continuous_actions=config.pop("continuous_actions", True))
    if config.pop("ou_noise", False):
        config["action_noise"] = OrnsteinUhlenbeckActionNoise(np.zeros(15), np.full(15, 0.3))
    env = make_vec_env(make_simple_spread, n_envs=n_envs, env_kwargs=env_kwargs)
    model = MADDPG("MlpPolicy", env, critic_sharing=scheme, **{**TINY, **config})
    model.learn(150)
    model.learn(100, reset_num_timesteps=False)
    out: dict[str, str] = {"num_timesteps": str(model.num_timesteps), "n_updates": str(model._n_updates)}
    buffer = model.replay_buffer
    for name in ("observations", "next_observations", "actions", "rewards", "dones", "timeouts", "selections"):
        out[f"buffer/{name}"] = _digest(getattr(buffer, name)[: buffer.pos])
    _flatten(model.policy.state_dict(), "policy", out)
    _flatten(model.actor.optimizer.state_dict()["state"], "actor_optimizer", out)
    _flatten(model.critic.optimizer.state_dict()["state"], "critic_optimizer", out)
    np.random.seed(3)
    result = evaluate_team(model, make_simple_spread(**env_kwargs), n_episodes=2, seed=3, deterministic=False)
    out["explored_return"] = repr(result["return_mean"])
    return out


def versions() -> dict[str, str]:
    """What the hashes depend on besides the code."""
    return {
        "torch": th.__version__,
        "numpy": np.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "machine": platform.machine(),
        "torch_threads": str(th.get_num_threads()),
    }


if __name__ == "__main__":
    th.set_num_threads(1)
    names = sys.argv[1:] or list(CONFIGS)
    fingerprints = {name: run(CONFIGS[name]) for name in names}
    REFERENCE.write_text(json.dumps({"versions": versions(), "runs": fingerprints}, indent=1, sort_keys=True) + "\n")
    print(f"wrote {REFERENCE}: {len(fingerprints)} runs")
