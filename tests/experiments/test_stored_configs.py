"""The configs stored in the committed results (``benchmarks/*/results``: each run's ``config.json``, each setting's
``experiment.json``) each hold the version that wrote them and load unchanged through the one ``from_dict``, and a
config written now has the keys, in the order, that report and resume read."""

import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest

from sb3_maddpg.compat import STAMP_KEYS, VERSION_KEY, written_by
from sb3_maddpg.experiments.config import EXPERIMENTS
from sb3_maddpg.experiments.setting import ExperimentConfig, RunConfig, Setting

ROOT = Path(__file__).resolve().parents[2]
STORED = sorted(ROOT.glob("benchmarks/*/results/**/config.json")) + sorted(
    ROOT.glob("benchmarks/*/results/**/experiment.json")
)


def _default(config_type: type[Setting], name: str) -> Any:
    """The value a key missing from a stored file takes: this version's default."""
    (found,) = [f for f in dataclasses.fields(config_type) if f.name == name]
    return found.default_factory() if found.default_factory is not dataclasses.MISSING else found.default


def test_there_are_stored_configs_of_both_kinds() -> None:
    names = {path.name for path in STORED}
    assert names == {"config.json", "experiment.json"} and len(STORED) > 100


@pytest.mark.parametrize("path", STORED, ids=lambda path: str(path.relative_to(ROOT / "benchmarks")))
def test_a_stored_config_loads_unchanged(path: Path) -> None:
    written = json.loads(path.read_text())
    # Every committed file holds the version that wrote it (those written before versions were, once migrated).
    assert written_by(written, str(path)) is not None
    config_type: type[Setting] = RunConfig if path.name == "config.json" else ExperimentConfig
    loaded = json.loads(json.dumps(config_type.from_dict(written).to_dict()))
    # The version and commit that wrote a file (0.3 on) are read, not kept: the config it loads is this version's.
    assert not set(STAMP_KEYS) & set(loaded)
    stored = {key: value for key, value in written.items() if key not in STAMP_KEYS}
    assert {key: loaded[key] for key in stored} == stored
    missing = set(loaded) - set(stored)
    assert {key: loaded[key] for key in missing} == json.loads(
        json.dumps({key: _default(config_type, key) for key in missing})
    )


def test_configs_written_now_keep_their_keys_and_order() -> None:
    experiment = EXPERIMENTS["smoke"].to_dict()
    assert list(experiment)[:6] == ["name", "n_agents", "num_agent_neighbors", "episodes", "schemes", "seeds"]
    assert set(experiment) == {f.name for f in dataclasses.fields(ExperimentConfig)}
    run = EXPERIMENTS["smoke"].runs()[0].to_dict()
    assert list(run)[:4] == ["experiment", "scheme", "seed", "n_agents"]
    assert set(run) == {f.name for f in dataclasses.fields(RunConfig)}
    # A run shares every field of its setting with its experiment, from the one definition (Setting).
    shared = {f.name for f in dataclasses.fields(Setting)}
    assert set(run) - shared == {"experiment", "scheme", "seed"}
    experiment_only = {"name", "schemes", "seeds", "description", "scheme_model_kwargs", "reference_policies"}
    assert set(experiment) - shared == experiment_only


@pytest.mark.parametrize("config_type", [RunConfig, ExperimentConfig])
def test_every_field_is_stored(config_type: type[Setting]) -> None:
    """A field added to a config but not to its ``STORED_KEYS`` would be dropped from every file written."""
    stored = config_type.STORED_KEYS
    assert sorted(stored) == sorted(field.name for field in dataclasses.fields(config_type))
    assert len(set(stored)) == len(stored)


def test_a_config_written_now_holds_its_version_and_reads_back(tmp_path: Path) -> None:
    from sb3_maddpg import __version__
    from sb3_maddpg.experiments.results_dir import EXPERIMENT_FILE, load_experiments, write_experiment
    from sb3_maddpg.experiments.runner import start_run_directory
    from sb3_maddpg.provenance import COMMIT_KEY, source_commit

    experiment = EXPERIMENTS["smoke"]
    write_experiment(tmp_path, experiment.name, experiment.to_dict())
    stored = json.loads((tmp_path / experiment.name / EXPERIMENT_FILE).read_text())
    assert stored[VERSION_KEY] == __version__
    assert load_experiments(tmp_path) == {experiment.name: json.loads(json.dumps(experiment.to_dict()))}
    run = experiment.runs()[0]
    start_run_directory(run, tmp_path / "run")
    stored = json.loads((tmp_path / "run" / "config.json").read_text())
    assert stored[VERSION_KEY] == __version__ and RunConfig.from_dict(stored) == run
    # The commit of this checkout (the tests run from one), so a run's own files say which code made it.
    assert stored[COMMIT_KEY] == source_commit() and stored[COMMIT_KEY] is not None


def test_a_config_of_a_newer_version_is_refused_and_the_stamps_are_not_fields() -> None:
    from sb3_maddpg import __version__
    from sb3_maddpg.provenance import COMMIT_KEY

    run = EXPERIMENTS["smoke"].runs()[0]
    fields = run.to_dict()
    # This version's file: its fields as they are, the version and commit that wrote it read and dropped.
    assert RunConfig.from_dict({**fields, VERSION_KEY: __version__, COMMIT_KEY: "0" * 40}) == run
    assert ExperimentConfig.from_dict({"name": "x", VERSION_KEY: __version__}) == ExperimentConfig.from_fields({"name": "x"})
    # A file that names no version (written by hand) is this version's format: today's defaults for what it leaves out.
    assert RunConfig.from_dict(fields) == run
    with pytest.raises(ValueError, match=r"written by sb3-maddpg 99\.1, newer than the installed .*: upgrade"):
        RunConfig.from_dict({**fields, VERSION_KEY: "99.1"})
    with pytest.raises(ValueError, match=r"'not-a-version', which is no version number"):
        RunConfig.from_dict({**fields, VERSION_KEY: "not-a-version"})


def test_a_setting_is_made_of_its_concerns() -> None:
    from sb3_maddpg.experiments.setting import CONCERNS, SETTING_KEYS

    owned = [f.name for concern in CONCERNS for f in dataclasses.fields(concern)]
    assert len(owned) == len(set(owned))  # each field in one concern
    assert set(owned) == {f.name for f in dataclasses.fields(Setting)} == set(SETTING_KEYS)
