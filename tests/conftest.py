"""Shared pytest setup."""

import os
import signal
import sys

# A suite started in the background from a script (`cmd &` without job control) inherits SIGINT ignored; every subprocess
# would too, and the tests that press Ctrl-C on the CLI would then wait on a process that never sees it. Python's own
# handler here makes the subprocesses start with the default action, as from a terminal.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

# Headless rendering: pygame (imported by mpe2) must see this before it opens a display.
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

# One torch thread (unless OMP_NUM_THREADS says otherwise), as the package's entry points use: the tests' tiny
# networks gain nothing from more, and on a shared CPU several threads wait on each other.
from sb3_maddpg.common.torch_threads import use_torch_threads  # after the SDL variables

use_torch_threads()

from collections.abc import Callable  # noqa: E402  (after the SDL variables, as above)
from typing import Any  # noqa: E402

import pytest  # noqa: E402
import torch as th  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

from sb3_maddpg import MADDPG  # noqa: E402
from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples  # noqa: E402
from sb3_maddpg.envs import make_simple_spread  # noqa: E402

# Generated inputs (hypothesis): a small, seeded sample in CI; HYPOTHESIS_PROFILE=long for the longer run by hand.
settings.register_profile("ci", max_examples=12, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("long", max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

BATCH = 8
"""Rows of :func:`replay_batch`'s batches."""


@pytest.fixture(autouse=True)
def auto_device_is_the_cpu(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    """
    On a machine with a GPU, SB3's ``device="auto"`` means the CPU in the tests: they build models with the default
    device and check them against tensors made on the CPU (hand computations, batches, numpy). A test asks for CUDA by
    name (``device="cuda"``), or is marked ``sb3_auto_device`` to see SB3's own choice. Without a GPU nothing changes.
    Only this process's SB3 is patched: spawned workers and subprocesses (the CLI tests), and the run groups' own
    ``--device auto`` (``torch.cuda.is_available``), still pick CUDA there.
    """
    if not th.cuda.is_available() or request.node.get_closest_marker("sb3_auto_device") is not None:
        return
    from stable_baselines3.common import utils

    original = utils.get_device

    def get_device(device: th.device | str = "auto") -> th.device:
        return original("cpu" if device == "auto" else device)

    for name, module in list(sys.modules.items()):
        if name.startswith(("stable_baselines3", "sb3_maddpg")) and vars(module).get("get_device") is original:
            monkeypatch.setattr(module, "get_device", get_device)


@pytest.fixture
def collected_model() -> Callable[..., MADDPG]:
    """
    Build a model whose buffer holds 60 real steps of simple_spread (3 agents) and that has made no update
    (``learning_starts`` is beyond them): the update-math tests' model. ``selected`` selects the nearest other agent
    (a real subset of 3); keyword arguments go to the algorithm, ``policy_kwargs`` over ``net_arch=[16, 16]``.
    """

    def build(scheme: Any = "full", algorithm: type[MADDPG] = MADDPG, env: Any = None, **kwargs: Any) -> MADDPG:
        if scheme == "selected":
            kwargs.setdefault("selector", 1)
        kwargs["policy_kwargs"] = {"net_arch": [16, 16], **kwargs.get("policy_kwargs", {})}
        settings = {"learning_starts": 10_000, "buffer_size": 1_000, "batch_size": BATCH, "seed": 0, **kwargs}
        model = algorithm("MlpPolicy", env or make_simple_spread(n_agents=3), critic_sharing=scheme, **settings)
        model.learn(60)
        return model

    return build


@pytest.fixture
def replay_batch() -> Callable[[MADDPG], MultiAgentReplayBufferSamples]:
    """Sample a model's buffer: 8 rows, each agent's reward its own (random) and every third row terminal."""

    def sample(model: MADDPG) -> MultiAgentReplayBufferSamples:
        data = model.replay_buffer.sample(BATCH)
        n_agents = data.rewards.shape[1]
        dones = th.zeros(BATCH, n_agents)
        dones[::3] = 1.0
        return data._replace(rewards=th.randn(BATCH, n_agents), dones=dones)

    return sample
