"""Sweeps survive faults: killed workers and sweeps, half-written run directories, two sweeps at once, Ctrl-C.

Runs are tiny (N=3, 20 episodes, tiny networks). A run is stopped mid-run deterministically by
:class:`tests.fault_helpers.StallingMADDPG`: the run of one scheme stalls at its first training step and
writes its process id, and the test kills that process, or the sweep around it.
"""

import contextlib
import json
import os
import re
import runpy
import signal
import subprocess
import sys
import threading
import time
import types
from collections.abc import Callable
from pathlib import Path

import pytest

from sb3_maddpg.cli.main import main
from sb3_maddpg.cli.termination import Termination, run_stoppable, sigterm_as_ctrl_c
from sb3_maddpg.common.install_hint import extra_install_command
from sb3_maddpg.experiments import SMOKE, ExperimentConfig, run_sweep
from sb3_maddpg.experiments.local_pool import LOST_RUN
from sb3_maddpg.experiments.ray_tasks import ray_parallel_tasks, ray_task_options
from sb3_maddpg.experiments.results_dir import (
    CONFIG_FILE,
    DONE_FILE,
    SUMMARY_FILE,
    SWEEP_LOG,
    is_finished,
    load_summaries,
    write_experiment,
    write_result_files,
)
from sb3_maddpg.experiments.runner import execute_run
from sb3_maddpg.experiments.sweep import SweepProgress, SweepResult, plan_sweep
from tests.fault_helpers import stalled_pid
from tests.process_helpers import alive, wait_for

REPO = Path(__file__).resolve().parents[2]
STALLING = "tests.fault_helpers:StallingMADDPG"
FOUR = ("full", "independent", "actions", "observations")


def experiment(schemes: tuple[str, ...] = FOUR, stalls: dict[str, Path] | None = None) -> ExperimentConfig:
    """Tiny runs; ``stalls`` maps schemes to trigger files: while its trigger exists, that scheme's run stalls."""
    return SMOKE.replace(
        name="faults",
        schemes=schemes,
        seeds=(0,),
        episodes=20,
        n_checkpoints=1,
        eval_episodes=2,
        curve_points=0,
        algorithm=STALLING if stalls else None,
        scheme_model_kwargs={scheme: {"stall_trigger": str(trigger)} for scheme, trigger in stalls.items()}
        if stalls
        else None,
    )


def ignores_sigint(pid: int) -> bool:
    """Whether a process ignores SIGINT (Linux: the SigIgn mask in /proc)."""
    mask = next(line for line in Path(f"/proc/{pid}/status").read_text().splitlines() if line.startswith("SigIgn:"))
    return bool(int(mask.split()[1], 16) & (1 << (signal.SIGINT - 1)))


def finished_runs(results: Path, exp: ExperimentConfig) -> set[str]:
    return {config.run_id for config in exp.runs() if is_finished(results, config)}


def done_stamps(results: Path, run_ids: set[str]) -> dict[str, int]:
    return {run_id: (results / run_id / DONE_FILE).stat().st_mtime_ns for run_id in run_ids}


def run_directories(results: Path) -> set[str]:
    return {str(path.parent.relative_to(results)) for path in results.glob(f"*/*/seed_*/{CONFIG_FILE}")}


def done_lines(log: str, run_id: str) -> int:
    """How many times a sweep log says the run finished."""
    return sum(f" {run_id} done in " in line for line in log.splitlines())


def start_cli_sweep(exp: ExperimentConfig, results: Path, *options: str, in_background: bool = False) -> subprocess.Popen[str]:
    """
    ``python -m sb3_maddpg run`` in its own session (a terminal's process group), from the repository.

    :param in_background: Start it as a script's ``cmd &`` does (no job control): with SIGINT ignored.
    """
    config_path = results.parent / f"{results.name}.json"
    config_path.write_text(json.dumps(exp.to_dict()))
    command = [sys.executable, "-m", "sb3_maddpg", "run", "--config", str(config_path), "--results", str(results)]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    return subprocess.Popen(
        [*command, *options],
        cwd=REPO,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=(lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)) if in_background else None,
    )


