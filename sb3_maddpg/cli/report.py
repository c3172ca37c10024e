"""``sb3-maddpg report``: the report of a results directory (:func:`~sb3_maddpg.results.report.make_report`),
of some of its experiments, of the seeds every scheme has finished, or of some seeds, with each user's error said in
one line."""

import argparse
import importlib.util
import os
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from sb3_maddpg.analysis.evaluation import side_return_key
from sb3_maddpg.common.install_hint import extra_install_command
from sb3_maddpg.envs.mpe_tasks import MPE_TASK_SIDES
from sb3_maddpg.experiments.defaults import DEFAULT_RESULTS, LEFT_OUT_SHOWN
from sb3_maddpg.experiments.group_state import parse_seed_ranges, seed_ranges
from sb3_maddpg.experiments.metrics import METRICS
from sb3_maddpg.experiments.results_dir import link_complete_seeds, link_experiments, seed_of, unknown_experiments_message

if TYPE_CHECKING:
    from sb3_maddpg.results.report import UnscoredMetricError


def report_metric_choices(results_dir: str | None = None) -> list[str]:
    """
    :param results_dir: A results directory whose runs' declared task metrics are choices too (those their summaries
        record, e.g. pursuit's ``evaders_caught``); ``None``: the package's alone.
    :return: What ``report --metric`` takes: every score's key, each competitive MPE task's sides' returns, and the
        task metrics of the runs in ``results_dir``.
    """
    sides = {side_return_key(side) for task_sides in MPE_TASK_SIDES.values() for side in task_sides}
    declared: set[str] = set()
    if results_dir is not None:
        from sb3_maddpg.experiments.results_dir import load_summaries

        declared = {record["key"] for summary in load_summaries(results_dir) for record in summary.get("task_metrics", ())}
    return sorted({*METRICS, *sides, *declared})


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
    choices = report_metric_choices(args.results) if args.metric else []
    unknown = [metric for metric in args.metric or () if metric not in choices]
    if unknown:
        print(f"sb3-maddpg report: --metric {unknown[0]!r} is no score: give one of {', '.join(choices)}.", file=sys.stderr)
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
    if args.experiment:
        not_held = unknown_experiments_message(args.results, args.experiment)
        if not_held is not None:
            print(f"sb3-maddpg report: --experiment: {not_held}", file=sys.stderr)
            return 2
    seeds = None
    if args.seeds is not None:
        try:
            seeds = parse_seeds(args.seeds)
        except ValueError:
            print(f"sb3-maddpg report: --seeds {args.seeds!r}: give seeds and ranges, e.g. 0-4 or 0,2,5-9.", file=sys.stderr)
            return 2
    # What the report reads, as errors name it: the directory, or the experiments of it that --experiment names.
    reading = args.results if not args.experiment else f"{args.results} (experiments {', '.join(args.experiment)})"
    if seeds is not None:
        reading += f" (seeds {args.seeds})"
    if not args.complete_seeds and seeds is None:
        if not args.experiment:
            return _write_report(args.results, out, args.metric, plots)
        with tempfile.TemporaryDirectory(prefix="sb3_maddpg_report_") as view:
            chosen = str(Path(view) / "experiments")
            link_experiments(args.results, chosen, args.experiment)
            return _write_report(chosen, out, args.metric, plots, shown_as=reading)
    option = "--complete-seeds" if args.complete_seeds else "--seeds"
    with tempfile.TemporaryDirectory(prefix="sb3_maddpg_report_") as view:
        complete = str(Path(view) / "complete_seeds")
        left_out = link_complete_seeds(args.results, complete, args.experiment, seeds)
        if not Path(complete).is_dir() and seeds is not None:
            runs = (seed_of(done.parent.name) for done in Path(args.results).glob("*/*/seed_*/done"))
            finished = sorted({seed for seed in runs if seed is not None})
            there = f"seeds finished there: {seed_ranges(finished)}" if finished else "no run finished there"
            print(
                f"sb3-maddpg report: no seed of --seeds {args.seeds} in {args.results} is finished by every scheme of its "
                f"setting ({there}): give seeds the runs have finished, or report once they have.",
                file=sys.stderr,
            )
            return 1
        if not Path(complete).is_dir():
            print(
                f"sb3-maddpg report: no seed in {reading} is finished by every scheme of its setting "
                + (
                    f"({len(left_out)} finished run(s)): report them without {option}, or once every scheme "
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
                f"sb3-maddpg report: {option} leaves out {len(left_out)} finished run(s), their seed not "
                f"finished by every scheme of their setting: {shown}",
                file=sys.stderr,
            )
        return _write_report(complete, out, args.metric, plots, shown_as=reading)


def parse_seeds(text: str) -> set[int]:
    """
    :param text: ``report --seeds``' value: seeds and ranges, comma-separated (``0-4``, ``0,2,5-9``).
    :return: The seeds.
    :raise ValueError: For anything else.
    """
    seeds: set[int] = set()
    for part in text.split(","):
        in_part = parse_seed_ranges(part.strip())  # a group state's seed ranges: "0-4" (a range backwards is empty)
        if not in_part:
            raise ValueError(f"{part!r} is no seed or range")
        seeds |= in_part
    return seeds


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
    :param error: :func:`~sb3_maddpg.results.report.make_report`'s refusal of a metric no run scores.
    :param directory: The results directory, as the user named it.
    :return: ``report``'s line: the metric(s) no run scores, those that ``--metric`` could take instead, what to do.
    """
    asked = ", ".join(error.unscored)
    choices = set(report_metric_choices(error.results_dir))
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
    :param shown_as: What an error names instead of ``results`` when that is a temporary view of the user's directory
        (``--complete-seeds``, ``--experiment``); ``None``: ``results``.
    :return: The exit status.
    """
    from sb3_maddpg.results.report import UnscoredMetricError, make_report

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
