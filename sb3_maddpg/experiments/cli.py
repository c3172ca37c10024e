"""Command line: ``sb3-maddpg run ...`` (or ``python -m sb3_maddpg.experiments run ...``), ``... tune ...`` and
``... report ...``, derived from the config model (:mod:`~sb3_maddpg.experiments.cli_options`): ``run``'s options are
the fields of an experiment, each over every ``--config``'s
(:class:`~sb3_maddpg.experiments.setting.ExperimentConfig`), and of its execution
(:class:`~sb3_maddpg.experiments.backends.Execution`); ``tune``'s are the task's fields,
:class:`~sb3_maddpg.experiments.tune.TuneSettings`' and :func:`~sb3_maddpg.experiments.tune.run_study`'s. A user's error
(a bad name, value or file) ends the command with one line on stderr, its cause then what to do, and exit status 2."""

import argparse
import dataclasses
import importlib.util
import json
import os
import re
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import yaml
from jsonargparse import ArgumentParser

from sb3_maddpg.analysis.evaluation import side_return_key
from sb3_maddpg.common.install_hint import extra_install_command
from sb3_maddpg.envs.mpe_tasks import MPE_TASK_SIDES
from sb3_maddpg.experiments.backends import BACKENDS, Execution
from sb3_maddpg.experiments.cli_options import Option, add_options, flag, options_of
from sb3_maddpg.experiments.config import EXPERIMENTS, algorithm_argument, load_algorithm, load_experiment
from sb3_maddpg.experiments.defaults import ALGORITHMS, DEFAULT_ENV
from sb3_maddpg.experiments.results import link_complete_seeds
from sb3_maddpg.experiments.setting import (
    CONCERNS,
    NOTE_KEEPING_FIELDS,
    SETTING_KEYS,
    ExperimentConfig,
    TaskConfig,
    merge_model_kwargs,
    scaled_schedule,
)
from sb3_maddpg.experiments.stats import METRICS

if TYPE_CHECKING:
    from sb3_maddpg.experiments.report import UnscoredMetricError

DEFAULT_RESULTS = "runs/experiments"

LEFT_OUT_SHOWN = 10
"""``report --complete-seeds`` names this many of the finished runs it leaves out (and counts them all)."""


LISTS = {"schemes", "score_agents", "seeds"}
"""Fields of lists that also take one comma-separated (``--schemes full,selected``, ``--seeds 0,5``)."""


class UsageError(Exception):
    """A command line the parser refuses (its message in one line)."""


class _Parser(ArgumentParser):
    """jsonargparse's parser, whose errors are raised to :func:`main` (said there in one line) rather than exiting."""

    def error(self, message: str, ex: Exception | None = None) -> Any:  # type: ignore[override]
        """:param message: The parser's message, raised as a :class:`UsageError` of one line."""
        message = " ".join(str(message).split())
        message = re.sub(r'Parser key "(?:\w+\.)?(\w+)":', lambda key: flag(key.group(1)) + ":", message)
        message = re.sub(r"Expected a typing\.Literal\[(.*?)\]", r"Expected one of \1", message)
        union = re.match(
            r"(--[\w-]+): Does not validate against any of the Union subtypes Subtypes: \[(.*?)\].*Given "
            r"value: (.*)$",
            message,
        )
        if union:
            message = f"{union.group(1)}: {union.group(3)!r} is none of {union.group(2).replace('NoneType', 'null')}"
        raise UsageError(re.sub(r"<class '(\w+)'>", r"\1", message))


EXPERIMENT_OWN = tuple(f.name for f in dataclasses.fields(ExperimentConfig) if f.name not in SETTING_KEYS)
"""An experiment's fields beyond its setting's concerns: its name, schemes, seeds, description and per-scheme kwargs."""


def _setting_options(concern: type = ExperimentConfig) -> list[Option]:
    """
    :param concern: A concern of a setting (:data:`~sb3_maddpg.experiments.setting.CONCERNS`), or
        ``ExperimentConfig`` for every field of an experiment.
    :return: Its fields as options, lists also comma-separated.
    """
    options = []
    for option in options_of(concern):
        if option.name == "seeds":  # an integer before a string: "3" is three seeds
            option = option._replace(hint=option.hint | int, help=option.help + " An integer N: 0..N-1.")
        if option.name in LISTS:
            option = option._replace(hint=option.hint | str)
        if option.name == "num_agent_neighbors":
            option = option._replace(help=option.help + " Give null for all.")
        options.append(option)
    return options


