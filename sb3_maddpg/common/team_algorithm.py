"""SB3's off-policy loop for a team of agents: what MADDPG and MATD3 share besides their update.

The team's agent layout read from the env and checked wherever an env or a replay buffer comes in; the selection
rule of the schemes that use one; exploration in the policy's [-1, 1] space; the per-transition update rule's hooks
into SB3's loop; the logs; the version in every save.
"""

import io
import pathlib
import warnings
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.noise import ActionNoise
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, RolloutReturn, TrainFreq
from stable_baselines3.common.vec_env import VecEnv

from sb3_maddpg.common.buffers import (
    MultiAgentReplayBuffer,
    loading_a_saved_model,
    refuse_buffer_of_another_team,
    replay_buffer_bytes,
)
from sb3_maddpg.common.env_checks import check_same_layout, layout_of, refuse_env_of_another_team, refuse_reward_normalization
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.memory_release import release_freed_memory
from sb3_maddpg.common.noise import add_noise, default_noise, fit_noise_to_envs
from sb3_maddpg.common.package_warnings import SB3MADDPGWarning
from sb3_maddpg.common.selection import Selector, resolve_selector, warn_if_selecting_everyone
from sb3_maddpg.common.torch_threads import package_threads
from sb3_maddpg.common.train_logs import record_agent_returns
from sb3_maddpg.common.update_schedule import UpdateSchedule
from sb3_maddpg.common.user_code import user_stacklevel
from sb3_maddpg.compat import VERSION_KEY, read_saved_data, written_by
from sb3_maddpg.sharing import CriticSharing, schemes_per_agent
from sb3_maddpg.version import __version__

if TYPE_CHECKING:  # the algorithms' policy; the base class only names its type
    from sb3_maddpg.maddpg.policies import MADDPGPolicy

SelfTeamAlgorithm = TypeVar("SelfTeamAlgorithm", bound="TeamOffPolicyAlgorithm")

LOG_INTERVAL = 1000
"""Default ``log_interval`` of ``learn``, in finished episodes: 40 log tables per 1M steps of 25-step episodes."""


