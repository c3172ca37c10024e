"""The tuned hyperparameters (the presets' ``tuned`` sections) and the presets made from them: every entry reaches the
env and MADDPG it names, the tuned presets change only what their entry says, MADDPG's defaults stay the paper's."""

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sb3_maddpg import MADDPG
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.experiments.config import EXP1, EXP1_TUNED, EXP2, EXP2_TUNED, load_experiment
from sb3_maddpg.experiments.tasks import run_task
from sb3_maddpg.hyperparams import load_hyperparams, tuned_settings

PAPER_DEFAULTS = {
    "learning_rate": 1e-2,
    "batch_size": 1024,
    "tau": 0.01,
    "gamma": 0.95,
    "transitions_per_update": 100,
    "buffer_size": 1_000_000,
    "learning_starts": 25_600,
}
"""The paper's hyperparameters (SPEC: Lowe et al.'s), which MADDPG's defaults must stay."""


def landmark_distances(obs: np.ndarray, n_agents: int) -> np.ndarray:
    """:return: Each agent's distances to the landmarks in its observation's order (after own velocity and position)."""
    landmarks = obs[..., 4 : 4 + 2 * n_agents].reshape(*obs.shape[:-1], n_agents, 2)
    return np.linalg.norm(landmarks, axis=-1)


def test_maddpg_defaults_stay_the_papers() -> None:
    model = MADDPG("MlpPolicy", SimpleSpreadVecEnv(n_envs=2, n_agents=3), seed=0)
    assert {name: getattr(model, name) for name in PAPER_DEFAULTS} == PAPER_DEFAULTS


@pytest.mark.parametrize("setting", tuned_settings())
def test_every_entry_reaches_the_env_and_the_model(setting: str) -> None:
    tuned = load_hyperparams(setting)
    env = SimpleSpreadVecEnv(n_envs=2, n_agents=tuned.n_agents, **tuned.env_kwargs)
    model = MADDPG("MlpPolicy", env, seed=0, **tuned.model_kwargs)
    for name, value in tuned.model_kwargs.items():
        if name == "policy_kwargs":  # MADDPG adds the team's layout and scheme to them
            assert {key: model.policy_kwargs[key] for key in value} == value
        else:
            assert getattr(model, name) == value, name
    shared = tuned.model_kwargs.get("policy_kwargs", {}).get("share_parameters", False)
    assert model.actor.mlp.share_parameters == model.critic.mlp.share_parameters == shared  # reaches the networks
    assert any(getattr(model, name) != PAPER_DEFAULTS[name] for name in tuned.model_kwargs if name in PAPER_DEFAULTS)


def test_tuned_presets_change_only_what_their_entry_says() -> None:
    assert load_experiment("exp1_tuned") is EXP1_TUNED and load_experiment("exp2_tuned") is EXP2_TUNED
    for paper, tuned_preset in ((EXP1, EXP1_TUNED), (EXP2, EXP2_TUNED)):
        entry = load_hyperparams(paper.name)
        assert tuned_preset.name == f"{paper.name}_tuned"
        assert tuned_preset.num_agent_neighbors == entry.env_kwargs["num_agent_neighbors"]
        assert tuned_preset.model_kwargs == entry.model_kwargs
        assert "num_agent_neighbors" not in tuned_preset.env_kwargs
        entry_env = {name: value for name, value in entry.env_kwargs.items() if name != "num_agent_neighbors"}
        assert tuned_preset.env_kwargs == {**paper.env_kwargs, **entry_env}
        changed = {
            field.name
            for field in dataclasses.fields(paper)
            if getattr(paper, field.name) != getattr(tuned_preset, field.name)
        }
        assert changed <= {"name", "description", "num_agent_neighbors", "env_kwargs", "model_kwargs"}
        # The protocol is the paper's: same schemes, seeds, budget and checkpoints.
        assert [run.checkpoint_steps() for run in tuned_preset.runs()[:1]] == [paper.runs()[0].checkpoint_steps()]
        assert len(tuned_preset.runs()) == len(paper.runs()) == 5 * 31


def test_exp1_tuned_observes_landmarks_nearest_first_where_exp1_does_not() -> None:
    def sortedness(experiment: Any) -> float:
        run = experiment.runs()[0]
        env = run_task(dataclasses.replace(run, n_envs=50)).make_env()
        distances = landmark_distances(env.reset(), run.n_agents)
        return float(np.mean(np.all(np.diff(distances, axis=-1) >= 0, axis=-1)))

    assert sortedness(EXP1_TUNED) == 1.0
    assert sortedness(EXP1) < 0.1  # index order: sorted by chance in 1 of 5! = 120 worlds


def test_unknown_setting_and_algorithm_are_refused_with_what_exists() -> None:
    with pytest.raises(ValueError, match=r"No tuned maddpg hyperparameters for setting 'exp3'.*\['exp1', 'exp2'\]"):
        load_hyperparams("exp3")
    with pytest.raises(ValueError, match=r"No tuned hyperparameters for algorithm 'ppo'.*\['maddpg'\]"):
        load_hyperparams("exp1", algo="ppo")


def test_an_entry_is_a_copy() -> None:
    first = load_hyperparams("exp1")
    first.model_kwargs["transitions_per_update"] = 1
    assert load_hyperparams("exp1").model_kwargs["transitions_per_update"] != 1


def test_exp1_tuned_is_the_configuration_measured_in_benchmarks() -> None:
    # exp1.yml's tuned comment reports benchmarks/n5_tuned's runs: exp1_tuned's full runs must be those runs.
    measured = json.loads((Path(__file__).resolve().parents[2] / "benchmarks/n5_tuned/exp1_shared_best.json").read_text())
    run = EXP1_TUNED.replace(schemes=("full",), seeds=(0,)).runs()[0].to_dict()
    differs = {key for key, value in measured.items() if run.get(key, value) != value}
    assert differs == {"keep_checkpoints"}  # kept by exp1 (a protocol choice), not a learning one


def test_an_entry_with_other_keys_is_refused_by_name(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import sb3_maddpg.hyperparams as hyperparams

    entry = "exp1:\n  n_agents: 5\n  n_timesteps: 10\n  note: x\n  env_kwargs: {}\n"
    monkeypatch.setattr(hyperparams.resources, "files", lambda package: tmp_path)
    for text in (entry, entry + "  model_kwargs: {}\n  gamma: 0.9\n"):  # a key missing; a key too many
        (tmp_path / "maddpg.yml").write_text(text)
        hyperparams._entries.cache_clear()
        try:
            with pytest.raises(ValueError, match=r"maddpg.yml, entry 'exp1': an entry has exactly the keys"):
                hyperparams.load_hyperparams("exp1")
        finally:
            hyperparams._entries.cache_clear()


def test_a_preset_whose_entry_is_for_another_budget_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    import sb3_maddpg.experiments.presets as presets

    entry = dataclasses.replace(load_hyperparams("exp1"), n_timesteps=1_000)
    monkeypatch.setattr(presets, "load_hyperparams", lambda setting, algo: entry)
    with pytest.raises(ValueError, match=r"entry 'exp1' is for 5 agents and 1000 steps, the setting has 5 and 2500000"):
        presets.read_preset_file(presets.resources.files(presets.__name__).joinpath("exp1.yml"))
