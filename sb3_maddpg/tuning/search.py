"""Hyperparameter search on Optuna, as rl-zoo3 does for SB3: a sampler of MADDPG's hyperparameters, evaluations during
training reported to a pruner, and a study in SQLite that resumes and that several workers share.

Each trial trains one run of an experiment's setting (its task, N, observability; the first scheme) for
``budget`` env steps with sampled ``model_kwargs`` over the experiment's own, evaluates the team
``n_evaluations`` times on the same seeded episodes, reports each evaluation's objective (one of the task's
metrics, :func:`task_objectives`) to the pruner, and scores the mean objective over the last ``last_evaluations``
evaluations. Stale trials of a killed worker are
retried (Optuna's heartbeat), and the study stops at ``n_trials`` finished trials, however many workers share it.
"""

import dataclasses
import json
import math
import os
import time
import warnings
from collections.abc import Callable, Sequence
from typing import Any, Literal

import numpy as np
import yaml

from sb3_maddpg.analysis.evaluation import TeamEvalCallback, scores_simple_spread
from sb3_maddpg.common.argument_ranges import Range
from sb3_maddpg.common.install_hint import extra_install_command
from sb3_maddpg.common.torch_threads import use_torch_threads
from sb3_maddpg.compat import VERSION_KEY
from sb3_maddpg.experiments.config import TUNE_OBJECTIVES
from sb3_maddpg.experiments.defaults import DEFAULT_ENV
from sb3_maddpg.experiments.local_pool import worker_pool
from sb3_maddpg.experiments.runner import build_model
from sb3_maddpg.experiments.setting import ExperimentConfig, RunConfig, merge_model_kwargs
from sb3_maddpg.experiments.tasks import declared_metrics, run_task
from sb3_maddpg.version import __version__

HEARTBEAT_SECONDS = 60
"""How often a running trial tells the study it is alive; a trial silent for twice as long is failed and retried."""


def import_optuna() -> Any:
    """:return: The ``optuna`` module, or a clear error naming the install command."""
    try:
        import optuna
    except ModuleNotFoundError as error:
        raise ModuleNotFoundError(
            f"sb3-maddpg tune needs Optuna, which is not installed: {extra_install_command('tune')}."
        ) from error
    return optuna


CATEGORICAL_PARAMS: dict[str, tuple[Any, ...]] = {
    "width": (64, 128, 256),
    "batch_size": (256, 512, 1024, 2048),
    "transitions_per_update": (10, 25, 50, 100, 200, 400),
    "tau": (0.005, 0.01, 0.02, 0.05),
    "gamma": (0.9, 0.95, 0.97, 0.99),
    "actor_reg_coef": (0.0, 1e-4, 1e-3, 1e-2),
}
"""The sampled parameters with a few choices each, by their names in the study."""

LOG_UNIFORM_PARAMS: dict[str, tuple[float, float]] = {"learning_rate": (1e-4, 2e-2), "noise_std": (0.02, 0.5)}
"""The sampled parameters drawn on a log scale between two bounds, by their names in the study."""


def sample_maddpg_params(trial: Any) -> dict[str, Any]:
    """
    A sample of MADDPG's hyperparameters around the paper's (Lowe et al.'s), rl-zoo3 style
    (:data:`CATEGORICAL_PARAMS`, :data:`LOG_UNIFORM_PARAMS`).

    :param trial: An Optuna trial.
    :return: ``MADDPG`` keyword arguments: the learning rate (actors and critics), the exploration noise (in mpe2's
        units), the batch size, the network width (actors of 2 and critics of 3 hidden layers), the update ratio
        (transitions per gradient step), tau, gamma and the actor regulariser.
    """
    values = {name: trial.suggest_float(name, low, high, log=True) for name, (low, high) in LOG_UNIFORM_PARAMS.items()}
    values |= {name: trial.suggest_categorical(name, list(choices)) for name, choices in CATEGORICAL_PARAMS.items()}
    width = values.pop("width")
    return {**values, "policy_kwargs": {"net_arch": {"pi": [width, width], "qf": [width, width, width]}}}