class TeamOffPolicyAlgorithm(OffPolicyAlgorithm):
    """
    SB3's ``OffPolicyAlgorithm`` for a team whose joint observation and action an
    :class:`~sb3_maddpg.common.layout.AgentLayout` describes. A subclass calls :meth:`_set_up_team` in its constructor,
    after SB3's, and implements ``train``.
    """

    policy: "MADDPGPolicy"
    replay_buffer: MultiAgentReplayBuffer
    agent_layout: AgentLayout | None
    selector: Selector | None
    update_rule: UpdateSchedule
    _memory_released_at: int = 0
    """The gradient steps at the last release of freed heap memory (:mod:`~sb3_maddpg.common.memory_release`)."""

    def _set_up_team(
        self,
        critic_sharing: CriticSharing,
        selector: Selector | int | dict[str, Any] | None,
        update_rule: UpdateSchedule,
        noise_std: float | Sequence[float],
        warn_selection: bool,
    ) -> None:
        """
        Read the team from the env (if any), and set what depends on it. Called by a subclass's constructor.

        :param critic_sharing: What each critic sees (see :class:`~sb3_maddpg.MADDPG`).
        :param selector: The selection rule asked for, or None for the default.
        :param update_rule: When the model takes gradient steps.
        :param noise_std: The default exploration noise's standard deviation (see :class:`~sb3_maddpg.MADDPG`).
        :param warn_selection: Whether to warn of a selection of every other agent (not on load: the save's rule wins).
        """
        self.update_rule = update_rule
        """When the model takes gradient steps (see :attr:`update_schedule`)."""
        self.noise_std = noise_std
        self._logs_dumped_at = -1
        self._warned_never_updated = False  # not saved: a loaded model may warn once more
        self._warned_empty_resume = False  # not saved, as above
        # Each env's running per-agent return in the episode under way, [n_envs, n_agents] (None: none under way).
        self._agent_episode_returns: np.ndarray | None = None
        self.agent_layout = None
        self.selector = None
        noise = self.action_noise
        if noise is not None and not (isinstance(noise, ActionNoise) or (callable(noise) and hasattr(noise, "reset"))):
            raise TypeError(  # else a str or a number fails at the first noisy step, far from its cause; SB3 only calls it
                f"action_noise must be an SB3 ActionNoise (or a callable with reset()) or None, got {type(noise).__name__} "
                f"{noise!r}: use e.g. NormalActionNoise(np.zeros(d), sigma * np.ones(d)) over the joint "
                f"action, or leave it None and set noise_std."
            )
        if self.env is None:
            return
        self.agent_layout = layout_of(self.env)
        refuse_reward_normalization(self.env)
        schemes = schemes_per_agent(critic_sharing, self.agent_layout.agent_ids)
        for scheme in dict.fromkeys(schemes):  # a team a scheme cannot serve: say so before the selection's errors
            scheme.check_layout(self.agent_layout)
        if any(scheme.uses_selection for scheme in schemes):
            self.selector = resolve_selector(selector)
            self.selector.validate(self.agent_layout)
            if warn_selection:
                warn_if_selecting_everyone(self.selector, self.agent_layout)
        elif selector is not None:
            raise ValueError(
                f"selector is used only by schemes that read a selection (critic_sharing='selected'), got "
                f"critic_sharing={critic_sharing!r}: drop selector or use critic_sharing='selected'."
            )
        if self.action_noise is None:
            assert isinstance(self.action_space, spaces.Box)
            self.action_noise = default_noise(self.agent_layout, noise_std, self.action_space)

    def _setup_model(self) -> None:
        if self.agent_layout is None:
            raise ValueError(f"{type(self).__name__} needs an env to read the agent layout from (or a saved model to load).")
        if self.env is not None:  # on load(path, env=...), SB3 compares only the spaces
            check_same_layout(layout_of(self.env), self.agent_layout)
        self.__dict__.pop(VERSION_KEY, None)  # the version load() read from the save: the next save writes its own
        # A new dict: SB3 keeps the caller's, which must not change under them.
        if self.replay_buffer_class is not None and issubclass(self.replay_buffer_class, MultiAgentReplayBuffer):
            self.replay_buffer_kwargs = {**self.replay_buffer_kwargs, "layout": self.agent_layout, "selector": self.selector}
            if self.verbose >= 1 and self.replay_buffer is None:  # said before the arrays exist (refused if too large)
                selector, layout = self.selector, self.agent_layout
                next_stored = selector is not None and selector.stores_next_selection(layout)
                needed = replay_buffer_bytes(self.buffer_size, self.n_envs, layout, self.selection_size, next_stored)
                print(f"Replay buffer: {self.buffer_size:,} joint transitions, {needed / 2**30:.2f} GiB once full")
        self.policy_kwargs = {**self.policy_kwargs, **self._team_policy_kwargs()}  # a new dict, as above
        self.train_freq = self.update_rule.train_freq(self.n_envs) or self.train_freq  # type: ignore[assignment]
        super()._setup_model()
        self._discrete_components = self.agent_layout.discrete_components()  # one-hots: no exploration noise

    def _team_policy_kwargs(self) -> dict[str, Any]:
        """:return: What the policy needs to know of the team, over the caller's ``policy_kwargs``."""
        return {"agent_layout": self.agent_layout}

    @property
    def selection_size(self) -> int:
        """How many other agents the selection rule selects for each agent (0 without one)."""
        return 0 if self.selector is None else self.selector.k

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
        # The heap the last gradient steps freed goes back to the system (sb3_maddpg.common.memory_release).
        self._memory_released_at = release_freed_memory(self._n_updates, self._memory_released_at)
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
        resets_env = reset_num_timesteps or self._last_obs is None  # as SB3 decides below
        result = super()._setup_learn(total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar)
        if resets_env:  # new episodes: no agent has earned anything in them yet
            self._agent_episode_returns = None
        if reset_num_timesteps:  # timesteps count from 0 again, and so do the credit and the last log step
            self.update_rule.reset()
            self._logs_dumped_at = -1
        return result

    def _sample_action(
        self, learning_starts: int, action_noise: ActionNoise | None = None, n_envs: int = 1
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        The exploration action: SB3's, with the same result, without ``predict``'s unscale-then-rescale round trip on
        every step, and with a clear error when the noise does not fit the joint action.

        :param learning_starts: Env steps of uniformly random actions (a discrete agent's: a uniform one-hot).
        :param action_noise: Noise added in the [-1, 1] space, then clipped to it.
        :param n_envs: Number of envs.
        :return: The action for the env and the [-1, 1] action for the replay buffer.
        """
        assert self.agent_layout is not None
        if self.num_timesteps < learning_starts:
            unscaled = np.array([self.action_space.sample() for _ in range(n_envs)])
            buffer_action = self.agent_layout.one_hot_discrete(self.policy.scale_action(unscaled))
        else:
            with th.no_grad():
                observations = th.as_tensor(self._last_obs, dtype=th.float32, device=self.device)
                buffer_action = self.policy.actor.sample(observations.reshape(n_envs, -1)).cpu().numpy()
        if action_noise is not None:
            buffer_action = add_noise(buffer_action, action_noise, self._discrete_components)
        return self.policy.unscale_action(buffer_action), buffer_action

    def predict_agents(self, observations: Mapping[Any, Any], deterministic: bool = True) -> dict[Any, np.ndarray | int]:
        """
        Each agent's action from each agent's observation, in PettingZoo's terms (``predict`` takes and gives the
        joint vectors, as SB3's envs do): ``actions = model.predict_agents(observations)``, then
        ``observations, *_ = parallel_env.step(actions)``. Agents are matched by id, in any order.

        :param observations: One step's observation of every agent of the team still in the episode, by agent id (a
            PettingZoo ``ParallelEnv``'s ``reset()`` or ``step()``): an agent that has left is seen as zeros and gets no
            action; an agent not in the team is refused.
        :param deterministic: As in ``predict`` (MADDPG's actors are deterministic either way).
        :return: Each agent's action in the env's units, by agent id: its slice of ``predict``'s joint action (a
            continuous agent's float32 vector, rescaled from the policy's [-1, 1] to its ``Box``), or for a discrete
            agent the index of its choice (an ``int``, which a ``Discrete`` space takes).
        """
        return self.policy.predict_agents(observations, deterministic)

    def _update_info_buffer(self, infos: list[dict[str, Any]], dones: np.ndarray | None = None) -> None:
        """
        SB3's episode statistics, with each agent's return: its rewards (``info["agent_rewards"]``) summed over the
        episode and added, as ``agent_returns`` (a list of floats, layout order), to the episode's ``info["episode"]``
        (Monitor's or VecMonitor's), which SB3 keeps for ``rollout/ep_rew_mean``: the per-agent means then cover the
        same episodes (the last ``stats_window_size``), are saved with them, and callbacks see them.

        :param infos: Each env's info of the step.
        :param dones: Whether each env's episode ended at the step.
        """
        assert self.agent_layout is not None
        returns = self._agent_episode_returns
        if returns is None or len(returns) != len(infos):
            returns = self._agent_episode_returns = np.zeros((len(infos), self.agent_layout.n_agents))
        # Once per env step over up to hundreds of envs: one array operation for the rewards, a loop over ended episodes.
        rewards = [info.get("agent_rewards") for info in infos]
        has_rewards = [reward is not None for reward in rewards]  # a custom VecEnv's may lack them: no agent returns
        if all(has_rewards):
            returns += np.asarray(rewards)
        else:
            for index, reward in enumerate(rewards):
                if reward is not None:
                    returns[index] += reward
        ended: set[int] = {index for index, info in enumerate(infos) if "episode" in info}
        ended.update(np.flatnonzero(dones).tolist() if dones is not None else ())
        for index in ended:
            episode = infos[index].get("episode")
            if episode is not None and has_rewards[index]:
                episode["agent_returns"] = returns[index].tolist()  # floats, as Monitor's "r": JSON-ready
            returns[index] = 0.0  # the env resets itself: its next step is a new episode's
        super()._update_info_buffer(infos, dones)

    def dump_logs(self) -> None:
        """
        Write the logs at most once per env step (SB3 asks at finished episodes, which many envs end together), with
        :meth:`_record_diagnostics` and each agent's mean episode return, ``rollout/<agent_id>/ep_rew_mean``, beside
        SB3's team return ``rollout/ep_rew_mean``, over the same episodes.
        """
        if self._logs_dumped_at == self.num_timesteps:
            return
        self._logs_dumped_at = self.num_timesteps
        self._record_diagnostics()
        assert self.agent_layout is not None and self.ep_info_buffer is not None
        record_agent_returns(self.logger, self.agent_layout.agent_ids, self.ep_info_buffer)
        super().dump_logs()

    def _record_diagnostics(self) -> None:
        """Record what is worth computing only when the logs are written (none here)."""

    def learn(  # type: ignore[override]  # tb_log_name defaults to the class's name
        self: SelfTeamAlgorithm,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int = LOG_INTERVAL,
        tb_log_name: str | None = None,
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfTeamAlgorithm:
        """
        Train the model. The first ``learning_starts`` steps (25,600 by default) are uniformly random actions that
        fill the replay buffer, with no gradient update: a ``learn()`` that ends before the first update says so in
        a warning.

        :param total_timesteps: Env steps to train for (all envs counted); a lower bound, as in SB3.
        :param callback: Callback(s) called at every step.
        :param log_interval: Finished episodes (all envs counted) between two writes of the logs (the table that
            ``verbose=1`` prints). The default, 1000, is every 25,000 steps of simple_spread's 25-step episodes:
            40 tables for 1M steps, whatever the number of envs (SB3's default of 4 would print 10,000).
        :param tb_log_name: The name of the run for TensorBoard logging (default: the algorithm's, e.g. ``"MADDPG"``).
        :param reset_num_timesteps: Whether to count timesteps from 0 again (False to continue a run).
        :param progress_bar: Display a progress bar (needs tqdm and rich).
        :return: The trained model.
        """
        if (
            isinstance(total_timesteps, bool)
            or not isinstance(total_timesteps, int | float | np.integer | np.floating)
            or not 0 <= total_timesteps < float("inf")
            or total_timesteps != int(total_timesteps)
        ):  # SB3 takes any number: learn(-5) trained nothing without a word
            raise ValueError(
                f"total_timesteps (env steps to train for, all envs counted) must be a whole number >= 0, got "
                f"{total_timesteps!r}: use e.g. learn(1_000_000) (1e6 is taken too)."
            )
        if not reset_num_timesteps:
            self._warn_if_resuming_on_an_empty_buffer()
        with package_threads():  # one torch thread unless the user chose one (sb3_maddpg.common.torch_threads)
            result = super().learn(
                total_timesteps=int(total_timesteps),  # 1e6 taken, an int stored
                callback=callback,
                log_interval=log_interval,
                tb_log_name=type(self).__name__ if tb_log_name is None else tb_log_name,
                reset_num_timesteps=reset_num_timesteps,
                progress_bar=progress_bar,
            )
        self._warn_if_never_updated()
        return result

    def _warn_if_resuming_on_an_empty_buffer(self) -> None:
        """
        Say once when training goes on past ``learning_starts`` from a replay buffer that holds fewer rows: a loaded
        model's buffer starts empty (SB3 saves it apart), and its first updates would sample the few transitions
        collected since, over and over.
        """
        if self._warned_empty_resume or self.num_timesteps < self.learning_starts or self.replay_buffer is None:
            return
        rows = self.replay_buffer.size() * self.replay_buffer.n_envs
        capacity = self.replay_buffer.buffer_size * self.replay_buffer.n_envs  # a smaller buffer never holds more
        if rows >= min(self.learning_starts, capacity):
            return
        self._warned_empty_resume = True
        warnings.warn(
            f"learn(reset_num_timesteps=False) goes on at step {self.num_timesteps:,}, past learning_starts="
            f"{self.learning_starts:,}, with {rows:,} transitions in the replay buffer: a loaded model's buffer starts "
            "empty, and its updates start at once on the few transitions collected since. Load the buffer saved with "
            "the model (model.load_replay_buffer(path), saved by model.save_replay_buffer(path)), or accept that the "
            "first updates overfit a small buffer.",
            SB3MADDPGWarning,
            stacklevel=user_stacklevel(),
        )

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
            f"learning_starts for a short test (e.g. {type(self).__name__}(..., learning_starts=2_000)).",
            SB3MADDPGWarning,
            stacklevel=user_stacklevel(),
        )

    def set_env(self, env: GymEnv, force_reset: bool = True) -> None:
        """
        Use a new env; it must have the same agent layout as the model.

        :param env: The new environment.
        :param force_reset: Force a reset before the next ``learn``.
        """
        wrapped = self._wrap_env(env, self.verbose)  # checked before it replaces the env: a refused one must not stay
        check_same_layout(layout_of(wrapped), self.agent_layout)
        refuse_reward_normalization(wrapped)
        super().set_env(wrapped, force_reset)

    @classmethod
    def load(  # type: ignore[override]  # the same signature as SB3's, typed for the subclass
        cls: type[SelfTeamAlgorithm],
        path: str | pathlib.Path | io.BufferedIOBase,
        env: GymEnv | None = None,
        device: th.device | str = "auto",
        custom_objects: dict[str, Any] | None = None,
        print_system_info: bool = False,
        force_reset: bool = True,
        **kwargs: Any,
    ) -> SelfTeamAlgorithm:
        """
        Load a saved model (SB3's ``load``); an ``env`` must be of the model's team (the same agents, order and sizes),
        and a model saved by a newer sb3-maddpg is refused (:func:`~sb3_maddpg.compat.written_by`).

        :param path: The saved model (``.zip`` optional) or an open file.
        :param env: The env to train or evaluate on, or ``None`` (``predict`` needs none).
        :param device: Device to load the model on.
        :param custom_objects: Objects to replace on load (SB3's argument).
        :param print_system_info: Print the system the model was saved on and this one.
        :param force_reset: Reset the env before the next ``learn``.
        :param kwargs: Attributes to set on the model over the saved ones.
        :return: The model.
        """
        if isinstance(path, str | pathlib.Path) and not any(pathlib.Path(f"{path}{end}").is_file() for end in ("", ".zip")):
            raise FileNotFoundError(  # SB3's error names the path with a second ".zip"
                f"No saved model at {path}: {cls.__name__}.load takes the path model.save(path) wrote (with or without "
                f"its .zip); check the path and the working directory ({pathlib.Path.cwd()})."
            )
        data = read_saved_data(path, custom_objects)  # None where unreadable: SB3's load says why
        if env is not None:
            refuse_env_of_another_team(data, env)
        if data is not None:
            written_by(data, "The model")
        with loading_a_saved_model():
            return super().load(path, env, device, custom_objects, print_system_info, force_reset, **kwargs)

    def load_replay_buffer(self, path: str | pathlib.Path | io.BufferedIOBase, truncate_last_traj: bool = True) -> None:
        """
        Load a replay buffer saved by :meth:`save_replay_buffer`; it must be of this model's team.

        :param path: Path to the pickled replay buffer.
        :param truncate_last_traj: SB3's argument (used by ``HerReplayBuffer`` only).
        """
        current = self.replay_buffer
        super().load_replay_buffer(path, truncate_last_traj)
        try:
            refuse_buffer_of_another_team(self.replay_buffer, self.agent_layout, self.selection_size, self.n_envs)
            assert self.agent_layout is not None
            needs_next = self.selector is not None and self.selector.stores_next_selection(self.agent_layout)
            if needs_next and getattr(self.replay_buffer, "next_selections", None) is None:
                raise ValueError(
                    "The replay buffer holds no next-step selections, and this model's selector (target='next') needs "
                    "them from the env's positions, which only the env had when the rows were stored: load a buffer "
                    "saved by a model with the same selector, or start with an empty one."
                )
        except (TypeError, ValueError):
            self.replay_buffer = current  # a refused buffer must not stay in the model
            raise
        self.replay_buffer.selector = self.selector  # new rows: the model's rule, of the same size k
        if not needs_next:
            self.replay_buffer.next_selections = None  # a buffer's own; this model selects again at sampling

    def save(
        self,
        path: str | pathlib.Path | io.BufferedIOBase,
        exclude: Iterable[str] | None = None,
        include: Iterable[str] | None = None,
    ) -> None:
        """
        Save the model (SB3's ``save``), with the sb3-maddpg version that wrote it (:data:`~sb3_maddpg.compat.VERSION_KEY`),
        by which :meth:`load` refuses a save of a newer version.

        :param path: Where to save (``.zip`` added if missing) or an open file.
        :param exclude: Attributes not to save, beyond the default ones.
        :param include: Attributes to save that are excluded by default.
        """
        self.__dict__[VERSION_KEY] = __version__
        try:
            super().save(path, exclude, include)
        finally:
            del self.__dict__[VERSION_KEY]

    def _excluded_save_params(self) -> list[str]:
        # The running returns belong to the env's episodes under way, which a loaded model's env starts again.
        return [
            *super()._excluded_save_params(),
            "_discrete_components",
            "_warned_never_updated",
            "_warned_empty_resume",
            "_agent_episode_returns",
            "_memory_released_at",
        ]
