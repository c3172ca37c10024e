"""Tests of the paper's protocol: configs, statistics, runs, resume, both backends, the report and the CLI."""

import ast
import csv
import dataclasses
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.stats import mannwhitneyu

from sb3_maddpg.analysis.normalised_score import reference_scores
from sb3_maddpg.cli.main import main
from sb3_maddpg.experiments import EXP1, EXP1_TUNED, EXP2, SCHEMES, SMOKE, ExperimentConfig, RunConfig, run_sweep
from sb3_maddpg.experiments.backends import BACKENDS, Execution, make_backend
from sb3_maddpg.experiments.config import EXPERIMENTS, PAPER_NAMES, algorithm_argument, setting_label
from sb3_maddpg.experiments.results_dir import (
    DONE_FILE,
    RESULT_FILES,
    curve_value_at,
    is_finished,
    link_complete_seeds,
    link_experiments,
    load_summaries,
    write_experiment,
    write_result_files,
)
from sb3_maddpg.experiments.runner import execute_run
from sb3_maddpg.results import make_report
from sb3_maddpg.results.marl_eval import MARL_EVAL_FILE
from sb3_maddpg.results.report import format_markdown
from sb3_maddpg.results.stats import aggregate, mann_whitney, mean_std, significance_stars

# ---------------------------------------------------------------------------------------------------------------
# Configs


def test_paper_presets() -> None:
    assert (EXP1.n_agents, EXP1.num_agent_neighbors, EXP1.episodes) == (5, None, 100_000)
    assert (EXP2.n_agents, EXP2.num_agent_neighbors, EXP2.episodes) == (5, 2, 150_000)
    for experiment in (EXP1, EXP2):
        runs = experiment.runs()
        assert len(runs) == 5 * 31
        assert {run.scheme for run in runs} == set(SCHEMES)
        assert sorted({run.seed for run in runs}) == list(range(31))
        assert len({run.run_id for run in runs}) == len(runs)
    # 20 models over episodes 80k-100k and 30 over 120k-150k, every 1,000 episodes, the last at the end.
    assert EXP1.runs()[0].checkpoint_episodes() == list(range(81_000, 100_001, 1_000))
    assert EXP2.runs()[0].checkpoint_episodes() == list(range(121_000, 150_001, 1_000))
    assert EXP1.runs()[0].checkpoint_steps()[-1] == EXP1.runs()[0].total_timesteps == 2_500_000
    assert SMOKE.n_agents == 3 and len(SMOKE.seeds) == 2 and SMOKE.schemes == SCHEMES


def test_overrides_and_validation() -> None:
    small = EXP1.replace(n_agents=3, episodes=500, seeds=(4, 5), schemes=("full", "selected"), n_checkpoints=10, name=None)
    assert small.name == "exp1" and small.n_agents == 3  # None overrides are ignored
    runs = small.runs()
    assert [(run.seed, run.scheme) for run in runs] == [(4, "full"), (4, "selected"), (5, "full"), (5, "selected")]
    assert runs[0].checkpoint_episodes() == list(range(410, 501, 10))  # 1% of the budget over the last 20%
    assert runs[0].total_timesteps == 500 * 25
    run = runs[0]
    assert RunConfig.from_dict(json.loads(json.dumps(run.to_dict()))).same_as(run)
    assert not dataclasses.replace(run, seed=9).same_as(run)
    with pytest.raises(ValueError, match="checkpoints do not fit"):
        EXP1.replace(episodes=50, n_checkpoints=20).runs()
    with pytest.raises(ValueError, match="checkpoint_fraction"):
        dataclasses.replace(run, checkpoint_fraction=0.0)
    assert (run.vec_env, run.n_envs) == ("batched", 100)  # the paper's presets train on the batched env
    with pytest.raises(ValueError, match="vec_env must be one of"):
        EXP1.replace(vec_env="gpu")
    with pytest.raises(ValueError, match=r"^n_envs \(.*\) must be an integer >= 1, got 0"):
        dataclasses.replace(run, n_envs=0)
    assert ExperimentConfig.from_dict(EXP1.to_dict()).runs()[0].vec_env == "batched"


def test_scheme_model_kwargs_and_the_n3_presets() -> None:
    experiment = SMOKE.replace(scheme_model_kwargs={"selected": {"selector": 1, "batch_size": 32}})
    by_scheme = {run.scheme: run.model_kwargs for run in experiment.runs() if run.seed == 0}
    assert by_scheme["selected"] == {**SMOKE.model_kwargs, "selector": 1, "batch_size": 32}  # over model_kwargs
    assert all(by_scheme[scheme] == SMOKE.model_kwargs for scheme in SCHEMES if scheme != "selected")
    # Every RunConfig field that is not per run comes from the experiment.
    run = experiment.runs()[0]
    for field in dataclasses.fields(RunConfig):
        if field.name not in ("experiment", "scheme", "seed", "model_kwargs"):
            assert getattr(run, field.name) == getattr(experiment, field.name), field.name
    # Written to JSON and read back, as sweeps store it.
    assert ExperimentConfig.from_dict(json.loads(json.dumps(experiment.to_dict()))).runs()[4].same_as(experiment.runs()[4])
    with pytest.raises(ValueError, match=r"unknown scheme 'selectd': its keys must be schemes"):
        SMOKE.replace(scheme_model_kwargs={"selectd": {"selector": 1}})
    n3_full, n3_partial = EXPERIMENTS["n3_full"], EXPERIMENTS["n3_partial"]
    for experiment in (n3_full, n3_partial):
        runs = experiment.runs()
        assert len(runs) == 5 * 10 and runs[0].n_agents == 3 and runs[0].total_timesteps == 500_000
        assert {run.scheme: run.model_kwargs.get("selector") for run in runs}["selected"] == 1
    assert (n3_full.num_agent_neighbors, n3_partial.num_agent_neighbors) == (None, 1)


# ---------------------------------------------------------------------------------------------------------------
# Statistics on fixed arrays

