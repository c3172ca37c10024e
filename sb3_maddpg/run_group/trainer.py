"""
``R`` independent MADDPG (or MATD3) runs trained together in one process, on one device: the runs' networks stacked,
one optimiser over them, the replay buffers and the worlds on the device, each run's randomness from its own seed.
"""

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch as th

from sb3_maddpg.common.buffers import MultiAgentReplayBufferSamples
from sb3_maddpg.common.losses import ActionParts
from sb3_maddpg.common.memory_release import release_freed_memory
from sb3_maddpg.common.noise import noisy_actions, per_env_noise
from sb3_maddpg.common.train_logs import StepLosses, summarise_steps
from sb3_maddpg.common.update_schedule import UpdateSchedule
from sb3_maddpg.common.update_step import GroupFunctions, update_step
from sb3_maddpg.maddpg import MADDPG
from sb3_maddpg.run_group.buffer import RunReplayBuffers, buffer_capacity
from sb3_maddpg.run_group.checks import check_models
from sb3_maddpg.run_group.compiled import CompiledPart, captures, mark_static
from sb3_maddpg.run_group.selection import DeviceSelector
from sb3_maddpg.run_group.stacked import StackedModule, StackedTeams
from sb3_maddpg.run_group.stacked_adam import StackedAdam
from sb3_maddpg.run_group.streams import RunStreams
from sb3_maddpg.run_group.worlds import METRICS, SpreadRuns, SpreadTask

STATE_VERSION = 3
"""The layout of :meth:`RunGroup.state_dict`'s value (a state of another version is refused)."""


class GroupCallback:
    """
    Hooks into :meth:`RunGroup.learn`, as SB3's callbacks into ``learn``: e.g. to save checkpoints at given steps.
    Subclass it and override what you need; both do nothing here.
    """

    def on_step(self, group: "RunGroup") -> None:
        """
        Called after each step of every run's worlds (``group.num_timesteps`` counts it), before the round's updates:
        where SB3 calls a callback's ``on_step``.

        :param group: The group.
        """

    def on_round_end(self, group: "RunGroup") -> None:
        """
        Called at the end of each round (its steps, then the updates they earned): a state saved here
        (:meth:`RunGroup.state_dict`) resumes with the next round.

        :param group: The group.
        """


