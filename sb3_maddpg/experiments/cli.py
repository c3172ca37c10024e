"""Command line: ``sb3-maddpg run ...`` (or ``python -m sb3_maddpg.experiments run ...``), ``... tune ...`` and
``... report ...``. A user's error (a bad name, JSON or number, a missing file) ends the command with one line on
stderr, its cause then what to do, and exit status 2."""

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
from typing import TYPE_CHECKING, Any, NoReturn

from sb3_maddpg.analysis.evaluation import side_return_key
from sb3_maddpg.common.install_hint import extra_install_command
from sb3_maddpg.envs.mpe_tasks import MPE_TASK_SIDES
from sb3_maddpg.experiments.backends import BACKENDS
from sb3_maddpg.experiments.config import EXPERIMENTS, algorithm_argument, load_experiment
from sb3_maddpg.experiments.defaults import DEFAULT_ENV, DEFAULT_N_ENVS, VEC_ENVS
from sb3_maddpg.experiments.results import link_complete_seeds
from sb3_maddpg.experiments.setting import ExperimentConfig, merge_model_kwargs, scaled_schedule
from sb3_maddpg.experiments.stats import METRICS

if TYPE_CHECKING:
    from sb3_maddpg.experiments.report import UnscoredMetricError

DEFAULT_RESULTS = "runs/experiments"

LEFT_OUT_SHOWN = 10
"""``report --complete-seeds`` names this many of the finished runs it leaves out (and counts them all)."""

ALGORITHMS = {"maddpg": "sb3_maddpg:MADDPG", "matd3": "sb3_maddpg:MATD3"}
"""``run --algo``'s names and the experiments' ``algorithm`` each sets."""

SETTING_FLAGS = {
    "env": "--env",
    "env_kwargs": "--env-kwargs",
    "n_agents": "--n-agents",
    "neighbors": "--neighbors",
    "episodes": "--episodes",
    "n_checkpoints": "--n-checkpoints",
    "eval_episodes": "--eval-episodes",
    "curve_points": "--curve-points",
    "curve_eval_episodes": "--curve-eval-episodes",
    "algo": "--algo",
    "model_kwargs": "--model-kwargs",
    "scheme_model_kwargs": "--scheme-model-kwargs",
    "score_agents": "--score-agents",
    "normalize_observations": "--normalize-observations",
}
"""``run``'s options that change a setting (not only which of its runs, or where): given any, the experiment's
description says its new values after ``"<config> with <options>"``."""

SCHEDULE_FLAGS = {
    "n_checkpoints": "--n-checkpoints",
    "eval_episodes": "--eval-episodes",
    "curve_points": "--curve-points",
    "curve_eval_episodes": "--curve-eval-episodes",
}
"""The evaluation schedule's options: those not given follow ``--episodes`` (:func:`~.config.scaled_schedule`)."""


class _OneLineErrors(argparse.ArgumentParser):
    """argparse's parser, whose errors are one line: the cause, then where the options are listed."""

    def error(self, message: str) -> NoReturn:
        """:param message: argparse's message; printed as ``<prog>: <message> (see <prog> --help)``, exit status 2."""
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def _int_list(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(item) for item in text.split(",") if item.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of integers, e.g. 0,5,7") from None


def _str_list(text: str) -> tuple[str, ...]:
    return tuple(item.strip() for item in text.split(",") if item.strip())


def _json_object(example: str) -> Any:
    def parse(text: str) -> dict[str, Any]:
        try:
            value = json.loads(text)
        except json.JSONDecodeError as error:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not JSON ({error}): give an object, e.g. '{example}' (names and strings in double quotes)"
            ) from None
        if not isinstance(value, dict):
            raise argparse.ArgumentTypeError(f"{text!r} is not a JSON object: give one, e.g. '{example}'")
        return value

    return parse


def _count(least: int) -> Any:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = least - 1
        if value < least:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer of at least {least}")
        return value

    return parse


def _neighbors(text: str) -> int | str:
    if text == "all":
        return text
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r} is neither a number of agents (0 or more) nor 'all'")
    return value


def report_metric_choices() -> list[str]:
    """:return: What ``report --metric`` takes: every score's key, and each competitive MPE task's sides' returns."""
    sides = {side_return_key(side) for task_sides in MPE_TASK_SIDES.values() for side in task_sides}
    return sorted({*METRICS, *sides})


