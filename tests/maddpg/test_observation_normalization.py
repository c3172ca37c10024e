"""Runs that normalise observations (``normalize_observations``, SB3's VecNormalize with raw rewards): the statistics are
saved beside each checkpoint and each checkpoint is scored with its own, the behaviour is read from raw observations,
and what cannot take them (a run group) is refused."""

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecNormalize

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.cli.main import main
from sb3_maddpg.experiments import SMOKE, run_sweep
from sb3_maddpg.experiments.group_plan import BatchedRunRefused, check_batched
from sb3_maddpg.experiments.runner import (
    NormalizedObservationPolicy,
    build_model,
    final_behaviour,
    load_observation_statistics,
    statistics_path,
)
from sb3_maddpg.experiments.tasks import run_task


def checkpoints(directory: Path) -> list[Path]:
    """:return: A run's checkpoint model files, in the order of their steps."""
    return sorted((directory / "checkpoints").glob("model_*_steps.zip"), key=lambda path: int(path.stem.split("_")[1]))


NORMALIZED = dataclasses.replace(
    SMOKE, name="normalized", schemes=("full",), seeds=(0,), keep_checkpoints=True, normalize_observations=True
)


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One normalising smoke run, trained and scored; its directory."""
    results = tmp_path_factory.mktemp("normalized")
    result = run_sweep([NORMALIZED], results, verbose=0)
    assert result.ok, result.failed
    return results / "normalized" / "full" / "seed_000"


def test_each_checkpoint_is_scored_with_its_own_statistics(finished_run: Path) -> None:
    config = NORMALIZED.runs()[0]
    with open(finished_run / "checkpoint_evals.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    models = checkpoints(finished_run)
    assert len(models) == len(rows) == config.n_checkpoints
    for row, path in zip(rows, models):
        assert statistics_path(path).exists()
        model = MADDPG.load(path, device="cpu")
        eval_env = run_task(config).make_eval_env(config.eval_episodes)
        load_observation_statistics(eval_env, path)
        scored = evaluate_team(model, eval_env, n_episodes=config.eval_episodes, seed=config.eval_seed)
        assert scored["return_mean"] == pytest.approx(float(row["return_mean"]))
        # Without the statistics (raw observations) the same model acts otherwise: they were applied.
        raw = evaluate_team(model, eval_env.venv, n_episodes=config.eval_episodes, seed=config.eval_seed)
        assert raw["return_mean"] != pytest.approx(scored["return_mean"])


def test_the_behaviour_is_read_from_raw_observations(finished_run: Path) -> None:
    # The behaviour's min-dist sum comes from the episodes' last raw observations; on the same seeded episodes it is
    # the last checkpoint's evaluated min-dist sum (from the env's landmark distances). Normalised ones would differ.
    config = NORMALIZED.runs()[0]
    summary = json.loads((finished_run / "summary.json").read_text())
    with open(finished_run / "checkpoint_evals.csv", newline="") as file:
        last = list(csv.DictReader(file))[-1]
    assert summary["behaviour"]["min_dist_sum"] == pytest.approx(float(last["min_dist_sum"]), rel=1e-5)
    path = checkpoints(finished_run)[-1]
    eval_env = run_task(config).make_eval_env(config.eval_episodes)
    load_observation_statistics(eval_env, path)
    again = final_behaviour(run_task(config), MADDPG.load(path, device="cpu"), eval_env)
    assert again == pytest.approx(summary["behaviour"])


def test_a_normalising_run_uses_obs_only_vecnormalize_and_the_wrapper_normalises() -> None:
    model = build_model(run_task(NORMALIZED.runs()[0]))
    normalization = model.get_vec_normalize_env()
    assert isinstance(normalization, VecNormalize) and normalization.norm_obs and not normalization.norm_reward
    normalization.obs_rms.mean[:] = 0.5  # statistics of its own, so that normalising changes the observations
    normalization.obs_rms.var[:] = 4.0
    observations = np.random.default_rng(0).normal(size=(3, *model.observation_space.shape)).astype(np.float32)
    expected, _ = model.predict(normalization.normalize_obs(observations), deterministic=True)
    actions, _ = NormalizedObservationPolicy(model, normalization).predict(observations)
    np.testing.assert_allclose(actions, expected)
    assert not np.allclose(actions, model.predict(observations, deterministic=True)[0])


def test_missing_statistics_and_run_groups_are_refused(tmp_path: Path) -> None:
    config = NORMALIZED.runs()[0]
    with pytest.raises(FileNotFoundError, match=r"model_5_steps.vecnormalize.pkl is missing: a run that normalises"):
        load_observation_statistics(run_task(config).make_eval_env(2), tmp_path / "model_5_steps.zip")
    with pytest.raises(BatchedRunRefused, match=r"normalized/full/seed_000 .*cannot train in a run group.*VecNormalize"):
        check_batched(NORMALIZED.runs(), device="cpu")


def test_the_command_line_turns_it_on(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["run", "--config", "smoke", "--schemes", "full", "--results", str(tmp_path), "--dry-run"]
    assert main([*argv, "--normalize-observations"]) == 0
    assert '"normalize_observations": true' in capsys.readouterr().out
    assert main(argv) == 0
    assert '"normalize_observations": false' in capsys.readouterr().out
