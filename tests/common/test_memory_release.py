"""Freed heap memory goes back to the system while a model trains (glibc's ``malloc_trim``, every 40 gradient steps)."""

import ctypes
import sys
from pathlib import Path
from typing import Any

import pytest

from sb3_maddpg import MADDPG
from sb3_maddpg.common import memory_release
from sb3_maddpg.envs import SimpleSpreadVecEnv


@pytest.fixture
def trims(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The calls of ``malloc_trim``, recorded (and not made)."""
    calls: list[int] = []

    def malloc_trim(pad: int) -> int:
        calls.append(pad)
        return 1

    monkeypatch.setattr(memory_release, "MALLOC_TRIM", malloc_trim)
    return calls


def test_memory_is_released_once_every_40_gradient_steps(trims: list[int]) -> None:
    assert memory_release.release_freed_memory(39, 0) == 0 and trims == []
    assert memory_release.release_freed_memory(40, 0) == 40 and trims == [0]  # pad 0: every free page at the top
    assert memory_release.release_freed_memory(79, 40) == 40 and trims == [0]


def test_training_releases_freed_memory_as_it_goes(trims: list[int]) -> None:
    # One gradient step per 2 transitions: 150 steps over the 300 transitions past learning_starts.
    env = SimpleSpreadVecEnv(4, n_agents=2)
    model = MADDPG("MlpPolicy", env, learning_starts=100, batch_size=32, buffer_size=1_000, transitions_per_update=2)
    model.learn(400)
    assert model._n_updates >= 120
    assert len(trims) == model._n_updates // memory_release.TRIM_EVERY  # every 40, at the rollout after the 40th


def test_a_save_does_not_carry_the_release_count(tmp_path: Path) -> None:
    model = MADDPG("MlpPolicy", SimpleSpreadVecEnv(1, n_agents=2), learning_starts=10, batch_size=8, buffer_size=100)
    model._memory_released_at = 40
    model.save(tmp_path / "model.zip")
    assert MADDPG.load(tmp_path / "model.zip")._memory_released_at == 0


def _has_glibc() -> bool:
    try:
        ctypes.CDLL("libc.so.6")
    except OSError:
        return False
    return sys.platform.startswith("linux")


@pytest.mark.skipif(not _has_glibc(), reason="malloc_trim is glibc's (Linux; not musl, macOS or Windows)")
def test_glibc_malloc_trim_is_found_where_glibc_is() -> None:
    assert memory_release.MALLOC_TRIM is not None


def test_a_run_config_for_build_model_says_to_pass_its_task() -> None:
    from sb3_maddpg.experiments import SMOKE
    from sb3_maddpg.experiments.runner import build_model

    with pytest.raises(TypeError, match=r"build_model takes a run's task, got a RunConfig: build_model\(run_task"):
        build_model(SMOKE.runs()[0])  # type: ignore[arg-type]


def test_a_run_group_releases_freed_memory_as_a_model_does(trims: list[int]) -> None:
    from sb3_maddpg.run_group import RunGroup

    env = SimpleSpreadVecEnv(2, n_agents=2)
    settings: dict[str, Any] = {"learning_starts": 20, "batch_size": 16, "buffer_size": 500, "transitions_per_update": 10}
    models = [MADDPG("MlpPolicy", env, seed=seed, device="cpu", **settings) for seed in (0, 1)]
    group = RunGroup(models)
    group.learn(2_000)
    assert group.n_updates >= 80
    assert len(trims) == group.n_updates // memory_release.TRIM_EVERY
