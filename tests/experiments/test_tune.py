"""sb3-maddpg tune: the sampler gives MADDPG's arguments, a tiny study runs, is killed mid-trial, resumes (the killed
trial failed and retried), prunes, and prints the best trial as a preset that `sb3-maddpg run` takes."""

import contextlib
import multiprocessing
import os
import re
import signal
import subprocess
import sys
import time
import types
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import optuna
import pytest
from sqlalchemy.exc import IntegrityError, OperationalError

from sb3_maddpg import MADDPG
from sb3_maddpg.cli.main import main
from sb3_maddpg.envs import make_simple_spread
from sb3_maddpg.experiments import SMOKE
from sb3_maddpg.experiments.presets import read_preset_file
from sb3_maddpg.tuning.search import (
    TrialEvalCallback,
    TuneSettings,
    finished_trials,
    load_study,
    open_storage,
    run_study,
    sample_maddpg_params,
)
from tests.process_helpers import alive, spawned_workers, wait_for
from tests.settings import FILLS_THE_BUFFER_ONLY, SELECTS_EVERY_OTHER_AGENT

TINY = SMOKE.replace(schemes=("full",))


def settings(tmp_path: Path, **changes) -> TuneSettings:
    values = dict(
        experiment=TINY,
        study_name="tiny",
        storage=f"sqlite:///{tmp_path / 'tune.db'}",
        n_trials=2,
        budget=800,
        n_evaluations=2,
        eval_episodes=2,
        last_evaluations=1,
        heartbeat_seconds=1,
    )
    return TuneSettings(**{**values, **changes})


def test_the_sampler_gives_arguments_maddpg_takes() -> None:
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    for _ in range(5):
        kwargs = sample_maddpg_params(study.ask())
        assert 1e-4 <= kwargs["learning_rate"] <= 2e-2 and 0.02 <= kwargs["noise_std"] <= 0.5
        width = kwargs["policy_kwargs"]["net_arch"]["pi"][0]
        assert kwargs["policy_kwargs"]["net_arch"] == {"pi": [width] * 2, "qf": [width] * 3}
        model = MADDPG("MlpPolicy", make_simple_spread(n_agents=2), **kwargs)
        assert model.transitions_per_update == kwargs["transitions_per_update"] and model.gamma == kwargs["gamma"]


@pytest.mark.slow
def test_a_tiny_study_runs_and_gives_a_preset_run_takes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    preset = tmp_path / "best.yml"
    argv = ["tune", "--config", "smoke", "--scheme", "full", "--n-trials", "2", "--budget", "800", "--n-evaluations", "2"]
    argv += ["--eval-episodes", "2", "--last-evaluations", "1", "--storage", f"sqlite:///{tmp_path / 'tune.db'}"]
    assert main([*argv, "--preset-out", str(preset)]) == 0
    out = capsys.readouterr().out
    assert "best trial" in out and "(lower is better) of 2 finished trials" in out
    assert re.search(r"trial 1: 400/800 steps, min_dist_sum \d+\.\d{4}, \d+\.\d min\n", out)  # progress per evaluation
    (config,) = read_preset_file(preset)
    study = load_study(settings(tmp_path, study_name="smoke_min_dist_sum"))
    assert (
        config.name == "smoke_min_dist_sum_best" and config.model_kwargs["learning_rate"] == study.best_params["learning_rate"]
    )
    assert config.model_kwargs["learning_starts"] == SMOKE.model_kwargs["learning_starts"]  # the setting's own stay
    # The trial's value is its last evaluation's min-dist sum (last_evaluations=1): a real evaluation, not a constant.
    assert 0.0 < study.best_value < 10.0 and len({trial.value for trial in study.trials}) == 2
    # And the preset runs.
    assert main(["run", "--config", str(preset), "--seeds", "1", "--episodes", "20", "--results", str(tmp_path / "r")]) == 0