FIXED_PAIRS = [
    ([0.61, 0.72, 0.55, 0.80, 0.67], [0.41, 0.38, 0.52, 0.45, 0.49]),  # separated: exact p = 2/252
    ([0.1, 0.2, 0.3, 0.4], [0.15, 0.25, 0.35, 0.45]),  # interleaved
    ([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]),
]


@pytest.mark.parametrize(("x", "y"), FIXED_PAIRS)
def test_mann_whitney_matches_scipy_s_exact_test_without_ties(x: list[float], y: list[float]) -> None:
    # Without ties scipy's exact test is the test (with ties it is not: tests/experiments/test_exact_tests.py).
    expected = mannwhitneyu(x, y, alternative="two-sided", method="exact")
    u_statistic, p_value = mann_whitney(x, y)
    assert u_statistic == pytest.approx(expected.statistic)
    assert p_value == pytest.approx(expected.pvalue)


def test_mann_whitney_known_values_and_edge_cases() -> None:
    # Five against five, completely separated: U = 25 and the exact two-sided p = 2 / C(10, 5) = 2/252.
    u_statistic, p_value = mann_whitney(*FIXED_PAIRS[0])
    assert u_statistic == 25.0
    assert p_value == pytest.approx(2 / 252)
    assert mann_whitney([0.0, 0.0, 0.0], [0.0, 0.0]) == (3.0, 1.0)  # all equal: no difference
    assert all(math.isnan(value) for value in mann_whitney([], [1.0, 2.0]))


@pytest.mark.parametrize(
    ("p_value", "stars"),
    [(0.0001, "**"), (0.0099, "**"), (0.01, "*"), (0.03, "*"), (0.0499, "*"), (0.05, ""), (0.5, ""), (math.nan, "")],
)
def test_significance_stars(p_value: float, stars: str) -> None:
    assert significance_stars(p_value) == stars


def make_summaries(scores: dict[str, dict[str, list[float]]], metric: str = "success_rate") -> list[dict[str, Any]]:
    summaries = []
    for setting, by_scheme in scores.items():
        for scheme, values in by_scheme.items():
            for seed, value in enumerate(values):
                summaries.append({"experiment": setting, "scheme": scheme, "seed": seed, "score": {metric: value}})
    return summaries


def test_table2_aggregation() -> None:
    scores = {
        "exp1": {
            "selected": [0.70, 0.74, 0.69, 0.78, 0.71],
            "full": [0.61, 0.66, 0.58, 0.64, 0.60],
            "independent": [0.41, 0.47, 0.44, 0.39, 0.50],
            "actions": [0.60, 0.65, 0.62, 0.59, 0.66],
        },
        "exp2": {"full": [0.3, 0.2], "observations": [0.1, 0.4]},
    }
    # Seeds in shuffled order must give the same cells (scores are matched by seed, not by order).
    summaries = make_summaries(scores)[::-1]
    cells = aggregate(summaries, "success_rate")
    assert [(cell.setting, cell.scheme) for cell in cells] == [
        ("exp2", "full"),
        ("exp2", "observations"),
        ("exp1", "full"),
        ("exp1", "independent"),
        ("exp1", "actions"),
        ("exp1", "selected"),
    ]
    by_key = {(cell.setting, cell.scheme): cell for cell in cells}
    for (setting, scheme), cell in by_key.items():
        percent = 100 * np.array(scores[setting][scheme])
        assert cell.scores == pytest.approx(tuple(percent))
        assert cell.mean == pytest.approx(percent.mean())
        assert cell.std == pytest.approx(percent.std(ddof=1))
        assert cell.method in {"MADDPG", "IDDPG", "MADDPG-fo", "MADDPG-fa", "MADDPG-soa"}
        if scheme == "full":
            assert math.isnan(cell.p_value) and cell.stars == ""
        else:
            expected = mann_whitney(percent, 100 * np.array(scores[setting]["full"]))[1]
            assert cell.p_value == pytest.approx(expected)
            assert cell.stars == significance_stars(expected)
    assert by_key[("exp1", "selected")].stars == "**"  # completely above MADDPG, 5 vs 5
    assert by_key[("exp1", "independent")].stars == "**"
    assert by_key[("exp1", "actions")].stars == ""
    # exp1's actions tie full's runs twice (0.66, 0.60): the exact p (204 of the 252 splits as extreme), where scipy's
    # default takes its normal approximation (0.834).
    assert by_key[("exp1", "actions")].p_value == pytest.approx(204 / 252)
    # Holm within each setting's family (exp1: three methods against MADDPG; exp2: one).
    assert by_key[("exp1", "selected")].p_adjusted == pytest.approx(3 * 2 / 252)
    assert by_key[("exp2", "observations")].p_adjusted == by_key[("exp2", "observations")].p_value
    markdown = format_markdown(cells, "success_rate")
    header = "| setting | MADDPG | IDDPG | MADDPG-fo | MADDPG-fa | MADDPG-soa |"
    assert header in markdown
    selected = by_key[("exp1", "selected")]
    assert f"{selected.mean:.2f} ({selected.std:.2f}) **" in markdown
    assert "| exp1 | baseline | 0.0079, Holm 0.0238 (U=0.0) |" in markdown  # IDDPG: below MADDPG in every run
    assert "the smallest two-sided p is .33 at 2 runs a side, .0079 at 5 runs a side" in markdown
    assert "A family is one study x one setting x one metric" in markdown
    # min_dist_sum is reported in its own units, not in percent.
    raw = aggregate(make_summaries({"s": {"full": [1.5, 2.5]}}, "min_dist_sum"), "min_dist_sum")
    assert raw[0].mean == pytest.approx(2.0)
    assert mean_std([3.0]) == (3.0, 0.0)


# ---------------------------------------------------------------------------------------------------------------
# Runs, resume and backends (the smoke configuration: N=3, tiny budget and networks)


def tiny(experiment_name: str = "smoke", **changes: Any) -> Any:
    return SMOKE.replace(name=experiment_name, **changes)


