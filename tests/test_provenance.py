"""The commit written into every stored config: read from the git checkout that holds the package, marked when the
checkout has uncommitted changes, absent (``None``) outside one."""

import shutil
import subprocess
from pathlib import Path

import pytest

from sb3_maddpg.provenance import DIRTY, source_commit

pytestmark = pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")


def _git(cwd: Path, *args: str) -> str:
    done = subprocess.run(
        ["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=cwd, capture_output=True, text=True, check=True
    )
    return done.stdout.strip()


def _checkout(root: Path) -> Path:
    """A git checkout with a committed ``sb3_maddpg`` package directory; :return: that directory."""
    package = root / "sb3_maddpg"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("x = 1\n")
    _git(root, "init", "-q")
    _git(root, "add", ".")
    _git(root, "commit", "-q", "-m", "first")
    return package


def test_a_clean_checkout_gives_its_commit(tmp_path: Path) -> None:
    package = _checkout(tmp_path)
    assert source_commit.__wrapped__(package) == _git(tmp_path, "rev-parse", "HEAD")


def test_uncommitted_changes_to_tracked_files_mark_the_commit(tmp_path: Path) -> None:
    package = _checkout(tmp_path)
    (tmp_path / "results.csv").write_text("untracked output does not count\n")
    assert not source_commit.__wrapped__(package).endswith(DIRTY)
    (package / "__init__.py").write_text("x = 2\n")
    assert source_commit.__wrapped__(package) == _git(tmp_path, "rev-parse", "HEAD") + DIRTY


def test_outside_a_checkout_of_the_package_there_is_no_commit(tmp_path: Path) -> None:
    (tmp_path / "sb3_maddpg").mkdir()
    assert source_commit.__wrapped__(tmp_path / "sb3_maddpg") is None
    # A checkout of another project that vendors the package deeper down is not the package's commit.
    vendored = _checkout(tmp_path / "project").parent / "vendor" / "sb3_maddpg"
    vendored.mkdir(parents=True)
    assert source_commit.__wrapped__(vendored) is None
