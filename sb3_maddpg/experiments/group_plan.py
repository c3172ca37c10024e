"""Which of a sweep's runs train together in run groups (the batched backends), and the checks that refuse, before
anything trains, the runs and devices a group cannot train on."""

import json
from collections.abc import Callable, Sequence

import torch as th

from sb3_maddpg.experiments.defaults import DEFAULT_ENV
from sb3_maddpg.experiments.runner import build_model
from sb3_maddpg.experiments.setting import RunConfig
from sb3_maddpg.experiments.tasks import run_task

BATCHED_HINT = (
    'Train such runs on the local backend (backend="local"), e.g. in a second sweep, leaving their schemes out of this '
    "one's experiments."
)


class BatchedRunRefused(ValueError):
    """
    A sweep refused before anything trains: a device this machine or Ray cluster lacks, or a run that cannot train in a
    run group (the message names it, the cause, and what to do).
    """


def group_key(config: RunConfig) -> str:
    """:return: What runs of one group have in common: their whole config but the seed (as JSON)."""
    return json.dumps({key: value for key, value in config.to_dict().items() if key != "seed"}, sort_keys=True)


def plan_groups(
    configs: Sequence[RunConfig],
    runs_per_process: int | None = None,
    most_runs: Callable[[Sequence[RunConfig]], int] | None = None,
) -> list[list[RunConfig]]:
    """
    :param configs: The runs to do.
    :param runs_per_process: The most runs in one group (``None``: all that share a setting and scheme, or as many as
        ``most_runs`` allows).
    :param most_runs: When ``runs_per_process`` is ``None``: the most runs of a setting and scheme one group holds,
        given those runs (e.g. :func:`memory_bound`).
    :return: The groups, each the runs of one setting and scheme (different seeds), in the sweep's order.
    """
    check_runs_per_process(runs_per_process)
    buckets: dict[str, list[RunConfig]] = {}
    for config in configs:
        buckets.setdefault(group_key(config), []).append(config)
    groups = []
    for runs in buckets.values():
        size = runs_per_process or (len(runs) if most_runs is None else max(1, min(len(runs), most_runs(runs))))
        groups += [runs[start : start + size] for start in range(0, len(runs), size)]
    return groups


def check_runs_per_process(runs_per_process: int | None) -> None:
    """
    :param runs_per_process: The most runs in one group, or ``None``.
    :raise ValueError: For fewer than one.
    """
    if runs_per_process is not None and runs_per_process < 1:
        raise ValueError(f"runs_per_process must be at least 1, got {runs_per_process}: e.g. 31 (one scheme's seeds).")


def too_large_groups(groups: Sequence[Sequence[RunConfig]], fits: Callable[[Sequence[RunConfig]], int]) -> list[str]:
    """
    :param groups: Groups of a size given by ``runs_per_process`` (:func:`plan_groups`).
    :param fits: The most runs one group holds (:func:`memory_bound`).
    :return: A warning for each setting and scheme whose groups may not fit, said by its first (largest) group.
    """
    warnings: dict[str, str] = {}
    for group in groups:
        setting = f"{group[0].experiment}/{group[0].scheme}"
        if setting not in warnings and len(group) > fits(group):
            warnings[setting] = (
                f"{setting}: groups of {len(group)} runs (runs_per_process) may not fit in memory: {fits(group)} fit "
                "by the package's estimate; lower runs_per_process if the sweep runs out of memory"
            )
    return list(warnings.values())


def resolve_device(device: str) -> th.device:
    """
    :param device: The device asked for: ``"auto"``, ``"cpu"``, ``"cuda"`` or ``"cuda:<index>"``.
    :return: The device a group trains on (``"auto"``: CUDA when there is a GPU, else the CPU).
    """
    if device == "auto":
        return th.device("cuda" if th.cuda.is_available() else "cpu")
    return th.device(device)


