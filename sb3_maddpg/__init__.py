"""sb3-maddpg: multi-agent DDPG for Stable-Baselines3, with swappable critic information sharing."""

from sb3_maddpg.analysis.export import export_actors
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.envs import register_envs
from sb3_maddpg.maddpg import MADDPG
from sb3_maddpg.matd3 import MATD3
from sb3_maddpg.version import __version__

register_envs()

__all__ = ["MADDPG", "MATD3", "AgentLayout", "__version__", "export_actors"]
