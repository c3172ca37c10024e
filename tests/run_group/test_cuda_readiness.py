"""
A run group on a GPU's terms, checked on a CPU: a small group on the ``meta`` device under
:class:`~sb3_maddpg.run_group.audit.DeviceAudit` makes no host sync, no host-device transfer and no float64 in its env
step and its update, and launches as many kernels for 8 runs as for 2. Each defect the audit guards against is planted
below, and the audit is seen to catch it.
"""

from collections.abc import Callable
from typing import Any

import pytest
import torch as th

from sb3_maddpg import MADDPG, MATD3
from sb3_maddpg.envs import SimpleSpreadVecEnv
from sb3_maddpg.run_group import RunGroup, RunStreams
from sb3_maddpg.run_group.audit import DeviceAudit

WORLDS = 4


def meta_group(n_runs: int, algorithm: type[MADDPG] = MADDPG, scheme: str = "full", n_agents: int = 5) -> RunGroup:
    """A group of tiny models on the meta device, past its warm-up (its next round collects with the actors)."""
    settings: dict[str, Any] = {
        "learning_starts": 2 * WORLDS,
        "batch_size": 16,
        "buffer_size": 100 * WORLDS,
        "transitions_per_update": WORLDS,
        "policy_kwargs": {"net_arch": [8, 8]},
        "critic_sharing": scheme,
    }
    if scheme == "selected":
        settings["selector"] = 2
    env = SimpleSpreadVecEnv(WORLDS, n_agents=n_agents)
    models = [algorithm("MlpPolicy", env, seed=seed, **settings) for seed in range(n_runs)]
    return RunGroup(models, device="meta").learn(2 * WORLDS)


def audit(group: RunGroup) -> tuple[DeviceAudit, DeviceAudit]:
    """:return: The audits of one env step and of two updates (MATD3: one with the actors, one without)."""
    with DeviceAudit() as step:
        group.collect_step()
    with DeviceAudit() as update:
        group.train(2)
    return step, update


@pytest.mark.parametrize(("algorithm", "scheme"), [(MADDPG, "full"), (MADDPG, "selected"), (MATD3, "full")])
def test_the_step_and_the_update_make_no_sync_no_transfer_and_no_float64(algorithm: type[MADDPG], scheme: str) -> None:
    step, update = audit(meta_group(2, algorithm, scheme))
    assert step.problems() == [] and update.problems() == []
    assert step.n_launches > 50 and update.n_launches > 200  # the audit saw the work


def test_the_warm_up_step_makes_no_sync_either() -> None:
    group = meta_group(2)
    group.learning_starts = 10**9  # uniform actions, drawn per run
    step, _ = audit(group)
    assert step.problems() == []


@pytest.mark.slow
@pytest.mark.parametrize(("algorithm", "scheme"), [(MADDPG, "full"), (MADDPG, "selected"), (MATD3, "full")])
def test_launches_do_not_grow_with_the_number_of_runs(algorithm: type[MADDPG], scheme: str) -> None:
    """8 runs launch what 2 launch. (1 run launches a few fewer: reshaping a run dimension of size 1 is a view where
    a larger one needs a copy.)"""
    counts = {n_runs: [a.launches for a in audit(meta_group(n_runs, algorithm, scheme))] for n_runs in (1, 2, 8)}
    assert counts[2] == counts[8]
    assert all(sum(one.values()) <= sum(two.values()) for one, two in zip(counts[1], counts[2]))


def test_the_streams_state_is_host_integers_that_mean_the_same_on_every_device() -> None:
    """What made resuming on another device fail (a CPU generator's 5,056-byte state into a CUDA generator's 16): the
    streams' state is the seeds' keys and a counter, loaded into streams of the same seeds on any device; streams of
    other seeds refuse it."""
    streams = RunStreams([0, 1])
    streams.normal((3,))
    state = streams.state_dict()
    assert all(tensor.device.type == "cpu" and tensor.dtype == th.int64 for tensor in state.values())
    resumed = RunStreams([0, 1], device="meta")
    resumed.load_state_dict(state)  # no device-specific state to mismatch
    assert resumed.counter.device.type == "meta"
    with pytest.raises(ValueError, match="other seeds"):
        RunStreams([0, 2]).load_state_dict(state)


# ----- the defects the audit guards against, planted -----


def plant_sync(group: RunGroup, monkeypatch: pytest.MonkeyPatch) -> None:
    """An ``.item()`` in the loop (e.g. a loss logged per step)."""
    explore = group.explore
    monkeypatch.setattr(group, "explore", lambda obs, *warm_up: explore(obs, *warm_up) * (1.0 + 0.0 * obs.sum().item()))


def plant_per_run_loop(group: RunGroup, monkeypatch: pytest.MonkeyPatch) -> None:
    """A Python loop over the runs (e.g. one generator per run)."""
    explore = group.explore
    monkeypatch.setattr(
        group, "explore", lambda obs, *warm_up: th.stack([run * 1.0 for run in explore(obs, *warm_up).unbind(0)])
    )


def plant_host_tensor(group: RunGroup, monkeypatch: pytest.MonkeyPatch) -> None:
    """A tensor made on the host in the step (a Python constant turned into a device tensor each call)."""
    explore = group.explore
    monkeypatch.setattr(group, "explore", lambda obs, *warm_up: explore(obs, *warm_up) + th.tensor(0.0, device=obs.device))


def plant_float64(group: RunGroup, monkeypatch: pytest.MonkeyPatch) -> None:
    """float64 arithmetic (e.g. a NumPy value's dtype carried over)."""
    explore = group.explore
    monkeypatch.setattr(group, "explore", lambda obs, *warm_up: explore(obs, *warm_up).double().float())


@pytest.mark.parametrize(
    ("plant", "caught"),
    [
        (plant_sync, "host sync: _local_scalar_dense"),
        (plant_host_tensor, "host-device transfer: torch.tensor of host data"),
        (plant_float64, "float64"),
    ],
)
def test_the_audit_catches_a_planted_sync_transfer_and_float64(
    plant: Callable[[RunGroup, pytest.MonkeyPatch], None], caught: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    group = meta_group(2)
    plant(group, monkeypatch)
    step, _ = audit(group)
    assert any(problem.startswith(caught) for problem in step.problems()), step.problems()


def test_the_audit_catches_a_planted_per_run_loop(monkeypatch: pytest.MonkeyPatch) -> None:
    steps = {}
    for n_runs in (2, 8):
        group = meta_group(n_runs)
        plant_per_run_loop(group, monkeypatch)
        steps[n_runs] = audit(group)[0].n_launches
    assert steps[8] > steps[2]
