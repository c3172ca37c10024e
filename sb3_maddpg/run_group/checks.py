"""What a run group refuses, with the cause first: models that differ in more than their seed, and what it cannot stack."""

from collections.abc import Sequence
from typing import Any

import numpy as np
from stable_baselines3.common.noise import NormalActionNoise

from sb3_maddpg.common.noise import per_env_noise
from sb3_maddpg.common.selection import FixedGraph, NearestAgents, Selector
from sb3_maddpg.maddpg import MADDPG
from sb3_maddpg.matd3 import MATD3
from sb3_maddpg.sharing import LEARNED_SCHEMES, CriticFeaturesExtractor, schemes_per_agent

SAME_EXCEPT_SEED = (
    "A run group trains runs that differ only in their seed: build every model with the same env layout and "
    "hyperparameters, e.g. [MADDPG('MlpPolicy', env, ..., seed=s) for s in seeds]."
)


def check_models(models: Sequence[MADDPG]) -> None:
    """
    Refuse models a run group cannot train together, naming the cause first and what to do.

    :param models: One model per run.
    """
    if len(models) == 0:
        raise ValueError("A run group needs at least one model: pass one MADDPG model per run.")
    for index, model in enumerate(models):
        check_model(model, index)
    reference = settings(models[0])
    shapes = parameter_shapes(models[0])
    for index, model in enumerate(models[1:], start=1):
        for name, value in settings(model).items():
            if value != reference.get(name):
                raise ValueError(
                    f"The models differ in {name}: model 0 has {reference.get(name)!r}, model {index} has {value!r}. "
                    + SAME_EXCEPT_SEED
                )
        # What the settings above miss (e.g. a policy class of a user's): the group stacks parameters name by name.
        other = parameter_shapes(model)
        for name in [*shapes, *(name for name in other if name not in shapes)]:
            if other.get(name) != shapes.get(name):
                raise ValueError(
                    f"The models' networks differ in parameter {name}: model 0's has shape {shapes.get(name, 'none')}, "
                    f"model {index}'s {other.get(name, 'none')}. " + SAME_EXCEPT_SEED
                )


def check_model(model: MADDPG, index: int) -> None:
    """Refuse one model the group cannot train (its algorithm, its env, its team, its scheme, its schedule, its seed)."""
    if type(model) not in (MADDPG, MATD3):
        raise TypeError(
            f"Model {index} is a {type(model).__name__}, but a run group trains MADDPG and MATD3 models only (it runs "
            "their own update step; a subclass's train() may differ): train it with its own learn(), or pass MADDPG "
            "or MATD3 models."
        )
    if model.get_vec_normalize_env() is not None:
        raise ValueError(
            f"Model {index}'s env is wrapped in VecNormalize, but a run group steps its own worlds and would train on "
            'raw observations: train it with MADDPG.learn (a sweep\'s local backend, backend="local"), or build the '
            "model on the env without VecNormalize."
        )
    layout = model.agent_layout
    assert layout is not None, "MADDPG reads the layout when it is built"
    if layout.has_discrete_actions:
        raise ValueError(
            f"Model {index}'s team has discrete agents: their actions are sampled (Gumbel) from torch's global "
            "generator, which vmap cannot split into one stream per run. Train discrete teams with MADDPG.learn, or "
            "use continuous actions."
        )
    schemes = schemes_per_agent(model.critic_sharing, layout.agent_ids)
    learned = [scheme.__name__ for scheme in schemes if scheme in LEARNED_SCHEMES.values()]
    extractor_params = [
        parameter
        for module in model.critic.modules()
        if isinstance(module, CriticFeaturesExtractor)
        for parameter in module.parameters()
    ]  # the critics' extractors' own (MATD3's twins' too), as the modules say
    if learned or extractor_params:
        raise ValueError(
            f"Model {index}'s critics use a learned scheme ({', '.join(dict.fromkeys(learned)) or 'an extractor'} with "
            "parameters of its own), which a run group does not stack: its per-run-and-agent gradient clipping "
            "covers the critics' networks only. Use a fixed scheme ('full', 'independent', 'observations', 'actions', "
            "'selected'), or train learned schemes with MADDPG.learn."
        )
    if not model.update_rule.earns_gradient_steps:
        raise ValueError(
            f"Model {index} was given train_freq or gradient_steps (SB3's semantics), but a run group updates by the "
            "paper's rule only, one gradient step per transitions_per_update transitions: leave train_freq and "
            "gradient_steps None and set transitions_per_update."
        )
    if model.seed is None:
        raise ValueError(
            f"Model {index} has no seed, but each run of a group draws its episodes, noise and batches from a generator "
            "of its own seed: build each model with MADDPG(..., seed=s)."
        )
    noise = None if model.action_noise is None else per_env_noise(model.action_noise)
    if noise is not None and not isinstance(noise, NormalActionNoise):
        raise ValueError(
            f"Model {index} explores with {type(noise).__name__}, but a run group draws Gaussian noise only (one "
            "stream per run, on the device): use noise_std (the default NormalActionNoise) or a NormalActionNoise."
        )
    if not model.replay_buffer.handle_timeout_termination:
        raise ValueError(
            f"Model {index}'s replay buffer has handle_timeout_termination=False, but a run group bootstraps on "
            "truncation (simple_spread's episodes never terminate): leave handle_timeout_termination=True."
        )


