"""Generated PettingZoo envs (``tests/generated_envs.py``) through the adapter and MADDPG / MATD3 with each scheme:
learning runs or refuses in one line that names the cause, episodes end exactly when the env's do, every replay-buffer
row is one step of every agent, save/load round-trips exactly, and ``predict_agents`` takes the agents present.

CI draws a small seeded sample (``tests/conftest.py``'s "ci" profile); ``HYPOTHESIS_PROFILE=long`` draws more."""

from pathlib import Path

import numpy as np
import pytest
from gymnasium import spaces
from hypothesis import example, given, note
from hypothesis import strategies as st
from pettingzoo.test import parallel_api_test

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import PettingZooToGym
from tests.generated_envs import (
    SUPPORTED_ACTIONS,
    SUPPORTED_OBSERVATIONS,
    AgentSpec,
    GeneratedParallelEnv,
    TeamSpec,
    team_specs,
)

SCHEMES = ("independent", "full", "observations", "actions", "selected", "attention")
SMALL = dict(
    learning_starts=12, transitions_per_update=4, batch_size=8, buffer_size=200, policy_kwargs=dict(net_arch=[8]), seed=0
)


def checked_env(spec: TeamSpec) -> GeneratedParallelEnv:
    """:return: The spec's env, after PettingZoo's own API test (a broken generator fails here, not in our code)."""
    note(repr(spec))
    parallel_api_test(GeneratedParallelEnv(spec), num_cycles=spec.max_cycles + 2)
    return GeneratedParallelEnv(spec)


def adapted(spec: TeamSpec) -> PettingZooToGym:
    return PettingZooToGym(checked_env(spec), positions=spec.position_sources())


def assert_one_line_naming(error: BaseException, *causes: str) -> None:
    message = str(error)
    assert "\n" not in message.strip(), message
    assert any(cause in message for cause in causes), message


@given(team_specs(supported_only=False))
# Found by the long profile: the adapter reads every observation space before any action space, so it names the first
# agent whose observation it cannot take, even when an agent before it has an action it cannot take.
@example(
    TeamSpec(
        (
            AgentSpec("box", 1, "multidiscrete", 2, None, "termination"),
            AgentSpec("discrete", 1, "box", 2, None, "termination"),
        ),
        1,
        False,
    )
)
def test_spaces_the_adapter_cannot_take_are_refused_in_one_line(spec: TeamSpec) -> None:
    env = checked_env(spec)
    if spec.supported:
        PettingZooToGym(env, positions=spec.position_sources())
        return
    with pytest.raises(TypeError) as refused:
        PettingZooToGym(env, positions=spec.position_sources())
    observation_refused = [i for i, agent in enumerate(spec.agents) if agent.observation not in SUPPORTED_OBSERVATIONS]
    action_refused = [i for i, agent in enumerate(spec.agents) if agent.action not in SUPPORTED_ACTIONS]
    first, kind = (observation_refused[0], "observation") if observation_refused else (action_refused[0], "action")
    assert_one_line_naming(refused.value, f"Agent 'agent_{first}' has a")
    assert f" {kind} space;" in str(refused.value)


@given(team_specs(), st.integers(0, 2**16))
def test_an_episode_ends_exactly_when_the_env_s_does(spec: TeamSpec, seed: int) -> None:
    env = adapted(spec)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    end, terminated_at_end = spec.episode_end()
    for t in range(1, end + 1):
        obs, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        here_at_start = [a.leaves_at is None or a.leaves_at >= t for a in spec.agents]
        assert info["agent_active"].tolist() == here_at_start
        for i, present in enumerate(here_at_start):
            if not present:  # an agent that left: zeros and no reward
                assert not obs[env.agent_layout.obs_slices[i]].any() and info["agent_rewards"][i] == 0
        assert (terminated, truncated) == ((terminated_at_end, not terminated_at_end) if t == end else (False, False))
    with pytest.raises(RuntimeError, match="The episode is over"):
        env.step(np.zeros(env.action_space.shape, np.float32))


