"""What trained a run (device, threads, runs trained together), recorded in its summary for the study's cost."""

import dataclasses
from typing import Any

from sb3_maddpg.common.torch_threads import package_threads


@dataclasses.dataclass(frozen=True)
class TrainingResources:
    """
    What trained a run, as its summary records it.

    :param device: The device type its networks trained on (``"cpu"``, ``"cuda"``).
    :param torch_threads: The intra-op threads of its process (``torch.get_num_threads()``).
    :param runs_trained_together: Runs trained in the same process at once (a run group's size; 1 alone).
    """

    device: str
    torch_threads: int
    runs_trained_together: int = 1

    @classmethod
    def here(cls, device: str, runs_trained_together: int = 1) -> "TrainingResources":
        """
        :param device: The device type the run trained on.
        :param runs_trained_together: Runs trained in this process at once.
        :return: This process's resources, with the threads ``learn()`` trains on here (:func:`package_threads`: one
            unless the user chose a count).
        """
        with package_threads() as threads:
            return cls(device, threads, runs_trained_together)

    def to_summary(self) -> dict[str, Any]:
        """:return: The summary's fields."""
        return dataclasses.asdict(self)
