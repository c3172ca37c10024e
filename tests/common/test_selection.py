"""Who each agent selects: k nearest, fixed graph and roles, user callables, and their errors."""

import warnings
from typing import Any

import numpy as np
import pytest

from sb3_maddpg import MADDPG
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.selection import (
    CallableSelector,
    FixedGraph,
    NearestAgents,
    Selector,
    resolve_selector,
    warn_if_selecting_everyone,
)
from sb3_maddpg.envs import SimpleSpreadVecEnv, make_simple_spread
from tests.settings import FILLS_THE_BUFFER_ONLY

# Positions as MPE lays them out, [vel(2), pos(2), ...], declared as the MPE tasks declare them.
LAYOUT = AgentLayout(("a", "b", "c", "d"), (6,) * 4, (2,) * 4, position_slices=(slice(2, 4),) * 4)


def observations_with_positions(positions: list[tuple[float, float]]) -> np.ndarray:
    """One joint observation where agent i's observation is [vel(2), pos(2), extra(2)] as in MPE."""
    obs = np.zeros((1, LAYOUT.obs_dim), dtype=np.float32)
    for i, position in enumerate(positions):
        obs[0, 6 * i + 2 : 6 * i + 4] = position
        obs[0, 6 * i + 4 : 6 * i + 6] = 100.0  # far-away numbers elsewhere must not matter
    return obs


def test_nearest_agents_by_hand() -> None:
    obs = observations_with_positions([(0, 0), (1, 0), (0, 3), (0.5, 0)])
    selection = NearestAgents(k=2).select(obs, LAYOUT)
    assert selection.dtype == np.int64 and selection.shape == (1, 4, 2)
    # From a: b 1, c 3, d 0.5 -> [d, b]; from b: a 1, c 3.16, d 0.5 -> [d, a];
    # from c: a 3, b 3.16, d 3.04 -> [a, d]; from d: a 0.5, b 0.5 (tie: lower index), c 3.04 -> [a, b].
    assert selection[0].tolist() == [[3, 1], [3, 0], [0, 3], [0, 1]]


def test_nearest_agents_never_selects_itself_and_breaks_ties_by_index() -> None:
    obs = observations_with_positions([(0, 0)] * 4)  # everyone at the same place
    assert NearestAgents(k=3).select(obs, LAYOUT)[0].tolist() == [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]


def test_nearest_agents_batched_and_custom_position_slice() -> None:
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(5, LAYOUT.obs_dim)).astype(np.float32)
    selection = NearestAgents(k=1, position_slice=slice(4, 6)).select(obs, LAYOUT)
    for row in range(5):
        positions = obs[row].reshape(4, 6)[:, 4:6]
        for i in range(4):
            distances = np.linalg.norm(positions - positions[i], axis=1)
            distances[i] = np.inf
            assert selection[row, i, 0] == np.argmin(distances)


def test_nearest_agents_errors() -> None:
    with pytest.raises(ValueError, match="k=4 other agents.*use k <= 3"):
        NearestAgents(k=4).validate(LAYOUT)
    with pytest.raises(ValueError, match="k >= 1"):
        NearestAgents(k=0)
    with pytest.raises(ValueError, match="position_slice.*does not fit"):
        NearestAgents(k=1, position_slice=slice(5, 8)).validate(LAYOUT)
    with pytest.raises(TypeError, match=r"position_slice must be a slice .*got \(2, 4\)"):
        NearestAgents(k=1, position_slice=(2, 4))  # type: ignore[arg-type]


def test_nearest_agents_on_an_env_without_declared_positions_is_refused_naming_how_to_give_them() -> None:
    """Issue 46: on a non-MPE env, obs[2:4] may be anything (waterworld's sensors): never read it unasked."""
    undeclared = AgentLayout(("a", "b", "c", "d"), (6,) * 4, (2,) * 4)
    with pytest.raises(
        ValueError,
        match=r"^NearestAgents selects by distance, but this env does not say where.*"
        r"PettingZooToGym\(parallel_env, positions=\.\.\.\).*NearestAgents\(position_slice=\.\.\.\)",
    ):
        NearestAgents(k=1).validate(undeclared)
    obs = observations_with_positions([(0, 0), (1, 0), (0, 3), (0.5, 0)])
    with pytest.raises(ValueError, match="no declared positions"):
        NearestAgents(k=1).select(obs, undeclared)
    # The user's slice needs no declaration, and a declaration elsewhere is read from there.
    assert NearestAgents(k=1, position_slice=slice(2, 4)).select(obs, undeclared)[0, :, 0].tolist() == [3, 3, 0, 0]
    moved = AgentLayout(("a", "b", "c", "d"), (6,) * 4, (2,) * 4, position_slices=(slice(4, 6),) * 4)
    assert NearestAgents(k=1).select(obs, moved)[0].tolist() == [[1], [0], [0], [0]]  # all at (100, 100): by index


