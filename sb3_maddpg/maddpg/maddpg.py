"""MADDPG on SB3's off-policy base, with the critic's information sharing as a swappable part."""

from collections.abc import Sequence
from typing import Any, ClassVar

import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, Schedule

from sb3_maddpg.common.argument_ranges import TEAM_ALGORITHM_RANGES, check_arguments
from sb3_maddpg.common.buffers import MultiAgentReplayBuffer, MultiAgentReplayBufferSamples
from sb3_maddpg.common.env_checks import refuse_unsupported_env
from sb3_maddpg.common.gradient_step import gradient_step, polyak_update_foreach
from sb3_maddpg.common.losses import ActionParts, actor_loss_terms, critic_losses, team_critic_targets
from sb3_maddpg.common.policies import MultiAgentActor, MultiAgentCritic
from sb3_maddpg.common.selection import Selector
from sb3_maddpg.common.team_algorithm import TeamOffPolicyAlgorithm
from sb3_maddpg.common.train_logs import StepLosses, record_critic_diagnostics, record_losses, step_losses, summarise_steps
from sb3_maddpg.common.update_schedule import UpdateSchedule
from sb3_maddpg.common.update_step import StepSettings
from sb3_maddpg.maddpg.policies import MADDPGPolicy, MlpPolicy
from sb3_maddpg.sharing import CriticSharing, validate_critic_sharing


