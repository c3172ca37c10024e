"""Checks and small helpers of MADDPG's set-up: the team's layout from the env, the refusals that name their cause, the
selection, and the exploration noise's draw."""

import warnings

import numpy as np
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.vec_env import VecEnv, VecNormalize, unwrap_vec_normalize

from sb3_maddpg.layout import AgentLayout
from sb3_maddpg.selection import NearestAgents, Selector


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
    :param env_layout: The layout of an env given to a model (``set_env``, ``load(env=...)``).
    :param model_layout: The model's layout.
    """
    if env_layout != model_layout:
        raise ValueError(
            f"The env's agent layout {env_layout} differs from the model's agent layout {model_layout}: "
            "use an env with the same agents, in the same order, with the same observation and action sizes."
        )


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


def draw_noise(action_noise: ActionNoise, action_shape: tuple[int, ...]) -> np.ndarray:
    """
    One draw of the exploration noise, refused with the cause when it does not fit the joint actions.

    :param action_noise: The noise.
    :param action_shape: The joint actions' shape, ``[n_envs, action_dim]``.
    :return: Noise of shape ``[n_envs, action_dim]`` or ``[action_dim]``.
    """
    noise = action_noise()
    if np.shape(noise) != action_shape and np.shape(noise) != action_shape[1:]:
        n_envs, action_dim = action_shape
        raise ValueError(
            f"action_noise gives noise of shape {np.shape(noise)}, but the joint actions have shape {action_shape} "
            f"({n_envs} env(s), {action_dim} action components over all agents): give a noise over the joint action, "
            f"e.g. NormalActionNoise(mean=np.zeros({action_dim}), sigma=...) (SB3 vectorises it over the envs), or "
            "leave action_noise=None for the default noise of noise_std."
        )
    return noise


def resolve_selection(selection: Selector | int | None) -> Selector:
    """The selector of ``selected`` sharing: the default ``NearestAgents(k=2)``, or an int ``k`` for ``NearestAgents(k)``."""
    if selection is None:
        return NearestAgents(k=2)
    if isinstance(selection, int) and not isinstance(selection, bool):
        return NearestAgents(k=selection)
    if not isinstance(selection, Selector):
        raise TypeError(
            f"selection must be a sb3_maddpg.selection.Selector or an int k (the k nearest agents), got "
            f"{type(selection).__name__}: wrap a function as CallableSelector(fn, k=...)."
        )
    return selection


def warn_if_selecting_everyone(selection: Selector, layout: AgentLayout) -> None:
    """Selecting all n - 1 other agents is full sharing in another order: say so, since it compares nothing."""
    if selection.k == layout.n_agents - 1:
        warnings.warn(
            f"critic_sharing='selected' with k={selection.k} selects every other agent of this {layout.n_agents}-agent "
            f"team: each critic sees what 'full' sees, in another order. Select fewer (e.g. selection=1, the nearest "
            "agent) for a critic that selects.",
            UserWarning,
            stacklevel=3,
        )