def settings(model: MADDPG) -> dict[str, Any]:
    """:return: Everything that must be the same in every run of a group, by name (comparable values)."""
    policy = model.policy
    noise = None if model.action_noise is None else per_env_noise(model.action_noise)
    return {
        "agent_layout": model.agent_layout,
        "critic_sharing": model.critic_sharing,
        "critic_sharing_kwargs": model.critic_sharing_kwargs,
        "selector": describe_selector(model.selector),
        "learning_rate": model.learning_rate,
        "buffer_size": model.buffer_size,
        "learning_starts": model.learning_starts,
        "batch_size": model.batch_size,
        "tau": model.tau,
        "gamma": model.gamma,
        "transitions_per_update": model.transitions_per_update,
        "max_grad_norm": model.max_grad_norm,
        "actor_reg_coef": model.actor_reg_coef,
        "n_envs": model.n_envs,
        "algorithm": type(model).__name__,
        # The step's own beyond those above, as the algorithm states them (MATD3's delay and smoothing)
        "policy_delay": model._step_settings().policy_delay,
        "smoothing": model._step_settings().smoothing,
        "policy_class": type(policy).__name__,
        # The policy's whole configuration (net_arch, activation_fn, share_parameters, layer_norm, ...) but what is
        # compared above, the schedule (a function object; learning_rate is compared) and the spaces (the layout).
        **{
            name: value
            for name, value in policy._get_constructor_parameters().items()
            if name not in ("lr_schedule", "observation_space", "action_space", "agent_layout", *_MODEL_SETTINGS)
        },
        "optimizer": (type(model.actor.optimizer).__name__, model.actor.optimizer.defaults),
        "action_noise": None if noise is None else _normal_noise(noise),
        "num_timesteps": model.num_timesteps,
        "n_updates": model._n_updates,
        "update_credit": (model.update_rule.credit, model.update_rule.counted_at),
    }


_MODEL_SETTINGS = ("critic_sharing", "critic_sharing_kwargs")
"""The policy's constructor parameters :func:`settings` reads from the model instead."""


def parameter_shapes(model: MADDPG) -> dict[str, tuple[int, ...]]:
    """:return: The shape of each parameter of the model's actors and critics, by name (e.g. ``"actor.mlp.weight_0"``)."""
    modules = (("actor", model.actor), ("critic", model.critic))
    return {f"{prefix}.{name}": tuple(p.shape) for prefix, module in modules for name, p in module.named_parameters()}


def describe_selector(selector: Selector | None) -> tuple[Any, ...] | None:
    """:return: The selection rule as comparable values (its class, ``k`` and its settings)."""
    if selector is None:
        return None
    if isinstance(selector, NearestAgents):
        return ("NearestAgents", selector.k, selector.position_slice, selector.target)
    if isinstance(selector, FixedGraph):
        return ("FixedGraph", selector.k, selector.neighbors.tolist())
    return (type(selector).__name__, selector.k, id(selector))  # a user's rule: the same object in every model


def _normal_noise(noise: Any) -> tuple[list[float], list[float]]:
    """:return: A NormalActionNoise's mean and std per action component."""
    return np.asarray(noise._mu).tolist(), np.asarray(noise._sigma).tolist()
