"""Where agents' positions are, as the env declares them: a Dict key wherever gymnasium's flattening puts it, or the
env's state through its infos; selection by distance reads them there and nowhere else (issue 46)."""

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from sb3_maddpg import MADDPG
from sb3_maddpg.common.selection import NearestAgents
from sb3_maddpg.envs import MPE_TASK_METRICS, MPE_TASKS, PettingZooToGym, make_mpe_env, make_simple_spread
from tests.envs.walkers import Walkers
from tests.settings import FILLS_THE_BUFFER_ONLY


def nearest(positions: np.ndarray, k: int) -> np.ndarray:
    """Each agent's k nearest others by hand: ``positions`` ``[batch, n, d]`` -> ``[batch, n, k]``."""
    out = []
    for row in positions:
        distances = np.linalg.norm(row[:, None] - row[None], axis=-1)
        np.fill_diagonal(distances, np.inf)
        out.append(np.argsort(distances, axis=1, kind="stable")[:, :k])
    return np.array(out)


@pytest.mark.parametrize("observe", ["dict", "nested", "noise"])
def test_walkers_is_a_real_parallel_env(observe: str) -> None:
    parallel_api_test(Walkers(observe=observe), num_cycles=20)


@pytest.mark.parametrize(("observe", "key", "where"), [("dict", "pos", slice(3, 5)), ("nested", ("self", "pos"), slice(3, 5))])
def test_a_dict_key_is_found_wherever_gymnasiums_flattening_puts_it(observe: str, key: str | tuple, where: slice) -> None:
    """Flattening sorts the keys (landmarks, pos, vel): MPE's 2:4 would read a landmark and the velocity."""
    walkers = Walkers(observe=observe)
    env = PettingZooToGym(walkers, positions=key)
    assert env.agent_layout.position_slices == (where,) * 4
    obs, _ = env.reset(seed=3)
    layout = env.agent_layout
    np.testing.assert_array_equal(layout.positions(obs[None])[0], walkers.positions())
    selection = NearestAgents(k=2).select(obs[None], layout)
    assert selection.tolist() == nearest(walkers.positions()[None], 2).tolist()


def test_positions_from_the_envs_state_select_in_the_buffer_for_the_stored_and_the_next_step() -> None:
    walkers = Walkers(observe="noise", max_cycles=5)
    env = PettingZooToGym(walkers, positions=lambda parallel_env: parallel_env.positions())
    assert env.agent_layout.positions_in_info and env.agent_layout.position_slices is None
    _, info = env.reset(seed=0)
    before = walkers.positions()
    np.testing.assert_array_equal(info["agent_positions"], before)
    for _ in range(5):
        *_, info = env.step(np.full(8, 0.5, np.float32))
        np.testing.assert_array_equal(info["agent_positions_before"], before)
        before = walkers.positions()
        np.testing.assert_array_equal(info["agent_positions"], before)

    model = MADDPG(
        "MlpPolicy",
        PettingZooToGym(Walkers(observe="noise", max_cycles=5), positions=lambda e: e.positions()),
        critic_sharing="selected",
        selector=NearestAgents(k=2, target="next"),
        learning_starts=20,
        batch_size=8,
        transitions_per_update=10,
        buffer_size=200,
        seed=0,
        policy_kwargs={"net_arch": [8, 8]},
    )
    recorded: list[tuple[np.ndarray, np.ndarray]] = []
    add = model.replay_buffer.add

    def spy(obs, next_obs, action, reward, done, infos):  # type: ignore[no-untyped-def]
        recorded.append((infos[0]["agent_positions_before"], infos[0]["agent_positions"]))
        add(obs, next_obs, action, reward, done, infos)

    model.replay_buffer.add = spy  # type: ignore[method-assign]
    model.learn(total_timesteps=100)
    buffer, n = model.replay_buffer, len(recorded)
    assert buffer.next_selections is not None and n == buffer.pos == 100
    before = np.stack([row[0] for row in recorded])
    after = np.stack([row[1] for row in recorded])
    assert (nearest(after, 2) != nearest(before, 2)).any()  # agents moved: the next step's nearest differ somewhere
    np.testing.assert_array_equal(buffer.selections[:n, 0], nearest(before, 2))
    np.testing.assert_array_equal(buffer.next_selections[:n, 0], nearest(after, 2))
    batch = buffer.sample(16)
    assert batch.next_selections is not None and batch.selections is not None
    assert model._n_updates > 0


