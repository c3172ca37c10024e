"""Experiment and run configurations: the paper's two experiments, a CI smoke test, and overrides."""

import copy
import dataclasses
import importlib
import inspect
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from sb3_maddpg.compat import renamed_in_0_3
from sb3_maddpg.experiments.task_envs import task_env_factory
from sb3_maddpg.hyperparams import load_hyperparams

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm

EPISODE_LENGTH = 25
"""Steps per simple_spread episode in the paper (``max_cycles``)."""

SCHEMES = ("full", "independent", "observations", "actions", "selected")
"""The five information-sharing schemes, in the paper's Table 2 column order."""

DEFAULT_ALGORITHM = "sb3_maddpg:MADDPG"
"""The algorithm every run trains, as ``"module:Class"``."""


def load_algorithm(path: str) -> "type[BaseAlgorithm]":
    """
    :param path: ``"module:Class"``, e.g. ``"sb3_maddpg:MADDPG"``.
    :return: The class.
    """
    module_name, _, class_name = path.partition(":")
    if not class_name:
        raise ValueError(f"The algorithm must be given as 'module:Class', got {path!r}.")
    return getattr(importlib.import_module(module_name), class_name)


def algorithm_argument(experiment: Mapping[str, Any], name: str, scheme: str | None = None) -> Any:
    """
    One argument that an experiment's runs give their algorithm, for tables and figures that compare experiments
    (e.g. gradient steps from ``transitions_per_update`` and ``learning_starts``).

    :param experiment: An experiment as stored (``ExperimentConfig.to_dict()``, a results directory's
        ``experiment.json``).
    :param name: The argument, e.g. ``"transitions_per_update"``.
    :param scheme: The scheme whose runs are meant, for an experiment with ``scheme_model_kwargs``; ``None``: the
        experiment's ``model_kwargs`` alone.
    :return: The scheme's ``scheme_model_kwargs`` value, else the experiment's ``model_kwargs`` value, else its
        algorithm's default (MADDPG's: the paper's).
    """
    model_kwargs = dict(experiment.get("model_kwargs") or {})
    if scheme is not None:
        model_kwargs |= (experiment.get("scheme_model_kwargs") or {}).get(scheme, {})
    if name in model_kwargs:
        return model_kwargs[name]
    algorithm_path = experiment.get("algorithm") or DEFAULT_ALGORITHM
    parameter = inspect.signature(load_algorithm(algorithm_path)).parameters.get(name)
    if parameter is None or parameter.default is inspect.Parameter.empty:
        raise ValueError(
            f"{algorithm_path} has no argument {name!r} with a default, and the experiment's model_kwargs do not set it: "
            "name one of the algorithm's constructor arguments."
        )
    return parameter.default


VEC_ENVS = ("batched", "mpe2")
"""How a run steps simple_spread: ``"batched"`` (:class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`, the same MDP as
mpe2, arrays) or ``"mpe2"`` (``DummyVecEnv`` over the adapter and mpe2 itself)."""

DEFAULT_N_ENVS = 100
"""Worlds stepped together: with the paper's one update per 100 transitions, one update per vectorised step."""


DEFAULT_ENV = "simple_spread"
"""The paper's task."""


def ordered_schemes(schemes: Iterable[str]) -> list[str]:
    """
    :param schemes: Scheme names, in any order, repeats allowed.
    :return: Each once: the paper's schemes in :data:`SCHEMES` order, then any others alphabetically.
    """
    present = set(schemes)
    return [scheme for scheme in SCHEMES if scheme in present] + sorted(present - set(SCHEMES))