def expected_refusal(spec: TeamSpec, scheme: str) -> tuple[str, ...] | None:
    """:return: What a refusal must name, for a team a scheme cannot serve; None where learning must run."""
    n_agents = len(spec.agents)
    if scheme in ("selected", "attention") and n_agents < 2:
        return ("needs at least 2 agents",)
    if scheme == "selected" and not spec.positions:
        return ("positions",)
    return None


@given(team_specs(max_agents=4), st.sampled_from(SCHEMES), st.sampled_from([MADDPG, MATD3]))
def test_learning_runs_or_refuses_and_every_buffer_row_is_one_step_of_the_team(
    tmp_path_factory: pytest.TempPathFactory, spec: TeamSpec, scheme: str, algorithm: type[MADDPG]
) -> None:
    env = adapted(spec)
    refusal = expected_refusal(spec, scheme)
    selector = {"selector": 1} if scheme == "selected" else {}
    if refusal is not None:
        with pytest.raises((ValueError, TypeError)) as refused:
            algorithm("MlpPolicy", env, critic_sharing=scheme, **selector, **SMALL).learn(32)
        assert_one_line_naming(refused.value, *refusal)
        return
    model = algorithm("MlpPolicy", env, critic_sharing=scheme, **selector, **SMALL).learn(32)
    assert model.num_timesteps == 32 and model._n_updates > 0

    # One row, one step: every active agent's clock (its observation's first entry) is the same, and one more in the
    # next observation; an agent that has left is zeros in the next observation (in the observation of its first row
    # away it is still its last one, given at the step it left).
    buffer, layout = model.replay_buffer, model.agent_layout
    rows = buffer.size()
    active = np.ones((rows, layout.n_agents), bool) if buffer.active is None else buffer.active[:rows, 0]
    clocks = np.stack([buffer.observations[:rows, 0, part.start] for part in layout.obs_slices], axis=1)
    next_clocks = np.stack([buffer.next_observations[:rows, 0, part.start] for part in layout.obs_slices], axis=1)
    for row in range(rows):
        assert len(set(clocks[row, active[row]])) == 1, (row, clocks[row], active[row])
        assert np.all(next_clocks[row, active[row]] == clocks[row, active[row]] + 1)
        for part in (part for part, here in zip(layout.obs_slices, active[row]) if not here):
            assert not buffer.next_observations[row, 0, part].any(), (row, part)

    # Save and load: the same actions on the same observations, every parameter equal.
    path = tmp_path_factory.mktemp("save") / "model"
    model.save(path)
    loaded = algorithm.load(Path(f"{path}.zip"))
    observations = buffer.observations[:rows, 0]
    np.testing.assert_array_equal(model.predict(observations)[0], loaded.predict(observations)[0])
    for name, value in model.policy.state_dict().items():
        assert np.array_equal(value.cpu().numpy(), loaded.policy.state_dict()[name].cpu().numpy()), name

    # predict_agents takes the agents present: an action for each of them in its own space, none for the others.
    parallel_env = env.parallel_env
    agent_observations, _ = parallel_env.reset(seed=1)
    leaving = next((agent for agent in list(agent_observations)[1:]), None)
    if leaving is not None:
        del agent_observations[leaving]
    # A Dict observation is passed flattened, as the adapter flattens it for training (predict_agents says so).
    agent_observations = {
        agent: spaces.flatten(parallel_env.observation_space(agent), obs) if isinstance(obs, dict) else obs
        for agent, obs in agent_observations.items()
    }
    actions = loaded.predict_agents(agent_observations)
    assert set(actions) == set(agent_observations)
    for agent, action in actions.items():
        space = parallel_env.action_space(agent)
        assert space.contains(action if isinstance(action, int) else np.asarray(action, space.dtype)), (agent, action)
