"""Environments: the PettingZoo-to-Gymnasium adapter, MPE cooperative navigation and every other MPE task."""

from sb3_maddpg.envs.adapter import MetricsFn, PettingZooToGym
from sb3_maddpg.envs.mpe_tasks import MPE_TASK_METRICS, MPE_TASK_SIDES, MPE_TASKS, make_mpe_env
from sb3_maddpg.envs.registration import SIMPLE_SPREAD_ID, register_envs
from sb3_maddpg.envs.simple_spread import CAPTURE_RADIUS, SimpleSpreadMetrics, make_simple_spread
from sb3_maddpg.envs.simple_spread_reference import RandomTeamPolicy, ScriptedSpreadPolicy
from sb3_maddpg.envs.simple_spread_vec_env import SimpleSpreadVecEnv, make_simple_spread_vec_env
from sb3_maddpg.envs.task_metric import TaskMetric

__all__ = [
    "CAPTURE_RADIUS",
    "MPE_TASKS",
    "MPE_TASK_METRICS",
    "MPE_TASK_SIDES",
    "SIMPLE_SPREAD_ID",
    "MetricsFn",
    "PettingZooToGym",
    "RandomTeamPolicy",
    "ScriptedSpreadPolicy",
    "SimpleSpreadMetrics",
    "SimpleSpreadVecEnv",
    "TaskMetric",
    "make_mpe_env",
    "make_simple_spread",
    "make_simple_spread_vec_env",
    "register_envs",
]
