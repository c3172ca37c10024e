"""MATD3: SB3's TD3 choices (twin critics, target policy smoothing, delayed policy updates) on MADDPG's base."""

from collections.abc import Sequence
from typing import Any, ClassVar

import torch as th
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, Schedule

from sb3_maddpg.common.argument_ranges import TD3_RANGES, check_arguments
from sb3_maddpg.common.losses import TargetSmoothing
from sb3_maddpg.common.selection import Selector
from sb3_maddpg.common.update_step import StepSettings
from sb3_maddpg.maddpg import MADDPG
from sb3_maddpg.matd3.policies import MATD3Policy, MlpPolicy, TwinMultiAgentCritic
from sb3_maddpg.sharing import CriticSharing


class MATD3(MADDPG):
    """
    Multi-Agent TD3: MADDPG with SB3's TD3 choices, agent by agent.

    TD3: Fujimoto et al. (2018) https://arxiv.org/abs/1802.09477; its multi-agent form (MATD3): Ackermann et al. (2019)
    https://arxiv.org/abs/1910.01465. Each agent i has two critics, each with its own instance of agent i's sharing
    scheme's extractor; critic i's target is ``r_i + gamma * (1 - done_i) * min(Q_i1', Q_i2')`` at the target actors'
    actions plus clipped smoothing noise; the actors ascend their first critic, and the actors and every target network
    move once every ``policy_delay`` critic updates. The update is MADDPG's ``train`` with MATD3's target actions,
    target critics and trained critics, which run groups apply to every run as they are.
    TD3's parameters have SB3's names and defaults; every other parameter is :class:`~sb3_maddpg.MADDPG`'s, with the
    paper's defaults (Lowe et al.).

    :param policy: The policy model to use (``"MlpPolicy"`` or a :class:`~sb3_maddpg.matd3.policies.MATD3Policy`
        subclass).
    :param env: The environment to learn from (see :class:`~sb3_maddpg.MADDPG`).
    :param critic_sharing: What each critic sees: a scheme's name, a
        :class:`~sb3_maddpg.sharing.CriticFeaturesExtractor` subclass, or one per agent id (see
        :class:`~sb3_maddpg.MADDPG`); both of an agent's critics see the same.
    :param selector: For schemes that use a selection, the rule that selects (see :class:`~sb3_maddpg.MADDPG`).
    :param learning_rate: Learning rate of every actor and critic (Adam), constant or a schedule.
    :param buffer_size: Replay buffer size, in joint transitions.
    :param learning_starts: Env steps (all envs counted) of uniformly random actions before learning starts.
    :param batch_size: Minibatch size of each gradient step (the same rows for every agent and both twins).
    :param tau: Polyak coefficient of the target networks.
    :param gamma: Discount factor.
    :param train_freq: SB3's semantics; None: the per-transition rule (see :class:`~sb3_maddpg.MADDPG`).
    :param gradient_steps: Critic updates per update, SB3's semantics; None: as :class:`~sb3_maddpg.MADDPG`.
    :param transitions_per_update: Transitions (all envs counted) per critic update when neither ``train_freq`` nor
        ``gradient_steps`` is given.
    :param policy_delay: The actors and the target networks are updated once every ``policy_delay`` critic updates
        (TD3's, counted over the model's ``_n_updates``, across ``train()`` calls).
    :param target_policy_noise: Standard deviation of the Gaussian noise added to the continuous agents' target actions,
        in the policy's [-1, 1] space (0.2, as SB3's TD3; 0.1 in mpe2's [0, 1] units); none on a discrete agent's
        one-hot.
    :param target_noise_clip: The smoothing noise is clipped to ``[-target_noise_clip, target_noise_clip]`` ([-1, 1]
        space) before it is added.
    :param action_noise: Exploration noise (see :class:`~sb3_maddpg.MADDPG`).
    :param noise_std: Standard deviation of the default Gaussian exploration noise, in each agent's own action units.
    :param max_grad_norm: Clip the norm of each agent's actor gradient, and of each of its two critics' gradients, to
        this; None to disable.
    :param actor_reg_coef: Weight of the penalty on each actor's pre-``tanh`` output (see :class:`~sb3_maddpg.MADDPG`).
    :param critic_sharing_kwargs: Extra keyword arguments for the sharing scheme's extractors, or, keyed by agent id,
        each agent's own (both twins get the same).
    :param replay_buffer_class: Replay buffer class (default :class:`~sb3_maddpg.common.buffers.MultiAgentReplayBuffer`).
    :param replay_buffer_kwargs: Keyword arguments for the replay buffer.
    :param stats_window_size: Window size for the rollout logging (episodes).
    :param tensorboard_log: The log location for tensorboard (None: no logging).
    :param policy_kwargs: Additional arguments for the policy, e.g. ``net_arch``, ``share_parameters``.
    :param verbose: 0 no output, 1 info messages, 2 debug messages.
    :param seed: Seed for the pseudo random generators.
    :param device: Device (cpu, cuda, ...) on which the code should be run; "auto" uses the GPU if possible.
    :param _init_setup_model: Whether or not to build the network at the creation of the instance.
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {"MlpPolicy": MlpPolicy}
    policy: MATD3Policy
    critic: TwinMultiAgentCritic
    critic_target: TwinMultiAgentCritic

    def __init__(
        self,
        policy: str | type[MATD3Policy],
        env: GymEnv | str | None,
        critic_sharing: CriticSharing = "full",
        selector: Selector | int | dict[str, Any] | None = None,
        learning_rate: float | Schedule = 1e-2,
        buffer_size: int = 1_000_000,
        learning_starts: int = 25_600,
        batch_size: int = 1024,
        tau: float = 0.01,
        gamma: float = 0.95,
        train_freq: int | tuple[int, str] | None = None,
        gradient_steps: int | None = None,
        transitions_per_update: int = 100,
        policy_delay: int = 2,
        target_policy_noise: float = 0.2,
        target_noise_clip: float = 0.5,
        action_noise: ActionNoise | None = None,
        noise_std: float | Sequence[float] = 0.1,
        max_grad_norm: float | None = 0.5,
        actor_reg_coef: float = 1e-3,
        critic_sharing_kwargs: dict[str, Any] | None = None,
        replay_buffer_class: type[ReplayBuffer] | None = None,
        replay_buffer_kwargs: dict[str, Any] | None = None,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "auto",
        _init_setup_model: bool = True,
    ) -> None:
        check_arguments(TD3_RANGES, locals())  # MADDPG's constructor checks the others
        # Set before MADDPG's constructor, which ends with _setup_model(): the attributes exist from then on.
        self.policy_delay = policy_delay
        self.target_policy_noise = float(target_policy_noise)
        self.target_noise_clip = float(target_noise_clip)
        super().__init__(
            policy,
            env,
            critic_sharing=critic_sharing,
            selector=selector,
            learning_rate=learning_rate,
            buffer_size=buffer_size,
            learning_starts=learning_starts,
            batch_size=batch_size,
            tau=tau,
            gamma=gamma,
            train_freq=train_freq,
            gradient_steps=gradient_steps,
            transitions_per_update=transitions_per_update,
            action_noise=action_noise,
            noise_std=noise_std,
            max_grad_norm=max_grad_norm,
            actor_reg_coef=actor_reg_coef,
            critic_sharing_kwargs=critic_sharing_kwargs,
            replay_buffer_class=replay_buffer_class,
            replay_buffer_kwargs=replay_buffer_kwargs,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
            _init_setup_model=_init_setup_model,
        )

    def _step_settings(self) -> StepSettings:
        """:return: MADDPG's settings with the actors delayed by ``policy_delay`` critic updates and the target actions
        smoothed (read now: a changed ``target_policy_noise`` takes effect at the next step)."""
        smoothing = TargetSmoothing(self.target_policy_noise, self.target_noise_clip)
        return super()._step_settings()._replace(policy_delay=self.policy_delay, smoothing=smoothing)
