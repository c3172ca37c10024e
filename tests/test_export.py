"""Each agent's actor exported alone (ONNX, TorchScript) gives what the model's predict gives for that agent, from that
agent's own observation: homogeneous, heterogeneous, shared-parameter and mixed continuous/discrete teams."""

import json
from pathlib import Path

import numpy as np
import onnxruntime
import pytest
import torch as th

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import PettingZooToGym, make_mpe_env, make_simple_spread
from sb3_maddpg.export import MANIFEST, export_actors
from sb3_maddpg.version import __version__
from tests.mixed_team import MixedTeam

FAST = {"learning_starts": 50, "batch_size": 16, "transitions_per_update": 10, "policy_kwargs": {"net_arch": [16, 16]}}

TEAMS = {
    "homogeneous": lambda: make_simple_spread(n_agents=3),
    "shared_parameters": lambda: make_simple_spread(n_agents=3),
    "heterogeneous": lambda: make_mpe_env("simple_speaker_listener"),  # observations of 3 and 11, actions of 3 and 5
    "mixed": lambda: PettingZooToGym(MixedTeam()),  # a Box(-1, 1) agent and a Discrete(3) one
    "layer_norm": lambda: make_mpe_env("simple_speaker_listener"),  # heterogeneous, with layer normalisation
}


def trained(team: str) -> MADDPG:
    kwargs = dict(FAST)
    options = {"shared_parameters": "share_parameters", "layer_norm": "layer_norm"}
    if team in options:
        kwargs["policy_kwargs"] = {**FAST["policy_kwargs"], options[team]: True}
    model = MADDPG("MlpPolicy", TEAMS[team](), seed=0, **kwargs)
    model.learn(300)  # trained weights, not the initial ones
    return model


def observations(model: MADDPG, n: int = 32) -> np.ndarray:
    return np.random.default_rng(1).normal(size=(n, model.observation_space.shape[0])).astype(np.float32)


@pytest.mark.parametrize("team", sorted(TEAMS))
def test_each_exported_actor_acts_as_the_model_from_its_own_observation(team: str, tmp_path: Path) -> None:
    model = trained(team)
    files = export_actors(model, tmp_path)
    layout = model.agent_layout
    obs = observations(model)
    joint, _ = model.predict(obs, deterministic=True)
    assert sorted(files) == sorted(layout.agent_ids) and all(path.name == f"{a}.onnx" for a, path in files.items())
    for i, agent_id in enumerate(layout.agent_ids):
        session = onnxruntime.InferenceSession(str(files[agent_id]))
        (action,) = session.run(None, {"observation": obs[:, layout.obs_slices[i]]})  # only its own observation
        expected = joint[:, layout.action_slices[i]]
        if layout.is_discrete(i):
            assert action.dtype == np.int64 and action.shape == (len(obs),)
            np.testing.assert_array_equal(action, expected.argmax(axis=1))  # the index of the model's one-hot
        else:
            np.testing.assert_allclose(action, expected, atol=1e-5)
            assert (action >= model.action_space.low[layout.action_slices[i]] - 1e-6).all()


def test_torchscript_export_matches_too(tmp_path: Path) -> None:
    model = trained("heterogeneous")
    files = export_actors(model, tmp_path, format="torchscript")
    layout = model.agent_layout
    obs = observations(model)
    joint, _ = model.predict(obs, deterministic=True)
    for i, agent_id in enumerate(layout.agent_ids):
        actor = th.jit.load(str(files[agent_id]))
        action = actor(th.as_tensor(obs[:, layout.obs_slices[i]])).numpy()
        np.testing.assert_allclose(action, joint[:, layout.action_slices[i]], atol=1e-5)


def test_the_manifest_describes_each_agent(tmp_path: Path) -> None:
    model = trained("mixed")
    export_actors(model, tmp_path)
    manifest = json.loads((tmp_path / MANIFEST).read_text())
    assert manifest["format"] == "onnx" and manifest["sb3_maddpg_version"] == __version__
    assert manifest["onnx"] == {"input": "observation", "output": "action", "opset": 17}
    mover, chooser = manifest["agents"]
    assert mover == {
        "agent_id": "mover",
        "file": "mover.onnx",
        "observation_size": 1,
        "observation_slice": [0, 1],
        "action": {"type": "box", "low": [-1.0], "high": [1.0]},
    }
    assert chooser["action"] == {"type": "discrete", "n": 3} and chooser["observation_slice"] == [1, 2]


def test_a_batch_of_any_size_and_the_model_stays_usable(tmp_path: Path) -> None:
    model = trained("homogeneous")
    files = export_actors(model, tmp_path)
    session = onnxruntime.InferenceSession(str(files["agent_1"]))
    for batch in (1, 5, 100):
        (action,) = session.run(None, {"observation": np.zeros((batch, 18), dtype=np.float32)})
        assert action.shape == (batch, 5)
    model.learn(100, reset_num_timesteps=False)  # the export leaves the model as it was


def test_an_unknown_format_says_which_there_are(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"format must be one of \['onnx', 'torchscript'\], got 'tflite'"):
        export_actors(trained("homogeneous"), tmp_path, format="tflite")