def _execution_options() -> list[Option]:
    """:return: The execution's fields as options: a backend of :data:`BACKENDS`, workers by the backend if not given."""
    backends = "; ".join(f"{name}: {entry.help}" for name, entry in BACKENDS.items())
    changes: dict[str, dict[str, Any]] = {
        "backend": {"hint": Literal[tuple(BACKENDS)], "help": backends},
        "workers": {
            "hint": int | None,
            "default": None,
            "help": "Parallel processes (local; default 1), or the CPUs of a "
            "local Ray instance (ray, batched-ray; default 0: all).",
        },
    }
    return [option._replace(**changes.get(option.name, {})) for option in options_of(Execution, skip=("verbose",))]


def report_metric_choices() -> list[str]:
    """:return: What ``report --metric`` takes: every score's key, and each competitive MPE task's sides' returns."""
    sides = {side_return_key(side) for task_sides in MPE_TASK_SIDES.values() for side in task_sides}
    return sorted({*METRICS, *sides})


COMMANDS = {
    "run": "run a sweep (finished runs are skipped: the same command resumes)",
    "tune": "search the hyperparameters on Optuna (the same command resumes)",
    "report": "Table 2, the paper's findings, curves and boxplots from a results directory",
}
"""The commands, and what each does."""


def build_parser(commands: Sequence[str] = tuple(COMMANDS)) -> ArgumentParser:
    """
    :param commands: The commands to parse (by default all; :func:`main` builds only the one given, so that a run
        imports no tuning code).
    :return: The argument parser of the ``sb3-maddpg`` command.
    """
    parser = _Parser(
        prog="sb3-maddpg",
        description="Reproduce the paper's experiments: train every scheme and seed, evaluate checkpoints, report Table 2.",
    )
    subcommands = parser.add_subcommands(dest="command")
    parsers = {"run": _run_parser, "tune": _tune_parser, "report": _report_parser}
    for command in commands:
        subcommands.add_subcommand(command, parsers[command](), help=COMMANDS[command])
    return parser


def _run_parser() -> ArgumentParser:
    """:return: ``run``'s parser: the experiments, each field over theirs, and where they execute."""
    run = _Parser(
        description="Run every (scheme, seed) of the experiments. Presets: "
        + "; ".join(f"{name}: {config.description}" for name, config in EXPERIMENTS.items()),
    )
    run.add_argument(
        "--config",
        action="append",
        default=None,
        help=f"a preset ({', '.join(EXPERIMENTS)}), a preset file (.yml) or a stored experiment (.json); repeat for "
        "several (required: the paper's sweep is --config exp1 --config exp2, 310 runs)",
    )
    run.add_argument("--results", default=DEFAULT_RESULTS, help="the results directory")
    for concern in CONCERNS:  # each option over every --config's
        title = (concern.__doc__ or "").strip().split(":")[0].split("\n")[0].rstrip(".")
        add_options(run.add_argument_group(title), _setting_options(concern), True)
    own = [option for option in _setting_options() if option.name in EXPERIMENT_OWN]
    add_options(run.add_argument_group("The experiment's runs"), own, True)
    add_options(run.add_argument_group("execution"), _execution_options())
    run.add_argument("--dry-run", action="store_true", help="list the runs and exit")
    run.add_argument("--quiet", action="store_true", help="print only the sweep's progress, not each run's")
    return run


def _tune_parser() -> ArgumentParser:
    """:return: ``tune``'s parser: the setting, the study's settings and its workers."""
    from sb3_maddpg.experiments.tune import TuneSettings, run_study

    tune = _Parser(
        description="Train trials of one setting with sampled hyperparameters, prune the poor ones, print the best as a "
        "preset. Several processes (--workers, or the same command in another shell) share the study.",
    )
    tune.add_argument("--config", default="exp1", help="the setting: a preset, a preset file or a stored experiment")
    add_options(tune.add_argument_group("the task (over --config's)"), _setting_options(TaskConfig), True)
    tune.add_argument("--scheme", help="the critic_sharing scheme (default: the setting's first)")
    changes: dict[str, dict[str, Any]] = {
        "study_name": {
            "hint": str | None,
            "default": None,
            "help": "The study's name in the storage (default: <setting>[_<task>]_<objective>, then each fixed parameter).",
        },
        "storage": {"default": "sqlite:///tune.db"},
    }
    study = [
        option._replace(**changes.get(option.name, {})) for option in options_of(TuneSettings, skip=("experiment", "pruner"))
    ]
    add_options(tune.add_argument_group("the study"), study)
    add_options(tune.add_argument_group("the workers"), options_of(run_study))
    tune.add_argument("--preset-out", help="also write the best trial's preset to this YAML file (.yml)")
    return tune


