"""Where a stored config came from: the git commit of the sb3-maddpg source that ran it.

A study's runs go on for hours from a checkout pinned to a commit; the commit written into each run's own
``config.json`` (:data:`COMMIT_KEY`) says which code made its numbers without a separate log. The commit is read once
per process: a run started from a checkout edited afterwards still names the commit it started from.
"""

import functools
import subprocess
from pathlib import Path

COMMIT_KEY = "sb3_maddpg_commit"
"""The key of the commit a stored config was written from: a 40-hex git commit, ``+dirty`` appended when the checkout
had uncommitted changes to tracked files, or ``None`` where sb3-maddpg was not run from a git checkout (an installed
wheel)."""

DIRTY = "+dirty"
"""Appended to :data:`COMMIT_KEY`'s commit when tracked files differed from it: the commit alone does not make the run."""

PACKAGE_ROOT = Path(__file__).resolve().parent


def _git(*args: str, cwd: Path) -> str | None:
    """:return: What ``git args`` printed in ``cwd``, stripped; ``None`` where git is missing or fails there."""
    try:
        done = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, timeout=30, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


@functools.cache
def source_commit(package_root: Path = PACKAGE_ROOT) -> str | None:
    """
    :param package_root: The ``sb3_maddpg`` package directory whose checkout to read (this package's by default).
    :return: The commit of the git checkout that holds ``package_root``, with :data:`DIRTY` appended when its tracked
        files have uncommitted changes; ``None`` when the package is not in a git checkout of sb3-maddpg (installed
        from a wheel, or inside another project's repository).
    """
    top = _git("rev-parse", "--show-toplevel", cwd=package_root)
    if top is None or Path(top).resolve() != package_root.parent:
        return None
    commit = _git("rev-parse", "HEAD", cwd=package_root)
    if commit is None:
        return None
    changes = _git("status", "--porcelain", "--untracked-files=no", cwd=package_root)
    return commit + DIRTY if changes else commit
