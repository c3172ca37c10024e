"""MADDPG: the algorithm and its multi-agent policy."""

from sb3_maddpg.maddpg.maddpg import MADDPG
from sb3_maddpg.maddpg.policies import DEFAULT_NET_ARCH, MADDPGPolicy, MlpPolicy

__all__ = ["DEFAULT_NET_ARCH", "MADDPG", "MADDPGPolicy", "MlpPolicy"]
