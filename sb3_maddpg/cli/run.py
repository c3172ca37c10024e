"""``sb3-maddpg run``: the experiments of ``--config`` with the given fields over each, checked, then swept on a
backend (:func:`~sb3_maddpg.experiments.sweep.run_sweep`)."""

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sb3_maddpg.cli.options import execution_options, given_fields, override, setting_options
from sb3_maddpg.common.progress import INTERRUPTED_EXIT_CODE
from sb3_maddpg.experiments.config import EXPERIMENTS, algorithm_argument, load_algorithm, load_experiment
from sb3_maddpg.experiments.defaults import ALGORITHMS
from sb3_maddpg.experiments.setting import CONCERNS, ExperimentConfig


def experiments_from_args(args: argparse.Namespace) -> list[ExperimentConfig]:
    """
    :param args: Parsed ``run`` arguments.
    :return: Each ``--config`` with the fields given over it (:func:`override`); a ``ValueError`` for a user's error.
    """
    if hasattr(args, "name") and len(args.config) != 1:
        raise ValueError(f"--name renames one experiment, but {len(args.config)} --config are given: give one --config.")
    names = [option.name for concern in (*CONCERNS, ExperimentConfig) for option in setting_options(concern)]
    given = given_fields(args, list(dict.fromkeys(names)))  # in the concerns' order, as --help lists them
    return [override(load_experiment(name), given, name) for name in args.config]


def check_experiments(experiments: Sequence[ExperimentConfig]) -> None:
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


def untrained_warning(experiment: ExperimentConfig, steps: int, option: str, unit: int = 1) -> str | None:
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


def _check_execution(args: argparse.Namespace) -> None:
    """:param args: Parsed ``run`` arguments, whose execution options are refused (a ``ValueError``) if they clash."""
    if args.ray_address and args.backend not in ("ray", "batched-ray"):
        raise ValueError(
            f"--ray-address is Ray's, but --backend {args.backend} trains on this machine: use --backend ray (a Ray task "
            "per run) or batched-ray (a Ray task per run group) to train there."
        )
    if Path(args.results).exists() and not Path(args.results).is_dir():
        raise ValueError(f"--results {args.results} is a file, not a directory: give a directory (new or a sweep's).")
    from sb3_maddpg.experiments.backends import Execution

    try:
        Execution(**execution_of(args))
    except ValueError as error:  # the error names the field first: say it as its option
        field, _, rest = str(error).partition(" ")
        raise ValueError(f"--{field.replace('_', '-')} {rest}") from None


def execution_of(args: argparse.Namespace) -> dict[str, Any]:
    """
    :param args: Parsed ``run`` arguments.
    :return: Their execution options (:class:`~sb3_maddpg.experiments.backends.Execution`'s fields), workers by the
        backend if not given.
    """
    execution = {option.name: getattr(args, option.name) for option in execution_options()}
    if execution["workers"] is None:
        execution["workers"] = 1 if args.backend == "local" else 0
    return execution


def run_command(args: argparse.Namespace) -> int:
    """
    :param args: Parsed ``run`` arguments.
    :return: The exit status.
    """
    from sb3_maddpg.experiments.group_plan import BatchedRunRefused
    from sb3_maddpg.experiments.references import ReferencePolicyError
    from sb3_maddpg.experiments.results_dir import ResultsDirectoryLocked
    from sb3_maddpg.experiments.sweep import SweepInterrupted, plan_sweep, run_sweep  # torch: imported for runs only

    try:
        _check_execution(args)
        experiments = experiments_from_args(args)
        check_experiments(experiments)
        todo, finished = plan_sweep(experiments, args.results)  # a finished run of another config is refused here
    except ValueError as error:
        print(f"sb3-maddpg run: {error}", file=sys.stderr)
        return 2
    for experiment in experiments:
        warning = untrained_warning(
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
        result = run_sweep(experiments, args.results, verbose=1 if args.quiet else 2, **execution_of(args))
    except (BatchedRunRefused, ReferencePolicyError) as error:  # said before anything trained
        print(f"sb3-maddpg run: {error}", file=sys.stderr)
        return 2
    except ResultsDirectoryLocked as error:
        print(f"sb3-maddpg run: {error}", file=sys.stderr)
        return 1
    except SweepInterrupted:  # Ctrl-C: the sweep has said how far it got and that the same command resumes
        return INTERRUPTED_EXIT_CODE
    if not args.quiet:
        print(f"results in {args.results}; report with: sb3-maddpg report {args.results}")
    return 0 if result.ok else 1