def test_fixed_graph_and_roles() -> None:
    graph = FixedGraph([[1, 2], [0, 3], [3, 0], [2, 1]])
    graph.validate(LAYOUT)
    selection = graph.select(np.zeros((3, LAYOUT.obs_dim)), LAYOUT)
    assert selection.shape == (3, 4, 2)
    assert (selection == np.array([[1, 2], [0, 3], [3, 0], [2, 1]])).all()
    roles = FixedGraph.from_roles(["scout", "carrier", "scout", "carrier"])
    assert roles.neighbors.tolist() == [[2], [3], [0], [1]]


def test_fixed_graph_errors() -> None:
    with pytest.raises(ValueError, match="out of range"):
        FixedGraph([[1], [0], [3], [4]]).validate(LAYOUT)
    with pytest.raises(ValueError, match="select itself"):
        FixedGraph([[0], [0], [1], [2]]).validate(LAYOUT)
    with pytest.raises(ValueError, match="for 3 agents, the team has 4"):
        FixedGraph([[1], [0], [0]]).validate(LAYOUT)
    with pytest.raises(ValueError, match="same length"):
        FixedGraph([[1, 2], [0], [0], [0]])
    with pytest.raises(ValueError, match="same number"):
        FixedGraph.from_roles(["x", "x", "x", "y"])


def test_callable_selector_is_checked_on_every_call() -> None:
    def ring(observations: np.ndarray, layout: AgentLayout) -> np.ndarray:
        nxt = (np.arange(layout.n_agents) + 1) % layout.n_agents
        return np.broadcast_to(nxt[None, :, None], (observations.shape[0], layout.n_agents, 1))

    assert CallableSelector(ring, k=1).select(np.zeros((2, LAYOUT.obs_dim)), LAYOUT)[:, :, 0].tolist() == [[1, 2, 3, 0]] * 2
    with pytest.raises(ValueError, match="shape.*expected \\(2, 4, 2\\)"):
        CallableSelector(ring, k=2).select(np.zeros((2, LAYOUT.obs_dim)), LAYOUT)
    with pytest.raises(ValueError, match="index 7, out of range for 4 agents"):
        CallableSelector(lambda o, lay: np.full((o.shape[0], 4, 1), 7), k=1).select(np.zeros((1, LAYOUT.obs_dim)), LAYOUT)
    with pytest.raises(ValueError, match="select itself"):
        CallableSelector(lambda o, lay: np.arange(4).reshape(1, 4, 1), k=1).select(np.zeros((1, LAYOUT.obs_dim)), LAYOUT)
    with pytest.raises(TypeError, match="integer agent indices"):
        CallableSelector(lambda o, lay: np.full((1, 4, 1), 1.5), k=1).select(np.zeros((1, LAYOUT.obs_dim)), LAYOUT)
    with pytest.raises(TypeError, match="needs a callable"):
        CallableSelector(3, k=1)  # type: ignore[arg-type]


@FILLS_THE_BUFFER_ONLY
def test_the_stored_selection_is_made_from_the_observation_at_time_t() -> None:
    """Each buffer row holds the selection made from its o_t, not from o_{t+1} (the paper's Algorithm 3)."""
    model = MADDPG(
        "MlpPolicy",
        make_simple_spread(n_agents=4),
        critic_sharing="selected",
        selector=1,
        learning_starts=10_000,  # collect only
        buffer_size=1_000,
        policy_kwargs=dict(net_arch=[8]),
        seed=0,
    )
    model.learn(100)
    buffer, layout = model.replay_buffer, model.agent_layout
    from_obs = model.selector.select(buffer.observations[:100, 0], layout)
    from_next_obs = model.selector.select(buffer.next_observations[:100, 0], layout)
    # The agents move: the nearest agent changes between t and t + 1 in some rows (17 of 100 with seed 0), so
    # the check below can tell the two apart.
    assert (from_obs != from_next_obs).any(axis=(1, 2)).sum() >= 5
    np.testing.assert_array_equal(buffer.selections[:100, 0], from_obs)


def collected(env: Any, selector: Selector) -> MADDPG:
    """:return: A small ``selected`` model of ``env`` after 20 steps of collecting (no update: learning_starts ahead)."""
    model = MADDPG(
        "MlpPolicy",
        env,
        critic_sharing="selected",
        selector=selector,
        learning_starts=1_000,
        buffer_size=1_000,
        policy_kwargs=dict(net_arch=[8]),
        seed=0,
    )
    return model.learn(20)


def ring_of_three(observations: np.ndarray, layout: AgentLayout) -> np.ndarray:
    """Agent i selects agent i + 1 (mod 3), whatever it observes."""
    return np.broadcast_to(np.array([[1], [2], [0]]), (observations.shape[0], 3, 1))


