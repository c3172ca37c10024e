"""MATD3's policy: MADDPG's, with two critics per agent (and their targets)."""

from collections.abc import Sequence
from typing import Any, ClassVar

import torch as th
from torch import nn

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.policies import MultiAgentCritic
from sb3_maddpg.maddpg.policies import MADDPGPolicy
from sb3_maddpg.sharing import CriticFeaturesExtractor


class TwinMultiAgentCritic(MultiAgentCritic):
    """
    Every agent's two critics Q_i1 and Q_i2, each with its own instances of agent i's features extractors and its
    own network (their initial weights differ).

    This module *is* the first twin (its :meth:`forward` is Q_i1, what the actors ascend, what
    :attr:`~sb3_maddpg.maddpg.policies.MADDPGPolicy.critics`, ``q_values`` and the extractors' diagnostics read) and holds
    the second as :attr:`twin`: its ``parameters()`` are both twins', so one optimiser and one Polyak update cover
    both, as SB3's TD3 critic.

    :param layout: The team's agent layout.
    :param extractor_class: The sharing scheme, or one per agent.
    :param extractor_kwargs: Extra keyword arguments for the extractor, or one dict per agent.
    :param selection_size: ``k`` selected agents per agent (0 when the scheme uses no selection).
    :param hidden_sizes: Hidden layer sizes.
    :param activation_fn: Activation function.
    :param share_parameters: One critic network per twin for all agents (needs equal feature sizes).
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
        arguments = (layout, extractor_class, extractor_kwargs, selection_size, hidden_sizes, activation_fn)
        super().__init__(*arguments, share_parameters, layer_norm)
        self.twin = MultiAgentCritic(*arguments, share_parameters, layer_norm)
        """The second critic of every agent, Q_i2."""

    def twins(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        """
        Both twins on a joint batch (arguments as :meth:`forward`).

        :return: ``[2, batch, n_agents]``: Q_i1 in ``[0]``, Q_i2 in ``[1]``.
        """
        return th.stack((self(observations, actions, selections), self.twin(observations, actions, selections)))

    def trained_q(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        """Both twins, trained together: :meth:`twins`, ``[2, batch, n_agents]`` (what ``critic_losses`` broadcasts over)."""
        return self.twins(observations, actions, selections)

    def target_q(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        """The minimum of the two twins, agent by agent (TD3's clipped double Q), ``[batch, n_agents]``."""
        return self.twins(observations, actions, selections).amin(dim=0)

    def clip_groups(self) -> list[list[str]]:
        """:return: The first twin's parameter names, then the second's (:attr:`twin`): each clipped on its own."""
        second = {id(parameter) for parameter in self.twin.parameters()}
        named = list(self.named_parameters())
        return [[name for name, p in named if id(p) not in second], [name for name, p in named if id(p) in second]]

    def clip_grad_norm_per_agent(self, max_norm: float) -> None:
        """
        Clip each agent's gradient norm separately for each twin, like one optimiser per critic network: the twins are
        independent estimators, and a norm over both would let twin 2's gradient shrink twin 1's step.
        """
        super().clip_grad_norm_per_agent(max_norm)
        self.twin.clip_grad_norm_per_agent(max_norm)


class MATD3Policy(MADDPGPolicy):
    """
    Policy for MATD3: :class:`~sb3_maddpg.maddpg.policies.MADDPGPolicy` (same arguments) whose ``critic`` and
    ``critic_target`` are :class:`TwinMultiAgentCritic`: two critics per agent, each fed by its own instance of the
    agent's sharing scheme's extractor, under one critic optimiser.
    """

    critic_class: ClassVar[type[MultiAgentCritic]] = TwinMultiAgentCritic
    critic: TwinMultiAgentCritic
    critic_target: TwinMultiAgentCritic


MlpPolicy = MATD3Policy
