"""Many MADDPG (or MATD3) runs in one process, on one device: ``R`` independent runs (seeds) trained together.

64-unit networks at batch 1024 leave a GPU idle; ``R`` runs stacked along a run dimension fill it. The parts, one job
each: :mod:`~sb3_maddpg.run_group.stacked` (the runs' networks stacked, evaluated with ``vmap``),
:mod:`~sb3_maddpg.run_group.stacked_adam` (their Adam, as tensors),
:mod:`~sb3_maddpg.run_group.buffer` (the runs' replay buffers on the device), :mod:`~sb3_maddpg.run_group.worlds`
(the runs' simple_spread worlds in torch), :mod:`~sb3_maddpg.run_group.selection` (selections on the device),
:mod:`~sb3_maddpg.run_group.streams` (each run's random numbers, every run's in one call),
:mod:`~sb3_maddpg.run_group.checks` (what a group refuses) and :mod:`~sb3_maddpg.run_group.trainer`
(:class:`RunGroup`: the algorithms' own update step with ``M = R``, the data loop, the way back into models).
"""

from sb3_maddpg.common.train_logs import LOSS_NAMES
from sb3_maddpg.run_group.buffer import RunReplayBuffers
from sb3_maddpg.run_group.stacked import StackedModule, StackedTeams
from sb3_maddpg.run_group.stacked_adam import StackedAdam
from sb3_maddpg.run_group.streams import RunStreams
from sb3_maddpg.run_group.trainer import GroupCallback, RunGroup
from sb3_maddpg.run_group.worlds import SpreadRuns, SpreadTask

__all__ = [
    "LOSS_NAMES",
    "GroupCallback",
    "RunGroup",
    "RunReplayBuffers",
    "RunStreams",
    "SpreadRuns",
    "SpreadTask",
    "StackedAdam",
    "StackedModule",
    "StackedTeams",
]
