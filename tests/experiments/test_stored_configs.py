"""The configs stored in the committed results (``benchmarks/*/results``: each run's ``config.json``, each setting's
``experiment.json``) load unchanged through the one ``from_dict``, whichever version wrote them, and a config written
now has the keys, in the order, that report and resume read."""

import dataclasses
import json
from pathlib import Path
from typing import Any

import pytest

from sb3_maddpg.compat import renamed_in_0_3
from sb3_maddpg.experiments.config import EXPERIMENTS
from sb3_maddpg.experiments.setting import ExperimentConfig, RunConfig, Setting

ROOT = Path(__file__).resolve().parents[2]
STORED = sorted(ROOT.glob("benchmarks/*/results/**/config.json")) + sorted(
    ROOT.glob("benchmarks/*/results/**/experiment.json")
)
WRITTEN_BEFORE_0_2 = {"vec_env": "mpe2", "n_envs": 1}  # what those runs stepped: one mpe2 env each


def _default(config_type: type[Setting], name: str) -> Any:
    """The value a key missing from a stored file takes: what the version that wrote the file ran with."""
    if name in WRITTEN_BEFORE_0_2:
        return WRITTEN_BEFORE_0_2[name]
    (found,) = [f for f in dataclasses.fields(config_type) if f.name == name]
    return found.default_factory() if found.default_factory is not dataclasses.MISSING else found.default


def _as_stored(name: str, value: Any) -> Any:
    """A stored value as it reads back: 0.2's names of ``model_kwargs`` as 0.3 has them."""
    if name == "model_kwargs":
        return renamed_in_0_3(value)
    if name == "scheme_model_kwargs":
        return {scheme: renamed_in_0_3(kwargs) for scheme, kwargs in value.items()}
    return value


def test_there_are_stored_configs_of_both_kinds() -> None:
    names = {path.name for path in STORED}
    assert names == {"config.json", "experiment.json"} and len(STORED) > 100


@pytest.mark.parametrize("path", STORED, ids=lambda path: str(path.relative_to(ROOT / "benchmarks")))
def test_a_stored_config_loads_unchanged(path: Path) -> None:
    stored = json.loads(path.read_text())
    config_type: type[Setting] = RunConfig if path.name == "config.json" else ExperimentConfig
    loaded = json.loads(json.dumps(config_type.from_dict(stored).to_dict()))
    assert {key: loaded[key] for key in stored} == {key: _as_stored(key, value) for key, value in stored.items()}
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
    assert set(experiment) - shared == {"name", "schemes", "seeds", "description", "scheme_model_kwargs"}


@pytest.mark.parametrize("config_type", [RunConfig, ExperimentConfig])
def test_every_field_is_stored(config_type: type[Setting]) -> None:
    """A field added to a config but not to its ``STORED_KEYS`` would be dropped from every file written."""
    stored = config_type.STORED_KEYS
    assert sorted(stored) == sorted(field.name for field in dataclasses.fields(config_type))
    assert len(set(stored)) == len(stored)