def stop_session(process: subprocess.Popen[str]) -> None:
    """Kill what is left of a subprocess's session (its workers too), whatever the test did."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGKILL)
    process.communicate()


def check_resume(results: Path, exp: ExperimentConfig, resume: Callable[[], SweepResult]) -> None:
    """The same sweep again runs exactly the missing runs, leaves the finished ones alone, ends like a clean sweep."""
    everything = {config.run_id for config in exp.runs()}
    before = finished_runs(results, exp)
    stamps = done_stamps(results, before)
    log_before = (results / SWEEP_LOG).read_text()
    resumed = resume()
    assert resumed.ok, resumed.failed
    assert resumed.skipped == len(before)
    assert sorted(summary["run_id"] for summary in resumed.completed) == sorted(everything - before)
    assert done_stamps(results, before) == stamps  # finished runs untouched
    assert finished_runs(results, exp) == everything
    assert run_directories(results) == everything  # a clean sweep's set of run directories, nothing more
    assert {summary["run_id"] for summary in load_summaries(results)} == everything
    log = (results / SWEEP_LOG).read_text().removeprefix(log_before)
    for run_id in everything:
        assert done_lines(log, run_id) == (run_id not in before), run_id  # each missing run once, no other
    assert not list(results.rglob("*.tmp"))


# ---------------------------------------------------------------------------------------------------------------
# Files


def test_half_written_run_directories_are_run_again(tmp_path: Path) -> None:
    exp = experiment(schemes=("full", "independent", "actions", "observations", "selected"))
    results = tmp_path / "results"
    assert run_sweep([exp], results, verbose=0).ok
    intact, no_done, no_summary, truncated_summary, truncated_config = (results / c.run_id for c in exp.runs())
    (no_done / DONE_FILE).unlink()  # files, but no done marker
    (no_summary / SUMMARY_FILE).unlink()  # a done marker without a summary
    text = (truncated_summary / SUMMARY_FILE).read_text()
    (truncated_summary / SUMMARY_FILE).write_text(text[: len(text) // 2])
    text = (truncated_config / CONFIG_FILE).read_text()
    (truncated_config / CONFIG_FILE).write_text(text[: len(text) // 2])

    run_id = {directory: directory.relative_to(results).as_posix() for directory in results.glob("*/*/seed_*")}
    assert finished_runs(results, exp) == {run_id[intact]}
    with pytest.warns(UserWarning, match="unreadable"):
        summaries = load_summaries(results)  # the report leaves out the runs without a readable summary
    assert {summary["run_id"] for summary in summaries} == {run_id[intact], run_id[truncated_config]}
    check_resume(results, exp, lambda: run_sweep([exp], results, verbose=0))


def test_run_files_are_written_whole_and_done_last(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    config = experiment(schemes=("full",)).runs()[0]
    replaced: list[str] = []
    real_replace = os.replace

    def recording_replace(source: str | os.PathLike[str], target: str | os.PathLike[str]) -> None:
        replaced.append(Path(target).name)
        real_replace(source, target)

    monkeypatch.setattr(os, "replace", recording_replace)
    result = execute_run(config, tmp_path, verbose=0)
    # Every file a resume reads is renamed into place whole, and the done marker is the last of them.
    assert {CONFIG_FILE, SUMMARY_FILE, "checkpoint_evals.csv", DONE_FILE} <= set(replaced)
    assert replaced[-1] == DONE_FILE and replaced.count(DONE_FILE) == 1

    # A crash just before a file is renamed into place leaves the old file (or none), never a part of one.
    crash_before: set[str] = set()

    def crashing_replace(source: str | os.PathLike[str], target: str | os.PathLike[str]) -> None:
        if Path(target).name in crash_before:
            raise OSError(f"simulated crash before {Path(target).name}")
        real_replace(source, target)

    monkeypatch.setattr(os, "replace", crashing_replace)
    crash_before.add(SUMMARY_FILE)
    with pytest.raises(OSError, match="simulated crash before summary.json"):
        execute_run(config, tmp_path / "crashed", verbose=0)
    assert not (tmp_path / "crashed" / config.run_id / SUMMARY_FILE).exists()
    assert not (tmp_path / "crashed" / config.run_id / DONE_FILE).exists()
    with pytest.raises(OSError, match="simulated crash before summary.json"):
        write_result_files(tmp_path / "collected", result)  # a remote run's files, collected here
    assert not is_finished(tmp_path / "collected", config)
    crash_before.clear()
    write_result_files(tmp_path / "collected", result)
    assert is_finished(tmp_path / "collected", config)
    write_experiment(tmp_path, "exp", {"version": 1})
    crash_before.add("experiment.json")
    with pytest.raises(OSError, match="simulated crash before experiment.json"):
        write_experiment(tmp_path, "exp", {"version": 2})
    assert json.loads((tmp_path / "exp" / "experiment.json").read_text())["version"] == 1
    assert not list(tmp_path.rglob("*.tmp"))  # no temporary file is left behind, crash or not


# ---------------------------------------------------------------------------------------------------------------
# Killed workers, killed sweeps, two sweeps at once (local process pool)


@pytest.mark.slow
def test_a_killed_local_worker_loses_only_the_runs_in_progress(tmp_path: Path) -> None:
    killed, beside, results = tmp_path / "killed", tmp_path / "beside", tmp_path / "results"
    killed.touch()
    beside.touch()
    # Two workers: full, then actions, run beside independent; observations waits for a free worker.
    exp = experiment(stalls={"independent": killed, "actions": beside})

    def kill_a_stalled_worker() -> None:
        wait_for(lambda: stalled_pid(killed) and stalled_pid(beside), "two stalled runs")
        os.kill(stalled_pid(killed), signal.SIGKILL)  # type: ignore[arg-type]

    killer = threading.Thread(target=kill_a_stalled_worker, daemon=True)
    killer.start()
    result = run_sweep([exp], results, workers=2, verbose=0)
    killer.join()
    # The killed worker's run and the one beside it (the pool stops every worker when one dies) are lost and
    # reported; the run not started goes on in a new pool.
    assert sorted(result.lost) == sorted(result.failed) == ["faults/actions/seed_000", "faults/independent/seed_000"]
    assert all(error.startswith(LOST_RUN) and "run the same command again" in error for error in result.failed.values())
    completed = sorted(summary["run_id"] for summary in result.completed)
    assert completed == ["faults/full/seed_000", "faults/observations/seed_000"]
    log = (results / SWEEP_LOG).read_text()
    assert "a worker process died: 2 run(s) in progress lost" in log and "1 run(s) not started go on in new worker" in log
    assert "2 failed (2 lost with a worker process that died); run the same command again" in log

    check_resume(results, exp, lambda: run_sweep([exp], results, verbose=0))


@pytest.mark.slow
def test_a_killed_local_sweep_resumes_and_a_second_sweep_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    trigger, results = tmp_path / "stall", tmp_path / "results"
    trigger.touch()
    exp = experiment(stalls={"independent": trigger})
    sweep = start_cli_sweep(exp, results, "--workers", "2", "--quiet")
    try:
        first_run = exp.runs()[0].run_id
        wait_for(lambda: stalled_pid(trigger) and (results / first_run / DONE_FILE).exists(), "a stalled run")
        # A second sweep on the same directory is refused, naming the first one, and changes nothing.
        log_before = (results / SWEEP_LOG).read_text()
        assert main(["run", "--config", str(tmp_path / "results.json"), "--results", str(results)]) == 1
        error = capsys.readouterr().err
        assert f"in use by another sweep (PID {sweep.pid}" in error and "another results directory" in error
        assert f"stop it (kill {sweep.pid}," in error  # SIGTERM stops a sweep started in the background too
        # The refused sweep wrote nothing; the first one's run lines may go on meanwhile (its next run can finish).
        log_after = (results / SWEEP_LOG).read_text()
        assert log_after.startswith(log_before) and "sweep of" not in log_after[len(log_before) :]

        os.kill(sweep.pid, signal.SIGKILL)  # the sweep's process only: its workers are orphaned ...
        sweep.wait()
        worker = stalled_pid(trigger)
        assert worker is not None
        wait_for(lambda: not alive(worker), "the killed sweep's worker to exit", timeout=10)  # ... and exit
    finally:
        stop_session(sweep)
    before = finished_runs(results, exp)
    assert first_run in before and "faults/independent/seed_000" not in before
    check_resume(results, exp, lambda: run_sweep([exp], results, verbose=0))  # the lock died with the sweep


def sweep_log(results: Path) -> str:
    """The results directory's sweep log so far (empty before it exists)."""
    path = results / SWEEP_LOG
    return path.read_text() if path.exists() else ""