class MADDPG(TeamOffPolicyAlgorithm):
    """
    Multi-Agent DDPG with selectable critic information sharing.

    MADDPG: Lowe et al. (2017) https://arxiv.org/abs/1706.02275. Sharing schemes: Sakagami and
    Takadama, "What Kind of Information Is Needed? Multi-Agent Reinforcement Learning that
    Selectively Shares Information from Other Agents". Each agent i has its own deterministic actor
    mu_i(o_i) and its own critic Q_i, whose input the sharing scheme builds from the joint
    observation, the joint action and (for ``"selected"``) the agents i selected.
    Defaults are the paper's (from Lowe et al.).

    :param policy: The policy model to use (``"MlpPolicy"`` or a :class:`~sb3_maddpg.maddpg.policies.MADDPGPolicy` subclass).
    :param env: The environment to learn from: a :class:`~sb3_maddpg.envs.PettingZooToGym` env (or a VecEnv of
        them, or a registered id), which exposes ``agent_layout`` and ``info["agent_rewards"]``.
    :param critic_sharing: What critic i sees: ``"independent"`` (IDDPG), ``"full"`` (MADDPG),
        ``"observations"`` (MADDPG-fo), ``"actions"`` (MADDPG-fa), ``"selected"`` (MADDPG-soa), the paper's
        short names ``"iddpg"``, ``"maddpg"``, ``"fo"``, ``"fa"``, ``"soa"``, beyond the paper ``"attention"`` and
        ``"learned_selection"`` (:mod:`sb3_maddpg.sharing.learned`), or a :class:`~sb3_maddpg.sharing.CriticFeaturesExtractor`
        subclass; or a mapping from each agent id to its own critic's scheme, e.g. ``{"adversary_0": "full",
        "agent_0": "independent", "agent_1": "independent"}``.
    :param selector: For schemes that use a selection, the rule that selects: a :class:`~sb3_maddpg.common.selection.Selector`,
        an int ``k`` for ``NearestAgents(k)`` (default ``NearestAgents(k=2)``), or a dict of ``NearestAgents``'s ``k``
        and ``target`` (``{"k": 2, "target": "next"}``). It is applied to the observation when a transition is stored
        (and, with ``target="next"``, to the next observation for the target). A ``k`` of ``n_agents - 1`` selects
        every other agent (full sharing in another order) and gets a warning.
    :param learning_rate: Learning rate of every actor and critic (Adam), constant or a schedule.
    :param buffer_size: Replay buffer size, in joint transitions.
    :param learning_starts: Env steps (all envs counted) of uniformly random actions before learning starts; no
        gradient update is made before (a ``learn()`` that ends there warns). The default, 1024 episodes of 25 steps,
        matches Lowe et al.'s code; lower it for a short test.
    :param batch_size: Minibatch size of each gradient step (the same rows for every agent).
    :param tau: Polyak coefficient of the target networks.
    :param gamma: Discount factor.
    :param train_freq: Update the model every ``train_freq`` vectorised env steps (``n_envs`` transitions each) or
        with a ``(n, "episode")`` tuple, SB3's semantics. None (default): every
        ``max(1, transitions_per_update // n_envs)`` vectorised steps.
    :param gradient_steps: Gradient steps per update (-1: as many as transitions collected), SB3's semantics.
        None (default): 1 if ``train_freq`` is given; if neither is, the gradient steps the collected transitions
        have earned, one per ``transitions_per_update`` transitions past ``learning_starts`` (a remainder carries
        over to the next update).
    :param transitions_per_update: Transitions (all envs counted) per gradient step when neither ``train_freq``
        nor ``gradient_steps`` is given: the paper's one update per 100 transitions, whatever ``n_envs`` is (with
        ``n_envs=100``, one gradient step per vectorised step). See :attr:`update_schedule`.
    :param action_noise: Exploration noise over the joint action in the policy's [-1, 1] space (any SB3
        ``ActionNoise`` of shape ``[action_dim]``; SB3 vectorises it over the envs, and ``learn()`` vectorises it
        again for a model loaded with another number of envs). None: Gaussian noise of ``noise_std``.
    :param noise_std: Standard deviation of the default Gaussian exploration noise, in each agent's own
        action units (for mpe2's [0, 1] actions, 0.1 is 0.2 in the policy's [-1, 1] space); one value, or one
        per agent. 0 disables it. Ignored when ``action_noise`` is given.
    :param max_grad_norm: Clip the norm of each agent's whole actor gradient and of its whole critic gradient (all
        its layers together) to this; None to disable. This package's decision: Lowe et al.'s code clips each
        weight and bias tensor's gradient separately to 0.5 (see the implementation details, item 7).
    :param actor_reg_coef: Weight of the penalty on each actor's pre-``tanh`` output, added to its loss as
        ``actor_reg_coef * mean(pre-activation ** 2)`` over the batch and the agent's action components (Lowe et al.'s
        code, 1e-3). It keeps the actors out of ``tanh`` saturation; 0 turns it off.
    :param critic_sharing_kwargs: Extra keyword arguments for the sharing scheme's extractor (e.g. ``{"k": 1}`` for
        ``learned_selection``), or, keyed by agent id, each critic's own.
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
    policy_delay: int = 1
    """Critic updates per actor and target update: 1 for MADDPG (MATD3 delays its actors)."""
    policy: MADDPGPolicy
    replay_buffer: MultiAgentReplayBuffer
    actor: MultiAgentActor
    actor_target: MultiAgentActor
    critic: MultiAgentCritic
    critic_target: MultiAgentCritic

    def __init__(
        self,
        policy: str | type[MADDPGPolicy],
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
        # Every numeric argument in its range, before SB3 takes it as given (locals(): the arguments, by name).
        check_arguments(TEAM_ALGORITHM_RANGES, locals())
        validate_critic_sharing(critic_sharing)  # fail early on an unknown name
        update_rule = UpdateSchedule.from_arguments(transitions_per_update, train_freq, gradient_steps)
        if env is not None and not isinstance(env, str):
            refuse_unsupported_env(env)
        super().__init__(
            policy,
            env,  # type: ignore[arg-type]  # None when loading
            learning_rate,
            buffer_size,
            learning_starts,
            batch_size,
            tau,
            gamma,
            1 if train_freq is None else train_freq,  # None: derived from n_envs in _setup_model
            1 if gradient_steps is None else gradient_steps,  # None with train_freq None: earned per rollout
            action_noise=action_noise,
            replay_buffer_class=replay_buffer_class or MultiAgentReplayBuffer,
            replay_buffer_kwargs=replay_buffer_kwargs,
            policy_kwargs=policy_kwargs,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            verbose=verbose,
            device=device,
            seed=seed,
            sde_support=False,
            supported_action_spaces=(spaces.Box,),
            support_multi_env=True,
        )
        self.critic_sharing = critic_sharing
        self.critic_sharing_kwargs = dict(critic_sharing_kwargs or {})
        self.max_grad_norm = max_grad_norm
        self.actor_reg_coef = float(actor_reg_coef)
        self._set_up_team(critic_sharing, selector, update_rule, noise_std, warn_selection=_init_setup_model)
        if _init_setup_model:
            self._setup_model()

    def _team_policy_kwargs(self) -> dict[str, Any]:
        return {
            **super()._team_policy_kwargs(),
            "critic_sharing": self.critic_sharing,
            "critic_sharing_kwargs": self.critic_sharing_kwargs,
            "selection_size": self.selection_size,
        }

    def _setup_model(self) -> None:
        super()._setup_model()
        assert self.agent_layout is not None
        self._action_parts = ActionParts.of(self.agent_layout, self.device)  # whose each action component is
        self._create_aliases()

    def _create_aliases(self) -> None:
        self.actor = self.policy.actor
        self.actor_target = self.policy.actor_target
        self.critic = self.policy.critic
        self.critic_target = self.policy.critic_target

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        # Switch to train mode (this affects batch norm / dropout)
        self.policy.set_training_mode(True)
        # Update learning rate according to lr schedule
        self._update_learning_rate([self.actor.optimizer, self.critic.optimizer])
        losses: list[StepLosses] = []
        for _ in range(gradient_steps):
            self._n_updates += 1
            # Sample replay buffer: one joint batch, the same rows for every agent (and every critic of one)
            replay_data = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)

            # y_i = r_i + gamma * (1 - done_i) * Q_i'(o', mu'(o')), every agent's target action on its next observation
            target_q_values = self._critic_targets(replay_data)
            # Each critic's loss on the batch, its extractor recording its diagnostics (e.g. attention weights)
            with self.critic.recording_diagnostics():
                critic_loss = critic_losses(self.critic.trained_q, replay_data, target_q_values)
            gradient_step(self.critic, critic_loss.sum(), self.max_grad_norm)
            critic_log = critic_loss.detach().reshape(-1, critic_loss.shape[-1]).mean(0)  # mean over an agent's critics

            # Delayed policy updates (MATD3's; MADDPG updates the actors at every critic update)
            actor_terms = None
            if self._n_updates % self.policy_delay == 0:
                # -Q_i with a_i replaced by mu_i(o_i), the others' actions as sampled, plus the regulariser
                actor_terms = actor_loss_terms(
                    self.actor.forward_with_preactivation, self.critic, replay_data, self._action_parts, self.actor_reg_coef
                )
                gradient_step(self.actor, actor_terms.total.sum(), self.max_grad_norm)
                polyak_update_foreach(
                    [*self.critic.parameters(), *self.actor.parameters()],
                    [*self.critic_target.parameters(), *self.actor_target.parameters()],
                    self.tau,
                )
            losses.append(step_losses(critic_log, actor_terms))
        # Kept on the device until here: one transfer per train() call, not one per gradient step.
        self._log_losses(**summarise_steps(losses))

    def _critic_targets(self, data: MultiAgentReplayBufferSamples) -> th.Tensor:
        """The team's critic targets on a replay batch (no gradient), ``[batch, n_agents]``: the functions a run group
        applies to each of its runs (:func:`~sb3_maddpg.common.losses.team_critic_targets`)."""
        settings = self._step_settings()
        return team_critic_targets(
            self.actor_target, self.critic_target, data, self.gamma, self._action_parts.continuous, settings.smoothing
        )

    def _step_settings(self) -> StepSettings:
        """:return: A run group's update step's hyperparameters, as they are now."""
        return StepSettings(self.gamma, self.tau, self.actor_reg_coef, self.max_grad_norm, self._action_parts)

    def _log_losses(self, **losses: th.Tensor) -> None:
        """Record the train call's per-agent means (``[n_agents]`` each, by name), each agent's and the team's."""
        assert self.agent_layout is not None
        record_losses(self.logger, self.agent_layout.agent_ids, self._n_updates, losses)

    def _record_diagnostics(self) -> None:
        """Each critic's extractor's diagnostics (e.g. whom an attention critic listens to), of the last critic batch."""
        assert self.agent_layout is not None
        record_critic_diagnostics(self.logger, self.agent_layout.agent_ids, self.critic.diagnostics())

    def _excluded_save_params(self) -> list[str]:
        return [
            *super()._excluded_save_params(),
            "actor",
            "critic",
            "actor_target",
            "critic_target",
            "_action_parts",
        ]

    def _get_torch_save_params(self) -> tuple[list[str], list[str]]:
        return ["policy", "actor.optimizer", "critic.optimizer"], []
