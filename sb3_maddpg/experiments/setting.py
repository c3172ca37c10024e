"""The configuration types: one dataclass per concern (:class:`TaskConfig`, :class:`AlgorithmConfig`,
:class:`ProtocolConfig`), :class:`Setting` (their fields together, defined once), an experiment (a setting with its
schemes and seeds) and a run (a setting with one scheme and one seed), the one way both are read back from JSON, and a
setting's values in words (:func:`describe_setting`) and for another budget (:func:`scaled_schedule`)."""

import copy
import dataclasses
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

from sb3_maddpg.common.argument_ranges import TEAM_ALGORITHM_RANGES, Range, check_arguments
from sb3_maddpg.compat import read_stored_config
from sb3_maddpg.envs.task_by_name import check_env_name, task_team_size
from sb3_maddpg.experiments.defaults import (
    ALGORITHMS,
    DEFAULT_ALGORITHM,
    DEFAULT_ENV,
    DEFAULT_N_ENVS,
    EPISODE_LENGTH,
    SCHEMES,
    VEC_ENVS,
)
from sb3_maddpg.experiments.reference_specs import check_reference_policies

SettingT = TypeVar("SettingT", bound="Setting")


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


def _check_vec_env(vec_env: str) -> None:
    if vec_env not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {VEC_ENVS}, got {vec_env!r}.")


TASK_RANGES: dict[str, Range] = {
    "n_agents": Range("agents in the team", integer=True, low=1, hint="use 5 (the paper's N=5 studies) or 3"),
    "num_agent_neighbors": Range(
        "the other agents each agent observes, nearest first",
        integer=True,
        low=0,
        none_means="every other agent",
        hint="use None for full observability, or 2 (the paper's Exp. 2)",
    ),
    "episode_length": Range("env steps per episode", integer=True, low=1, hint="use 25 (the paper's)"),
    "n_envs": Range("envs stepped at once per run", integer=True, low=1, hint="use 100 for the batched env"),
}
"""The numeric fields of :class:`TaskConfig` (simple_spread's own bounds on them are checked when its env is built)."""

PROTOCOL_RANGES: dict[str, Range] = {
    "episodes": Range("the training budget in episodes", integer=True, low=1, hint="use 40_000 (1M steps of 25)"),
    "n_checkpoints": Range("models saved over the last checkpoint_fraction of training", integer=True, low=1, hint="use 20"),
    "checkpoint_fraction": Range(
        "the final fraction of training over which checkpoints are saved",
        low=0,
        high=1,
        low_open=True,
        hint="use 0.2 (the paper's last 20%)",
    ),
    "eval_episodes": Range("episodes per checkpoint evaluation", integer=True, low=1, hint="use 100 (the paper's)"),
    "curve_points": Range("evaluations for the learning curve; 0: none", integer=True, low=0, hint="use 50"),
    "curve_eval_episodes": Range("episodes per learning-curve evaluation", integer=True, low=1, hint="use 20"),
}
"""The numeric fields of :class:`ProtocolConfig`."""


@dataclass(frozen=True, kw_only=True)
class TaskConfig:
    """
    The task and its env: what the team learns, which team, and how its envs are stepped in training.

    :param env: The task: ``"simple_spread"`` (the paper's; ``n_agents``, ``num_agent_neighbors`` and ``vec_env`` apply
        to it only), another MPE task of :data:`~sb3_maddpg.envs.MPE_TASKS` (scored by its
        :data:`~sb3_maddpg.envs.MPE_TASK_METRICS` too), a PettingZoo parallel env factory as ``"module:function"``, or a
        registered gymnasium id whose env has an ``agent_layout``. Other tasks step ``n_envs`` envs in a ``DummyVecEnv``.
    :param env_kwargs: Keyword arguments for the task's constructor (MPE tasks also get ``max_cycles=episode_length``;
        for simple_spread, those of :class:`~sb3_maddpg.envs.SimpleSpreadVecEnv` beyond the fields above, e.g.
        ``{"continuous_actions": false}``).
    :param n_agents: Number of agents and landmarks of simple_spread; another task's team size (its own: see
        :meth:`ExperimentConfig.replace`).
    :param num_agent_neighbors: Nearest other agents each agent observes, ``None`` for all.
    :param episode_length: Steps per episode.
    :param score_agents: Agent ids whose summed return is scored as ``group_return`` (e.g. the adversaries of
        ``simple_tag``); empty for none.
    :param normalize_observations: Normalise the observations the model sees by their running mean and variance
        (SB3's ``VecNormalize``, rewards left raw: the critics learn from per-agent rewards); the statistics are saved
        beside each checkpoint, and each checkpoint is evaluated with its own.
    :param vec_env: ``"batched"`` (:class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`) or ``"mpe2"`` (``DummyVecEnv``
        over mpe2 through the adapter): the same MDP, the first 92-152x faster to step with 64-256 worlds.
    :param n_envs: Worlds (envs) stepped together during training.
    """

    env: str = DEFAULT_ENV
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    n_agents: int = 5
    num_agent_neighbors: int | None = None
    episode_length: int = EPISODE_LENGTH
    score_agents: tuple[str, ...] = ()
    normalize_observations: bool = False
    vec_env: str = "batched"
    n_envs: int = DEFAULT_N_ENVS

    def __post_init__(self) -> None:
        check_arguments(TASK_RANGES, vars(self))
        _check_vec_env(self.vec_env)
        check_env_name(self.env)
        object.__setattr__(self, "score_agents", tuple(self.score_agents))


