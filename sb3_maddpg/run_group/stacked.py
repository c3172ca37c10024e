"""
The networks of ``R`` teams stacked along a run dimension: every parameter of R copies of one module as one tensor
``[R, ...]``, evaluated for every run at once by :class:`~sb3_maddpg.common.update_step.GroupFunctions` (``vmap`` over
``functional_call``).

The modules themselves are the package's (:class:`~sb3_maddpg.common.policies.MultiAgentActor`,
:class:`~sb3_maddpg.common.policies.MultiAgentCritic`), so their forward passes are not copied; only their parameters are
stacked. Run r's outputs depend on run r's parameters and inputs only, and its gradients land in slice ``[r]``.
"""

import copy
from collections.abc import Sequence

import torch as th
from torch import nn

from sb3_maddpg.common.gradient_step import polyak_update_foreach
from sb3_maddpg.common.policies import MultiAgentActor, MultiAgentCritic
from sb3_maddpg.run_group.streams import RunStreams


class StackedModule:
    """
    ``R`` copies of one module's parameters, stacked along a leading run dimension, on ``device``.

    The template (a copy of the first module) keeps the buffers (e.g. a fixed scheme's gather indices), which the
    runs share: they come from the layout, which every run has in common.

    :param modules: One module per run, all of the same architecture.
    :param device: Where the stacked parameters live.
    """

    def __init__(self, modules: Sequence[nn.Module], device: th.device | str) -> None:
        self.template = copy.deepcopy(modules[0]).to(device)
        self.names = [name for name, _ in modules[0].named_parameters()]
        self.params: dict[str, th.Tensor] = {}
        """Each parameter of every run, ``[R, *shape]``, in the module's ``named_parameters`` order."""
        for name in self.names:
            # Plain tensors: their gradients come from torch.func.grad, and the optimiser moves them in place.
            self.params[name] = th.stack([module.get_parameter(name).detach() for module in modules]).to(device)

    @property
    def n_runs(self) -> int:
        """The number of runs ``R``."""
        return next(iter(self.params.values())).shape[0]

    def parameters(self) -> list[th.Tensor]:
        """:return: The stacked parameters, in the module's order."""
        return [self.params[name] for name in self.names]

    def load_into(self, run: int, module: nn.Module) -> None:
        """
        Copy run ``run``'s parameters into a module of the same architecture (in place, keeping its tensors).

        :param run: The run.
        :param module: The module to write into.
        """
        with th.no_grad():
            for name in self.names:
                target = module.get_parameter(name)
                target.copy_(self.params[name][run].to(target.device))


class StackedTeams:
    """
    The actors, critics and their targets of ``R`` teams, stacked: :class:`~sb3_maddpg.common.update_step.MemberModules` of
    ``M = R`` members.

    :param actors: Each run's team actor.
    :param critics: Each run's team critic (MATD3's: both twins).
    :param actor_targets: Each run's target actor.
    :param critic_targets: Each run's target critic.
    :param device: Where the stacked parameters live.
    :param streams: Each run's random stream (for MATD3's smoothing noise).
    """

    def __init__(
        self,
        actors: Sequence[MultiAgentActor],
        critics: Sequence[MultiAgentCritic],
        actor_targets: Sequence[MultiAgentActor],
        critic_targets: Sequence[MultiAgentCritic],
        device: th.device | str,
        streams: RunStreams,
    ) -> None:
        self.actor = StackedModule(actors, device)
        self.critic = StackedModule(critics, device)
        self.actor_target = StackedModule(actor_targets, device)
        self.critic_target = StackedModule(critic_targets, device)
        self.streams = streams
        self._modules = {
            "actor": self.actor,
            "critic": self.critic,
            "actor_target": self.actor_target,
            "critic_target": self.critic_target,
        }
        # Each network whose gradient is clipped on its own, as the modules group them (MATD3's twins apart).
        self._clip_groups = {
            "actor": [[f"actor.{name}" for name in self.actor.names]],
            "critic": [[f"critic.{name}" for name in group] for group in critics[0].clip_groups()],
        }
        self._target_pairs = (
            [*self.critic.parameters(), *self.actor.parameters()],
            [*self.critic_target.parameters(), *self.actor_target.parameters()],
        )

    def stacked_parameters(self) -> dict[str, th.Tensor]:
        return {name: value for module in self._modules for name, value in self.module_parameters(module).items()}

    def module_parameters(self, module: str) -> dict[str, th.Tensor]:
        return {f"{module}.{name}": value for name, value in self._modules[module].params.items()}

    def templates(self) -> dict[str, nn.Module]:
        """:return: One team's four networks on the device (each stacked module's template), by module name."""
        return {module: stacked.template for module, stacked in self._modules.items()}

    def clip_groups(self, module: str) -> list[list[str]]:
        return self._clip_groups[module]

    def update_targets(self, tau: float) -> None:
        polyak_update_foreach(*self._target_pairs, tau)

    def normal_like(self, tensor: th.Tensor) -> th.Tensor:
        return self.streams.normal(tensor.shape[1:], tensor.dtype)