def _report_parser() -> ArgumentParser:
    """:return: ``report``'s parser."""
    report = _Parser(description="Table 2 (Markdown, CSV), aggregates, the paper's findings, curves and boxplots.")
    report.add_argument("results", nargs="?", default=DEFAULT_RESULTS, help="the results directory")
    report.add_argument("--out", help="output directory (default: <results>/report)")
    report.add_argument(
        "--metric",
        action="append",
        help="score(s) to tabulate and plot, repeat for several, e.g. min_dist_sum or a competitive task's "
        "return_adversaries (default: the task's main metrics: simple_spread's success_rate and min_dist_sum)",
    )
    report.add_argument("--no-plots", action="store_true", help="tables only")
    report.add_argument(
        "--complete-seeds",
        action="store_true",
        help="report only the seeds that every scheme of a setting has finished, so that a sweep in progress compares "
        f"like with like (the finished runs left out are counted, the first {LEFT_OUT_SHOWN} named; exit status 1 "
        "when no seed is complete)",
    )
    return report


def _given(args: argparse.Namespace, names: Sequence[str]) -> dict[str, Any]:
    """:return: The fields among ``names`` that ``args`` holds (given), lists of names split at commas."""
    given = {name: getattr(args, name) for name in names if hasattr(args, name)}
    for name in LISTS & given.keys():
        if isinstance(given[name], str):
            given[name] = tuple(item.strip() for item in given[name].split(",") if item.strip())
    if isinstance(given.get("seeds"), tuple):
        try:
            given["seeds"] = tuple(int(seed) for seed in given["seeds"])
        except ValueError:
            raise ValueError(f"--seeds {args.seeds!r}: give integers, e.g. 0,5 or [0, 5], or a number of seeds.") from None
    if isinstance(given.get("seeds"), int):
        if given["seeds"] < 1:
            raise ValueError(f"--seeds {given['seeds']}: give a number of seeds of at least 1, or a list of seeds, e.g. [0].")
        given["seeds"] = tuple(range(given["seeds"]))
    return given


def override(experiment: ExperimentConfig, given: dict[str, Any], config: str) -> ExperimentConfig:
    """
    :param experiment: A loaded ``--config``.
    :param given: The fields given on the command line (:func:`_given`).
    :param config: What ``--config`` said, for the description.
    :return: The experiment with the given fields: ``model_kwargs`` merged over its own (``scheme_model_kwargs`` per
        scheme); with ``--episodes``, each evaluation count not given follows the budget
        (:func:`~sb3_maddpg.experiments.setting.scaled_schedule`); a setting changed is described by its new values
        after ``"<config> with <options>"``. A ``ValueError`` for the team of a task other than simple_spread.
    """
    changes = dict(given)
    task = changes.get("env", experiment.env)
    team = [flag(name) for name in ("n_agents", "num_agent_neighbors") if name in changes]
    if task != DEFAULT_ENV and team:
        raise ValueError(
            f"{team[0]} sets simple_spread's team, but the task is {task}, whose team is its own: change it through "
            "--env-kwargs (e.g. simple_tag's '{\"num_adversaries\": 4}'), or leave out " + " and ".join(team) + "."
        )
    if "model_kwargs" in changes:
        changes["model_kwargs"] = merge_model_kwargs(experiment.model_kwargs, changes["model_kwargs"])
    if "scheme_model_kwargs" in changes:
        changes["scheme_model_kwargs"] = {
            scheme: merge_model_kwargs(experiment.scheme_model_kwargs.get(scheme, {}), kwargs)
            for scheme, kwargs in {**experiment.scheme_model_kwargs, **changes["scheme_model_kwargs"]}.items()
        }
    scaled = False
    if "episodes" in changes:
        for name, value in scaled_schedule(experiment, changes["episodes"]).items():
            if name not in changes:
                changes[name] = value
                scaled = scaled or value != getattr(experiment, name)
    nulls: dict[str, Any] = {name: None for name, value in changes.items() if value is None}  # e.g. every neighbour
    changed = dataclasses.replace(experiment.replace(**changes), **nulls)
    flags = [flag(name) for name in given if name not in NOTE_KEEPING_FIELDS]
    if not flags or "description" in given:
        return changed
    return changed.described(f"{config} with {' '.join(flags)}" + (" (evaluation scaled to the budget)" if scaled else ""))


