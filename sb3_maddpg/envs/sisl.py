"""PettingZoo's SISL pursuit and multiwalker as tasks of the experiments: the adapter with the agents' positions (for
selection by distance) and a task metric each, the evaders caught and the distance the walkers carried the package.

Run them as an experiment's task, ``env: "sb3_maddpg.envs.sisl:pursuit_env"`` (the preset ``pursuit``) or
``"sb3_maddpg.envs.sisl:multiwalker_env"`` (the preset ``multiwalker``), or build them directly::

    from sb3_maddpg.envs.sisl import multiwalker_env, pursuit_env
    env = pursuit_env(x_size=8, y_size=8, n_pursuers=4, n_evaders=4, max_cycles=100, surround=False, n_catch=2)
    walkers = multiwalker_env(n_walkers=3, max_cycles=500)

``pettingzoo.sisl`` (and pygame, which it imports) is imported when an env is built, not with this module, so that
``import sb3_maddpg`` does not need the ``sisl`` extra.
"""

from typing import Any

import numpy as np
from pettingzoo.utils.wrappers import BaseParallelWrapper

from sb3_maddpg.envs.adapter import PettingZooToGym
from sb3_maddpg.envs.task_metric import TaskMetric

EVADERS_CAUGHT = TaskMetric(
    "evaders_caught",
    "last",
    "higher",
    "team",
    "evaders caught in the episode (removed from the grid: n_catch pursuers on an evader's cell, or surrounding it)",
)
"""Pursuit's task metric: the evaders the team caught by the episode's last step."""

PURSUIT_TASK_METRICS = (EVADERS_CAUGHT,)
"""The task metrics :func:`pursuit_env` declares."""

PACKAGE_DISTANCE = TaskMetric(
    "package_distance",
    "last",
    "higher",
    "team",
    "how far the walkers carried the package from its start by the episode's end (Box2D world units; a fall ends it)",
)
"""Multiwalker's task metric: the package's forward distance from where it started."""

MULTIWALKER_TASK_METRICS = (PACKAGE_DISTANCE,)
"""The task metrics :func:`multiwalker_env` declares."""

PURSUIT_NO_OP = 4
"""Pursuit's action that leaves a pursuer where it is (its moves: 0-3 the four directions, 4 stay)."""


GONE = (-1e6, -1e6)
"""Where :func:`walker_positions` places a walker without a body: farther from every walker than the terrain is long."""


def sisl_state(parallel_env: Any) -> Any:
    """
    :param parallel_env: A SISL ``parallel_env`` (or a wrapper of it).
    :return: The env's state, which the AEC env keeps as ``env``: pursuit's ``Pursuit``, multiwalker's
        ``MultiWalkerEnv``.
    """
    return parallel_env.unwrapped.env


def walker_positions(parallel_env: Any) -> np.ndarray:
    """
    :param parallel_env: Multiwalker's ``parallel_env``.
    :return: Each walker's hull position ``(x, y)``, ``[n_walkers, 2]`` in ``possible_agents`` order; a walker whose
        body is gone (it fell, with ``remove_on_fall``, multiwalker's default) at :data:`GONE`, where no one selects it
        as near. (With ``remove_on_fall=False`` a fallen walker keeps its place and can still be selected.)
    """
    walkers = sisl_state(parallel_env).walkers  # new bodies at every reset: read them at every call
    return np.array([GONE if walker.hull is None else tuple(walker.hull.position) for walker in walkers], dtype=np.float32)


def package_distance(parallel_env: Any) -> dict[str, float]:
    """
    :param parallel_env: Multiwalker's ``parallel_env``.
    :return: ``{"package_distance": d}``: the package's x now less its x at the start (the walkers' middle start).
    """
    state = sisl_state(parallel_env)
    return {PACKAGE_DISTANCE.key: float(state.package.position.x - np.mean(state.start_x))}