@FILLS_THE_BUFFER_ONLY
@pytest.mark.parametrize(
    "selector", [FixedGraph([[1], [2], [0]]), CallableSelector(ring_of_three, k=1)], ids=["FixedGraph", "CallableSelector"]
)
def test_rules_that_need_no_positions_select_from_the_observations_on_an_env_that_reports_positions(
    selector: FixedGraph | CallableSelector,
) -> None:
    """An env that reports its agents' positions in its infos (``PettingZooToGym(positions=fn)``) serves a rule that
    does not select by position as any env does: the buffer asks it for the selection from the observations, and it
    stores no next-step selection (a rule that did need the positions would be handed them instead)."""
    from tests.envs.walkers import walkers_with_positions

    env = walkers_with_positions(n_agents=3, max_cycles=5)
    layout = env.agent_layout  # type: ignore[attr-defined]
    assert layout.positions_in_info
    assert not selector.needs_positions and not selector.stores_next_selection(layout)
    model = collected(env, selector)
    buffer = model.replay_buffer
    assert buffer.pos >= 20 and buffer.next_selections is None
    assert buffer.selections[: buffer.pos, 0, :, 0].tolist() == [[1, 2, 0]] * buffer.pos


def every_other(observations: np.ndarray, layout: AgentLayout) -> np.ndarray:
    """Agent i selects every other agent, in index order."""
    table = [[j for j in range(layout.n_agents) if j != i] for i in range(layout.n_agents)]
    return np.broadcast_to(np.array(table), (observations.shape[0], layout.n_agents, layout.n_agents - 1))


def test_k_may_be_every_other_agent_which_is_said_to_be_full_sharing_but_no_more() -> None:
    """On 4 agents any rule may select all 3 others (taken, with a warning: it is full sharing in another order);
    2 is a selection and nothing is said; 4 is refused."""
    for selector in (
        NearestAgents(k=3),
        FixedGraph(every_other(np.zeros((1, 1)), LAYOUT)[0]),
        CallableSelector(every_other, 3),
    ):
        selector.validate(LAYOUT)  # the boundary itself: no error
    with pytest.warns(UserWarning, match="with k=3 selects every other agent of this 4-agent team"):
        warn_if_selecting_everyone(NearestAgents(k=3), LAYOUT)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_if_selecting_everyone(NearestAgents(k=2), LAYOUT)
    with pytest.raises(ValueError, match="k=4 other agents.*use k <= 3"):
        CallableSelector(every_other, 4).validate(LAYOUT)


def test_the_default_selector_is_the_papers_two_nearest_agents() -> None:
    """No selector, a dict without k and NearestAgents() all select the paper's k = 2 nearest agents."""
    for default in (resolve_selector(None), resolve_selector({}), resolve_selector({"target": "next"}), NearestAgents()):
        assert isinstance(default, NearestAgents) and default.k == 2
    assert resolve_selector(3).k == 3 and resolve_selector({"k": 1}).k == 1


def test_a_fixed_graph_is_given_in_a_config_as_its_neighbors() -> None:
    """A JSON experiment names a fixed graph as ``{"neighbors": [...]}``: the same selector as ``FixedGraph``, and a
    run of it selects exactly those agents (issue 56's fixed-graph run)."""
    ring = [[4, 1], [0, 2], [1, 3], [2, 4], [3, 0]]
    selector = resolve_selector({"neighbors": ring})
    assert isinstance(selector, FixedGraph) and selector.k == 2 and selector.neighbors.tolist() == ring
    model = MADDPG(
        "MlpPolicy", SimpleSpreadVecEnv(n_envs=2, n_agents=5), critic_sharing="selected", selector={"neighbors": ring}
    )
    selections = model.selector.select(np.zeros((3, model.agent_layout.obs_dim), dtype=np.float32), model.agent_layout)
    assert selections.tolist() == [ring] * 3
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['k'\].*FixedGraph's 'neighbors'"):
        resolve_selector({"neighbors": ring, "k": 2})


@FILLS_THE_BUFFER_ONLY
@pytest.mark.parametrize("target", ["stored", "next"])
def test_only_a_next_target_by_positions_from_the_infos_stores_the_next_selection(target: str) -> None:
    """Positions the env reports in its infos cannot be read again at sampling: a ``target="next"`` rule by position
    stores the next step's selection with each row. A ``"stored"`` target uses each row's own selection and stores
    nothing more, and on an env whose positions are in its observations neither stores it (the next observation is
    at hand when sampling)."""
    from tests.envs.walkers import walkers_with_positions

    env = walkers_with_positions(n_agents=3, max_cycles=5)
    selector = NearestAgents(k=1, target=target)  # type: ignore[arg-type]
    assert selector.stores_next_selection(env.agent_layout) is (target == "next")  # type: ignore[attr-defined]
    assert not selector.stores_next_selection(LAYOUT)
    model = collected(env, selector)
    assert (model.replay_buffer.next_selections is not None) is (target == "next")
    assert (model.replay_buffer.sample(8).next_selections is not None) is (target == "next")
