"""
Fingerprints of short fixed-seed training runs: the replay buffer, every network and optimiser state, the counters,
and one exploring evaluation, hashed bit for bit.

A refactoring that keeps the algorithm's results keeps these hashes (on the same CPU and library versions):
``tests/test_same_results.py`` compares against ``tests/data/same_results.json``, which holds one recording per
machine (its :func:`versions`); on a machine without one the test is skipped. The first was recorded before the
refactoring of issue 19 (update schedule, noise and losses out of ``maddpg.py``), on a machine whose CPU it does not
name, so it serves none now. The same code gives other bits on another CPU (the BLAS kernels differ: on an AVX-512
Xeon, MKL limited to SSE4.2 changes 35 of 50 hashes), so each CPU gets its own recording, made with code that passed
on a recorded one: ``python tests/same_results.py`` adds or replaces this machine's. Record again for every machine
only for a change that is meant to change results, and say so.
"""

import hashlib
import json
import platform
import re
from pathlib import Path
from typing import Any

import numpy as np
import stable_baselines3
import torch as th
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.noise import OrnsteinUhlenbeckActionNoise

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.envs import make_simple_spread

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


def cpu() -> str:
    """:return: The CPU as its kernels see it: the model name (Linux's /proc/cpuinfo) and torch's CPU capability."""
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text()
    except OSError:
        cpuinfo = ""
    model = re.search(r"^model name\s*:\s*(.+)$", cpuinfo, re.MULTILINE)
    return f"{model.group(1).strip() if model else platform.processor()} ({th.backends.cpu.get_cpu_capability()})"


def versions() -> dict[str, str]:
    """What the hashes depend on besides the code."""
    return {
        "torch": th.__version__,
        "numpy": np.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "machine": platform.machine(),
        "cpu": cpu(),
        "torch_threads": str(th.get_num_threads()),
    }


def recording_for(recordings: list[dict[str, Any]], here: dict[str, str]) -> dict[str, Any] | None:
    """
    :param recordings: The reference file's recordings, each with its ``versions`` and ``runs``.
    :param here: This machine's :func:`versions`.
    :return: The recording made here: the one whose versions all equal this machine's, naming the most of them;
        ``None`` if none is.
    """
    matching = [r for r in recordings if all(here.get(key) == value for key, value in r["versions"].items())]
    return max(matching, key=lambda recording: len(recording["versions"]), default=None)


if __name__ == "__main__":
    th.set_num_threads(1)
    here = versions()
    recordings = json.loads(REFERENCE.read_text())["recordings"] if REFERENCE.exists() else []
    others = [recording for recording in recordings if recording["versions"] != here]
    runs = {name: run(config) for name, config in CONFIGS.items()}
    REFERENCE.write_text(
        json.dumps({"recordings": [*others, {"versions": here, "runs": runs}]}, indent=1, sort_keys=True) + "\n"
    )
    print(f"wrote {REFERENCE}: {len(runs)} runs for {here} ({len(others)} other recording(s) kept)")