def pursuer_positions(parallel_env: Any) -> np.ndarray:
    """
    :param parallel_env: Pursuit's ``parallel_env``.
    :return: Each pursuer's grid cell ``(x, y)``, ``[n_pursuers, 2]`` in ``possible_agents`` order (``pursuer_i`` is
        the pursuer layer's agent ``i``; pursuit never removes a pursuer).
    """
    layer = sisl_state(parallel_env).pursuer_layer  # a new layer at every reset: read it at every call
    return np.array([layer.get_position(i) for i in range(layer.n_agents())], dtype=np.float32)


def evaders_caught(parallel_env: Any) -> dict[str, float]:
    """
    :param parallel_env: Pursuit's ``parallel_env``.
    :return: ``{"evaders_caught": n}``: the evaders caught so far in the episode (pursuit's ``evaders_gone`` flags, set
        when it removes an evader from the grid).
    """
    return {EVADERS_CAUGHT.key: float(np.count_nonzero(sisl_state(parallel_env).evaders_gone))}


def episode_seed(first_seed: int, episode: int) -> int:
    """
    :param first_seed: The seed of an env's last seeded reset.
    :param episode: Episodes since then (0: that reset's).
    :return: The seed of that episode: the first seed itself for episode 0, else a draw of ``numpy``'s
        ``SeedSequence([first_seed, episode])`` (distinct across envs seeded ``s, s + 1, ...``, unlike ``s + episode``).
    """
    if episode == 0:
        return first_seed
    return int(np.random.SeedSequence([first_seed, episode]).generate_state(1)[0])


class EachEpisodeSeeded(BaseParallelWrapper):
    """
    A ParallelEnv whose every episode starts from a seed of its own: after a reset with a seed, each reset without one
    resets with :func:`episode_seed` of that seed and the episode's index.

    Why: pursuit's evaders move at random from the env's generator at every step, as many draws as evaders are left,
    so with one generator for all episodes the k-th episode's start depends on what the team caught before. Seeded
    per episode, the k-th evaluation episode after a seed starts the same for every team (a trained one, random
    actions, doing nothing) and the same generator moves its evaders until the teams' catches differ.

    :param env: The PettingZoo ParallelEnv.
    """

    def __init__(self, env: Any) -> None:
        super().__init__(env)
        self._first_seed: int | None = None
        self._episode = 0

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        """
        :param seed: A seed (starts the count of episodes), or ``None``: the next episode's seed, if one was given.
        :param options: Passed on.
        :return: The env's reset.
        """
        if seed is not None:
            self._first_seed, self._episode = int(seed), 0
        elif self._first_seed is not None:
            self._episode += 1
            seed = episode_seed(self._first_seed, self._episode)
        return self.env.reset(seed=seed, options=options)


def pursuit_parallel_env(**kwargs: Any) -> Any:
    """
    :param kwargs: ``pursuit``'s keyword arguments (``x_size``, ``n_pursuers``, ``n_catch``, ``surround``, ...).
    :return: PettingZoo's ``pursuit_v5.parallel_env`` (``pursuit_v4`` on PettingZoo before 1.27, the same arguments).
    """
    try:
        from pettingzoo.sisl import pursuit_v5 as pursuit
    except ImportError as error:
        try:
            from pettingzoo.sisl import pursuit_v4 as pursuit  # type: ignore[no-redef]  # PettingZoo 1.25 and 1.26
        except ImportError:
            from sb3_maddpg.common.install_hint import extra_install_command

            raise ImportError(
                f"pursuit cannot be imported ({error}): it needs PettingZoo's SISL envs and pygame; install the sisl "
                f"extra, {extra_install_command('sisl')}."
            ) from error
    return pursuit.parallel_env(**kwargs)