def _add_task_arguments(group: Any, default: str) -> None:
    """
    ``--env``, ``--env-kwargs`` and ``--score-agents``, as ``run`` and ``tune`` take them.

    :param group: The parser or argument group to add them to.
    :param default: What ``--env`` defaults to, for its help.
    """
    group.add_argument(
        "--env",
        help="the task: simple_spread, another MPE task (e.g. simple_tag; its own team size), a PettingZoo factory "
        f"'module:function', or a gymnasium id ({default})",
    )
    group.add_argument(
        "--env-kwargs", type=_json_object('{"num_adversaries": 4}'), help="JSON of the task constructor's keyword arguments"
    )
    group.add_argument(
        "--score-agents", type=_str_list, help="comma-separated agent ids whose summed return is scored (group_return)"
    )


def _add_team_arguments(group: Any) -> None:
    """
    ``--n-agents`` and ``--neighbors``, as ``run`` and ``tune`` take them (:func:`_with_team` reads them).

    :param group: The parser or argument group to add them to.
    """
    group.add_argument("--n-agents", type=_count(1), help="simple_spread's agents (and landmarks)")
    group.add_argument("--neighbors", type=_neighbors, help="nearest other agents observed: an integer, or 'all'")


def _with_team(experiment: ExperimentConfig, changes: dict[str, Any], args: argparse.Namespace) -> ExperimentConfig:
    """
    :param experiment: A loaded ``--config``.
    :param changes: The other options' changes to it (``n_agents`` among them), for ``ExperimentConfig.replace``.
    :param args: Parsed ``run`` or ``tune`` arguments (:func:`_add_team_arguments`).
    :return: The experiment changed, ``--neighbors`` included; a ``ValueError`` first when ``--n-agents`` or
        ``--neighbors`` is given for another task than simple_spread (whose team is its own).
    """
    task = args.env or experiment.env
    given = [SETTING_FLAGS[dest] for dest in ("n_agents", "neighbors") if getattr(args, dest) is not None]
    if task != DEFAULT_ENV and given:
        raise ValueError(
            f"{given[0]} sets simple_spread's team, but the task is {task}, whose team is its own: change it through "
            "--env-kwargs (e.g. simple_tag's '{\"num_adversaries\": 4}'), or leave out " + " and ".join(given) + "."
        )
    experiment = experiment.replace(**changes)
    if args.neighbors is not None:
        experiment = dataclasses.replace(experiment, num_agent_neighbors=None if args.neighbors == "all" else args.neighbors)
    return experiment


def build_parser() -> argparse.ArgumentParser:
    """:return: The argument parser of the ``sb3-maddpg`` command."""
    parser = _OneLineErrors(
        prog="sb3-maddpg",
        description="Reproduce the paper's experiments: train every scheme and seed, evaluate checkpoints, report Table 2.",
    )
    commands = parser.add_subparsers(dest="command", required=True)
    _add_run_parser(commands)
    _add_tune_parser(commands)
    _add_report_parser(commands)
    return parser


def _add_run_parser(commands: Any) -> None:
    """:param commands: The ``sb3-maddpg`` subparsers, given ``run``."""
    run = commands.add_parser(
        "run",
        help="run a sweep (finished runs are skipped, so the same command resumes an interrupted sweep)",
        description="Run every (scheme, seed) of the experiments. Presets: "
        + "; ".join(f"{name}: {config.description}" for name, config in EXPERIMENTS.items()),
    )
    run.add_argument(
        "--config",
        action="append",
        default=None,
        help=f"a preset ({', '.join(EXPERIMENTS)}) or an experiment JSON file; repeat for several "
        "(required: the paper's sweep is --config exp1 --config exp2, 310 runs)",
    )
    run.add_argument("--results", default=DEFAULT_RESULTS, help=f"results directory (default: {DEFAULT_RESULTS})")
    _add_run_overrides(run.add_argument_group("overrides (applied to every --config)"))
    _add_run_execution(run.add_argument_group("execution"))


