"""MADDPG on SB3's off-policy base, with the critic's information sharing as a swappable part."""

import io
import math
import pathlib
import warnings
from collections.abc import Sequence
from typing import Any, ClassVar, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, RolloutReturn, Schedule, TrainFreq
from stable_baselines3.common.utils import polyak_update
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg.buffers import MultiAgentReplayBuffer, MultiAgentReplayBufferSamples
from sb3_maddpg.compat import attributes_missing_from, pop_0_2_dev_schedule, read_saved_data
from sb3_maddpg.env_checks import (
    check_same_layout,
    layout_of,
    refuse_env_of_another_team,
    refuse_reward_normalization,
    refuse_unsupported_env,
)
from sb3_maddpg.layout import AgentLayout
from sb3_maddpg.losses import SATURATION_THRESHOLD as SATURATION_THRESHOLD  # import paths of 0.2.0.dev
from sb3_maddpg.losses import ActionParts, TeamNetworks, actor_loss_terms, critic_losses, critic_targets, one_member
from sb3_maddpg.losses import ActorLossTerms as ActorLossTerms
from sb3_maddpg.noise import add_noise, default_noise, discrete_components, fit_noise_to_envs
from sb3_maddpg.policies import MADDPGPolicy, MlpPolicy, MultiAgentActor, MultiAgentCritic
from sb3_maddpg.selection import Selector, resolve_selection, warn_if_selecting_everyone
from sb3_maddpg.sharing import CriticSharing, schemes_per_agent, validate_critic_sharing
from sb3_maddpg.update_schedule import UpdateSchedule

SelfMADDPG = TypeVar("SelfMADDPG", bound="MADDPG")

LOG_INTERVAL = 1000
"""Default ``log_interval`` of :meth:`MADDPG.learn`, in finished episodes: 40 log tables per 1M steps of 25-step episodes."""