def merge_model_kwargs(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """
    :param base: Keyword arguments of an algorithm (e.g. a setting's ``model_kwargs``).
    :param changes: Keyword arguments over them (e.g. a tuning trial's sample).
    :return: ``changes`` over ``base`` (copies), their ``policy_kwargs`` merged key by key (``changes`` win): a
        sample's network width keeps a setting's ``share_parameters`` or ``layer_norm``.
    """
    merged = copy.deepcopy({**base, **changes})
    if isinstance(base.get("policy_kwargs"), dict) and isinstance(changes.get("policy_kwargs"), dict):
        merged["policy_kwargs"] = copy.deepcopy({**base["policy_kwargs"], **changes["policy_kwargs"]})
    return merged


def setting_label(name: str, experiment: dict[str, Any] | None) -> str:
    """
    :param name: The experiment name.
    :param experiment: Its stored config (``ExperimentConfig.to_dict()``), if any.
    :return: A short label, e.g. ``"exp1 (N=5, full obs., 100,000 ep.)"``; an algorithm other than MADDPG is named
        first (``"n3_matd3 (MATD3, N=3, ...)"``), since the scheme columns keep the paper's MADDPG names.
    """
    if not experiment:
        return name
    algorithm = experiment.get("algorithm", DEFAULT_ALGORITHM)
    prefix = "" if algorithm == DEFAULT_ALGORITHM else f"{algorithm.rpartition(':')[2]}, "
    if experiment.get("env", DEFAULT_ENV) != DEFAULT_ENV:
        return f"{name} ({prefix}{experiment['env']}, {experiment['episodes']:,} ep.)"
    neighbors = experiment.get("num_agent_neighbors")
    if neighbors is None:
        observability = "full obs."
    elif neighbors >= experiment["n_agents"] - 1:  # every other agent, in order of distance
        observability = "full obs. nearest first"
    else:
        observability = f"{neighbors} nearest obs."
    return f"{name} ({prefix}N={experiment['n_agents']}, {observability}, {experiment['episodes']:,} ep.)"


def _plural(count: int, noun: str) -> str:
    return f"{count:,} {noun}" + ("" if count == 1 else "s")


def describe_setting(experiment: "ExperimentConfig") -> str:
    """
    The setting's values in words, derived from its fields, so that a changed field changes them.

    :param experiment: An experiment.
    :return: Its task (and the task's keyword arguments), its algorithm when not MADDPG, its team size, for
        simple_spread its observability, its budget and its evaluation schedule, e.g. ``"simple_spread, N=5, full
        observability, 100,000 episodes (2,500,000 steps), 20 checkpoints x 100 episodes over the last 20%, 50 curve
        points x 20 episodes"``.
    """
    task = experiment.env
    if experiment.env_kwargs:
        task += " (" + ", ".join(f"{key}={value}" for key, value in experiment.env_kwargs.items()) + ")"
    parts = [task]
    if experiment.algorithm != DEFAULT_ALGORITHM:
        parts.append(experiment.algorithm.rpartition(":")[2])
    if experiment.env == DEFAULT_ENV:
        neighbors = experiment.num_agent_neighbors
        parts.append(f"N={experiment.n_agents}")
        if neighbors is None:
            parts.append("full observability")
        elif neighbors >= experiment.n_agents - 1:
            parts.append("full observability nearest first")
        else:
            parts.append(f"{_plural(neighbors, 'nearest agent')} observed")
    else:
        parts.append(_plural(experiment.n_agents, "agent"))
    steps = experiment.episodes * experiment.episode_length
    parts.append(f"{_plural(experiment.episodes, 'episode')} ({steps:,} steps)")
    parts.append(
        f"{_plural(experiment.n_checkpoints, 'checkpoint')} x {_plural(experiment.eval_episodes, 'episode')} over the "
        f"last {experiment.checkpoint_fraction:.0%}"
    )
    if experiment.curve_points:
        parts.append(
            f"{_plural(experiment.curve_points, 'curve point')} x {_plural(experiment.curve_eval_episodes, 'episode')}"
        )
    else:
        parts.append("no learning curve")
    return ", ".join(parts)


SCHEDULE_FLOORS = {"n_checkpoints": 1, "eval_episodes": 10, "curve_points": 2, "curve_eval_episodes": 5}
"""The least of each evaluation count that :func:`scaled_schedule` shrinks to (or the experiment's own, if smaller)."""


def scaled_schedule(experiment: "ExperimentConfig", episodes: int) -> dict[str, int]:
    """
    The evaluation schedule of ``experiment`` for another budget: what ``sb3-maddpg run --episodes`` uses for each
    count that it is not given.

    A smaller budget shrinks each of the four counts by the square root of the budgets' ratio (rounded up, at least
    :data:`SCHEDULE_FLOORS` or the experiment's own count if that is smaller, and no more checkpoints than episodes in
    the last ``checkpoint_fraction``): evaluation keeps its share of a run (3% of exp1's episodes), and the number of
    evaluations and their size shrink alike. A budget as large or larger keeps the experiment's schedule.

    :param experiment: An experiment.
    :param episodes: The new budget in episodes.
    :return: ``n_checkpoints``, ``eval_episodes``, ``curve_points`` and ``curve_eval_episodes`` for that budget.
    """
    schedule = {name: int(getattr(experiment, name)) for name in SCHEDULE_FLOORS}
    if episodes >= experiment.episodes:
        return schedule
    factor = math.sqrt(episodes / experiment.episodes)
    for name, floor in SCHEDULE_FLOORS.items():
        # The 1e-9 keeps a product that is whole in exact arithmetic from rounding up past it.
        schedule[name] = max(min(floor, schedule[name]), math.ceil(schedule[name] * factor - 1e-9))
    schedule["n_checkpoints"] = min(schedule["n_checkpoints"], max(1, math.floor(episodes * experiment.checkpoint_fraction)))
    return schedule


def task_team_size(env: str, env_kwargs: dict[str, Any] | None = None) -> int:
    """
    :param env: A task other than simple_spread (see :class:`RunConfig`'s ``env``).
    :param env_kwargs: Its constructor's keyword arguments.
    :return: Its team size, read from one env of the task (its ``agent_layout``).
    """
    probe = RunConfig(experiment="team", scheme="full", seed=0, env=env, env_kwargs=dict(env_kwargs or {}))
    try:
        task = task_env_factory(probe.env, probe.env_kwargs, probe.episode_length)()
    except TypeError as error:  # an argument the task does not take (make_mpe_env names it and the task's own)
        raise ValueError(f"env_kwargs {env_kwargs} do not fit {env!r}: {error}") from None
    try:
        layout = getattr(task.unwrapped, "agent_layout", None)
    finally:
        task.close()
    if layout is None:
        raise ValueError(
            f"env={env!r} has no agent_layout, so MADDPG cannot tell its agents apart: give an MPE task, a PettingZoo "
            "parallel env factory as 'module:function', or a gymnasium id whose env has an agent_layout."
        )
    return int(layout.n_agents)


TUNE_OBJECTIVES = {"min_dist_sum": "minimize", "normalised": "maximize", "return_mean": "maximize"}
"""What ``sb3-maddpg tune`` optimises on simple_spread, and in which direction: the min-dist sum at the last step
(lower is better; the default), the normalised score (the mean of the min-dist sum's and the team return's, 0 = random,
1 = the scripted controller; higher is better) or the team return (higher is better). Other tasks':
:func:`~sb3_maddpg.experiments.tune.task_objectives`."""

BASELINE_SCHEME = "full"
"""The scheme every other one is tested against (MADDPG)."""

PAPER_NAMES = {
    "full": "MADDPG",
    "independent": "IDDPG",
    "observations": "MADDPG-fo",
    "actions": "MADDPG-fa",
    "selected": "MADDPG-soa",
}
"""The paper's name of each scheme."""


def _check_env(env: str) -> None:
    if not isinstance(env, str) or not env.strip():
        raise ValueError(
            f"env must name a task: 'simple_spread', another MPE task, 'module:function' or a gymnasium id, got {env!r}."
        )


def _check_vec_env(vec_env: str, n_envs: int) -> None:
    if vec_env not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {VEC_ENVS}, got {vec_env!r}.")
    if n_envs < 1:
        raise ValueError(f"n_envs must be at least 1, got {n_envs}.")


@dataclass(frozen=True)
class RunConfig:
    """
    One training run: a scheme, a seed and everything else a run needs. A run is a pure function of
    its config (the results of two runs with equal configs differ only by floating-point noise).

    :param experiment: The experiment (setting) name, e.g. ``"exp1"``.
    :param scheme: The critic information-sharing scheme (``MADDPG(critic_sharing=...)``).
    :param seed: The run's seed: the model's seed; the evaluation env is seeded from it too.
    :param n_agents: Number of agents and landmarks of simple_spread; another task's team size (its own: see
        :meth:`ExperimentConfig.replace`).
    :param num_agent_neighbors: Nearest other agents each agent observes, ``None`` for all.
    :param episodes: Training budget in episodes.
    :param episode_length: Steps per episode.
    :param n_checkpoints: Models saved (evenly) over the last ``checkpoint_fraction`` of training,
        the last one at the end; the run's score is the mean of their evaluations.
    :param checkpoint_fraction: The final fraction of training over which checkpoints are saved.
    :param eval_episodes: Episodes per checkpoint evaluation.
    :param curve_points: Evaluations during training for the learning curve (evenly spaced, plus one at step 0).
    :param curve_eval_episodes: Episodes per learning-curve evaluation.
    :param keep_checkpoints: Keep the checkpoint model files after they are evaluated.
    :param model_kwargs: Keyword arguments for the algorithm (overriding the paper's defaults).
    :param algorithm: The algorithm class as ``"module:Class"``; it is built as
        ``Class("MlpPolicy", env, critic_sharing=scheme, seed=seed, **model_kwargs)``.
    :param vec_env: ``"batched"`` (:class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`) or ``"mpe2"`` (``DummyVecEnv``
        over mpe2 through the adapter): the same MDP, the first 92-152x faster to step with 64-256 worlds.
    :param n_envs: Worlds (envs) stepped together during training.
    :param env: The task: ``"simple_spread"`` (the paper's; ``n_agents``, ``num_agent_neighbors`` and ``vec_env`` apply
        to it only), another MPE task of :data:`~sb3_maddpg.envs.MPE_TASKS` (scored by its
        :data:`~sb3_maddpg.envs.MPE_TASK_METRICS` too), a PettingZoo parallel env factory as ``"module:function"``, or a
        registered gymnasium id whose env has an ``agent_layout``. Other tasks step ``n_envs`` envs in a ``DummyVecEnv``.
    :param env_kwargs: Keyword arguments for the task's constructor (MPE tasks also get ``max_cycles=episode_length``;
        for simple_spread, those of :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` beyond the fields above, e.g.
        ``{"continuous_actions": false}``).
    :param score_agents: Agent ids whose summed return is scored as ``group_return`` (e.g. the adversaries of
        ``simple_tag``); empty for none.
    :param normalize_observations: Normalise the observations the model sees by their running mean and variance
        (SB3's ``VecNormalize``, rewards left raw: the critics learn from per-agent rewards); the statistics are saved
        beside each checkpoint, and each checkpoint is evaluated with its own.
    """

    experiment: str
    scheme: str
    seed: int
    n_agents: int = 5
    num_agent_neighbors: int | None = None
    episodes: int = 100_000
    episode_length: int = EPISODE_LENGTH
    n_checkpoints: int = 20
    checkpoint_fraction: float = 0.2
    eval_episodes: int = 100
    curve_points: int = 50
    curve_eval_episodes: int = 20
    keep_checkpoints: bool = True
    model_kwargs: dict[str, Any] = field(default_factory=dict)
    algorithm: str = DEFAULT_ALGORITHM
    vec_env: str = "batched"
    n_envs: int = DEFAULT_N_ENVS
    env: str = DEFAULT_ENV
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    score_agents: tuple[str, ...] = ()
    normalize_observations: bool = False

    def __post_init__(self) -> None:
        _check_vec_env(self.vec_env, self.n_envs)
        _check_env(self.env)
        object.__setattr__(self, "score_agents", tuple(self.score_agents))
        if self.episodes < 1 or self.episode_length < 1:
            raise ValueError(f"episodes and episode_length must be positive, got {self.episodes}, {self.episode_length}.")
        if not 0 < self.checkpoint_fraction <= 1:
            raise ValueError(f"checkpoint_fraction must be in (0, 1], got {self.checkpoint_fraction}.")
        if self.n_checkpoints < 1:
            raise ValueError(f"n_checkpoints must be at least 1, got {self.n_checkpoints}.")
        if self.n_checkpoints > self.episodes * self.checkpoint_fraction:
            raise ValueError(
                f"{self.n_checkpoints} checkpoints do not fit in the last {self.checkpoint_fraction:.0%} of "
                f"{self.episodes} episodes: lower n_checkpoints (--n-checkpoints) or raise the budget (--episodes)."
            )
        if self.eval_episodes < 1 or self.curve_eval_episodes < 1 or self.curve_points < 0:
            raise ValueError("eval_episodes and curve_eval_episodes must be positive and curve_points non-negative.")

    @property
    def total_timesteps(self) -> int:
        """The training budget in env steps."""
        return self.episodes * self.episode_length

    @property
    def run_id(self) -> str:
        """The run's path relative to the results directory: ``<experiment>/<scheme>/seed_<seed>``."""
        return f"{self.experiment}/{self.scheme}/seed_{self.seed:03d}"

    @property
    def eval_seed(self) -> int:
        """Seed of the evaluation env: derived from the run seed, apart from the training env's seeds."""
        return 1_000_003 + 7919 * self.seed

    def checkpoint_episodes(self) -> list[int]:
        """
        The episodes after which checkpoints are saved: ``n_checkpoints`` evenly spaced over the last
        ``checkpoint_fraction`` of training, the last at the end (paper: every 1,000 episodes over
        episodes 80k-100k for experiment 1).

        :return: Increasing episode numbers.
        """
        window = self.episodes * self.checkpoint_fraction
        start = self.episodes - window
        return [round(start + window * k / self.n_checkpoints) for k in range(1, self.n_checkpoints + 1)]

    def checkpoint_steps(self) -> list[int]:
        """:return: The env steps at which checkpoints are saved."""
        return [episode * self.episode_length for episode in self.checkpoint_episodes()]

    @property
    def curve_interval(self) -> int:
        """The env steps between learning-curve evaluations (whole episodes; 0 when there is no curve)."""
        if self.curve_points == 0:
            return 0
        return max(1, self.episodes // self.curve_points) * self.episode_length

    def to_dict(self) -> dict[str, Any]:
        """:return: The config as JSON-compatible values."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "RunConfig":
        """
        :param data: A dict from :meth:`to_dict` (unknown keys are an error). Configs written before 0.2 have
            no ``vec_env`` and ``n_envs``: those runs stepped one mpe2 env.
        :return: The config.
        """
        data = {"vec_env": "mpe2", "n_envs": 1, **data}
        if isinstance(data.get("model_kwargs"), dict):  # a run stored before 0.3 resumes
            data["model_kwargs"] = renamed_in_0_3(data["model_kwargs"])
        return cls(**data)

    def same_as(self, other: "RunConfig") -> bool:
        """
        :param other: Another config.
        :return: Whether the two describe the same run (compared through JSON, so tuples equal lists).
        """
        return json.dumps(self.to_dict(), sort_keys=True) == json.dumps(other.to_dict(), sort_keys=True)


NOTE_KEEPING_FIELDS = frozenset(("name", "schemes", "seeds", "keep_checkpoints", "vec_env", "n_envs", "description"))
"""The fields whose change leaves a setting's note (:meth:`ExperimentConfig.described`) true: which runs, where, and
what is kept."""


@dataclass(frozen=True)
class ExperimentConfig:
    """
    One setting of the paper (an environment and a budget) with the schemes and seeds to run in it.
    Use :meth:`replace` for smaller runs, e.g. ``EXPERIMENTS["exp1"].replace(n_agents=3, episodes=5000)``.

    :param name: The setting's name (a directory of the results).
    :param n_agents: Number of agents and landmarks.
    :param num_agent_neighbors: Nearest other agents each agent observes, ``None`` for full observability.
    :param episodes: Training budget in episodes (of ``episode_length`` steps).
    :param schemes: The information-sharing schemes to compare.
    :param seeds: The seeds (independent trials) of each scheme.
    :param n_checkpoints: Checkpoints over the last ``checkpoint_fraction`` of training.
    :param checkpoint_fraction: The final fraction of training the score is taken over.
    :param eval_episodes: Episodes per checkpoint evaluation.
    :param curve_points: Learning-curve evaluations per run.
    :param curve_eval_episodes: Episodes per learning-curve evaluation.
    :param episode_length: Steps per episode.
    :param keep_checkpoints: Keep the checkpoint model files after evaluation.
    :param model_kwargs: Keyword arguments for ``MADDPG`` (the paper's hyperparameters are its defaults).
    :param algorithm: The algorithm class as ``"module:Class"``.
    :param description: One line for reports. Empty: the setting's values (:func:`describe_setting`); the presets'
        are a few words then those values (:meth:`described`), so that a changed value changes them.
    :param vec_env: ``"batched"`` or ``"mpe2"`` (see :class:`RunConfig`).
    :param n_envs: Worlds (envs) stepped together during training.
    :param scheme_model_kwargs: Keyword arguments for ``MADDPG`` of one scheme only, over ``model_kwargs``, e.g.
        ``{"selected": {"selector": 1}}`` (the nearest agent) for the ``selected`` runs.
    :param env: The task (see :class:`RunConfig`).
    :param env_kwargs: Keyword arguments for the task's constructor.
    :param score_agents: Agent ids whose summed return is scored as ``group_return``.
    :param normalize_observations: See :class:`RunConfig`.
    """

    name: str
    n_agents: int = 5
    num_agent_neighbors: int | None = None
    episodes: int = 100_000
    schemes: tuple[str, ...] = SCHEMES
    seeds: tuple[int, ...] = tuple(range(31))
    n_checkpoints: int = 20
    checkpoint_fraction: float = 0.2
    eval_episodes: int = 100
    curve_points: int = 50
    curve_eval_episodes: int = 20
    episode_length: int = EPISODE_LENGTH
    keep_checkpoints: bool = True
    model_kwargs: dict[str, Any] = field(default_factory=dict)
    algorithm: str = DEFAULT_ALGORITHM
    description: str = ""
    vec_env: str = "batched"
    n_envs: int = DEFAULT_N_ENVS
    scheme_model_kwargs: dict[str, dict[str, Any]] = field(default_factory=dict)
    env: str = DEFAULT_ENV
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    score_agents: tuple[str, ...] = ()
    normalize_observations: bool = False

    def __post_init__(self) -> None:
        _check_vec_env(self.vec_env, self.n_envs)
        _check_env(self.env)
        object.__setattr__(self, "score_agents", tuple(self.score_agents))
        unknown = sorted(set(self.scheme_model_kwargs) - set(SCHEMES) - set(self.schemes))
        if unknown:
            raise ValueError(
                f"scheme_model_kwargs names unknown scheme(s) {unknown}: its keys must be schemes, e.g. "
                f"{{'selected': {{'selector': 1}}}} (schemes: {', '.join(SCHEMES)})."
            )
        if not self.description:
            object.__setattr__(self, "description", describe_setting(self))

    def described(self, note: str = "") -> "ExperimentConfig":
        """
        :param note: A few words on what the setting is (e.g. ``"Experiment 1"``), or none.
        :return: A copy described by its values (:func:`describe_setting`), after ``note`` and ``": "`` if given.
        """
        values = describe_setting(self)
        return dataclasses.replace(self, description=f"{note}: {values}" if note else values)

    @property
    def note(self) -> str | None:
        """The words before the values in a description that :meth:`described` wrote (``""`` for none), or ``None``
        for a description written by hand (one that does not end with the setting's values)."""
        values = describe_setting(self)
        if self.description == values:
            return ""
        if self.description.endswith(f": {values}"):
            return self.description[: -len(values) - 2]
        return None

    def runs(self) -> list[RunConfig]:
        """:return: One run config per (scheme, seed), seeds outermost so partial sweeps stay balanced."""
        per_run = {"experiment", "scheme", "seed", "model_kwargs"}
        shared = {f.name: getattr(self, f.name) for f in dataclasses.fields(RunConfig) if f.name not in per_run}
        return [
            RunConfig(
                experiment=self.name,
                scheme=scheme,
                seed=seed,
                # Deep copies: algorithms may write into their kwargs, and the configs must stay as they were.
                model_kwargs=merge_model_kwargs(self.model_kwargs, self.scheme_model_kwargs.get(scheme, {})),
                **shared,
            )
            for seed in self.seeds
            for scheme in self.schemes
        ]

    def replace(self, **changes: Any) -> "ExperimentConfig":
        """
        :param changes: Fields to change (``None`` values are ignored, so CLI options can be passed as they are;
            use :func:`dataclasses.replace` to set ``num_agent_neighbors=None``).
        :return: A copy with the changes. A task other than simple_spread sets ``n_agents`` to its own team size (read
            from one env) when the task, its ``env_kwargs`` or ``n_agents`` change. A description :meth:`described`
            wrote says the new values, and keeps its note only if the changes leave the setting as it was
            (:data:`NOTE_KEEPING_FIELDS`); a description written by hand is kept unless ``changes`` give another.
        """
        changes = {key: value for key, value in changes.items() if value is not None}
        note = self.note
        changed = dataclasses.replace(self, **changes)
        if changed.env != DEFAULT_ENV and changes.keys() & {"env", "env_kwargs", "n_agents"}:
            changed = dataclasses.replace(changed, n_agents=task_team_size(changed.env, changed.env_kwargs))
        if "description" in changes or note is None:
            return changed
        same_setting = all(key in NOTE_KEEPING_FIELDS or value == getattr(self, key) for key, value in changes.items())
        return changed.described(note if same_setting else "")

    def to_dict(self) -> dict[str, Any]:
        """:return: The config as JSON-compatible values."""
        data = dataclasses.asdict(self)
        data["schemes"], data["seeds"] = list(self.schemes), list(self.seeds)
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "ExperimentConfig":
        """
        :param data: A dict from :meth:`to_dict` or a JSON file. Files written before 0.2 have no ``vec_env`` and
            ``n_envs``: those experiments stepped one mpe2 env per run.
        :return: The config.
        """
        data = {"vec_env": "mpe2", "n_envs": 1, **data}
        if isinstance(data.get("model_kwargs"), dict):  # files written before 0.3
            data["model_kwargs"] = renamed_in_0_3(data["model_kwargs"])
        if isinstance(data.get("scheme_model_kwargs"), dict):
            data["scheme_model_kwargs"] = {
                scheme: renamed_in_0_3(kwargs) if isinstance(kwargs, dict) else kwargs
                for scheme, kwargs in data["scheme_model_kwargs"].items()
            }
        for key in ("schemes", "seeds", "score_agents"):
            if key in data:
                data[key] = tuple(data[key])
        return cls(**data)


EXP1 = ExperimentConfig(name="exp1", n_agents=5, num_agent_neighbors=None, episodes=100_000, n_checkpoints=20).described(
    "Experiment 1"
)
"""The paper's experiment 1 (fully observable cooperative navigation)."""

EXP2 = ExperimentConfig(name="exp2", n_agents=5, num_agent_neighbors=2, episodes=150_000, n_checkpoints=30).described(
    "Experiment 2"
)
"""The paper's experiment 2 (each agent observes its two nearest other agents)."""


def tuned_experiment(paper: ExperimentConfig) -> ExperimentConfig:
    """
    :param paper: One of the paper's settings (``EXP1``, ``EXP2``).
    :return: The same setting, protocol and budget at the hyperparameters ``sb3_maddpg/hyperparams/maddpg.yml``
        holds for it, named ``<setting>_tuned``.
    """
    tuned = load_hyperparams(paper.name)
    if tuned.n_agents != paper.n_agents or tuned.n_timesteps != paper.episodes * paper.episode_length:
        raise ValueError(
            f"maddpg.yml's {paper.name!r} entry is for {tuned.n_agents} agents and {tuned.n_timesteps:,} steps, but the "
            f"setting has {paper.n_agents} agents and {paper.episodes * paper.episode_length:,} steps: correct the entry."
        )
    env_kwargs = dict(tuned.env_kwargs)
    num_agent_neighbors = env_kwargs.pop("num_agent_neighbors", paper.num_agent_neighbors)
    return dataclasses.replace(
        paper,
        name=f"{paper.name}_tuned",
        num_agent_neighbors=num_agent_neighbors,
        env_kwargs={**paper.env_kwargs, **env_kwargs},
        model_kwargs=merge_model_kwargs(paper.model_kwargs, tuned.model_kwargs),
    ).described(tuned.description)


EXP1_TUNED = tuned_experiment(EXP1)
"""Experiment 1 at the best configuration measured at N=5 (``sb3_maddpg/hyperparams/maddpg.yml``)."""

EXP2_TUNED = tuned_experiment(EXP2)
"""Experiment 2 with experiment 1's best changes (``sb3_maddpg/hyperparams/maddpg.yml``)."""

SELECT_NEAREST_AT_N3: dict[str, dict[str, Any]] = {"selected": {"selector": 1}}
"""``selected`` runs of a 3-agent team select the nearest other agent: selecting both (the default ``k=2``) would be
``full`` sharing in another order."""

N3_FULL = ExperimentConfig(
    name="n3_full",
    n_agents=3,
    num_agent_neighbors=None,
    episodes=20_000,
    seeds=tuple(range(10)),
    n_checkpoints=20,
    keep_checkpoints=False,
    scheme_model_kwargs=SELECT_NEAREST_AT_N3,
).described("Experiment 1's setting with 3 agents, 10 seeds, selected with k=1")
"""Experiment 1's setting with 3 agents, at a budget where the package learns on a small machine."""

N3_PARTIAL = dataclasses.replace(N3_FULL, name="n3_partial", num_agent_neighbors=1).described(
    "Experiment 2's setting with 3 agents, 10 seeds, selected with k=1"
)
"""Experiment 2's setting with 3 agents: each agent observes its nearest other agent (of two)."""

TINY_MODEL_KWARGS: dict[str, Any] = {
    "learning_starts": 250,
    "batch_size": 64,
    "buffer_size": 10_000,
    "transitions_per_update": 50,
    "policy_kwargs": {"net_arch": {"pi": [16, 16], "qf": [16, 16]}},
}
"""Tiny networks and an early start for pipeline tests."""

SMOKE = ExperimentConfig(
    name="smoke",
    n_agents=3,
    num_agent_neighbors=None,
    episodes=40,
    seeds=(0, 1),
    n_envs=4,
    n_checkpoints=2,
    eval_episodes=4,
    curve_points=2,
    curve_eval_episodes=2,
    keep_checkpoints=False,
    model_kwargs=TINY_MODEL_KWARGS,
    scheme_model_kwargs=SELECT_NEAREST_AT_N3,  # k=2 of 3 would select everyone, as "full" does
).described("Smoke test, 2 seeds, tiny networks (tests the pipeline, not the methods)")
"""A pipeline check that runs every scheme in seconds (for CI)."""

EXPERIMENTS: dict[str, ExperimentConfig] = {
    config.name: config for config in (EXP1, EXP2, EXP1_TUNED, EXP2_TUNED, N3_FULL, N3_PARTIAL, SMOKE)
}
"""The named presets."""


def load_experiment(name_or_path: str) -> ExperimentConfig:
    """
    :param name_or_path: A preset name (``exp1``, ``exp2``, ``exp1_tuned``, ``exp2_tuned``, ``n3_full``, ``n3_partial``,
        ``smoke``) or the path of a JSON file written from :meth:`ExperimentConfig.to_dict`.
    :return: The experiment config; a ``ValueError`` that names the cause and what to give instead if there is none.
    """
    if name_or_path in EXPERIMENTS:
        return EXPERIMENTS[name_or_path]
    if not name_or_path.endswith(".json"):
        raise ValueError(f"Unknown experiment {name_or_path!r}: use one of {sorted(EXPERIMENTS)} or a .json config file.")
    try:
        with open(name_or_path) as file:
            data = json.load(file)
    except FileNotFoundError:
        raise ValueError(
            f"No experiment file {name_or_path!r}: give the path of an existing .json config file, or a preset "
            f"({', '.join(EXPERIMENTS)})."
        ) from None
    except OSError as error:
        raise ValueError(
            f"Cannot read experiment file {name_or_path!r} ({error.strerror}): give a readable .json file."
        ) from None
    except json.JSONDecodeError as error:
        raise ValueError(
            f"Experiment file {name_or_path!r} is not JSON ({error}): write it as ExperimentConfig.to_dict() gives it "
            "(e.g. sb3-maddpg tune --preset-out writes one)."
        ) from None
    return _experiment_from_file(name_or_path, data)


def _experiment_from_file(path: str, data: Any) -> ExperimentConfig:
    """:func:`load_experiment`'s config from a file's JSON, with the file named in any error."""
    fields = [field.name for field in dataclasses.fields(ExperimentConfig)]
    if not isinstance(data, dict) or "name" not in data:
        raise ValueError(f'Experiment file {path!r} holds no experiment: give a JSON object with a "name" and {fields[1:]}.')
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ValueError(f"Experiment file {path!r} has unknown key(s) {unknown}: an experiment's keys are {fields}.")
    try:
        return ExperimentConfig.from_dict(data)
    except (TypeError, ValueError) as error:
        raise ValueError(f"Experiment file {path!r}: {error}") from None