def read_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def test_run_directory_resume_and_purity(tmp_path: Path) -> None:
    config = tiny(schemes=("selected",), seeds=(3,)).runs()[0]
    first = execute_run(config, tmp_path / "a", verbose=0)
    directory = tmp_path / "a" / config.run_id
    for name in (*RESULT_FILES, DONE_FILE):
        assert (directory / name).exists(), name
    assert not (directory / "checkpoints").exists()  # the smoke config drops model files after evaluation
    evaluations = read_rows(directory / "checkpoint_evals.csv")
    assert [int(row["timesteps"]) for row in evaluations] == config.checkpoint_steps()
    # The score is the mean over the checkpoints.
    assert first["score"]["min_dist_sum"] == pytest.approx(np.mean([float(row["min_dist_sum"]) for row in evaluations]))
    curve = read_rows(directory / "learning_curve.csv")
    assert float(curve[0]["timesteps"]) == 0 and float(curve[-1]["timesteps"]) == config.total_timesteps
    assert "rollout/ep_rew_mean" in read_rows(directory / "progress.csv")[0]

    # A finished run is not repeated ...
    done_stamp = (directory / DONE_FILE).stat().st_mtime_ns
    assert execute_run(config, tmp_path / "a", verbose=0)["score"] == first["score"]
    assert (directory / DONE_FILE).stat().st_mtime_ns == done_stamp
    # ... a run is a pure function of its config: the same config elsewhere gives the same evaluations ...
    execute_run(config, tmp_path / "b", verbose=0)
    assert read_rows(tmp_path / "b" / config.run_id / "checkpoint_evals.csv") == evaluations
    # ... the result carries its files, so a remote worker's run can be written where the sweep collects it ...
    write_result_files(tmp_path / "collected", first)
    assert is_finished(tmp_path / "collected", config)
    assert read_rows(tmp_path / "collected" / config.run_id / "checkpoint_evals.csv") == evaluations
    assert load_summaries(tmp_path / "collected")[0]["score"] == first["score"]
    # ... and a finished run with another config in the same place is refused.
    with pytest.raises(ValueError, match="another config"):
        is_finished(tmp_path / "a", dataclasses.replace(config, eval_episodes=3))


def test_a_run_on_mpe2_itself(tmp_path: Path) -> None:
    config = tiny(schemes=("full",), seeds=(0,), vec_env="mpe2", n_envs=2).runs()[0]
    result = execute_run(config, tmp_path, verbose=0)
    assert result["n_checkpoints"] == 2 and np.isfinite(result["score"]["return_mean"])
    assert "on 2 mpe2 simple_spread env(s)" in (tmp_path / config.run_id / "train.log").read_text()


def test_interrupted_sweep_resumes(tmp_path: Path) -> None:
    experiment = tiny(schemes=("full", "independent"), seeds=(0,))
    runs = experiment.runs()
    # Simulate an interruption: one run finished, the other started (its directory exists, no done marker).
    execute_run(runs[0], tmp_path, verbose=0)
    unfinished = tmp_path / runs[1].run_id
    unfinished.mkdir(parents=True)
    (unfinished / "stale.txt").write_text("from the interrupted sweep")
    finished_stamp = (tmp_path / runs[0].run_id / DONE_FILE).stat().st_mtime_ns

    result = run_sweep([experiment], tmp_path, workers=1, verbose=0)
    assert result.ok and result.skipped == 1 and [s["run_id"] for s in result.completed] == [runs[1].run_id]
    assert (tmp_path / runs[0].run_id / DONE_FILE).stat().st_mtime_ns == finished_stamp
    assert (unfinished / DONE_FILE).exists() and not (unfinished / "stale.txt").exists()  # restarted cleanly

    again = run_sweep([experiment], tmp_path, workers=1, verbose=0)
    assert again.ok and again.skipped == 2 and not again.completed
    log = (tmp_path / "sweep.log").read_text()
    assert "1 finished before, 1 to run" in log and "2 finished before, 0 to run" in log


