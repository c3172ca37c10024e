"""The module paths of 0.2 that 0.3 moved are gone (importing one fails as any missing module does), and nothing is
installed in ``sys.meta_path`` by ``import sb3_maddpg``; saves of 0.1 and 0.2, which name their classes by those
paths, still load (``compat.old_module_paths``, only while a save is read), and every name an old path held is in one
of its new modules (or recorded as removed on purpose)."""

import importlib
import json
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import sb3_maddpg
from sb3_maddpg import MADDPG
from sb3_maddpg.compat import MOVED_IN_0_3, MovedModule, old_module_paths
from tests.settings import FILLS_THE_BUFFER_ONLY

DATA = Path(__file__).parent / "data"
RECORDED = json.loads((DATA / "module_names_0_2.json").read_text())
NAMES_OF_0_2: dict[str, list[str]] = RECORDED["modules"]
REMOVED_SINCE: dict[str, dict[str, str]] = RECORDED.get("removed_since", {})
"""Names of 0.2's modules removed on purpose since (each with the version and why): they must be gone, not moved."""


def test_every_moved_module_of_0_2_is_listed_and_none_is_a_file() -> None:
    assert sorted(NAMES_OF_0_2) == sorted(MOVED_IN_0_3)
    for old in MOVED_IN_0_3:
        assert not (Path(sb3_maddpg.__file__).parent / f"{old.rpartition('.')[2]}.py").exists(), old


@pytest.mark.parametrize("old", sorted(MOVED_IN_0_3))
def test_an_old_path_does_not_import(old: str) -> None:
    with pytest.raises(ModuleNotFoundError, match=f"No module named '{old}'"):
        importlib.import_module(old)


def test_importing_the_package_installs_no_import_hook() -> None:
    code = (
        "import sys; before = list(sys.meta_path); import sb3_maddpg; "
        "print([type(f).__module__ for f in sys.meta_path if f not in before])"
    )
    added = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "sb3_maddpg" not in added, added  # (dependencies may add their own, e.g. six's)


@pytest.mark.parametrize("old", sorted(MOVED_IN_0_3))
def test_while_a_save_is_read_an_old_path_gives_the_new_modules_objects(old: str) -> None:
    new = MOVED_IN_0_3[old]
    with old_module_paths():
        module = importlib.import_module(old)
        assert isinstance(module, MovedModule)
        for name in NAMES_OF_0_2[old]:
            if name in REMOVED_SINCE.get(old, {}):
                assert not any(hasattr(importlib.import_module(t), name) for t in new), f"{old}.{name} is back"
                continue
            homes = [importlib.import_module(t) for t in new if hasattr(importlib.import_module(t), name)]
            assert homes, f"{old}.{name} is in none of {new}"
            assert getattr(module, name) is getattr(homes[0], name), f"{old}.{name}"
    assert old not in sys.modules  # gone again after the read
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module(old)


@pytest.mark.parametrize("saved", ["maddpg_0.1.0.zip", "maddpg_0.2.0_selected.zip"])
def test_a_save_of_0_1_or_0_2_loads_and_leaves_no_old_path_behind(saved: str) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = MADDPG.load(DATA / saved, device="cpu")
    assert not [w for w in caught if "moved" in str(w.message)]
    assert type(model.policy).__module__ == "sb3_maddpg.maddpg.policies"
    assert not any(old in sys.modules for old in MOVED_IN_0_3)


def test_the_algorithm_packages_keep_the_names_their_modules_of_0_2_exported() -> None:
    from sb3_maddpg.common.losses import SATURATION_THRESHOLD, ActorLossTerms
    from sb3_maddpg.common.team_algorithm import LOG_INTERVAL
    from sb3_maddpg.maddpg import LOG_INTERVAL as log_interval
    from sb3_maddpg.maddpg import SATURATION_THRESHOLD as threshold
    from sb3_maddpg.maddpg import ActorLossTerms as terms
    from sb3_maddpg.matd3 import MATD3, smooth_target_actions  # noqa: F401

    assert (log_interval, threshold, terms) == (LOG_INTERVAL, SATURATION_THRESHOLD, ActorLossTerms)


@FILLS_THE_BUFFER_ONLY
def test_a_replay_buffer_saved_under_the_0_2_paths_loads(tmp_path: Path) -> None:
    from sb3_maddpg.common.buffers import MultiAgentReplayBuffer
    from sb3_maddpg.envs import make_simple_spread

    model = MADDPG("MlpPolicy", make_simple_spread(n_agents=2), learning_starts=1_000, buffer_size=100, seed=0)
    model.learn(30)
    stored = model.replay_buffer.size()
    path = tmp_path / "buffer.pkl"
    MultiAgentReplayBuffer.__module__ = "sb3_maddpg.buffers"  # pickled as 0.2 named it
    try:
        with old_module_paths():
            model.save_replay_buffer(path)
    finally:
        MultiAgentReplayBuffer.__module__ = "sb3_maddpg.common.buffers"
    assert b"sb3_maddpg.buffers" in path.read_bytes()
    model.load_replay_buffer(path)
    assert model.replay_buffer.size() == stored > 0
    assert "sb3_maddpg.buffers" not in sys.modules