@pytest.mark.slow
def test_ctrl_c_stops_the_cli_cleanly_and_the_same_command_resumes(tmp_path: Path) -> None:
    trigger, results = tmp_path / "stall", tmp_path / "results"
    trigger.touch()
    exp = experiment(schemes=("full", "independent"), stalls={"independent": trigger})
    sweep = start_cli_sweep(exp, results, "--workers", "2", "--quiet")
    try:
        wait_for(lambda: stalled_pid(trigger), "a stalled run")
        # The other run counted by the sweep itself (its progress line), not only written by its worker.
        wait_for(lambda: f"{exp.runs()[0].run_id} done" in sweep_log(results), "the sweep to count the other run")
        # Ctrl-C in a terminal reaches the whole foreground process group: the workers leave it to the sweep
        # (a worker that took it would fail its run, or print a traceback).
        assert ignores_sigint(stalled_pid(trigger)) and not ignores_sigint(sweep.pid)  # type: ignore[arg-type]
        os.killpg(sweep.pid, signal.SIGINT)
        out, err = sweep.communicate(timeout=60)
    finally:
        stop_session(sweep)
    assert sweep.returncode == 130, err
    assert "Traceback" not in out + err, err  # neither the sweep nor its workers dump one
    assert "sweep interrupted: 1 of 2 run(s) finished (1 by this sweep)" in out
    assert "Run the same command again to resume." in out
    worker = stalled_pid(trigger)
    assert worker is not None and not alive(worker)  # the workers are stopped, not left running
    todo, finished = plan_sweep([exp], results)  # the partial run is left for the next sweep
    assert [config.run_id for config in todo] == ["faults/independent/seed_000"] and finished == 1
    assert (results / "faults/independent/seed_000" / CONFIG_FILE).exists()


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 2])
def test_sigterm_stops_a_background_cli_sweep_as_ctrl_c_does(tmp_path: Path, workers: int) -> None:
    """Started in the background, a sweep ignores SIGINT; ``kill`` (SIGTERM), which the lock's message names, stops it
    cleanly, with its workers, and the same command resumes it."""
    trigger, results = tmp_path / "stall", tmp_path / "results"
    trigger.touch()
    exp = experiment(schemes=("full", "independent"), stalls={"independent": trigger})
    sweep = start_cli_sweep(exp, results, "--workers", str(workers), "--quiet", in_background=True)
    try:
        wait_for(lambda: stalled_pid(trigger), "a stalled run")
        wait_for(lambda: f"{exp.runs()[0].run_id} done" in sweep_log(results), "the sweep to count the other run")
        assert ignores_sigint(sweep.pid)  # kill -INT would not stop it
        sweep.terminate()
        out, err = sweep.communicate(timeout=60)
    finally:
        stop_session(sweep)
    assert sweep.returncode == 143, err  # 128 + SIGTERM, as a shell reports it
    assert "Traceback" not in out + err, err
    assert "sweep interrupted: 1 of 2 run(s) finished (1 by this sweep)" in out
    assert "Run the same command again to resume." in out
    worker = stalled_pid(trigger)
    assert worker is not None and not alive(worker)
    todo, finished = plan_sweep([exp], results)
    assert [config.run_id for config in todo] == ["faults/independent/seed_000"] and finished == 1


