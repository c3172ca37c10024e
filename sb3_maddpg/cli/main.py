"""Command line: ``sb3-maddpg run ...`` (or ``python -m sb3_maddpg run ...``), ``... tune ...`` and
``... report ...`` (each command's code in its module: :mod:`~sb3_maddpg.cli.run`, :mod:`~sb3_maddpg.cli.tune`,
:mod:`~sb3_maddpg.cli.report`), derived
from the config model (:mod:`~sb3_maddpg.cli.options`): ``run``'s options are the fields of an experiment
(:class:`~sb3_maddpg.experiments.setting.ExperimentConfig`), each over every ``--config``'s, and of its execution
(:class:`~sb3_maddpg.experiments.backends.Execution`); ``tune``'s the task's, ``TuneSettings``' and ``run_study``'s. A
user's error (a bad name, value or file) ends a command with one line on stderr, its cause then what to do, exit 2."""

import re
import sys
from collections.abc import Sequence
from typing import Any

from jsonargparse import ArgumentParser

from sb3_maddpg.cli.options import (
    EXPERIMENT_OWN,
    add_options,
    execution_options,
    flag,
    options_of,
    setting_options,
)
from sb3_maddpg.cli.termination import run_stoppable
from sb3_maddpg.experiments.config import EXPERIMENTS
from sb3_maddpg.experiments.defaults import DEFAULT_RESULTS, LEFT_OUT_SHOWN
from sb3_maddpg.experiments.setting import (
    CONCERNS,
    AlgorithmConfig,
    TaskConfig,
)


class UsageError(Exception):
    """A command line the parser refuses (its message in one line)."""


EXPECTED = {
    "int": "an integer",
    "float": "a number",
    "bool": "true or false",
    "dict": """a mapping (JSON or YAML, e.g. '{"batch_size": 256}')""",
}
"""What a value of each type is, in a refusal's words."""


class _Parser(ArgumentParser):
    """jsonargparse's parser, whose errors are raised to :func:`main` (said there in one line) rather than exiting."""

    def error(self, message: str, ex: Exception | None = None) -> Any:  # type: ignore[override]
        """:param message: The parser's message, raised as a :class:`UsageError` of one line."""
        message = re.sub(r"<class '(\w+)'>", r"\1", " ".join(str(message).split()))
        message = re.sub(r'Parser key "(?:\w+\.)?(\w+)":', lambda key: flag(key.group(1)) + ":", message)
        unions = re.sub(r"typing\.Literal\[([^\]]*)\]", r"\1", message)  # a choice among the types: its values
        union = re.match(r"(--[\w-]+): Does not .* Union subtypes Subtypes: \[(.*?)\].*Given value: (.*)$", unions)
        if union:
            message = f"{union.group(1)}: {union.group(3)!r} is none of {union.group(2).replace('NoneType', 'null')}"
        one = re.match(r"(--[\w-]+): Expected a (typing\.Literal\[(.*)\]|\w+)\. Got value: (.*)$", message)
        if one:
            expected = f"one of {one.group(3)}" if one.group(3) else EXPECTED.get(one.group(2), f"a {one.group(2)}")
            message = f"{one.group(1)}: {one.group(4)!r} is not {expected}"
        raise UsageError(message)


COMMANDS = {
    "run": "run a sweep (finished runs are skipped: the same command resumes)",
    "tune": "search the hyperparameters on Optuna (the same command resumes)",
    "report": "Table 2, the paper's findings, curves and boxplots from a results directory",
}
"""The commands, and what each does."""


def _title(concern: type) -> str:
    """:return: A concern's first words (its docstring's, up to a colon or full stop), as its options' heading."""
    return re.split(r"[:.]", " ".join((concern.__doc__ or "").split()), maxsplit=1)[0]


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
        add_options(run.add_argument_group(_title(concern)), setting_options(concern), True)
    own = [option for option in setting_options() if option.name in EXPERIMENT_OWN]
    add_options(run.add_argument_group("The experiment's runs"), own, True)
    add_options(run.add_argument_group("Where the runs execute"), execution_options())
    run.add_argument("--dry-run", action="store_true", help="list the runs and exit")
    run.add_argument("--quiet", action="store_true", help="print only the sweep's progress, not each run's")
    return run


def _tune_parser() -> ArgumentParser:
    """:return: ``tune``'s parser: the setting, the study's settings and its workers."""
    from sb3_maddpg.tuning.search import TuneSettings, run_study

    tune = _Parser(
        description="Train trials of one setting with sampled hyperparameters, prune the poor ones, print the best as a "
        "preset. Several processes (--workers, or the same command in another shell) share the study.",
    )
    tune.add_argument("--config", default="exp1", help="the setting: a preset, a preset file or a stored experiment")
    for concern in (TaskConfig, AlgorithmConfig):  # each option over --config's; the trials sample over the algorithm's
        add_options(tune.add_argument_group(_title(concern)), setting_options(concern), True)
    tune.add_argument("--scheme", help="the critic_sharing scheme; null: the setting's first")
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
    add_options(tune.add_argument_group("The study"), study)
    add_options(tune.add_argument_group("The workers"), options_of(run_study))
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
        help="score(s) to tabulate and plot, repeat for several, e.g. min_dist_sum, a competitive task's "
        "return_adversaries or a metric the task's env declares, e.g. pursuit's evaders_caught (default: the task's main "
        "metrics: simple_spread's success_rate and min_dist_sum)",
    )
    report.add_argument("--no-plots", action="store_true", help="tables only")
    report.add_argument(
        "--experiment",
        action="append",
        help="report only this experiment (setting) of the results directory, repeat for several, e.g. a study's "
        "settings without a learning curve's runs beside them (default: every experiment there)",
    )
    report.add_argument(
        "--complete-seeds",
        action="store_true",
        help="report only the seeds that every scheme of a setting has finished, so that a sweep in progress compares "
        f"like with like (the finished runs left out are counted, the first {LEFT_OUT_SHOWN} named; exit status 1 "
        "when no seed is complete)",
    )
    report.add_argument(
        "--seeds",
        help="report only these seeds, e.g. 0-4 or 0,2,5-9, those every scheme of a setting has finished (as "
        "--complete-seeds): a study read as it stood at its first seeds, beside its reading at all of them",
    )
    return report


def main(argv: Sequence[str] | None = None) -> int:
    """
    :param argv: The arguments (default: ``sys.argv[1:]``).
    :return: The exit status: 0 when every run finished (or the report was written), 1 otherwise, 2 for a usage
        error (said in one line on stderr), 130 after Ctrl-C and 143 after SIGTERM (either stops a ``run`` or ``tune``
        cleanly: the same command resumes it).
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
    if parsed.command == "run":  # each command's code imported for it alone: a run imports no tuning code
        from sb3_maddpg.cli.run import no_config_message, run_command

        if not args.config:
            print(no_config_message(), file=sys.stderr)
            return 2
        # run_command handles an interrupt during the sweep; one reaching here came before it began
        return run_stoppable(
            lambda: run_command(args), "sb3-maddpg run: interrupted before the sweep started; nothing was run."
        )
    if parsed.command == "tune":
        from sb3_maddpg.cli.tune import tune_command

        return run_stoppable(lambda: tune_command(args), "sb3-maddpg tune: interrupted; the same command resumes the study.")
    from sb3_maddpg.cli.report import report_command

    return report_command(args)


if __name__ == "__main__":
    sys.exit(main())