def task_objectives(experiment: ExperimentConfig) -> dict[str, str]:
    """
    What a study can optimise on the experiment's task, and in which direction.

    :param experiment: The setting.
    :return: ``"minimize"`` or ``"maximize"`` by objective, the default first: on simple_spread
        :data:`~sb3_maddpg.experiments.config.TUNE_OBJECTIVES` (the min-dist sum first); on any other task the metrics
        its env declares (:func:`~sb3_maddpg.experiments.tasks.declared_metrics`: an MPE task's
        :data:`~sb3_maddpg.envs.MPE_TASK_METRICS`, a factory's env's own) in their direction, e.g. ``goal_distance``
        (minimised) or ``simple_tag``'s ``collisions`` (the catches, maximised), then, for a cooperative task (every
        metric the whole team's), ``return_mean`` (alone for an env that declares none); for an env that declares
        simple_spread's metrics under another name (``sb3_maddpg/SimpleSpread-v3``), the min-dist sum and the return.
        A competitive task's team return would add opponents' rewards: it is not offered. ``group_return``
        (maximised) follows when the experiment scores a group (``score_agents``), e.g. the adversaries of
        ``simple_tag``.
    """
    metrics = () if experiment.env == DEFAULT_ENV else declared_metrics(experiment.env, experiment.env_kwargs)
    if experiment.env == DEFAULT_ENV:
        objectives = dict(TUNE_OBJECTIVES)
    elif scores_simple_spread(metrics):  # simple_spread under another name: its scores, no normalised references
        objectives = {name: way for name, way in TUNE_OBJECTIVES.items() if name != "normalised"}
    else:
        objectives = {
            metric.key: "minimize" if getattr(metric, "better", "higher") == "lower" else "maximize" for metric in metrics
        }
        if all(getattr(metric, "team", "team") == "team" for metric in metrics):
            objectives["return_mean"] = "maximize"
    if experiment.score_agents:
        objectives["group_return"] = "maximize"
    return objectives


def default_study_name(setting: str, objective: str, fixed: dict[str, Any]) -> str:
    """
    :param setting: The setting's name.
    :param objective: A key of :func:`task_objectives`.
    :param fixed: The study's fixed parameters (:attr:`TuneSettings.fixed_params`).
    :return: ``<setting>_<objective>``, then each fixed parameter as ``_<name>=<value>`` in the order of their names
        (so that the same fixes in another order resume the same study).
    """
    return f"{setting}_{objective}" + "".join(f"_{name}={fixed[name]}" for name in sorted(fixed))


def check_fixed_params(fixed: dict[str, Any]) -> None:
    """
    Refuse parameters a study cannot fix: names it does not sample, or values outside their range or choices.

    :param fixed: Sampled parameters to hold at one value, by name (e.g. ``{"transitions_per_update": 25}``).
    """
    for name, value in fixed.items():
        if name in CATEGORICAL_PARAMS:
            choices = CATEGORICAL_PARAMS[name]
            integers = all(isinstance(choice, int) for choice in choices)
            if value not in choices or isinstance(value, bool) or (integers and not isinstance(value, int)):
                raise ValueError(f"fixed parameter {name}={value!r} is not one of its choices {list(choices)}.")
        elif name in LOG_UNIFORM_PARAMS:
            low, high = LOG_UNIFORM_PARAMS[name]
            if not isinstance(value, int | float) or isinstance(value, bool) or not low <= value <= high:
                raise ValueError(f"fixed parameter {name}={value!r} is outside its range [{low}, {high}].")
        else:
            sampled = sorted([*CATEGORICAL_PARAMS, *LOG_UNIFORM_PARAMS])
            raise ValueError(f"fixed parameter {name!r} is not a sampled parameter: fix one of {sampled}.")


