"""Each agent's actor exported alone (ONNX, TorchScript) gives what the model's predict gives for that agent, from that
agent's own observation: homogeneous, heterogeneous, shared-parameter and mixed continuous/discrete teams; a team of
exported actors, each on its own observation, scores in mpe2 as evaluate_team scores the model."""

import json
import logging
import shutil
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch as th

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.analysis.export import EXPORTER_LOGGER, MANIFEST, agent_actors, export_actors
from sb3_maddpg.envs import PettingZooToGym, make_mpe_env, make_simple_spread
from sb3_maddpg.version import __version__
from tests.mixed_team import MixedTeam

onnxruntime = pytest.importorskip("onnxruntime", reason="the export extra is not installed: pip install -e '.[export]'")

FAST = {"learning_starts": 50, "batch_size": 16, "transitions_per_update": 10, "policy_kwargs": {"net_arch": [16, 16]}}

TEAMS = {
    "homogeneous": lambda: make_simple_spread(n_agents=3),
    "shared_parameters": lambda: make_simple_spread(n_agents=3),
    "heterogeneous": lambda: make_mpe_env("simple_speaker_listener"),  # observations of 3 and 11, actions of 3 and 5
    "mixed": lambda: PettingZooToGym(MixedTeam(mover_bounds=(-2.0, 3.0))),  # a Box(-2, 3) agent and a Discrete(3) one
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


@pytest.mark.slow
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
            low, high = model.action_space.low[layout.action_slices[i]], model.action_space.high[layout.action_slices[i]]
            assert (action >= low - 1e-6).all() and (action <= high + 1e-6).all()


def test_torchscript_export_matches_too(tmp_path: Path) -> None:
    model = trained("heterogeneous")
    with pytest.warns(FutureWarning, match=r"torch\.jit\.trace, which PyTorch deprecates: use format='onnx'") as record:
        files = export_actors(model, tmp_path, format="torchscript")
    assert len(record) == 1  # once per export, not torch's three per agent
    layout = model.agent_layout
    obs = observations(model)
    joint, _ = model.predict(obs, deterministic=True)
    for i, agent_id in enumerate(layout.agent_ids):
        actor = th.jit.load(str(files[agent_id]))
        action = actor(th.as_tensor(obs[:, layout.obs_slices[i]])).numpy()
        np.testing.assert_allclose(action, joint[:, layout.action_slices[i]], atol=1e-5)


@pytest.mark.slow
def test_the_manifest_describes_each_agent(tmp_path: Path) -> None:
    model = trained("mixed")
    export_actors(model, tmp_path)
    manifest = json.loads((tmp_path / MANIFEST).read_text())
    assert manifest["format"] == "onnx" and manifest["sb3_maddpg_version"] == __version__
    assert manifest["onnx"] == {"input": "observation", "output": "action", "opset": 18, "external_data": False}
    assert "self-contained (its weights inside, no .onnx.data file)" in manifest["about"]
    import onnx

    assert [entry.version for entry in onnx.load(tmp_path / "mover.onnx").opset_import if entry.domain == ""] == [18]
    mover, chooser = manifest["agents"]
    assert mover == {
        "agent_id": "mover",
        "file": "mover.onnx",
        "observation_size": 1,
        "observation_slice": [0, 1],
        "observation": {"type": "box", "dtype": "float32", "low": [-10.0], "high": [10.0]},
        "action": {"type": "box", "low": [-2.0], "high": [3.0]},
    }
    assert chooser["action"] == {"type": "discrete", "n": 3} and chooser["observation_slice"] == [1, 2]


@pytest.mark.slow
@pytest.mark.parametrize("team", ["homogeneous", "mixed"])
def test_one_onnx_file_copied_alone_runs_as_the_torch_actor(team: str, tmp_path: Path) -> None:
    """Issue 34: the weights travel inside each file; a file copied alone to an empty folder gives the actor's actions."""
    model = MADDPG("MlpPolicy", TEAMS[team](), seed=0, **FAST)  # its initial weights: what matters is that they travel
    files = export_actors(model, tmp_path / "export")
    assert sorted(path.name for path in (tmp_path / "export").iterdir()) == sorted(
        [MANIFEST, *(path.name for path in files.values())]
    )  # one file per agent and the manifest: no .onnx.data beside them
    layout, actors = model.agent_layout, agent_actors(model)
    obs = observations(model)
    for i, agent_id in enumerate(layout.agent_ids):
        alone = tmp_path / f"alone_{agent_id}"
        alone.mkdir()
        shutil.copy(files[agent_id], alone)  # only this file, as to an agent's own machine
        session = onnxruntime.InferenceSession(str(alone / files[agent_id].name))
        own = obs[:, layout.obs_slices[i]]
        (action,) = session.run(None, {"observation": own})
        with th.no_grad():
            expected = actors[agent_id](th.as_tensor(own)).numpy()
        np.testing.assert_allclose(action, expected, atol=1e-6)


@pytest.mark.slow
def test_the_onnx_export_is_quiet(tmp_path: Path) -> None:
    """Issue 34: no warning, and no log line of torch's exporter (e.g. 'torchvision is not installed'), for any agent."""
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=2), seed=0, **FAST)
    # torch's loggers print through torch's own handler and do not propagate to the root (caplog's): listen on
    # torch.onnx itself, where every exporter module's records pass.
    handler = logging.Handler(logging.WARNING)
    lines: list[str] = []
    handler.emit = lambda record: lines.append(record.getMessage())  # type: ignore[method-assign]
    logging.getLogger("torch.onnx").addHandler(handler)
    try:
        with warnings.catch_warnings(record=True) as record:
            warnings.simplefilter("always")  # every warning, each time, from any module
            export_actors(model, tmp_path)
            export_actors(model, tmp_path)  # a second export too (a once-per-process notice would hide in the first)
    finally:
        logging.getLogger("torch.onnx").removeHandler(handler)
    assert [str(warning.message) for warning in record] == []
    assert lines == []
    assert logging.getLogger(EXPORTER_LOGGER).filters == []  # the filter is gone once the export is done


