"""``sb3-maddpg tune``: a study of the ``--config`` setting, with the task's given fields over it, on Optuna
(:func:`~sb3_maddpg.tuning.search.run_study`); the best trial printed, and written as a preset."""

import argparse
import re
import sys
from pathlib import Path
from typing import Any

import yaml

from sb3_maddpg.cli.options import given_fields, options_of, override, setting_options
from sb3_maddpg.cli.run import check_experiments, untrained_warning
from sb3_maddpg.experiments.config import load_experiment
from sb3_maddpg.experiments.setting import AlgorithmConfig, TaskConfig


def _tune_settings(args: argparse.Namespace) -> Any:
    """
    :param args: Parsed ``tune`` arguments.
    :return: The study's :class:`~sb3_maddpg.tuning.search.TuneSettings`: ``--config`` with the task's fields and
        the scheme over it; a ``ValueError`` for a user's error.
    """
    from sb3_maddpg.tuning.search import TuneSettings, default_study_name, task_objectives

    names = [option.name for concern in (TaskConfig, AlgorithmConfig) for option in setting_options(concern)]
    given = given_fields(args, names) | ({"schemes": (args.scheme,)} if args.scheme else {})
    loaded = load_experiment(args.config)
    experiment = override(loaded, given, args.config)
    check_experiments([experiment])
    setting = experiment.name
    if "env" in given and given["env"] != loaded.env:  # another task than the config's: say it
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
    from sb3_maddpg.tuning.search import best_preset, describe_best, finished_trials, run_study

    try:
        if args.preset_out and not args.preset_out.endswith((".yml", ".yaml")):
            raise ValueError(f"--preset-out {args.preset_out}: a preset is a YAML file: give a name ending in .yml.")
        if args.preset_out and not Path(args.preset_out).resolve().parent.is_dir():
            raise ValueError(f"--preset-out {args.preset_out}: its directory does not exist: create it, or name another.")
        settings = _tune_settings(args)
    except ValueError as error:
        print(f"sb3-maddpg tune: {error}", file=sys.stderr)
        return 2
    experiment = settings.experiment
    warning = untrained_warning(experiment, settings.budget, "--budget")
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
        Path(args.preset_out).write_text(yaml.safe_dump(best_preset(study, settings), sort_keys=False, width=120))
        print(f"preset written to {args.preset_out}: sb3-maddpg run --config {args.preset_out}")
    return 0