def experiments_from_args(args: argparse.Namespace) -> list[ExperimentConfig]:
    """
    :param args: Parsed ``run`` arguments.
    :return: Each ``--config`` with the fields given over it (:func:`override`); a ``ValueError`` for a user's error.
    """
    if hasattr(args, "name") and len(args.config) != 1:
        raise ValueError(f"--name renames one experiment, but {len(args.config)} --config are given: give one --config.")
    given = _given(args, [option.name for option in _setting_options()])
    return [override(load_experiment(name), given, name) for name in args.config]


def _check_experiments(experiments: Sequence[ExperimentConfig]) -> None:
    """
    Refuse, before anything runs, what would fail in every run: checkpoints that do not fit the budget, and schemes
    that the package's algorithms do not know.

    :param experiments: The sweep's experiments.
    """
    from sb3_maddpg.experiments.runner import run_critic_sharing
    from sb3_maddpg.sharing.registry import validate_critic_sharing

    for experiment in experiments:
        if not experiment.schemes or not experiment.seeds:
            raise ValueError(f"{experiment.name}: no runs: give at least one scheme (--schemes) and one seed (--seeds).")
        try:
            load_algorithm(experiment.algorithm)
        except (ImportError, AttributeError, ValueError) as error:
            raise ValueError(
                f"{experiment.name}: --algorithm {experiment.algorithm!r} cannot be imported ({error}): give maddpg, matd3 "
                "or an importable 'module:Class'."
            ) from None
        runs = experiment.runs()  # RunConfig checks each run's budget and schedule
        if experiment.algorithm in ALGORITHMS.values():
            for scheme, config in {config.scheme: config for config in runs}.items():
                try:
                    validate_critic_sharing(run_critic_sharing(config))
                except ValueError as error:
                    raise ValueError(f"{experiment.name}: --schemes {scheme!r}: {error}") from None


def _untrained_warning(experiment: ExperimentConfig, steps: int, option: str, unit: int = 1) -> str | None:
    """
    :param experiment: An experiment.
    :param steps: The env steps each of its runs (or trials) trains.
    :param option: The option that sets ``steps``, for the advice (e.g. ``"--episodes"``).
    :param unit: The env steps in one unit of ``option`` (e.g. the episode length).
    :return: A warning if a scheme's runs would not pass ``learning_starts`` (random actions, no update), else ``None``.
    """
    for scheme in experiment.schemes:
        try:
            starts = int(algorithm_argument(experiment.to_dict(), "learning_starts", scheme))
        except (ImportError, AttributeError, ValueError, TypeError):  # an algorithm without learning_starts
            return None
        if steps <= starts:
            return (
                f"{experiment.name}: {steps:,} env steps per run are not above learning_starts ({starts:,}), so the "
                f"runs act at random throughout and train nothing: raise {option} above {starts // unit:,}, or lower "
                "learning_starts, e.g. "
                f"--model-kwargs '{{\"learning_starts\": {max(1, steps // 4)}}}'."
            )
    return None


