"""What a setting derives from its values: each run's evaluation seed, and the setting's description."""

import re
from typing import Any

import numpy as np
import pytest

from sb3_maddpg.analysis.evaluation import evaluate_team
from sb3_maddpg.experiments import EXP1, SMOKE, RunConfig
from sb3_maddpg.experiments.config import EXPERIMENTS, setting_label
from sb3_maddpg.experiments.setting import ExperimentConfig, describe_setting, scaled_schedule
from sb3_maddpg.experiments.tasks import run_task


class StandingTeam:
    """A 'model' whose agents never act (a zero joint action: no force, or MPE's no-op): an episode's scores then
    depend on its initial state alone."""

    def __init__(self, action_dim: int) -> None:
        self.action_dim = action_dim

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None, deterministic: bool = False) -> tuple:
        return np.zeros((np.asarray(observation).shape[0], self.action_dim), np.float32), None


def standing_team_score(run: RunConfig) -> float:
    """:return: The summed minimum distances, at the last step, of a team that stands still, evaluated as ``run``'s
    checkpoints are (its eval env and its evaluation seed)."""
    env = run_task(run).make_eval_env(run.eval_episodes)
    team = StandingTeam(env.action_space.shape[0])  # type: ignore[index]
    result = evaluate_team(team, env, n_episodes=run.eval_episodes, seed=run.eval_seed)
    return float(result["min_dist_sum"])


def test_runs_of_different_seeds_are_evaluated_on_episodes_of_their_own() -> None:
    """Each seed's runs are evaluated on episodes drawn from a seed of their own (so that seeds are independent
    samples), and every scheme of one seed on the same ones (so that schemes are compared on the same episodes)."""
    runs = list(SMOKE.replace(seeds=(0, 1, 2)).runs())
    # By hand: 1,000,003 + 7,919 x seed.
    assert {run.seed: run.eval_seed for run in runs} == {0: 1_000_003, 1: 1_007_922, 2: 1_015_841}
    scores: dict[int, set[float]] = {}
    for run in runs:
        scores.setdefault(run.seed, set()).add(standing_team_score(run))
    assert all(len(by_scheme) == 1 for by_scheme in scores.values())  # the same episodes for every scheme of a seed
    assert len({by_scheme.pop() for by_scheme in scores.values()}) == 3  # other episodes for each seed


def test_no_two_runs_evaluate_in_the_same_world_seed_and_none_where_training_does() -> None:
    """An evaluation seeds world ``i`` of its env with ``eval_seed + i`` (SB3's ``VecEnv.seed``), training world ``i``
    with ``seed + i``: over the paper's 31 seeds the evaluations' worlds and the training worlds never share a seed."""
    runs = [run for run in EXP1.runs() if run.scheme == "full"]
    assert len(runs) == 31
    worlds = max(EXP1.eval_episodes, EXP1.curve_eval_episodes)  # the batched eval env: one world per episode
    evaluation = [set(range(run.eval_seed, run.eval_seed + worlds)) for run in runs]
    training = set().union(*(range(run.seed, run.seed + run.n_envs) for run in runs))
    assert sum(map(len, evaluation)) == len(set().union(*evaluation))  # pairwise disjoint
    assert not training & set().union(*evaluation)


@pytest.mark.parametrize(
    "neighbors, described, labelled",
    [
        (None, "full observability", "full obs."),
        (3, "3 nearest agents observed", "3 nearest obs."),  # N - 2: one agent unseen
        (4, "full observability nearest first", "full obs. nearest first"),  # N - 1: every other agent, by distance
    ],
)
def test_observing_every_other_agent_is_described_as_full_observability_nearest_first(
    neighbors: int | None, described: str, labelled: str
) -> None:
    """At N=5, observing the 4 nearest agents is observing them all (in order of distance): the description and the
    report's label say so, and say "3 nearest" one below it."""
    setting = EXP1.replace(num_agent_neighbors=neighbors)
    assert re.search(rf"N=5, {described}, 100,000 episodes", describe_setting(setting))
    assert setting_label("exp1", setting.to_dict()) == f"exp1 (N=5, {labelled}, 100,000 ep.)"


def test_a_team_of_one_agent_is_a_setting_and_of_none_is_refused() -> None:
    """The least team is one agent, observing none of the others (0 neighbours); below either is refused."""
    alone = SMOKE.replace(n_agents=1, num_agent_neighbors=0, schemes=("full",))
    assert (alone.n_agents, alone.num_agent_neighbors) == (1, 0)
    for name, refused in (("n_agents", 0), ("num_agent_neighbors", -1)):
        with pytest.raises(ValueError, match=name):  # the refusal names the argument
            SMOKE.replace(schemes=("full",), **{name: refused})


def test_a_setting_without_a_learning_curve_says_so_and_evaluates_none() -> None:
    """``curve_points=0`` is a setting (no learning curve: no curve evaluation during training); below 0 is refused."""
    plain = SMOKE.replace(curve_points=0)
    assert describe_setting(plain).endswith(", no learning curve")
    assert all(run.curve_interval == 0 for run in plain.runs())
    with pytest.raises(ValueError, match="curve_points"):
        SMOKE.replace(curve_points=-1)


def test_a_budget_too_small_for_any_evaluation_count_gets_each_counts_floor() -> None:
    """At 100 of Experiment 1's 100,000 episodes the square-root scaling (x 0.0316) gives 1 checkpoint, 4 episodes,
    2 curve points and 1 curve episode: each is raised to its floor (1, 10, 2, 5)."""
    assert scaled_schedule(EXP1, 100) == {"n_checkpoints": 1, "eval_episodes": 10, "curve_points": 2, "curve_eval_episodes": 5}


@pytest.mark.parametrize(
    ("seeds", "refusal"),
    [
        ([0, -1], r"^seeds \(.*\) must be an integer in \[0, 4,294,967,295\], got -1: use a non-negative integer"),
        ([0, None], r"^seeds \(.*\) must be an integer .*, got None"),
        ([1.5], r"^seeds \(.*\) must be an integer .*, got 1\.5"),
        ([True], r"^seeds \(.*\) must be an integer .*, got True"),
        ([0, 3, 0], r"^seeds holds \[0\] more than once"),
    ],
)
def test_an_experiment_s_seeds_are_refused_by_name(seeds: list[Any], refusal: str) -> None:
    """Seeds no run can take (or two runs in one directory) are refused when the experiment is read, not at its runs."""
    fields = {**EXPERIMENTS["smoke"].to_dict(), "seeds": seeds}
    with pytest.raises(ValueError, match=refusal):
        ExperimentConfig.from_fields(fields)
    assert ExperimentConfig.from_fields({**fields, "seeds": [0, 4_294_967_295]}).seeds == (0, 4_294_967_295)
