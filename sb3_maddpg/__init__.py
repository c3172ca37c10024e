"""sb3-maddpg: multi-agent DDPG for Stable-Baselines3, with swappable critic information sharing."""

from sb3_maddpg.compat import install_moved_module_finder

install_moved_module_finder()  # the module paths of 0.3 keep working, with a warning

from sb3_maddpg.analysis.export import export_actors  # noqa: E402
from sb3_maddpg.common.layout import AgentLayout  # noqa: E402
from sb3_maddpg.envs import register_envs  # noqa: E402
from sb3_maddpg.maddpg import MADDPG  # noqa: E402
from sb3_maddpg.matd3 import MATD3  # noqa: E402
from sb3_maddpg.version import __version__  # noqa: E402

register_envs()

__all__ = ["MADDPG", "MATD3", "AgentLayout", "__version__", "export_actors"]
