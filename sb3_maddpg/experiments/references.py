"""Reference policies beside a setting's runs: teams that need no training, evaluated on the runs' own episodes.

A setting declares them in ``reference_policies`` (:class:`~sb3_maddpg.experiments.setting.ExperimentConfig`), by
name, each a kind of :data:`~sb3_maddpg.experiments.reference_specs.REFERENCE_KINDS`::

    reference_policies:
      random: {kind: random}            # uniform over each agent's actions
      nothing: {kind: no_op, action: 4}  # every agent does nothing (pursuit's no-op: 4, stay)

``sb3-maddpg run`` evaluates each once per seed of the setting, before its runs (:func:`write_references`): on the
evaluation env a run of that seed evaluates its checkpoints on, from the same seed, for as many episodes, and scored
by the same keys, so that a reference and a run of one seed see the same seeded episodes. The scores go into
``<results>/<experiment>/references.json`` (kept across sweeps: a seed evaluated before is not evaluated again), and
``sb3-maddpg report`` shows them beside the schemes' with their intervals (``references.md``,
:func:`~sb3_maddpg.results.reference_table.format_references_markdown`).
"""

import json
import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from stable_baselines3.common.vec_env import VecEnv

    from sb3_maddpg.experiments.setting import ExperimentConfig, RunConfig

REFERENCE_PROTOCOL_KEYS = (
    "env",
    "env_kwargs",
    "n_agents",
    "num_agent_neighbors",
    "episode_length",
    "eval_episodes",
    "vec_env",
    "score_agents",
)
"""A setting's fields that decide a reference's evaluation episodes and scores: stored scores of other values are
evaluated again."""


class ReferencePolicyError(ValueError):
    """A setting's reference policy cannot act in its task (e.g. no no-op action for discrete agents): a user's
    error, which ``sb3-maddpg run`` says in one line, before any run trains."""


class NoOpTeamPolicy:
    """
    A team that does nothing: each continuous agent's action is zero (clipped into its space), each discrete agent's
    is its no-op action (a one-hot slot of the joint action, as MADDPG's actions are on
    :class:`~sb3_maddpg.envs.PettingZooToGym`).

    :param action_space: The env's joint action space (a ``Box``).
    :param layout: The team's :class:`~sb3_maddpg.common.layout.AgentLayout` (which agents are discrete, and where).
    :param no_op: The discrete agents' no-op action (an index of their moves); ``None`` for a team with none.
    """

    def __init__(self, action_space: Any, layout: Any, no_op: int | None = None) -> None:
        action = np.clip(np.zeros(action_space.shape, dtype=action_space.dtype), action_space.low, action_space.high)
        for agent, (part, size) in enumerate(zip(layout.action_slices, layout.action_sizes)):
            if not layout.is_discrete(agent):
                continue
            if no_op is None or no_op >= size:
                cause = "no no-op action is given" if no_op is None else f"its no-op action {no_op} is not one of them"
                raise ValueError(
                    f"reference_policies: agent {layout.agent_ids[agent]!r} has {size} discrete actions, and {cause}: give "
                    f"the no_op policy the action that does nothing, e.g. {{kind: no_op, action: {size - 1}}} if its last "
                    "is 'stay' (pursuit's is 4)."
                )
            action[part] = 0.0
            action[part.start + no_op] = 1.0
        self.action = action

    def predict(
        self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ) -> tuple[np.ndarray, None]:
        """
        :param observation: A joint observation, or a batch of them (only its batch size is read).
        :param state: Unused.
        :param episode_start: Unused.
        :param deterministic: Unused: the team does the same either way.
        :return: The no-op joint action (one per observation of a batch) and ``None``.
        """
        observation = np.asarray(observation)
        if observation.ndim == 1:
            return self.action.copy(), None
        return np.repeat(self.action[None], observation.shape[0], axis=0), None


def reference_policy(spec: Mapping[str, Any], env: "VecEnv", seed: int) -> Any:
    """
    :param spec: A reference policy as a setting declares it (:func:`check_reference_policies`).
    :param env: The evaluation env it acts in.
    :param seed: Seed of its draws (a random policy's).
    :return: The policy, with SB3's ``predict``: :class:`~sb3_maddpg.envs.RandomTeamPolicy` or
        :class:`NoOpTeamPolicy`.
    """
    from sb3_maddpg.envs import RandomTeamPolicy

    if spec["kind"] == "random":  # uniform over a discrete agent's one-hot slot: its largest entry, uniform
        return RandomTeamPolicy(env.action_space, seed=seed)
    return NoOpTeamPolicy(env.action_space, env.get_attr("agent_layout")[0], spec.get("action"))


