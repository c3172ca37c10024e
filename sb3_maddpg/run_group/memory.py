"""How many runs one group can hold: the replay buffers bound it, on the group's device and, while the group's state
is saved, in host memory (networks and batches are small beside them: 64-unit networks, batches of 1024)."""

import os
from dataclasses import dataclass

import torch as th

from sb3_maddpg.maddpg import MADDPG
from sb3_maddpg.run_group.buffer import buffer_capacity, replay_nbytes
from sb3_maddpg.run_group.worlds import SpreadTask

MEMORY_FRACTION = 0.8
"""The share of a device's (and the host's) total memory the groups' replay buffers may fill: the rest is for the
networks, batches, the CUDA context and the process itself."""


def run_buffer_nbytes(model: MADDPG) -> int:
    """
    :param model: A model a group would be built from (its env, ``buffer_size`` and selector).
    :return: The bytes of one run's replay buffer in a group (:func:`~sb3_maddpg.run_group.buffer.replay_nbytes`).
    """
    env, layout = model.get_env(), model.agent_layout
    if env is None or layout is None:
        raise ValueError(
            "The model has no env, but a group's buffers are sized from the env's team and worlds: build the model "
            "with its env, or give it one with model.set_env(env)."
        )
    worlds = env.num_envs
    task = SpreadTask.from_env(env)
    return replay_nbytes(
        1,
        buffer_capacity(model.buffer_size, worlds),
        layout.obs_dim,
        layout.action_dim,
        layout.n_agents,
        rows_per_step=worlds,
        episode_length=1 if task is None else task.max_cycles,
        selection_size=0 if model.selector is None else model.selector.k,
    )


def host_memory() -> int:
    """:return: This machine's physical memory in bytes."""
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def device_memory(device: th.device) -> int:
    """
    :param device: A device.
    :return: Its total memory in bytes (the host's for the CPU).
    """
    if device.type == "cuda":
        return int(th.cuda.get_device_properties(device).total_memory)
    return host_memory()


@dataclass(frozen=True)
class GroupSize:
    """
    The most runs of one setting and scheme that one group holds, and why.

    :param runs: The most runs (at least 1).
    :param run_bytes: One run's replay buffer.
    :param limit: What bounds it, in words (e.g. ``"80% of cuda:0's 150.1 GB"``; GB are 10^9 bytes).
    """

    runs: int
    run_bytes: int
    limit: str


def runs_that_fit(model: MADDPG, device: th.device | str, host_bytes: int | None = None) -> GroupSize:
    """
    The most runs like ``model`` one group holds on ``device``: :data:`MEMORY_FRACTION` of the device's total memory
    over one run's buffer; on a GPU also of the host's (a save copies the state to the host), on the CPU half of it
    (a save of partly filled buffers copies their rows). From total, not free, memory: the same machine plans the same
    groups on every attempt, so a resumed sweep finds its groups' state files.

    :param model: A model the group's runs would be built from.
    :param device: The group's device.
    :param host_bytes: The host's memory (default: :func:`host_memory`).
    :return: The size and what bounds it.
    :raise ValueError: When not even one run's buffer fits, naming the sizes and what to do.
    """
    device = th.device(device)
    run_bytes = run_buffer_nbytes(model)
    host = host_memory() if host_bytes is None else host_bytes
    limits = [(host * MEMORY_FRACTION / 2, f"40% of the host's {host / 1e9:.1f} GB (the buffers and a save's copy)")]
    if device.type == "cuda":
        total = device_memory(device)
        limits = [
            (total * MEMORY_FRACTION, f"80% of {device}'s {total / 1e9:.1f} GB"),
            (host * MEMORY_FRACTION, f"80% of the host's {host / 1e9:.1f} GB (a save's copy)"),
        ]
    budget, limit = min(limits)
    runs = int(budget // run_bytes)
    if runs < 1:
        raise ValueError(
            f"One run's replay buffer ({run_bytes / 1e9:.2f} GB) does not fit in {limit}: lower the runs' buffer_size "
            '(model_kwargs={"buffer_size": ...}), or train on a device with more memory.'
        )
    return GroupSize(runs, run_bytes, limit)
