"""Gymnasium ids, so that ``gymnasium.make`` and SB3's ``make_vec_env`` build our envs by name."""

import gymnasium as gym

SIMPLE_SPREAD_ID = "sb3_maddpg/SimpleSpread-v3"
"""``gymnasium.make(SIMPLE_SPREAD_ID, n_agents=5, num_agent_neighbors=2)`` builds :func:`make_simple_spread`.

The id is registered when ``sb3_maddpg`` is imported. Processes that never import it (``SubprocVecEnv``
workers started with ``spawn`` or ``forkserver``) need the ``module:id`` form, which imports it first:
``make_vec_env("sb3_maddpg:sb3_maddpg/SimpleSpread-v3", n_envs=4, vec_env_cls=SubprocVecEnv)``.
"""


def register_envs() -> None:
    """Register the package's gymnasium ids (done on ``import sb3_maddpg``; safe to call again)."""
    if SIMPLE_SPREAD_ID not in gym.registry:
        # The env truncates itself at max_cycles, so gymnasium adds no TimeLimit.
        gym.register(id=SIMPLE_SPREAD_ID, entry_point="sb3_maddpg.envs.simple_spread:make_simple_spread")