def test_an_env_with_positions_nowhere_refuses_selection_by_distance_but_not_other_rules() -> None:
    env = PettingZooToGym(Walkers(observe="noise"))
    with pytest.raises(ValueError, match=r"^NearestAgents selects by distance, but this env does not say where"):
        MADDPG("MlpPolicy", env, critic_sharing="selected", selector=2)
    MADDPG("MlpPolicy", env, critic_sharing="full")  # nothing else needs positions


@pytest.mark.parametrize(
    ("positions", "error", "message"),
    [
        ("pos", ValueError, r"positions='pos' names a Dict observation key, but agent 'walker_0'.*is a Box: give a slice"),
        (("self", "place"), None, None),  # checked on a Dict below
        (3, TypeError, r"positions=3 is not a position source: give a slice"),
        ({"walker_0": slice(0, 2)}, ValueError, r"positions maps agents \['walker_0'\], but the env's agents are"),
        (slice(3, 6), ValueError, r"Agent 0's position slice slice\(3, 6, None\) does not fit its observation of size 4"),
    ],
)
def test_a_position_source_that_does_not_fit_is_refused_naming_the_fix(positions, error, message) -> None:  # type: ignore[no-untyped-def]
    if error is None:
        with pytest.raises(
            ValueError, match=r"agent 'walker_0''s Dict observation has no key 'place' \(its keys: \['pos', 'vel'\]\)"
        ):
            PettingZooToGym(Walkers(observe="nested"), positions=positions)
        return
    with pytest.raises(error, match=message):
        PettingZooToGym(Walkers(observe="noise"), positions=positions)


@pytest.mark.parametrize("task", sorted(MPE_TASKS))
def test_every_mpe_task_declares_its_positions_and_metrics(task: str) -> None:
    env = make_mpe_env(task)
    layout = env.agent_layout
    assert layout.declares_positions and env.task_metrics == MPE_TASK_METRICS[task]
    _, info = env.reset(seed=0)
    if layout.positions_in_info:  # every task but simple_spread: the world's positions, whatever the agents observe
        world = {agent.name: agent.state.p_pos for agent in env.parallel_env.unwrapped.world.agents}
        np.testing.assert_allclose(info["agent_positions"], [world[a] for a in layout.agent_ids], rtol=1e-6)


def test_the_mpe_tasks_declare_their_positions() -> None:
    env = make_simple_spread(n_agents=3)
    assert env.agent_layout.position_slices == (slice(2, 4),) * 3
    obs, _ = env.reset(seed=0)
    world = [agent.state.p_pos for agent in env.parallel_env.unwrapped.world.agents]
    np.testing.assert_allclose(env.agent_layout.positions(obs[None])[0], world, rtol=1e-6)


@FILLS_THE_BUFFER_ONLY
def test_a_replay_buffer_without_the_next_selections_a_model_needs_is_refused(tmp_path) -> None:  # type: ignore[no-untyped-def]
    def build(target: str) -> MADDPG:
        env = PettingZooToGym(Walkers(observe="noise", max_cycles=5), positions=lambda e: e.positions())
        selector = NearestAgents(k=1, target=target)  # type: ignore[arg-type]
        return MADDPG(
            "MlpPolicy",
            env,
            critic_sharing="selected",
            selector=selector,
            learning_starts=50,
            buffer_size=100,
            seed=0,
            policy_kwargs={"net_arch": [8]},
        )

    stored, following = build("stored"), build("next")
    stored.learn(20)
    stored.save_replay_buffer(tmp_path / "stored")
    with pytest.raises(ValueError, match=r"^The replay buffer holds no next-step selections"):
        following.load_replay_buffer(tmp_path / "stored")
    assert following.replay_buffer.next_selections is not None  # the refused buffer did not stay
    following.learn(20)
    following.save_replay_buffer(tmp_path / "next")
    stored.load_replay_buffer(tmp_path / "next")  # more than it needs: its own rule at sampling
    assert stored.replay_buffer.next_selections is None and stored.replay_buffer.sample(4).next_selections is None


def test_a_cli_factory_may_return_the_adapter_with_its_positions_declared() -> None:
    from sb3_maddpg.envs.task_by_name import task_env_factory

    declared = task_env_factory("tests.envs.walkers:walkers_with_positions", {"max_cycles": 5}, 25)()
    assert isinstance(declared, PettingZooToGym) and declared.agent_layout.positions_in_info
    plain = task_env_factory("tests.envs.walkers:Walkers", {"observe": "noise"}, 25)()
    assert isinstance(plain, PettingZooToGym) and not plain.agent_layout.declares_positions
    model = MADDPG("MlpPolicy", declared, critic_sharing="selected", selector=1, policy_kwargs={"net_arch": [4]})
    assert model.agent_layout is not None and model.agent_layout.positions_in_info