def memory_bound(device: str, log: Callable[[str], None] | None = None) -> Callable[[Sequence[RunConfig]], int]:
    """
    :param device: The groups' device (``"auto"``, ``"cpu"``, ``"cuda"`` or ``"cuda:<index>"``).
    :param log: Called with a line for each setting and scheme whose seeds do not fit in one group.
    :return: For :func:`plan_groups`: the most of given runs (one setting and scheme) that one group holds on that device
        (:func:`~sb3_maddpg.run_group.memory.runs_that_fit`: their replay buffers bound it).
    """
    from sb3_maddpg.run_group.memory import runs_that_fit

    sizes: dict[str, int] = {}  # by group key: each setting and scheme's model is built and said once

    def most_runs(runs: Sequence[RunConfig]) -> int:
        config = runs[0]
        key = group_key(config)
        if key not in sizes:
            model = build_model(run_task(config), device="cpu")
            try:
                size = runs_that_fit(model, resolve_device(device))
            finally:
                model.get_env().close()
            if log is not None and size.runs < len(runs):
                log(
                    f"{config.experiment}/{config.scheme}: groups of at most {size.runs} runs (each run's replay buffer "
                    f"{size.run_bytes / 1e9:.2f} GB; bound: {size.limit}); runs_per_process sets another size"
                )
            sizes[key] = size.runs
        return sizes[key]

    return most_runs


def check_device(device: str) -> None:
    """
    Refuse a device the runs (alone or in groups) cannot train on here, before anything is written (every run would
    fail after its directory was started afresh).

    :param device: The device asked for: ``"auto"``, ``"cpu"``, ``"cuda"`` or ``"cuda:<index>"``.
    :raise BatchedRunRefused: For a device that is not one, or a CUDA device this machine does not have.
    """
    try:
        resolved = th.device(device) if device != "auto" else None
    except (RuntimeError, TypeError) as error:
        raise BatchedRunRefused(
            f'device {device!r} is not a device torch knows ({error}): use "cpu", "cuda" or "auto".'
        ) from None
    if resolved is None or resolved.type != "cuda":
        return
    if not th.cuda.is_available():
        raise BatchedRunRefused(
            f'CUDA is not available on this machine, so the runs cannot train on {device}: use device="cpu" or '
            '"auto" (or the ray or batched-ray backend, to train on a Ray cluster\'s GPUs).'
        )
    if resolved.index is not None and resolved.index >= th.cuda.device_count():
        raise BatchedRunRefused(
            f'This machine has {th.cuda.device_count()} CUDA device(s), so there is no {device}: use device="cuda" '
            f"(device 0), or an index below {th.cuda.device_count()}."
        )


def check_batched(configs: Sequence[RunConfig], device: str | None = None) -> None:
    """
    Refuse, before anything trains, the runs a run group cannot train: the first such run is named, with the cause
    and what to do. One model of each setting and scheme is built and checked as :class:`RunGroup` checks its models,
    and, given a device, for one run's replay buffer fitting in its memory
    (:func:`~sb3_maddpg.run_group.memory.runs_that_fit`).

    :param configs: The runs to do.
    :param device: The groups' device, checked first (:func:`check_device`) when there are runs; ``None``: not
        checked (e.g. under Ray, where the tasks' machines have the GPUs).
    :raise BatchedRunRefused: For the device, or the first run refused.
    """
    from sb3_maddpg.run_group import SpreadTask
    from sb3_maddpg.run_group.checks import check_models
    from sb3_maddpg.run_group.memory import runs_that_fit

    if device is not None and configs:
        check_device(device)
    firsts: dict[str, RunConfig] = {}
    for config in configs:
        firsts.setdefault(group_key(config), config)  # one model of each setting and scheme is checked
    for config in firsts.values():
        if config.env != DEFAULT_ENV or config.vec_env != "batched":
            cause = (
                f"it trains on {config.env} (vec_env {config.vec_env!r}), but a run group steps simple_spread's batched "
                "worlds only (env 'simple_spread', vec_env 'batched')."
            )
        else:
            model = build_model(run_task(config), device="cpu")
            try:
                check_models([model])
                cause = "" if SpreadTask.from_env(model.get_env()) is not None else "its env tells no simple_spread task."
                if device is not None and not cause:
                    runs_that_fit(model, resolve_device(device))  # one run's buffers at least
            except (TypeError, ValueError) as error:
                cause = str(error)
            model.get_env().close()
        if cause:
            raise BatchedRunRefused(
                f"{config.run_id} (and its other seeds) cannot train in a run group (the batched backends): {cause} "
                + BATCHED_HINT
            )
