"""The command line on any task (issue 34, item 4): settings that describe themselves from their values, a run's own
team size, an evaluation schedule that follows the budget, the docs' examples sized to train, and a user's error said
in one line with exit status 2 in every subcommand."""

import dataclasses
import importlib.util
import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from sb3_maddpg.cli.main import main
from sb3_maddpg.experiments import EXP1, EXP2, SMOKE, ExperimentConfig
from sb3_maddpg.experiments.setting import describe_setting, scaled_schedule

REPO = Path(__file__).resolve().parents[2]

SCHEDULE = ("n_checkpoints", "eval_episodes", "curve_points", "curve_eval_episodes")


def schedule(experiment: ExperimentConfig | dict) -> tuple[int, ...]:
    if isinstance(experiment, dict):
        return tuple(experiment[name] for name in SCHEDULE)
    return tuple(getattr(experiment, name) for name in SCHEDULE)


def dry_run(capsys: pytest.CaptureFixture[str], tmp_path: Path, *argv: str) -> dict:
    """The first experiment that ``run ... --dry-run`` prints."""
    assert main(["run", *argv, "--results", str(tmp_path / "dry"), "--dry-run"]) == 0
    return json.loads(capsys.readouterr().out.splitlines()[0].split(": ", 1)[1])


# ---------------------------------------------------------------------------------------------------------------
# Descriptions derived from the values


def test_a_presets_description_says_its_values_and_an_override_changes_them() -> None:
    assert EXP1.description == (
        "Experiment 1: simple_spread, N=5, full observability, 100,000 episodes (2,500,000 steps), "
        "20 checkpoints x 100 episodes over the last 20%, 50 curve points x 20 episodes"
    )
    assert "2 nearest agents observed, 150,000 episodes" in EXP2.description
    # Another budget: the values follow, and "Experiment 1" (a note on the old values) goes.
    smaller = EXP1.replace(episodes=8_000)
    assert smaller.description == describe_setting(smaller) and "8,000 episodes (200,000 steps)" in smaller.description
    assert not smaller.description.startswith("Experiment 1")
    # Which runs, under which name: the setting is the same, so is its note.
    assert EXP1.replace(name="n5", seeds=(0, 1)).description == EXP1.description
    # Stored (experiment.json) and read back: still derived, so still follows a change.
    stored = ExperimentConfig.from_dict(json.loads(json.dumps(EXP1.to_dict())))
    assert "N=3, full observability" in stored.replace(n_agents=3).description
    # A description written by hand is the author's: kept.
    mine = SMOKE.replace(description="my own words")
    assert mine.replace(episodes=30).description == "my own words"


def test_the_command_line_describes_what_it_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    experiment = dry_run(capsys, tmp_path, "--config", "exp1", "--env", "simple_tag", "--episodes", "2000")
    assert experiment["description"] == (
        "exp1 with --env --episodes (evaluation scaled to the budget): simple_tag, 4 agents, 2,000 episodes (50,000 "
        "steps), 3 checkpoints x 15 episodes over the last 20%, 8 curve points x 5 episodes"
    )
    # A hand-written description (a JSON setting) is replaced too once an option changes the setting.
    setting = tmp_path / "mine.json"
    setting.write_text(json.dumps(SMOKE.replace(name="mine", description="my tiny spread").to_dict()))
    changed = dry_run(capsys, tmp_path, "--config", str(setting), "--n-agents", "4")
    assert changed["description"].startswith(f"{setting} with --n-agents: simple_spread, N=4, full observability")
    assert dry_run(capsys, tmp_path, "--config", str(setting), "--seeds", "1")["description"] == "my tiny spread"


# ---------------------------------------------------------------------------------------------------------------
# A run's own team size


