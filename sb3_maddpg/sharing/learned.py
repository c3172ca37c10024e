"""Critics that learn whom to listen to: attention over the other agents, and a learned hard choice of k of them.

The paper's conclusion is that a critic fed a few *selected* agents beats one fed everything, with the selection
fixed by a rule (k nearest); its named future work is a selection that is learned. Two schemes do that here:

=================== ==================================================================================================
scheme              critic i's input
=================== ==================================================================================================
attention           ``[e_i, sum_j w_ij v_j]``: its own encoding ``e_i = g_i(o_i, a_i)`` and the values of every other
                    agent's encoding ``g_ij(o_j, a_j)``, weighted by multi-head attention (query from ``e_i``); in the
                    spirit of MAAC (Iqbal and Sha, 2019), for deterministic actions
learned_selection   ``[o_i, a_i, o_s1, a_s1, .., o_sk, a_sk]``: its own data and that of the k agents with the highest
                    learned attention scores, highest first: exactly k other agents, as ``selected``, chosen by learning
=================== ==================================================================================================

Both are :class:`~sb3_maddpg.sharing.CriticFeaturesExtractor` subclasses with parameters: they train with their
critic's loss (critic i's encoders, attention and scores are its own, so critic i's loss moves only critic i's
parameters; with ``share_parameters=True`` the Q network after them is shared, the extractors still are not), have
target copies, and are saved with the model. Agents of unequal sizes are served: each other agent
has its own encoder, and a learned selection pads the chosen agents' ``o_j`` and ``a_j`` separately.

The hard choice is trained with a straight-through estimator: the forward pass gathers the top-k agents' data
exactly; the backward pass takes the gradient of the softmax of the scores in its place, so the scores learn from how
the other agents' data would change Q. The scores are cosine similarities divided by a temperature, so they are
bounded: an unbounded dot product lets the softmax saturate, its gradient vanish and the choice freeze. The choice is
deterministic (no sampling): it changes when the scores' order does.
"""

from typing import ClassVar

import torch as th
from torch import nn

from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.networks import AgentEnsembleMLP, stack_padded
from sb3_maddpg.sharing.base import CriticFeaturesExtractor, check_agent_index

DEFAULT_POSITION_SLICE = slice(2, 4)
"""Where an MPE observation holds the agent's own position: the diagnostics rank the others by distance from it."""


