"""Exploration noise in the policy's [-1, 1] action space, the same for data collection and for evaluation."""

import copy
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.noise import ActionNoise, NormalActionNoise, VectorizedActionNoise

from sb3_maddpg.common.layout import AgentLayout, ArrayT, array_namespace


def default_noise(
    layout: AgentLayout, noise_std: float | Sequence[float], action_space: spaces.Box
) -> NormalActionNoise | None:
    """
    MADDPG's default exploration noise: Gaussian, with each agent's std given in its own action units and converted to
    the [-1, 1] space; zero on a discrete agent's one-hot (it explores by sampling its action, Gumbel-max).

    :param layout: The team's agent layout.
    :param noise_std: One std for every agent, or one per agent (in agent order), each finite and >= 0.
    :param action_space: The joint action space (the units of ``noise_std``).
    :return: The noise over the joint action, or None when every std is 0.
    """
    values = np.atleast_1d(np.asarray(noise_std, dtype=np.float64))
    if values.ndim != 1 or len(values) not in (1, layout.n_agents):
        raise ValueError(
            f"noise_std has {values.size} values, but the team has {layout.n_agents} agents {list(layout.agent_ids)}: "
            f"give one std for every agent (e.g. noise_std=0.1) or one per agent, in that order."
        )
    if not all(math.isfinite(value) and value >= 0 for value in values):
        raise ValueError(
            f"noise_std must be finite and >= 0 (a standard deviation in the agents' action units), got {noise_std!r}: "
            "use 0.1 (0.1 of mpe2's [0, 1] actions), or 0 for no exploration noise."
        )
    if not np.any(values > 0):
        return None
    per_agent = np.broadcast_to(values, (layout.n_agents,))
    per_agent = np.where(discrete_agents(layout), 0.0, per_agent)
    half_range = (action_space.high - action_space.low) / 2.0
    sigma = np.concatenate([np.full(size, std) for std, size in zip(per_agent, layout.action_sizes)]) / half_range
    return NormalActionNoise(mean=np.zeros(layout.action_dim), sigma=sigma)


def discrete_agents(layout: AgentLayout) -> np.ndarray:
    """:return: Whether each agent's action is discrete, ``[n_agents]``."""
    return np.array([layout.is_discrete(i) for i in range(layout.n_agents)], dtype=bool)


def per_env_noise(noise: ActionNoise) -> ActionNoise:
    """:return: The noise of one env: SB3's ``VectorizedActionNoise`` unwrapped, any other noise itself."""
    return noise.base_noise if isinstance(noise, VectorizedActionNoise) else noise


def fit_noise_to_envs(noise: ActionNoise | None, n_envs: int) -> ActionNoise | None:
    """
    :param noise: A model's exploration noise.
    :param n_envs: The number of envs it will explore in.
    :return: A noise vectorised for another number of envs (a model saved with 2 envs, loaded with 4) unwrapped to its
        per-env noise, which SB3's ``_setup_learn`` vectorises again; any other noise unchanged.
    """
    if isinstance(noise, VectorizedActionNoise) and noise.n_envs != n_envs:
        return noise.base_noise
    return noise


def noise_copy_for_envs(noise: ActionNoise, n_envs: int) -> VectorizedActionNoise:
    """:return: A fresh copy of a model's noise for ``n_envs`` envs (an evaluation's: the model's own is not advanced)."""
    return VectorizedActionNoise(copy.deepcopy(per_env_noise(noise)), n_envs)


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


def add_noise(actions: np.ndarray, action_noise: ActionNoise, discrete: np.ndarray | None = None) -> np.ndarray:
    """
    Explore: add one draw of the noise to actions in the [-1, 1] space, none on discrete agents' one-hots (they stay
    one-hots), and clip to [-1, 1]. SB3's off-policy collection does the same (``_sample_action``), without the mask.

    :param actions: Joint actions in [-1, 1], ``[n_envs, action_dim]``.
    :param action_noise: The noise (over the joint action, or vectorised over the envs).
    :param discrete: Which action components belong to discrete agents
        (:meth:`~sb3_maddpg.common.layout.AgentLayout.discrete_components`), or None.
    :return: The noisy actions, ``[n_envs, action_dim]``.
    """
    return noisy_actions(actions, draw_noise(action_noise, actions.shape), discrete)


def noisy_actions(actions: ArrayT, noise: ArrayT, discrete: np.ndarray | None = None) -> ArrayT:
    """
    The exploration rule, written once against the array API standard: a model's collection runs it in numpy
    (:func:`add_noise`), a run group in torch on its device, with noise from each run's own stream.

    :param actions: Joint actions in [-1, 1], ``[..., action_dim]``.
    :param noise: A draw of the noise, of a shape that broadcasts to ``actions``.
    :param discrete: Which action components belong to discrete agents (no noise on their one-hots), a numpy mask
        (put where ``actions`` are), or None.
    :return: ``actions + noise``, clipped to [-1, 1].
    """
    values: Any = actions  # numpy or torch
    if discrete is not None and discrete.any():
        xp = array_namespace(values)
        noise = xp.where(xp.asarray(discrete, device=getattr(values, "device", None)), 0.0, noise)
    return (values + noise).clip(-1.0, 1.0)  # the arrays' own clip: numpy's and torch's alike, without a wrapper
