"""What each critic sees: the information-sharing schemes as critic features extractors.

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
"""

from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import torch as th
from torch import nn

from sb3_maddpg.layout import AgentLayout


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
        _check_agent_index(layout, agent_index)
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

    def forward(self, observations: th.Tensor, actions: th.Tensor, selection: th.Tensor | None = None) -> th.Tensor:
        """
        :param observations: Joint observations ``[batch, obs_dim]``.
        :param actions: Joint actions in the policy's [-1, 1] space ``[batch, action_dim]``.
        :param selection: Selected agents ``[batch, n_agents, k]`` (LongTensor), for schemes that use it.
        :return: Critic input ``[batch, features_dim]``.
        """
        raise NotImplementedError

    def agent_observation(self, observations: th.Tensor, agent: int) -> th.Tensor:
        """Agent ``agent``'s part of the joint observation, ``[batch, obs_size]``."""
        return observations[:, self.layout.obs_slices[agent]]

    def agent_action(self, actions: th.Tensor, agent: int) -> th.Tensor:
        """Agent ``agent``'s part of the joint action, ``[batch, action_size]``."""
        return actions[:, self.layout.action_slices[agent]]


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
        _check_agent_index(layout, agent_index)
        obs_index = [d for j in obs_agents for d in range(layout.obs_slices[j].start, layout.obs_slices[j].stop)]
        action_index = [d for j in action_agents for d in range(layout.action_slices[j].start, layout.action_slices[j].stop)]
        super().__init__(layout, agent_index, len(obs_index) + len(action_index), selection_size)
        self.obs_agents = tuple(obs_agents)
        self.action_agents = tuple(action_agents)
        self.register_buffer("_obs_index", th.tensor(obs_index, dtype=th.long), persistent=False)
        self.register_buffer("_action_index", th.tensor(action_index, dtype=th.long), persistent=False)

    def forward(self, observations: th.Tensor, actions: th.Tensor, selection: th.Tensor | None = None) -> th.Tensor:
        return th.cat((observations.index_select(1, self._obs_index), actions.index_select(1, self._action_index)), dim=1)


def _check_agent_index(layout: AgentLayout, agent_index: int) -> None:
    if not 0 <= agent_index < layout.n_agents:
        raise ValueError(f"agent_index {agent_index} is out of range for a team of {layout.n_agents} agents.")


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

    def __init__(self, layout: AgentLayout, agent_index: int, selection_size: int = 2) -> None:
        self.check_layout(layout)
        if not 1 <= selection_size <= layout.n_agents - 1:
            raise ValueError(f"selection_size must be between 1 and {layout.n_agents - 1}, got {selection_size}.")
        obs_size, action_size = max(layout.obs_sizes), max(layout.action_sizes)
        super().__init__(layout, agent_index, (1 + selection_size) * (obs_size + action_size), selection_size)
        self._obs_size, self._action_size = obs_size, action_size

    def forward(self, observations: th.Tensor, actions: th.Tensor, selection: th.Tensor | None = None) -> th.Tensor:
        if selection is None:
            raise ValueError("critic_sharing='selected' needs the selection [batch, n_agents, k] of each transition.")
        batch, n_agents, k = observations.shape[0], self.layout.n_agents, self.selection_size
        chosen = selection[:, self.agent_index, :]
        # Own agent first, then the selected ones, for observations and for actions alike.
        agents = th.cat((th.full_like(chosen[:, :1], self.agent_index), chosen), dim=1)
        if self.layout.is_homogeneous:
            obs = observations.view(batch, n_agents, self._obs_size)
            act = actions.reshape(batch, n_agents, self._action_size)
        else:
            obs = _padded_per_agent(observations, self.layout.obs_slices, self._obs_size)
            act = _padded_per_agent(actions, self.layout.action_slices, self._action_size)
        seen_obs = obs.gather(1, agents.unsqueeze(-1).expand(batch, k + 1, self._obs_size))
        seen_act = act.gather(1, agents.unsqueeze(-1).expand(batch, k + 1, self._action_size))
        return th.cat((seen_obs.reshape(batch, -1), seen_act.reshape(batch, -1)), dim=1)


def _padded_per_agent(joint: th.Tensor, slices: Sequence[slice], width: int) -> th.Tensor:
    """``[batch, n_agents, width]``: each agent's part of a joint vector, zero-padded to ``width``."""
    parts = [joint[:, part] for part in slices]
    return th.stack([nn.functional.pad(part, (0, width - part.shape[1])) for part in parts], dim=1)


SHARING_SCHEMES: dict[str, type[CriticFeaturesExtractor]] = {
    "independent": IndependentCriticFeatures,
    "full": FullCriticFeatures,
    "observations": ObservationsCriticFeatures,
    "actions": ActionsCriticFeatures,
    "selected": SelectedCriticFeatures,
}
"""The built-in schemes by name."""