class _OtherAgentsEncoder(nn.Module):
    """
    Critic i's encoders: ``e_i = act(W_i [o_i, a_i])`` and, for every other agent j, ``e_j = act(W_ij [o_j, a_j])``
    (one linear layer per other agent, evaluated together).

    :param layout: The team's agent layout.
    :param agent_index: The critic's agent.
    :param embed_dim: Size of each encoding.
    """

    def __init__(self, layout: AgentLayout, agent_index: int, embed_dim: int) -> None:
        super().__init__()
        self.layout = layout
        self.agent_index = agent_index
        self.others = [j for j in range(layout.n_agents) if j != agent_index]
        sizes = [layout.obs_sizes[j] + layout.action_sizes[j] for j in range(layout.n_agents)]
        self.own = nn.Linear(sizes[agent_index], embed_dim)
        self.other = AgentEnsembleMLP([sizes[j] for j in self.others], [embed_dim] * len(self.others), [])
        self.max_other_size = self.other.max_in_dim
        self.activation = nn.LeakyReLU()

    def own_input(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """:return: ``[o_i, a_i]``, ``[batch, obs_i + act_i]``."""
        i = self.agent_index
        return th.cat((observations[:, self.layout.obs_slices[i]], actions[:, self.layout.action_slices[i]]), dim=1)

    def others_input(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """:return: Every other agent's ``[o_j, a_j]``, zero-padded, in ascending index, ``[batch, n - 1, max size]``."""
        layout = self.layout
        per_agent = [
            th.cat((observations[:, layout.obs_slices[j]], actions[:, layout.action_slices[j]]), dim=1) for j in self.others
        ]
        return stack_padded(per_agent, self.max_other_size).transpose(0, 1)

    def forward(self, own: th.Tensor, others: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """
        :param own: ``[batch, obs_i + act_i]``.
        :param others: ``[batch, n - 1, max size]``.
        :return: The own encoding ``[batch, embed_dim]`` and the others' ``[batch, n - 1, embed_dim]``.
        """
        return self.activation(self.own(own)), self.activation(self.other(others.transpose(0, 1))).transpose(0, 1)


class _ListeningExtractor(CriticFeaturesExtractor):
    """What both schemes share: the encoders, and the last batch's weights kept for :meth:`diagnostics`."""

    def __init__(
        self,
        layout: AgentLayout,
        agent_index: int,
        features_dim: int,
        embed_dim: int,
        selection_size: int = 0,
        position_slice: slice | None = None,
    ) -> None:
        if embed_dim < 1:
            raise ValueError(f"embed_dim must be positive, got {embed_dim}.")
        super().__init__(layout, agent_index, features_dim, selection_size)
        self.embed_dim = int(embed_dim)
        self.position_slice = position_slice
        self.encoder = _OtherAgentsEncoder(layout, agent_index, embed_dim)
        self._last: tuple[th.Tensor, th.Tensor] | None = None  # (observations, weights) of the last recorded batch

    scheme_name: ClassVar[str]
    """The scheme's name in ``critic_sharing`` (for messages)."""

    @classmethod
    def check_layout(cls, layout: AgentLayout) -> None:
        """Refuse a team with no other agent to listen to."""
        if layout.n_agents < 2:
            raise ValueError(f"critic_sharing={cls.scheme_name!r} needs at least 2 agents, got {layout.n_agents}.")

    def _remember(self, observations: th.Tensor, weights: th.Tensor) -> None:
        if self.recording:  # the critic update's batch (stored actions), not the actor update's or a target's
            self._last = (observations.detach(), weights.detach())

    def listening_weights(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """
        :param observations: Joint observations ``[batch, obs_dim]``.
        :param actions: Joint actions in [-1, 1], ``[batch, action_dim]``.
        :return: How much critic i listens to each other agent, ``[batch, n - 1]`` (ascending agent index, summing
            to 1): the attention weights, or the softmax of the selection scores.
        """
        raise NotImplementedError

    def chosen_agents(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor | None:
        """
        :param observations: Joint observations ``[batch, obs_dim]``.
        :param actions: Joint actions in [-1, 1], ``[batch, action_dim]``.
        :return: The agents critic i sees, ``[batch, k]`` (agent indices, highest score first), or ``None`` when it
            sees every agent (``attention``).
        """
        return None

    def diagnostics(self) -> dict[str, float]:
        """
        Summaries of the last critic update's batch (replayed observations and actions):

        - ``attention_entropy``: mean entropy of the listening weights, in nats (``log(n - 1)`` is uniform); for
          ``attention`` these are the heads' mean weights, and ``head_entropy`` is the mean entropy of each head's
          own weights (at most ``attention_entropy``: heads that each listen sharply to different agents have a
          low ``head_entropy`` and a high ``attention_entropy``);
        - for a hard choice, ``top_choice_share``: the fraction of rows whose first choice is the agent chosen first
          most often (1 when the choice ignores the state, ``1 / (n - 1)`` when it spreads evenly);
        - when the observations hold positions (``position_slice``), ``weight_on_nearest``: mean weight on the
          nearest other agent, and, for a hard choice, ``chose_nearest`` (fraction of rows whose chosen set is the k
          nearest agents) and ``chosen_rank`` (mean distance rank of the chosen agents, 1 = nearest).

        The distances are those of the observations the critic is given: under ``VecNormalize`` the normalised
        ones, whose ranks can differ from the world's.

        :return: The summaries (empty before the first training batch).
        """
        if self._last is None:
            return {}
        observations, weights = self._last
        result = {"attention_entropy": float(_entropy(weights).mean())}
        result.update(self._extra_diagnostics())
        chosen = self._last_choice()
        if chosen is not None:
            first_choices = nn.functional.one_hot(chosen[:, 0], weights.shape[1]).sum(dim=0)  # deterministic
            result["top_choice_share"] = float(first_choices.max()) / chosen.shape[0]
        ranks = self._distance_ranks(observations)
        if ranks is not None:
            result["weight_on_nearest"] = float((weights * (ranks == 1)).sum(dim=1).mean())
            if chosen is not None:
                chosen_ranks = ranks.gather(1, chosen)
                result["chose_nearest"] = float((chosen_ranks <= self.selection_size).all(dim=1).float().mean())
                result["chosen_rank"] = float(chosen_ranks.float().mean())
        return result

    def _last_choice(self) -> th.Tensor | None:
        """:return: The last recorded batch's chosen others (positions among the others, highest first), if any."""
        return None

    def _extra_diagnostics(self) -> dict[str, float]:
        """:return: A scheme's own summaries of the last recorded batch."""
        return {}

    def _distance_ranks(self, observations: th.Tensor) -> th.Tensor | None:
        """Each other agent's distance rank from agent i (1 = nearest), ``[batch, n - 1]``, or ``None`` without positions."""
        layout = self.layout
        # The user's slice, else where the env declares positions (never MPE's layout assumed on another env).
        slices = layout.position_slices if self.position_slice is None else (self.position_slice,) * layout.n_agents
        if slices is None or any(len(range(*where.indices(size))) != 2 for where, size in zip(slices, layout.obs_sizes)):
            return None
        positions = th.stack([observations[:, part][:, where] for part, where in zip(layout.obs_slices, slices)], 1)
        own = positions[:, self.agent_index : self.agent_index + 1]
        distances = (positions[:, self.encoder.others] - own).norm(dim=-1)
        # Stable order (ties to the lower index), as NearestAgents.
        order = th.sort(distances, dim=1, stable=True).indices
        ranks = th.arange(1, order.shape[1] + 1, device=order.device).expand_as(order)
        return th.empty_like(order).scatter_(1, order, ranks)


class AttentionCriticFeatures(_ListeningExtractor):
    """
    Critic i attends over every other agent: ``[e_i, MultiHeadAttention(query=e_i, keys=values=e_others)]``.

    :param layout: The team's agent layout.
    :param agent_index: The critic's agent.
    :param selection_size: Unused (every agent is attended to).
    :param embed_dim: Size of each agent's encoding (the features are twice this).
    :param n_heads: Attention heads (``embed_dim`` must be a multiple).
    :param position_slice: Where each observation holds its agent's position, for the diagnostics (``None``: where
        the env declares positions, :attr:`AgentLayout.position_slices`; none declared: no such diagnostics).
    """

    scheme_name = "attention"

    def __init__(
        self,
        layout: AgentLayout,
        agent_index: int,
        selection_size: int = 0,
        embed_dim: int = 64,
        n_heads: int = 4,
        position_slice: slice | None = None,
    ) -> None:
        self.check_layout(layout)
        if n_heads < 1 or embed_dim % n_heads:
            raise ValueError(f"embed_dim ({embed_dim}) must be a positive multiple of n_heads ({n_heads}).")
        super().__init__(layout, agent_index, 2 * embed_dim, embed_dim, selection_size, position_slice)
        self.attention = nn.MultiheadAttention(embed_dim, n_heads, batch_first=True)
        self._last_heads: th.Tensor | None = None

    def _attend(self, observations: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
        """:return: The own encoding, the attended values and each head's weights, ``[batch, n_heads, n - 1]``."""
        own, others = self.encoder(
            self.encoder.own_input(observations, actions), self.encoder.others_input(observations, actions)
        )
        attended, heads = self.attention(own.unsqueeze(1), others, others, need_weights=True, average_attn_weights=False)
        return own, attended.squeeze(1), heads.squeeze(2)

    def forward(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        own, attended, heads = self._attend(observations, actions)
        if self.recording:  # the mean only for a recorded batch, not in every forward pass
            self._remember(observations, heads.mean(dim=1))
            self._last_heads = heads.detach()
        return th.cat((own, attended), dim=1)

    def listening_weights(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """The heads' mean attention weights (as ``torch.nn.MultiheadAttention`` averages them)."""
        return self._attend(observations, actions)[2].mean(dim=1)

    def _extra_diagnostics(self) -> dict[str, float]:
        return {} if self._last_heads is None else {"head_entropy": float(_entropy(self._last_heads).mean())}


class LearnedSelectionCriticFeatures(_ListeningExtractor):
    """
    Critic i sees its own data and that of the ``k`` other agents it scores highest, highest first:
    ``[o_i, a_i, o_s1, a_s1, .., o_sk, a_sk]`` (each chosen agent's ``o_j`` and ``a_j`` zero-padded separately to
    the largest other agent's, so a column means the same whichever agent fills the slot). The score of agent j is
    ``cos(W_q e_i, W_k e_j) / temperature``: a query from critic i's own encoding against a key from j's.

    :param layout: The team's agent layout.
    :param agent_index: The critic's agent.
    :param selection_size: ``k`` when ``k`` is not given (MADDPG passes 0: this scheme reads no stored selection).
    :param k: The number of agents chosen, set through ``critic_sharing_kwargs={"k": ...}`` (default: 2, at most
        ``n_agents - 2``, at least 1; see :func:`default_selection_size`).
    :param embed_dim: Size of the encodings the scores are computed from.
    :param temperature: The scores lie in ``[-1 / temperature, 1 / temperature]``. Lower makes the softmax the
        gradient comes from closer to the hard choice, higher keeps its gradient larger.
    :param position_slice: Where each observation holds its agent's position, for the diagnostics (``None``: where
        the env declares positions, :attr:`AgentLayout.position_slices`; none declared: no such diagnostics).
    """

    scheme_name = "learned_selection"

    def __init__(
        self,
        layout: AgentLayout,
        agent_index: int,
        selection_size: int = 0,
        k: int | None = None,
        embed_dim: int = 64,
        temperature: float = 0.5,
        position_slice: slice | None = None,
    ) -> None:
        self.check_layout(layout)  # first: k's range would read "up to 0"
        check_agent_index(layout, agent_index)  # before the sizes below index the layout with it
        k = int(k if k is not None else (selection_size or default_selection_size(layout.n_agents)))
        if not 1 <= k <= layout.n_agents - 1:
            raise ValueError(
                f"critic_sharing='learned_selection' chooses k of the {layout.n_agents - 1} other agents, got k={k}: "
                f"give critic_sharing_kwargs={{'k': 1}} (up to {layout.n_agents - 1})."
            )
        if not temperature > 0:
            raise ValueError(f"temperature must be positive, got {temperature}: the scores are divided by it.")
        others = [j for j in range(layout.n_agents) if j != agent_index]
        self._slot_obs_size = max(layout.obs_sizes[j] for j in others)
        self._slot_action_size = max(layout.action_sizes[j] for j in others)
        own_size = layout.obs_sizes[agent_index] + layout.action_sizes[agent_index]
        slot_size = self._slot_obs_size + self._slot_action_size
        super().__init__(layout, agent_index, own_size + k * slot_size, embed_dim, k, position_slice)
        self.temperature = float(temperature)
        self.query = nn.Linear(embed_dim, embed_dim, bias=False)
        self.key = nn.Linear(embed_dim, embed_dim, bias=False)
        self._last_chosen: th.Tensor | None = None

    def _scores(self, observations: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """:return: ``[o_i, a_i]`` and the scores of the other agents, ``[batch, n - 1]`` (ascending index)."""
        own_input = self.encoder.own_input(observations, actions)
        own, others = self.encoder(own_input, self.encoder.others_input(observations, actions))
        query = nn.functional.normalize(self.query(own), dim=-1).unsqueeze(-1)
        keys = nn.functional.normalize(self.key(others), dim=-1)
        return own_input, (keys @ query).squeeze(-1) / self.temperature

    def _slots(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """:return: Every other agent's ``[o_j, a_j]``, each part zero-padded on its own, ``[batch, n - 1, slot]``."""
        layout, others = self.layout, self.encoder.others
        obs = stack_padded([observations[:, layout.obs_slices[j]] for j in others], self._slot_obs_size)
        act = stack_padded([actions[:, layout.action_slices[j]] for j in others], self._slot_action_size)
        return th.cat((obs, act), dim=-1).transpose(0, 1)

    def forward(self, observations: th.Tensor, actions: th.Tensor, selections: th.Tensor | None = None) -> th.Tensor:
        own_input, scores = self._scores(observations, actions)
        slots = self._slots(observations, actions)
        soft = th.softmax(scores, dim=1)
        top = scores.topk(self.selection_size, dim=1).indices  # highest first
        chosen = slots.gather(1, top.unsqueeze(-1).expand(-1, -1, slots.shape[-1]))  # exactly the chosen data
        # Straight-through: adds zero to the value, and the gradient of the softmax-weighted mixture to each slot.
        chosen = chosen + ((soft - soft.detach()).unsqueeze(1) @ slots)
        self._remember(observations, soft)
        if self.recording:
            self._last_chosen = top.detach()
        return th.cat((own_input, chosen.flatten(1)), dim=1)

    def listening_weights(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor:
        return th.softmax(self._scores(observations, actions)[1], dim=1)

    def chosen_agents(self, observations: th.Tensor, actions: th.Tensor) -> th.Tensor:
        top = self._scores(observations, actions)[1].topk(self.selection_size, dim=1).indices
        return th.as_tensor(self.encoder.others, device=top.device)[top]

    def _last_choice(self) -> th.Tensor | None:
        return self._last_chosen


def _entropy(weights: th.Tensor) -> th.Tensor:
    """:return: The entropy in nats of each distribution along the last dimension (``0 log 0 = 0``)."""
    return -(weights * weights.clamp_min(1e-12).log()).sum(dim=-1)


def default_selection_size(n_agents: int) -> int:
    """
    :param n_agents: Team size.
    :return: The default k of a learned selection: 2, but at most ``n_agents - 2`` (so it does not choose every other
        agent), and at least 1.
    """
    return max(1, min(2, n_agents - 2))