@FILLS_THE_BUFFER_ONLY
def test_every_trial_is_pruned_by_a_pruner_that_always_prunes(tmp_path: Path) -> None:
    # min-dist sums are positive: a threshold of 0 prunes at the first report after warm-up (step 0 here).
    study = run_study(settings(tmp_path, pruner=optuna.pruners.ThresholdPruner(upper=0.0)))
    states = [trial.state for trial in study.trials]
    assert states == [optuna.trial.TrialState.PRUNED] * 2 and finished_trials(study) == 2
    # Pruned after its first evaluation: one intermediate value, at the step of the first evaluation.
    assert all(len(trial.intermediate_values) == 1 for trial in study.trials)


@FILLS_THE_BUFFER_ONLY
@SELECTS_EVERY_OTHER_AGENT
def test_the_callback_stops_training_when_the_pruner_says_so() -> None:
    reports = []

    class Trial:
        def report(self, value: float, step: int) -> None:
            reports.append((step, value))

        def should_prune(self) -> bool:
            return len(reports) >= 2

    env = make_simple_spread(n_agents=2)
    model = MADDPG("MlpPolicy", env, learning_starts=50, batch_size=16, policy_kwargs={"net_arch": [8]})
    callback = TrialEvalCallback(
        Trial(), "min_dist_sum", None, eval_env=make_simple_spread(n_agents=2), eval_freq=50, n_eval_episodes=1
    )
    model.learn(1_000, callback=callback)
    assert callback.pruned and model.num_timesteps == 100  # stopped at the second evaluation, not at 1,000 steps
    assert [step for step, _ in reports] == [50, 100] and reports[0][1] == callback.history[0]["min_dist_sum"]


@pytest.mark.slow
def test_a_killed_study_resumes_and_retries_the_killed_trial(tmp_path: Path) -> None:
    db = tmp_path / "tune.db"
    argv = [sys.executable, "-m", "sb3_maddpg", "tune", "--config", "smoke", "--scheme", "full"]
    argv += ["--n-trials", "2", "--budget", "3000", "--n-evaluations", "3", "--eval-episodes", "2", "--last-evaluations", "1"]
    argv += ["--storage", f"sqlite:///{db}", "--heartbeat-seconds", "1", "--study-name", "killed"]
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy"}
    process = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    study_settings = settings(tmp_path, study_name="killed", n_trials=2, budget=3000, n_evaluations=3)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline:  # kill it inside its first trial, once that trial has reported
        time.sleep(0.5)
        if db.exists():
            trials = load_study(study_settings).trials
            if trials and trials[0].intermediate_values:
                break
    process.send_signal(signal.SIGKILL)
    process.wait(timeout=30)
    assert load_study(study_settings).trials[0].state == optuna.trial.TrialState.RUNNING  # left as it was
    time.sleep(3)  # past the grace period of two heartbeats
    resumed = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=600, check=False)
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    states = [trial.state for trial in load_study(study_settings).trials]
    # The killed trial failed; its retry and one more completed: 2 finished, as asked.
    assert states[0] == optuna.trial.TrialState.FAIL, states
    assert states.count(optuna.trial.TrialState.COMPLETE) == 2, states
    killed, retried = load_study(study_settings).trials[:2]
    assert retried.system_attrs["failed_trial"] == 0 and retried.params == killed.params  # the same sample, again


def test_workers_and_resumed_runs_draw_samples_of_their_own(tmp_path: Path) -> None:
    # Samplers seeded alike drew the same samples in every worker and again after each resume (three of a study's
    # first seven trials were one sample).
    shared = settings(tmp_path, fixed_params={"width": 64})

    def draw(study: optuna.Study) -> dict[str, Any]:
        trial = study.ask()
        sample_maddpg_params(trial)
        return trial.params

    first = draw(load_study(shared, worker=0))
    beside = draw(load_study(shared, worker=1))  # another worker of the same command
    resumed = draw(load_study(shared, worker=0))  # the same command again, later
    assert first != beside and resumed not in (first, beside) and first["width"] == beside["width"] == 64
    # A new study of one worker still draws from the study's seed alone: reproducible.
    again = settings(tmp_path, storage=f"sqlite:///{tmp_path / 'again.db'}", fixed_params={"width": 64})
    assert draw(load_study(again)) == first


