"""Command line: ``sb3-maddpg run ...`` (or ``python -m sb3_maddpg.experiments run ...``) and ``... report ...``."""

import argparse
import importlib.util
import json
import sys
from collections.abc import Sequence
from typing import Any

from sb3_maddpg.experiments.config import (
    DEFAULT_N_ENVS,
    EXPERIMENTS,
    TUNE_OBJECTIVES,
    VEC_ENVS,
    ExperimentConfig,
    load_experiment,
    merge_model_kwargs,
)
from sb3_maddpg.experiments.stats import METRICS
from sb3_maddpg.install_hint import extra_install_command

DEFAULT_RESULTS = "runs/experiments"

ALGORITHMS = {"maddpg": "sb3_maddpg:MADDPG", "matd3": "sb3_maddpg:MATD3"}
"""``run --algo``'s names and the experiments' ``algorithm`` each sets."""


def _int_list(text: str) -> tuple[int, ...]:
    return tuple(int(item) for item in text.split(",") if item.strip())


def _str_list(text: str) -> tuple[str, ...]:
    return tuple(item.strip() for item in text.split(",") if item.strip())


def build_parser() -> argparse.ArgumentParser:
    """:return: The argument parser of the ``sb3-maddpg`` command."""
    parser = argparse.ArgumentParser(
        prog="sb3-maddpg",
        description="Reproduce the paper's experiments: train every scheme and seed, evaluate checkpoints, report Table 2.",
    )
    commands = parser.add_subparsers(dest="command", required=True)

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
    group = run.add_argument_group("overrides (applied to every --config)")
    group.add_argument("--name", help="store the experiment under this name (one --config only)")
    group.add_argument("--schemes", type=_str_list, help="comma-separated schemes, e.g. full,selected")
    group.add_argument("--seeds", type=int, help="number of seeds (0..N-1)")
    group.add_argument("--seed-list", type=_int_list, help="comma-separated seeds (instead of --seeds)")
    group.add_argument("--n-agents", type=int, help="agents (and landmarks)")
    group.add_argument("--neighbors", help="nearest other agents observed: an integer, or 'all'")
    group.add_argument("--episodes", type=int, help="training budget in episodes")
    group.add_argument("--n-checkpoints", type=int, help="checkpoints over the last 20%% of training")
    group.add_argument("--eval-episodes", type=int, help="episodes per checkpoint evaluation")
    group.add_argument("--curve-points", type=int, help="learning-curve evaluations per run")
    group.add_argument("--curve-eval-episodes", type=int, help="episodes per learning-curve evaluation")
    group.add_argument(
        "--algo",
        choices=sorted(ALGORITHMS),
        help="the algorithm every run trains (default: the config's, MADDPG for the presets); store a MATD3 sweep under "
        "its own --name or --results, so that report tells it apart",
    )
    group.add_argument(
        "--model-kwargs", type=json.loads, help="JSON merged into the MADDPG kwargs, e.g. '{\"batch_size\": 256}'"
    )
    group.add_argument(
        "--scheme-model-kwargs",
        type=json.loads,
        help='JSON of MADDPG kwargs for one scheme only, merged per scheme, e.g. \'{"selected": {"selector": 1}}\'',
    )
    group.add_argument(
        "--env",
        help="the task: simple_spread (default), another MPE task (e.g. simple_tag), a PettingZoo factory "
        "'module:function', or a gymnasium id",
    )
    group.add_argument("--env-kwargs", type=json.loads, help="JSON of the task constructor's keyword arguments")
    group.add_argument(
        "--score-agents", type=_str_list, help="comma-separated agent ids whose summed return is scored (group_return)"
    )
    group.add_argument(
        "--vec-env",
        choices=VEC_ENVS,
        help="batched: SimpleSpreadVecEnv (the same MDP as mpe2, arrays; default); mpe2: DummyVecEnv over mpe2 itself",
    )
    group.add_argument("--n-envs", type=int, help=f"worlds stepped together in training (default {DEFAULT_N_ENVS})")
    group.add_argument("--keep-checkpoints", action=argparse.BooleanOptionalAction, default=None, help="keep model files")
    group.add_argument(
        "--normalize-observations",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="normalise the observations by their running mean and variance (SB3's VecNormalize; rewards raw)",
    )
    execution = run.add_argument_group("execution")
    execution.add_argument(
        "--backend",
        choices=("local", "ray", "batched"),
        default="local",
        help="local process pool, Ray, or batched: a setting and scheme's seeds trained together in one process (run "
        "groups, fixed schemes on the batched simple_spread env; see --device, --runs-per-process, --ray)",
    )
    execution.add_argument(
        "--device", default="auto", help="batched: where the run groups train, cpu or cuda (default auto: cuda if there)"
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

    tune = commands.add_parser(
        "tune",
        help="search MADDPG's hyperparameters on Optuna (a study in SQLite: the same command resumes it)",
        description="Train trials of one setting with sampled hyperparameters, prune the poor ones, print the best as a "
        "preset. Several processes (--workers, or the same command in another shell) share the study.",
    )
    tune.add_argument("--config", default="exp1", help="the setting: a preset or an experiment JSON file (default: exp1)")
    tune.add_argument("--n-agents", type=int, help="agents (and landmarks)")
    tune.add_argument("--neighbors", help="nearest other agents observed: an integer, or 'all'")
    tune.add_argument("--scheme", help="the critic_sharing scheme (default: the setting's first)")
    tune.add_argument("--env-kwargs", type=json.loads, help="JSON of the task constructor's keyword arguments")
    tune.add_argument("--study-name", help="the study's name (default: <setting>_<objective>, then each --fix)")
    tune.add_argument("--storage", default="sqlite:///tune.db", help="Optuna storage URL (default: sqlite:///tune.db)")
    tune.add_argument("--trials", type=int, default=50, help="finished trials at which the study stops (default 50)")
    tune.add_argument("--steps", type=int, default=1_000_000, help="env steps per trial (default 1,000,000)")
    tune.add_argument("--evaluations", type=int, default=10, help="evaluations per trial, reported to the pruner")
    tune.add_argument("--eval-episodes", type=int, default=100, help="episodes per evaluation (default 100)")
    tune.add_argument("--last-evaluations", type=int, default=3, help="a trial scores its mean over these last ones")
    tune.add_argument(
        "--warmup-evaluations", type=int, default=1, help="first evaluations at which no trial is pruned (default 1)"
    )
    tune.add_argument("--objective", choices=sorted(TUNE_OBJECTIVES), default="min_dist_sum", help="what to optimise")
    tune.add_argument("--seed", type=int, default=0, help="seed of the sampler and of every trial's run")
    tune.add_argument("--workers", type=int, default=1, help="parallel worker processes sharing the study")
    tune.add_argument("--backend", choices=("local", "ray"), default="local", help="local processes or Ray tasks")
    tune.add_argument("--address", default=None, help="Ray cluster address (with --backend ray)")
    tune.add_argument("--threads", type=int, default=1, help="torch threads per worker (default: 1)")
    tune.add_argument("--heartbeat", type=int, default=60, help="seconds between a trial's heartbeats (default 60)")
    tune.add_argument("--preset-out", help="also write the best trial's preset (experiment JSON) to this file")
    tune.add_argument(
        "--fix",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="hold a sampled parameter at one value in every trial (repeat for several), e.g. --fix "
        "transitions_per_update=25 --fix width=64; the study's default name then says so",
    )

    report = commands.add_parser(
        "report", help="Table 2 (Markdown, CSV), learning curves and boxplots from a results directory"
    )
    report.add_argument("results", nargs="?", default=DEFAULT_RESULTS, help=f"results directory (default: {DEFAULT_RESULTS})")
    report.add_argument("--out", help="output directory (default: <results>/report)")
    report.add_argument(
        "--metric",
        action="append",
        choices=sorted(METRICS),
        help="score(s) to tabulate and plot, repeat for several (default: success_rate and min_dist_sum; other tasks: return)",
    )
    report.add_argument("--no-plots", action="store_true", help="tables only")
    return parser


def experiments_from_args(args: argparse.Namespace) -> list[ExperimentConfig]:
    """
    :param args: Parsed ``run`` arguments.
    :return: The experiments with the overrides applied.
    """
    names = args.config
    if args.name and len(names) != 1:
        raise SystemExit("--name renames one experiment: give a single --config.")
    experiments = []
    for name in names:
        experiment = load_experiment(name)
        seeds = args.seed_list or (tuple(range(args.seeds)) if args.seeds is not None else None)
        model_kwargs = merge_model_kwargs(experiment.model_kwargs, args.model_kwargs) if args.model_kwargs else None
        scheme_model_kwargs = None
        if args.scheme_model_kwargs:
            scheme_model_kwargs = {
                scheme: merge_model_kwargs(experiment.scheme_model_kwargs.get(scheme, {}), kwargs)
                for scheme, kwargs in {**experiment.scheme_model_kwargs, **args.scheme_model_kwargs}.items()
            }
        experiment = experiment.replace(
            name=args.name,
            schemes=args.schemes,
            seeds=seeds,
            n_agents=args.n_agents,
            episodes=args.episodes,
            n_checkpoints=args.n_checkpoints,
            eval_episodes=args.eval_episodes,
            curve_points=args.curve_points,
            curve_eval_episodes=args.curve_eval_episodes,
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
        if args.neighbors is not None:
            neighbors = None if args.neighbors == "all" else int(args.neighbors)
            experiment = ExperimentConfig.from_dict({**experiment.to_dict(), "num_agent_neighbors": neighbors})
        experiments.append(experiment)
    return experiments


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
        error, 130 after Ctrl-C (the sweep resumes with the same command).
    """
    args = build_parser().parse_args(argv)
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


def tune_command(args: argparse.Namespace) -> int:
    """
    :param args: Parsed ``tune`` arguments.
    :return: The exit status.
    """
    from sb3_maddpg.experiments.tune import (
        TuneSettings,
        best_preset,
        default_study_name,
        describe_best,
        finished_trials,
        run_study,
    )

    experiment = load_experiment(args.config).replace(
        n_agents=args.n_agents, schemes=(args.scheme,) if args.scheme else None, env_kwargs=args.env_kwargs
    )
    if args.neighbors is not None:
        neighbors = None if args.neighbors == "all" else int(args.neighbors)
        experiment = ExperimentConfig.from_dict({**experiment.to_dict(), "num_agent_neighbors": neighbors})
    try:
        fixed = parse_fixed_params(args.fix)
        settings = TuneSettings(
            experiment=experiment,
            study_name=args.study_name or default_study_name(experiment.name, args.objective, fixed),
            storage=args.storage,
            n_trials=args.trials,
            budget=args.steps,
            n_evaluations=args.evaluations,
            eval_episodes=args.eval_episodes,
            last_evaluations=args.last_evaluations,
            warmup_evaluations=args.warmup_evaluations,
            objective=args.objective,
            seed=args.seed,
            heartbeat_seconds=args.heartbeat,
            fixed_params=fixed,
        )
        if fixed:
            print("fixed in every trial: " + ", ".join(f"{name}={value}" for name, value in fixed.items()), flush=True)
        print(
            f"study {settings.study_name!r} in {settings.storage}: {settings.n_trials} trials of {settings.budget:,} steps "
            f"on {experiment.name} (N={experiment.n_agents}, scheme {experiment.schemes[0]}), {args.workers} worker(s)",
            flush=True,
        )
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


def run_command(args: argparse.Namespace) -> int:
    """
    :param args: Parsed ``run`` arguments.
    :return: The exit status.
    """
    from sb3_maddpg.experiments.batched import BatchedRunRefused
    from sb3_maddpg.experiments.results import ResultsDirectoryLocked
    from sb3_maddpg.experiments.sweep import SweepInterrupted, plan_sweep, run_sweep  # torch: imported for runs only

    if args.ray and args.backend != "batched":
        print(
            f"sb3-maddpg run: --ray runs the batched backend's run groups as Ray tasks, but the backend is {args.backend}: "
            "use --backend batched --ray, or --backend ray for one Ray task per run.",
            file=sys.stderr,
        )
        return 2
    if args.ray_address and args.backend == "batched" and not args.ray:
        print(
            "sb3-maddpg run: --ray-address is Ray's, but --backend batched without --ray trains in this process: add "
            "--ray to run the groups as Ray tasks there.",
            file=sys.stderr,
        )
        return 2
    experiments = experiments_from_args(args)
    if args.dry_run:
        todo, finished = plan_sweep(experiments, args.results)
        for experiment in experiments:
            print(f"{experiment.name}: {json.dumps(experiment.to_dict())}")
        for config in todo:
            print(f"  {config.run_id}: {config.total_timesteps:,} steps, checkpoints at {config.checkpoint_steps()}")
        print(f"{len(todo)} run(s) to do, {finished} finished")
        return 0
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
            on_ray=args.ray,
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
    from sb3_maddpg.experiments.report import make_report

    plots = not args.no_plots
    if plots and importlib.util.find_spec("matplotlib") is None:  # said before any table is written
        print(no_matplotlib_message(), file=sys.stderr)
        return 1
    out = args.out or f"{args.results.rstrip('/')}/report"
    try:
        for path in make_report(args.results, out, metrics=args.metric, plots=plots):
            print(path)
    except ModuleNotFoundError as error:  # a part of matplotlib missing: the same advice
        if error.name is None or error.name.split(".")[0] != "matplotlib":
            raise
        print(no_matplotlib_message(), file=sys.stderr)
        return 1
    except (FileNotFoundError, ValueError) as error:  # no finished runs, or a metric the runs do not have
        print(f"sb3-maddpg report: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