def no_config_message() -> str:
    """:return: What ``run`` says without ``--config``: the presets, their sizes, and ``--dry-run``."""
    presets = "\n".join(
        f"  {name}: {len(config.schemes) * len(config.seeds)} runs, {config.description}"
        for name, config in EXPERIMENTS.items()
    )
    return (
        "sb3-maddpg run: no experiment given: name one with --config (a preset below, a preset file or a stored "
        "experiment; repeat it for several). The paper's full sweep is --config exp1 --config exp2 (310 runs, days of "
        f"CPU); add --dry-run to list the runs first.\n{presets}"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """
    :param argv: The arguments (default: ``sys.argv[1:]``).
    :return: The exit status: 0 when every run finished (or the report was written), 1 otherwise, 2 for a usage
        error (said in one line on stderr), 130 after Ctrl-C (the sweep resumes with the same command).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        parsed = build_parser([argv[0]] if argv and argv[0] in COMMANDS else tuple(COMMANDS)).parse_args(argv)
    except UsageError as error:
        command = f"sb3-maddpg {argv[0]}" if argv and argv[0] in ("run", "tune", "report") else "sb3-maddpg"
        print(f"{command}: {error} (see {command} --help)", file=sys.stderr)
        return 2
    except SystemExit as exit:  # --help
        return exit.code if isinstance(exit.code, int) else 2
    args = getattr(parsed, parsed.command)
    if parsed.command == "run":
        if not args.config:
            print(no_config_message(), file=sys.stderr)
            return 2
        try:
            return run_command(args)
        except KeyboardInterrupt:  # Ctrl-C before the sweep began (run_command handles it during the sweep)
            print("sb3-maddpg run: interrupted before the sweep started; nothing was run.", file=sys.stderr)
            return 130
    if parsed.command == "tune":
        try:
            return tune_command(args)
        except KeyboardInterrupt:
            print("sb3-maddpg tune: interrupted; the same command resumes the study.", file=sys.stderr)
            return 130
    return report_command(args)


def _tune_settings(args: argparse.Namespace) -> Any:
    """
    :param args: Parsed ``tune`` arguments.
    :return: The study's :class:`~sb3_maddpg.experiments.tune.TuneSettings`: ``--config`` with the task's fields and
        the scheme over it; a ``ValueError`` for a user's error.
    """
    from sb3_maddpg.experiments.tune import TuneSettings, default_study_name, task_objectives

    task = [option.name for option in _setting_options(TaskConfig)]
    given = _given(args, task) | ({"schemes": (args.scheme,)} if args.scheme else {})
    experiment = override(load_experiment(args.config), given, args.config)
    _check_experiments([experiment])
    setting = experiment.name
    if "env" in given and given["env"] != load_experiment(args.config).env:  # another task than the config's: say it
        setting += "_" + re.sub(r"[^A-Za-z0-9_.-]+", "_", given["env"])
    study = {option.name: getattr(args, option.name) for option in options_of(TuneSettings, skip=("experiment", "pruner"))}
    study["objective"] = args.objective or next(iter(task_objectives(experiment)))
    study["study_name"] = args.study_name or default_study_name(setting, study["objective"], args.fixed_params)
    return TuneSettings(experiment=experiment, **study)


def tune_command(args: argparse.Namespace) -> int:
    """
    :param args: Parsed ``tune`` arguments.
    :return: The exit status.
    """
    from sb3_maddpg.experiments.tune import best_preset, describe_best, finished_trials, run_study

    try:
        if args.preset_out and not args.preset_out.endswith((".yml", ".yaml")):
            raise ValueError(f"--preset-out {args.preset_out}: a preset is a YAML file: give a name ending in .yml.")
        settings = _tune_settings(args)
    except ValueError as error:
        print(f"sb3-maddpg tune: {error}", file=sys.stderr)
        return 2
    experiment = settings.experiment
    warning = _untrained_warning(experiment, settings.budget, "--budget")
    if warning:
        print(f"sb3-maddpg tune: warning: {warning}", file=sys.stderr)
    if settings.fixed_params:
        print(
            "fixed in every trial: " + ", ".join(f"{name}={value}" for name, value in settings.fixed_params.items()),
            flush=True,
        )
    print(
        f"study {settings.study_name!r} in {settings.storage}: {settings.n_trials} trials of {settings.budget:,} steps "
        f"on {experiment.name} ({experiment.env}, N={experiment.n_agents}, scheme {experiment.schemes[0]}), objective "
        f"{settings.objective} ({settings.direction}), {args.workers} worker(s)",
        flush=True,
    )
    try:
        study = run_study(settings, workers=args.workers, backend=args.backend, threads=args.threads, address=args.address)
    except (ModuleNotFoundError, ValueError) as error:
        print(f"sb3-maddpg tune: {error}", file=sys.stderr)
        return 2
    if not any(trial.value is not None and trial.state.name == "COMPLETE" for trial in study.trials):
        print(f"sb3-maddpg tune: no trial completed ({finished_trials(study)} pruned).", file=sys.stderr)
        return 1
    for line in describe_best(study, settings):
        print(line)
    if args.preset_out:
        Path(args.preset_out).write_text(yaml.safe_dump(best_preset(study, settings), sort_keys=False))
        print(f"preset written to {args.preset_out}: sb3-maddpg run --config {args.preset_out}")
    return 0


def _check_execution(args: argparse.Namespace) -> None:
    """:param args: Parsed ``run`` arguments, whose execution options are refused (a ``ValueError``) if they clash."""
    if args.ray_address and args.backend not in ("ray", "batched-ray"):
        raise ValueError(
            f"--ray-address is Ray's, but --backend {args.backend} trains on this machine: use --backend ray (a Ray task "
            "per run) or batched-ray (a Ray task per run group) to train there."
        )
    if Path(args.results).exists() and not Path(args.results).is_dir():
        raise ValueError(f"--results {args.results} is a file, not a directory: give a directory (new or a sweep's).")


def run_command(args: argparse.Namespace) -> int:
    """
    :param args: Parsed ``run`` arguments.
    :return: The exit status.
    """
    from sb3_maddpg.experiments.group_plan import BatchedRunRefused
    from sb3_maddpg.experiments.results import ResultsDirectoryLocked
    from sb3_maddpg.experiments.sweep import SweepInterrupted, plan_sweep, run_sweep  # torch: imported for runs only

    try:
        _check_execution(args)
        experiments = experiments_from_args(args)
        _check_experiments(experiments)
        todo, finished = plan_sweep(experiments, args.results)  # a finished run of another config is refused here
    except ValueError as error:
        print(f"sb3-maddpg run: {error}", file=sys.stderr)
        return 2
    for experiment in experiments:
        warning = _untrained_warning(
            experiment, experiment.episodes * experiment.episode_length, "--episodes", experiment.episode_length
        )
        if warning:
            print(f"sb3-maddpg run: warning: {warning}", file=sys.stderr)
    if args.dry_run:
        for experiment in experiments:
            print(f"{experiment.name}: {json.dumps(experiment.to_dict())}")
        for config in todo:
            print(f"  {config.run_id}: {config.total_timesteps:,} steps, checkpoints at {config.checkpoint_steps()}")
        print(f"{len(todo)} run(s) to do, {finished} finished")
        return 0
    if not args.quiet:
        for experiment in experiments:
            print(f"{experiment.name}: {experiment.description}")
    execution = {option.name: getattr(args, option.name) for option in _execution_options()}
    if execution["workers"] is None:
        execution["workers"] = 1 if args.backend == "local" else 0
    try:
        result = run_sweep(experiments, args.results, verbose=1 if args.quiet else 2, **execution)
    except BatchedRunRefused as error:  # said before anything trained
        print(f"sb3-maddpg run: {error}", file=sys.stderr)
        return 2
    except ResultsDirectoryLocked as error:
        print(f"sb3-maddpg run: {error}", file=sys.stderr)
        return 1
    except SweepInterrupted:  # Ctrl-C: the sweep has said how far it got and that the same command resumes
        return 130
    if not args.quiet:
        print(f"results in {args.results}; report with: sb3-maddpg report {args.results}")
    return 0 if result.ok else 1


def no_matplotlib_message() -> str:
    """:return: What ``report`` says without matplotlib: the install command for this install, or ``--no-plots``."""
    return (
        "sb3-maddpg report: the figures need matplotlib, which is not installed. Install the experiments extra, "
        f"{extra_install_command('experiments')}, or add --no-plots for the tables only."
    )


def report_command(args: argparse.Namespace) -> int:
    """
    :param args: Parsed ``report`` arguments.
    :return: The exit status.
    """
    if not Path(args.results).is_dir():
        print(
            f"sb3-maddpg report: no results directory {args.results}: give the directory a sweep wrote (sb3-maddpg run "
            f"--results DIR; default {DEFAULT_RESULTS}).",
            file=sys.stderr,
        )
        return 2
    unknown = [metric for metric in args.metric or () if metric not in report_metric_choices()]
    if unknown:
        print(
            f"sb3-maddpg report: --metric {unknown[0]!r} is no score: give one of {', '.join(report_metric_choices())}.",
            file=sys.stderr,
        )
        return 2
    plots = not args.no_plots
    if plots and importlib.util.find_spec("matplotlib") is None:  # said before any table is written
        print(no_matplotlib_message(), file=sys.stderr)
        return 1
    out = args.out or f"{args.results.rstrip('/')}/report"
    unwritable = unwritable_out_message(out)
    if unwritable is not None:
        print(unwritable, file=sys.stderr)
        return 2
    if not args.complete_seeds:
        return _write_report(args.results, out, args.metric, plots)
    with tempfile.TemporaryDirectory(prefix="sb3_maddpg_report_") as view:
        complete = str(Path(view) / "complete_seeds")
        left_out = link_complete_seeds(args.results, complete)
        if not Path(complete).is_dir():
            print(
                f"sb3-maddpg report: no seed in {args.results} is finished by every scheme of its setting "
                + (
                    f"({len(left_out)} finished run(s)): report them without --complete-seeds, or once every scheme "
                    "of a setting has finished a seed."
                    if left_out
                    else "(no finished runs): report it once a sweep has finished runs there (sb3-maddpg run --results DIR)."
                ),
                file=sys.stderr,
            )
            return 1
        if left_out:
            shown = ", ".join(left_out[:LEFT_OUT_SHOWN]) + (", ..." if len(left_out) > LEFT_OUT_SHOWN else "")
            print(
                f"sb3-maddpg report: --complete-seeds leaves out {len(left_out)} finished run(s), their seed not "
                f"finished by every scheme of their setting: {shown}",
                file=sys.stderr,
            )
        return _write_report(complete, out, args.metric, plots, shown_as=args.results)


def unwritable_out_message(out: str) -> str | None:
    """
    :param out: The report's directory (``--out``, or ``<results>/report``).
    :return: Why ``report`` cannot write there, in one line with what to do (the directory, or the first of its
        parents that exists, is a file or not writable); ``None`` when it can.
    """
    existing = Path(out)
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if existing.exists() and not existing.is_dir():
        where = "is a file" if existing == Path(out) else f"is inside {existing}, a file"
        return f"sb3-maddpg report: the report's directory {out} {where}: give --out a directory (new or existing)."
    if existing.is_dir() and not os.access(existing, os.W_OK | os.X_OK):
        return (
            f"sb3-maddpg report: cannot write the report's directory {out} ({existing} is not writable): give --out a "
            "directory you can write to."
        )
    return None


def unscored_metric_message(error: "UnscoredMetricError", directory: str) -> str:
    """
    :param error: :func:`~sb3_maddpg.experiments.report.make_report`'s refusal of a metric no run scores.
    :param directory: The results directory, as the user named it.
    :return: ``report``'s line: the metric(s) no run scores, those that ``--metric`` could take instead, what to do.
    """
    asked = ", ".join(error.unscored)
    choices = set(report_metric_choices())
    instead = [metric for metric in error.scored if metric in choices]
    radii = any(
        metric not in ("success_rate", "coverage") and metric.startswith(("success_rate_", "coverage_"))
        for metric in error.unscored
    )
    old_runs = " (runs written before 0.2 have no success or coverage at other radii)" if radii else ""
    fix = (
        f"the runs there score {', '.join(instead)}: give --metric one of those, or leave --metric out for each task's "
        "main metrics."
        if instead
        else "leave --metric out for each task's main metrics."
    )
    return f"sb3-maddpg report: no run in {directory} scores --metric {asked}{old_runs}; {fix}"


def _write_report(results: str, out: str, metrics: list[str] | None, plots: bool, shown_as: str | None = None) -> int:
    """
    :param results: The results directory to report.
    :param out: Where to write the report.
    :param metrics: ``--metric``'s scores (``None``: the tasks' main ones).
    :param plots: Draw the figures too.
    :param shown_as: The directory an error names instead of ``results`` (``--complete-seeds``' temporary view of the
        user's directory); ``None``: ``results``.
    :return: The exit status.
    """
    from sb3_maddpg.experiments.report import UnscoredMetricError, make_report

    try:
        for path in make_report(results, out, metrics=metrics, plots=plots):
            print(path)
    except UnscoredMetricError as error:  # a user's error: said before anything is written
        print(unscored_metric_message(error, shown_as or results), file=sys.stderr)
        return 2
    except ModuleNotFoundError as error:  # a part of matplotlib missing: the same advice
        if error.name is None or error.name.split(".")[0] != "matplotlib":
            raise
        print(no_matplotlib_message(), file=sys.stderr)
        return 1
    except (FileNotFoundError, ValueError) as error:  # no finished runs, or runs that cannot be read
        print(f"sb3-maddpg report: {str(error).replace(results, shown_as or results)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
