"""The module paths of 0.2 that 0.3 moved keep working: each warns once, names the new path, and hands out the new
modules' own objects; loading a model saved under the old paths warns about nothing the user wrote."""

import importlib
import json
import sys
import warnings
from pathlib import Path

import pytest

import sb3_maddpg
from sb3_maddpg import MADDPG
from sb3_maddpg.compat import MOVED_IN_0_3, MovedModule, MovedModuleWarning

DATA = Path(__file__).parent / "data"
NAMES_OF_0_2: dict[str, list[str]] = json.loads((DATA / "module_names_0_2.json").read_text())["modules"]


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
