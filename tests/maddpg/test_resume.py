"""A training that goes on from a loaded model says, once, when its replay buffer is too empty to go on from, and
stays quiet when the buffer saved with the model is loaded back (or when it starts over)."""

import warnings
from pathlib import Path

import pytest

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import SimpleSpreadVecEnv

LEARNING_STARTS = 200
SETTINGS = dict(learning_starts=LEARNING_STARTS, batch_size=16, buffer_size=1_000, policy_kwargs=dict(net_arch=[8]))
EMPTY_RESUME = r"^learn\(reset_num_timesteps=False\) goes on at step 400, past learning_starts=200, with 0 transitions"


def _saved(tmp_path: Path, algorithm: type[MADDPG]) -> tuple[Path, Path]:
    """:return: A model trained past learning_starts, saved, and its replay buffer, saved apart."""
    model = algorithm("MlpPolicy", SimpleSpreadVecEnv(n_envs=4, n_agents=3), seed=0, **SETTINGS)
    model.learn(400)
    model.save(tmp_path / "model")
    model.save_replay_buffer(tmp_path / "buffer")
    return tmp_path / "model.zip", tmp_path / "buffer.pkl"


@pytest.mark.parametrize("algorithm", [MADDPG, MATD3])
def test_going_on_from_an_empty_buffer_warns_once(tmp_path: Path, algorithm: type[MADDPG]) -> None:
    model_file, _ = _saved(tmp_path, algorithm)
    loaded = algorithm.load(model_file, env=SimpleSpreadVecEnv(n_envs=4, n_agents=3))
    with pytest.warns(UserWarning, match=EMPTY_RESUME) as caught:
        loaded.learn(100, reset_num_timesteps=False)
    message = str(next(w.message for w in caught if "goes on at step" in str(w.message)))
    assert "load_replay_buffer" in message and "save_replay_buffer" in message and "overfit" in message
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # said once: the next learn is quiet, though the buffer is still small
        loaded.learn(100, reset_num_timesteps=False)


def test_the_saved_buffer_loaded_back_is_quiet(tmp_path: Path) -> None:
    model_file, buffer_file = _saved(tmp_path, MADDPG)
    loaded = MADDPG.load(model_file, env=SimpleSpreadVecEnv(n_envs=4, n_agents=3))
    loaded.load_replay_buffer(buffer_file)
    assert loaded.replay_buffer.size() * loaded.replay_buffer.n_envs == 400
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loaded.learn(100, reset_num_timesteps=False)
    assert loaded.num_timesteps == 500


def test_starting_over_or_before_learning_starts_is_quiet(tmp_path: Path) -> None:
    model_file, _ = _saved(tmp_path, MADDPG)
    loaded = MADDPG.load(model_file, env=SimpleSpreadVecEnv(n_envs=4, n_agents=3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loaded.learn(LEARNING_STARTS + 100)  # reset_num_timesteps=True: the buffer fills before the first update
    fresh = MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs=4, n_agents=3), seed=0, **SETTINGS)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fresh.learn(LEARNING_STARTS + 100, reset_num_timesteps=False)  # from step 0: it fills its buffer first


def test_a_buffer_smaller_than_learning_starts_full_is_quiet(tmp_path: Path) -> None:
    """A buffer that holds fewer rows than learning_starts is as full as it gets once full: nothing to warn of."""
    small = {**SETTINGS, "buffer_size": 100}
    model = MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs=4, n_agents=3), seed=0, **small).learn(400)
    assert model.replay_buffer.full
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.learn(100, reset_num_timesteps=False)
