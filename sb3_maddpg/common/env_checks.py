"""Checks of the env a model is given: each refusal names its cause first and says what to do.

Duck-typed on purpose: algorithm code never imports an environment package (PettingZoo is recognised by its API).
"""

from typing import Any

from gymnasium import spaces
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecNormalize, unwrap_vec_normalize

from sb3_maddpg.common.layout import AgentLayout

WRAP_HINT = (
    "wrap it: sb3_maddpg.envs.PettingZooToGym(env) for any ParallelEnv, or build one ready to use with "
    "sb3_maddpg.envs.make_simple_spread(n_agents=3) or sb3_maddpg.envs.make_mpe_env('simple_tag')"
)


def pettingzoo_kind(env: Any) -> str | None:
    """
    :param env: Anything given as an env.
    :return: ``"ParallelEnv"`` or ``"AECEnv"`` if it is a PettingZoo env (per-agent ``action_space(agent)`` methods
        and ``possible_agents``), else ``None``.
    """
    if not (hasattr(env, "possible_agents") and callable(getattr(env, "action_space", None))):
        return None
    return "AECEnv" if hasattr(env, "agent_iter") else "ParallelEnv"


def refuse_unsupported_env(env: Any) -> None:
    """
    Refuse an env MADDPG cannot train on before SB3 inspects it: a raw PettingZoo env, or a joint action space that
    is not a ``Box``.

    :param env: The env given to the model (not ``None``, not a string).
    """
    kind = pettingzoo_kind(env)
    if kind == "ParallelEnv":
        raise TypeError(
            f"MADDPG got a raw PettingZoo ParallelEnv ({type(env).__name__}), which SB3 cannot step (it takes one dict "
            f"per agent): {WRAP_HINT}."
        )
    if kind == "AECEnv":
        raise TypeError(
            f"MADDPG got a raw PettingZoo AECEnv ({type(env).__name__}), which SB3 cannot step (agents act in turn): "
            "make it a ParallelEnv (mpe2: simple_spread_v3.parallel_env(...) instead of .env(...); any other: "
            f"pettingzoo.utils.conversions.aec_to_parallel(env)), then {WRAP_HINT}."
        )
    if not isinstance(env.action_space, spaces.Box):
        raise TypeError(
            f"MADDPG trains on one joint Box action space, but the env's action space is {env.action_space}: wrap a "
            "PettingZoo env in sb3_maddpg.envs.PettingZooToGym (each Discrete agent becomes a one-hot slot of the Box), "
            "or give a gymnasium env with a Box action space and an agent_layout."
        )


def layout_of(env: VecEnv) -> AgentLayout:
    """
    :param env: The training env.
    :return: Its team's agent layout (every env of a VecEnv must have the same).
    """
    try:
        layouts = env.get_attr("agent_layout")
    except AttributeError:
        raise ValueError(
            "The env has no agent_layout: MADDPG needs to know which part of the joint observation and action belongs "
            "to which agent. Wrap your PettingZoo ParallelEnv in sb3_maddpg.envs.PettingZooToGym (or use "
            "sb3_maddpg.envs.make_simple_spread)."
        ) from None
    if any(layout != layouts[0] for layout in layouts):
        raise ValueError(f"All envs of the VecEnv must have the same agent layout, got {set(layouts)}.")
    if not isinstance(layouts[0], AgentLayout):
        raise TypeError(f"env.agent_layout must be an sb3_maddpg.AgentLayout, got {type(layouts[0]).__name__}.")
    return layouts[0]


def check_same_layout(env_layout: AgentLayout, model_layout: AgentLayout | None) -> None:
    """
    Refuse an env of another team than the model's (``set_env``, ``load(env=...)``).

    :param env_layout: The layout of the env given to the model.
    :param model_layout: The model's layout.
    """
    if model_layout is None or env_layout == model_layout:
        return
    if env_layout.n_agents != model_layout.n_agents:
        what = f"the model has {model_layout.n_agents} agents, the env {env_layout.n_agents}"
    elif set(env_layout.agent_ids) != set(model_layout.agent_ids):
        what = "other agent ids"
    elif env_layout.agent_ids != model_layout.agent_ids:
        what = "the same agents in another order"
    else:
        what = "agents of other observation or action sizes"
    raise ValueError(
        f"The env's team differs from the model's ({what}): the model was trained for {model_layout.describe()}; the "
        f"env has {env_layout.describe()}. A model's team cannot change (its size, agent ids, order, and each agent's "
        "observation and action sizes): give an env built as the model's training env was (e.g. the same n_agents "
        "and num_agent_neighbors for simple_spread), or train a new model for this team."
    )


def env_layout(env: Any) -> AgentLayout:
    """
    :param env: A gymnasium env with an ``agent_layout`` or a VecEnv of them.
    :return: Its agent layout.
    """
    return layout_of(env if isinstance(env, VecEnv) else DummyVecEnv([lambda: env]))


def refuse_env_of_another_team(data: dict[str, Any] | None, env: Any) -> None:
    """
    Refuse an env given to ``MADDPG.load`` whose team is not the saved model's, before SB3 compares the spaces (whose
    error names neither the agents nor what to do).

    :param data: The save's attributes (:func:`~sb3_maddpg.compat.read_saved_data`; ``None``: unreadable, SB3 says why).
    :param env: The env given to ``load``.
    """
    refuse_unsupported_env(env)
    model_layout = None if data is None else data.get("agent_layout")
    if isinstance(model_layout, AgentLayout):
        check_same_layout(env_layout(env), model_layout)


def refuse_reward_normalization(env: VecEnv) -> None:
    """
    :param env: The training env; a ``VecNormalize`` that normalises rewards is refused (the critics learn from the
        per-agent rewards in ``info``, which it would leave as they are).
    """
    vec_normalize = unwrap_vec_normalize(env)
    if isinstance(vec_normalize, VecNormalize) and vec_normalize.norm_reward:
        raise ValueError(
            "VecNormalize(norm_reward=True) would normalise only the team's scalar reward, not the per-agent rewards "
            "the critics learn from: use VecNormalize(env, norm_reward=False) (observation normalisation is fine)."
        )