TUNE_RANGES: dict[str, Range] = {
    "n_trials": Range("finished trials at which the study stops", integer=True, low=1, hint="use 50"),
    "budget": Range("env steps per trial", integer=True, low=1, hint="use a tenth to a fifth of a run's budget"),
    "n_evaluations": Range("evaluations per trial, each reported to the pruner", integer=True, low=1, hint="use 10"),
    "eval_episodes": Range("episodes per evaluation", integer=True, low=1, hint="use 100, or 5 on a slow task"),
    "last_evaluations": Range(
        "the last evaluations whose mean is a trial's value",
        integer=True,
        low=1,
        high_is="n_evaluations",
        hint="lower last_evaluations or raise n_evaluations",
    ),
    "warmup_evaluations": Range(
        "a trial's first evaluations that the default pruner never stops at",
        integer=True,
        low=0,
        hint="0 lets the pruner stop a trial at any evaluation, 1 (the default) spares its first",
    ),
    "seed": Range("the sampler's and every trial's seed", integer=True, low=0, high=2**32 - 1, hint="use 0"),
    "heartbeat_seconds": Range(
        "how often a running trial tells the study it is alive", integer=True, low=1, hint=f"use {HEARTBEAT_SECONDS}"
    ),
}
"""The valid range of each numeric field of :class:`TuneSettings` (as :mod:`~sb3_maddpg.common.argument_ranges`)."""