@pytest.mark.parametrize("budget", [1_000_000, 1_000_050])
@pytest.mark.parametrize("warmup", [0, 1, 2])
def test_the_default_pruner_spares_the_warmup_evaluations(tmp_path: Path, warmup: int, budget: int) -> None:
    # Five finished trials at 1.0 at every evaluation, then one at 10.0: the pruner may stop it only past the first
    # `warmup` evaluations (a first evaluation, near the random warm-up, said nothing and pruned good samples).
    # Reports land where a run's evaluations do: at the multiples of the evaluation step (whole steps of every world).
    study_settings = settings(tmp_path, budget=budget, n_evaluations=4, warmup_evaluations=warmup)
    study = load_study(study_settings)
    n_envs = study_settings.experiment.n_envs
    steps = [k * (budget // 4 // n_envs) * n_envs for k in range(1, 5)]
    for _ in range(5):
        trial = study.ask()
        for step in steps:
            trial.report(1.0, step)
        study.tell(trial, 1.0)
    trial = study.ask()
    prunes = []
    for step in steps:
        trial.report(10.0, step)
        prunes.append(trial.should_prune())
    assert prunes == [False] * warmup + [True] * (4 - warmup)


@pytest.mark.slow
@pytest.mark.parametrize("stop", ["SIGTERM", "SIGKILL", "Ctrl-C"])
def test_a_stopped_study_takes_its_workers_with_it(tmp_path: Path, stop: str) -> None:
    # Two workers in trials that would run for minutes: killing the study's process must stop them too, or they go
    # on training (a core each) on trials that the resumed study retries anyway. Ctrl-C in a terminal reaches the
    # whole process group: the study stops its workers and says how to resume, without a traceback.
    db, log = tmp_path / "tune.db", tmp_path / "tune.log"
    argv = [sys.executable, "-m", "sb3_maddpg", "tune", "--config", "smoke", "--scheme", "full"]
    argv += ["--n-trials", "4", "--budget", "10000000", "--n-evaluations", "2", "--eval-episodes", "1"]
    # Heartbeats far apart: a loaded machine must not see one worker fail the other's trial as stale meanwhile.
    argv += ["--last-evaluations", "1", "--storage", f"sqlite:///{db}", "--heartbeat-seconds", "60", "--workers", "2"]
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy"}
    with open(log, "w") as out:  # a file, not a pipe: an orphaned worker would hold a pipe open
        process = subprocess.Popen(argv, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    workers: list[int] = []
    try:
        study_settings = settings(tmp_path, study_name="smoke_min_dist_sum", n_trials=4, budget=10_000_000)

        def both_workers_in_a_trial() -> bool:
            if process.poll() is not None:
                raise AssertionError(f"the study ended before it was stopped:\n{log.read_text()}")
            workers[:] = spawned_workers(process.pid)
            running = optuna.trial.TrialState.RUNNING
            return db.exists() and len(workers) == 2 and len(load_study(study_settings).get_trials(states=(running,))) == 2

        wait_for(both_workers_in_a_trial, "two workers in a trial each", timeout=120, interval=0.5)
        if stop == "Ctrl-C":
            os.killpg(process.pid, signal.SIGINT)
        else:
            process.send_signal(signal.SIGTERM if stop == "SIGTERM" else signal.SIGKILL)
        process.wait(timeout=60)
        for worker in workers:
            wait_for(lambda worker=worker: not alive(worker), f"worker {worker} to exit with the stopped study", timeout=10)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
    if stop != "SIGKILL":  # Ctrl-C and SIGTERM (a started-in-the-background study's stop) end it cleanly
        output = log.read_text()
        status = 130 if stop == "Ctrl-C" else 143  # 128 + the signal, as a shell reports it
        assert process.returncode == status and "the same command resumes the study" in output, output
        assert "Traceback" not in output, output


def test_a_bad_thread_count_with_workers_is_refused_clearly(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["tune", "--config", "smoke", "--n-trials", "1", "--budget", "800", "--workers", "2", "--threads", "0"]
    assert main([*argv, "--storage", f"sqlite:///{tmp_path / 'tune.db'}"]) == 2
    assert "threads must be a positive integer, got 0" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"objective": "speed"},
            r"^objective 'speed' is not one of simple_spread's objectives: give one of min_dist_sum",
        ),
        (
            {"last_evaluations": 3},
            r"^last_evaluations \(the last evaluations whose mean is a trial's value\) must be an integer in "
            r"\[1, n_evaluations = 2\], got 3: lower last_evaluations or raise n_evaluations\.$",
        ),
        ({"budget": 0}, r"^budget \(env steps per trial\) must be an integer >= 1, got 0: use "),
        ({"n_trials": 2.5}, r"^n_trials \(finished trials at which the study stops\) must be an integer >= 1, got 2\.5"),
        ({"eval_episodes": True}, r"^eval_episodes \(episodes per evaluation\) must be an integer >= 1, got True"),
        ({"warmup_evaluations": -1}, r"^warmup_evaluations \(.*\) must be an integer >= 0, got -1: 0 lets the pruner stop"),
        (
            {"experiment": TINY.replace(env="simple_tag"), "objective": "min_dist_sum"},
            r"'min_dist_sum' is not one of simple_tag's objectives: give one of collisions \(maximize\) \(group_return needs "
            r"the experiment's score_agents\)",
        ),
    ],
)
def test_bad_settings_say_what_to_do(tmp_path: Path, changes: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        settings(tmp_path, **changes)


def test_a_settings_policy_kwargs_stay_under_the_sampled_width(tmp_path: Path) -> None:
    # A setting that shares parameters (or normalises layers) must keep doing so in every trial: the sample sets the
    # width through policy_kwargs too, and replacing the setting's policy_kwargs whole dropped share_parameters.
    shared = TINY.replace(model_kwargs={**TINY.model_kwargs, "policy_kwargs": {"share_parameters": True, "layer_norm": True}})
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    sample = sample_maddpg_params(study.ask())
    kwargs = settings(tmp_path, experiment=shared).run_config(sample).model_kwargs
    assert kwargs["policy_kwargs"] == {"share_parameters": True, "layer_norm": True, **sample["policy_kwargs"]}
    assert kwargs["learning_starts"] == TINY.model_kwargs["learning_starts"] and kwargs["gamma"] == sample["gamma"]
    assert shared.model_kwargs["policy_kwargs"] == {"share_parameters": True, "layer_norm": True}  # not written into


def test_fixed_parameters_hold_in_every_trial_and_the_others_are_searched(tmp_path: Path) -> None:
    fixed = {"transitions_per_update": 50, "width": 64, "learning_rate": 1e-3}
    study = run_study(settings(tmp_path, n_trials=3, fixed_params=fixed))
    trials = [trial for trial in study.trials if trial.state.name == "COMPLETE"]
    assert len(trials) == 3
    for trial in trials:
        kwargs = trial.user_attrs["model_kwargs"]
        assert (kwargs["transitions_per_update"], kwargs["learning_rate"]) == (50, 1e-3)
        assert kwargs["policy_kwargs"]["net_arch"] == {"pi": [64, 64], "qf": [64, 64, 64]}
    assert len({trial.params["noise_std"] for trial in trials}) == 3  # the rest is still sampled


@pytest.mark.parametrize(
    ("fixed", "message"),
    [
        ({"hidden": 64}, r"^fixed parameter 'hidden' is not a sampled parameter: fix one of \['actor_reg_coef', 'batch_size'"),
        ({"width": 96}, r"^fixed parameter width=96 is not one of its choices \[64, 128, 256\]"),
        ({"learning_rate": 0.5}, r"^fixed parameter learning_rate=0.5 is outside its range \[0.0001, 0.02\]"),
        ({"transitions_per_update": 25.0}, r"^fixed parameter transitions_per_update=25.0 is not one of"),  # an int
    ],
)
def test_parameters_a_study_cannot_fix_are_refused(tmp_path: Path, fixed: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        settings(tmp_path, fixed_params=fixed)


def test_the_tune_command_takes_fixes_and_names_its_study_by_them(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    storage = f"sqlite:///{tmp_path / 'tune.db'}"
    argv = ["tune", "--config", "smoke", "--scheme", "full", "--n-trials", "1", "--budget", "800", "--n-evaluations", "1"]
    argv += ["--eval-episodes", "2", "--last-evaluations", "1", "--storage", storage]
    assert main([*argv, "--fixed-params", '{"transitions_per_update": 50, "width": 64}']) == 0
    assert "fixed in every trial: transitions_per_update=50, width=64" in capsys.readouterr().out
    names = optuna.study.get_all_study_names(storage)
    assert names == ["smoke_min_dist_sum_transitions_per_update=50_width=64"]
    assert main([*argv, "--fixed-params", "{width: 64, transitions_per_update: 50}"]) == 0  # the same study, resumed
    assert optuna.study.get_all_study_names(storage) == names
    assert main([*argv, "--fixed-params", "width"]) == 2
    assert "--fixed-params: 'width' is not a mapping (JSON or YAML" in capsys.readouterr().err


def open_the_study_at_once(storage: str, barrier: Any) -> int:
    barrier.wait()  # every process past its imports, so that they create the new file's tables together
    study = load_study(TuneSettings(experiment=TINY, study_name="together", storage=storage, heartbeat_seconds=1))
    return len(study.trials)


@pytest.mark.slow
def test_workers_that_open_a_new_study_together_all_get_it(tmp_path: Path) -> None:
    # --workers N opens one new SQLite file from N processes at once; each creates the tables, and without the
    # retry every one but the first fails with "table ... already exists" (the CI failure of 2026-12-01).
    storage, workers = f"sqlite:///{tmp_path / 'together.db'}", 4
    with multiprocessing.Manager() as manager:
        barrier = manager.Barrier(workers)
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(workers, mp_context=context) as pool:
            futures = [pool.submit(open_the_study_at_once, storage, barrier) for _ in range(workers)]
            assert [future.result(timeout=120) for future in futures] == [0] * workers


def test_opening_a_storage_retries_only_the_race_of_creating_its_tables() -> None:
    calls: list[int] = []

    def created_by_another_worker_twice() -> str:
        calls.append(1)
        if len(calls) <= 2:
            raise OperationalError("CREATE TABLE studies", {}, Exception("table studies already exists"))
        return "storage"

    assert open_storage(created_by_another_worker_twice, wait_seconds=0) == "storage" and len(calls) == 3

    def version_row_written_by_another_worker() -> str:
        calls.append(1)
        if len(calls) <= 4:
            raise IntegrityError("INSERT INTO alembic_version", {}, Exception("UNIQUE constraint failed: alembic_version"))
        return "storage"

    assert open_storage(version_row_written_by_another_worker, wait_seconds=0) == "storage" and len(calls) == 5

    def locked() -> str:
        raise OperationalError("SELECT", {}, Exception("database is locked"))

    with pytest.raises(OperationalError, match="database is locked"):
        open_storage(locked, wait_seconds=0)


def test_the_objectives_are_the_tasks_metrics_in_their_directions() -> None:
    from sb3_maddpg.experiments.config import TUNE_OBJECTIVES
    from sb3_maddpg.tuning.search import task_objectives

    assert task_objectives(TINY) == TUNE_OBJECTIVES and next(iter(TUNE_OBJECTIVES)) == "min_dist_sum"
    # simple_tag's catches, for the predators; no team return, which would add the prey's to the predators'.
    assert task_objectives(TINY.replace(env="simple_tag")) == {"collisions": "maximize"}
    tag_group = TINY.replace(env="simple_tag", score_agents=("adversary_0", "adversary_1", "adversary_2"))
    assert task_objectives(tag_group) == {"collisions": "maximize", "group_return": "maximize"}
    assert task_objectives(TINY.replace(env="simple")) == {"goal_distance": "minimize", "return_mean": "maximize"}
    # A gymnasium id's env declares its own metrics; this one simple_spread's, scored as simple_spread's are.
    spread = {"min_dist_sum": "minimize", "return_mean": "maximize"}
    assert task_objectives(TINY.replace(env="sb3_maddpg/SimpleSpread-v3")) == spread


@pytest.mark.slow
def test_tune_on_another_task_optimises_that_tasks_metric(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    storage, preset = f"sqlite:///{tmp_path / 'tune.db'}", tmp_path / "best.yml"
    argv = ["tune", "--config", "smoke", "--env", "simple_tag", "--scheme", "full", "--n-trials", "2", "--budget", "800"]
    argv += ["--n-evaluations", "2", "--eval-episodes", "2", "--last-evaluations", "1", "--storage", storage]
    assert main([*argv, "--preset-out", str(preset)]) == 0
    out = capsys.readouterr().out
    assert "on smoke (simple_tag, N=4, scheme full), objective collisions (maximize)" in out
    assert re.search(r"trial 1: 400/800 steps, collisions \d+\.\d{4}", out) and "(higher is better)" in out
    study = optuna.load_study(study_name="smoke_simple_tag_collisions", storage=storage)
    assert study.direction == optuna.study.StudyDirection.MAXIMIZE
    for trial in study.trials:  # each trial scores its last evaluation's catches per episode (2 episodes)
        assert trial.value == trial.intermediate_values[max(trial.intermediate_values)]
        assert trial.value >= 0 and (2 * trial.value).is_integer()
    (config,) = read_preset_file(preset)
    assert (config.env, config.n_agents) == ("simple_tag", 4) and "simple_tag, 4 agents" in config.description


def test_tunes_help_names_every_option_with_its_default(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tune", "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())
    for option, default in (
        ("--n-trials", "50"),
        ("--budget", "1000000"),
        ("--n-evaluations", "10"),
        ("--eval-episodes", "100"),
        ("--last-evaluations", "3"),
        ("--warmup-evaluations", "1"),
        ("--heartbeat-seconds", "60"),
        ("--config", "exp1"),
    ):
        # The option's own help (up to the next "default:"), not the usage line's "[--n-trials N_TRIALS]".
        assert re.search(rf"{option} [A-Z_]+ (?:(?!default:).)*default: {default}\)", help_text), option
    for option in ("--env", "--num-agent-neighbors", "--objective", "--fixed-params", "--workers", "--address"):
        assert f"{option} " in help_text, option


@pytest.mark.filterwarnings("ignore:evaluate_team")  # simple_tag gives no min-dist sum: said once per evaluation
def test_an_objective_the_evaluations_do_not_score_stops_the_study_clearly() -> None:
    # Optuna fails a trial whose value is NaN and starts another, which fares no better: the study would never end.
    from sb3_maddpg.envs import make_mpe_env

    study = optuna.create_study()
    env = make_mpe_env("simple_tag")
    callback = TrialEvalCallback(study.ask(), "min_dist_sum", None, eval_env=make_mpe_env("simple_tag"), eval_freq=50)
    callback.n_eval_episodes = 1
    model = MADDPG("MlpPolicy", env, learning_starts=50, batch_size=16, policy_kwargs={"net_arch": [8]})
    with pytest.raises(ValueError, match=r"trial 0's min_dist_sum is nan at step 50: the"):
        model.learn(1_000, callback=callback)


def test_a_study_on_ray_reaches_ray_as_a_sweep_does(monkeypatch: pytest.MonkeyPatch) -> None:
    """``--backend ray`` goes through the sweeps' ``ray_session``: a local instance's workers at normal priority (not
    Ray's niceness 15), shut down after the study; one task per worker, ``threads`` CPUs each."""
    from sb3_maddpg.tuning import search as tune

    calls: dict[str, Any] = {"tasks": []}

    def remote(**options: Any) -> Any:
        return lambda work: types.SimpleNamespace(remote=lambda *args: calls["tasks"].append((options, args[1:])))

    fake = types.SimpleNamespace(
        is_initialized=lambda: False,
        init=lambda **kwargs: calls.update(init=kwargs),
        shutdown=lambda: calls.update(shutdown=True),
        remote=remote,
        get=lambda refs: None,
    )
    monkeypatch.setitem(sys.modules, "ray", fake)
    monkeypatch.setattr(tune, "load_study", lambda settings, worker=0: "the study")
    assert run_study(None, workers=2, backend="ray", threads=3) == "the study"  # type: ignore[arg-type]
    assert calls["init"]["_system_config"] == {"worker_niceness": 0} and calls["init"]["address"] is None
    assert calls.get("shutdown")
    assert calls["tasks"] == [({"num_cpus": 3}, (3, 0)), ({"num_cpus": 3}, (3, 1))]
