"""Pursuit through the package's own path (issue 57): the preset, the metrics a task's env declares, the reference
policies on the runs' own episodes, and a tiny sweep through ``sb3-maddpg run`` read by ``sb3-maddpg report``."""

import importlib.util
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.cli.main import main
from sb3_maddpg.envs import PettingZooToGym, RandomTeamPolicy, TaskMetric
from sb3_maddpg.experiments import SMOKE
from sb3_maddpg.experiments.config import EXPERIMENTS
from sb3_maddpg.experiments.reference_specs import check_reference_policies
from sb3_maddpg.experiments.references import NoOpTeamPolicy, write_references
from sb3_maddpg.experiments.runner import execute_run
from sb3_maddpg.experiments.tasks import RunTask, run_task
from sb3_maddpg.results import make_report
from sb3_maddpg.results.reference_table import load_references
from sb3_maddpg.tuning.search import task_objectives

BEYOND_MPE = Path(__file__).resolve().parents[2] / "benchmarks" / "beyond_mpe" / "results" / "pursuit_seed0.json"
"""What the Beyond MPE study ran with (its seed 0's record)."""

SCHEMES = ["independent", "full", "observations", "actions", "selected", "selected_next"]

HAS_SISL = importlib.util.find_spec("pygame") is not None
"""Whether pursuit can be built here (PettingZoo's SISL envs need pygame: the sisl extra)."""

sisl = pytest.mark.skipif(not HAS_SISL, reason="pursuit needs the sisl extra (pygame)")


