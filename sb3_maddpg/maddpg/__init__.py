"""MADDPG: the algorithm and its multi-agent policy."""

from sb3_maddpg.maddpg.maddpg import LOG_INTERVAL, MADDPG, SATURATION_THRESHOLD, ActorLossTerms
from sb3_maddpg.maddpg.policies import DEFAULT_NET_ARCH, MADDPGPolicy, MlpPolicy

# LOG_INTERVAL, SATURATION_THRESHOLD and ActorLossTerms: import paths of 0.2 (the module sb3_maddpg.maddpg re-exported them)
__all__ = ["DEFAULT_NET_ARCH", "LOG_INTERVAL", "MADDPG", "SATURATION_THRESHOLD", "ActorLossTerms", "MADDPGPolicy", "MlpPolicy"]
