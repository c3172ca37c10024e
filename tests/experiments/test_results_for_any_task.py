"""Results read right for any task: each task's metrics with their directions, each side's return in a competitive
task (never a sum over opponents), strict JSON, the report's main table on the terminal, a warning for runs that never
updated, and marl-eval's JSON."""

import csv
import json
import math
import shutil
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sb3_maddpg import MADDPG
from sb3_maddpg.analysis.evaluation import (
    EVAL_KEYS,
    TeamEvalCallback,
    describe_result,
    evaluate_team,
    resolve_sides,
    side_return_label,
)
from sb3_maddpg.cli.main import main
from sb3_maddpg.envs import MPE_TASK_METRICS, MPE_TASK_SIDES, MPE_TASKS, make_mpe_env
from sb3_maddpg.experiments import SMOKE, run_sweep
from sb3_maddpg.experiments.results_dir import (
    SUMMARY_FILE,
    load_summaries,
    read_summary,
    run_updates,
    write_json_atomic,
)
from sb3_maddpg.results import make_report
from sb3_maddpg.results.marl_eval import ABSOLUTE_METRICS, MARL_EVAL_FILE, marl_eval_data, write_marl_eval

REPO = Path(__file__).resolve().parents[2]
OLD_TAG_RESULTS = REPO / "benchmarks" / "discrete_and_tasks" / "results" / "tag"
"""Committed simple_tag runs: metrics that do not apply as null, the team return summed over both sides."""


class ConstantModel:
    """A 'model' whose ``predict`` returns the same action everywhere."""

    def __init__(self, action: np.ndarray) -> None:
        self.action = action

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = False) -> tuple:
        return np.tile(self.action, (np.asarray(observation).shape[0], 1)), None


def strict_loads(text: str) -> Any:
    """Parse strict JSON: ``NaN`` and infinities are refused, as every parser but Python's refuses them."""

    def refuse(constant: str) -> None:
        raise ValueError(f"not strict JSON: {constant}")

    return json.loads(text, parse_constant=refuse)


class RandomModel:
    """A 'model' that acts uniformly at random in [0, 1], from its own seeded stream."""

    def __init__(self, n_actions: int) -> None:
        self.n_actions = n_actions
        self.rng = np.random.default_rng(0)

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = False) -> tuple:
        return self.rng.uniform(0.0, 1.0, (np.asarray(observation).shape[0], self.n_actions)).astype(np.float32), None


def evaluate_task(task: str, n_episodes: int = 3) -> dict[str, Any]:
    env = make_mpe_env(task)
    assert env.action_space.shape is not None
    model = RandomModel(env.action_space.shape[0])  # seeded: catches happen, and the sides' returns differ
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the task's own metrics: no warning about simple_spread's
        return evaluate_team(
            model, env, n_episodes=n_episodes, seed=2, task_metrics=MPE_TASK_METRICS[task], sides=MPE_TASK_SIDES[task]
        )


# ---------------------------------------------------------------------------------------------------------------
# describe_result and evaluate_team: the task's own metrics, directions and sides


def test_simple_tag_is_described_by_catches_for_the_adversaries_and_each_sides_return() -> None:
    result = evaluate_task("simple_tag")
    assert result["collisions"] > 0  # the predators catch the prey: their return and the prey's differ
    text = describe_result(result)
    assert "collisions/episode" in text and "(higher is better for the adversaries)" in text
    assert "(lower" not in text  # simple_spread's direction for collisions is not simple_tag's
    # No simple_spread key, so no NaN: every scalar applies to the task.
    assert not {"success_rate", "coverage", "min_dist_sum", "success_rate_r0.1"} & set(result)
    assert all(math.isfinite(value) for value in result.values() if isinstance(value, float)), result
    # Each side's return is the mean of its agents' returns; no return adds the predators' to the prey's.
    returns = result["agent_returns"]
    assert result["return_adversaries"] == pytest.approx(np.mean(returns[:3]))
    assert result["return_good_agents"] == pytest.approx(returns[3])
    assert "return_mean" not in result and "team return" not in text
    assert f"adversaries' return {result['return_adversaries']:.2f}" in text
    assert f"good agents' return {result['return_good_agents']:.2f}" in text
    # An explicit task_metrics argument says the same as the one the result carries.
    assert describe_result({k: v for k, v in result.items() if k != "task_metrics"}, MPE_TASK_METRICS["simple_tag"]) == text


