"""The paper's protocol on any task: another MPE task, a PettingZoo factory or a gymnasium id, scored by the task's
metrics and by a group of agents' return."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.cli.main import main
from sb3_maddpg.envs import MPE_TASK_METRICS, make_simple_spread
from sb3_maddpg.experiments import SMOKE, run_sweep
from sb3_maddpg.experiments.results_dir import load_summaries
from sb3_maddpg.experiments.runner import execute_run
from sb3_maddpg.experiments.tasks import run_task
from sb3_maddpg.results import make_report

ADVERSARIES = ("adversary_0", "adversary_1", "adversary_2")


def run_config(**changes: object) -> object:
    return SMOKE.replace(schemes=("full",), seeds=(0,), episodes=30, n_checkpoints=2, **changes).runs()[0]


def read_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def test_a_run_on_simple_tag_is_scored_by_catches_and_the_adversaries_return(tmp_path: Path) -> None:
    experiment = SMOKE.replace(schemes=("full",), seeds=(0,), episodes=30, n_checkpoints=2, env="simple_tag")
    experiment = experiment.replace(score_agents=ADVERSARIES)
    config = experiment.runs()[0]
    assert run_sweep([experiment], tmp_path, verbose=0).ok
    score = load_summaries(tmp_path)[0]["score"]
    assert {"collisions", "group_return", "return_adversaries", "return_good_agents"} <= set(score)
    assert "success_rate" not in score  # simple_spread's metrics do not apply
    assert "return_mean" not in score  # it would add the prey's return to the predators'
    directory = tmp_path / config.run_id  # type: ignore[attr-defined]
    checkpoints = read_rows(directory / "checkpoint_evals.csv")
    assert score["group_return"] == pytest.approx(np.mean([float(row["group_return"]) for row in checkpoints]))
    assert "group_return" in read_rows(directory / "learning_curve.csv")[0]
    written = make_report(tmp_path, tmp_path / "report", metrics=("group_return", "collisions"), plots=False)
    table = (tmp_path / "report" / "table_group_return.md").read_text()
    assert "smoke (simple_tag, 30 ep.)" in table and len(written) == 11  # tables and aggregates, md and csv; cost; marl-eval
    # By default a task's main table: its own metrics, each side's return, the scored group's.
    metrics = ("collisions", "return_adversaries", "return_good_agents", "group_return")
    assert {path.name for path in make_report(tmp_path, tmp_path / "default", plots=False)} == {
        *(f"{kind}_{metric}.{ext}" for metric in metrics for kind in ("table", "aggregates") for ext in ("md", "csv")),
        "cost.md",
        "cost.csv",
        "marl_eval.json",
    }


def test_group_return_is_the_sum_of_the_groups_returns() -> None:
    env = make_simple_spread(n_agents=3, local_ratio=1.0)  # each agent's own reward: the agents' returns differ

    class Random:
        rng = np.random.default_rng(0)

        def predict(self, observation, state=None, episode_start=None, deterministic=False):  # type: ignore[no-untyped-def]
            return self.rng.uniform(0, 1, (len(observation), env.action_space.shape[0])).astype(np.float32), None

    result = evaluate_team(Random(), env, n_episodes=2, seed=0, score_agents=("agent_0", "agent_2"))
    returns = result["agent_returns"]
    assert result["group_return"] == pytest.approx(returns[0] + returns[2])
    assert result["group_return"] != pytest.approx(result["return_mean"])  # agent_1's return is left out
    with pytest.raises(ValueError, match=r"score_agents names agents not in the team: \['wolf_0'\]"):
        evaluate_team(Random(), env, n_episodes=1, score_agents=("wolf_0",))
    assert tuple(m.key for m in MPE_TASK_METRICS["simple_tag"]) == ("collisions",)


@pytest.mark.parametrize(
    ("env", "env_kwargs"),
    [
        ("mpe2.simple_push_v3:parallel_env", {"continuous_actions": True, "max_cycles": 25}),
        ("sb3_maddpg/SimpleSpread-v3", {"n_agents": 3}),
    ],
)
def test_a_pettingzoo_factory_or_a_gymnasium_id(env: str, env_kwargs: dict, tmp_path: Path) -> None:
    config = run_config(env=env, env_kwargs=env_kwargs)
    assert run_task(config).make_env(2).num_envs == 2
    summary = execute_run(config, tmp_path, verbose=0)
    assert np.isfinite(summary["score"]["return_mean"])


def test_bad_tasks_say_what_to_give(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="Unknown env 'simple_nonsense': use 'simple_spread', an MPE task"):
        run_task(run_config(env="simple_nonsense")).make_env(1)
    with pytest.raises(ValueError, match="names no importable function"):
        run_task(run_config(env="mpe2.simple_push_v3:no_such_factory")).make_env(1)
    with pytest.raises(ValueError, match="env must name a task"):
        run_config(env=" ")


def test_cli_sets_the_task(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["run", "--config", "smoke", "--results", str(tmp_path), "--env", "simple_tag", "--score-agents", "adversary_0"]
    assert main([*argv, "--env-kwargs", '{"num_obstacles": 1}', "--dry-run"]) == 0
    experiment = json.loads(capsys.readouterr().out.splitlines()[0].split(": ", 1)[1])
    assert (experiment["env"], experiment["score_agents"], experiment["env_kwargs"]) == (
        "simple_tag",
        ["adversary_0"],
        {"num_obstacles": 1},
    )


def test_an_mpe_task_is_scored_by_its_own_metrics(tmp_path: Path) -> None:
    summary = execute_run(run_config(env="simple"), tmp_path, verbose=0)
    assert summary["score"]["goal_distance"] > 0  # the agent's distance to its landmark, at the last step
    curve = read_rows(tmp_path / summary["run_id"] / "learning_curve.csv")
    assert "goal_distance" in curve[0]


def test_simple_spread_takes_its_env_kwargs() -> None:
    discrete = run_task(run_config(env_kwargs={"continuous_actions": False})).make_env(2)
    assert discrete.get_attr("agent_layout")[0].has_discrete_actions
    assert not run_task(run_config()).make_env(2).get_attr("agent_layout")[0].has_discrete_actions