@dataclass(frozen=True, kw_only=True)
class AlgorithmConfig:
    """
    The algorithm and its hyperparameters.

    :param algorithm: The algorithm class as ``"module:Class"``, or ``"maddpg"`` or ``"matd3"`` (stored as their
        ``"module:Class"``: :data:`~sb3_maddpg.experiments.defaults.ALGORITHMS`); it is built as
        ``Class("MlpPolicy", env, critic_sharing=scheme, seed=seed, **model_kwargs)``.
    :param model_kwargs: Keyword arguments for the algorithm (overriding the paper's defaults).
    """

    algorithm: str = DEFAULT_ALGORITHM
    model_kwargs: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "algorithm", ALGORITHMS.get(self.algorithm, self.algorithm))


@dataclass(frozen=True, kw_only=True)
class ProtocolConfig:
    """
    The training budget and the evaluation protocol: the paper's evaluates checkpoints saved over the last 20% of
    training, each on seeded episodes.

    :param episodes: Training budget in episodes (of ``episode_length`` steps).
    :param n_checkpoints: Models saved (evenly) over the last ``checkpoint_fraction`` of training,
        the last one at the end; a run's score is the mean of their evaluations.
    :param checkpoint_fraction: The final fraction of training over which checkpoints are saved.
    :param eval_episodes: Episodes per checkpoint evaluation.
    :param curve_points: Evaluations during training for the learning curve (evenly spaced, plus one at step 0).
    :param curve_eval_episodes: Episodes per learning-curve evaluation.
    :param keep_checkpoints: Keep the checkpoint model files after they are evaluated.
    """

    episodes: int = 100_000
    n_checkpoints: int = 20
    checkpoint_fraction: float = 0.2
    eval_episodes: int = 100
    curve_points: int = 50
    curve_eval_episodes: int = 20
    keep_checkpoints: bool = True

    def __post_init__(self) -> None:
        check_arguments(PROTOCOL_RANGES, vars(self))


CONCERNS = (TaskConfig, AlgorithmConfig, ProtocolConfig)  # Setting's bases, in this order
"""The concerns a setting is made of, each a dataclass of its own fields."""

SETTING_KEYS = (
    "n_agents",
    "num_agent_neighbors",
    "episodes",
    "episode_length",
    "n_checkpoints",
    "checkpoint_fraction",
    "eval_episodes",
    "curve_points",
    "curve_eval_episodes",
    "keep_checkpoints",
    "model_kwargs",
    "algorithm",
    "vec_env",
    "n_envs",
    "env",
    "env_kwargs",
    "score_agents",
    "normalize_observations",
)
"""A setting's fields in the order the files written so far hold them."""