def test_simple_adversary_is_described_by_its_own_metrics() -> None:
    result = evaluate_task("simple_adversary")
    text = describe_result(result)
    assert f"goal distance {result['goal_distance']:.2f} (lower is better for the good agents)" in text
    assert f"adversary goal distance {result['adversary_goal_distance']:.2f} (lower is better for the adversaries)" in text
    assert "success" not in text and "min-dist" not in text
    returns = result["agent_returns"]  # adversary_0, agent_0, agent_1
    assert result["return_adversaries"] == pytest.approx(returns[0])
    assert result["return_good_agents"] == pytest.approx(np.mean(returns[1:]))
    assert not any(isinstance(value, float) and math.isnan(value) for value in result.values())


def test_simple_spread_is_described_as_before() -> None:
    env = make_mpe_env("simple_spread", n_agents=3, max_cycles=5)
    assert env.action_space.shape is not None
    result = evaluate_team(ConstantModel(np.full(env.action_space.shape, 0.5, np.float32)), env, n_episodes=2, seed=0)
    assert set(EVAL_KEYS) <= set(result) and "task_metrics" not in result
    text = describe_result(result)
    assert text.startswith("success ") and "collisions/episode" in text and "(lower)" in text
    assert text.endswith(f"return {result['return_mean']:.2f} (std {result['return_std']:.2f}, higher)")


def test_the_sides_of_every_competitive_task_are_mpe2s_adversaries() -> None:
    import importlib

    for task, module in MPE_TASKS.items():
        parallel_env = importlib.import_module(module).parallel_env()
        agents = parallel_env.unwrapped.world.agents
        adversaries = tuple(agent.name for agent in agents if getattr(agent, "adversary", False))
        if not adversaries:  # a cooperative task: one team, no sides
            assert task not in MPE_TASK_SIDES, task
            continue
        good = tuple(agent.name for agent in agents if not getattr(agent, "adversary", False))
        assert resolve_sides(MPE_TASK_SIDES[task], parallel_env.possible_agents) == {
            "adversaries": adversaries,
            "good agents": good,
        }, task


def test_sides_that_leave_out_or_share_an_agent_are_refused() -> None:
    team = ("adversary_0", "adversary_1", "agent_0")
    assert resolve_sides({"hunters": ("adversary",), "prey": ("agent_0",)}, team) == {
        "hunters": ("adversary_0", "adversary_1"),
        "prey": ("agent_0",),
    }
    with pytest.raises(ValueError, match=r"sides: agent_0 is on no side: give every agent .* exactly one side"):
        resolve_sides({"hunters": ("adversary",)}, team)
    with pytest.raises(ValueError, match=r"sides: adversary_0 is on 2 sides \(a, b\)"):
        resolve_sides({"a": ("adversary",), "b": ("adversary_0", "agent")}, team)
    with pytest.raises(ValueError, match=r"sides: 'wolves' \(wolf\) names no agent of the team"):
        resolve_sides({"wolves": ("wolf",), "all": ("adversary", "agent")}, team)
    assert (side_return_label("hunters"), side_return_label("prey")) == ("hunters' return", "prey's return")


def test_team_eval_callback_prints_a_competitive_tasks_sides(capsys: pytest.CaptureFixture[str]) -> None:
    env = make_mpe_env("simple_tag", max_cycles=5)
    model = MADDPG("MlpPolicy", env, learning_starts=1_000, policy_kwargs={"net_arch": [8]}, seed=0)
    callback = TeamEvalCallback(
        make_mpe_env("simple_tag", max_cycles=5),
        eval_freq=1_000,
        n_eval_episodes=1,
        eval_at_start=True,
        verbose=1,
        task_metrics=MPE_TASK_METRICS["simple_tag"],
        sides=MPE_TASK_SIDES["simple_tag"],
    )
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "learn\\(\\) ended at step")
        model.learn(5, callback=callback)
    printed = capsys.readouterr().out
    assert "Team eval num_timesteps=0: collisions/episode" in printed and "adversaries' return" in printed
    assert set(callback.history[0]) == {"timesteps", "collisions", "return_adversaries", "return_good_agents"} | {
        "episode_length"
    }


