"""The paper's five schemes (Table 1): critics that see fixed parts of the joint batch, or the selected agents'.

Critic i of MADDPG sees a vector x_i built from the joint observation, the joint action and (for
selected sharing) the agents it selected. Each scheme of the paper (Table 1) is a subclass of
:class:`CriticFeaturesExtractor`; a new scheme is a new subclass.

The input order is stable, own agent first:

============== ======= ===================================================================
scheme         paper   x_i
============== ======= ===================================================================
independent    IDDPG   ``[o_i, a_i]``
full           MADDPG  ``[o_i, o_others..., a_i, a_others...]`` (others in ascending index)
observations   fo      ``[o_i, o_others..., a_i]``
actions        fa      ``[o_i, a_i, a_others...]``
selected       soa     ``[o_i, o_s1 .. o_sk, a_i, a_s1 .. a_sk]`` (selection order, nearest first)
============== ======= ===================================================================

So critic i's input is critic 0's with agent i called agent 0 (the others keeping their order): one critic network
shared by interchangeable agents (``share_parameters=True``) reads the same thing in the same place for each.
"""

from collections.abc import Sequence

import torch as th

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.networks import stack_padded
from sb3_maddpg.sharing.base import CriticFeaturesExtractor, check_agent_index


class _FixedAgentsCriticFeatures(CriticFeaturesExtractor):
    """Sees the observations of ``obs_agents`` and the actions of ``action_agents``, in that order (one gather each)."""

    _obs_index: th.Tensor
    _action_index: th.Tensor

    def __init__(
        self,
        layout: AgentLayout,
        agent_index: int,
        obs_agents: Sequence[int],
        action_agents: Sequence[int],
        selection_size: int,
    ) -> None:
        check_agent_index(layout, agent_index)
        obs_index = [d for j in obs_agents for d in range(layout.obs_slices[j].start, layout.obs_slices[j].stop)]
        action_index = [d for j in action_agents for d in range(layout.action_slices[j].start, layout.action_slices[j].stop)]
        super().__init__(layout, agent_index, len(obs_index) + len(action_index), selection_size)
        self.obs_agents = tuple(obs_agents)
        self.action_agents = tuple(action_agents)
        self.register_buffer("_obs_index", th.tensor(obs_index, dtype=th.long), persistent=False)
        self.register_buffer("_action_index", th.tensor(action_index, dtype=th.long), persistent=False)

    def forward(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        return th.cat((observations.index_select(1, self._obs_index), actions.index_select(1, self._action_index)), dim=1)


def _own_first(layout: AgentLayout, agent_index: int) -> list[int]:
    return [agent_index] + [j for j in range(layout.n_agents) if j != agent_index]


class IndependentCriticFeatures(_FixedAgentsCriticFeatures):
    """IDDPG: critic i sees ``[o_i, a_i]`` only."""

    def __init__(self, layout: AgentLayout, agent_index: int, selection_size: int = 0) -> None:
        super().__init__(layout, agent_index, [agent_index], [agent_index], selection_size)


class FullCriticFeatures(_FixedAgentsCriticFeatures):
    """MADDPG: critic i sees every observation and every action, ``[o_i, o_others..., a_i, a_others...]``."""

    def __init__(self, layout: AgentLayout, agent_index: int, selection_size: int = 0) -> None:
        order = _own_first(layout, agent_index)
        super().__init__(layout, agent_index, order, order, selection_size)


class ObservationsCriticFeatures(_FixedAgentsCriticFeatures):
    """MADDPG-fo (Algorithm 1): critic i sees every observation and its own action, ``[o_i, o_others..., a_i]``."""

    def __init__(self, layout: AgentLayout, agent_index: int, selection_size: int = 0) -> None:
        super().__init__(layout, agent_index, _own_first(layout, agent_index), [agent_index], selection_size)


class ActionsCriticFeatures(_FixedAgentsCriticFeatures):
    """MADDPG-fa (Algorithm 2): critic i sees its own observation and every action, ``[o_i, a_i, a_others...]``."""

    def __init__(self, layout: AgentLayout, agent_index: int, selection_size: int = 0) -> None:
        super().__init__(layout, agent_index, [agent_index], _own_first(layout, agent_index), selection_size)


class SelectedCriticFeatures(CriticFeaturesExtractor):
    """
    MADDPG-soa (Algorithm 3): critic i sees its own observation and action and those of the ``k``
    agents it selected, ``[o_i, o_s1 .. o_sk, a_i, a_s1 .. a_sk]`` in selection order. The selection
    is the one stored with the transition. On a team of unequal agents every observation is zero-padded to the
    largest observation and every action to the largest action, so that each slot has one size whoever fills it.
    """

    uses_selection = True

    @classmethod
    def check_layout(cls, layout: AgentLayout) -> None:
        """Refuse a team with no other agent to select."""
        if layout.n_agents < 2:
            raise ValueError(f"critic_sharing='selected' needs at least 2 agents, got {layout.n_agents}.")

    def __init__(self, layout: AgentLayout, agent_index: int, selection_size: int = 2) -> None:
        self.check_layout(layout)
        if not 1 <= selection_size <= layout.n_agents - 1:
            raise ValueError(f"selection_size must be between 1 and {layout.n_agents - 1}, got {selection_size}.")
        obs_size, action_size = max(layout.obs_sizes), max(layout.action_sizes)
        super().__init__(layout, agent_index, (1 + selection_size) * (obs_size + action_size), selection_size)
        self._obs_size, self._action_size = obs_size, action_size

    def forward(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        if selections is None:
            raise ValueError("critic_sharing='selected' needs the selection [batch, n_agents, k] of each transition.")
        batch, n_agents, k = observations.shape[0], self.layout.n_agents, self.selection_size
        chosen = selections[:, self.agent_index, :]
        # Own agent first, then the selected ones, for observations and for actions alike.
        agents = th.cat((th.full_like(chosen[:, :1], self.agent_index), chosen), dim=1)
        if self.layout.is_homogeneous:
            obs = observations.view(batch, n_agents, self._obs_size)
            act = actions.reshape(batch, n_agents, self._action_size)
        else:
            # Each agent's part zero-padded to the largest, [batch, n_agents, width].
            obs = stack_padded([observations[:, part] for part in self.layout.obs_slices], self._obs_size).transpose(0, 1)
            act = stack_padded([actions[:, part] for part in self.layout.action_slices], self._action_size).transpose(0, 1)
        seen_obs = obs.gather(1, agents.unsqueeze(-1).expand(batch, k + 1, self._obs_size))
        seen_act = act.gather(1, agents.unsqueeze(-1).expand(batch, k + 1, self._action_size))
        return th.cat((seen_obs.reshape(batch, -1), seen_act.reshape(batch, -1)), dim=1)
