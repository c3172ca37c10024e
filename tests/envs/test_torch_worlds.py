"""
TorchSpreadWorlds against the numpy worlds (step by step from copied states, and 25 steps without re-syncing) and
against mpe2 (seeded episodes), its resets against mpe2's distribution, and the env package's freedom from torch.
"""

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch as th
from scipy import stats

from sb3_maddpg.envs import make_simple_spread
from sb3_maddpg.envs.simple_spread import CAPTURE_RADIUS
from sb3_maddpg.envs.simple_spread_worlds import SimpleSpreadWorlds, WorldDistances
from sb3_maddpg.envs.torch_spread_worlds import TorchSpreadWorlds

TOLERANCE = 1e-12
"""Largest difference from the numpy worlds in float64 (torch's logaddexp differs from numpy's in the last bit)."""
OBS_TOLERANCE = 1e-6
"""Largest difference in the float32 observations (a float64 difference in the last bit may round either way)."""
MPE2_TOLERANCE = 1e-5
"""Largest difference from mpe2 through the adapter (float32 observations and rewards)."""

SETTINGS = [
    (n_agents, num_agent_neighbors, num_landmark_neighbors)
    for n_agents in range(2, 9)
    for num_agent_neighbors in (None, *range(1, n_agents))
    for num_landmark_neighbors in dict.fromkeys((None, 1, n_agents - 1, n_agents))
]
"""N from 2 to 8, every observability of other agents; all landmarks in index order, or the nearest 1, N-1 or N."""


def random_state(worlds: SimpleSpreadWorlds, rng: np.random.Generator, crowded: bool) -> None:
    """A random state; crowded: every agent within 0.25 of the origin and moving (agents overlap, contacts act)."""
    shape = worlds.agent_pos.shape
    worlds.agent_pos[:] = rng.uniform(-0.25, 0.25, shape) if crowded else rng.uniform(-1, 1, shape)
    worlds.agent_vel[:] = rng.uniform(-1, 1, shape)
    worlds.landmark_pos[:] = rng.uniform(-1, 1, shape)


def copy_to_torch(numpy_worlds: SimpleSpreadWorlds, torch_worlds: TorchSpreadWorlds) -> None:
    torch_worlds.set_state(numpy_worlds.agent_pos, numpy_worlds.agent_vel, numpy_worlds.landmark_pos)


def largest_differences(
    numpy_worlds: SimpleSpreadWorlds,
    numpy_distances: WorldDistances[np.ndarray],
    torch_worlds: TorchSpreadWorlds,
    torch_distances: WorldDistances[th.Tensor],
) -> tuple[float, float]:
    """
    :return: The largest difference in the float64 quantities (state, rewards, metrics incl. landmark_distances),
        relative to their size where it exceeds 1, and the largest in the observations.
    """
    pairs = [
        (numpy_worlds.agent_pos, torch_worlds.agent_pos),
        (numpy_worlds.agent_vel, torch_worlds.agent_vel),
        (numpy_worlds.rewards(numpy_distances), torch_worlds.rewards(torch_distances)),
    ]
    numpy_metrics = numpy_worlds.metrics(numpy_distances, CAPTURE_RADIUS)
    torch_metrics = torch_worlds.metrics(torch_distances, CAPTURE_RADIUS)
    assert set(numpy_metrics) == set(torch_metrics)
    pairs += [(numpy_metrics[key], torch_metrics[key]) for key in numpy_metrics]
    largest = 0.0
    for expected, actual in pairs:
        assert actual.dtype == th.float64 and tuple(actual.shape) == expected.shape
        difference = np.abs(actual.cpu().numpy() - expected) / np.maximum(1.0, np.abs(expected))
        largest = max(largest, float(difference.max()))
    observations = torch_worlds.observations(torch_distances)
    assert observations.dtype == th.float32
    obs_difference = np.abs(observations.cpu().numpy() - numpy_worlds.observations(numpy_distances)).max()
    return largest, float(obs_difference)