def _add_run_overrides(group: Any) -> None:
    """:param group: ``run``'s argument group of the overrides."""
    group.add_argument("--name", help="store the experiment under this name (one --config only)")
    group.add_argument("--schemes", type=_str_list, help="comma-separated schemes, e.g. full,selected")
    group.add_argument("--seeds", type=_count(1), help="number of seeds (0..N-1)")
    group.add_argument("--seed-list", type=_int_list, help="comma-separated seeds (instead of --seeds)")
    _add_team_arguments(group)
    group.add_argument(
        "--episodes",
        type=_count(1),
        help="training budget in episodes; a smaller budget than the config's shrinks the evaluation options below "
        "that are not given (each by the square root of the budgets' ratio; see the reproduce guide)",
    )
    group.add_argument("--n-checkpoints", type=_count(1), help="checkpoints over the last 20%% of training")
    group.add_argument("--eval-episodes", type=_count(1), help="episodes per checkpoint evaluation")
    group.add_argument("--curve-points", type=_count(0), help="learning-curve evaluations per run")
    group.add_argument("--curve-eval-episodes", type=_count(1), help="episodes per learning-curve evaluation")
    group.add_argument(
        "--algo",
        choices=sorted(ALGORITHMS),
        help="the algorithm every run trains (default: the config's, MADDPG for the presets); store a MATD3 sweep under "
        "its own --name or --results, so that report tells it apart",
    )
    group.add_argument(
        "--model-kwargs",
        type=_json_object('{"batch_size": 256}'),
        help="JSON merged into the MADDPG kwargs, e.g. '{\"batch_size\": 256}'",
    )
    group.add_argument(
        "--scheme-model-kwargs",
        type=_json_object('{"selected": {"selector": 1}}'),
        help='JSON of MADDPG kwargs for one scheme only, merged per scheme, e.g. \'{"selected": {"selector": 1}}\'',
    )
    _add_task_arguments(group, "simple_spread by default")
    group.add_argument(
        "--vec-env",
        choices=VEC_ENVS,
        help="batched: SimpleSpreadVecEnv (the same MDP as mpe2, arrays; default); mpe2: DummyVecEnv over mpe2 itself",
    )
    group.add_argument("--n-envs", type=_count(1), help=f"worlds stepped together in training (default {DEFAULT_N_ENVS})")
    group.add_argument("--keep-checkpoints", action=argparse.BooleanOptionalAction, default=None, help="keep model files")
    group.add_argument(
        "--normalize-observations",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="normalise the observations by their running mean and variance (SB3's VecNormalize; rewards raw)",
    )


def _add_run_execution(execution: Any) -> None:
    """:param execution: ``run``'s argument group of where and how the runs execute."""
    execution.add_argument(
        "--backend",
        choices=tuple(BACKENDS),
        default="local",
        help="; ".join(f"{name}: {entry.help}" for name, entry in BACKENDS.items()) + " (default: %(default)s)",
    )
    execution.add_argument(
        "--device",
        default="auto",
        help="where the runs (or, batched, the run groups) train: cpu or cuda (default auto: cuda if there)",
    )
    execution.add_argument(
        "--no-snapshots",
        action="store_true",
        help="local and ray: save no snapshot of a run's training state at each tenth of its budget (a killed run then "
        "starts again from scratch; a snapshot takes about two replay buffers of disk per run in progress)",
    )
    execution.add_argument(
        "--compile",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="batched: compile each run group's rounds (torch.compile, one graph per part; CUDA graphs on a GPU): faster "
        "rounds after tens of seconds of compiling, said in the progress lines (default: where measured to pay, CPU "
        "groups of runs of 1M env steps or more)",
    )
    execution.add_argument(
        "--runs-per-process",
        type=int,
        default=None,
        help="batched: the most runs in one group (default: all seeds of a setting and scheme, or as many as the "
        "device's memory holds; with --ray: all seeds)",
    )
    execution.add_argument(
        "--ray",
        action="store_true",
        help="batched: each run group a Ray task (one GPU each with --device cuda, else --threads CPUs), on a local "
        "Ray instance or the cluster at --ray-address",
    )
    execution.add_argument(
        "--workers",
        type=int,
        default=None,
        help="parallel runs (local, default 1); CPUs of a local Ray instance (ray, batched --ray; default 0: all of "
        "this machine's)",
    )
    execution.add_argument("--threads", type=int, default=1, help="torch threads per run (default: 1)")
    execution.add_argument(
        "--ray-address",
        help="Ray cluster address for ray or batched --ray (e.g. auto, ray://head:10001); default: start a local one",
    )
    execution.add_argument("--dry-run", action="store_true", help="list the runs and exit")
    execution.add_argument("--quiet", action="store_true", help="print only the sweep's progress, not each run's")


