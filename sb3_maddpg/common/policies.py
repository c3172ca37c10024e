"""The team's actor and critic: every agent's network in one ensemble, evaluated together; the views of one agent's."""

import contextlib
from collections.abc import Iterator, Sequence
from typing import Any

import torch as th
from torch import nn

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.networks import AgentEnsembleMLP, clip_coefficients, stack_padded
from sb3_maddpg.sharing import CriticFeaturesExtractor


class MultiAgentActor(nn.Module):
    """
    Every agent's deterministic actor mu_i(o_i), squashed by ``tanh`` to [-1, 1].

    A discrete agent's actor outputs logits over its actions instead, and its action is a one-hot vector, written
    in the [-1, 1] space as ``2 * one_hot - 1``: the most likely action when acting (:meth:`forward`), a Gumbel-max
    sample when exploring and for the critics' targets (:meth:`sample`), and a straight-through Gumbel-softmax
    sample in the actor update (:meth:`forward_with_preactivation`: the one-hot forward, the softmax's gradient
    backward), as Lowe et al. relax discrete actions (temperature 1).

    :param layout: The team's agent layout.
    :param hidden_sizes: Hidden layer sizes.
    :param activation_fn: Activation function.
    :param share_parameters: One actor network for all agents.
    :param layer_norm: Layer normalisation of every hidden layer (see :class:`~sb3_maddpg.common.networks.AgentEnsembleMLP`).
    """

    def __init__(
        self,
        layout: AgentLayout,
        hidden_sizes: list[int],
        activation_fn: type[nn.Module],
        share_parameters: bool = False,
        layer_norm: bool = False,
    ) -> None:
        super().__init__()
        self.layout = layout
        self.has_discrete = layout.has_discrete_actions
        self.mlp = AgentEnsembleMLP(
            layout.obs_sizes,
            layout.action_sizes,
            hidden_sizes,
            activation_fn,
            squash_output=not self.has_discrete,  # with discrete agents, each agent's output is shaped below
            share_parameters=share_parameters,
            layer_norm=layer_norm,
        )
        self.optimizer: th.optim.Optimizer

    def forward(self, observations: th.Tensor) -> th.Tensor:
        """
        :param observations: Joint observations ``[batch, obs_dim]``.
        :return: Joint actions in [-1, 1], ``[batch, action_dim]``; agent i's from its own observation only (a
            discrete agent's: its most likely action, one-hot).
        """
        if self.has_discrete:
            return self._shape(self._preactivations(observations), "greedy")
        layout, batch = self.layout, observations.shape[0]
        if layout.is_homogeneous:
            per_agent = observations.view(batch, layout.n_agents, -1).transpose(0, 1)
            return self.mlp(per_agent).transpose(0, 1).reshape(batch, layout.action_dim)
        per_agent = stack_padded([observations[:, sl] for sl in layout.obs_slices], self.mlp.max_in_dim)
        out = self.mlp(per_agent)
        return th.cat([out[i, :, :size] for i, size in enumerate(layout.action_sizes)], dim=1)

    def forward_with_preactivation(self, observations: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """
        The joint actions and the actors' outputs before ``tanh``, from one forward pass (the actor update
        needs both: the actions for the critic, the pre-activations for the regulariser).

        :param observations: Joint observations ``[batch, obs_dim]``.
        :return: ``(actions, preactivations)``, both ``[batch, action_dim]``, with ``actions = tanh(preactivations)``;
            only each agent's real action components (no padding).
        """
        if self.has_discrete:
            preactivations = self._preactivations(observations)
            return self._shape(preactivations, "straight_through"), preactivations
        # forward's body with the squash moved out, not a shared helper: forward runs at batch 1 on every
        # env step, where each extra Python call is a measurable part of its cost.
        layout, batch = self.layout, observations.shape[0]
        if layout.is_homogeneous:
            per_agent = observations.view(batch, layout.n_agents, -1).transpose(0, 1)
            preactivations = self.mlp.forward_preactivation(per_agent).transpose(0, 1).reshape(batch, layout.action_dim)
        else:
            per_agent = stack_padded([observations[:, sl] for sl in layout.obs_slices], self.mlp.max_in_dim)
            out = self.mlp.forward_preactivation(per_agent)
            preactivations = th.cat([out[i, :, :size] for i, size in enumerate(layout.action_sizes)], dim=1)
        return th.tanh(preactivations), preactivations

    def sample(self, observations: th.Tensor) -> th.Tensor:
        """
        The actions of exploration and of the critics' targets: a continuous agent's as in :meth:`forward`, a discrete
        agent's a Gumbel-max sample of its logits (one-hot).

        :param observations: Joint observations ``[batch, obs_dim]``.
        :return: Joint actions in [-1, 1], ``[batch, action_dim]``.
        """
        if not self.has_discrete:
            return self(observations)
        return self._shape(self._preactivations(observations), "sample")

    def _preactivations(self, observations: th.Tensor) -> th.Tensor:
        """Every agent's network output (logits for a discrete agent), joint, ``[batch, action_dim]``."""
        per_agent = stack_padded([observations[:, sl] for sl in self.layout.obs_slices], self.mlp.max_in_dim)
        out = self.mlp.forward_preactivation(per_agent)
        return th.cat([out[i, :, :size] for i, size in enumerate(self.layout.action_sizes)], dim=1)

    def _shape(self, preactivations: th.Tensor, mode: str) -> th.Tensor:
        """Each agent's action from its output: ``tanh`` (continuous), or a one-hot choice scaled to [-1, 1]."""
        parts = []
        for agent, part in enumerate(self.layout.action_slices):
            output = preactivations[:, part]
            if not self.layout.is_discrete(agent):
                parts.append(th.tanh(output))
                continue
            if mode == "straight_through":
                one_hot = nn.functional.gumbel_softmax(output, tau=1.0, hard=True)
            else:
                scores = output if mode == "greedy" else output - th.empty_like(output).exponential_().log()
                one_hot = nn.functional.one_hot(scores.argmax(dim=1), output.shape[1]).to(output.dtype)
            parts.append(2.0 * one_hot - 1.0)
        return th.cat(parts, dim=1)

    def clip_grad_norm_per_agent(self, max_norm: float) -> None:
        """Clip each agent's actor gradient norm separately, like N optimisers."""
        self.mlp.clip_grad_norm_per_member(max_norm)


class MultiAgentCritic(nn.Module):
    """
    Every agent's critic Q_i(x_i), where ``x_i`` comes from agent i's :class:`CriticFeaturesExtractor`.

    :param layout: The team's agent layout.
    :param extractor_class: The sharing scheme, or one per agent.
    :param extractor_kwargs: Extra keyword arguments for the extractor, or one dict per agent.
    :param selection_size: ``k`` selected agents per agent (0 when the scheme uses no selection).
    :param hidden_sizes: Hidden layer sizes.
    :param activation_fn: Activation function.
    :param share_parameters: One critic network for all agents (needs equal feature sizes).
    :param layer_norm: Layer normalisation of every hidden layer (see :class:`~sb3_maddpg.common.networks.AgentEnsembleMLP`).
    """

    def __init__(
        self,
        layout: AgentLayout,
        extractor_class: type[CriticFeaturesExtractor] | Sequence[type[CriticFeaturesExtractor]],
        extractor_kwargs: dict[str, Any] | Sequence[dict[str, Any]],
        selection_size: int,
        hidden_sizes: list[int],
        activation_fn: type[nn.Module],
        share_parameters: bool = False,
        layer_norm: bool = False,
    ) -> None:
        super().__init__()
        self.layout = layout
        classes = list(extractor_class) if isinstance(extractor_class, Sequence) else [extractor_class] * layout.n_agents
        kwargs = list(extractor_kwargs) if isinstance(extractor_kwargs, Sequence) else [extractor_kwargs] * layout.n_agents
        if len(classes) != layout.n_agents or len(kwargs) != layout.n_agents:
            raise ValueError(f"Need one extractor class and one kwargs dict per agent ({layout.n_agents}).")
        extractors = [
            cls(layout, i, selection_size=selection_size if cls.uses_selection else 0, **kwargs[i])
            for i, cls in enumerate(classes)
        ]
        self.extractors = nn.ModuleList(extractors)
        features_dims = [extractor.features_dim for extractor in extractors]
        self.mlp = AgentEnsembleMLP(
            features_dims,
            [1] * layout.n_agents,
            hidden_sizes,
            activation_fn,
            share_parameters=share_parameters,
            layer_norm=layer_norm,
        )
        self.optimizer: th.optim.Optimizer

    def forward(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        """
        :param observations: Joint observations ``[batch, obs_dim]``.
        :param actions: Joint actions in [-1, 1]: ``[batch, action_dim]`` for all critics, or
            ``[n_agents, batch, action_dim]`` to give critic i its own joint action ``actions[i]``.
        :param selections: Selected agents ``[batch, n_agents, k]``, for schemes that use one.
        :return: Q-values ``[batch, n_agents]``.
        """
        per_critic = actions.dim() == 3
        features = [
            extractor(observations, actions[i] if per_critic else actions, selections)
            for i, extractor in enumerate(self.extractors)
        ]
        return self.mlp(stack_padded(features, self.mlp.max_in_dim)).squeeze(-1).transpose(0, 1)

    @contextlib.contextmanager
    def recording_diagnostics(self) -> Iterator[None]:
        """Let the extractors record what they report in :meth:`diagnostics` during the forward passes inside."""
        extractors: list[CriticFeaturesExtractor] = list(self.extractors)  # type: ignore[arg-type]
        for extractor in extractors:
            extractor.recording = True
        try:
            yield
        finally:
            for extractor in extractors:
                extractor.recording = False

    def diagnostics(self) -> list[dict[str, float]]:
        """:return: Each critic's extractor's :meth:`~sb3_maddpg.sharing.CriticFeaturesExtractor.diagnostics`."""
        return [extractor.diagnostics() for extractor in self.extractors]  # type: ignore[operator]

    def trained_q(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        """Every critic a gradient step trains (arguments as :meth:`forward`): one per agent, ``[batch, n_agents]``."""
        return self(observations, actions, selections)  # type: ignore[no-any-return]

    def target_q(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        """What a target critic gives the critic targets (arguments as :meth:`forward`), ``[batch, n_agents]``."""
        return self(observations, actions, selections)  # type: ignore[no-any-return]

    def clip_groups(self) -> list[list[str]]:
        """:return: The names of this module's parameters, one list per network whose gradient is clipped on its own."""
        return [[name for name, _ in self.named_parameters()]]

    def clip_grad_norm_per_agent(self, max_norm: float) -> None:
        """Clip each agent's gradient norm (its network slice and its extractor) separately, like N optimisers."""
        squared = self.mlp.squared_grad_norms()
        extractor_grads = [[p.grad for p in extractor.parameters() if p.grad is not None] for extractor in self.extractors]
        if any(extractor_grads):
            extra = th.stack([sum((grad.pow(2).sum() for grad in grads), squared.new_zeros(())) for grads in extractor_grads])
            squared = squared + (extra.sum(0, keepdim=True) if self.mlp.share_parameters else extra)
        coefficients = clip_coefficients(squared, max_norm)
        self.mlp.scale_grads(coefficients)
        for i, grads in enumerate(extractor_grads):
            for grad in grads:
                grad.mul_(coefficients[0 if self.mlp.share_parameters else i])


class AgentActor(nn.Module):
    """
    A view of agent i's actor inside :class:`MultiAgentActor` (its parameters live there).

    :param actor: The team's actor.
    :param agent_index: The agent.
    """

    def __init__(self, actor: MultiAgentActor, agent_index: int) -> None:
        super().__init__()
        self._team = [actor]  # a list, so the shared module is not registered twice
        self.agent_index = agent_index

    def forward(self, observation: th.Tensor) -> th.Tensor:
        """
        :param observation: Agent i's observations ``[batch, obs_size_i]``.
        :return: Agent i's actions in [-1, 1], ``[batch, action_size_i]`` (a discrete agent's most likely action as
            ``2 * one_hot - 1``).
        """
        team = self._team[0]
        output = team.mlp.forward_agent(self.agent_index, observation)
        if not team.has_discrete:
            return output  # squashed by the network
        if not team.layout.is_discrete(self.agent_index):
            return th.tanh(output)
        return 2.0 * nn.functional.one_hot(output.argmax(dim=1), output.shape[1]).to(output.dtype) - 1.0


class AgentCritic(nn.Module):
    """
    A view of agent i's critic inside :class:`MultiAgentCritic` (its parameters live there).

    :param critic: The team's critic.
    :param agent_index: The agent.
    """

    def __init__(self, critic: MultiAgentCritic, agent_index: int) -> None:
        super().__init__()
        self._team = [critic]
        self.agent_index = agent_index

    @property
    def features_extractor(self) -> CriticFeaturesExtractor:
        """The extractor that builds this critic's input."""
        return self._team[0].extractors[self.agent_index]  # type: ignore[return-value]

    def forward(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        """
        :param observations: Joint observations ``[batch, obs_dim]``.
        :param actions: Joint actions in [-1, 1], ``[batch, action_dim]``.
        :param selections: Selected agents ``[batch, n_agents, k]``, for schemes that use one.
        :return: Q_i ``[batch, 1]``.
        """
        features = self.features_extractor(observations, actions, selections)
        return self._team[0].mlp.forward_agent(self.agent_index, features)