class MADDPG(OffPolicyAlgorithm):
    """
    Multi-Agent DDPG with selectable critic information sharing.

    MADDPG: Lowe et al. (2017) https://arxiv.org/abs/1706.02275. Sharing schemes: Sakagami and
    Takadama, "What Kind of Information Is Needed? Multi-Agent Reinforcement Learning that
    Selectively Shares Information from Other Agents". Each agent i has its own deterministic actor
    mu_i(o_i) and its own critic Q_i, whose input the sharing scheme builds from the joint
    observation, the joint action and (for ``"selected"``) the agents i selected.
    Defaults are the paper's (from Lowe et al.).

    :param policy: The policy model to use (``"MlpPolicy"`` or a :class:`~sb3_maddpg.policies.MADDPGPolicy` subclass).
    :param env: The environment to learn from: a :class:`~sb3_maddpg.envs.PettingZooToGym` env (or a VecEnv of
        them, or a registered id), which exposes ``agent_layout`` and ``info["agent_rewards"]``.
    :param critic_sharing: What critic i sees: ``"independent"`` (IDDPG), ``"full"`` (MADDPG),
        ``"observations"`` (MADDPG-fo), ``"actions"`` (MADDPG-fa), ``"selected"`` (MADDPG-soa), the paper's
        short names ``"iddpg"``, ``"maddpg"``, ``"fo"``, ``"fa"``, ``"soa"``, beyond the paper ``"attention"`` and
        ``"learned_selection"`` (:mod:`sb3_maddpg.attention`), or a :class:`~sb3_maddpg.sharing.CriticFeaturesExtractor`
        subclass; or a mapping from each agent id to its own critic's scheme, e.g. ``{"adversary_0": "full",
        "agent_0": "independent", "agent_1": "independent"}``.
    :param selection: For schemes that use a selection: a :class:`~sb3_maddpg.selection.Selector`, or an int
        ``k`` for ``NearestAgents(k)`` (default ``NearestAgents(k=2)``). It is applied to the observation when a
        transition is stored. A ``k`` of ``n_agents - 1`` selects every other agent (full sharing in another order)
        and gets a warning.
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
    :param replay_buffer_class: Replay buffer class (default :class:`~sb3_maddpg.buffers.MultiAgentReplayBuffer`).
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
        selection: Selector | int | None = None,
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
        validate_critic_sharing(critic_sharing)  # fail early on an unknown name
        if not (math.isfinite(actor_reg_coef) and actor_reg_coef >= 0):
            raise ValueError(
                f"actor_reg_coef must be a finite number >= 0, got {actor_reg_coef}: use 1e-3 (Lowe et al.'s value) "
                "or 0 to turn the actor regulariser off."
            )
        if max_grad_norm is not None and not max_grad_norm > 0:
            raise ValueError(
                f"max_grad_norm must be > 0 (the largest norm each agent's gradient is clipped to), got {max_grad_norm}: "
                "use 0.5 (Lowe et al.'s value), or None to turn gradient clipping off."
            )
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
        self.update_rule = update_rule
        """When the model takes gradient steps (see :attr:`update_schedule`)."""
        self._logs_dumped_at = -1
        self._warned_never_updated = False  # not saved: a loaded model may warn once more
        self.noise_std = noise_std
        self.agent_layout: AgentLayout | None = None
        self.selection: Selector | None = None
        if self.env is not None:
            self.agent_layout = layout_of(self.env)
            refuse_reward_normalization(self.env)
            schemes = schemes_per_agent(critic_sharing, self.agent_layout.agent_ids)
            for scheme in dict.fromkeys(schemes):  # a team a scheme cannot serve: say so before the selection's errors
                scheme.check_layout(self.agent_layout)
            if any(scheme.uses_selection for scheme in schemes):
                self.selection = resolve_selection(selection)
                self.selection.validate(self.agent_layout)
                if _init_setup_model:  # load() sets the saved selection over this one
                    warn_if_selecting_everyone(self.selection, self.agent_layout)
            elif selection is not None:
                raise ValueError(
                    f"selection is used only by schemes that read one (critic_sharing='selected'), got "
                    f"critic_sharing={critic_sharing!r}: drop selection or use critic_sharing='selected'."
                )
            if self.action_noise is None:
                assert isinstance(self.action_space, spaces.Box)
                self.action_noise = default_noise(self.agent_layout, noise_std, self.action_space)
        if _init_setup_model:
            self._setup_model()

    def _setup_model(self) -> None:
        if self.agent_layout is None:
            raise ValueError("MADDPG needs an env to read the agent layout from (or a saved model to load).")
        if self.env is not None:  # on load(path, env=...), SB3 compares only the spaces
            check_same_layout(layout_of(self.env), self.agent_layout)
        selection_size = self.selection.k if self.selection is not None else 0
        # New dicts: SB3 keeps the caller's, which must not change under them.
        if self.replay_buffer_class is not None and issubclass(self.replay_buffer_class, MultiAgentReplayBuffer):
            self.replay_buffer_kwargs = {**self.replay_buffer_kwargs, "layout": self.agent_layout, "selector": self.selection}
        self.policy_kwargs = dict(
            self.policy_kwargs,
            agent_layout=self.agent_layout,
            critic_sharing=self.critic_sharing,
            critic_sharing_kwargs=self.critic_sharing_kwargs,
            selection_size=selection_size,
        )
        pop_0_2_dev_schedule(self.__dict__)  # a 0.2.0 development save's old attributes (load() read them)
        self.train_freq = self.update_rule.train_freq(self.n_envs) or self.train_freq  # type: ignore[assignment]
        super()._setup_model()
        self._create_aliases()
        self._action_parts = ActionParts.of(self.agent_layout, self.device)  # whose each action component is
        self._discrete_components = discrete_components(self.agent_layout)  # one-hots: no exploration noise

    @property
    def transitions_per_update(self) -> int:
        """Transitions (all envs counted) per gradient step of the per-transition rule."""
        return self.update_rule.transitions_per_update

    @property
    def update_schedule(self) -> str:
        """When the model updates, in words (e.g. for a log line)."""
        assert isinstance(self.train_freq, TrainFreq), "_setup_model() converts train_freq"
        return self.update_rule.describe(
            self.train_freq, self.n_envs, self.gradient_steps, self.batch_size, self.learning_starts
        )

    def collect_rollouts(
        self,
        env: VecEnv,
        callback: BaseCallback,
        train_freq: TrainFreq,
        replay_buffer: ReplayBuffer,
        action_noise: ActionNoise | None = None,
        learning_starts: int = 0,
        log_interval: int | None = None,
    ) -> RolloutReturn:
        rollout = super().collect_rollouts(
            env, callback, train_freq, replay_buffer, action_noise, learning_starts, log_interval
        )
        if self.update_rule.earns_gradient_steps:
            # SB3's learn() reads self.gradient_steps right after this call: the steps this rollout earned.
            self.gradient_steps = self.update_rule.earned(self.num_timesteps, self.learning_starts)
        return rollout

    def _setup_learn(
        self,
        total_timesteps: int,
        callback: MaybeCallback = None,
        reset_num_timesteps: bool = True,
        tb_log_name: str = "run",
        progress_bar: bool = False,
    ) -> tuple[int, BaseCallback]:
        if self.env is not None:  # a noise vectorised for another number of envs: SB3 vectorises it again
            self.action_noise = fit_noise_to_envs(self.action_noise, self.env.num_envs)
        result = super()._setup_learn(total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar)
        if reset_num_timesteps:  # timesteps count from 0 again, and so do the credit and the last log step
            self.update_rule.reset()
            self._logs_dumped_at = -1
        return result

    def dump_logs(self) -> None:
        """
        Write the logs at most once per env step (SB3 asks at finished episodes, which many envs end together), with
        what each critic's features extractor reports.
        """
        if self._logs_dumped_at == self.num_timesteps:
            return
        self._logs_dumped_at = self.num_timesteps
        self._log_critic_diagnostics()
        super().dump_logs()

    def _create_aliases(self) -> None:
        self.actor = self.policy.actor
        self.actor_target = self.policy.actor_target
        self.critic = self.policy.critic
        self.critic_target = self.policy.critic_target
        self._team = TeamNetworks(self.actor, self.critic, self.actor_target, self.critic_target)  # for the losses

    def _sample_action(
        self, learning_starts: int, action_noise: ActionNoise | None = None, n_envs: int = 1
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        The exploration action: uniformly random before ``learning_starts``, then every actor on its own
        observation; plus noise in the [-1, 1] space, clipped to [-1, 1].

        Same result as SB3's version, without ``predict``'s unscale-then-rescale round trip on every step, and with
        a clear error when the noise does not fit the joint action.

        :param learning_starts: Env steps of uniformly random actions before the actors act.
        :param action_noise: Noise added to the actors' actions.
        :param n_envs: Number of envs.
        :return: The action for the env and the [-1, 1] action for the replay buffer.
        """
        if self.num_timesteps < learning_starts:
            # SB3's warm-up: uniform actions over the Box (a discrete agent's: a uniform choice, one-hot).
            unscaled = np.array([self.action_space.sample() for _ in range(n_envs)])
            buffer_action = self._one_hot_discrete(self.policy.scale_action(unscaled))
        else:
            with th.no_grad():
                observations = th.as_tensor(self._last_obs, dtype=th.float32, device=self.device)
                buffer_action = self.actor.sample(observations.reshape(n_envs, -1)).cpu().numpy()
        if action_noise is not None:
            buffer_action = add_noise(buffer_action, action_noise, self._discrete_components)
        return self.policy.unscale_action(buffer_action), buffer_action

    def _one_hot_discrete(self, actions: np.ndarray) -> np.ndarray:
        """Each discrete agent's slot of ``[-1, 1]`` actions made the one-hot of its largest entry (in place)."""
        layout = self.agent_layout
        assert layout is not None
        for i, part in enumerate(layout.action_slices):
            if layout.is_discrete(i):
                chosen = actions[:, part].argmax(axis=1)
                actions[:, part] = -1.0
                actions[np.arange(len(actions)), part.start + chosen] = 1.0
        return actions

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        # Switch to train mode (this affects batch norm / dropout)
        self.policy.set_training_mode(True)
        # Update learning rate according to lr schedule
        self._update_learning_rate([self.actor.optimizer, self.critic.optimizer])
        team = self._team  # the losses' view of the networks: a member dimension of 1 in front
        critic_log, actor_log, reg_log, saturation_log = [], [], [], []
        actor_params = list(self.actor.parameters())
        for _ in range(gradient_steps):
            self._n_updates += 1
            # Sample replay buffer: one joint batch, the same rows for every agent
            replay_data = one_member(self.replay_buffer.sample(batch_size, env=self._vec_normalize_env))
            # Critic targets: every target actor on its next observation, then every target critic (no gradient)
            target_q = critic_targets(team.target_actions, team.target_q, replay_data, self.gamma)
            # Critic losses, while the critics' extractors record their diagnostics (this batch, as replayed)
            with self.critic.recording_diagnostics():
                critic_loss = critic_losses(team.q, replay_data, target_q)
            # Optimize the critics: agents' parameters are disjoint, each gets its own loss's gradient
            self.critic.optimizer.zero_grad()
            critic_loss.sum().backward()
            if self.max_grad_norm is not None:
                self.critic.clip_grad_norm_per_agent(self.max_grad_norm)
            self.critic.optimizer.step()
            # Actor losses: -Q_i with only a_i replaced by mu_i(o_i), plus the regulariser
            actor_terms = actor_loss_terms(team.policy, team.q, replay_data, self._action_parts, self.actor_reg_coef)
            # Optimize the actors, computing only the actors' gradients (the critics' are not needed here)
            self.actor.optimizer.zero_grad()
            for param, grad in zip(actor_params, th.autograd.grad(actor_terms.total.sum(), actor_params)):
                param.grad = grad
            if self.max_grad_norm is not None:
                self.actor.clip_grad_norm_per_agent(self.max_grad_norm)
            self.actor.optimizer.step()
            # Update the target networks (Polyak averaging)
            polyak_update(self.critic.parameters(), self.critic_target.parameters(), self.tau)
            polyak_update(self.actor.parameters(), self.actor_target.parameters(), self.tau)
            # Kept on the device: one transfer per train() call, not one per gradient step.
            critic_log.append(critic_loss[0].detach())
            actor_log.append(actor_terms.policy_loss[0].detach())
            reg_log.append(actor_terms.reg_loss[0].detach())
            saturation_log.append(actor_terms.saturation[0])

        self._log_losses(*(th.stack(log).mean(0) for log in (critic_log, actor_log, reg_log, saturation_log)))

    def _critic_targets(self, data: MultiAgentReplayBufferSamples) -> th.Tensor:
        """The team's critic targets (:func:`~sb3_maddpg.losses.critic_targets`) on a replay batch, ``[batch, n_agents]``."""
        return critic_targets(self._team.target_actions, self._team.target_q, one_member(data), self.gamma)[0]

    def _log_losses(
        self, critic_losses: th.Tensor, actor_losses: th.Tensor, actor_reg_losses: th.Tensor, saturation: th.Tensor
    ) -> None:
        """
        Record the train call's per-agent means, each agent's and the team's (the mean over agents).

        :param critic_losses: ``[n_agents]``.
        :param actor_losses: The policy-gradient part of the actor losses, ``[n_agents]``.
        :param actor_reg_losses: The actor regulariser, ``[n_agents]``.
        :param saturation: Fraction of saturated action components, ``[n_agents]``.
        """
        assert self.agent_layout is not None
        names = ("critic_loss", "actor_loss", "actor_reg_loss", "action_saturation")
        per_agent = th.stack((critic_losses, actor_losses, actor_reg_losses, saturation)).tolist()  # one transfer
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        for name, values in zip(names, per_agent):
            self.logger.record(f"train/{name}", sum(values) / len(values))
            for agent, value in zip(self.agent_layout.agent_ids, values):
                self.logger.record(f"train/{agent}/{name}", value)

    def _log_critic_diagnostics(self) -> None:
        """
        Record each critic's extractor's diagnostics (e.g. whom an attention critic listens to), from the last critic
        update's batch: computed only when the logs are written, not at every update.
        """
        assert self.agent_layout is not None
        diagnostics = self.critic.diagnostics()
        for name in sorted({key for summary in diagnostics for key in summary}):
            values = [summary[name] for summary in diagnostics if name in summary]
            self.logger.record(f"train/{name}", sum(values) / len(values))
            for agent, summary in zip(self.agent_layout.agent_ids, diagnostics):
                if name in summary:
                    self.logger.record(f"train/{agent}/{name}", summary[name])

    def learn(
        self: SelfMADDPG,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int = LOG_INTERVAL,
        tb_log_name: str = "MADDPG",
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfMADDPG:
        """
        Train the model. The first ``learning_starts`` steps (25,600 by default) are uniformly random actions that
        fill the replay buffer, with no gradient update: a ``learn()`` that ends before the first update says so in
        a warning.

        :param total_timesteps: Env steps to train for (all envs counted); a lower bound, as in SB3.
        :param callback: Callback(s) called at every step.
        :param log_interval: Finished episodes (all envs counted) between two writes of the logs (the table that
            ``verbose=1`` prints). The default, 1000, is every 25,000 steps of simple_spread's 25-step episodes:
            40 tables for 1M steps, whatever the number of envs (SB3's default of 4 would print 10,000).
        :param tb_log_name: The name of the run for TensorBoard logging.
        :param reset_num_timesteps: Whether to count timesteps from 0 again (False to continue a run).
        :param progress_bar: Display a progress bar (needs tqdm and rich).
        :return: The trained model.
        """
        result = super().learn(
            total_timesteps=total_timesteps,
            callback=callback,
            log_interval=log_interval,
            tb_log_name=tb_log_name,
            reset_num_timesteps=reset_num_timesteps,
            progress_bar=progress_bar,
        )
        self._warn_if_never_updated()
        return result

    def _warn_if_never_updated(self) -> None:
        """Say once, naming learning_starts, that the model has not been trained at all: a short run is otherwise silent."""
        explicitly_no_updates = not self.update_rule.earns_gradient_steps and self.gradient_steps == 0
        if self._n_updates > 0 or self._warned_never_updated or explicitly_no_updates:
            return
        self._warned_never_updated = True
        warnings.warn(
            f"learn() ended at step {self.num_timesteps:,} without a single gradient update: the first "
            f"learning_starts={self.learning_starts:,} steps (all envs counted) are uniformly random actions that fill "
            f"the replay buffer, and then the model takes {self.update_schedule}. Train for longer, or lower "
            "learning_starts for a short test (e.g. MADDPG(..., learning_starts=2_000)).",
            UserWarning,
            stacklevel=3,
        )

    def set_env(self, env: GymEnv, force_reset: bool = True) -> None:
        """
        Use a new env; it must have the same agent layout as the model.

        :param env: The new environment.
        :param force_reset: Force a reset before the next ``learn``.
        """
        # Check before replacing: a refused env must not stay in the model.
        wrapped = self._wrap_env(env, self.verbose)
        check_same_layout(layout_of(wrapped), self.agent_layout)
        refuse_reward_normalization(wrapped)
        super().set_env(wrapped, force_reset)

    @classmethod
    def load(  # type: ignore[override]  # the same signature as SB3's, typed for MADDPG
        cls: type[SelfMADDPG],
        path: str | pathlib.Path | io.BufferedIOBase,
        env: GymEnv | None = None,
        device: th.device | str = "auto",
        custom_objects: dict[str, Any] | None = None,
        print_system_info: bool = False,
        force_reset: bool = True,
        **kwargs: Any,
    ) -> SelfMADDPG:
        """
        Load a saved model (SB3's ``load``); an ``env`` must be of the model's team (the same agents, order and sizes).

        :param path: The saved model (``.zip`` optional) or an open file.
        :param env: The env to train or evaluate on, or ``None`` (``predict`` needs none).
        :param device: Device to load the model on.
        :param custom_objects: Objects to replace on load (SB3's argument).
        :param print_system_info: Print the system the model was saved on and this one.
        :param force_reset: Reset the env before the next ``learn``.
        :param kwargs: Attributes to set on the model over the saved ones.
        :return: The model.
        """
        data = read_saved_data(path, custom_objects)  # read once: for the team check and for older saves
        if env is not None:
            refuse_env_of_another_team(data, env)
        # What an older save lacks, filled with what its version implies; the caller's kwargs over it.
        missing = {} if data is None else attributes_missing_from(data)
        return super().load(path, env, device, custom_objects, print_system_info, force_reset, **{**missing, **kwargs})

    def load_replay_buffer(self, path: str | pathlib.Path | io.BufferedIOBase, truncate_last_traj: bool = True) -> None:
        """
        Load a replay buffer saved by :meth:`save_replay_buffer`; it must be of this model's team.

        :param path: Path to the pickled replay buffer.
        :param truncate_last_traj: SB3's argument (used by ``HerReplayBuffer`` only).
        """
        current = self.replay_buffer
        super().load_replay_buffer(path, truncate_last_traj)
        try:
            self._check_replay_buffer(self.replay_buffer)
        except (TypeError, ValueError):
            self.replay_buffer = current  # a refused buffer must not stay in the model
            raise
        self.replay_buffer.selector = self.selection  # new rows: the model's rule, of the same size k

    def _check_replay_buffer(self, buffer: ReplayBuffer) -> None:
        """Refuse a buffer of another agent layout, selection size or number of envs: its rows would be misread."""
        if not isinstance(buffer, MultiAgentReplayBuffer):
            raise TypeError(
                f"The replay buffer is a {type(buffer).__name__}, not a MultiAgentReplayBuffer: it has no per-agent "
                "rewards. Load a buffer saved by a MADDPG model's save_replay_buffer()."
            )
        k = self.selection.k if self.selection is not None else 0
        if (buffer.layout, buffer.selection_size, buffer.n_envs) != (self.agent_layout, k, self.n_envs):
            raise ValueError(
                f"The replay buffer holds transitions of agent layout {buffer.layout} with selections of "
                f"k={buffer.selection_size} from {buffer.n_envs} env(s), but this model has agent layout "
                f"{self.agent_layout} with k={k} and {self.n_envs} env(s): load a buffer saved by a model of the same "
                "team (same agents, sizes and order), the same selection size and the same number of envs."
            )

    def _excluded_save_params(self) -> list[str]:
        return [
            *super()._excluded_save_params(),
            "actor",
            "critic",
            "actor_target",
            "critic_target",
            "_team",
            "_action_parts",
            "_discrete_components",
            "_warned_never_updated",
        ]

    def _get_torch_save_params(self) -> tuple[list[str], list[str]]:
        return ["policy", "actor.optimizer", "critic.optimizer"], []
