"""The critics that learn whom to listen to, at their 0.2 import path: they live in :mod:`sb3_maddpg.sharing.learned`
and :func:`critic_listening` in :mod:`sb3_maddpg.inspection` (kept so that code and saved models naming
``sb3_maddpg.attention`` keep working)."""

from sb3_maddpg.inspection import critic_listening
from sb3_maddpg.sharing.learned import (
    DEFAULT_POSITION_SLICE,
    AttentionCriticFeatures,
    LearnedSelectionCriticFeatures,
    default_selection_size,
)

__all__ = [
    "DEFAULT_POSITION_SLICE",
    "AttentionCriticFeatures",
    "LearnedSelectionCriticFeatures",
    "critic_listening",
    "default_selection_size",
]
