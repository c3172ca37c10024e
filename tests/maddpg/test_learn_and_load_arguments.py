"""``learn``'s budget and ``load``'s path: a budget that is not a whole number of steps, and a path with no saved model,
are refused by name with what to give; the forms SB3 users write (``1e6``, a path without ``.zip``) are taken."""

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import SimpleSpreadVecEnv

SMALL = dict(buffer_size=64, learning_starts=0, batch_size=8, policy_kwargs=dict(net_arch=[8]))


@pytest.mark.parametrize("budget", [-5, -1.0, 10.5, math.nan, math.inf, "100", True, None])
@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_a_budget_that_is_not_whole_steps_is_refused(algorithm: type[MADDPG], budget: Any) -> None:
    model = algorithm("MlpPolicy", SimpleSpreadVecEnv(n_envs=1, n_agents=2), **SMALL)
    with pytest.raises(ValueError, match=r"^total_timesteps \(env steps to train for.*\) must be a whole number >= 0"):
        model.learn(budget)
    assert model.num_timesteps == 0


@pytest.mark.parametrize("budget", [200, 200.0, 2e2, np.int64(200)])
def test_whole_budgets_train_that_many_steps(budget: Any) -> None:
    model = MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs=1, n_agents=2), **SMALL)
    model.learn(budget)  # 200: two whole rounds of the default 100 transitions per update
    assert model.num_timesteps == 200
    assert type(model._total_timesteps) is int  # saved and printed as a count, not 200.0


def test_a_budget_of_nothing_is_taken_and_said() -> None:
    model = MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs=1, n_agents=2), **SMALL)
    with pytest.warns(UserWarning, match="without a single gradient update"):
        model.learn(0)
    assert model.num_timesteps == 0


def test_a_path_without_a_saved_model_is_named_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    missing = tmp_path / "no_model"
    with pytest.raises(FileNotFoundError, match=rf"^No saved model at {missing}: MADDPG.load takes the path") as refused:
        MADDPG.load(missing)
    assert ".zip.zip" not in str(refused.value) and str(tmp_path) in str(refused.value)


def test_a_saved_model_loads_with_or_without_its_zip(tmp_path: Path) -> None:
    model = MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs=1, n_agents=2), **SMALL)
    model.save(tmp_path / "model")
    for path in (tmp_path / "model", tmp_path / "model.zip", str(tmp_path / "model")):
        assert MADDPG.load(path).agent_layout == model.agent_layout
