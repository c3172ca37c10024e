"""Per-agent MLPs evaluated together: one batched matmul per layer instead of one small matmul per agent.

Each agent owns a slice ``[i]`` of every weight tensor, so its parameters, gradients and (with an
element-wise optimiser such as Adam) optimiser state are independent of the other agents': this is
numerically the same as N separate networks with N optimisers, only faster.
"""

import itertools
import math
from collections.abc import Sequence

import torch as th
from torch import nn

LAYER_NORM_EPS = 1e-5
"""``torch.nn.LayerNorm``'s default epsilon, used by ``layer_norm=True`` and by the exported actors."""


class AgentEnsembleMLP(nn.Module):
    """
    ``n_agents`` independent MLPs (or one shared MLP) with possibly different input and output sizes.

    Inputs are ``[n_agents, batch, max_in_dim]`` (zero-padded per agent); outputs ``[n_agents, batch,
    max_out_dim]`` (agent i's first ``out_dims[i]`` columns are its output). Padded input rows start
    at zero and, fed zeros, never receive gradient, so each agent's network is exactly its own size.

    :param in_dims: Input size of each agent's network.
    :param out_dims: Output size of each agent's network.
    :param hidden_sizes: Hidden layer sizes (shared by all agents).
    :param activation_fn: Activation between layers.
    :param squash_output: Apply ``tanh`` to the output.
    :param share_parameters: One network for all agents (needs equal in and out sizes).
    :param layer_norm: Normalise each hidden layer's pre-activations over its features (layer normalisation, with a
        learned scale and shift per agent), before the activation.
    """

    def __init__(
        self,
        in_dims: Sequence[int],
        out_dims: Sequence[int],
        hidden_sizes: Sequence[int],
        activation_fn: type[nn.Module] = nn.ReLU,
        squash_output: bool = False,
        share_parameters: bool = False,
        layer_norm: bool = False,
    ) -> None:
        super().__init__()
        if len(in_dims) != len(out_dims) or not in_dims:
            raise ValueError(f"Need one input and one output size per agent, got {in_dims} and {out_dims}.")
        if share_parameters and (len(set(in_dims)) > 1 or len(set(out_dims)) > 1):
            raise ValueError(
                f"share_parameters=True needs agents with equal network sizes, got inputs {list(in_dims)} and outputs "
                f"{list(out_dims)}: use share_parameters=False for a heterogeneous team."
            )
        self.in_dims = tuple(int(d) for d in in_dims)
        self.out_dims = tuple(int(d) for d in out_dims)
        self.n_agents = len(self.in_dims)
        self.share_parameters = share_parameters
        self.n_members = 1 if share_parameters else self.n_agents
        self.squash_output = squash_output
        self.activation = activation_fn()
        sizes = [max(self.in_dims), *[int(h) for h in hidden_sizes], max(self.out_dims)]
        self.n_layers = len(sizes) - 1
        # Plain parameters read from self._parameters in forward: iterating a ParameterList costs
        # ~10 us per call, as much as the whole batch-1 forward pass of a rollout step.
        self._weight_names = tuple(f"weight_{layer}" for layer in range(self.n_layers))
        self._bias_names = tuple(f"bias_{layer}" for layer in range(self.n_layers))
        for layer, (fan_in, fan_out) in enumerate(itertools.pairwise(sizes)):
            weight = th.zeros(self.n_members, fan_in, fan_out)
            bias = th.zeros(self.n_members, 1, fan_out)
            for member in range(self.n_members):
                true_in = self.in_dims[member] if layer == 0 else fan_in
                # nn.Linear's default initialisation, computed from the member's true fan-in.
                bound = 1.0 / math.sqrt(true_in)
                weight[member, :true_in].uniform_(-bound, bound)
                bias[member].uniform_(-bound, bound)
            self.register_parameter(self._weight_names[layer], nn.Parameter(weight))
            self.register_parameter(self._bias_names[layer], nn.Parameter(bias))
        self.layer_norm = layer_norm
        hidden = sizes[1:-1] if layer_norm else []
        self._norm_names = tuple((f"norm_scale_{layer}", f"norm_shift_{layer}") for layer in range(len(hidden)))
        for (scale_name, shift_name), width in zip(self._norm_names, hidden):
            self.register_parameter(scale_name, nn.Parameter(th.ones(self.n_members, 1, width)))
            self.register_parameter(shift_name, nn.Parameter(th.zeros(self.n_members, 1, width)))
        self.max_in_dim = sizes[0]
        """Width of the padded input."""

    @property
    def weights(self) -> list[nn.Parameter]:
        """Every layer's weights, ``[n_members, in, out]`` each (member i is agent i's network)."""
        return [self._parameters[name] for name in self._weight_names]  # type: ignore[misc]

    @property
    def biases(self) -> list[nn.Parameter]:
        """Every layer's biases, ``[n_members, 1, out]`` each."""
        return [self._parameters[name] for name in self._bias_names]  # type: ignore[misc]

    @property
    def norms(self) -> list[tuple[nn.Parameter, nn.Parameter]]:
        """Every hidden layer's normalisation scale and shift, ``[n_members, 1, width]`` each (none without
        ``layer_norm``)."""
        return [(self._parameters[scale], self._parameters[shift]) for scale, shift in self._norm_names]  # type: ignore[misc]

    def forward(self, inputs: th.Tensor) -> th.Tensor:
        """
        :param inputs: ``[n_agents, batch, max_in_dim]``.
        :return: ``[n_agents, batch, max_out_dim]``.
        """
        n_agents, batch = inputs.shape[0], inputs.shape[1]
        x = inputs.reshape(1, n_agents * batch, -1) if self.share_parameters else inputs
        x = self._layers(x, self.weights, self.biases, self.norms, self.squash_output)
        return x.reshape(n_agents, batch, -1) if self.share_parameters else x

    def forward_preactivation(self, inputs: th.Tensor) -> th.Tensor:
        """
        The output before the ``tanh`` squash (the same as :meth:`forward` when ``squash_output=False``).

        :param inputs: ``[n_agents, batch, max_in_dim]``.
        :return: ``[n_agents, batch, max_out_dim]``.
        """
        # A copy of forward rather than a shared helper: forward runs at batch 1 on every env step,
        # where one more Python call is a measurable part of its cost.
        n_agents, batch = inputs.shape[0], inputs.shape[1]
        x = inputs.reshape(1, n_agents * batch, -1) if self.share_parameters else inputs
        x = self._layers(x, self.weights, self.biases, self.norms, False)
        return x.reshape(n_agents, batch, -1) if self.share_parameters else x

    def forward_agent(self, agent: int, inputs: th.Tensor) -> th.Tensor:
        """
        Agent ``agent``'s network alone.

        :param agent: The agent's index.
        :param inputs: ``[batch, in_dims[agent]]``.
        :return: ``[batch, out_dims[agent]]``.
        """
        member = 0 if self.share_parameters else agent
        padded = pad_features(inputs, self.max_in_dim).unsqueeze(0)
        weights = [w[member : member + 1] for w in self.weights]
        biases = [b[member : member + 1] for b in self.biases]
        norms = [(scale[member : member + 1], shift[member : member + 1]) for scale, shift in self.norms]
        return self._layers(padded, weights, biases, norms, self.squash_output)[0, :, : self.out_dims[agent]]

    def _layers(
        self,
        x: th.Tensor,
        weights: Sequence[th.Tensor],
        biases: Sequence[th.Tensor],
        norms: Sequence[tuple[th.Tensor, th.Tensor]],
        squash: bool,
    ) -> th.Tensor:
        activation = self.activation.forward  # skip Module.__call__: ~4 us per call at batch 1
        for layer, (weight, bias) in enumerate(zip(weights, biases)):
            x = th.baddbmm(bias, x, weight)
            if layer < self.n_layers - 1:
                if norms:
                    scale, shift = norms[layer]
                    x = th.addcmul(shift, nn.functional.layer_norm(x, x.shape[-1:], eps=LAYER_NORM_EPS), scale)
                x = activation(x)
        return th.tanh(x) if squash else x

    def squared_grad_norms(self) -> th.Tensor:
        """Per member, the squared norm of its gradients, ``[n_members]`` (zeros where none)."""
        total = th.zeros(self.n_members, device=self.weights[0].device)
        for param in self.parameters():
            if param.grad is not None:
                total += param.grad.pow(2).sum(dim=(1, 2))
        return total

    def clip_grad_norm_per_member(self, max_norm: float) -> None:
        """Clip each member's gradient norm to ``max_norm`` separately."""
        self.scale_grads(clip_coefficients(self.squared_grad_norms(), max_norm))

    def scale_grads(self, coefficients: th.Tensor) -> None:
        """Multiply member m's gradients by ``coefficients[m]``."""
        for param in self.parameters():
            if param.grad is not None:
                param.grad.mul_(coefficients.view(-1, 1, 1))


def clip_coefficients(squared_norms: th.Tensor, max_norm: float) -> th.Tensor:
    """The factors that bring each norm down to ``max_norm`` (1 where it is already below), as ``clip_grad_norm_``."""
    return (max_norm / (squared_norms.sqrt() + 1e-6)).clamp(max=1.0)


def pad_features(features: th.Tensor, width: int) -> th.Tensor:
    """Zero-pad ``[..., d]`` to ``[..., width]`` (no copy when ``d == width``)."""
    missing = width - features.shape[-1]
    return features if missing == 0 else nn.functional.pad(features, (0, missing))


def stack_padded(features: Sequence[th.Tensor], width: int) -> th.Tensor:
    """Stack per-agent ``[batch, d_i]`` tensors into ``[n_agents, batch, width]``, zero-padding each."""
    return th.stack([pad_features(f, width) for f in features])
