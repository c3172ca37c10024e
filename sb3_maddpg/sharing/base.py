"""The base class of every information-sharing scheme: what critic i sees, built from the joint batch."""

from typing import ClassVar

import torch as th
from torch import nn

from sb3_maddpg.common.layout import AgentLayout


class CriticFeaturesExtractor(nn.Module):
    """
    Base class: builds critic ``agent_index``'s input from the joint batch, in the spirit of SB3's
    ``BaseFeaturesExtractor``. It may hold parameters (they train with the critic and have target
    copies); the built-in schemes have none.

    Subclasses take ``(layout, agent_index, selection_size=0, **kwargs)`` and pass their
    ``features_dim`` to this constructor.

    :param layout: The team's agent layout.
    :param agent_index: Which agent's critic this extractor feeds.
    :param features_dim: Length of the features it returns.
    :param selection_size: ``k``, the number of selected agents per agent (0 when unused).
    """

    uses_selection: ClassVar[bool] = False
    """Whether :meth:`forward` reads the stored selection (then MADDPG makes and stores one)."""

    recording: bool = False
    """True while MADDPG's critic update runs its forward pass: what an extractor reports in :meth:`diagnostics`
    should come from those batches (replayed actions), not from the actor update's or the targets'."""

    def __init__(self, layout: AgentLayout, agent_index: int, features_dim: int, selection_size: int = 0) -> None:
        super().__init__()
        check_agent_index(layout, agent_index)
        if features_dim < 1:
            raise ValueError(f"features_dim must be positive, got {features_dim}.")
        self.layout = layout
        self.agent_index = int(agent_index)
        self.selection_size = int(selection_size)
        self._features_dim = int(features_dim)

    @classmethod
    def check_layout(cls, layout: AgentLayout) -> None:
        """
        Raise a clear error if this scheme cannot serve the team; MADDPG calls it before anything else about the
        scheme (the selection included), so that the real cause comes first. Every team fits by default.

        :param layout: The team's agent layout.
        """

    @property
    def features_dim(self) -> int:
        """Length of the critic input this extractor builds."""
        return self._features_dim

    def diagnostics(self) -> dict[str, float]:
        """
        Summaries of what this extractor did on the last critic update's batch, recorded by MADDPG each time it writes
        the logs, as ``train/<agent_id>/<key>`` (and their team mean as ``train/<key>``). None by default.

        :return: Names and values.
        """
        return {}

    def forward(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        """
        :param observations: Joint observations ``[batch, obs_dim]``.
        :param actions: Joint actions in the policy's [-1, 1] space ``[batch, action_dim]``.
        :param selections: Selected agents ``[batch, n_agents, k]`` (LongTensor), for schemes that use it.
        :return: Critic input ``[batch, features_dim]``.
        """
        raise NotImplementedError

    def agent_observation(self, observations: th.Tensor, agent: int) -> th.Tensor:
        """Agent ``agent``'s part of the joint observation, ``[batch, obs_size]``."""
        return observations[:, self.layout.obs_slices[agent]]

    def agent_action(self, actions: th.Tensor, agent: int) -> th.Tensor:
        """Agent ``agent``'s part of the joint action, ``[batch, action_size]``."""
        return actions[:, self.layout.action_slices[agent]]


def check_agent_index(layout: AgentLayout, agent_index: int) -> None:
    """Refuse an agent index outside the team."""
    if not 0 <= agent_index < layout.n_agents:
        raise ValueError(f"agent_index {agent_index} is out of range for a team of {layout.n_agents} agents.")