@dataclasses.dataclass(frozen=True)
class TuneSettings:
    """
    One study.

    :param experiment: The setting the trials train in (its first scheme; its ``model_kwargs`` under the samples).
    :param study_name: The study's name in the storage.
    :param storage: An Optuna storage URL, e.g. ``"sqlite:///tune.db"`` (shared by every worker; resumes).
    :param n_trials: Finished trials (complete or pruned) at which the study stops.
    :param budget: Env steps per trial.
    :param n_evaluations: Evaluations per trial (evenly spaced; each reported to the pruner).
    :param eval_episodes: Episodes per evaluation.
    :param last_evaluations: The trial's value is its objective's mean over this many last evaluations.
    :param objective: A key of :func:`task_objectives` for the experiment; ``None``: its first (the min-dist sum on
        simple_spread).
    :param seed: Seed of the sampler and of every trial's run.
    :param heartbeat_seconds: See :data:`HEARTBEAT_SECONDS`.
    :param warmup_evaluations: The default pruner never stops a trial at its first ``warmup_evaluations`` evaluations
        (early ones score little more than the random warm-up); 0 lets it stop one at any evaluation, and
        ``n_evaluations`` or more at none.
    :param pruner: An Optuna pruner; ``None``: a median pruner after 5 trials, past ``warmup_evaluations``
        (:meth:`default_pruner`).
    :param fixed_params: Sampled parameters held at one value in every trial, by their names in the study (e.g.
        ``{"transitions_per_update": 25, "width": 64}``; Optuna's ``PartialFixedSampler``): the others are searched.
    """

    experiment: ExperimentConfig
    study_name: str
    storage: str
    n_trials: int = 50
    budget: int = 1_000_000
    n_evaluations: int = 10
    eval_episodes: int = 100
    last_evaluations: int = 3
    warmup_evaluations: int = 1
    objective: str | None = None
    seed: int = 0
    heartbeat_seconds: int = HEARTBEAT_SECONDS
    pruner: Any = None
    fixed_params: dict[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        check_fixed_params(self.fixed_params)
        objectives = task_objectives(self.experiment)
        if self.objective is None:
            object.__setattr__(self, "objective", next(iter(objectives)))
        elif self.objective not in objectives:
            choices = ", ".join(f"{name} ({direction})" for name, direction in objectives.items())
            group = "" if self.experiment.score_agents else " (group_return needs the experiment's score_agents)"
            raise ValueError(
                f"objective {self.objective!r} is not one of {self.experiment.env}'s objectives: give one of {choices}{group}."
            )
        bounds = {"last_evaluations": self.n_evaluations}  # the upper bounds that depend on another field
        for name, valid in TUNE_RANGES.items():
            valid.check(name, getattr(self, name), bounds.get(name))

    @property
    def direction(self) -> str:
        """``"minimize"`` or ``"maximize"``: the objective's direction on the experiment's task."""
        assert self.objective is not None  # set in __post_init__
        return task_objectives(self.experiment)[self.objective]

    @property
    def evaluation_step(self) -> int:
        """
        Env steps between a trial's evaluations: the budget over ``n_evaluations``, rounded down to whole steps of the
        experiment's ``n_envs`` worlds (at least one), so that evaluation k reports at exactly k times this.
        """
        n_envs = self.experiment.n_envs
        return max(1, self.budget // self.n_evaluations // n_envs) * n_envs

    def default_pruner(self) -> Any:
        """
        :return: Optuna's median pruner: once 5 trials completed, it stops a trial whose objective is worse than the
            median of earlier trials at the same step, at any evaluation past the first ``warmup_evaluations``. Optuna
            prunes at a step of at least ``n_warmup_steps``, and evaluation k reports at k times
            :attr:`evaluation_step`: one step past evaluation ``warmup_evaluations`` spares it and no later one.
        """
        optuna = import_optuna()
        warmup_steps = self.warmup_evaluations * self.evaluation_step + 1 if self.warmup_evaluations else 0
        return optuna.pruners.MedianPruner(n_startup_trials=5, n_warmup_steps=warmup_steps)

    def run_config(self, model_kwargs: dict[str, Any]) -> RunConfig:
        """
        :param model_kwargs: The trial's sampled keyword arguments.
        :return: The trial's run: the experiment's first run with the trial's budget, seed and kwargs over its own
            (:func:`~sb3_maddpg.experiments.setting.merge_model_kwargs`: its ``policy_kwargs`` are kept under the
            sample's network width).
        """
        base = self.experiment.replace(seeds=(self.seed,)).runs()[0]
        episodes = max(1, math.ceil(self.budget / base.episode_length))
        merged = merge_model_kwargs(base.model_kwargs, model_kwargs)
        return dataclasses.replace(base, episodes=episodes, model_kwargs=merged, curve_points=0)


def objective_value(row: dict[str, float], objective: str, references: dict[str, dict[str, float]] | None) -> float:
    """
    :param row: One evaluation (:class:`~sb3_maddpg.analysis.evaluation.TeamEvalCallback`'s history row).
    :param objective: A key of :func:`task_objectives`.
    :param references: The task's references, for ``"normalised"``.
    :return: The evaluation's objective: its value in the row (NaN when the evaluations do not score it), or for
        ``"normalised"`` the mean of the min-dist sum's and the team return's normalised scores.
    """
    if objective != "normalised":
        return float(row.get(objective, math.nan))
    from sb3_maddpg.analysis.normalised_score import normalised_scores

    assert references is not None
    scores = normalised_scores(row, references)
    return (scores["min_dist_sum"] + scores["return_mean"]) / 2


class TrialEvalCallback(TeamEvalCallback):
    """
    :class:`~sb3_maddpg.analysis.evaluation.TeamEvalCallback` that reports each evaluation's objective to an Optuna trial and
    stops training when the pruner says so.

    :param trial: The trial.
    :param objective: A key of :func:`task_objectives`.
    :param references: The task's references, for ``"normalised"``.
    :param log: Called with a line after each evaluation (the trial's progress), or ``None``.
    :param budget: The trial's env steps, for those lines.
    :param kwargs: For :class:`~sb3_maddpg.analysis.evaluation.TeamEvalCallback`.
    """

    def __init__(
        self,
        trial: Any,
        objective: str,
        references: dict[str, dict[str, float]] | None,
        log: Callable[[str], None] | None = None,
        budget: int = 0,
        **kwargs: Any,
    ) -> None:
        super().__init__(**kwargs)
        self.trial = trial
        self.objective = objective
        self.references = references
        self.log = log
        self.budget = budget
        self.values: list[float] = []
        self.pruned = False
        self._started = time.monotonic()

    def _on_step(self) -> bool:
        evaluated = len(self.history)
        super()._on_step()
        if len(self.history) == evaluated:
            return True
        value = objective_value(self.history[-1], self.objective, self.references)
        if not math.isfinite(value):  # Optuna fails such a trial and starts another, which would fare no better
            raise ValueError(
                f"trial {self.trial.number}'s {self.objective} is {value} at step {self.num_timesteps}: the task's "
                "evaluations do not score it; choose another objective of the task "
                "(sb3_maddpg.tuning.search.task_objectives)."
            )
        self.values.append(value)
        self.trial.report(value, step=self.num_timesteps)
        self.pruned = self.trial.should_prune()
        if self.log is not None:
            elapsed = time.monotonic() - self._started
            self.log(
                f"trial {self.trial.number}: {self.num_timesteps:,}/{self.budget:,} steps, {self.objective} {value:.4f}, "
                f"{elapsed / 60:.1f} min" + (", pruned" if self.pruned else "")
            )
        return not self.pruned  # False: SB3 stops learn()


def run_trial(trial: Any, settings: TuneSettings, log: Callable[[str], None] | None = None) -> float:
    """
    Train and score one trial (the study's objective function).

    :param trial: The Optuna trial.
    :param settings: The study.
    :param log: Called with a line after each of the trial's evaluations (its progress), or ``None``.
    :return: The objective's mean over the last evaluations; ``optuna.TrialPruned`` is raised when pruned.
    """
    optuna = import_optuna()
    assert settings.objective is not None  # set by TuneSettings
    model_kwargs = sample_maddpg_params(trial)
    config = settings.run_config(model_kwargs)
    trial.set_user_attr("model_kwargs", json.loads(json.dumps(model_kwargs)))
    references = None
    if settings.objective == "normalised":
        from sb3_maddpg.results.normalised_table import setting_references

        references = setting_references(settings.experiment.to_dict())
    task = run_task(config)
    model = build_model(task)  # as a sweep's run builds it
    env = model.get_env()
    callback = TrialEvalCallback(
        trial,
        settings.objective,
        references,
        log=log,
        budget=settings.budget,
        eval_env=task.make_eval_env(settings.eval_episodes),
        eval_freq=settings.evaluation_step // env.num_envs,
        n_eval_episodes=settings.eval_episodes,
        seed=task.eval_seed,
        task_metrics=task.metrics,
        score_agents=config.score_agents,
    )
    model.learn(settings.budget, callback=callback)
    env.close()
    if callback.pruned:
        raise optuna.TrialPruned()
    if not callback.values:
        raise RuntimeError(f"trial {trial.number} made no evaluation: raise the budget or lower n_evaluations.")
    last = callback.values[-settings.last_evaluations :]
    return float(sum(last) / len(last))


STORAGE_ATTEMPTS = 10
"""How many times a worker tries to open a storage that another worker is creating at the same moment."""


def open_storage(open_once: Callable[[], Any], attempts: int = STORAGE_ATTEMPTS, wait_seconds: float = 0.2) -> Any:
    """
    Open an Optuna database storage that other workers may be creating at the same moment.

    Two processes that open a new SQLite file together both create its tables (and the schema's version row), and the
    later one fails with "table ... already exists" (or a UNIQUE constraint on that row); ``--workers 2`` does that on
    a new study. The tables exist by then, so opening it again succeeds. Other errors (e.g. a locked database) are
    raised at once.

    :param open_once: Opens the storage once (e.g. builds an ``optuna.storages.RDBStorage``).
    :param attempts: How many times to try before the error is raised.
    :param wait_seconds: The wait after the first failure; it grows by that much after each one.
    :return: The storage.
    """
    from sqlalchemy.exc import IntegrityError, OperationalError

    for attempt in range(1, attempts):
        try:
            return open_once()
        except (OperationalError, IntegrityError) as error:
            # The tables, or the schema's version row, created by another worker in between.
            if not any(sign in str(error) for sign in ("already exists", "UNIQUE constraint failed")):
                raise
            time.sleep(wait_seconds * attempt)
    return open_once()  # the last attempt's error, if any, is the caller's


def sampler_seed(seed: int, trials_so_far: int, worker: int) -> int:
    """
    The seed of one worker's sampler. Workers of one study whose samplers share a seed draw the same samples (TPE's
    first trials are random draws, and later ones start from the same random state): each worker, and each resumed
    run, gets its own seed, drawn from the study's.

    :param seed: The study's seed.
    :param trials_so_far: The trials in the study when the worker starts (enqueued ones count).
    :param worker: The worker's number among those started together (0 for one).
    :return: ``seed`` itself for the first worker of a study without trials (so that a study of one worker is
        reproducible), else a seed drawn from the three and this process's id (numpy's ``SeedSequence``), so that
        commands started apart (other shells, other machines) differ too. Two commands that start a new study at the
        same moment both draw from ``seed``: give the second another ``seed``.
    """
    if trials_so_far == 0 and worker == 0:
        return seed
    return int(np.random.SeedSequence([seed, trials_so_far, worker, os.getpid()]).generate_state(1)[0])


def load_study(settings: TuneSettings, worker: int = 0) -> Any:
    """
    :param settings: The study.
    :param worker: The worker's number among those started together, for its sampler's seed (:func:`sampler_seed`).
    :return: The Optuna study, created or resumed: a TPE sampler seeded from ``settings.seed``, the trials so far and
        ``worker``, the settings' pruner, heartbeats so that a killed worker's trial is failed and retried (once).
    """
    optuna = import_optuna()
    storage = settings.storage
    if storage.startswith(("sqlite:", "postgresql:", "mysql:")):
        with warnings.catch_warnings():  # heartbeats are "experimental" in Optuna since 2.8: said on every start
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            retry: dict[str, Any]
            if hasattr(optuna.storages, "RetryHeartbeatStaleTrialCallback"):  # Optuna >= 4.9
                retry = {"heartbeat_stale_trial_callback": optuna.storages.RetryHeartbeatStaleTrialCallback(max_retry=1)}
            else:
                retry = {"failed_trial_callback": optuna.storages.RetryFailedTrialCallback(max_retry=1)}
            storage = open_storage(
                lambda: optuna.storages.RDBStorage(
                    settings.storage,
                    heartbeat_interval=settings.heartbeat_seconds,
                    grace_period=2 * settings.heartbeat_seconds,
                    **retry,
                )
            )

    def make_sampler(seed: int) -> Any:
        sampler = optuna.samplers.TPESampler(seed=seed, n_startup_trials=5)
        if not settings.fixed_params:
            return sampler
        with warnings.catch_warnings():  # "experimental" since Optuna 2.4: said on every start
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            return optuna.samplers.PartialFixedSampler(settings.fixed_params, sampler)

    study = optuna.create_study(
        study_name=settings.study_name,
        storage=storage,
        direction=settings.direction,
        sampler=make_sampler(settings.seed),
        pruner=settings.pruner or settings.default_pruner(),
        load_if_exists=True,
    )
    seed = sampler_seed(settings.seed, len(study.get_trials(deepcopy=False)), worker)
    if seed != settings.seed:
        study.sampler = make_sampler(seed)
    return study


def finished_trials(study: Any) -> int:
    """:return: The study's complete and pruned trials."""
    optuna = import_optuna()
    states = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
    return len(study.get_trials(deepcopy=False, states=states))


def print_line(line: str) -> None:
    """:param line: Printed at once (a study's lines go to a log file, read while it runs)."""
    print(line, flush=True)


def optimize(settings: TuneSettings, threads: int | None = 1, log: Callable[[str], None] = print_line, worker: int = 0) -> Any:
    """
    Run trials in this process until the study has ``n_trials`` finished ones.

    :param settings: The study.
    :param threads: Torch threads (see :func:`~sb3_maddpg.common.torch_threads.use_torch_threads`).
    :param log: Where each trial's lines go: one per evaluation (its progress) and one when it ends.
    :param worker: This worker's number among those started together (its sampler's seed, :func:`sampler_seed`).
    :return: The study.
    """
    optuna = import_optuna()
    use_torch_threads(threads)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    study = load_study(settings, worker)

    def report(study: Any, trial: Any) -> None:
        value = "pruned" if trial.value is None else f"{settings.objective} {trial.value:.4f}"
        log(f"trial {trial.number}: {trial.state.name.lower()}, {value} ({finished_trials(study)}/{settings.n_trials})")

    stop = optuna.study.MaxTrialsCallback(
        settings.n_trials, states=(optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
    )
    if finished_trials(study) < settings.n_trials:
        study.optimize(lambda trial: run_trial(trial, settings, log), callbacks=[stop, report], gc_after_trial=True)
    return study


def _worker(settings: TuneSettings, threads: int | None, worker: int) -> None:
    optimize(settings, threads, log=lambda line: print(f"[worker {os.getpid()}] {line}", flush=True), worker=worker)


def run_study(
    settings: TuneSettings,
    workers: int = 1,
    backend: Literal["local", "ray"] = "local",
    threads: int | None = 1,
    address: str | None = None,
) -> Any:
    """
    Run the study with ``workers`` processes sharing its storage: this one, a local pool, or Ray tasks.

    :param settings: The study (its storage must be shared by the workers: SQLite for one machine).
    :param workers: Parallel workers.
    :param backend: ``"local"`` or ``"ray"``.
    :param threads: Torch threads per worker.
    :param address: The Ray cluster's address (``None``: a local Ray instance).
    :return: The study, reloaded after the workers finished.
    """
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}.")
    if backend == "ray":
        from sb3_maddpg.experiments.ray_tasks import ray_session  # Ray's code only for Ray's workers

        # As a sweep reaches Ray: a local instance's workers at normal priority, and shut down with the study.
        with ray_session(address, None, verbose=1) as ray:
            remote = ray.remote(num_cpus=threads or 1)(_worker)
            ray.get([remote.remote(settings, threads, worker) for worker in range(workers)])
    elif workers == 1:
        optimize(settings, threads)
    else:
        # The workers go with this process: Ctrl-C stops them, and a killed study (SIGTERM, SIGKILL) leaves no worker
        # training on: its trials stay "running" until their heartbeats go stale, and the resumed study retries each
        # once. Each worker sets its threads in optimize(), which refuses a bad count with a clear error.
        use_torch_threads(threads)  # the same check here, before any worker starts
        with worker_pool(workers, None) as pool:
            for future in [pool.submit(_worker, settings, threads, worker) for worker in range(workers)]:
                future.result()
    return load_study(settings)


def best_preset(study: Any, settings: TuneSettings) -> dict[str, Any]:
    """
    :param study: A study with a complete trial.
    :param settings: The study's settings.
    :return: The best trial as a preset (:mod:`~sb3_maddpg.experiments.presets`: YAML-ready, for ``sb3-maddpg run
        --config``): the experiment's fields with the trial's ``model_kwargs`` over its own, named ``<study>_best``
        (not ``<experiment>_tuned``: the package's own ``exp1_tuned`` and ``exp2_tuned`` presets hold those names and
        their results' directories), and a note on the study that found it.
    """
    best = study.best_trial
    model_kwargs = merge_model_kwargs(settings.experiment.model_kwargs, best.user_attrs["model_kwargs"])
    note = (
        f"{settings.experiment.name} with the best of {finished_trials(study)} trials of study "
        f"{settings.study_name!r} ({settings.objective} {best.value:.4f} over the last {settings.last_evaluations} of "
        f"{settings.n_evaluations} evaluations, {settings.budget:,} steps)"
    )
    tuned = dataclasses.replace(settings.experiment, name=f"{settings.study_name}_best", model_kwargs=model_kwargs)
    fields = {key: value for key, value in tuned.to_dict().items() if key not in ("name", "description")}
    return {"name": tuned.name, "note": note, **fields, VERSION_KEY: __version__}


def describe_best(study: Any, settings: TuneSettings) -> Sequence[str]:
    """:return: Lines saying the best trial's value, its parameters, and the preset."""
    best = study.best_trial
    direction = "lower" if settings.direction == "minimize" else "higher"
    return [
        f"best trial {best.number}: {settings.objective} {best.value:.4f} ({direction} is better) of "
        f"{finished_trials(study)} finished trials",
        "parameters: " + ", ".join(f"{key}={value}" for key, value in best.params.items()),
        "preset:",
        yaml.safe_dump(best_preset(study, settings), sort_keys=False, width=120).rstrip(),
    ]