SCHEME_ALIASES: dict[str, str] = {
    "iddpg": "independent",
    "maddpg": "full",
    "fo": "observations",
    "fa": "actions",
    "soa": "selected",
}
"""The paper's short names for the built-in schemes."""


def learned_schemes() -> dict[str, type[CriticFeaturesExtractor]]:
    """
    :return: The schemes whose critics learn whom to listen to (:mod:`sb3_maddpg.attention`): ``"attention"`` and
        ``"learned_selection"``.
    """
    # Imported here: sb3_maddpg.attention builds on this module.
    from sb3_maddpg.attention import AttentionCriticFeatures, LearnedSelectionCriticFeatures

    return {"attention": AttentionCriticFeatures, "learned_selection": LearnedSelectionCriticFeatures}


def resolve_scheme(scheme: Any) -> type[CriticFeaturesExtractor]:
    """
    The extractor class for a scheme name, a paper alias or a user's subclass.

    :param scheme: ``"independent"``, ``"full"``, ``"observations"``, ``"actions"``, ``"selected"``,
        ``"attention"``, ``"learned_selection"``, one of the aliases in :data:`SCHEME_ALIASES`, or a
        :class:`CriticFeaturesExtractor` subclass.
    :return: The class.
    """
    if isinstance(scheme, type) and issubclass(scheme, CriticFeaturesExtractor):
        return scheme
    schemes = {**SHARING_SCHEMES, **learned_schemes()}
    if isinstance(scheme, str):
        name = SCHEME_ALIASES.get(scheme.lower(), scheme.lower())
        if name in schemes:
            return schemes[name]
    known = ", ".join(repr(name) for name in [*schemes, *SCHEME_ALIASES])
    raise ValueError(f"Unknown critic_sharing {scheme!r}: use one of {known}, or a CriticFeaturesExtractor subclass.")


CriticSharing = str | type[CriticFeaturesExtractor] | Mapping[str, str | type[CriticFeaturesExtractor]]
"""A scheme for every critic (a name or a class), or a mapping from agent id to each critic's scheme."""


def validate_critic_sharing(critic_sharing: Any) -> None:
    """
    Fail early, before any env is known, on an unknown scheme name (in a mapping, on any of them).

    :param critic_sharing: ``MADDPG``'s ``critic_sharing``.
    """
    if isinstance(critic_sharing, Mapping):
        if not critic_sharing:
            raise ValueError("critic_sharing is an empty mapping: give each agent id a scheme, e.g. {'agent_0': 'full', ...}.")
        for scheme in critic_sharing.values():
            resolve_scheme(scheme)
    else:
        resolve_scheme(critic_sharing)


def schemes_per_agent(critic_sharing: CriticSharing, agent_ids: Sequence[str]) -> list[type[CriticFeaturesExtractor]]:
    """
    Each critic's scheme.

    :param critic_sharing: One scheme for every critic, or a mapping from each agent id to its critic's scheme (e.g.
        ``{"adversary_0": "full", "agent_0": "independent", "agent_1": "independent"}``).
    :param agent_ids: The team's agent ids, in order.
    :return: One extractor class per agent, in the team's order.
    """
    if not isinstance(critic_sharing, Mapping):
        return [resolve_scheme(critic_sharing)] * len(agent_ids)
    unknown = sorted(set(critic_sharing) - set(agent_ids))
    missing = [agent for agent in agent_ids if agent not in critic_sharing]
    if unknown or missing:
        problems = ([f"it names agents not in the team: {unknown}"] if unknown else []) + (
            [f"it gives no scheme to {missing}"] if missing else []
        )
        raise ValueError(
            f"critic_sharing maps agent ids to schemes, but {'; '.join(problems)}: give exactly the team's agents "
            f"{list(agent_ids)} a scheme each."
        )
    return [resolve_scheme(critic_sharing[agent]) for agent in agent_ids]


def kwargs_per_agent(critic_sharing_kwargs: Mapping[str, Any] | None, agent_ids: Sequence[str]) -> list[dict[str, Any]]:
    """
    Each critic's extractor keyword arguments.

    :param critic_sharing_kwargs: The same keyword arguments for every critic, or, when every key is an agent id and
        every value a dict, each agent's own (agents left out get none).
    :param agent_ids: The team's agent ids, in order.
    :return: One dict per agent, in the team's order.
    """
    kwargs = dict(critic_sharing_kwargs or {})
    per_agent = bool(kwargs) and set(kwargs) <= set(agent_ids) and all(isinstance(v, Mapping) for v in kwargs.values())
    if per_agent:
        return [dict(kwargs.get(agent, {})) for agent in agent_ids]
    return [dict(kwargs) for _ in agent_ids]
