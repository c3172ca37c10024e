"""The README's Python snippets run after its install command: only the base install's packages, and they work."""

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()
SNIPPETS = re.findall(r"```python\n(.*?)```", README, flags=re.DOTALL)

# Top-level modules of the base install (setup.cfg's install_requires and what they pull in).
BASE_MODULES = {"sb3_maddpg", "stable_baselines3", "gymnasium", "pettingzoo", "mpe2", "supersuit", "torch", "scipy", "numpy"}
BASE_MODULES |= set(sys.stdlib_module_names)


def imported_modules(code: str) -> set[str]:
    tree = ast.parse(code)
    names = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    names |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module}
    return {name.split(".")[0] for name in names}


def test_readme_snippets_need_only_the_base_install() -> None:
    assert SNIPPETS, "the README has Python snippets"
    for snippet in SNIPPETS:
        extra = imported_modules(snippet) - BASE_MODULES
        assert not extra, f"a README snippet imports {extra}, which the README's install command does not install"
        # progress_bar=True needs tqdm and rich (the experiments extra).
        assert "progress_bar=True" not in snippet


@pytest.mark.slow
def test_readme_snippets_run(tmp_path: Path) -> None:
    for snippet in SNIPPETS:
        # The same code at a test's budget: a run past learning_starts, an evaluation of 4 episodes.
        code = snippet.replace("total_timesteps=1_000_000", "total_timesteps=27_000").replace("n_episodes=100", "n_episodes=4")
        env = {**os.environ, "SDL_VIDEODRIVER": "dummy", "OMP_NUM_THREADS": "1"}
        result = subprocess.run(
            [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600, check=False
        )
        assert result.returncode == 0, f"README snippet failed:\n{code}\n{result.stdout[-2000:]}\n{result.stderr[-4000:]}"
