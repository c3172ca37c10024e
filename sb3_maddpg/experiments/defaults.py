"""The names and numbers every setting starts from: the paper's task, episode length, schemes and algorithm, and how
simple_spread is stepped (one module that imports nothing, so that configs, descriptions and tasks share them)."""

EPISODE_LENGTH = 25
"""Steps per simple_spread episode in the paper (``max_cycles``)."""

SCHEMES = ("full", "independent", "observations", "actions", "selected")
"""The five information-sharing schemes, in the paper's Table 2 column order."""

DEFAULT_ALGORITHM = "sb3_maddpg:MADDPG"
"""The algorithm every run trains, as ``"module:Class"``."""

ALGORITHMS = {"maddpg": DEFAULT_ALGORITHM, "matd3": "sb3_maddpg:MATD3"}
"""The package's algorithms by short name: a setting's ``algorithm`` may be given so (it stores ``"module:Class"``)."""


VEC_ENVS = ("batched", "mpe2")
"""How a run steps simple_spread: ``"batched"`` (:class:`~sb3_maddpg.envs.SimpleSpreadVecEnv`, the same MDP as
mpe2, arrays) or ``"mpe2"`` (``DummyVecEnv`` over the adapter and mpe2 itself)."""

DEFAULT_N_ENVS = 100
"""Worlds stepped together: with the paper's one update per 100 transitions, one update per vectorised step."""


DEFAULT_ENV = "simple_spread"
"""The paper's task."""

DEFAULT_RESULTS = "runs/experiments"
"""Where ``sb3-maddpg run`` writes a sweep and ``report`` reads one, unless told."""

LEFT_OUT_SHOWN = 10
"""``report --complete-seeds`` names this many of the finished runs it leaves out (and counts them all)."""
