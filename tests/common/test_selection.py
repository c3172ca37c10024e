"""Who each agent selects: k nearest, fixed graph and roles, user callables, and their errors."""

import numpy as np
import pytest

from sb3_maddpg import MADDPG
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.common.selection import CallableSelector, FixedGraph, NearestAgents
from sb3_maddpg.envs import make_simple_spread

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