def run_both(
    n_agents: int,
    num_agent_neighbors: int | None,
    num_landmark_neighbors: int | None,
    resync: bool,
    seed: int,
    device: str = "cpu",
) -> tuple[float, float, int]:
    """
    25 steps of 16 worlds (half of them crowded) in numpy and in torch from the same start and actions; with
    ``resync``, the numpy state is copied into the torch worlds before every step (so each step is compared alone).

    :return: The largest differences (float64 quantities, observations) and the number of agent pairs in contact.
    """
    n_worlds, steps = 16, 25
    rng = np.random.default_rng(seed)
    numpy_worlds = SimpleSpreadWorlds(n_worlds, n_agents, num_agent_neighbors, num_landmark_neighbors, local_ratio=0.3)
    torch_worlds = TorchSpreadWorlds(
        n_worlds, n_agents, num_agent_neighbors, num_landmark_neighbors, local_ratio=0.3, device=device
    )
    random_state(numpy_worlds, rng, crowded=False)
    crowded = SimpleSpreadWorlds(n_worlds // 2, n_agents)
    random_state(crowded, rng, crowded=True)
    numpy_worlds.agent_pos[::2], numpy_worlds.agent_vel[::2] = crowded.agent_pos, crowded.agent_vel
    copy_to_torch(numpy_worlds, torch_worlds)
    largest, obs_largest = largest_differences(numpy_worlds, numpy_worlds.distances(), torch_worlds, torch_worlds.distances())
    contacts = 0
    for _ in range(steps):
        if resync:
            copy_to_torch(numpy_worlds, torch_worlds)
        actions = rng.uniform(0, 1, (n_worlds, n_agents, 5)).astype(np.float32)
        numpy_distances = numpy_worlds.step(actions)
        torch_distances = torch_worlds.step(th.from_numpy(actions).to(device))
        step_largest, step_obs_largest = largest_differences(numpy_worlds, numpy_distances, torch_worlds, torch_distances)
        largest, obs_largest = max(largest, step_largest), max(obs_largest, step_obs_largest)
        contacts += int(numpy_distances.in_contact.sum()) // 2
    return largest, obs_largest, contacts


@pytest.mark.slow
@pytest.mark.parametrize("resync", [True, False], ids=["one step", "25 steps"])
@pytest.mark.parametrize("n_agents", range(2, 9))
def test_steps_equal_the_numpy_worlds(n_agents: int, resync: bool) -> None:
    """From copied random and crowded states, one step and 25 steps give the numpy worlds' state, observations,
    rewards and metrics, for every observability of N agents."""
    for setting in [setting for setting in SETTINGS if setting[0] == n_agents]:
        largest, obs_largest, contacts = run_both(*setting, resync=resync, seed=sum(s or 0 for s in setting))
        assert largest <= TOLERANCE, f"{setting}: float64 quantities differ by {largest:.3g}"
        assert obs_largest <= OBS_TOLERANCE, f"{setting}: observations differ by {obs_largest:.3g}"
        assert contacts >= 4, f"{setting}: the crowded starts should force contacts, got {contacts}"


def test_float32_worlds_stay_close() -> None:
    """float32 worlds (for speed on a GPU) keep float32 state and compute what float64 worlds compute, to its rounding."""
    rng = np.random.default_rng(1)
    numpy_worlds = SimpleSpreadWorlds(8, 4, num_agent_neighbors=2)
    random_state(numpy_worlds, rng, crowded=False)
    worlds = TorchSpreadWorlds(8, 4, num_agent_neighbors=2, dtype=th.float32)
    copy_to_torch(numpy_worlds, worlds)
    actions = rng.uniform(0, 1, (8, 4, 5)).astype(np.float32)
    numpy_distances, distances = numpy_worlds.step(actions), worlds.step(th.from_numpy(actions))
    assert worlds.agent_pos.dtype == worlds.agent_vel.dtype == worlds.rewards(distances).dtype == th.float32
    np.testing.assert_allclose(worlds.agent_pos.numpy(), numpy_worlds.agent_pos, atol=1e-5)
    np.testing.assert_allclose(worlds.rewards(distances).numpy(), numpy_worlds.rewards(numpy_distances), atol=1e-4)
    np.testing.assert_allclose(worlds.observations(distances).numpy(), numpy_worlds.observations(numpy_distances), atol=1e-5)


def mpe2_state(env: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    world = env.parallel_env.unwrapped.world  # type: ignore[attr-defined]
    return (
        np.array([[agent.state.p_pos for agent in world.agents]]),
        np.array([[agent.state.p_vel for agent in world.agents]]),
        np.array([[landmark.state.p_pos for landmark in world.landmarks]]),
    )


@pytest.mark.parametrize(
    ("n_agents", "num_agent_neighbors", "num_landmark_neighbors"),
    [(2, None, None), (3, 1, None), (4, None, 2), (5, 2, None), (6, 3, 3), (8, None, None)],
)
def test_seeded_mpe2_episodes_replay_from_their_first_state(
    n_agents: int, num_agent_neighbors: int | None, num_landmark_neighbors: int | None
) -> None:
    """
    mpe2's seeded episodes (every other one starting crowded), from mpe2's first state copied in once and never
    re-synced: every step's observations, per-agent rewards and metrics are mpe2's. (The torch worlds draw their
    own episodes from torch generators, so mpe2's seeds cannot choose them: only the start is copied.)
    """
    env = make_simple_spread(
        n_agents=n_agents,
        num_agent_neighbors=num_agent_neighbors,
        num_landmark_neighbors=num_landmark_neighbors,
        local_ratio=0.4,
    )
    worlds = TorchSpreadWorlds(1, n_agents, num_agent_neighbors, num_landmark_neighbors, local_ratio=0.4)
    rng = np.random.default_rng(n_agents)
    contacts = 0
    for episode in range(4):
        env.reset(seed=1000 * n_agents + episode)
        if episode % 2:
            for agent in env.parallel_env.unwrapped.world.agents:  # type: ignore[attr-defined]
                agent.state.p_pos = rng.uniform(-0.25, 0.25, 2)
                agent.state.p_vel = rng.uniform(-1, 1, 2)
        worlds.set_state(*mpe2_state(env))
        for step in range(24):  # the 25th step truncates (and the adapter's last observation is the same)
            actions = rng.uniform(0, 1, (n_agents, 5)).astype(np.float32)
            observation, _, _, _, info = env.step(actions.reshape(-1))
            distances = worlds.step(th.from_numpy(actions[None]))
            where = f"episode {episode}, step {step}"
            np.testing.assert_allclose(
                worlds.observations(distances)[0].reshape(-1).numpy(), observation, atol=MPE2_TOLERANCE, err_msg=where
            )
            np.testing.assert_allclose(
                worlds.rewards(distances)[0].numpy(), info["agent_rewards"], atol=MPE2_TOLERANCE, err_msg=where
            )
            metrics = worlds.metrics(distances, CAPTURE_RADIUS)
            for key in ("coverage", "success", "collisions", "min_dist_sum", "landmark_distances"):
                np.testing.assert_allclose(metrics[key][0].numpy(), info[key], atol=MPE2_TOLERANCE, err_msg=f"{key}, {where}")
            contacts += int(info["collisions"] > 0)
            # mpe2's float64 state itself, to rounding, after up to 24 steps without a re-sync.
            agent_pos, agent_vel, _ = mpe2_state(env)
            np.testing.assert_allclose(worlds.agent_pos.numpy(), agent_pos, rtol=TOLERANCE, atol=TOLERANCE, err_msg=where)
            np.testing.assert_allclose(worlds.agent_vel.numpy(), agent_vel, rtol=TOLERANCE, atol=TOLERANCE, err_msg=where)
    assert contacts >= 2  # the crowded episodes did force contacts


def mpe2_resets(n_agents: int, episodes: int) -> tuple[np.ndarray, np.ndarray]:
    """mpe2's first states of ``episodes`` seeded episodes: agent and landmark positions, ``[episodes, N, 2]`` each."""
    env = make_simple_spread(n_agents=n_agents)
    agents, landmarks = [], []
    for seed in range(episodes):
        env.reset(seed=seed)
        agent_pos, agent_vel, landmark_pos = mpe2_state(env)
        assert not agent_vel.any()
        agents.append(agent_pos[0])
        landmarks.append(landmark_pos[0])
    return np.array(agents), np.array(landmarks)


def test_resets_have_mpe2s_distribution() -> None:
    """
    Two-sample KS tests against mpe2's own resets: each coordinate of agents and of landmarks, and the first
    state's sum of landmark-to-nearest-agent distances (which depends on all positions together); velocities zero.
    """
    n_agents = 3
    agents, landmarks = mpe2_resets(n_agents, episodes=300)
    worlds = TorchSpreadWorlds(3000, n_agents)
    worlds.agent_vel += 1.0
    worlds.reset(th.Generator().manual_seed(0))
    assert not worlds.agent_vel.any()
    ours = {"agents": worlds.agent_pos.numpy(), "landmarks": worlds.landmark_pos.numpy()}
    for name, theirs in (("agents", agents), ("landmarks", landmarks)):
        for axis in range(2):
            result = stats.ks_2samp(ours[name][..., axis].ravel(), theirs[..., axis].ravel())
            assert result.pvalue > 0.01, f"{name}, axis {axis}: {result}"
        assert np.abs(ours[name]).max() <= 1.0
    reference = SimpleSpreadWorlds(len(agents), n_agents)
    reference.agent_pos[:], reference.landmark_pos[:] = agents, landmarks
    theirs_sum = reference.metrics(reference.distances(), CAPTURE_RADIUS)["min_dist_sum"]
    ours_sum = worlds.metrics(worlds.distances(), CAPTURE_RADIUS)["min_dist_sum"].numpy()
    result = stats.ks_2samp(ours_sum, theirs_sum)
    assert result.pvalue > 0.01, f"min_dist_sum at reset: {result}"
    # And against the uniform distribution on [-1, 1] itself, with many more draws than mpe2 gives quickly.
    for values in ours.values():
        assert stats.kstest(values.ravel(), "uniform", args=(-1, 2)).pvalue > 0.01


def test_draws_given_by_the_caller_place_the_worlds() -> None:
    """Draws made by the caller (a run group's streams) are the episodes, scaled as a generator's: agents first, then
    landmarks, u in [0, 1) to 2u - 1; the same numbers through a generator give the same worlds."""
    worlds, draws = TorchSpreadWorlds(4, 3), th.rand((4, 6, 2), generator=th.Generator().manual_seed(5), dtype=th.float64)
    worlds.reset(draws)
    assert th.equal(worlds.agent_pos, draws[:, :3] * 2 - 1) and th.equal(worlds.landmark_pos, draws[:, 3:] * 2 - 1)
    assert th.equal(worlds.agent_vel, th.zeros_like(worlds.agent_pos))
    through_generator = TorchSpreadWorlds(4, 3)
    through_generator.reset(th.Generator().manual_seed(5))
    assert th.equal(through_generator.agent_pos, worlds.agent_pos)


def test_bad_arguments_are_refused() -> None:
    worlds = TorchSpreadWorlds(4, 3)
    with pytest.raises(ValueError, match=r"must be uniform numbers of shape \(4, 6, 2\)"):
        worlds.reset(th.rand(3, 6, 2, dtype=th.float64))
    worlds.reset(th.rand(4, 6, 2, dtype=th.float64))  # the shape the refusal names is taken
    with pytest.raises(ValueError, match="must have shape"):
        worlds.set_state(np.zeros((4, 2, 2)), np.zeros((4, 3, 2)), np.zeros((4, 3, 2)))
    with pytest.raises(ValueError, match="floating dtype"):
        TorchSpreadWorlds(4, 3, dtype=th.int64)


def test_the_env_package_never_imports_torch() -> None:
    """Only torch_spread_worlds imports torch; the numpy worlds load and step without torch ever being imported."""
    envs = Path(__file__).resolve().parents[2] / "sb3_maddpg" / "envs"
    importing_torch = set()
    for path in envs.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [alias.name for alias in node.names] if isinstance(node, ast.Import) else []
            names += [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            if any(name.split(".")[0] == "torch" for name in names):
                importing_torch.add(path.name)
    assert importing_torch == {"torch_spread_worlds.py"}
    # The package's own __init__ imports the algorithm (and torch): load the worlds' module alone.
    script = (
        "import importlib.util, sys\n"
        f"spec = importlib.util.spec_from_file_location('worlds', {str(envs / 'simple_spread_worlds.py')!r})\n"
        "module = importlib.util.module_from_spec(spec); spec.loader.exec_module(module)\n"
        "import numpy as np\n"
        "worlds = module.SimpleSpreadWorlds(3, 4, 2, 2)\n"
        "worlds.reset_world(0, np.random.default_rng(0))\n"
        "d = worlds.step(np.zeros((3, 4, 5), np.float32)); worlds.observations(d); worlds.rewards(d); worlds.metrics(d, 0.1)\n"
        "assert 'torch' not in sys.modules, 'torch was imported'\n"
    )
    subprocess.run([sys.executable, "-c", script], check=True)


@pytest.mark.skipif(not th.cuda.is_available(), reason="needs a CUDA GPU")
def test_on_cuda() -> None:
    """On a GPU: float64 worlds equal the numpy ones (25 steps from crowded and random states), resets draw from a
    CUDA generator, float32 worlds step."""
    for setting in [(3, None, None), (5, 2, None), (8, 3, 4)]:
        largest, obs_largest, _ = run_both(*setting, resync=False, seed=7, device="cuda")
        assert largest <= 1e-10 and obs_largest <= OBS_TOLERANCE, setting
    worlds = TorchSpreadWorlds(1000, 5, num_agent_neighbors=2, device="cuda", dtype=th.float32)
    worlds.reset(th.Generator(device="cuda").manual_seed(4))
    assert worlds.agent_pos.is_cuda and worlds.agent_pos.abs().max() <= 1
    distances = worlds.step(th.rand((1000, 5, 5), device="cuda"))
    assert worlds.observations(distances).shape == (1000, 5, worlds.obs_size)
    with pytest.raises(ValueError, match="cannot draw on"):
        worlds.reset(th.Generator())
