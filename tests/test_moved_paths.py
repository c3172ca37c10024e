"""The module paths of 0.2 that 0.3 moved keep working: each warns once, names the new path, and hands out the new
modules' own objects; loading a model saved under the old paths warns about nothing the user wrote."""

import importlib
import json
import pickle
import sys
import warnings
from pathlib import Path
from unittest import mock

import pytest

import sb3_maddpg
from sb3_maddpg import MADDPG
from sb3_maddpg.compat import MOVED_IN_0_3, MovedModule, MovedModuleWarning

DATA = Path(__file__).parent / "data"
RECORDED = json.loads((DATA / "module_names_0_2.json").read_text())
NAMES_OF_0_2: dict[str, list[str]] = RECORDED["modules"]
REMOVED_SINCE: dict[str, dict[str, str]] = RECORDED.get("removed_since", {})
"""Names of 0.2's modules removed on purpose since (each with the version and why): they must be gone, not moved."""


def forget(old: str) -> None:
    """Drop an old path from the import caches, so the next import goes through the finder again."""
    sys.modules.pop(old, None)
    parent, _, child = old.rpartition(".")
    if isinstance(getattr(sys.modules[parent], child, None), MovedModule):
        delattr(sys.modules[parent], child)


def test_every_moved_module_of_0_2_is_listed() -> None:
    assert sorted(NAMES_OF_0_2) == sorted(MOVED_IN_0_3)
    for old in MOVED_IN_0_3:  # and none is still a file of its own
        assert not (Path(sb3_maddpg.__file__).parent / f"{old.rpartition('.')[2]}.py").exists(), old


@pytest.mark.parametrize("old", sorted(MOVED_IN_0_3))
def test_an_old_path_warns_naming_the_new_one_and_gives_the_same_objects(old: str) -> None:
    forget(old)
    new = MOVED_IN_0_3[old]
    with pytest.warns(MovedModuleWarning, match=f"{old} moved to {new[0]}"):
        module = importlib.import_module(old)
    assert NAMES_OF_0_2[old], old
    for name in NAMES_OF_0_2[old]:
        if name in REMOVED_SINCE.get(old, {}):
            assert not any(hasattr(importlib.import_module(target), name) for target in new), f"{old}.{name} is back"
            continue
        objects = [
            getattr(importlib.import_module(target), name) for target in new if hasattr(importlib.import_module(target), name)
        ]
        assert objects, f"{old}.{name} is in none of {new}"
        assert getattr(module, name) is objects[0], f"{old}.{name}"
    with pytest.raises(AttributeError, match="moved to"):
        module.no_such_name  # noqa: B018


def test_from_import_of_an_old_path_works() -> None:
    forget("sb3_maddpg.policies")
    with pytest.warns(MovedModuleWarning):
        from sb3_maddpg.policies import MADDPGPolicy, MultiAgentActor  # type: ignore[attr-defined]
    from sb3_maddpg.common.policies import MultiAgentActor as actor_now
    from sb3_maddpg.maddpg.policies import MADDPGPolicy as policy_now

    assert MADDPGPolicy is policy_now and MultiAgentActor is actor_now


@pytest.mark.parametrize("saved", ["maddpg_0.1.0.zip", "maddpg_0.2.0_selected.zip"])
def test_loading_a_save_of_0_1_or_0_2_warns_about_no_moved_path(saved: str) -> None:
    for old in MOVED_IN_0_3:
        forget(old)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = MADDPG.load(DATA / saved, device="cpu")
    assert [w for w in caught if issubclass(w.category, MovedModuleWarning)] == []
    assert type(model.policy).__module__ == "sb3_maddpg.maddpg.policies"
    # the save named its classes by their 0.2 paths: the load went through them
    assert any(name in sys.modules for name in MOVED_IN_0_3)


def test_the_algorithm_packages_keep_the_names_their_modules_of_0_2_exported() -> None:
    from sb3_maddpg.common.losses import SATURATION_THRESHOLD, ActorLossTerms
    from sb3_maddpg.common.team_algorithm import LOG_INTERVAL
    from sb3_maddpg.maddpg import LOG_INTERVAL as log_interval
    from sb3_maddpg.maddpg import SATURATION_THRESHOLD as threshold
    from sb3_maddpg.maddpg import ActorLossTerms as terms
    from sb3_maddpg.matd3 import MATD3, smooth_target_actions  # noqa: F401

    assert (log_interval, threshold, terms) == (LOG_INTERVAL, SATURATION_THRESHOLD, ActorLossTerms)


def test_a_star_import_of_an_old_path_binds_the_new_modules_public_names() -> None:
    forget("sb3_maddpg.layout")
    namespace: dict[str, object] = {}
    with pytest.warns(MovedModuleWarning):
        exec("from sb3_maddpg.layout import *", namespace)
    from sb3_maddpg.common.layout import AgentLayout

    assert namespace["AgentLayout"] is AgentLayout


def test_patching_a_name_through_an_old_path_patches_the_module_the_package_reads() -> None:
    forget("sb3_maddpg.noise")
    with pytest.warns(MovedModuleWarning):
        old = importlib.import_module("sb3_maddpg.noise")
    import sb3_maddpg.common.noise as noise

    original = noise.add_noise
    with mock.patch("sb3_maddpg.noise.add_noise") as patched:
        assert noise.add_noise is patched
    assert noise.add_noise is original and old.add_noise is original


def test_loading_a_replay_buffer_saved_under_the_0_2_paths_warns_about_no_moved_path(tmp_path: Path) -> None:
    from sb3_maddpg.common.buffers import MultiAgentReplayBuffer
    from sb3_maddpg.envs import make_simple_spread

    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=2), learning_starts=1_000, buffer_size=100, seed=0)
    model.learn(30)
    stored = model.replay_buffer.size()
    path = tmp_path / "buffer.pkl"
    MultiAgentReplayBuffer.__module__ = "sb3_maddpg.buffers"  # pickled as 0.2 named it
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MovedModuleWarning)
            model.save_replay_buffer(path)
    finally:
        MultiAgentReplayBuffer.__module__ = "sb3_maddpg.common.buffers"
    assert b"sb3_maddpg.buffers" in path.read_bytes() and pickle.loads(path.read_bytes()) is not None
    for old in MOVED_IN_0_3:
        forget(old)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model.load_replay_buffer(path)
    assert [w for w in caught if issubclass(w.category, MovedModuleWarning)] == []
    assert model.replay_buffer.size() == stored > 0
