"""One registry of the schemes: the seven names, the paper's aliases, and how ``critic_sharing`` resolves."""

from collections.abc import Mapping, Sequence
from typing import Any

from sb3_maddpg.sharing.base import CriticFeaturesExtractor
from sb3_maddpg.sharing.fixed import (
    ActionsCriticFeatures,
    FullCriticFeatures,
    IndependentCriticFeatures,
    ObservationsCriticFeatures,
    SelectedCriticFeatures,
)
from sb3_maddpg.sharing.learned import AttentionCriticFeatures, LearnedSelectionCriticFeatures

SHARING_SCHEMES: dict[str, type[CriticFeaturesExtractor]] = {
    "independent": IndependentCriticFeatures,
    "full": FullCriticFeatures,
    "observations": ObservationsCriticFeatures,
    "actions": ActionsCriticFeatures,
    "selected": SelectedCriticFeatures,
}
"""The paper's five schemes by name."""

LEARNED_SCHEMES: dict[str, type[CriticFeaturesExtractor]] = {
    "attention": AttentionCriticFeatures,
    "learned_selection": LearnedSelectionCriticFeatures,
}
"""The schemes whose critics learn whom to listen to (:mod:`sb3_maddpg.sharing.learned`)."""

SCHEME_ALIASES: dict[str, str] = {
    "iddpg": "independent",
    "maddpg": "full",
    "fo": "observations",
    "fa": "actions",
    "soa": "selected",
}
"""The paper's short names for the built-in schemes."""


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
    schemes = {**SHARING_SCHEMES, **LEARNED_SCHEMES}
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