# ---------------------------------------------------------------------------------------------------------------
# Ray


@pytest.mark.slow
def test_ray_sweep_retries_a_killed_worker_and_resumes_after_a_killed_sweep(tmp_path: Path) -> None:
    pytest.importorskip("ray", reason="the Ray backend test needs ray (installed in CI through the dev extra)")
    retried, stalled, results = tmp_path / "retried", tmp_path / "stalled", tmp_path / "results"
    retried.touch()
    stalled.touch()
    exp = experiment(stalls={"independent": retried, "actions": stalled})
    sweep = start_cli_sweep(exp, results, "--backend", "ray", "--workers", "2", "--quiet")
    try:
        # A Ray worker killed mid-run: Ray runs the task again (the trigger is spent, so it finishes) ...
        wait_for(lambda: stalled_pid(retried), "a stalled run")
        os.kill(stalled_pid(retried), signal.SIGKILL)  # type: ignore[arg-type]
        others = [config.run_id for config in exp.runs() if config.scheme != "actions"]
        log = results / SWEEP_LOG

        def others_logged() -> bool:
            # The sweep's log line, not the run's done file: the driver writes it after the file, so killing the
            # sweep between the two would lose the line this test counts.
            text = log.read_text()
            return all(done_lines(text, run_id) for run_id in others)

        wait_for(
            lambda: "FAILED" in log.read_text() or bool(stalled_pid(stalled) and others_logged()),
            "the other runs, one stalled",
        )
        assert "FAILED" not in log.read_text()
        # ... and the whole sweep killed: Ray's workers go with it.
        os.kill(sweep.pid, signal.SIGKILL)
        sweep.wait()
        worker = stalled_pid(stalled)
        assert worker is not None
        wait_for(lambda: not alive(worker), "the killed sweep's Ray worker to exit", timeout=30)
    finally:
        stop_session(sweep)
    log = (results / SWEEP_LOG).read_text()
    assert "FAILED" not in log and done_lines(log, "faults/independent/seed_000") == 1  # retried, counted once
    assert finished_runs(results, exp) == {config.run_id for config in exp.runs() if config.scheme != "actions"}
    check_resume(results, exp, lambda: run_sweep([exp], results, verbose=0))  # the runs are the same on either backend


# ---------------------------------------------------------------------------------------------------------------
# The command line and the time-left estimate


