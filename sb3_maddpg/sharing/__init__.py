"""What each critic sees: the information-sharing schemes as critic features extractors.

Critic i of MADDPG sees a vector x_i built from the joint observation, the joint action and (for selected sharing) the
agents it selected. Each scheme is a subclass of :class:`CriticFeaturesExtractor` (:mod:`sb3_maddpg.sharing.base`); a
new scheme is a new subclass. The paper's five (Table 1) are in :mod:`sb3_maddpg.sharing.fixed`, the two whose critics
learn whom to listen to in :mod:`sb3_maddpg.sharing.learned`, and their names and the paper's aliases in one registry,
:mod:`sb3_maddpg.sharing.registry`. Everything is importable from ``sb3_maddpg.sharing`` itself.
"""

from sb3_maddpg.sharing.base import CriticFeaturesExtractor
from sb3_maddpg.sharing.fixed import (
    ActionsCriticFeatures,
    FullCriticFeatures,
    IndependentCriticFeatures,
    ObservationsCriticFeatures,
    SelectedCriticFeatures,
)
from sb3_maddpg.sharing.learned import AttentionCriticFeatures, LearnedSelectionCriticFeatures, default_selection_size
from sb3_maddpg.sharing.registry import (
    LEARNED_SCHEMES,
    SCHEME_ALIASES,
    SHARING_SCHEMES,
    CriticSharing,
    kwargs_per_agent,
    resolve_scheme,
    schemes_per_agent,
    validate_critic_sharing,
)

__all__ = [
    "LEARNED_SCHEMES",
    "SCHEME_ALIASES",
    "SHARING_SCHEMES",
    "ActionsCriticFeatures",
    "AttentionCriticFeatures",
    "CriticFeaturesExtractor",
    "CriticSharing",
    "FullCriticFeatures",
    "IndependentCriticFeatures",
    "LearnedSelectionCriticFeatures",
    "ObservationsCriticFeatures",
    "SelectedCriticFeatures",
    "default_selection_size",
    "kwargs_per_agent",
    "resolve_scheme",
    "schemes_per_agent",
    "validate_critic_sharing",
]