def test_a_run_of_another_task_records_that_tasks_team(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    results = tmp_path / "results"
    argv = ["run", "--config", "smoke", "--env", "simple_tag", "--schemes", "full", "--seeds", "1", "--episodes", "20"]
    assert main([*argv, "--n-checkpoints", "1", "--results", str(results), "--quiet"]) == 0
    capsys.readouterr()
    stored = json.loads((results / "smoke" / "experiment.json").read_text())
    assert stored["n_agents"] == 4  # mpe2's simple_tag: 3 adversaries and 1 prey, not the smoke preset's 3
    assert "simple_tag, 4 agents, 20 episodes" in stored["description"] and "N=3" not in stored["description"]
    assert json.loads((results / "smoke" / "full" / "seed_000" / "config.json").read_text())["n_agents"] == 4
    # Its own arguments set the team.
    bigger = dry_run(capsys, tmp_path, "--config", "smoke", "--env", "simple_tag", "--env-kwargs", '{"num_good": 2}')
    assert bigger["n_agents"] == 5 and "simple_tag (num_good=2), 5 agents" in bigger["description"]
    assert SMOKE.replace(env="simple_speaker_listener").n_agents == 2  # the Python API, the same


# ---------------------------------------------------------------------------------------------------------------
# The evaluation schedule follows the budget


def test_a_smaller_budget_scales_the_evaluation_schedule() -> None:
    # By the square root of the budgets' ratio, rounded up: evaluation keeps its share of the run.
    assert scaled_schedule(EXP1, 8_000) == {
        "n_checkpoints": 6,
        "eval_episodes": 29,
        "curve_points": 15,
        "curve_eval_episodes": 6,
    }

    def share(counts: dict[str, int], episodes: int) -> float:
        evaluated = counts["n_checkpoints"] * counts["eval_episodes"] + counts["curve_points"] * counts["curve_eval_episodes"]
        return evaluated / episodes

    paper = {name: getattr(EXP1, name) for name in SCHEDULE}
    assert share(scaled_schedule(EXP1, 8_000), 8_000) == pytest.approx(share(paper, 100_000), rel=0.15)
    # Floors: one checkpoint of 10 episodes, 2 curve points of 5 (or the setting's own, if fewer).
    assert scaled_schedule(EXP1, 200) == {"n_checkpoints": 1, "eval_episodes": 10, "curve_points": 3, "curve_eval_episodes": 5}
    assert schedule(scaled_schedule(SMOKE, 30)) == schedule(SMOKE)  # the smoke test's own counts are below the floors
    # No more checkpoints than episodes in the window; a budget as large or larger keeps the setting's schedule.
    assert scaled_schedule(ExperimentConfig("x", episodes=100, n_checkpoints=20), 25)["n_checkpoints"] == 5
    for episodes in (100_000, 400_000):
        assert schedule(scaled_schedule(EXP1, episodes)) == schedule(EXP1)


def test_the_command_line_scales_only_what_it_is_not_given(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert schedule(dry_run(capsys, tmp_path, "--config", "exp1")) == (20, 100, 50, 20)  # the paper's, untouched
    assert schedule(dry_run(capsys, tmp_path, "--config", "exp1", "--seeds", "2")) == (20, 100, 50, 20)
    scaled = dry_run(capsys, tmp_path, "--config", "exp1", "--episodes", "8000", "--eval-episodes", "50")
    assert schedule(scaled) == (6, 50, 15, 6)
    given = ["--n-checkpoints", "20", "--eval-episodes", "50", "--curve-points", "15", "--curve-eval-episodes", "20"]
    assert schedule(dry_run(capsys, tmp_path, "--config", "exp1", "--episodes", "6000", *given)) == (20, 50, 15, 20)
    assert schedule(dry_run(capsys, tmp_path, "--config", "exp2", "--episodes", "300000")) == schedule(EXP2)


# ---------------------------------------------------------------------------------------------------------------
# The docs' command lines train


def docs_run_commands() -> list[tuple[str, list[str]]]:
    """Every ``sb3-maddpg run`` command line in the guide's code blocks (continuation lines joined)."""
    commands = []
    for path in sorted((REPO / "docs" / "guide").glob("*.rst")):
        text = re.sub(r"\\\n\s*", " ", path.read_text())
        for line in text.splitlines():
            line = line.split("#")[0].strip()
            if line.startswith("sb3-maddpg run "):
                commands.append((f"{path.name}: {line}", shlex.split(line)[2:]))
    return commands


@pytest.mark.parametrize(("where", "argv"), docs_run_commands(), ids=lambda value: value if isinstance(value, str) else "")
def test_the_docs_run_commands_pass_a_dry_run_without_the_train_nothing_warning(
    where: str, argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(REPO)  # JSON settings named relative to the repository
    made_before = [arg for arg in argv if arg.endswith((".json", ".yml")) and not Path(arg).exists()]
    if made_before:
        pytest.skip(f"{made_before[0]} is written by an earlier command (e.g. tune --preset-out)")
    assert main(["run", *argv, "--results", str(tmp_path / "r"), "--dry-run"]) == 0, where
    assert "train nothing" not in capsys.readouterr().err, where


def test_a_budget_within_learning_starts_is_warned_about(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--config", "exp1", "--episodes", "200", "--results", str(tmp_path), "--dry-run"]) == 0
    error = capsys.readouterr().err
    assert "5,000 env steps per run are not above learning_starts (25,600)" in error
    assert "raise --episodes above 1,024, or lower learning_starts" in error


# ---------------------------------------------------------------------------------------------------------------
# A user's error: one line, its cause then what to do, exit status 2


def user_errors(tmp_path: Path) -> list[tuple[list[str], str]]:
    (tmp_path / "broken.json").write_text("{")
    (tmp_path / "unknown.json").write_text(json.dumps({**SMOKE.to_dict(), "bogus": 1}))
    (tmp_path / "a_file").write_text("")
    run = ["run", "--results", str(tmp_path / "results")]
    return [
        ([*run, "--config", "exp3"], "sb3-maddpg run: Unknown experiment 'exp3': use one of ['exp1', "),
        ([*run, "--config", str(tmp_path / "none.json")], "No experiment file '"),
        ([*run, "--config", str(tmp_path / "broken.json")], "broken.json' is not JSON (Expecting property name"),
        ([*run, "--config", str(tmp_path / "unknown.json")], "has unknown key(s) ['bogus']: an experiment's keys are"),
        ([*run, "--config", "smoke", "--model-kwargs", "{batch_size"], "--model-kwargs: '{batch_size' is not a mapping"),
        ([*run, "--config", "smoke", "--env-kwargs", "[1]"], "--env-kwargs: '[1]' is not a mapping"),
        ([*run, "--config", "smoke", "--scheme-model-kwargs", "{"], "--scheme-model-kwargs: '{' is not a mapping"),
        ([*run, "--config", "smoke", "--env", "simple_nonsense"], "Unknown env 'simple_nonsense': use 'simple_spread', an"),
        ([*run, "--config", "smoke", "--env", "simple_tag", "--env-kwargs", '{"bogus": 1}'], "has no argument 'bogus'"),
        ([*run, "--config", "smoke", "--env", "simple_tag", "--n-agents", "3"], "--n-agents sets simple_spread's team"),
        ([*run, "--config", "smoke", "--num-agent-neighbors", "two"], "'two' is none of int, 'all', null"),
        ([*run, "--config", "smoke", "--seeds", "0"], "--seeds 0: give a number of seeds of at least 1, or a list"),
        ([*run, "--config", "smoke", "--episodes", "many"], "--episodes: 'many' is not an integer"),
        ([*run, "--config", "smoke", "--seeds", "0,x"], "--seeds '0,x': give integers, e.g. 0,5 or [0, 5]"),
        ([*run, "--config", "smoke", "--seeds", "[]"], "smoke: no runs: give at least one scheme (--schemes) and one seed"),
        ([*run, "--config", "smoke", "--algorithm", "foo"], "smoke: --algorithm 'foo' cannot be imported"),
        ([*run, "--config", "smoke", "--n-agents", "0"], "n_agents (agents in the team) must be an integer >= 1, got 0"),
        (["tune", "--config", "smoke", "--backend", "slurm"], "--backend: 'slurm' is not one of 'local', 'ray' (see"),
        ([*run, "--config", "smoke", "--config", "exp1", "--name", "x"], "--name renames one experiment, but 2 --config"),
        ([*run, "--config", "smoke", "--episodes", "3", "--n-checkpoints", "2"], "2 checkpoints do not fit in the last"),
        ([*run, "--config", "smoke", "--schemes", "fulll"], "smoke: --schemes 'fulll': Unknown critic_sharing 'fulll'"),
        (["run", "--config", "smoke", "--results", str(tmp_path / "a_file")], "is a file, not a directory"),
        (["report", str(tmp_path / "missing")], "sb3-maddpg report: no results directory"),
        (["report", str(tmp_path), "--metric", "speed"], "--metric 'speed' is no score: give one of adversary_goal"),
        (["tune", "--config", "exp3"], "sb3-maddpg tune: Unknown experiment 'exp3'"),
        (["tune", "--config", "smoke", "--env", "simple_nonsense"], "sb3-maddpg tune: Unknown env 'simple_nonsense'"),
        (["tune", "--config", "smoke", "--env-kwargs", "{"], "sb3-maddpg tune: --env-kwargs: '{' is not a mapping"),
        (["tune", "--config", "smoke", "--num-agent-neighbors", "x"], "'x' is none of int, 'all', null"),
        (["tune", "--config", "smoke", "--objective", "speed"], "objective 'speed' is not one of simple_spread's"),
        (["tune", "--config", "smoke", "--scheme", "fulll"], "Unknown critic_sharing 'fulll'"),
        (
            ["tune", "--config", "smoke", "--n-evaluations", "2"],
            "last_evaluations (the last evaluations whose mean is a trial's value) must be an integer in "
            "[1, n_evaluations = 2], got 3: lower last_evaluations or raise n_evaluations",
        ),
        (["bogus"], "sb3-maddpg: argument command: invalid choice: 'bogus'"),
    ]


def test_every_user_error_is_one_line_and_exit_status_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for argv, message in user_errors(tmp_path):
        assert main(argv) == 2, argv  # returned, not raised: no traceback
        error = capsys.readouterr().err
        assert message in error, (argv, error)
        assert error.count("\n") == 1 and "Traceback" not in error, (argv, error)
    assert not (tmp_path / "results").exists()  # refused before anything was written


def test_the_command_itself_prints_no_traceback(tmp_path: Path) -> None:
    argv = [sys.executable, "-m", "sb3_maddpg", "run", "--config", "exp3", "--results", str(tmp_path)]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.startswith("sb3-maddpg run: Unknown experiment 'exp3'") and done.stderr.count("\n") == 1


def test_the_small_scale_command_is_the_committed_comparisons_setting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # examples/reproduce_paper.py --scale small (and the same command in the docs) must give the committed small-scale
    # comparison's budget and schedule, which --episodes alone would now scale.
    spec = importlib.util.spec_from_file_location("reproduce_paper", REPO / "examples" / "reproduce_paper.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    committed = json.loads((REPO / "benchmarks" / "paper_small" / "config.json").read_text())
    experiment = dry_run(capsys, tmp_path, *shlex.split(module.SCALES["small"]))
    for name in ("name", "n_agents", "episodes", "seeds", *SCHEDULE):
        assert experiment[name] == committed[name], name


def test_every_field_of_the_config_model_is_an_option(capsys: pytest.CaptureFixture[str]) -> None:
    from sb3_maddpg.experiments.backends import Execution
    from sb3_maddpg.experiments.setting import AlgorithmConfig, TaskConfig
    from sb3_maddpg.tuning.search import TuneSettings

    def options(command: str) -> set[str]:
        assert main([command, "--help"]) == 0
        return set(re.findall(r"--[a-z][a-z-]*", capsys.readouterr().out))

    def flags(config: type, skip: tuple[str, ...] = ()) -> set[str]:
        return {"--" + f.name.replace("_", "-") for f in dataclasses.fields(config) if f.name not in skip}

    assert flags(ExperimentConfig) | flags(Execution, ("verbose",)) <= options("run")
    assert flags(TaskConfig) | flags(AlgorithmConfig) | flags(TuneSettings, ("experiment", "pruner")) <= options("tune")
    # Booleans both ways; each option explained by its field's docstring.
    assert {"--keep-checkpoints", "--no-keep-checkpoints", "--snapshots", "--no-snapshots"} <= options("run")
    assert main(["run", "--help"]) == 0
    assert "The final fraction of training over which checkpoints are saved" in " ".join(capsys.readouterr().out.split())


def test_all_neighbours_may_be_said_as_all_or_null(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for value in ("all", "null"):
        assert dry_run(capsys, tmp_path, "--config", "exp2", "--num-agent-neighbors", value)["num_agent_neighbors"] is None
    assert dry_run(capsys, tmp_path, "--config", "exp1", "--num-agent-neighbors", "2")["num_agent_neighbors"] == 2