def test_run_without_a_config_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--results", str(tmp_path / "results")]) == 2
    error = capsys.readouterr().err
    assert error.startswith("sb3-maddpg run: no experiment given: name one with --config")
    for words in ("--config exp1 --config exp2 (310 runs", "--dry-run", "smoke: 10 runs", "exp1: 155 runs"):
        assert words in error
    assert not (tmp_path / "results").exists()


def test_report_and_render_team_without_the_experiments_extra(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    results = REPO / "benchmarks" / "paper_small" / "results"
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib fails as if it were not installed
    assert main(["report", str(results), "--out", str(tmp_path / "report")]) == 1
    error = capsys.readouterr().err
    assert error.startswith("sb3-maddpg report: the figures need matplotlib, which is not installed")
    assert extra_install_command("experiments") in error and "--no-plots" in error
    assert not (tmp_path / "report").exists()  # said before anything is written
    assert main(["report", str(results), "--out", str(tmp_path / "report"), "--no-plots"]) == 0  # tables need no extra

    monkeypatch.setitem(sys.modules, "imageio", None)
    monkeypatch.setitem(sys.modules, "imageio.v3", None)
    with pytest.raises(
        SystemExit, match=r"needs imageio, which is not installed: " + re.escape(extra_install_command("experiments"))
    ):
        runpy.run_path(str(REPO / "examples" / "render_team.py"))


def test_the_time_left_counts_the_runs_executing_at_once() -> None:
    lines: list[str] = []
    progress = SweepProgress(total=10, skipped=0, parallel=4, echo=False)
    progress.log = lines.append  # type: ignore[method-assign]
    progress.update("a", "done", duration=60)
    progress.update("b", "done", duration=120)
    assert lines[-1].endswith("left ~3m00s")  # mean 90 s x 8 runs left / 4 at once
    for run_id in "cdefgh":
        progress.update(run_id, "done", duration=90)
    assert lines[-1].endswith("left ~1m30s")  # 2 runs left share 2 of the 4 slots
    progress.update("i", "FAILED")
    progress.update("j", "done", duration=90)
    assert lines[-1].endswith("left ~0m00s")

    def ray_parallel_runs(resources: dict[str, float], threads: int) -> int:
        return ray_parallel_tasks(resources, ray_task_options(threads))

    assert ray_parallel_runs({"CPU": 16.0}, threads=3) == 5
    assert ray_parallel_runs({"CPU": 2.0}, threads=4) == 1 and ray_parallel_runs({}, threads=1) == 1


@pytest.mark.parametrize(("threads", "parallel"), [(1, 6), (2, 3)])
def test_a_ray_sweep_counts_the_clusters_cpus(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, threads: int, parallel: int
) -> None:
    # workers=0 means all of Ray's CPUs: the estimate must use what Ray reports, not max(1, workers) // threads.
    cluster = types.SimpleNamespace(
        is_initialized=lambda: True, cluster_resources=lambda: {"CPU": 6.0}, remote=lambda **options: lambda task: task
    )
    monkeypatch.setitem(sys.modules, "ray", cluster)
    assert run_sweep([experiment().replace(seeds=())], tmp_path, backend="ray", workers=0, threads=threads, verbose=0).ok
    assert f"Ray: {parallel} run(s) at once ({threads} CPU(s) each)" in (tmp_path / SWEEP_LOG).read_text()


def test_sigterm_raises_keyboard_interrupt_inside_the_block_and_its_handler_comes_back() -> None:
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt), sigterm_as_ctrl_c() as termination:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)  # the handler runs at the next bytecode: not reached
    assert signal.getsignal(signal.SIGTERM) is before
    assert termination.received
    assert termination.exit_status(130) == 143 and termination.exit_status(1) == 1
    assert Termination().exit_status(130) == 130  # Ctrl-C's status stays without SIGTERM


def sigterm_to_self() -> int:
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(5)  # the handler runs at the next bytecode: not reached
    return 0


def ctrl_c() -> int:
    raise KeyboardInterrupt


@pytest.mark.parametrize(
    ("command", "status", "said"), [(lambda: 0, 0, False), (ctrl_c, 130, True), (sigterm_to_self, 143, True)]
)
def test_a_stoppable_command_says_it_was_stopped_and_exits_as_a_shell_reports_the_signal(
    capsys: pytest.CaptureFixture[str], command: Callable[[], int], status: int, said: bool
) -> None:
    before = signal.getsignal(signal.SIGTERM)
    assert run_stoppable(command, "stopped; the same command resumes") == status
    assert ("stopped; the same command resumes" in capsys.readouterr().err) is said
    assert signal.getsignal(signal.SIGTERM) is before
