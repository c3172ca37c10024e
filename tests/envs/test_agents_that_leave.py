"""Agents that leave mid-episode, on a real PettingZoo env (Knights-Archers-Zombies): the team stays fixed, episodes end
as the env ends them, and the replay buffer bootstraps exactly where the env was truncated (issue 46)."""

from typing import Any

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.env_checker import check_env

from sb3_maddpg import MADDPG
from sb3_maddpg.common.buffers import MultiAgentReplayBuffer
from sb3_maddpg.envs import PettingZooToGym
from tests.settings import FILLS_THE_BUFFER_ONLY

kaz = pytest.importorskip("pettingzoo.butterfly.knights_archers_zombies_v11")

# Seed 0 with these settings and the action stream below: archer_1 is killed at step 111, knight_1 at 119, the other
# two at 139 (asserted below, so a change in the env shows as a failed precondition, not a silent pass).
KAZ = {"spawn_delay": 2, "max_zombies": 20}


def play(max_cycles: int, seed: int = 0) -> tuple[Any, PettingZooToGym, list[tuple], list[list[str]]]:
    """One seeded episode of random actions through the adapter; also the agents the env itself had after each step."""
    parallel_env = kaz.parallel_env(max_cycles=max_cycles, **KAZ)
    env = PettingZooToGym(parallel_env)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    layout = env.agent_layout
    steps, present = [], []
    done = False
    while not done:
        action = np.zeros(layout.action_dim, np.float32)
        for part in layout.action_slices:
            action[part.start + int(rng.integers(6))] = 1.0  # a one-hot per agent: its discrete action
        steps.append(env.step(action))
        present.append(list(parallel_env.agents))
        done = steps[-1][2] or steps[-1][3]
    return parallel_env, env, steps, present


def test_kaz_agents_leave_and_the_episode_ends_by_termination_without_an_extra_step() -> None:
    _, env, steps, present = play(max_cycles=200)
    ids = env.agent_layout.agent_ids
    assert len(steps) == 139  # the env's own episode: no step added after its last
    archer_1 = ids.index("archer_1")
    assert "archer_1" in present[109] and "archer_1" not in present[110]  # precondition: it left at step 111
    for t, (obs, _, terminated, truncated, info) in enumerate(steps, start=1):
        gone_before = [i for i, agent in enumerate(ids) if t >= 2 and agent not in present[t - 2]]
        for i in gone_before:  # an agent that left: zeros, no reward, terminated in every later transition
            assert not obs[env.agent_layout.obs_slices[i]].any()
            assert info["agent_rewards"][i] == 0 and info["agent_terminations"][i]
        assert (terminated, truncated) == ((True, False) if t == 139 else (False, False))
    assert steps[110][4]["agent_terminations"][archer_1] and not steps[109][4]["agent_terminations"][archer_1]
    assert steps[-1][4]["agent_terminations"].all()


def test_kaz_time_limit_after_a_departure_is_truncation_and_the_buffer_bootstraps_the_agents_still_there() -> None:
    _, env, steps, present = play(max_cycles=115)
    ids = env.agent_layout.agent_ids
    assert len(steps) == 115 and set(present[112]) == set(ids) - {"archer_1"}  # archer_1 left at 111, the rest stayed
    obs, _, terminated, truncated, info = steps[-1]
    assert (terminated, truncated) == (False, True)  # the env's time limit, reported as such
    assert info["agent_terminations"].tolist() == [agent == "archer_1" for agent in ids]
    assert info["agent_truncations"].tolist() == [agent != "archer_1" for agent in ids]
    # What SB3's VecEnv hands the buffer at that step: a time-limit truncation.
    buffer = MultiAgentReplayBuffer(4, env.observation_space, env.action_space, layout=env.agent_layout)
    sb3_info = {**info, "TimeLimit.truncated": True}
    buffer.add(obs[None], obs[None], np.zeros((1, env.agent_layout.action_dim)), np.zeros(1), np.ones(1), [sb3_info])
    assert buffer.dones[0, 0].tolist() == [float(agent == "archer_1") for agent in ids]  # only the departed one stops


def test_maddpg_trains_on_kaz_through_departures() -> None:
    env = PettingZooToGym(kaz.parallel_env(max_cycles=120, **KAZ))
    check_env(env, skip_render_check=True)
    model = MADDPG(
        "MlpPolicy",
        env,
        learning_starts=150,
        batch_size=16,
        buffer_size=1_000,
        transitions_per_update=25,
        seed=0,
        policy_kwargs={"net_arch": [8, 8]},
    )
    model.learn(total_timesteps=300)
    assert model._n_updates > 0
    rows = model.replay_buffer.dones[: model.replay_buffer.pos, 0]
    assert rows.any(axis=1).any()  # some agent left within the 300 steps (seed 0), and training went on


@FILLS_THE_BUFFER_ONLY
def test_an_agent_truncated_alone_bootstraps_and_its_later_rows_train_nothing() -> None:
    """A lone truncation mid-episode (a real ParallelEnv): the row where the agent leaves bootstraps; the rows after it
    are marked inactive for that agent, and the losses average each agent's terms over its active rows only."""
    from sb3_maddpg.common.losses import actor_loss_terms, critic_losses
    from tests.envs.walkers import Walkers

    env = PettingZooToGym(Walkers(n_agents=3, observe="noise", max_cycles=6, leaves={"walker_1": (2, "truncation")}))
    env.reset(seed=0)
    steps = [env.step(np.zeros(6, np.float32)) for _ in range(6)]
    assert [info["agent_active"].tolist() for *_, info in steps] == [[True] * 3] * 2 + [[True, False, True]] * 4
    assert [bool(info["agent_truncations"][1]) for *_, info in steps] == [False, True, False, False, False, False]
    assert not any(info["agent_terminations"].any() for *_, info in steps)  # nobody terminated: nothing stops a bootstrap
    assert (steps[-1][2], steps[-1][3]) == (False, True)  # the time limit, a truncation
    assert all(info["agent_rewards"][1] == 0 for *_, info in steps[2:])

    model = MADDPG(
        "MlpPolicy",
        PettingZooToGym(Walkers(n_agents=3, observe="noise", max_cycles=6, leaves={"walker_1": (2, "truncation")})),
        learning_starts=30,
        batch_size=16,
        buffer_size=200,
        seed=0,
        policy_kwargs={"net_arch": [8, 8]},
    )
    model.learn(60)
    buffer = model.replay_buffer
    assert buffer.active is not None
    assert buffer.active[:60, 0, 1].tolist() == ([True] * 2 + [False] * 4) * 10  # per episode: 2 rows active, 4 after
    batch = buffer.sample(64)
    assert batch.active is not None and batch.active[:, [0, 2]].eq(1).all() and (batch.active[:, 1] == 0).any()
    targets = model._critic_targets(batch)
    losses = critic_losses(model.critic, batch, targets)
    with th.no_grad():
        errors = (model.critic(batch.observations, batch.actions, batch.selections) - targets).pow(2)
    by_hand = (errors * batch.active).sum(0) / batch.active.sum(0)
    th.testing.assert_close(losses, by_hand)
    # Rows after the departure reach nothing of agent 1's critic or actor.
    after = batch._replace(active=batch.active * (batch.active[:, 1:2] == 0))  # only the rows where agent 1 is gone
    loss = critic_losses(model.critic, after, targets)[1]
    assert loss == 0 and th.autograd.grad(loss, list(model.critic.parameters()), allow_unused=True)
    terms = actor_loss_terms(model.actor.forward_with_preactivation, model.critic, after, model._action_parts, 1e-3)
    assert terms.total[1] == 0