def pursuit_env(seed_each_episode: bool = True, **kwargs: Any) -> PettingZooToGym:
    """
    PettingZoo's SISL pursuit as one gymnasium env: the team reward is the sum of the pursuers' rewards, each pursuer's
    ``Discrete(5)`` move a one-hot slot of the joint action (:class:`~sb3_maddpg.envs.PettingZooToGym`).

    It declares the pursuers' grid positions, read from the env's state at every reset and step (``positions``, for
    :class:`~sb3_maddpg.common.selection.NearestAgents` and the ``selected`` scheme), and the evaders caught per
    episode (:data:`EVADERS_CAUGHT`, higher is better), scored by
    :func:`~sb3_maddpg.analysis.evaluation.evaluate_team` and reported by the experiments.

    :param seed_each_episode: Start every episode after a seeded reset from a seed of its own
        (:class:`EachEpisodeSeeded`), so that evaluations of different teams on one seed see the same episodes.
        ``False``: one generator for all episodes, as pursuit itself does.
    :param kwargs: ``pursuit``'s keyword arguments, e.g. the Beyond MPE setting: ``x_size=8, y_size=8, n_pursuers=4,
        n_evaders=4, max_cycles=100, surround=False, n_catch=2``.
    :return: The env.
    """
    parallel_env = pursuit_parallel_env(**kwargs)
    if seed_each_episode:
        parallel_env = EachEpisodeSeeded(parallel_env)
    return PettingZooToGym(
        parallel_env, metrics_fn=evaders_caught, positions=pursuer_positions, task_metrics=PURSUIT_TASK_METRICS
    )


class TimeLimitTruncates(BaseParallelWrapper):
    """
    Multiwalker's time limit as a truncation. PettingZoo's multiwalker marks every walker *terminated* when the episode
    reaches ``max_cycles`` (its own env says done only for a fall, the package dropped or the terrain's end), so a
    learner would take the time limit for the task's end and never bootstrap there; this wrapper moves those
    terminations to truncations, and keeps the env's own endings as they are.

    :param env: Multiwalker's ``parallel_env``.
    """

    def step(self, actions: dict[str, Any]) -> Any:
        """:return: The env's step, a walker terminated by the time limit alone truncated instead."""
        observations, rewards, terminations, truncations, infos = self.env.step(actions)
        state = sisl_state(self.env)
        if state.frames >= state.max_cycles:
            for agent, terminated in terminations.items():
                if terminated and not state.last_dones[self.possible_agents.index(agent)]:
                    terminations[agent], truncations[agent] = False, True
        return observations, rewards, terminations, truncations, infos


def multiwalker_env(seed_each_episode: bool = True, **kwargs: Any) -> PettingZooToGym:
    """
    PettingZoo's SISL multiwalker as one gymnasium env: bipedal walkers carry a package together; the team reward is
    the sum of the walkers' rewards, each walker's four joint torques in [-1, 1] a part of the joint action.

    It declares the walkers' positions (their hulls', for ``selected``) and the package's distance from its start
    (:data:`PACKAGE_DISTANCE`, higher is better), and ends an episode at ``max_cycles`` by truncation
    (:class:`TimeLimitTruncates`), not termination as PettingZoo's multiwalker does.

    :param seed_each_episode: As :func:`pursuit_env`'s: every episode after a seeded reset from a seed of its own.
    :param kwargs: ``multiwalker``'s keyword arguments, e.g. ``n_walkers=3, max_cycles=500``.
    :return: The env.
    """
    try:
        from pettingzoo.sisl import multiwalker_v9
    except ImportError as error:
        from sb3_maddpg.common.install_hint import extra_install_command

        raise ImportError(
            f"multiwalker cannot be imported ({error}): it needs PettingZoo's SISL envs and Box2D; install the sisl "
            f"extra, {extra_install_command('sisl')}."
        ) from error
    parallel_env = TimeLimitTruncates(multiwalker_v9.parallel_env(**kwargs))
    if seed_each_episode:
        parallel_env = EachEpisodeSeeded(parallel_env)
    return PettingZooToGym(
        parallel_env, metrics_fn=package_distance, positions=walker_positions, task_metrics=MULTIWALKER_TASK_METRICS
    )