def evaluate_reference(spec: Mapping[str, Any], config: "RunConfig") -> dict[str, Any]:
    """
    Evaluate a reference policy as a run's checkpoints are evaluated
    (:func:`~sb3_maddpg.experiments.runner.evaluate_checkpoints`): the same evaluation env, seed, episodes and scores.

    :param spec: The reference policy.
    :param config: A run of the seed to evaluate it on (its scheme does not matter).
    :return: ``{"eval_seed": ..., "n_episodes": ..., "score": {key: value}}``, the score's keys the run's
        (:attr:`~sb3_maddpg.experiments.tasks.RunTask.keys`).
    """
    from sb3_maddpg.experiments.tasks import run_task

    task = run_task(config)
    env = task.make_eval_env(config.eval_episodes)
    try:
        result = task.evaluate(reference_policy(spec, env, seed=task.eval_seed), env)
    finally:
        env.close()
    return {"eval_seed": task.eval_seed, "n_episodes": result["n_episodes"], "score": {k: result[k] for k in task.keys}}


def reference_protocol(experiment: "ExperimentConfig") -> dict[str, Any]:
    """
    :return: The setting's fields that decide its references' scores (:data:`REFERENCE_PROTOCOL_KEYS`), as JSON reads
        them back (lists for tuples), so that a stored protocol compares equal to the same setting's.
    """
    stored = experiment.to_dict()
    return json.loads(json.dumps({key: stored[key] for key in REFERENCE_PROTOCOL_KEYS}))


def write_references(
    experiment: "ExperimentConfig", results_dir: str | os.PathLike[str], log: Callable[[str], None] | None = None
) -> Path | None:
    """
    Evaluate a setting's reference policies on each of its seeds that the results directory does not hold yet, and
    write ``<results_dir>/<experiment>/references.json``: ``protocol`` (:func:`reference_protocol`) and, per policy,
    ``policy`` (as declared) and ``seeds``: seed -> :func:`evaluate_reference`'s result. Scores of another protocol
    or another declaration are evaluated again; seeds the setting no longer runs are kept.

    :param experiment: The setting.
    :param results_dir: The results directory of its sweep.
    :param log: Where to say what was evaluated (e.g. the sweep's log), or ``None``.
    :return: The file, or ``None`` for a setting that declares no reference policy.
    :raise ReferencePolicyError: When a policy cannot act in the task (the file is left as it was).
    """
    from sb3_maddpg.compat import with_version
    from sb3_maddpg.experiments.results_dir import REFERENCES_FILE, read_json, write_json_atomic

    if not experiment.reference_policies:
        return None
    path = Path(results_dir) / experiment.name / REFERENCES_FILE
    protocol = reference_protocol(experiment)
    stored = read_json(path)
    held = stored.get("policies", {}) if isinstance(stored, dict) and stored.get("protocol") == protocol else {}
    runs = {config.seed: config for config in experiment.runs()}  # a run of each seed: its eval env and seed
    policies, evaluated, started = {}, [], time.perf_counter()
    for name, spec in experiment.reference_policies.items():
        spec = json.loads(json.dumps(spec))  # as stored
        before = held.get(name) if isinstance(held.get(name), dict) and held[name].get("policy") == spec else None
        seeds = dict(before["seeds"]) if before else {}
        for seed, config in runs.items():
            if str(seed) not in seeds:
                try:
                    seeds[str(seed)] = evaluate_reference(spec, config)
                except ValueError as error:  # the policy does not fit the task: nothing of it is written
                    raise ReferencePolicyError(f"{experiment.name}: {error}") from None
                evaluated.append(f"{name} seed {seed}")
        policies[name] = {"policy": dict(spec), "seeds": dict(sorted(seeds.items(), key=lambda item: int(item[0])))}
    if evaluated or held != policies:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_json_atomic(path, with_version({"experiment": experiment.name, "protocol": protocol, "policies": policies}))
    if log is not None:
        done = f"evaluated {len(evaluated)} ({', '.join(evaluated)}) in {time.perf_counter() - started:.0f} s"
        log(f"{experiment.name}: reference policies {', '.join(policies)}: " + (done if evaluated else "held already"))
    return path
