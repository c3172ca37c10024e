"""
What a critic network shared by every agent reads (``share_parameters=True``): for each of the paper's five schemes,
critic i's input is what critic 0's input would be in the same world with agent i called agent 0 (the others keeping
their order). So one network reads the same thing, in the same places, for every agent: own agent first, then the
others in ascending index (which, relabelled so, is the same order for everyone), or the selected agents nearest
first. That is what makes one critic correct for a team of interchangeable agents, as simple_spread's are: its
observations (mpe2 itself, checked here) and rewards relabel with the agents. A team whose critics read different
schemes cannot share one network, and is refused.
"""

import numpy as np
import pytest
import torch as th
from mpe2 import simple_spread_v3

from sb3_maddpg import MADDPG
from sb3_maddpg.common.layout import AgentLayout
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.sharing import SHARING_SCHEMES
from tests.settings import SELECTS_EVERY_OTHER_AGENT

N, OBS, ACT, BATCH = 4, 6, 5, 7
LAYOUT = AgentLayout(tuple(f"agent_{i}" for i in range(N)), (OBS,) * N, (ACT,) * N)
PAPER_SCHEMES = ["independent", "full", "observations", "actions", "selected"]


def agent_i_as_agent_0(i: int) -> list[int]:
    """The relabelling: new index j holds old agent ``order[j]``: agent i first, the others in their order."""
    return [i] + [j for j in range(N) if j != i]


def relabel(joint: th.Tensor, order: list[int], size: int) -> th.Tensor:
    return joint.view(BATCH, N, size)[:, order].reshape(BATCH, N * size)


def relabel_selections(selections: th.Tensor, order: list[int]) -> th.Tensor:
    new_index = th.tensor([order.index(j) for j in range(N)])  # old index -> new index
    return new_index[selections[:, order]]


@pytest.mark.parametrize("scheme", PAPER_SCHEMES)
def test_critic_i_reads_what_critic_0_reads_with_agent_i_called_agent_0(scheme: str) -> None:
    generator = th.Generator().manual_seed(0)
    obs, actions = th.randn(BATCH, N * OBS, generator=generator), th.randn(BATCH, N * ACT, generator=generator)
    # Each agent's 2 selected others, as a selector stores them (never itself).
    selections = th.stack([th.randperm(N - 1, generator=generator)[:2] for _ in range(BATCH * N)]).view(BATCH, N, 2)
    selections = selections + (selections >= th.arange(N).view(1, N, 1)).long()
    extractor_class = SHARING_SCHEMES[scheme]
    k = 2 if scheme == "selected" else 0
    critic_0 = extractor_class(LAYOUT, 0, selection_size=k)
    for i in range(1, N):
        order = agent_i_as_agent_0(i)
        critic_i = extractor_class(LAYOUT, i, selection_size=k)
        relabelled = critic_0(relabel(obs, order, OBS), relabel(actions, order, ACT), relabel_selections(selections, order))
        assert th.equal(critic_i(obs, actions, selections), relabelled), (scheme, i)


def test_index_order_alone_would_not_do_for_a_shared_critic() -> None:
    """The check above can fail: a layout that lists every agent in index order (own agent not first) gives critic i
    agent 0's observation where critic 0 has its own."""
    generator = th.Generator().manual_seed(1)
    obs = th.randn(BATCH, N * OBS, generator=generator)
    order = agent_i_as_agent_0(2)
    assert not th.equal(obs, relabel(obs, order, OBS))  # what a "[o_1 .. o_N]" critic 2 would read, vs critic 0's


@pytest.mark.parametrize(("num_agent_neighbors", "num_landmark_neighbors"), [(None, None), (3, 4), (2, 4)])
def test_mpe2s_observations_relabel_with_the_agents(
    num_agent_neighbors: int | None, num_landmark_neighbors: int | None
) -> None:
    """In mpe2 itself, agent i's observation in a world equals agent 0's in the same world with agent i called agent 0:
    simple_spread's agents are interchangeable under that relabelling (index-ordered and nearest-first observations,
    the paper's two nearest agents), so the critics' inputs above mean the same for every agent."""
    kwargs = {"N": N, "continuous_actions": True}
    if num_agent_neighbors is not None:
        kwargs.update(num_agent_neighbors=num_agent_neighbors, num_landmark_neighbors=num_landmark_neighbors)
    env, other = simple_spread_v3.parallel_env(**kwargs), simple_spread_v3.parallel_env(**kwargs)
    env.reset(seed=3)
    other.reset(seed=4)
    world, relabelled = env.unwrapped.world, other.unwrapped.world
    rng = np.random.default_rng(5)
    for agent in world.agents:  # moving agents: velocities are observed too
        agent.state.p_vel = rng.uniform(-1, 1, 2)
    for landmark, copy in zip(world.landmarks, relabelled.landmarks):
        copy.state.p_pos = landmark.state.p_pos.copy()
    for i in range(N):
        for new, old in enumerate(agent_i_as_agent_0(i)):
            relabelled.agents[new].state.p_pos = world.agents[old].state.p_pos.copy()
            relabelled.agents[new].state.p_vel = world.agents[old].state.p_vel.copy()
        observe, observe_other = env.unwrapped.scenario.observation, other.unwrapped.scenario.observation
        np.testing.assert_array_equal(observe(world.agents[i], world), observe_other(relabelled.agents[0], relabelled))


@SELECTS_EVERY_OTHER_AGENT
def test_a_shared_critic_with_a_scheme_per_agent_is_refused() -> None:
    env = SimpleSpreadVecEnv(2, n_agents=3)
    mixed = {"agent_0": "full", "agent_1": "selected", "agent_2": "full"}  # at N=3, k=2: the same input size
    with pytest.raises(ValueError, match="one scheme for every agent"):
        MADDPG("MlpPolicy", env, critic_sharing=mixed, policy_kwargs={"share_parameters": True})
    same = dict.fromkeys(mixed, "full")
    MADDPG("MlpPolicy", env, critic_sharing=same, policy_kwargs={"share_parameters": True})  # one scheme: accepted