# ---------------------------------------------------------------------------------------------------------------
# A simple_tag sweep, its summaries, its report and its marl-eval JSON


@pytest.fixture(scope="module")
def tag_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two schemes, one seed each, 30 episodes of simple_tag (enough to update: learning starts at 250 steps)."""
    results = tmp_path_factory.mktemp("tag")
    experiment = SMOKE.replace(schemes=("full", "independent"), seeds=(0,), episodes=30, n_checkpoints=2, env="simple_tag")
    assert run_sweep([experiment], results, verbose=0).ok
    return results


@pytest.mark.slow
def test_a_competitive_runs_summary_scores_each_side_and_is_strict_json(tag_results: Path) -> None:
    path = tag_results / "smoke" / "full" / "seed_000" / SUMMARY_FILE
    summary = strict_loads(path.read_text())
    assert set(summary["score"]) == {"collisions", "return_adversaries", "return_good_agents", "episode_length"}
    assert summary["n_updates"] > 0
    assert "never updated" not in (tag_results / "sweep.log").read_text()


def test_report_prints_the_tasks_main_table(tag_results: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    written = make_report(tag_results, tmp_path / "report", plots=False)
    printed = capsys.readouterr().out
    assert {path.name for path in written} == {
        *(f"{kind}_{metric}.{ext}" for metric in ("collisions", "return_adversaries", "return_good_agents")
          for kind in ("table", "aggregates") for ext in ("md", "csv")),
        "cost.md", "cost.csv", MARL_EVAL_FILE,
    }  # fmt: skip
    assert "smoke (simple_tag, 30 ep.): mean (std) over runs" in printed
    header = next(line for line in printed.splitlines() if line.startswith("method"))
    for column in (
        "collisions per episode (adversaries), higher is better",
        "adversaries' return per agent, higher is better",
        "good agents' return per agent, higher is better",
    ):
        assert column in header
    summaries = {summary["scheme"]: summary for summary in load_summaries(tag_results)}
    row = next(line for line in printed.splitlines() if line.startswith("IDDPG"))
    assert f"{summaries['independent']['score']['return_good_agents']:.2f} (0.00)" in row
    assert "return_mean" not in printed and "team return" not in printed
    table = (tmp_path / "report" / "table_collisions.md").read_text()
    assert "### Score: collisions per episode (adversaries)" in table and "(higher is better)" in table
    aggregates = (tmp_path / "report" / "aggregates_collisions.md").read_text()
    assert "its mean collisions per episode (adversaries) over the checkpoints" in aggregates
    # The command line prints the same table, then the files.
    assert main(["report", str(tag_results), "--out", str(tmp_path / "cli"), "--no-plots"]) == 0
    output = capsys.readouterr().out
    assert header in output and output.rstrip().endswith(MARL_EVAL_FILE)


def test_marl_eval_json_follows_marl_evals_schema(tag_results: Path, tmp_path: Path) -> None:
    path = write_marl_eval(tag_results, tmp_path / MARL_EVAL_FILE)
    data = strict_loads(path.read_text())
    check_marl_eval_schema(data)
    runs = data["mpe"]["smoke"]
    assert set(runs) == {"MADDPG", "IDDPG"}
    for summary in load_summaries(tag_results):
        run = runs[summary["method"]][f"seed_{summary['seed']}"]
        # The final scores: one evaluation per checkpoint, whose mean is the run's score.
        for metric, values in run[ABSOLUTE_METRICS].items():
            assert len(values) == summary["n_checkpoints"]
            assert np.mean(values) == pytest.approx(summary["score"][metric])
        # The steps: the learning curve's evaluations, at its env steps.
        with open(Path(summary["directory"]) / "learning_curve.csv", newline="") as file:
            curve = list(csv.DictReader(file))
        steps = [key for key in run if key != ABSOLUTE_METRICS]
        assert steps == [f"step_{k}" for k in range(len(curve))]
        assert [run[step]["step_count"] for step in steps] == [int(float(row["timesteps"])) for row in curve]
        assert run[steps[-1]]["return_good_agents"] == [pytest.approx(float(curve[-1]["return_good_agents"]))]


def check_marl_eval_schema(data: dict[str, Any]) -> None:
    """
    What marl-eval's tools require of their raw data (its README's "Data Structure for Raw Experiment data",
    ``DiagnoseData.check_data`` and ``data_process_pipeline``): env -> task -> algorithm -> run -> step; every task of
    an env has the same algorithms (no comma in their names), every algorithm the same number of runs, every run the
    same number of entries, ``step_0`` ... ``step_<k>`` then ``absolute_metrics`` last; each step has an integer
    ``step_count`` and every entry the same metrics, lower case, each a non-empty list of finite numbers.
    """
    assert data, "no environment"
    for env, tasks in data.items():
        algorithms, runs, entries, metrics = set(), set(), set(), set()
        for task, by_algorithm in tasks.items():
            assert task == task.lower(), task
            algorithms.add(tuple(sorted(by_algorithm)))
            for algorithm, by_run in by_algorithm.items():
                assert "," not in algorithm, algorithm
                runs.add(len(by_run))
                for run, steps in by_run.items():
                    keys = list(steps)
                    entries.add(len(keys))
                    assert keys[-1] == ABSOLUTE_METRICS, (env, task, algorithm, run)
                    assert keys[:-1] == [f"step_{k}" for k in range(len(keys) - 1)], keys
                    for key, entry in steps.items():
                        values = {metric: numbers for metric, numbers in entry.items() if metric != "step_count"}
                        assert key == ABSOLUTE_METRICS or isinstance(entry["step_count"], int), key
                        metrics.add(tuple(sorted(values)))
                        for metric, numbers in values.items():
                            assert metric == metric.lower(), metric
                            assert numbers and all(isinstance(x, float) and math.isfinite(x) for x in numbers), metric
        assert len(algorithms) == 1 and len(runs) == 1 and len(entries) == 1 and len(metrics) == 1, env


def test_marl_evals_own_tools_read_it(tag_results: Path) -> None:
    pytest.importorskip("marl_eval", reason="marl-eval (PyPI: id-marl-eval) is not installed")
    from marl_eval.utils.data_processing_utils import create_matrices_for_rliable, data_process_pipeline
    from marl_eval.utils.diagnose_data_errors import DiagnoseData

    data = marl_eval_data(tag_results)
    assert all(all(check.values()) for check in DiagnoseData(data).check_data().values())
    processed = data_process_pipeline(data, metrics_to_normalize=["return_good_agents"])
    final, _ = create_matrices_for_rliable(processed, "mpe", ["return_good_agents"])
    assert final["mean_collisions"]["maddpg" if "maddpg" in final["mean_collisions"] else "MADDPG"].shape == (1, 1)


# ---------------------------------------------------------------------------------------------------------------
# Strict JSON


def test_summaries_are_strict_json_and_read_back_with_nan(tmp_path: Path) -> None:
    write_json_atomic(tmp_path / SUMMARY_FILE, {"score": {"success_rate": math.nan, "return_mean": -3.5}, "seed": 0})
    text = (tmp_path / SUMMARY_FILE).read_text()
    assert strict_loads(text)["score"] == {"success_rate": None, "return_mean": -3.5}
    (tmp_path / "done").write_text("")
    score = read_summary(tmp_path)["score"]  # type: ignore[index]
    assert math.isnan(score["success_rate"]) and score["return_mean"] == -3.5


def test_committed_results_with_metrics_that_do_not_apply_are_read_and_reported(tmp_path: Path) -> None:
    results = tmp_path / "old"
    shutil.copytree(OLD_TAG_RESULTS, results / "tag")
    assert strict_loads((results / "tag" / "full" / "seed_000" / SUMMARY_FILE).read_text())["score"]["success_rate"] is None
    summaries = load_summaries(results)
    assert len(summaries) == 3 and all(math.isnan(summary["score"]["success_rate"]) for summary in summaries)
    assert all((run_updates(summary) or 0) > 0 for summary in summaries)
    written = make_report(results, tmp_path / "report", plots=False, verbose=0)
    # simple_tag's main metrics: catches and the scored group; not the team return, a sum over predators and prey.
    assert {path.name for path in written} >= {"table_collisions.md", "table_group_return.md", MARL_EVAL_FILE}
    assert not any("return_mean" in path.name or "success" in path.name for path in written)
    data = strict_loads((tmp_path / "report" / MARL_EVAL_FILE).read_text())
    check_marl_eval_schema(data)
    run = data["mpe"]["tag"]["MADDPG"]["seed_0"]
    assert set(run[ABSOLUTE_METRICS]) == {"collisions", "episode_length", "group_return", "return"}


# ---------------------------------------------------------------------------------------------------------------
# Runs that never updated


def test_a_run_that_never_updated_is_warned_about_in_its_log_the_sweep_log_and_the_report(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # 9 episodes are 225 steps: training ends before learning_starts=250, so no gradient step is taken.
    experiment = SMOKE.replace(schemes=("full",), seeds=(0,), episodes=9, n_checkpoints=1, curve_points=0)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "learn\\(\\) ended at step")
        assert run_sweep([experiment], tmp_path, verbose=0).ok
    run = tmp_path / "smoke" / "full" / "seed_000"
    assert strict_loads((run / SUMMARY_FILE).read_text())["n_updates"] == 0
    assert "never updated (0 gradient steps: the budget ended before learning_starts=250)" in (run / "train.log").read_text()
    assert "smoke/full/seed_000 done in" in (log := (tmp_path / "sweep.log").read_text()) and "never updated" in log
    with pytest.warns(UserWarning, match=r"1 run\(s\) never updated \(0 gradient steps.*\): smoke/full/seed_000\."):
        written = make_report(tmp_path, tmp_path / "report", plots=False)
    table = next(path for path in written if path.name == "table_min_dist_sum.md").read_text()
    assert table.startswith("> **Warning**: 1 run(s) never updated")
    assert "MADDPG" in capsys.readouterr().out


def test_a_runs_updates_are_its_summarys_own_count() -> None:
    assert run_updates({"n_updates": 7}) == 7 and run_updates({"n_updates": 0}) == 0
    assert run_updates({}) is None and run_updates({"n_updates": None}) is None


# ---------------------------------------------------------------------------------------------------------------
# One metric, two tasks: each setting keeps its task's direction


def test_each_setting_compares_methods_in_its_tasks_direction() -> None:
    from sb3_maddpg.experiments.tasks import metric_info
    from sb3_maddpg.results.report import aggregate_estimates, format_markdown
    from sb3_maddpg.results.stats import aggregate

    collisions = {"full": (3.0, 4.0, 5.0), "independent": (1.0, 1.5, 2.0)}  # IDDPG's teams touch less often
    summaries = [
        {"experiment": setting, "scheme": scheme, "seed": seed, "score": {"collisions": value}}
        for setting in ("spread", "tag")
        for scheme, values in collisions.items()
        for seed, value in enumerate(values)
    ]
    cells = aggregate(summaries, "collisions")
    infos = {"spread": metric_info("collisions", "simple_spread"), "tag": metric_info("collisions", "simple_tag")}
    assert (infos["spread"].higher_is_better, infos["tag"].higher_is_better) == (False, True)
    rows = {(row["setting"], row["scheme"]): row for row in aggregate_estimates(cells, "collisions", infos=infos)}
    # In simple_spread fewer collisions are better: IDDPG beats MADDPG; in simple_tag they are catches: it loses.
    assert rows["spread", "independent"]["improvement"].value == pytest.approx(1.0)
    assert rows["tag", "independent"]["improvement"].value == pytest.approx(0.0)
    assert rows["all", "independent"]["improvement"].value == pytest.approx(0.5)
    text = format_markdown(cells, "collisions", infos=infos)
    assert "### Score: collisions, mean (std)" in text  # the tasks label it differently: its key
    assert "(lower is better in spread, higher is better in tag)" in text