def _add_tune_parser(commands: Any) -> None:
    """:param commands: The ``sb3-maddpg`` subparsers, given ``tune``."""
    tune = commands.add_parser(
        "tune",
        help="search MADDPG's hyperparameters on Optuna (a study in SQLite: the same command resumes it)",
        description="Train trials of one setting with sampled hyperparameters, prune the poor ones, print the best as a "
        "preset. Several processes (--workers, or the same command in another shell) share the study.",
    )
    setting = tune.add_argument_group("the setting")
    setting.add_argument(
        "--config", default="exp1", help="the setting: a preset or an experiment JSON file (default: %(default)s)"
    )
    _add_task_arguments(setting, "default: the setting's")
    _add_team_arguments(setting)
    setting.add_argument("--scheme", help="the critic_sharing scheme (default: the setting's first)")
    _add_tune_study(tune.add_argument_group("the study"))


def _add_tune_study(study: Any) -> None:
    """:param study: ``tune``'s argument group of the study, its trials and its workers."""
    study.add_argument("--study-name", help="the study's name (default: <setting>[_<task>]_<objective>, then each --fix)")
    study.add_argument("--storage", default="sqlite:///tune.db", help="Optuna storage URL (default: %(default)s)")
    study.add_argument(
        "--trials", type=_count(1), default=50, help="finished trials at which the study stops (default: %(default)s)"
    )
    study.add_argument("--steps", type=_count(1), default=1_000_000, help="env steps per trial (default: %(default)s)")
    study.add_argument(
        "--evaluations",
        type=_count(1),
        default=10,
        help="evaluations per trial, each reported to the pruner (default: %(default)s)",
    )
    study.add_argument("--eval-episodes", type=_count(1), default=100, help="episodes per evaluation (default: %(default)s)")
    study.add_argument(
        "--last-evaluations",
        type=_count(1),
        default=3,
        help="a trial scores its mean over its last this many evaluations, at most --evaluations (default: %(default)s)",
    )
    study.add_argument(
        "--warmup-evaluations",
        type=_count(0),
        default=1,
        help="first evaluations at which no trial is pruned (default: %(default)s)",
    )
    study.add_argument(
        "--objective",
        help="what a trial optimises (default: the task's first): on simple_spread min_dist_sum (lower is better), "
        "normalised or return_mean; on another MPE task one of its metrics (sb3_maddpg.envs.MPE_TASK_METRICS, e.g. "
        "simple_tag's collisions, the catches, higher) or return_mean; on any other task return_mean; group_return "
        "with --score-agents",
    )
    study.add_argument(
        "--seed", type=int, default=0, help="seed of the sampler and of every trial's run (default: %(default)s)"
    )
    study.add_argument(
        "--workers", type=_count(1), default=1, help="parallel worker processes sharing the study (default: %(default)s)"
    )
    study.add_argument(
        "--backend", choices=("local", "ray"), default="local", help="local processes or Ray tasks (default: %(default)s)"
    )
    study.add_argument("--address", default=None, help="Ray cluster address (with --backend ray; default: a local Ray)")
    study.add_argument("--threads", type=int, default=1, help="torch threads per worker (default: %(default)s)")
    study.add_argument(
        "--heartbeat", type=_count(1), default=60, help="seconds between a trial's heartbeats (default: %(default)s)"
    )
    study.add_argument("--preset-out", help="also write the best trial's preset (experiment JSON) to this file")
    study.add_argument(
        "--fix",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="hold a sampled parameter at one value in every trial (repeat for several), e.g. --fix "
        "transitions_per_update=25 --fix width=64; the study's default name then says so",
    )


