"""The presets in one format: the package's YAML files give the settings the protocol names (each file named after its
setting, its tuned section the ``_tuned`` preset), a user's YAML file runs as a package preset does, and a bad file is
refused in one line naming the file, the cause and what to give."""

import dataclasses
import json
from pathlib import Path

import pytest

from sb3_maddpg.cli.main import main
from sb3_maddpg.experiments.config import EXPERIMENTS, load_experiment
from sb3_maddpg.experiments.presets import PACKAGE_PRESETS, package_presets, read_preset_file
from sb3_maddpg.experiments.setting import ExperimentConfig


def test_each_package_file_holds_the_setting_it_is_named_after() -> None:
    assert list(EXPERIMENTS) == [
        "exp1",
        "exp1_tuned",
        "exp2",
        "exp2_tuned",
        "n3_full",
        "n3_partial",
        "pursuit",
        "multiwalker",
        "smoke",
    ]
    for name in PACKAGE_PRESETS:
        assert EXPERIMENTS[name].name == name
    # The paper's settings, as its text gives them (SPEC: 100k and 150k episodes, 2 nearest agents in experiment 2).
    exp1, exp2 = EXPERIMENTS["exp1"], EXPERIMENTS["exp2"]
    assert (exp1.n_agents, exp1.num_agent_neighbors, exp1.episodes, exp1.n_checkpoints) == (5, None, 100_000, 20)
    assert (exp2.n_agents, exp2.num_agent_neighbors, exp2.episodes, exp2.n_checkpoints) == (5, 2, 150_000, 30)
    assert exp1.description.startswith("Experiment 1: simple_spread, N=5, full observability, 100,000 episodes")
    assert EXPERIMENTS["n3_full"].seeds == tuple(range(10)) and EXPERIMENTS["smoke"].seeds == (0, 1)
    assert package_presets() == EXPERIMENTS  # read again, the same


def test_a_tuned_section_merges_kwargs_and_replaces_other_fields(tmp_path: Path) -> None:
    path = tmp_path / "mine.yml"
    path.write_text(
        "name: mine\nnote: My setting\nn_agents: 3\nepisodes: 400\nn_checkpoints: 2\nseeds: [3, 4]\n"
        "env_kwargs: {num_landmark_neighbors: 1}\n"
        "model_kwargs: {batch_size: 32, policy_kwargs: {net_arch: [8]}}\n"
        "tuned:\n  note: tuned\n  episodes: 800\n  env_kwargs: {local_ratio: 0.3}\n"
        "  model_kwargs: {tau: 0.02, policy_kwargs: {share_parameters: true}}\n"
    )
    setting, tuned = read_preset_file(path)
    assert setting.name == "mine" and setting.seeds == (3, 4) and setting.description.startswith("My setting: ")
    assert tuned.name == "mine_tuned" and tuned.episodes == 800 and tuned.seeds == (3, 4)
    assert tuned.env_kwargs == {"num_landmark_neighbors": 1, "local_ratio": 0.3}
    assert tuned.model_kwargs == {"batch_size": 32, "tau": 0.02, "policy_kwargs": {"net_arch": [8], "share_parameters": True}}
    assert tuned.description.startswith("tuned: ") and "800 episodes" in tuned.description
    assert load_experiment(str(path)) == setting  # the file's setting; its tuned preset is for the package's own


