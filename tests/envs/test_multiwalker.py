"""SISL multiwalker as a task (issue 57, item 2): the walkers' positions and the package's distance read from the env's
own state, and a tiny sweep of the ``multiwalker`` preset through ``sb3-maddpg run`` and ``report``."""

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pettingzoo.sisl.multiwalker_v9", reason="multiwalker needs the sisl extra (Box2D)")

from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.cli.main import main
from sb3_maddpg.envs import RandomTeamPolicy
from sb3_maddpg.envs.sisl import GONE, multiwalker_env, sisl_state
from sb3_maddpg.experiments.references import NoOpTeamPolicy


def test_the_positions_are_the_walkers_hulls_and_a_fallen_walker_is_gone() -> None:
    env = multiwalker_env(n_walkers=3, max_cycles=200)
    _, info = env.reset(seed=3)
    done, steps = False, 0
    while not done:
        state = sisl_state(env.parallel_env)
        hulls = [None if walker.hull is None else tuple(walker.hull.position) for walker in state.walkers]
        expected = np.array([GONE if hull is None else hull for hull in hulls], dtype=np.float32)
        np.testing.assert_array_equal(info["agent_positions"], expected)
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        done, steps = terminated or truncated, steps + 1
    assert steps < 200  # standing still, a walker falls and ends the episode
    assert (info["agent_positions"] == np.float32(GONE[0])).all(axis=1).any()  # its body is gone at the end


def test_the_package_distance_is_how_far_the_package_moved_from_its_start() -> None:
    env = multiwalker_env(n_walkers=3, max_cycles=60)
    _, info = env.reset(seed=0)
    start = sisl_state(env.parallel_env).package.position.x
    assert info["package_distance"] == pytest.approx(0.0, abs=1e-5)  # it starts at the walkers' middle
    rng = np.random.default_rng(0)
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        done = terminated or truncated
        moved = sisl_state(env.parallel_env).package.position.x - start
        assert info["package_distance"] == pytest.approx(moved, abs=1e-5)
    scores = evaluate_team(RandomTeamPolicy(env.action_space, seed=0), multiwalker_env(n_walkers=3, max_cycles=60), 3)
    assert "package_distance" in scores and np.isfinite(scores["package_distance"])


def test_the_time_limit_truncates_and_a_fall_terminates() -> None:
    env = multiwalker_env(n_walkers=3, max_cycles=5)
    env.reset(seed=0)
    for _ in range(4):
        assert env.step(np.zeros(env.action_space.shape, dtype=np.float32))[2:4] == (False, False)
    assert env.step(np.zeros(env.action_space.shape, dtype=np.float32))[2:4] == (False, True)  # PettingZoo: terminated
    env = multiwalker_env(n_walkers=3, max_cycles=500)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        done = terminated or truncated
    assert terminated and not truncated  # standing still, a walker falls: the task's own end


def test_every_episode_after_a_seed_starts_the_same_whatever_the_team_did() -> None:
    """Multiwalker draws its terrain at reset and noise at every step from one generator: each episode is seeded."""
    starts = []
    for torque in (0.0, 1.0):
        env = multiwalker_env(n_walkers=3, max_cycles=30)
        env.reset(seed=7)
        done = False
        while not done:
            _, _, terminated, truncated, _ = env.step(np.full(env.action_space.shape, torque, dtype=np.float32))
            done = terminated or truncated
        starts.append(env.reset()[0])
    np.testing.assert_array_equal(starts[0], starts[1])


def test_doing_nothing_is_zero_torque() -> None:
    env = multiwalker_env(n_walkers=3, max_cycles=20)
    team = NoOpTeamPolicy(env.action_space, env.agent_layout)
    assert np.array_equal(team.predict(np.zeros((2, *env.observation_space.shape)))[0], np.zeros((2, 12)))


def test_a_tiny_multiwalker_sweep_through_the_cli_is_scored_by_its_metric_beside_its_references(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    kwargs = '{"learning_starts": 100, "batch_size": 32, "buffer_size": 2000, "policy_kwargs": {"net_arch": [16, 16]}}'
    results = str(tmp_path / "results")
    argv = ["run", "--config", "multiwalker", "--episodes", "6", "--episode-length", "40", "--seeds", "[0]"]
    argv += ["--env-kwargs", '{"n_walkers": 3, "max_cycles": 40}', "--schemes", "full,selected"]
    argv += ["--model-kwargs", kwargs, "--eval-episodes", "2", "--curve-points", "0", "--n-envs", "2"]
    assert main([*argv, "--results", results, "--quiet"]) == 0
    summary = json.loads((tmp_path / "results" / "multiwalker" / "selected" / "seed_000" / "summary.json").read_text())
    assert {"package_distance", "return_mean"} <= set(summary["score"])
    references = json.loads((tmp_path / "results" / "multiwalker" / "references.json").read_text())
    assert set(references["policies"]) == {"random", "nothing"}
    capsys.readouterr()
    assert main(["report", results, "--no-plots"]) == 0
    assert "| reference: nothing | 0 |" in (tmp_path / "results" / "report" / "references.md").read_text()
