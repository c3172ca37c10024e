"""Where runs execute: one :class:`Backend` interface for every way a sweep runs its runs (in a local process pool,
:mod:`~sb3_maddpg.experiments.local_pool`; on Ray, :mod:`~sb3_maddpg.experiments.ray_tasks`; in run groups,
:mod:`~sb3_maddpg.experiments.batched`), chosen by name from :data:`BACKENDS`.
"""

import importlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

from sb3_maddpg.common.argument_ranges import Range
from sb3_maddpg.experiments.group_plan import check_runs_per_process
from sb3_maddpg.experiments.local_pool import OnResult, run_local
from sb3_maddpg.experiments.setting import RunConfig


@dataclass(frozen=True)
class Execution:
    """
    Where and how a sweep's runs execute (:func:`~sb3_maddpg.experiments.sweep.run_sweep`'s parameters of the same
    names).

    :param backend: The backend's name in :data:`BACKENDS`.
    :param workers: Parallel processes (local), or the CPUs of a local Ray instance (0: all).
    :param threads: Torch threads per run (or per run group).
    :param ray_address: The Ray cluster's address; ``None`` starts a local instance.
    :param device: Where the runs train, alone or in run groups (``"auto"``: CUDA when there is a GPU).
    :param runs_per_process: The most runs per group (``None``: all of a setting and scheme, or as many as fit).
    :param verbose: 1 to print each run's (or group's) progress.
    :param snapshots: Runs alone (local, Ray) save a snapshot at each tenth of their budget, which a killed run goes
        on from (:mod:`~sb3_maddpg.experiments.run_snapshot`); run groups save their own state regardless.
    :param compile: Run groups compile their rounds (``RunGroup(..., compile=True)``); None: where it was measured to
        pay (:func:`~sb3_maddpg.experiments.batched.compile_pays`).
    """

    backend: str = "local"
    workers: int = 1
    threads: int = 1
    ray_address: str | None = None
    device: str = "auto"
    runs_per_process: int | None = None
    verbose: int = 1
    snapshots: bool = True
    compile: bool | None = None

    def __post_init__(self) -> None:
        # Checked here, so that a dry run and a sweep refuse the same values before anything trains.
        local = self.backend == "local"
        workers_are = {"local": "parallel processes of the local backend", "batched": "unused by the batched backend"}
        meaning = workers_are.get(self.backend, f"CPUs of a local Ray instance, for the {self.backend} backend")
        Range(meaning, integer=True, low=1 if local else 0, hint="use 1" + ("" if local else ", or 0 for all CPUs")).check(
            "workers", self.workers
        )
        Range("torch threads per run or run group", integer=True, low=1, hint="use 1").check("threads", self.threads)
        check_runs_per_process(self.runs_per_process)

    @property
    def ray_cpus(self) -> int | None:
        """The CPUs of a local Ray instance (``None``: all of this machine's)."""
        return self.workers if self.workers > 0 else None


@dataclass
class SweepPlan:
    """
    What a sweep hands its backend, planned once: the runs to do in the units that execute together.

    :param results_dir: The sweep's results directory.
    :param units: Each unit's runs: a run alone, or a run group (whose runs end together).
    :param parallel: Runs executing at once (for the time-left estimate; a Ray backend sets it again once Ray is up).
    :param where: How the sweep log says where the runs execute (e.g. ``"with 2 worker(s) x 1 thread(s)"``).
    :param notes: Lines for the sweep log, said once it is open (e.g. a setting's seeds split to fit the memory).
    """

    results_dir: str
    units: list[list[RunConfig]]
    parallel: int
    where: str
    notes: list[str] = field(default_factory=list)

    @property
    def runs(self) -> list[RunConfig]:
        """Every run to do, in the sweep's order."""
        return [config for unit in self.units for config in unit]


class SweepLog(Protocol):
    """What a backend tells the sweep as it runs (:class:`~sb3_maddpg.experiments.sweep.SweepProgress`)."""

    parallel: int

    def log(self, line: str) -> None:
        """:param line: A line for stdout and the sweep log."""


class Backend(Protocol):
    """
    One way to execute a sweep's runs. The sweep calls, in order: :meth:`check` (before anything is written),
    :meth:`plan` (once), then :meth:`run`.
    """

    name: str
    """Its name in :data:`BACKENDS` and in the sweep log."""

    def check(self, runs: Sequence[RunConfig]) -> None:
        """
        :param runs: The runs to do.
        :raise ValueError: For runs or settings this backend cannot execute (before anything is written).
        """

    def plan(self, runs: Sequence[RunConfig], results_dir: str) -> SweepPlan:
        """
        :param runs: The runs to do (checked).
        :param results_dir: The sweep's results directory.
        :return: The plan to :meth:`run`.
        """

    def run(self, plan: SweepPlan, on_result: OnResult, progress: SweepLog) -> None:
        """
        Execute the plan's runs, each reported as it ends.

        :param plan: What :meth:`plan` returned.
        :param on_result: Called as each run ends.
        :param progress: The sweep's log (a line when a worker dies, how many runs execute at once).
        """