def test_a_users_preset_runs_as_a_package_preset_does(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    smoke = EXPERIMENTS["smoke"]
    path = tmp_path / "tiny.yaml"
    path.write_text(
        "name: tiny\nn_agents: 3\nepisodes: 40\nseeds: [0]\nschemes: [full]\nn_envs: 4\nn_checkpoints: 2\n"
        "eval_episodes: 4\ncurve_points: 2\ncurve_eval_episodes: 2\nkeep_checkpoints: false\nmodel_kwargs:\n"
        + "".join(f"  {key}: {json.dumps(value)}\n" for key, value in smoke.model_kwargs.items())
    )
    expected = dataclasses.replace(smoke, name="tiny", seeds=(0,), schemes=("full",), scheme_model_kwargs={}, description="")
    assert load_experiment(str(path)) == expected  # left-out fields keep today's defaults
    assert main(["run", "--config", str(path), "--results", str(tmp_path / "results"), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "tiny/full/seed_000: 1,000 steps" in out and "1 run(s) to do" in out


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("name: x\nepisode: 10\n", r"has unknown key\(s\) \['episode'\]: its keys are \['name'"),
        ("n_agents: 3\n", r"holds no experiment: give a YAML mapping with a name"),
        ("name: x\ntuned: {name: y}\n", r", in tuned, has unknown key\(s\) \['name'\]"),
        ("name: x\ntuned: 3\n", r"tuned must be a mapping"),
        ("name: x\nepisodes: [1\n", r"is not YAML \(line 3\)"),
        ("name: x\nvec_env: gpu\n", r"vec_env must be one of"),
        ("name: x\ntuned: {model_kwargs: [1]}\n", r", tuned: model_kwargs must be a mapping, got \[1\]"),
        ("name: x\ntuned: {env_kwargs: null}\n", r", tuned: env_kwargs must be a mapping, got None"),
        ("name: x\nschemes: full\n", r"schemes must be a list, e.g. schemes: \[full\], got 'full'"),
        ("name: x\nn_agents: 0\n", r"n_agents \(agents in the team\) must be an integer >= 1, got 0"),
        ("name: x\nepisode_length: 0\n", r"episode_length \(.*\) must be an integer >= 1, got 0"),
        ("name: x\nepisodes: 0\n", r"episodes \(.*\) must be an integer >= 1, got 0"),
        ("name: x\ncheckpoint_fraction: 2\n", r"checkpoint_fraction \(.*\) must be a number in \(0, 1\], got 2"),
    ],
)
def test_a_bad_preset_file_is_refused_naming_it(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.yml"
    path.write_text(text)
    with pytest.raises(ValueError, match=rf"Preset file '{path}'.*{message}"):
        load_experiment(str(path))
    with pytest.raises(ValueError, match=r"No preset file .*missing\.yml"):
        load_experiment(str(tmp_path / "missing.yml"))


def test_a_left_out_field_gets_todays_default() -> None:
    # A preset file and a stored file are this version's fields: a left-out field gets today's default.
    assert ExperimentConfig.from_fields({"name": "x"}).vec_env == "batched"
    assert ExperimentConfig.from_dict({"name": "x"}).vec_env == "batched"


def test_the_docs_preset_file_reads(tmp_path: Path) -> None:
    page = (Path(__file__).resolve().parents[2] / "docs/guide/reproduce.rst").read_text()
    block = page.split(".. code-block:: yaml\n\n", 1)[1].split("\n\n", 1)[0]
    path = tmp_path / "my_setting.yml"
    path.write_text("\n".join(line.removeprefix("   ") for line in block.splitlines()))
    (experiment,) = read_preset_file(path)
    assert (experiment.name, experiment.n_agents, experiment.seeds) == ("n4_short", 4, (0, 1, 2))
    assert {run.scheme: run.model_kwargs.get("selector") for run in experiment.runs()} == {"full": None, "selected": 1}


def test_a_preset_with_a_version_reads_unless_newer(tmp_path: Path) -> None:
    from sb3_maddpg import __version__

    path = tmp_path / "best.yml"
    path.write_text(f"name: best\nn_agents: 3\nsb3_maddpg_version: {__version__}\n")
    assert read_preset_file(path)[0].n_agents == 3
    path.write_text("name: best\nsb3_maddpg_version: '99.0'\n")
    with pytest.raises(ValueError, match=rf"Preset file '{path}' was written by sb3-maddpg 99.0, newer than the installed"):
        read_preset_file(path)