def test_the_pursuit_preset_is_beyond_mpes_setting_and_its_dry_run_lists_30_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pursuit, beyond = EXPERIMENTS["pursuit"], json.loads(BEYOND_MPE.read_text())
    assert pursuit.env_kwargs == beyond["env_kwargs"]
    trained = beyond["hyperparameters"]
    for name in ("learning_rate", "buffer_size", "learning_starts", "batch_size", "gamma", "tau", "noise_std"):
        assert pursuit.model_kwargs[name] == trained[name], name
    assert pursuit.model_kwargs["transitions_per_update"] == trained["transitions_per_update"]
    assert pursuit.model_kwargs["policy_kwargs"] == trained["policy_kwargs"]
    assert (pursuit.n_envs, pursuit.episodes * pursuit.episode_length) == (trained["n_envs"], 200_000)
    assert (pursuit.n_checkpoints, pursuit.eval_episodes) == (1, beyond["eval_episodes"])  # the team at the end, 50 ep.
    assert pursuit.scheme_model_kwargs["selected_next"] == {
        "critic_sharing": "selected",
        "selector": {"k": 2, "target": "next"},
    }
    assert pursuit.reference_policies == {"random": {"kind": "random"}, "nothing": {"kind": "no_op", "action": 4}}

    assert main(["run", "--config", "pursuit", "--results", str(tmp_path), "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    runs = [line.split(":")[0].strip() for line in lines if line.startswith("  pursuit/")]
    assert len(runs) == 30 and lines[-1] == "30 run(s) to do, 0 finished"
    assert runs == [f"pursuit/{scheme}/seed_{seed:03d}" for seed in range(5) for scheme in SCHEMES]


def declaring_env(**kwargs: Any) -> PettingZooToGym:
    """A task of a factory's own: mpe2's ``simple`` with a metric no MPE task declares, lower is better."""
    from mpe2 import simple_v3

    def distance_left(env: Any) -> dict[str, float]:
        world = env.unwrapped.world
        return {"distance_left": float(np.linalg.norm(world.agents[0].state.p_pos - world.landmarks[0].state.p_pos))}

    metric = TaskMetric("distance_left", "last", "lower", "team", "the agent's distance to its landmark at the end")
    parallel = simple_v3.parallel_env(continuous_actions=True, max_cycles=25, **kwargs)
    return PettingZooToGym(parallel, metrics_fn=distance_left, task_metrics=[metric])


def test_a_factorys_task_is_scored_and_reported_by_the_metrics_its_env_declares(tmp_path: Path) -> None:
    experiment = SMOKE.replace(schemes=("full",), seeds=(0,), episodes=30, n_checkpoints=1, env=f"{__name__}:declaring_env")
    config = experiment.runs()[0]
    task = run_task(config)
    assert [metric.key for metric in task.metrics] == ["distance_left"]
    assert task.higher_is_better["distance_left"] is False  # the env's declared direction, no METRICS entry
    assert task_objectives(experiment) == {"distance_left": "minimize", "return_mean": "maximize"}
    summary = execute_run(config, tmp_path, verbose=0)
    assert np.isfinite(summary["score"]["distance_left"])
    assert summary["task_metrics"][0]["key"] == "distance_left" and summary["task_metrics"][0]["better"] == "lower"
    (tmp_path / config.experiment).mkdir(exist_ok=True)
    (tmp_path / config.experiment / "experiment.json").write_text(json.dumps(experiment.to_dict()))
    written = make_report(tmp_path, tmp_path / "report", plots=False, verbose=0)
    assert tmp_path / "report" / "table_distance_left.md" in written  # a main metric of the task, unasked
    assert "distance left, mean (std) over runs" in (tmp_path / "report" / "table_distance_left.md").read_text()
    assert "(lower is better)" in (tmp_path / "report" / "table_distance_left.md").read_text()


class EpisodeStarts(VecEnvWrapper):
    """Records the first observation of every episode after each seeding, by seed (every evaluation seeds first)."""

    seen: dict[int, list[list[np.ndarray]]] = {}

    def __init__(self, venv: VecEnv) -> None:
        super().__init__(venv)
        self.current: list[np.ndarray] | None = None

    def seed(self, seed: int | None = None) -> Any:
        self.current = []
        EpisodeStarts.seen.setdefault(int(seed or 0), []).append(self.current)
        return self.venv.seed(seed)

    def reset(self) -> Any:
        observations = self.venv.reset()
        if self.current is not None:
            self.current.append(observations[0].copy())
        return observations

    def step_wait(self) -> Any:
        observations, rewards, dones, infos = self.venv.step_wait()
        if self.current is not None and dones[0]:
            self.current.append(observations[0].copy())  # the next episode's first (the env reset itself)
        return observations, rewards, dones, infos


def record_episode_starts(monkeypatch: pytest.MonkeyPatch) -> dict[int, list[list[np.ndarray]]]:
    """:return: Every seeded evaluation's episode starts from now on, by seed (the runs' and the references' alike)."""
    original = RunTask.make_eval_env
    EpisodeStarts.seen = {}
    monkeypatch.setattr(RunTask, "make_eval_env", lambda task, n: EpisodeStarts(original(task, n)))
    return EpisodeStarts.seen


@sisl
def test_reference_policies_are_evaluated_on_each_seeds_evaluation_episodes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    experiment = EXPERIMENTS["pursuit"].replace(seeds=(0, 3), eval_episodes=3)
    seen = record_episode_starts(monkeypatch)
    lines: list[str] = []
    write_references(experiment, tmp_path, lines.append)
    stored = load_references(tmp_path)["pursuit"]
    assert list(stored) == ["random", "nothing"] and "evaluated 4" in lines[0]
    for config in [config for config in experiment.runs() if config.scheme == "full"]:
        task = run_task(config)
        for name, entry in stored.items():
            held = entry["seeds"][str(config.seed)]
            assert (held["eval_seed"], held["n_episodes"]) == (config.eval_seed, 3)  # the seed's runs' own
            env = task.make_eval_env(3)
            team = (
                RandomTeamPolicy(env.action_space, seed=config.eval_seed)
                if name == "random"
                else NoOpTeamPolicy(env.action_space, env.get_attr("agent_layout")[0], 4)
            )
            again = evaluate_team(team, env, n_episodes=3, seed=config.eval_seed, task_metrics=task.metrics)
            assert held["score"] == {key: again[key] for key in task.keys}
        starts = seen[config.eval_seed]
        assert len(starts) == 4  # each reference, then each by hand: the same 3 episodes (and the next's start)
        for other in starts[1:]:
            np.testing.assert_array_equal(np.array(other), np.array(starts[0]))
    assert stored["nothing"]["seeds"]["0"]["score"]["evaders_caught"] == 0.0  # staying still catches no one


def test_references_are_kept_across_sweeps_and_evaluated_again_for_another_protocol(tmp_path: Path) -> None:
    policies = {"random": {"kind": "random"}, "still": {"kind": "no_op"}}  # simple_spread: continuous, zero actions
    experiment = SMOKE.replace(seeds=(0,), reference_policies=policies)
    lines: list[str] = []
    write_references(experiment, tmp_path, lines.append)
    first = load_references(tmp_path)["smoke"]
    assert list(first["still"]["seeds"]) == ["0"] and "evaluated 2" in lines[-1]
    write_references(experiment, tmp_path, lines.append)
    assert lines[-1].endswith("held already") and load_references(tmp_path)["smoke"] == first
    write_references(experiment.replace(seeds=(0, 1)), tmp_path, lines.append)
    assert "evaluated 2 (random seed 1, still seed 1)" in lines[-1]
    assert load_references(tmp_path)["smoke"]["random"]["seeds"]["0"] == first["random"]["seeds"]["0"]
    write_references(experiment.replace(eval_episodes=3), tmp_path, lines.append)  # other episodes: evaluated again
    assert "evaluated 2" in lines[-1] and load_references(tmp_path)["smoke"]["random"]["seeds"]["0"]["n_episodes"] == 3


def test_doing_nothing_is_the_no_op_for_discrete_agents_and_zero_for_continuous_ones() -> None:
    from sb3_maddpg.envs import make_simple_spread

    if HAS_SISL:
        from sb3_maddpg.envs.sisl import pursuit_env

        pursuit = pursuit_env(n_pursuers=3)
        action, _ = NoOpTeamPolicy(pursuit.action_space, pursuit.agent_layout, 4).predict(np.zeros((2, 3)))
        assert action.shape == (2, 15)
        assert pursuit.agent_actions(action[1]) == {"pursuer_0": 4, "pursuer_1": 4, "pursuer_2": 4}  # stay, each
    spread = make_simple_spread(n_agents=3)
    action, _ = NoOpTeamPolicy(spread.action_space, spread.agent_layout).predict(np.zeros(spread.observation_space.shape))
    np.testing.assert_array_equal(action, np.zeros(spread.action_space.shape))  # no force


@pytest.mark.parametrize(
    ("policies", "message"),
    [
        ({"random": "random"}, "'random' is 'random', no policy: give a mapping with a kind of"),
        ({"r": {"kind": "scripted"}}, "no policy: give a mapping with a kind of ['random', 'no_op']"),
        ({"r": {"kind": "random", "action": 1}}, "'r' (random) has unknown key(s) ['action']: a random policy takes"),
        ({"n": {"kind": "no_op", "action": -1}}, "has action=-1: give the discrete agents' no-op action as an index"),
        ({"a b": {"kind": "random"}}, "name 'a b' cannot name a reference policy"),
    ],
)
def test_bad_reference_policies_are_refused_naming_the_cause(policies: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)):
        check_reference_policies(policies)
    with pytest.raises(ValueError, match=re.escape(message)):
        SMOKE.replace(reference_policies=policies)


@sisl
def test_doing_nothing_without_a_no_op_for_discrete_agents_is_refused_before_any_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["run", "--config", "pursuit", "--seeds", "[0]", "--schemes", "full", "--results", str(tmp_path)]
    assert main([*argv, "--reference-policies", '{"nothing": {"kind": "no_op"}}', "--quiet"]) == 2
    error = capsys.readouterr().err
    assert "agent 'pursuer_0' has 5 discrete actions, and no no-op action is given" in error
    assert "{kind: no_op, action: 4}" in error
    assert not list(tmp_path.glob("pursuit/*/seed_*"))  # nothing trained


@sisl
@pytest.mark.slow
def test_a_tiny_pursuit_sweep_through_the_cli_is_reported_with_its_metric_and_references(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    seen = record_episode_starts(monkeypatch)
    kwargs = '{"learning_starts": 300, "batch_size": 32, "buffer_size": 3000, "policy_kwargs": {"net_arch": [16, 16]}}'
    results = str(tmp_path / "results")
    argv = ["run", "--config", "pursuit", "--episodes", "12", "--seeds", "0,1", "--schemes", "full,selected"]
    argv += ["--model-kwargs", kwargs, "--eval-episodes", "3", "--curve-points", "0", "--n-envs", "2"]
    assert main([*argv, "--results", results, "--quiet"]) == 0
    summary = json.loads((tmp_path / "results" / "pursuit" / "selected" / "seed_001" / "summary.json").read_text())
    assert {"evaders_caught", "return_mean"} <= set(summary["score"])
    # Each seed's checkpoint evaluations (one a run) and its two references saw the same seeded episodes.
    for seed in (0, 1):
        starts = seen[1_000_003 + 7919 * seed]
        assert len(starts) == 4
        for other in starts[1:]:
            np.testing.assert_array_equal(np.array(other[:3]), np.array(starts[0][:3]))

    capsys.readouterr()
    assert main(["report", results, "--no-plots"]) == 0
    printed = capsys.readouterr().out
    assert "evaders caught, higher is better" in printed and "reference: nothing" in printed
    report = tmp_path / "results" / "report"
    assert (report / "table_evaders_caught.md").exists() and (report / "table_return_mean.md").exists()
    table = (report / "references.md").read_text()
    for row in ("| MADDPG (`full`) | 0, 1 |", "| MADDPG-soa (`selected`) | 0, 1 |", "| reference: random | 0, 1 |"):
        assert row in table, row
    assert "| reference: nothing | 0, 1 | 0.00 [0.00, 0.00] |" in table  # no evader caught standing still
    assert "evaders caught (higher is better) | team return (higher is better)" in table
    complete = tmp_path / "complete"
    assert (
        main(["report", results, "--no-plots", "--complete-seeds", "--metric", "evaders_caught", "--out", str(complete)]) == 0
    )
    assert "reference: random" in (complete / "references.md").read_text()  # the references through the view too
