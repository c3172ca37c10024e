"""Every Python snippet of the docs runs: each page's ``code-block:: python`` blocks, in order, as one script.

Only the budgets are cut, so that the pages run in seconds: ``total_timesteps`` and ``learn(...)`` to at most
26,000 steps (past the default ``learning_starts``) and evaluations to 4 episodes. Doctest-style blocks (``>>>``)
are output shown to the reader, not run.
"""

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
MAX_STEPS = 26_000


def python_blocks(page: Path) -> list[str]:
    """The page's ``.. code-block:: python`` bodies, dedented, in order."""
    lines = page.read_text().splitlines()
    blocks, i = [], 0
    while i < len(lines):
        match = re.match(r"^(\s*)\.\. code-block:: python\s*$", lines[i])
        i += 1
        if not match:
            continue
        indent, body = len(match.group(1)), []
        while i < len(lines) and (not lines[i].strip() or len(lines[i]) - len(lines[i].lstrip()) > indent):
            body.append(lines[i])
            i += 1
        block = textwrap.dedent("\n".join(body)).strip("\n")
        if not block.startswith(">>>"):
            blocks.append(block)
    return blocks


def with_small_budgets(code: str) -> str:
    """The same code with training and evaluation budgets cut (see the module docstring)."""
    code = re.sub(r"total_timesteps=([\d_]+)", lambda m: f"total_timesteps={min(int(m.group(1)), MAX_STEPS)}", code)
    code = re.sub(r"\.learn\(([\d_]+)", lambda m: f".learn({min(int(m.group(1)), MAX_STEPS)}", code)
    return re.sub(r"n_episodes=\d+", "n_episodes=4", code)


PAGES = sorted(page for page in DOCS.rglob("*.rst") if "_build" not in page.parts and python_blocks(page))


def test_snippet_pages_are_found_and_budgets_are_cut() -> None:
    names = {page.name for page in PAGES}
    assert {"quickstart.rst", "selection.rst", "sharing.rst", "learned_selection.rst", "index.rst"} <= names
    assert with_small_budgets("model.learn(1_000_000); model.learn(total_timesteps=300_000)") == (
        f"model.learn({MAX_STEPS}); model.learn(total_timesteps={MAX_STEPS})"
    )


@pytest.mark.slow
@pytest.mark.parametrize("page", PAGES, ids=lambda page: str(page.relative_to(DOCS)))
def test_page_snippets_run(page: Path, tmp_path: Path) -> None:
    code = with_small_budgets("\n\n".join(python_blocks(page)))
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "MPLBACKEND": "Agg"}
    env.setdefault("OMP_NUM_THREADS", "1")
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600, check=False
    )
    assert result.returncode == 0, f"{page.name}'s snippets failed:\n{result.stdout[-2000:]}\n{result.stderr[-4000:]}"