@dataclass(frozen=True)
class BackendEntry:
    """
    A backend in :data:`BACKENDS`.

    :param target: ``"module:Class"``, imported when the backend is made (a class taking an :class:`Execution`).
    :param help: What it is (``sb3-maddpg run --help`` lists it).
    """

    target: str
    help: str


BACKENDS: dict[str, BackendEntry] = {
    "local": BackendEntry("sb3_maddpg.experiments.backends:LocalBackend", "a local process pool of workers"),
    "ray": BackendEntry("sb3_maddpg.experiments.backends:RayBackend", "one Ray task per run"),
    "batched": BackendEntry(
        "sb3_maddpg.experiments.batched:GroupBackend",
        "a setting and scheme's seeds trained together in this process (run groups, fixed schemes on the batched "
        "simple_spread env; on the device, runs_per_process at most per group)",
    ),
    "batched-ray": BackendEntry(
        "sb3_maddpg.experiments.batched:GroupRayBackend",
        "run groups as Ray tasks, one each (a GPU each on a CUDA device, else threads CPUs)",
    ),
}
"""The backends by name: the one registry that sweeps and ``sb3-maddpg run --backend`` read."""


def make_backend(execution: Execution) -> Backend:
    """
    :param execution: Where and how the runs execute; its ``backend`` names one of :data:`BACKENDS`.
    :return: That backend.
    :raise ValueError: For a name not in :data:`BACKENDS`.
    """
    if execution.backend not in BACKENDS:
        raise ValueError(f"Unknown backend {execution.backend!r}; use one of {tuple(BACKENDS)}.")
    module, _, name = BACKENDS[execution.backend].target.partition(":")
    backend: Backend = getattr(importlib.import_module(module), name)(execution)
    return backend


class RunsBackend:
    """
    What the backends that execute each run alone share: any run is executed (by the runner), one unit per run.

    :param execution: Where and how the runs execute.
    """

    name = "runs"

    def __init__(self, execution: Execution) -> None:
        self.execution = execution

    def check(self, runs: Sequence[RunConfig]) -> None:
        """:param runs: The runs to do (the runner executes any)."""

    def parallel(self) -> int:
        """:return: The runs that execute at once, as far as known before the backend starts."""
        raise NotImplementedError

    def plan(self, runs: Sequence[RunConfig], results_dir: str) -> SweepPlan:
        """
        :param runs: The runs to do.
        :param results_dir: The sweep's results directory.
        :return: One unit per run, :meth:`parallel` at once.
        """
        how = f"with {self.execution.workers} worker(s) x {self.execution.threads} thread(s)"
        return SweepPlan(results_dir, [[run] for run in runs], self.parallel(), how)


class LocalBackend(RunsBackend):
    """
    Runs in this process (one worker) or a local process pool (:func:`~sb3_maddpg.experiments.local_pool.run_local`).

    :param execution: Where and how the runs execute.
    """

    name = "local"

    def check(self, runs: Sequence[RunConfig]) -> None:
        """
        :param runs: The runs to do.
        :raise BatchedRunRefused: For a ``device`` this machine cannot train on (before anything is written).
        """
        from sb3_maddpg.experiments.group_plan import check_device

        if runs:
            check_device(self.execution.device)

    def parallel(self) -> int:
        """:return: The pool's workers."""
        return self.execution.workers

    def run(self, plan: SweepPlan, on_result: OnResult, progress: SweepLog) -> None:
        """See :meth:`Backend.run`."""
        execution = self.execution
        run_local(
            plan.runs,
            plan.results_dir,
            on_result,
            workers=execution.workers,
            threads=execution.threads,
            verbose=execution.verbose,
            log=progress.log,
            snapshots=execution.snapshots,
            device=execution.device,
        )


class RayBackend(RunsBackend):
    """
    Runs as Ray tasks, one per run (:func:`~sb3_maddpg.experiments.ray_tasks.run_ray`).

    :param execution: Where and how the runs execute.
    """

    name = "ray"

    def parallel(self) -> int:
        """
        :return: A first guess, ``workers // threads``; the runs at once are known once Ray is up
            (``workers=0``: all CPUs).
        """
        return max(1, self.execution.workers) // max(1, self.execution.threads)

    def run(self, plan: SweepPlan, on_result: OnResult, progress: SweepLog) -> None:
        """See :meth:`Backend.run`."""
        execution = self.execution

        def on_parallel(slots: int) -> None:
            progress.parallel = slots
            progress.log(f"Ray: {slots} run(s) at once ({execution.threads} CPU(s) each)")

        from sb3_maddpg.experiments.ray_tasks import run_ray  # Ray's code, for Ray's backend only

        run_ray(
            plan.runs,
            plan.results_dir,
            on_result,
            address=execution.ray_address,
            threads=execution.threads,
            num_cpus=execution.ray_cpus,
            verbose=execution.verbose,
            on_parallel=on_parallel,
            snapshots=execution.snapshots,
            device=execution.device,
        )
