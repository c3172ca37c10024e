"""The multi-agent policy of MADDPG: one actor and one critic per agent (and their targets), evaluated together."""

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import PyTorchObs, Schedule
from torch import nn

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.policies import AgentActor, AgentCritic, MultiAgentActor, MultiAgentCritic
from sb3_maddpg.sharing import CriticSharing, kwargs_per_agent, schemes_per_agent

DEFAULT_NET_ARCH = {"pi": [64, 64], "qf": [64, 64, 64]}
"""The paper's networks: actor of 3 and critic of 4 fully connected layers, 64 hidden units."""


def hidden_sizes(net_arch: list[int] | dict[str, list[int]] | None) -> dict[str, list[int]]:
    """
    The actors' and critics' hidden sizes, checked: a torch error about a negative dimension, or a ``KeyError``, named
    neither the argument nor what to write.

    :param net_arch: ``dict(pi=[...], qf=[...])``, one list for both, or None for the paper's (:data:`DEFAULT_NET_ARCH`).
    :return: ``{"pi": [...], "qf": [...]}``, new lists.
    """
    if net_arch is None:
        net_arch = DEFAULT_NET_ARCH
    example = "e.g. net_arch=dict(pi=[64, 64], qf=[64, 64, 64]) or net_arch=[64, 64]"
    if isinstance(net_arch, Mapping):
        if not {"pi", "qf"} <= set(net_arch):  # other keys are ignored, as SB3's TD3 ignores them
            raise ValueError(
                f"net_arch as a dict needs the keys 'pi' (the actors) and 'qf' (the critics), got "
                f"{sorted(map(repr, net_arch))}: {example}."
            )
        sizes = {"pi": net_arch["pi"], "qf": net_arch["qf"]}
    else:
        sizes = {"pi": net_arch, "qf": net_arch}
    for part, layers in sizes.items():
        if not isinstance(layers, list | tuple | np.ndarray) or not all(
            isinstance(units, int | np.integer) and not isinstance(units, bool) and units >= 1 for units in layers
        ):
            raise ValueError(f"net_arch's {part!r} must be a list of hidden sizes, integers >= 1, got {layers!r}: {example}.")
    return {part: [int(units) for units in layers] for part, layers in sizes.items()}