def _add_report_parser(commands: Any) -> None:
    """:param commands: The ``sb3-maddpg`` subparsers, given ``report``."""
    report = commands.add_parser(
        "report",
        help="Table 2 (Markdown, CSV), aggregates, the paper's findings asked of the runs, learning curves and "
        "boxplots from a results directory",
    )
    report.add_argument("results", nargs="?", default=DEFAULT_RESULTS, help=f"results directory (default: {DEFAULT_RESULTS})")
    report.add_argument("--out", help="output directory (default: <results>/report)")
    report.add_argument(
        "--metric",
        action="append",
        choices=report_metric_choices(),
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


def experiments_from_args(args: argparse.Namespace) -> list[ExperimentConfig]:
    """
    :param args: Parsed ``run`` arguments.
    :return: The experiments with the overrides applied; a ``ValueError`` that names the option for a user's error.
        With ``--episodes``, each evaluation count not given follows the budget
        (:func:`~sb3_maddpg.experiments.setting.scaled_schedule`); an experiment that options of ``SETTING_FLAGS``
        changed is described by its new values, after ``"<config> with <options>"``.
    """
    if args.name and len(args.config) != 1:
        raise ValueError(f"--name renames one experiment, but {len(args.config)} --config are given: give one --config.")
    return [_override_experiment(load_experiment(name), name, args) for name in args.config]


def _override_experiment(experiment: ExperimentConfig, config: str, args: argparse.Namespace) -> ExperimentConfig:
    """
    :param experiment: A loaded ``--config``.
    :param config: What ``--config`` said (a preset's name or a file), for the description.
    :param args: Parsed ``run`` arguments.
    :return: The experiment with ``args``' overrides (see :func:`experiments_from_args`).
    """
    changed = _with_team(experiment, _run_overrides(experiment, args), args)
    flags = [flag for dest, flag in SETTING_FLAGS.items() if getattr(args, dest) is not None]
    if not flags:
        return changed
    scaled = any(getattr(changed, dest) != getattr(experiment, dest) for dest in SCHEDULE_FLAGS if getattr(args, dest) is None)
    return changed.described(f"{config} with {' '.join(flags)}" + (" (evaluation scaled to the budget)" if scaled else ""))


def _run_overrides(experiment: ExperimentConfig, args: argparse.Namespace) -> dict[str, Any]:
    """
    :param experiment: A loaded ``--config``.
    :param args: Parsed ``run`` arguments.
    :return: :meth:`~sb3_maddpg.experiments.setting.ExperimentConfig.replace`'s changes (``None``: not given), the
        evaluation schedule scaled to ``--episodes`` where it is not given.
    """
    seeds = args.seed_list or (tuple(range(args.seeds)) if args.seeds is not None else None)
    model_kwargs = merge_model_kwargs(experiment.model_kwargs, args.model_kwargs) if args.model_kwargs else None
    scheme_model_kwargs = None
    if args.scheme_model_kwargs:
        scheme_model_kwargs = {
            scheme: merge_model_kwargs(experiment.scheme_model_kwargs.get(scheme, {}), kwargs)
            for scheme, kwargs in {**experiment.scheme_model_kwargs, **args.scheme_model_kwargs}.items()
        }
    schedule = {dest: getattr(args, dest) for dest in SCHEDULE_FLAGS}
    if args.episodes is not None:
        scaled = scaled_schedule(experiment, args.episodes)
        schedule = {dest: scaled[dest] if value is None else value for dest, value in schedule.items()}
    return dict(
        name=args.name,
        schemes=args.schemes,
        seeds=seeds,
        n_agents=args.n_agents,
        episodes=args.episodes,
        **schedule,
        model_kwargs=model_kwargs,
        scheme_model_kwargs=scheme_model_kwargs,
        env=args.env,
        env_kwargs=args.env_kwargs,
        score_agents=args.score_agents,
        keep_checkpoints=args.keep_checkpoints,
        normalize_observations=args.normalize_observations,
        vec_env=args.vec_env,
        n_envs=args.n_envs,
        algorithm=ALGORITHMS[args.algo] if args.algo else None,
    )


def _check_experiments(experiments: Sequence[ExperimentConfig]) -> None:
    """
    Refuse, before anything runs, what would fail in every run: checkpoints that do not fit the budget, and schemes
    that the package's algorithms do not know.

    :param experiments: The sweep's experiments.
    """
    from sb3_maddpg.experiments.runner import run_critic_sharing
    from sb3_maddpg.sharing.registry import validate_critic_sharing

    for experiment in experiments:
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
        "sb3-maddpg run: no experiment given: name one with --config (a preset below or an experiment JSON file; "
        "repeat it for several). The paper's full sweep is --config exp1 --config exp2 (310 runs, days of CPU); "
        f"add --dry-run to list the runs first.\n{presets}"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """
    :param argv: The arguments (default: ``sys.argv[1:]``).
    :return: The exit status: 0 when every run finished (or the report was written), 1 otherwise, 2 for a usage
        error (said in one line on stderr), 130 after Ctrl-C (the sweep resumes with the same command).
    """
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exit:  # argparse: --help (0), or a usage error said in one line (2)
        return exit.code if isinstance(exit.code, int) else 2
    if args.command == "run":
        if not args.config:
            print(no_config_message(), file=sys.stderr)
            return 2
        try:
            return run_command(args)
        except KeyboardInterrupt:  # Ctrl-C before the sweep began (run_command handles it during the sweep)
            print("sb3-maddpg run: interrupted before the sweep started; nothing was run.", file=sys.stderr)
            return 130
    if args.command == "tune":
        try:
            return tune_command(args)
        except KeyboardInterrupt:
            print("sb3-maddpg tune: interrupted; the same command resumes the study.", file=sys.stderr)
            return 130
    return report_command(args)


def parse_fixed_params(items: list[str]) -> dict[str, Any]:
    """
    :param items: ``--fix`` values, ``NAME=VALUE`` each (the value as JSON: ``25``, ``1e-3``).
    :return: The parameters to hold, by name (checked by the study's settings).
    """
    fixed: dict[str, Any] = {}
    for item in items:
        name, equals, text = item.partition("=")
        if not equals or not name:
            raise ValueError(f"--fix {item!r} is not NAME=VALUE: e.g. --fix transitions_per_update=25.")
        try:
            fixed[name.strip()] = json.loads(text)
        except json.JSONDecodeError:
            raise ValueError(f"--fix {item!r}: its value {text!r} is not a number (JSON), e.g. 25 or 1e-3.") from None
    return fixed


def _tune_experiment(args: argparse.Namespace) -> ExperimentConfig:
    """
    :param args: Parsed ``tune`` arguments.
    :return: The setting the trials train in: ``--config`` with the task, team and scheme options over it.
    """
    scheme = (args.scheme,) if args.scheme else None
    changes = {"env": args.env, "env_kwargs": args.env_kwargs, "score_agents": args.score_agents, "n_agents": args.n_agents}
    experiment = _with_team(load_experiment(args.config), {**changes, "schemes": scheme}, args)
    _check_experiments([experiment])
    return experiment


def _tune_settings(args: argparse.Namespace) -> Any:
    """
    :param args: Parsed ``tune`` arguments.
    :return: The study's :class:`~sb3_maddpg.experiments.tune.TuneSettings`; a ``ValueError`` for a user's error.
    """
    from sb3_maddpg.experiments.tune import TuneSettings, default_study_name, task_objectives

    experiment = _tune_experiment(args)
    fixed = parse_fixed_params(args.fix)
    setting = experiment.name
    if args.env and args.env != load_experiment(args.config).env:  # another task than the config's: say it
        setting += "_" + re.sub(r"[^A-Za-z0-9_.-]+", "_", args.env)
    objective = args.objective or next(iter(task_objectives(experiment)))
    return TuneSettings(
        experiment=experiment,
        study_name=args.study_name or default_study_name(setting, objective, fixed),
        storage=args.storage,
        n_trials=args.trials,
        budget=args.steps,
        n_evaluations=args.evaluations,
        eval_episodes=args.eval_episodes,
        last_evaluations=args.last_evaluations,
        warmup_evaluations=args.warmup_evaluations,
        objective=objective,
        seed=args.seed,
        heartbeat_seconds=args.heartbeat,
        fixed_params=fixed,
    )


def tune_command(args: argparse.Namespace) -> int:
    """
    :param args: Parsed ``tune`` arguments.
    :return: The exit status.
    """
    from sb3_maddpg.experiments.tune import best_preset, describe_best, finished_trials, run_study

    try:
        settings = _tune_settings(args)
    except ValueError as error:
        print(f"sb3-maddpg tune: {error}", file=sys.stderr)
        return 2
    experiment = settings.experiment
    warning = _untrained_warning(experiment, settings.budget, "--steps")
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
        with open(args.preset_out, "w") as file:
            json.dump(best_preset(study, settings), file, indent=2)
            file.write("\n")
        print(f"preset written to {args.preset_out}: sb3-maddpg run --config {args.preset_out}")
    return 0


def _check_execution(args: argparse.Namespace) -> None:
    """:param args: Parsed ``run`` arguments, whose execution options are refused (a ``ValueError``) if they clash."""
    if args.ray and args.backend not in ("batched", "batched-ray"):
        raise ValueError(
            f"--ray runs the batched backend's run groups as Ray tasks, but the backend is {args.backend}: use --backend "
            "batched --ray, or --backend ray for one Ray task per run."
        )
    if args.ray_address and args.backend == "batched" and not args.ray:  # batched-ray is on Ray
        raise ValueError(
            "--ray-address is Ray's, but --backend batched without --ray trains in this process: add --ray to run the "
            "groups as Ray tasks there."
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
    try:
        result = run_sweep(
            experiments,
            args.results,
            backend=args.backend,
            workers=args.workers if args.workers is not None else (1 if args.backend == "local" else 0),
            threads=args.threads,
            ray_address=args.ray_address,
            verbose=1 if args.quiet else 2,
            device=args.device,
            runs_per_process=args.runs_per_process,
            on_ray=args.ray and args.backend == "batched",
            snapshots=not args.no_snapshots,
            compile=args.compile,
        )
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