@pytest.mark.slow
def test_onnx_actor_takes_batches_of_1_5_100_and_learn_runs_after_export(tmp_path: Path) -> None:
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


@pytest.mark.slow
def test_an_exported_team_run_agent_by_agent_in_mpe2_scores_as_evaluate_team(tmp_path: Path) -> None:
    """Decentralised execution: each agent's ONNX file on its own mpe2 observation, no package code in the loop."""
    from mpe2 import simple_spread_v3

    model = MATD3("MlpPolicy", make_simple_spread(n_agents=3), seed=0, **FAST)
    model.learn(300)
    export_actors(model, tmp_path)
    manifest = json.loads((tmp_path / MANIFEST).read_text())
    sessions = {a["agent_id"]: onnxruntime.InferenceSession(str(tmp_path / a["file"])) for a in manifest["agents"]}
    env = simple_spread_v3.parallel_env(N=3, max_cycles=25, continuous_actions=True)
    episodes, seed = 4, 3
    agent_returns, min_dist_sums = [], []
    for episode in range(episodes):
        observations, _ = env.reset(seed=seed if episode == 0 else None)  # as evaluate_team seeds its env
        returns = dict.fromkeys(env.possible_agents, 0.0)
        while env.agents:
            actions = {
                agent: sessions[agent].run(None, {"observation": observations[agent][None].astype(np.float32)})[0][0]
                for agent in env.agents
            }
            observations, rewards, _, _, _ = env.step(actions)
            for agent, reward in rewards.items():
                returns[agent] += reward
        world = env.unwrapped.world
        # Each landmark's distance to its nearest agent, summed, at the episode's last step (by hand)
        min_dist_sums.append(
            sum(min(np.linalg.norm(a.state.p_pos - lm.state.p_pos) for a in world.agents) for lm in world.landmarks)
        )
        agent_returns.append([returns[agent] for agent in env.possible_agents])
    expected = evaluate_team(model, make_simple_spread(n_agents=3), n_episodes=episodes, seed=seed)
    np.testing.assert_allclose(np.mean(agent_returns, axis=0), expected["agent_returns"], rtol=1e-4)
    np.testing.assert_allclose(np.sum(agent_returns, axis=1).mean(), expected["return_mean"], rtol=1e-4)
    np.testing.assert_allclose(np.mean(min_dist_sums), expected["min_dist_sum"], rtol=1e-4)


def test_onnx_export_without_the_extra_names_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=2), seed=0, **FAST)
    monkeypatch.setitem(sys.modules, "onnxscript", None)  # as if not installed: importing it raises
    with pytest.raises(ModuleNotFoundError, match=r"needs onnx and onnxscript, which are not installed: .*\[export\]"):
        export_actors(model, tmp_path)
    with pytest.warns(FutureWarning, match="PyTorch deprecates"):
        export_actors(model, tmp_path, format="torchscript")  # the alternative the error names works without them
    assert (tmp_path / "agent_0.pt").exists()
