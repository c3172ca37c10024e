"""MATD3: MADDPG with twin critics, delayed actor updates and target policy smoothing; its policy."""

from sb3_maddpg.matd3.matd3 import MATD3
from sb3_maddpg.matd3.policies import MATD3Policy, MlpPolicy, TwinMultiAgentCritic

__all__ = ["MATD3", "MATD3Policy", "MlpPolicy", "TwinMultiAgentCritic"]