@pytest.fixture(scope="module")
def local_results(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The whole smoke configuration (five schemes, two seeds) on the local backend with two workers."""
    results = tmp_path_factory.mktemp("local")
    result = run_sweep([SMOKE], results, backend="local", workers=2, verbose=0)
    assert result.ok, result.failed
    assert result.total == 10 and len(result.completed) == 10
    return results


@pytest.mark.slow
def test_local_backend_runs_the_smoke_sweep(local_results: Path) -> None:
    summaries = load_summaries(local_results)
    assert len(summaries) == 10
    assert {(s["scheme"], s["seed"]) for s in summaries} == {(scheme, seed) for scheme in SCHEMES for seed in (0, 1)}
    for summary in summaries:
        assert summary["n_checkpoints"] == 2
        assert 0.0 <= summary["score"]["success_rate"] <= 1.0
        assert summary["score"]["min_dist_sum"] > 0
        assert summary["train_steps_per_s"] > 0
        # What the last checkpoint's team does at its episodes' end, on the same evaluation episodes.
        assert 0 <= summary["behaviour"]["covered"] <= 3 and 0 <= summary["behaviour"]["strays"] <= 3
        assert summary["behaviour"]["assignment_gap"] >= -1e-9
    assert "sweep finished: 10 run(s)" in (local_results / "sweep.log").read_text()


@pytest.mark.slow
def test_ray_backend_runs_the_smoke_sweep(tmp_path: Path, local_results: Path) -> None:
    pytest.importorskip("ray", reason="the Ray backend test needs ray (installed in CI through the dev extra)")
    result = run_sweep([SMOKE], tmp_path, backend="ray", workers=2, verbose=0)
    assert result.ok, result.failed
    assert len(result.completed) == 10
    # Ray tasks return their result files; they are in the results directory, with the same scores as the
    # local backend's (a run is a pure function of its config).
    ray_scores = {s["run_id"]: s["score"] for s in load_summaries(tmp_path)}
    local_scores = {s["run_id"]: s["score"] for s in load_summaries(local_results)}
    assert ray_scores.keys() == local_scores.keys()
    for run_id, score in ray_scores.items():
        assert score == pytest.approx(local_scores[run_id]), run_id


def test_one_registry_names_the_backends_that_run_takes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``run --backend`` offers the names of :data:`BACKENDS`, each of which makes a backend that plans the runs it is
    given; a name not there is refused with the names."""
    assert main(["run", "--backend", "none"]) == 2
    offered = capsys.readouterr().err.split("--backend: 'none' is not one of ")[1].split(" (see ")[0]
    assert offered == ", ".join(repr(name) for name in BACKENDS)
    runs = dataclasses.replace(SMOKE, schemes=("full",)).runs()
    for name in BACKENDS:
        plan = make_backend(Execution(name, runs_per_process=1)).plan(runs, str(tmp_path))
        assert plan.runs == runs and all(len(unit) == 1 for unit in plan.units), name
    assert "a Ray task each" in make_backend(Execution("batched-ray")).plan(runs, str(tmp_path)).where
    with pytest.raises(ValueError, match="Unknown backend 'none'; use one of"):
        make_backend(Execution("none"))


def test_report_writes_table_and_plots(local_results: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from sb3_maddpg.results import plots

    y_limits: dict[str, tuple[float, float]] = {}
    save = plots._save
    monkeypatch.setattr(
        plots,
        "_save",
        lambda figure, path: (y_limits.__setitem__(Path(path).stem, figure.axes[0].get_ylim()), save(figure, path)),
    )
    written = make_report(local_results, tmp_path)  # the default metrics: success and min-dist sum
    names = sorted(path.name for path in written)
    assert names == sorted(
        ["normalised.md", "cost.md", "cost.csv", "marl_eval.json"]
        + [
            f"{kind}_{metric}.{ext}"
            for metric in ("success_rate", "min_dist_sum")
            for kind, ext in (
                ("table", "md"),
                ("table", "csv"),
                ("aggregates", "md"),
                ("aggregates", "csv"),
                ("claims", "md"),  # smoke is simple_spread with full observation: the paper's Exp. 1 claims
                ("claims", "csv"),
                ("learning_curves", "png"),
                ("boxplot", "png"),
            )
        ]
    )
    # The normalised scores by hand: each scheme's mean between the task's random team and the controller.
    references = reference_scores(3)
    normalised_rows = [line for line in (tmp_path / "normalised.md").read_text().splitlines() if line.startswith("| smoke")]
    assert len(normalised_rows) == len(SCHEMES) + 1  # a row per method, and the references
    for line in normalised_rows[: len(SCHEMES)]:
        method, runs, min_dist, min_dist_score = line.split(" | ")[1:5]
        scheme = next(scheme for scheme, name in PAPER_NAMES.items() if name == method)
        values = [s["score"]["min_dist_sum"] for s in load_summaries(local_results) if s["scheme"] == scheme]
        random, scripted = references["random"]["min_dist_sum"], references["scripted"]["min_dist_sum"]
        assert float(min_dist) == pytest.approx(np.mean(values), abs=5e-4) and int(runs) == 2
        assert float(min_dist_score) == pytest.approx((np.mean(values) - random) / (scripted - random), abs=5e-3)
    for path in written:
        assert path.stat().st_size > 0
        if path.suffix == ".png":
            assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # Rates and distances cannot be negative: their axes start at 0 (the smoke runs' success is all zeros).
    assert set(y_limits) == {
        f"{kind}_{metric}" for kind in ("learning_curves", "boxplot") for metric in ("success_rate", "min_dist_sum")
    }
    assert all(bottom == 0.0 < top for bottom, top in y_limits.values()), y_limits
    rows = read_rows(tmp_path / "table_min_dist_sum.csv")
    assert [row["method"] for row in rows] == ["MADDPG", "IDDPG", "MADDPG-fo", "MADDPG-fa", "MADDPG-soa"]
    summaries = load_summaries(local_results)
    for row in rows:
        values = [s["score"]["min_dist_sum"] for s in summaries if s["scheme"] == row["scheme"]]
        assert float(row["mean"]) == pytest.approx(np.mean(values))
        assert int(row["n"]) == 2
    assert "smoke (N=3, full obs., 40 ep.)" in (tmp_path / "table_success_rate.md").read_text()
    aggregates = {row["scheme"]: row for row in read_rows(tmp_path / "aggregates_min_dist_sum.csv")}
    for scheme, row in aggregates.items():
        values = [s["score"]["min_dist_sum"] for s in summaries if s["scheme"] == scheme]
        assert float(row["iqm"]) == pytest.approx(np.mean(values))  # the IQM of two runs is their mean
        assert (row["improvement"] == "") == (scheme == "full")
    # Regenerating gives the same table.
    before = (tmp_path / "table_min_dist_sum.md").read_text()
    make_report(local_results, tmp_path, metrics=("min_dist_sum",), plots=False)
    assert (tmp_path / "table_min_dist_sum.md").read_text() == before
    with pytest.raises(ValueError, match="Unknown metric"):
        make_report(local_results, tmp_path, metrics=("nonsense",), plots=False)


def test_cli_run_and_report(tmp_path: Path, local_results: Path, capsys: pytest.CaptureFixture[str]) -> None:
    results, report = tmp_path / "results", tmp_path / "report"
    argv = ["run", "--config", "smoke", "--results", str(results), "--schemes", "full,actions", "--seeds", "1"]
    assert main([*argv, "--dry-run"]) == 0
    assert "2 run(s) to do, 0 finished" in capsys.readouterr().out
    assert main([*argv, "--episodes", "30", "--n-checkpoints", "3", "--num-agent-neighbors", "1", "--quiet"]) == 0
    output = capsys.readouterr().out
    assert "[2/2]" in output and "left" in output  # sweep progress: runs done of total, time left
    config = json.loads((results / "smoke" / "actions" / "seed_000" / "config.json").read_text())
    assert (config["episodes"], config["n_checkpoints"], config["num_agent_neighbors"]) == (30, 3, 1)

    # Report from a copy of the local sweep plus this one: two settings, both with MADDPG.
    shutil.copytree(local_results / "smoke", results / "smoke_local")
    for path in (results / "smoke_local").glob("*/seed_*/summary.json"):
        summary = json.loads(path.read_text())
        path.write_text(json.dumps({**summary, "experiment": "smoke_local"}))
    assert main(["report", str(results), "--out", str(report), "--metric", "coverage", "--metric", "return_mean"]) == 0
    for metric in ("coverage", "return_mean"):
        for name in (f"table_{metric}.md", f"table_{metric}.csv", f"learning_curves_{metric}.png", f"boxplot_{metric}.png"):
            assert (report / name).exists(), name
    assert main(["report", str(results), "--out", str(report), "--metric", "success_rate_r0.2", "--no-plots"]) == 0
    capsys.readouterr()
    (tmp_path / "nothing").mkdir()  # a directory without finished runs (a missing one is a usage error: 2)
    assert main(["report", str(tmp_path / "nothing"), "--no-plots"]) == 1
    assert "sb3-maddpg report: No finished runs" in capsys.readouterr().err
    # One scheme's kwargs from the command line, over the preset's.
    fresh = ["run", "--config", "smoke", "--results", str(tmp_path / "fresh")]
    assert main([*fresh, "--scheme-model-kwargs", '{"selected": {"selector": 1}}', "--dry-run"]) == 0
    assert '"scheme_model_kwargs": {"selected": {"selector": 1}}' in capsys.readouterr().out
    table = (report / "table_coverage.md").read_text()
    assert "| smoke (N=3, 1 nearest obs., 30 ep.) |" in table
    assert "| smoke_local" in table


# ---------------------------------------------------------------------------------------------------------------
# The committed small-scale result

REPO = Path(__file__).resolve().parents[2]
PAPER_SMALL_RESULTS = REPO / "benchmarks" / "paper_small" / "results"


REPORTED_EXPERIMENTS = {"paper_n5_independent": ("paper_n5i_exp1", "paper_n5i_exp2")}
"""Studies whose report reads some of their results directory's experiments (the rest: a learning curve's runs)."""
COMMITTED_REPORTS = [
    (REPO / "benchmarks" / name / "results", REPO / "docs" / "_static" / name)
    for name in (
        "paper_small",
        "paper_n3",
        "paper_n5_outlook",
        "learned_selection",
        "paper_n5",
        "paper_n5_independent",
        "pursuit",
    )
    if (REPO / "docs" / "_static" / name).is_dir()
]


@pytest.mark.slow
@pytest.mark.parametrize(("results", "report"), COMMITTED_REPORTS, ids=lambda path: path.parent.name)
def test_report_regenerates_the_committed_results(results: Path, report: Path, tmp_path: Path) -> None:
    committed_tables = sorted(report.glob("table_*.md"))
    assert committed_tables, f"no committed tables in {report}"
    metrics = [path.stem.removeprefix("table_") for path in committed_tables]
    # Reports are made from the seeds every scheme has finished: a sweep cut short still compares like with like,
    # and runs finished since (not yet in the report) do not change it. A study's report.sh may name its experiments.
    link_complete_seeds(results, tmp_path / "view", REPORTED_EXPERIMENTS.get(results.parent.name))
    written = make_report(tmp_path / "view", tmp_path / "report", metrics=metrics)
    for path in written:
        if (
            path.name == MARL_EVAL_FILE
        ):  # not committed with the docs (tests/experiments/test_results_for_any_task.py checks it)
            continue
        committed = report / path.name
        assert committed.exists(), committed
        if path.suffix in (".md", ".csv"):
            assert path.read_text() == committed.read_text(), path.name


def test_only_seeds_every_scheme_finished_are_linked(tmp_path: Path) -> None:
    results = tmp_path / "results"
    for name, schemes, finished in (
        ("both", ["full", "selected"], {"full": [0, 1, 2], "selected": [0, 2]}),
        ("none_common", ["full", "attention"], {"full": [0], "attention": []}),
    ):
        write_experiment(results, name, {"schemes": schemes})
        for scheme, seeds in finished.items():
            for seed in seeds:
                (results / name / scheme / f"seed_{seed:03d}").mkdir(parents=True)
                (results / name / scheme / f"seed_{seed:03d}" / "done").write_text("")
        (results / name / schemes[1] / "seed_001").mkdir(parents=True, exist_ok=True)  # started, not finished
    left_out = link_complete_seeds(results, tmp_path / "view")
    assert left_out == ["both/full/seed_001", "none_common/full/seed_000"]
    view = tmp_path / "view"
    assert sorted(str(path.relative_to(view)) for path in view.glob("*/*/seed_*")) == [
        "both/full/seed_000",
        "both/full/seed_002",
        "both/selected/seed_000",
        "both/selected/seed_002",
    ]
    assert (view / "both" / "experiment.json").is_file() and not (view / "none_common").exists()


def test_only_the_named_experiments_are_linked_and_an_unknown_name_is_refused(tmp_path: Path) -> None:
    results = tmp_path / "results"
    for name in ("study", "curve"):
        write_experiment(results, name, {"schemes": ["full"]})
        (results / name / "full" / "seed_000").mkdir(parents=True)
        (results / name / "full" / "seed_000" / "done").write_text("")
    assert link_complete_seeds(results, tmp_path / "view", ["study"]) == []
    assert sorted(path.name for path in (tmp_path / "view").iterdir()) == ["study"]
    link_experiments(results, tmp_path / "whole", ["curve"])
    assert sorted(path.name for path in (tmp_path / "whole").iterdir()) == ["curve"]
    assert (tmp_path / "whole" / "curve" / "full" / "seed_000" / "done").is_file()
    for link in (link_complete_seeds, link_experiments):
        with pytest.raises(ValueError, match=r"^no experiment stuyd in .* \(it holds: curve, study\)"):
            link(results, tmp_path / f"refused_{link.__name__}", ["stuyd", "stuyd"])
        assert not (tmp_path / f"refused_{link.__name__}").exists()
    with pytest.raises(ValueError, match=r"^no experiment study in .*: it holds no experiment; give the results dir"):
        link_experiments(tmp_path / "empty", tmp_path / "refused_empty", ["study"])


def test_report_of_named_experiments_leaves_out_the_others(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    results = tmp_path / "results"
    shutil.copytree(PAPER_SMALL_RESULTS, results)
    (setting,) = [path.parent.name for path in results.glob("*/experiment.json")]
    # A learning curve's runs beside the study's: a copy of them (the same setting, so its runs count twice).
    shutil.copytree(results / setting, results / "curve")
    argv = ["report", str(results), "--metric", "min_dist_sum", "--no-plots"]

    def runs_per_scheme(out: Path) -> dict[str, int]:
        with open(out / "table_min_dist_sum.csv") as file:
            return {row["scheme"]: int(row["n"]) for row in csv.DictReader(file)}

    assert main([*argv, "--out", str(tmp_path / "all")]) == 0
    assert main([*argv, "--out", str(tmp_path / "named"), "--experiment", setting]) == 0
    assert main([*argv, "--out", str(tmp_path / "complete"), "--experiment", setting, "--complete-seeds"]) == 0
    named = runs_per_scheme(tmp_path / "named")
    assert runs_per_scheme(tmp_path / "all") == {scheme: 2 * runs for scheme, runs in named.items()}
    assert runs_per_scheme(tmp_path / "complete") == named and set(named.values()) == {8}
    assert main([*argv, "--out", str(tmp_path / "twice"), "--experiment", setting, "--experiment", setting]) == 0
    assert runs_per_scheme(tmp_path / "twice") == named
    # Named experiments without a finished run: the error names them, not the directory's other runs.
    for run in (results / "curve").glob("*/seed_*"):
        (run / "done").unlink()
    capsys.readouterr()
    for complete in ([], ["--complete-seeds"]):
        assert main([*argv, "--out", str(tmp_path / "unfinished"), "--experiment", "curve", *complete]) == 1
        assert f"{results} (experiments curve)" in capsys.readouterr().err
    capsys.readouterr()
    assert main([*argv, "--out", str(tmp_path / "refused"), "--experiment", "cruve"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("sb3-maddpg report: --experiment: no experiment cruve in") and "it holds: curve, " in err
    assert len(err.splitlines()) == 1 and not (tmp_path / "refused").exists()


def test_report_of_complete_seeds_leaves_out_a_seed_one_scheme_has_not_finished(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    results = tmp_path / "results"
    shutil.copytree(PAPER_SMALL_RESULTS, results)
    (setting,) = [path.parent for path in results.glob("*/experiment.json")]
    (setting / "full" / "seed_003" / "done").unlink()  # one scheme's seed 3 still running
    (setting / "selected" / "seed_005" / "done").unlink()  # another's seed 5
    argv = ["report", str(results), "--metric", "min_dist_sum", "--no-plots"]

    def runs_per_scheme(out: Path) -> dict[str, int]:
        with open(out / "table_min_dist_sum.csv") as file:
            return {row["scheme"]: int(row["n"]) for row in csv.DictReader(file)}

    listing = sorted(results.rglob("*"))
    assert main([*argv, "--out", str(tmp_path / "all")]) == 0
    all_runs = runs_per_scheme(tmp_path / "all")
    assert main([*argv, "--out", str(tmp_path / "complete"), "--complete-seeds"]) == 0
    complete = runs_per_scheme(tmp_path / "complete")
    err = capsys.readouterr().err
    # Seeds 3 and 5 are left out of every scheme, and the finished runs of them are named.
    assert set(complete) == set(all_runs) and all(complete[scheme] == all_runs["independent"] - 2 for scheme in complete)
    assert f"{setting.name}/independent/seed_003" in err and f"{setting.name}/full/seed_005" in err
    assert f"{setting.name}/full/seed_003" not in err  # not finished: not a run left out
    assert sorted(results.rglob("*")) == listing  # nothing written into the results
    # An error names the user's directory, not the temporary view of it.
    assert main(["report", str(results), "--metric", "bob_correct", "--no-plots", "--complete-seeds"]) == 2
    err = capsys.readouterr().err
    assert f"no run in {results} scores --metric bob_correct" in err and "sb3_maddpg_report_" not in err
    # No seed finished by every scheme: said, and nothing reported.
    for run in (setting / "full").glob("seed_*"):
        (run / "done").unlink(missing_ok=True)
    assert main([*argv, "--out", str(tmp_path / "none"), "--complete-seeds"]) == 1
    assert "no seed in" in capsys.readouterr().err and not (tmp_path / "none").exists()


def test_report_of_some_seeds_reads_the_study_as_it_stood_then(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    results = tmp_path / "results"
    shutil.copytree(PAPER_SMALL_RESULTS, results)
    (setting,) = [path.parent for path in results.glob("*/experiment.json")]
    (setting / "full" / "seed_003" / "done").unlink()  # one scheme's seed 3 still running
    argv = ["report", str(results), "--metric", "min_dist_sum", "--no-plots"]

    def runs_per_scheme(out: Path) -> dict[str, int]:
        with open(out / "table_min_dist_sum.csv") as file:
            return {row["scheme"]: int(row["n"]) for row in csv.DictReader(file)}

    assert main([*argv, "--out", str(tmp_path / "first"), "--seeds", "0-2,5"]) == 0
    assert set(runs_per_scheme(tmp_path / "first").values()) == {4}  # seeds 0, 1, 2 and 5 of every scheme
    assert capsys.readouterr().err == ""  # no finished run of those seeds left out
    assert main([*argv, "--out", str(tmp_path / "with_3"), "--seeds", "2-3"]) == 0
    assert set(runs_per_scheme(tmp_path / "with_3").values()) == {1}  # seed 3 is not finished by full
    err = capsys.readouterr().err
    assert err.startswith("sb3-maddpg report: --seeds leaves out") and f"{setting.name}/independent/seed_003" in err
    assert main([*argv, "--out", str(tmp_path / "none"), "--seeds", "3,40"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("sb3-maddpg report: no seed of --seeds 3,40 in") and "(seeds finished there: 0-7)" in err
    assert not (tmp_path / "none").exists()
    for bad in ("4-2", "a", "-1", "1,,2"):
        assert main([*argv, "--out", str(tmp_path / "bad"), "--seeds", bad]) == 2
        assert capsys.readouterr().err.startswith(f"sb3-maddpg report: --seeds {bad!r}: give seeds and ranges, e.g. 0-4")


def test_a_report_s_user_errors_are_one_line_naming_the_cause_and_the_fix_with_exit_status_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A metric the runs do not score, or a report directory that cannot be one, is the user's error: one line on
    stderr (the cause, then what to do), exit status 2, nothing written; as a missing results directory or a metric
    ``--metric`` does not take."""
    results, out = tmp_path / "results", tmp_path / "report"
    shutil.copytree(PAPER_SMALL_RESULTS, results)
    listing = sorted(results.rglob("*"))

    def refused(*options: str) -> str:
        assert main(["report", str(results), "--no-plots", *options]) == 2
        captured = capsys.readouterr()
        assert captured.out == "" and captured.err.count("\n") == 1 and captured.err.startswith("sb3-maddpg report: ")
        assert sorted(results.rglob("*")) == listing and not out.exists()  # nothing written
        return captured.err

    # A metric of another task (simple_crypto's): named, with the metrics these runs score that --metric takes (not
    # return_std or episode_length, which it refuses), and the fix.
    err = refused("--out", str(out), "--metric", "bob_correct")
    assert err == (
        f"sb3-maddpg report: no run in {results} scores --metric bob_correct; the runs there score collisions, "
        "coverage, min_dist_sum, return_mean, success_rate: give --metric one of those, or leave --metric out for "
        "each task's main metrics.\n"
    )
    # Several, among metrics the runs do score: those they do not are named; a radius says why old runs lack it.
    err = refused("--out", str(out), "--metric", "min_dist_sum", "--metric", "group_return", "--metric", "coverage_r0.2")
    assert f"no run in {results} scores --metric group_return, coverage_r0.2 (runs written before 0.2" in err
    # The report's directory is a file, or inside one.
    (tmp_path / "file").write_text("")
    for where in ("file", "file/report"):
        err = refused("--out", str(tmp_path / where), "--metric", "min_dist_sum")
        assert f"the report's directory {tmp_path / where} " in err and "give --out a directory (new or existing)" in err
    # A metric --metric does not take, and a missing results directory, were refused so already.
    assert "--metric 'nonsense' is no score: give one of" in refused("--metric", "nonsense")
    assert main(["report", str(tmp_path / "missing"), "--no-plots"]) == 2
    assert capsys.readouterr().err.startswith(f"sb3-maddpg report: no results directory {tmp_path / 'missing'}: give ")
    # The command itself, as a shell runs it: the status and the line, no traceback.
    done = subprocess.run(
        [sys.executable, "-m", "sb3_maddpg", "report", str(results), "--no-plots", "--metric", "bob_correct"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert done.stderr.startswith(f"sb3-maddpg report: no run in {results} scores --metric bob_correct; ")
    # The library's make_report raises the error as a ValueError (its text unchanged), before writing anything.
    with pytest.raises(ValueError, match=r"Unknown metric\(s\) \['bob_correct'\]"):
        make_report(results, out, metrics=("bob_correct",), plots=False)
    assert not out.exists()


def test_the_small_scale_result_is_its_config() -> None:
    assert COMMITTED_REPORTS[0][0] == PAPER_SMALL_RESULTS
    config = json.loads((REPO / "benchmarks" / "paper_small" / "config.json").read_text())
    summaries = load_summaries(PAPER_SMALL_RESULTS)
    assert {s["experiment"] for s in summaries} == {config["name"]}
    assert len([s for s in summaries if s["scheme"] == "full"]) >= 3


def test_scheme_order_is_defined_once_and_plots_do_not_import_the_report() -> None:
    from sb3_maddpg.experiments.config import ordered_schemes

    assert ordered_schemes(["selected", "zeta", "full", "alpha", "full"]) == ["full", "selected", "alpha", "zeta"]
    assert ordered_schemes(reversed(SCHEMES)) == list(SCHEMES)
    # report imports plots (lazily) for its figures; plots must not import report back, at any level.
    import sb3_maddpg.results.plots as plots

    tree = ast.parse(Path(plots.__file__).read_text())
    imported = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    imported |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    assert "sb3_maddpg.results.report" not in imported
    assert "sb3_maddpg.experiments.results_dir" in imported  # sanity: the walk sees plots' imports


def test_a_setting_of_another_algorithm_is_labelled_with_its_name() -> None:
    # The report's scheme columns keep the paper's MADDPG names: the setting's label must say a MATD3 sweep is one.
    maddpg = EXP1.to_dict()
    assert setting_label("exp1", maddpg) == "exp1 (N=5, full obs., 100,000 ep.)"
    matd3 = {**maddpg, "algorithm": "sb3_maddpg:MATD3"}
    assert setting_label("exp1", matd3) == "exp1 (MATD3, N=5, full obs., 100,000 ep.)"
    other_task = {**matd3, "env": "simple_tag"}
    assert setting_label("tag", other_task) == "tag (MATD3, simple_tag, 100,000 ep.)"


def test_model_kwargs_from_the_command_line_keep_the_settings_policy_kwargs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # A setting that shares parameters, told on the command line to normalise layers too, does both.
    setting = tmp_path / "shared.json"
    policy_kwargs = {**SMOKE.model_kwargs["policy_kwargs"], "share_parameters": True}
    shared = SMOKE.replace(name="shared", model_kwargs={**SMOKE.model_kwargs, "policy_kwargs": policy_kwargs})
    setting.write_text(json.dumps(shared.to_dict()))
    argv = ["run", "--config", str(setting), "--results", str(tmp_path / "r"), "--dry-run"]
    assert main([*argv, "--model-kwargs", '{"policy_kwargs": {"layer_norm": true}}']) == 0
    printed = json.loads(capsys.readouterr().out.splitlines()[0].split(": ", 1)[1])
    assert printed["model_kwargs"]["policy_kwargs"] == {
        **SMOKE.model_kwargs["policy_kwargs"],
        "share_parameters": True,
        "layer_norm": True,
    }


def test_a_setting_that_observes_every_agent_nearest_first_is_labelled_full() -> None:
    # exp1_tuned observes all 4 other agents, in order of distance: that is full observability, not "4 nearest".
    assert setting_label("exp1_tuned", EXP1_TUNED.to_dict()) == "exp1_tuned (N=5, full obs. nearest first, 100,000 ep.)"
    assert setting_label("exp2", EXP2.to_dict()) == "exp2 (N=5, 2 nearest obs., 150,000 ep.)"


def test_curve_value_at_reads_the_nearest_evaluation_and_none_beyond_the_tolerance() -> None:
    rows = [{"timesteps": 100_000.0, "min_dist_sum": 2.0}, {"timesteps": 196_000.0, "min_dist_sum": 1.5}]
    assert curve_value_at(rows, 200_000) == 1.5  # 2% away: the nearest evaluation
    assert curve_value_at(rows, 104_000) == 2.0
    assert curve_value_at(rows, 250_000) is None  # the nearest is 22% away: the run says nothing there
    assert curve_value_at(rows, 250_000, tolerance=0.25) == 1.5
    assert curve_value_at([], 200_000) is None
    assert curve_value_at([{"timesteps": 200_000.0, "min_dist_sum": 1.0, "return_mean": -5.0}], 200_000, "return_mean") == -5.0


def _curve_run(directory: Path, experiment: str, scheme: str, values: list[float], every: int = 50_000) -> dict[str, Any]:
    directory.mkdir(parents=True)
    rows = ["timesteps,min_dist_sum"] + [f"{(index + 1) * every},{value}" for index, value in enumerate(values)]
    (directory / "learning_curve.csv").write_text("\n".join(rows) + "\n")
    return {"experiment": experiment, "scheme": scheme, "directory": str(directory)}


def test_experiment_curves_draw_each_factor_against_env_and_gradient_steps(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from sb3_maddpg.results import plots

    summaries = [
        _curve_run(tmp_path / "a0", "paper", "full", [2.0, 1.8, 1.6]),
        _curve_run(tmp_path / "a1", "paper", "full", [2.2, 2.0, 1.8]),
        _curve_run(tmp_path / "b0", "utd25", "full", [1.5, 1.0, 0.5]),
        _curve_run(tmp_path / "c0", "left_out", "full", [9.0, 9.0, 9.0]),
    ]
    drawn: dict[str, Any] = {}
    monkeypatch.setattr(plots, "_save", lambda figure, path: drawn.update(figure=figure))
    plots.plot_experiment_curves(
        summaries,
        "min_dist_sum",
        tmp_path / "curves.png",
        {"paper": "the paper's", "utd25": "one step per 25"},
        transitions_per_update={"paper": 100, "utd25": 25},
        learning_starts=50_000,
        levels={"random": 2.9},
        y_max=2.5,
    )
    env_axis, gradient_axis = drawn["figure"].axes
    for axis, x_paper, x_utd25 in (
        (env_axis, [50_000, 100_000, 150_000], [50_000, 100_000, 150_000]),
        (gradient_axis, [0, 500, 1_000], [0, 2_000, 4_000]),  # (env steps - learning starts) / ratio
    ):
        lines = {line.get_label(): line for line in axis.get_lines()}
        assert set(lines) == {"the paper's", "one step per 25", "random"}  # the unlisted experiment is not drawn
        np.testing.assert_allclose(lines["the paper's"].get_xdata(), x_paper)
        np.testing.assert_allclose(lines["the paper's"].get_ydata(), [2.1, 1.9, 1.7])  # IQM of two runs: their mean
        np.testing.assert_allclose(lines["one step per 25"].get_xdata(), x_utd25)
        np.testing.assert_allclose(lines["random"].get_ydata(), [2.9, 2.9])
        assert axis.get_ylim() == (0.0, 2.5)
    with pytest.raises(ValueError, match="no ratio for utd25"):
        plots.plot_experiment_curves(
            summaries, "min_dist_sum", tmp_path / "x.png", {"utd25": "x"}, transitions_per_update={"paper": 100}
        )
    mixed = [*summaries, _curve_run(tmp_path / "a2", "paper", "selected", [1.0, 1.0, 1.0])]
    with pytest.raises(ValueError, match="'paper' has runs of 2 schemes"):
        plots.plot_experiment_curves(mixed, "min_dist_sum", tmp_path / "x.png", {"paper": "x"})


def test_an_experiments_algorithm_argument_is_its_own_else_its_algorithms_default() -> None:
    from sb3_maddpg import MADDPG, MATD3
    from sb3_maddpg.envs import make_simple_spread

    env = make_simple_spread(n_agents=2)
    paper = EXP1.to_dict()
    assert algorithm_argument(paper, "transitions_per_update") == MADDPG("MlpPolicy", env).transitions_per_update
    assert algorithm_argument(paper, "learning_starts") == MADDPG("MlpPolicy", env).learning_starts
    stored = EXP1.replace(model_kwargs={"transitions_per_update": 25}).to_dict()
    assert algorithm_argument(stored, "transitions_per_update") == 25
    matd3 = EXP1.replace(algorithm="sb3_maddpg:MATD3").to_dict()
    assert algorithm_argument(matd3, "policy_delay") == MATD3("MlpPolicy", env).policy_delay
    per_scheme = EXP1.replace(scheme_model_kwargs={"selected": {"transitions_per_update": 50}}).to_dict()
    assert algorithm_argument(per_scheme, "transitions_per_update", scheme="selected") == 50
    assert algorithm_argument(per_scheme, "transitions_per_update", scheme="full") == 100
    with pytest.raises(ValueError, match=r"sb3_maddpg:MADDPG has no argument 'policy_delay' with a default"):
        algorithm_argument(paper, "policy_delay")