@dataclass(frozen=True, kw_only=True)
class Setting(TaskConfig, AlgorithmConfig, ProtocolConfig):
    """
    What an experiment and each of its runs share: a task (:class:`TaskConfig`), an algorithm and its hyperparameters
    (:class:`AlgorithmConfig`) and a budget with its evaluation protocol (:class:`ProtocolConfig`), their fields as
    keywords. :class:`ExperimentConfig` adds the schemes and seeds, :class:`RunConfig` one scheme and one seed.
    """

    STORED_KEYS: ClassVar[tuple[str, ...]] = ()
    """The keys of :meth:`to_dict`, in the order the files written so far have them."""

    def __post_init__(self) -> None:
        for concern in CONCERNS:
            check = getattr(concern, "__post_init__", None)
            if check is not None:
                check(self)

    def setting(self) -> dict[str, Any]:
        """:return: The :class:`Setting` fields' values (the same objects), by name."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(Setting)}

    def to_dict(self) -> dict[str, Any]:
        """:return: The config as JSON-compatible values, its keys in the order of :attr:`STORED_KEYS`."""
        data = dataclasses.asdict(self)
        for key in ("schemes", "seeds"):  # an experiment's: written as lists, as they always were
            if key in data:
                data[key] = list(data[key])
        return {key: data[key] for key in self.STORED_KEYS or tuple(data)}

    @classmethod
    def from_dict(cls: type[SettingT], data: dict[str, Any]) -> SettingT:
        """
        :param data: A dict from :meth:`to_dict` or a stored JSON file, read by
            :func:`~sb3_maddpg.compat.read_stored_config` (unknown keys are an error).
        :return: The config.
        """
        return cls.from_fields(read_stored_config(data))

    @classmethod
    def from_fields(cls: type[SettingT], fields: dict[str, Any]) -> SettingT:
        """
        :param fields: This version's fields as JSON or YAML give them (lists where the config holds tuples), e.g. a
            preset file's; those left out keep their defaults (unknown keys are an error).
        :return: The config.
        """
        data = dict(fields)
        for key in ("schemes", "seeds", "score_agents"):  # JSON and YAML have lists; the configs hold tuples
            if key in data:
                if not isinstance(data[key], list | tuple):
                    raise ValueError(f"{key} must be a list, e.g. {key}: [{data[key]}], got {data[key]!r}.")
                data[key] = tuple(data[key])
        return cls(**data)


@dataclass(frozen=True)
class RunConfig(Setting):
    """
    One training run: a scheme, a seed and a :class:`Setting` (every other field, as keywords). A run is a pure
    function of its config (the results of two runs with equal configs differ only by floating-point noise).

    :param experiment: The experiment (setting) name, e.g. ``"exp1"``.
    :param scheme: The critic information-sharing scheme (``MADDPG(critic_sharing=...)``).
    :param seed: The run's seed: the model's seed; the evaluation env is seeded from it too.
    """

    STORED_KEYS: ClassVar[tuple[str, ...]] = ("experiment", "scheme", "seed", *SETTING_KEYS)

    experiment: str
    scheme: str
    seed: int

    def __post_init__(self) -> None:
        super().__post_init__()  # each concern's checks
        if self.n_checkpoints > self.episodes * self.checkpoint_fraction:  # an experiment may be shrunk in steps
            raise ValueError(
                f"{self.n_checkpoints} checkpoints do not fit in the last {self.checkpoint_fraction:.0%} of "
                f"{self.episodes} episodes: lower n_checkpoints or raise episodes."
            )

    def __getstate__(self) -> dict[str, Any]:
        # A config sent to a worker travels as its fields alone: what was derived from them and kept beside them (its
        # task: sb3_maddpg.experiments.tasks.run_task) is derived again there, once.
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

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

    def same_as(self, other: "RunConfig") -> bool:
        """
        :param other: Another config.
        :return: Whether the two describe the same run (compared through JSON, so tuples equal lists).
        """
        return json.dumps(self.to_dict(), sort_keys=True) == json.dumps(other.to_dict(), sort_keys=True)


RUN_SEED = dataclasses.replace(TEAM_ALGORITHM_RANGES["seed"], none_means=None)
"""A run's seed: the model's seed, but never None (a run is one seeded trial)."""


def check_seeds(seeds: Sequence[int]) -> None:
    """
    Refuse a seed out of range or one seed twice (its runs would share a directory). No seed is an experiment of no
    runs, which ``sb3-maddpg run`` refuses by name.

    :param seeds: An experiment's seeds.
    """
    for seed in seeds:
        RUN_SEED.check("seeds", seed)
    repeated = sorted({seed for seed in seeds if list(seeds).count(seed) > 1})
    if repeated:
        raise ValueError(f"seeds holds {repeated} more than once: each seed is one run of each scheme; give each once.")


NOTE_KEEPING_FIELDS = frozenset(
    ("name", "schemes", "seeds", "keep_checkpoints", "vec_env", "n_envs", "description", "reference_policies")
)
"""The fields whose change leaves a setting's note (:meth:`ExperimentConfig.described`) true: which runs, where, what
is kept, and which references are evaluated beside them."""


@dataclass(frozen=True)
class ExperimentConfig(Setting):
    """
    One setting of the paper (a :class:`Setting`, its fields as keywords) with the schemes and seeds to run in it.
    Use :meth:`replace` for smaller runs, e.g. ``EXPERIMENTS["exp1"].replace(n_agents=3, episodes=5000)``.

    :param name: The setting's name (a directory of the results).
    :param schemes: The information-sharing schemes to compare.
    :param seeds: The seeds (independent trials) of each scheme.
    :param description: One line for reports. Empty: the setting's values (:func:`describe_setting`); the presets'
        are a few words then those values (:meth:`described`), so that a changed value changes them.
    :param scheme_model_kwargs: Keyword arguments for the algorithm of one scheme only, over ``model_kwargs``, e.g.
        ``{"selected": {"selector": 1}}`` (the nearest agent) for the ``selected`` runs.
    :param reference_policies: Teams that need no training, evaluated once per seed on the same seeded episodes as
        that seed's runs and reported beside the schemes, by name: ``{"kind": "random"}`` (uniformly random actions)
        or ``{"kind": "no_op", "action": 4}`` (doing nothing: zero actions, and ``action`` for discrete agents), e.g.
        ``{"random": {"kind": "random"}, "nothing": {"kind": "no_op", "action": 4}}`` for pursuit
        (:mod:`~sb3_maddpg.experiments.references`); empty for none.
    """

    STORED_KEYS: ClassVar[tuple[str, ...]] = (
        "name",
        "n_agents",
        "num_agent_neighbors",
        "episodes",
        "schemes",
        "seeds",
        "n_checkpoints",
        "checkpoint_fraction",
        "eval_episodes",
        "curve_points",
        "curve_eval_episodes",
        "episode_length",
        "keep_checkpoints",
        "model_kwargs",
        "algorithm",
        "description",
        "vec_env",
        "n_envs",
        "scheme_model_kwargs",
        "env",
        "env_kwargs",
        "score_agents",
        "normalize_observations",
        "reference_policies",
    )

    name: str
    schemes: tuple[str, ...] = SCHEMES
    seeds: tuple[int, ...] = tuple(range(31))
    description: str = ""
    scheme_model_kwargs: dict[str, dict[str, Any]] = field(default_factory=dict)
    reference_policies: dict[str, dict[str, Any]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        super().__post_init__()
        check_scheme_variants(self.schemes, self.model_kwargs, self.scheme_model_kwargs)
        check_reference_policies(self.reference_policies)
        check_seeds(self.seeds)
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
        shared = {name: value for name, value in self.setting().items() if name != "model_kwargs"}
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
        :param changes: Fields to change (``None`` values are ignored: use :func:`dataclasses.replace` to set
            ``num_agent_neighbors=None``).
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


SCHEDULE_FLOORS = {"n_checkpoints": 1, "eval_episodes": 10, "curve_points": 2, "curve_eval_episodes": 5}
"""The least of each evaluation count that :func:`scaled_schedule` shrinks to (or the experiment's own, if smaller)."""


def scaled_schedule(experiment: Setting, episodes: int) -> dict[str, int]:
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


def _plural(count: int, noun: str) -> str:
    return f"{count:,} {noun}" + ("" if count == 1 else "s")


def describe_setting(experiment: Setting) -> str:
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


SCHEME_LABEL = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
"""What a scheme's name may be: it names its runs' directory (``<experiment>/<scheme>/seed_<seed>``)."""


def check_scheme_variants(
    schemes: tuple[str, ...], model_kwargs: dict[str, Any], scheme_model_kwargs: dict[str, dict[str, Any]]
) -> None:
    """
    Refuse what would train a scheme under another's name: ``critic_sharing`` in the kwargs every scheme shares, a
    scheme of the registry given another's ``critic_sharing``, ``scheme_model_kwargs`` of a scheme that is neither one
    of the package's nor a variant (one that names its ``critic_sharing``), and a scheme name that is no directory name.

    :param schemes: The experiment's schemes.
    :param model_kwargs: The kwargs of every scheme.
    :param scheme_model_kwargs: Each scheme's own kwargs.
    """
    from sb3_maddpg.sharing.registry import resolve_scheme

    if "critic_sharing" in model_kwargs:
        raise ValueError(
            f"model_kwargs hold critic_sharing={model_kwargs['critic_sharing']!r}, which would train every scheme as "
            "that one under its own name: a scheme's critic_sharing is its name; for a variant of a scheme under a name "
            'of its own, give it in scheme_model_kwargs, e.g. {"selected_next": {"critic_sharing": "selected", ...}}.'
        )
    for scheme in schemes:
        if not SCHEME_LABEL.match(scheme):
            raise ValueError(
                f"Scheme name {scheme!r} cannot name its runs' directory: use letters, digits, '_', '-' and '.', "
                "starting with a letter or digit (e.g. 'selected_next')."
            )
    for scheme, kwargs in scheme_model_kwargs.items():
        if "critic_sharing" not in kwargs:
            if scheme not in SCHEMES and scheme not in schemes:
                raise ValueError(
                    f"scheme_model_kwargs names unknown scheme {scheme!r}: its keys must be schemes, e.g. "
                    f"{{'selected': {{'selector': 1}}}} (schemes: {', '.join(SCHEMES)}), or variants that name their "
                    "critic_sharing, e.g. {'selected_next': {'critic_sharing': 'selected', ...}}."
                )
            continue
        try:
            named = resolve_scheme(scheme)
        except ValueError:
            continue  # a variant's own name
        if resolve_scheme(kwargs["critic_sharing"]) is not named:
            raise ValueError(
                f"scheme_model_kwargs give scheme {scheme!r} critic_sharing={kwargs['critic_sharing']!r}: its runs would "
                f"be reported as {scheme!r}. Give the variant a name of its own (e.g. '{scheme}_variant')."
            )