class MADDPGPolicy(BasePolicy):
    """
    Policy for MADDPG: per-agent actors, per-agent critics fed by a sharing scheme, and target copies.

    :param observation_space: The joint observation space (a flat ``Box``).
    :param action_space: The joint action space (a flat ``Box``).
    :param lr_schedule: Learning rate schedule (for every optimiser).
    :param agent_layout: The team's agent layout (MADDPG fills it in from the env).
    :param critic_sharing: The sharing scheme: a name from :data:`~sb3_maddpg.sharing.SHARING_SCHEMES`,
        an alias, a :class:`~sb3_maddpg.sharing.CriticFeaturesExtractor` subclass, or a mapping from each agent id to
        its critic's scheme.
    :param critic_sharing_kwargs: Extra keyword arguments for the extractors, or a dict of them per agent id.
    :param selection_size: ``k`` selected agents per agent (0 when the scheme uses no selection).
    :param net_arch: Hidden sizes, ``dict(pi=[...], qf=[...])`` (default: the paper's ``pi=[64, 64], qf=[64, 64, 64]``)
        or one list for both.
    :param activation_fn: Activation function (ReLU, as in Lowe et al.).
    :param share_parameters: One actor and one critic network for all agents (homogeneous teams only).
    :param layer_norm: Layer normalisation of every hidden layer of the actors and critics (a learned scale and shift
        per agent), which often steadies learning with many updates per transition. Off by default: the paper has none.
    :param optimizer_class: Optimiser class (Adam). It must be element-wise (Adam, SGD, RMSprop...) so that
        one optimiser over the agents' stacked parameters equals one optimiser per agent.
    :param optimizer_kwargs: Extra keyword arguments for the optimiser.
    :param normalize_images: Unused (observations are vectors); kept for SB3 compatibility.
    """

    critic_class: ClassVar[type[MultiAgentCritic]] = MultiAgentCritic
    """The team critic :meth:`make_critic` builds (MATD3's policy: twin critics)."""

    def __init__(
        self,
        observation_space: spaces.Box,
        action_space: spaces.Box,
        lr_schedule: Schedule,
        agent_layout: AgentLayout | None = None,
        critic_sharing: CriticSharing = "full",
        critic_sharing_kwargs: dict[str, Any] | None = None,
        selection_size: int = 0,
        net_arch: list[int] | dict[str, list[int]] | None = None,
        activation_fn: type[nn.Module] = nn.ReLU,
        share_parameters: bool = False,
        layer_norm: bool = False,
        optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
        optimizer_kwargs: dict[str, Any] | None = None,
        normalize_images: bool = False,
    ) -> None:
        super().__init__(
            observation_space,
            action_space,
            optimizer_class=optimizer_class,
            optimizer_kwargs=optimizer_kwargs,
            squash_output=True,
            normalize_images=normalize_images,
        )
        if agent_layout is None:
            raise ValueError("MADDPGPolicy needs agent_layout (MADDPG passes the env's layout; pass it in policy_kwargs).")
        if agent_layout.obs_dim != int(observation_space.shape[0]) or agent_layout.action_dim != int(action_space.shape[0]):
            raise ValueError(
                f"The agent layout (obs {agent_layout.obs_dim}, action {agent_layout.action_dim}) does not match the spaces "
                f"{observation_space.shape} and {action_space.shape}."
            )
        self.net_arch = hidden_sizes(net_arch)
        self.agent_layout = agent_layout
        self.critic_sharing = critic_sharing
        self.critic_sharing_kwargs = dict(critic_sharing_kwargs or {})
        self.selection_size = int(selection_size)
        self.activation_fn = activation_fn
        self.share_parameters = share_parameters
        self.layer_norm = layer_norm
        self._build(lr_schedule)

    def _build(self, lr_schedule: Schedule) -> None:
        self.actor = self.make_actor()
        self.actor_target = self.make_actor()
        self.actor_target.load_state_dict(self.actor.state_dict())
        self.critic = self.make_critic()
        self.critic_target = self.make_critic()
        self.critic_target.load_state_dict(self.critic.state_dict())
        self.actor.optimizer = self.optimizer_class(  # type: ignore[call-arg]
            self.actor.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs
        )
        self.critic.optimizer = self.optimizer_class(  # type: ignore[call-arg]
            self.critic.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs
        )
        # Targets only follow (Polyak) and never train.
        for target in (self.actor_target, self.critic_target):
            target.train(False)
            target.requires_grad_(False)
        self._actor_views = [AgentActor(self.actor, i) for i in range(self.agent_layout.n_agents)]
        self._critic_views = [AgentCritic(self.critic, i) for i in range(self.agent_layout.n_agents)]

    def make_actor(self) -> MultiAgentActor:
        """A new team actor."""
        return MultiAgentActor(
            self.agent_layout, self.net_arch["pi"], self.activation_fn, self.share_parameters, self.layer_norm
        ).to(self.device)

    def make_critic(self) -> MultiAgentCritic:
        """A new team critic."""
        agent_ids = self.agent_layout.agent_ids
        schemes = schemes_per_agent(self.critic_sharing, agent_ids)
        if self.share_parameters and len(set(schemes)) > 1:
            # Inputs of equal size may still mean different things (e.g. 'full' and 'selected' with k = N - 1).
            raise ValueError(
                f"share_parameters=True needs one scheme for every agent (one critic network reads one input layout), "
                f"got {dict(zip(agent_ids, (scheme.__name__ for scheme in schemes)))}: give every agent the same "
                "critic_sharing, or use share_parameters=False."
            )
        return self.critic_class(
            self.agent_layout,
            schemes,
            kwargs_per_agent(self.critic_sharing_kwargs, agent_ids),
            self.selection_size,
            self.net_arch["qf"],
            self.activation_fn,
            self.share_parameters,
            self.layer_norm,
        ).to(self.device)

    @property
    def actors(self) -> list[AgentActor]:
        """Agent i's actor, ``actors[i](o_i) -> a_i`` in [-1, 1] (views into the team's actor)."""
        return self._actor_views

    @property
    def critics(self) -> list[AgentCritic]:
        """Agent i's critic, ``critics[i](obs, actions, selections) -> Q_i`` (views into the team's critic)."""
        return self._critic_views

    def q_values(
        self,
        obs: th.Tensor,
        actions: th.Tensor,
        selections: th.Tensor | None = None,
    ) -> th.Tensor:
        """
        Every agent's critic on a joint batch.

        :param obs: Joint observations ``[batch, obs_dim]``.
        :param actions: Joint actions in the policy's [-1, 1] space ``[batch, action_dim]``.
        :param selections: LongTensor ``[batch, n_agents, k]`` of the agents each agent selected (itself
            excluded); needed by schemes that use a selection.
        :return: ``[batch, n_agents]``.
        """
        return self.critic(obs, actions, selections)

    def predict(
        self,
        observation: np.ndarray | dict[str, np.ndarray],
        state: tuple[np.ndarray, ...] | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, tuple[np.ndarray, ...] | None]:
        """
        The team's joint action for a joint observation (SB3's ``predict``), after a check that the observation is of
        the model's team: SB3's own error for another size names only shapes.

        :param observation: The joint observation, ``[obs_dim]``, or one per env, ``[n_envs, obs_dim]``.
        :param state: Unused (no recurrent state); SB3's argument.
        :param episode_start: Unused; SB3's argument.
        :param deterministic: Unused: the actors are deterministic (exploration noise is the algorithm's, in ``learn``).
        :return: The joint action in the env's units (``[action_dim]`` or ``[n_envs, action_dim]``) and ``state``.
        """
        self._check_joint_observation(observation)
        return super().predict(observation, state, episode_start, deterministic)

    def predict_agents(self, observations: Mapping[Any, Any], deterministic: bool = True) -> dict[Any, np.ndarray | int]:
        """
        Each agent's action from each agent's observation, as PettingZoo's ``ParallelEnv`` gives and takes them:
        ``actions = model.predict_agents(observations)``, then ``parallel_env.step(actions)``.

        :param observations: One step's observation of every agent of the team still in the episode, by agent id
            (``parallel_env.reset()`` and ``step()``'s first value); an agent that has left is seen as zeros.
        :param deterministic: As in :meth:`predict` (the actors are deterministic either way).
        :return: Each given agent's action in the env's units, by its id: what :meth:`predict` gives for its
            slice of the joint action (a continuous agent's float32 vector, rescaled from the policy's [-1, 1] to its
            ``Box``), or for a discrete agent the index of its choice (an ``int``, as the env's ``Discrete`` space takes).
        """
        ids = {str(agent): agent for agent in observations}  # the caller's ids back, whatever their type
        joint = self.agent_layout.joint_observation(observations)
        action, _ = self.predict(joint, deterministic=deterministic)
        return {ids[agent]: value for agent, value in self.agent_layout.agent_actions(action).items() if agent in ids}

    def _check_joint_observation(self, observation: Any) -> None:
        """
        Refuse, naming the model's team first, an observation that is not its joint observation: of another team size,
        or a dict of per-agent observations (which :meth:`predict_agents` takes).

        :param observation: What ``predict`` was given.
        """
        layout = self.agent_layout
        shape: tuple[int, ...] = () if isinstance(observation, Mapping) else np.shape(observation)
        if len(shape) in (1, 2) and shape[-1] == layout.obs_dim:
            return  # the joint observation (of one env or several): the common case, checked first and cheaply
        team = f"{layout.describe()}, a joint observation of {layout.obs_dim} numbers"
        if isinstance(observation, Mapping):
            raise TypeError(
                f"predict() got a dict of observations (keys {list(observation)}), but it takes the team's joint "
                f"observation; the model's team is {team}. For PettingZoo's {{agent_id: observation}}, use "
                "model.predict_agents(observations), which returns {agent_id: action}."
            )
        if len(shape) == 1:
            given = f"an observation of {shape[0]} numbers (shape {shape})"
        elif len(shape) == 2:
            given = f"{shape[0]} observations of {shape[1]} numbers (shape {shape})"
        else:
            given = f"an observation of shape {shape}"
        raise ValueError(
            f"predict() got {given}, but the model's team is {team}: an env of another "
            f"team (e.g. another number of agents)? Pass this team's joint observation, shape ({layout.obs_dim},) or "
            f"(n_envs, {layout.obs_dim}) (each agent's observation in turn, in agent_layout.agent_ids order; "
            "model.predict_agents takes PettingZoo's {agent_id: observation}), or train a model for the other team."
        )

    def forward(self, observation: th.Tensor, deterministic: bool = False) -> th.Tensor:
        return self._predict(observation, deterministic=deterministic)

    def _predict(self, observation: PyTorchObs, deterministic: bool = False) -> th.Tensor:
        # Deterministic actors: exploration noise is added by the algorithm, not here. Float32 as the networks (SB3's
        # preprocess_obs, which other policies call, does this cast): a float64 array would fail in the matmul.
        return self.actor(observation.float())  # type: ignore[union-attr]  # a flat Box: a tensor, never a dict

    def set_training_mode(self, mode: bool) -> None:
        """
        Put the actors and critics (not the targets, which stay in eval mode) in training or eval mode.

        :param mode: True for training.
        """
        # Called before every predict(): skip the module-tree walk when nothing changes.
        if self.actor.training != mode or self.critic.training != mode:
            self.actor.train(mode)
            self.critic.train(mode)
        self.training = mode

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(
            lr_schedule=self._dummy_schedule,  # as TD3Policy: the optimisers' state is not part of policy.save()
            agent_layout=self.agent_layout,
            critic_sharing=self.critic_sharing,
            critic_sharing_kwargs=self.critic_sharing_kwargs,
            selection_size=self.selection_size,
            net_arch=self.net_arch,
            activation_fn=self.activation_fn,
            share_parameters=self.share_parameters,
            layer_norm=self.layer_norm,
            optimizer_class=self.optimizer_class,
            optimizer_kwargs=self.optimizer_kwargs,
        )
        return data


MlpPolicy = MADDPGPolicy