class RunGroup:
    """
    ``R`` independent MADDPG (or MATD3) runs of one configuration, differing only in their seeds, trained at once.

    Each run's actors, critics and targets are the parameters of its model stacked along a run dimension
    (:class:`~sb3_maddpg.run_group.stacked.StackedTeams`); one update of every run is the algorithm's own functions and
    losses, those ``MADDPG.train`` and ``MATD3.train`` run for one team, ``vmap``-ed over the runs
    (:func:`~sb3_maddpg.common.update_step.update_step`): one optimiser step (the models' optimiser, element-wise:
    Adam's state of run r is run r's), gradient clipping per run and agent, Polyak updates. Data come from ``R`` runs of
    ``E`` simple_spread worlds in torch on the same device, into replay buffers there; each run's new episodes,
    exploration noise, warm-up actions, replay batches (and MATD3's smoothing noise) are drawn from its own
    counter-based stream of its model's ``seed`` (:class:`~sb3_maddpg.run_group.streams.RunStreams`), every run's at
    once, so that a run's data depend on its seed only, not on the other runs. The update ratio is the models' (the
    paper's one gradient step per ``transitions_per_update`` transitions of each run, after ``learning_starts``).

    The models are read once, when the group is built; :meth:`write_back` puts each run's weights, optimiser state
    and counters into a model, which then saves as any MADDPG model (``MADDPG.load`` reads it).

    :param models: One MADDPG (or MATD3) model per run: the same layout and hyperparameters, each with its own ``seed``.
    :param worlds_per_run: Worlds ``E`` each run collects in (default: the models' ``n_envs``).
    :param task: simple_spread's settings (default: read from the models' env, a
        :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`); only :meth:`learn` needs them.
    :param device: The device of everything: networks, optimiser state, buffers, worlds.
    :param world_dtype: The worlds' floating dtype (float64: mpe2's arithmetic; float32, the default: faster).
    :param compile: Compile each part of a round with ``torch.compile(fullgraph=True)``, one graph each: the env step
        of every run's worlds (actions, physics, selections) and each gradient step (its batch drawn, critics, actors,
        targets). ``True``: inductor's default mode, and on CUDA the gradient step captured as CUDA graphs (mode
        ``"reduce-overhead"``); a string: that mode for both. The first calls compile (tens of seconds:
        :attr:`compile_seconds`); results differ from eager ones by float rounding. Groups of the same settings
        share their graphs; on CUDA, alternating between two live captured groups re-records them at each switch, and
        groups of other settings add graphs up to torch's limit (``torch._dynamo.config.cache_size_limit``): call
        ``torch._dynamo.reset()`` before compiling a new group once the last one is done.
    """

    def __init__(
        self,
        models: Sequence[MADDPG],
        worlds_per_run: int | None = None,
        task: SpreadTask | None = None,
        device: th.device | str = "cpu",
        world_dtype: th.dtype = th.float32,
        compile: bool | str = False,
    ) -> None:
        check_models(models)
        first = models[0]
        assert first.agent_layout is not None
        self.n_runs = len(models)
        self.device = th.device(device)
        self.layout = first.agent_layout
        self.seeds = [int(model.seed) for model in models]  # type: ignore[arg-type]  # checked: not None
        self.streams = RunStreams(self.seeds, self.device)
        """Each run's random stream: episodes, warm-up actions, noise, replay batches."""
        self.teams = StackedTeams(
            [model.actor for model in models],
            [model.critic for model in models],
            [model.actor_target for model in models],
            [model.critic_target for model in models],
            self.device,
            self.streams,
        )
        self.actor_optimizer = StackedAdam.of_models(self.teams.actor.parameters(), [m.actor.optimizer for m in models])
        self.critic_optimizer = StackedAdam.of_models(self.teams.critic.parameters(), [m.critic.optimizer for m in models])
        # The algorithm's own networks and step settings (checked: the same in every model), over the stacked runs.
        self.settings = first._step_settings()._replace(parts=ActionParts.of(self.layout, self.device))
        self.networks = GroupFunctions(self.settings, self.teams, self.teams.templates())
        self.batch_size = first.batch_size
        self.learning_starts = first.learning_starts
        self.lr_schedule = first.lr_schedule
        self.update_rule = UpdateSchedule.from_arguments(first.transitions_per_update, None, None)
        # The models' credit (checked: the same in each): a group of written-back models earns no steps twice.
        self.update_rule.credit, self.update_rule.counted_at = first.update_rule.credit, first.update_rule.counted_at
        self.selector = first.selector
        self.select = None if self.selector is None else DeviceSelector(self.selector, self.layout, self.device)
        self.num_timesteps = first.num_timesteps
        """Env steps of each run (all its worlds counted)."""
        self.n_updates = first._n_updates
        """Gradient steps of each run."""
        self._memory_released_at = self.n_updates
        noise = None if first.action_noise is None else per_env_noise(first.action_noise)
        # Checked: a NormalActionNoise (or none); its mean and std per action component, on the device.
        self.noise_mean: th.Tensor | None = None if noise is None else _tensor(noise._mu, self.device)  # type: ignore[attr-defined]
        self.noise_std: th.Tensor | None = None if noise is None else _tensor(noise._sigma, self.device)  # type: ignore[attr-defined]
        self.worlds_per_run = int(worlds_per_run or first.n_envs)
        self.task = task if task is not None else SpreadTask.from_env(first.env) if first.env is not None else None
        self.buffers = RunReplayBuffers(
            self.n_runs,
            buffer_capacity(first.buffer_size, self.worlds_per_run),
            self.layout.obs_dim,
            self.layout.action_dim,
            self.layout.n_agents,
            0 if self.selector is None else self.selector.k,
            self.device,
            rows_per_step=self.worlds_per_run,
            episode_length=1 if self.task is None else self.task.max_cycles,
        )
        self.world_dtype = world_dtype
        self.worlds: SpreadRuns | None = None
        self.losses: dict[str, th.Tensor] = {}
        """
        The last :meth:`train` call's means of :data:`~sb3_maddpg.common.train_logs.LOSS_NAMES`, ``[R, n_agents]``
        each, on the device.
        """
        self.compiled = bool(compile)
        # A mode by name is the user's; else CUDA graphs for the gradient step on a GPU, inductor's default elsewhere.
        update_mode = compile if isinstance(compile, str) else "reduce-overhead" if self.device.type == "cuda" else None
        # The env step replaces the worlds' state between calls: never captured (a capturing mode: the default here).
        env_mode = None if captures(update_mode) else update_mode
        if self.compiled and captures(update_mode):
            self._mark_static()
        self._update = CompiledPart(self._gradient_step, update_mode, self.compiled)
        self._sampled_update = CompiledPart(self._sample_and_step, update_mode, self.compiled)
        self._env_step = CompiledPart(self._act_and_move, env_mode, self.compiled)

    @property
    def compile_seconds(self) -> float:
        """Seconds spent compiling so far: each part's first call with each value of its Python arguments (with and
        without the actors' update, before and after ``learning_starts``). Not counted: recompiles for another batch
        shape given to :meth:`update`, and on CUDA graphs their recording, which torch does at the next calls."""
        return sum(part.seconds for part in (self._update, self._sampled_update, self._env_step))

    # ----- updates -----

    def update(self, batch: MultiAgentReplayBufferSamples) -> dict[str, th.Tensor]:
        """
        One gradient step of every run on its batch, as one step of the models' ``train``: the critics, then the
        actors (against the updated critics) and the targets when due.

        :param batch: Each run's batch, ``[R, batch, ...]`` each field, on the group's device.
        :return: This step's :data:`~sb3_maddpg.common.train_logs.LOSS_NAMES` (the actors' only when they were updated),
            ``[R, n_agents]`` each.
        """
        return summarise_steps([self._step(batch)])

    def _step(self, batch: MultiAgentReplayBufferSamples | None) -> StepLosses:
        """One gradient step of every run, on ``batch`` or (None) on a batch drawn from each run's buffer."""
        self.n_updates += 1
        due = self.settings.actor_due(self.n_updates)
        if batch is None:
            return self._sampled_update(due, key=due)  # type: ignore[no-any-return]
        return self._update(batch, due, key=due)  # type: ignore[no-any-return]

    def _gradient_step(self, batch: MultiAgentReplayBufferSamples, actor_due: bool) -> StepLosses:
        """One gradient step of every run on ``batch``; Adam in its capturable form where torch allows it (a
        compiled step, a GPU), else (eager on a CPU) in its host form."""
        optimizers = (self.actor_optimizer, self.critic_optimizer)
        capturable = self.compiled or StackedAdam.capturable_on(self.device)
        return update_step(self.networks, optimizers, batch, self.settings, actor_due, capturable=capturable)

    def _sample_and_step(self, actor_due: bool) -> StepLosses:
        """A batch drawn from each run's buffer by its stream (:meth:`_sample`, checked before), then its step."""
        return self._gradient_step(self._sample(), actor_due)

    def _mark_static(self) -> None:
        """The tensors a captured gradient step reads or changes in place, read where they are (CUDA graphs:
        :func:`mark_static`): the weights, Adam's state, the random streams and the replay buffers, which would
        otherwise be copied into the graph's memory at every replay."""
        tensors = [*self.teams.stacked_parameters().values()]
        for optimizer in (self.actor_optimizer, self.critic_optimizer):
            tensors += [*optimizer.exp_avgs, *optimizer.exp_avg_sqs, *optimizer.max_exp_avg_sqs, *optimizer.steps]
            tensors.append(optimizer.lr_tensor)
        for holder in (self.streams, self.buffers, self.select):
            if holder is not None:
                tensors += [value for value in vars(holder).values() if isinstance(value, th.Tensor)]
        mark_static(tensors)

    def train(self, gradient_steps: int) -> None:
        """
        ``gradient_steps`` updates of every run, each on a batch of ``batch_size`` rows drawn from its buffer by its
        stream; the steps' mean losses go to :attr:`losses` (no transfer to the host).

        :param gradient_steps: Gradient steps of each run.
        """
        self.buffers.check_sample(self.streams)
        steps = [self._step(None) for _ in range(gradient_steps)]
        if steps:
            self.losses = summarise_steps(steps)
        # The heap the steps freed goes back to the system, as a single model's (sb3_maddpg.common.memory_release).
        self._memory_released_at = release_freed_memory(self.n_updates, self._memory_released_at)

    def _sample(self) -> MultiAgentReplayBufferSamples:
        """Each run's batch (the buffers checked before, by :meth:`train`: the draw reads no Python value that changes
        as they fill); with a selector whose ``target`` is ``"next"``, the target's selection made from the next
        observations, as :class:`~sb3_maddpg.common.buffers.MultiAgentReplayBuffer` makes it."""
        batch = self.buffers.draw(self.batch_size, self.streams)
        if self.select is not None and self.selector is not None and self.selector.target == "next":
            batch = batch._replace(next_selections=self.select(batch.next_observations))
        return batch

    # ----- data -----

    def explore(self, observations: th.Tensor, warm_up: bool | None = None) -> th.Tensor:
        """
        Each run's exploration actions in the [-1, 1] space, as ``MADDPG._sample_action``: uniform before
        ``learning_starts``, then every actor on its own observation; plus Gaussian noise, clipped to [-1, 1] by the
        models' own rule (:func:`~sb3_maddpg.common.noise.noisy_actions`).

        :param observations: ``[R, E, obs_dim]``.
        :param warm_up: Whether the actions are uniform (default: whether ``learning_starts`` is still ahead).
        :return: ``[R, E, action_dim]``.
        """
        shape = (observations.shape[1], self.layout.action_dim)
        if warm_up if warm_up is not None else self.num_timesteps < self.learning_starts:
            actions = self.streams.uniform(shape) * 2.0 - 1.0
        else:
            actions = self.networks.actions(observations)
        if self.noise_std is not None and self.noise_mean is not None:
            actions = noisy_actions(actions, self.noise_mean + self.streams.normal(shape) * self.noise_std)
        return actions

    def collect_step(self) -> None:
        """One step of every run's worlds, its transitions stored in the runs' buffers."""
        worlds = self._worlds()
        observations = worlds.observations
        warm_up = self.num_timesteps < self.learning_starts
        actions, next_observations, rewards, selections = self._env_step(observations, warm_up, key=warm_up)
        step = worlds.record(next_observations, rewards)
        dones = th.zeros_like(rewards)  # simple_spread never terminates: its truncations bootstrap
        self.buffers.add(observations, actions, next_observations, rewards, dones, selections, step.truncated)
        self.num_timesteps += self.worlds_per_run

    def _act_and_move(
        self, observations: th.Tensor, warm_up: bool
    ) -> tuple[th.Tensor, th.Tensor, th.Tensor, th.Tensor | None]:
        """
        The device's part of :meth:`collect_step`: every run's actions, its worlds' physics step and the selections.

        :return: The actions, next observations, rewards and selections (None without a selector).
        """
        actions = self.explore(observations, warm_up)
        next_observations, rewards = self._worlds().move(actions)
        selections = None if self.select is None else self.select(observations)
        return actions, next_observations, rewards, selections

    def learn(self, total_timesteps: int, callback: GroupCallback | None = None) -> "RunGroup":
        """
        Collect and train every run for ``total_timesteps`` more env steps each (all its worlds counted), as
        ``MADDPG.learn`` with ``reset_num_timesteps=False``: rounds of ``max(1, transitions_per_update // E)`` steps,
        each followed by the gradient steps its transitions past ``learning_starts`` have earned.

        :param total_timesteps: Env steps of each run.
        :param callback: Called after each step and at the end of each round.
        :return: The group.
        """
        end = self.num_timesteps + total_timesteps
        train_freq = self.update_rule.train_freq(self.worlds_per_run)
        assert train_freq is not None, "the group's rule derives train_freq"
        while self.num_timesteps < end:
            for _ in range(train_freq.frequency):
                self.collect_step()
                if callback is not None:
                    callback.on_step(self)
            steps = self.update_rule.earned(self.num_timesteps, self.learning_starts)
            if steps > 0 and self.num_timesteps > self.learning_starts:
                self._update_learning_rate(1.0 - self.num_timesteps / end)
                self.train(steps)
            if callback is not None:
                callback.on_round_end(self)
        return self

    def _update_learning_rate(self, progress_remaining: float) -> None:
        """Every optimiser's learning rate from the models' schedule, as SB3's ``_update_learning_rate``."""
        for optimizer in (self.actor_optimizer, self.critic_optimizer):
            optimizer.set_lr(self.lr_schedule(progress_remaining))

    def _worlds(self) -> SpreadRuns:
        if self.worlds is None:
            if self.task is None:
                raise ValueError(
                    "The run group does not know its worlds' settings: the models' env is not a SimpleSpreadVecEnv. "
                    "Pass RunGroup(models, task=SpreadTask(n_agents=..., num_agent_neighbors=...))."
                )
            worlds = SpreadRuns(self.task, self.worlds_per_run, self.streams, self.world_dtype)
            expected = self.task.layout(worlds.obs_size)
            if expected != self.layout:
                raise ValueError(
                    f"The task's worlds have agent layout {expected}, but the models' team is {self.layout}: pass the "
                    "SpreadTask of the env the models were built on."
                )
            self.worlds = worlds
        return self.worlds

    def episode_stats(self) -> dict[str, np.ndarray]:
        """
        :return: For every finished round of episodes, each run's mean over its worlds of the team reward
            (``"reward"``) and of the task metrics at the episodes' end, ``[rounds, R]`` each (one transfer).
        """
        names = ("reward", *METRICS)
        episodes = [] if self.worlds is None else self.worlds.episodes
        if not episodes:
            return {name: np.zeros((0, self.n_runs)) for name in names}
        table = th.stack(episodes).cpu().numpy()
        return {name: table[:, i] for i, name in enumerate(names)}

    # ----- save and resume -----

    def state_dict(self, copy_buffers: bool = False) -> dict[str, Any]:
        """
        Everything the group's training goes on from, as tensors (on the group's device) and plain values, for
        ``torch.save``: the stacked weights and targets, the optimisers' states, the replay buffers (the rows
        filled so far), the runs' random streams, the worlds (positions, velocities, the episodes' steps and returns,
        the finished episodes' records), the counters and the update rule's credit. Taken at the end of a round
        (:meth:`GroupCallback.on_round_end`), :meth:`load_state_dict` continues the same training exactly, on this
        device or another (the random streams' state means the same on every device).

        :param copy_buffers: Copy the buffers' filled rows (and the worlds' state) on the device, for a state kept in
            memory while the group trains on. ``False`` (the default), to ``torch.save`` the state at once: full
            buffers are the group's own tensors (no second copy on the device: groups are sized to fill it) and partly
            filled ones' rows are copied to host memory; such a state changes as the group trains on.
        :return: The state.
        """
        teams, buffers = self.teams, self.buffers
        worlds = self.worlds
        # The worlds' tensors change in place as the group steps: copied for a state kept in memory.
        kept = (lambda tensor: tensor.clone()) if copy_buffers else (lambda tensor: tensor)
        return {
            "version": STATE_VERSION,
            "seeds": list(self.seeds),
            "params": {name: [p.detach().clone() for p in module.parameters()] for name, module in _modules(teams)},
            "actor_optimizer": self.actor_optimizer.state_dict(),
            "critic_optimizer": self.critic_optimizer.state_dict(),
            "num_timesteps": self.num_timesteps,
            "n_updates": self.n_updates,
            "update_rule": (self.update_rule.credit, self.update_rule.counted_at),
            "streams": self.streams.state_dict(),
            "buffers": buffers.state_dict(copy=copy_buffers),
            "worlds": None
            if worlds is None
            else {
                "state": [kept(worlds.worlds.agent_pos), kept(worlds.worlds.agent_vel), kept(worlds.worlds.landmark_pos)],
                "steps": worlds.steps,
                "observations": kept(worlds.observations),
                "agent_returns": kept(worlds._agent_returns),
                "episodes": th.stack(worlds.episodes) if worlds.episodes else None,
                "agent_episodes": th.stack(worlds.agent_episodes) if worlds.agent_episodes else None,
            },
            "losses": dict(self.losses),
        }

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """
        Continue from a state of :meth:`state_dict`, taken from a group of the same models (seeds and configuration).

        :param state: The state (its tensors on any device).
        """
        if state.get("version") != STATE_VERSION:
            raise ValueError(
                f"This run-group state has version {state.get('version')!r}, this package reads {STATE_VERSION}: "
                "start the runs afresh (delete the state file)."
            )
        if list(state["seeds"]) != self.seeds:
            raise ValueError(
                f"This run-group state is of seeds {state['seeds']}, the group's are {self.seeds}: load a state into "
                "a group of the same runs."
            )
        device = self.device
        with th.no_grad():
            for name, module in _modules(self.teams):
                for param, saved in zip(module.parameters(), state["params"][name]):
                    param.copy_(saved.to(device))
        self.actor_optimizer.load_state_dict(state["actor_optimizer"])
        self.critic_optimizer.load_state_dict(state["critic_optimizer"])
        self.num_timesteps = int(state["num_timesteps"])
        self.n_updates = int(state["n_updates"])
        self.update_rule.credit, self.update_rule.counted_at = state["update_rule"]
        if state["worlds"] is not None:
            self._worlds()  # built first: building them draws new episodes from the streams, set next
        self.streams.load_state_dict(state["streams"])
        self.buffers.load_state_dict(state["buffers"])
        saved_worlds = state["worlds"]
        if saved_worlds is not None:
            worlds = self._worlds()
            worlds.worlds.set_state(*saved_worlds["state"])
            worlds.steps = int(saved_worlds["steps"])
            worlds.observations = saved_worlds["observations"].to(device)
            worlds._agent_returns = saved_worlds["agent_returns"].to(device)
            for name in ("episodes", "agent_episodes"):
                rounds = saved_worlds[name]
                setattr(worlds, name, [] if rounds is None else list(rounds.to(device).unbind(0)))
        self.losses = {name: value.to(device) for name, value in state["losses"].items()}

    # ----- back to the models -----

    def write_back(self, run: int, model: MADDPG) -> MADDPG:
        """
        Put run ``run``'s weights (actors, critics, targets), optimiser states and counters (``num_timesteps``,
        ``_n_updates``, the update rule's credit) into ``model``, a model
        of the group's configuration (e.g. the one the run was built from); ``model.save`` then writes a file
        ``MADDPG.load`` reads. The replay buffer stays in the group.

        :param run: The run.
        :param model: The model to write into.
        :return: The model.
        """
        if not 0 <= run < self.n_runs:
            raise ValueError(f"run must be in [0, {self.n_runs - 1}], got {run}.")
        if model.agent_layout != self.layout:
            raise ValueError(
                f"The model's team is {model.agent_layout}, the group's is {self.layout}: write a run back into a model "
                "of the group's configuration."
            )
        teams = self.teams
        pairs: list[tuple[StackedModule, Any]] = [
            (teams.actor, model.actor),
            (teams.critic, model.critic),
            (teams.actor_target, model.actor_target),
            (teams.critic_target, model.critic_target),
        ]
        for stacked, module in pairs:
            stacked.load_into(run, module)
        _load_member_state(self.actor_optimizer, run, model.actor.optimizer)
        _load_member_state(self.critic_optimizer, run, model.critic.optimizer)
        model.num_timesteps = self.num_timesteps
        model._n_updates = self.n_updates
        # The credit too: the model's learn(reset_num_timesteps=False), or a group built from it, goes on exactly.
        model.update_rule.credit, model.update_rule.counted_at = self.update_rule.credit, self.update_rule.counted_at
        return model


def _modules(teams: StackedTeams) -> list[tuple[str, StackedModule]]:
    return [
        ("actor", teams.actor),
        ("critic", teams.critic),
        ("actor_target", teams.actor_target),
        ("critic_target", teams.critic_target),
    ]


def _tensor(values: Any, device: th.device) -> th.Tensor:
    return th.as_tensor(np.asarray(values), dtype=th.float32, device=device)


def _load_member_state(optimizer: StackedAdam, run: int, target: th.optim.Optimizer) -> None:
    """Write run ``run``'s slice of the stacked optimiser's state into one model's optimiser (and its learning rate)."""
    param_groups = target.state_dict()["param_groups"]
    for group in param_groups:
        group["lr"] = optimizer.lr
    target.load_state_dict({"state": optimizer.run_state(run), "param_groups": param_groups})
