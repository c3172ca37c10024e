"""A run's task is derived once from its config (``run_task(config)``, a :class:`RunTask` kept on the config): a
run reads its envs, metrics, directions, sides, evaluation schedule and description from that one object."""

import dataclasses
import json
import pickle
import re
from pathlib import Path
from typing import Any

import pytest

from sb3_maddpg.cli.main import main
from sb3_maddpg.common.selection import NearestAgents
from sb3_maddpg.envs.simple_spread import SIMPLE_SPREAD_TASK_METRICS
from sb3_maddpg.experiments.config import SMOKE, load_experiment
from sb3_maddpg.experiments.runner import build_model, execute_run
from sb3_maddpg.experiments.tasks import RunTask, run_task
from tests.settings import FILLS_THE_BUFFER_ONLY, SELECTS_EVERY_OTHER_AGENT


@FILLS_THE_BUFFER_ONLY
@SELECTS_EVERY_OTHER_AGENT
def test_a_run_derives_its_task_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    config = SMOKE.replace(schemes=("full",), seeds=(0,), episodes=10, n_checkpoints=2).runs()[0]
    derived = []
    derive = RunTask.of

    def counted(config: object) -> RunTask:
        derived.append(config)
        return derive(config)  # type: ignore[arg-type]

    monkeypatch.setattr(RunTask, "of", staticmethod(counted))
    summary = execute_run(config, tmp_path, verbose=0)
    assert summary["n_checkpoints"] == 2
    assert derived == [config]


def test_the_task_is_kept_on_the_config_and_a_copy_sent_away_derives_its_own() -> None:
    config = SMOKE.runs()[0]
    task = run_task(config)
    assert run_task(config) is task and task.config is config
    assert task.checkpoint_steps == tuple(config.checkpoint_steps())
    assert (task.curve_interval, task.eval_seed) == (config.curve_interval, config.eval_seed)
    sent = pickle.loads(pickle.dumps(config))
    assert set(sent.__dict__) == set(config.to_dict())  # the fields travel, not what derives from them
    assert sent == config and run_task(sent) is not task and run_task(sent).keys == task.keys


def test_the_task_holds_its_metrics_their_directions_and_sides() -> None:
    spread = run_task(SMOKE.runs()[0])
    assert spread.metrics == SIMPLE_SPREAD_TASK_METRICS and spread.sides == {} and spread.scores_behaviour
    assert spread.higher_is_better["success_rate"] and not spread.higher_is_better["min_dist_sum"]
    assert "simple_spread" in spread.description
    tag = run_task(SMOKE.replace(env="simple_tag", schemes=("full",)).runs()[0])
    assert [metric.key for metric in tag.metrics] == ["collisions"] and tag.higher_is_better["collisions"]  # catches
    assert set(tag.sides) == {"adversaries", "good agents"} and not tag.scores_behaviour
    assert "return_mean" not in tag.keys and "simple_tag" in tag.description
    partial = run_task(SMOKE.replace(env_kwargs={"num_landmark_neighbors": 1}).runs()[0])
    assert not partial.scores_behaviour  # the behaviour reads every landmark from the observations


def test_a_json_configs_selector_dict_reaches_the_model_as_nearest_agents_with_its_target(tmp_path: Path) -> None:
    data = {
        **SMOKE.to_dict(),
        "schemes": ["selected"],
        "scheme_model_kwargs": {"selected": {"selector": {"k": 1, "target": "next"}}},
    }
    path = tmp_path / "experiment.json"
    path.write_text(json.dumps(data))
    (config,) = load_experiment(str(path)).runs()[:1]
    model = build_model(run_task(config))
    assert isinstance(model.selector, NearestAgents) and (model.selector.k, model.selector.target) == (1, "next")


@SELECTS_EVERY_OTHER_AGENT
def test_a_schemes_variant_names_its_critic_sharing_and_runs_in_its_own_directory(tmp_path: Path) -> None:
    variant = {"critic_sharing": "selected", "selector": {"k": 1, "target": "next"}}
    experiment = dataclasses.replace(
        SMOKE, schemes=("selected", "selected_next"), seeds=(0,), scheme_model_kwargs={"selected_next": variant}
    )
    stored, next_step = experiment.runs()
    assert next_step.run_id == "smoke/selected_next/seed_000"
    models = [build_model(run_task(config)) for config in (stored, next_step)]
    assert [type(model.critic.extractors[0]).__name__ for model in models] == ["SelectedCriticFeatures"] * 2
    assert [model.selector.target for model in models] == ["stored", "next"]


def test_a_scheme_that_is_none_says_how_to_name_a_variants_critic_sharing() -> None:
    (config,) = dataclasses.replace(SMOKE, schemes=("selected_next",), seeds=(0,)).runs()
    cause, remedy = "^Unknown critic_sharing 'selected_next': use one of ", "For a variant of a scheme under a name of its own"
    with pytest.raises(ValueError, match=f"{cause}.*{remedy}"):
        build_model(run_task(config))


def test_the_cli_takes_an_experiment_with_a_variant_and_refuses_a_scheme_that_is_none(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    variant = {"critic_sharing": "selected", "selector": {"k": 1, "target": "next"}}
    data = {**SMOKE.to_dict(), "schemes": ["selected", "selected_next"], "scheme_model_kwargs": {"selected_next": variant}}
    path = tmp_path / "experiment.json"
    path.write_text(json.dumps(data))
    argv = ["run", "--config", str(path), "--results", str(tmp_path / "results"), "--dry-run"]
    assert main(argv) == 0
    assert "smoke/selected_next/seed_001" in capsys.readouterr().out
    path.write_text(json.dumps({**data, "scheme_model_kwargs": {}}))
    assert main(argv) == 2
    assert "smoke: --schemes 'selected_next': Unknown critic_sharing 'selected_next'" in capsys.readouterr().err


def test_an_experiment_with_a_variant_narrows_to_the_papers_schemes() -> None:
    variant = {"critic_sharing": "selected", "selector": {"k": 1, "target": "next"}}
    experiment = dataclasses.replace(SMOKE, schemes=("full", "selected_next"), scheme_model_kwargs={"selected_next": variant})
    assert dataclasses.replace(experiment, schemes=("full",)).schemes == ("full",)  # as --schemes full does


@pytest.mark.parametrize(
    ("changes", "refusal"),
    [
        ({"model_kwargs": {"critic_sharing": "full"}}, "model_kwargs hold critic_sharing='full', which would train every"),
        (
            {"scheme_model_kwargs": {"full": {"critic_sharing": "independent"}}},
            "give scheme 'full' critic_sharing='independent': its runs would be reported as 'full'",
        ),
        ({"schemes": ("full", "../elsewhere")}, "Scheme name '../elsewhere' cannot name its runs' directory"),
        ({"scheme_model_kwargs": {"selected_nxt": {"selector": 1}}}, "names unknown scheme 'selected_nxt'"),
    ],
)
def test_what_would_train_a_scheme_under_another_name_is_refused(changes: dict[str, Any], refusal: str) -> None:
    with pytest.raises(ValueError, match=re.escape(refusal)):
        dataclasses.replace(SMOKE, **changes)
