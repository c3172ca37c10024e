"""Small helpers of MADDPG's set-up: the selection and the exploration noise's draw (the env's checks are in
:mod:`sb3_maddpg.env_checks`)."""

import warnings

import numpy as np
from stable_baselines3.common.noise import ActionNoise

from sb3_maddpg.layout import AgentLayout
from sb3_maddpg.selection import NearestAgents, Selector


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
