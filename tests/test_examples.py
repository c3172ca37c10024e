"""Every example runs in its fast mode, and the docs' scheme figures match the code, so neither can rot."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted(path.name for path in (ROOT / "examples").glob("*.py"))


def _run(args: list[str], timeout: float) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.update(SB3_MADDPG_FAST="1", SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", MPLBACKEND="Agg")
    # Small networks on a shared CPU: one intra-op thread each is faster than contending for cores.
    env.setdefault("OMP_NUM_THREADS", "1")
    return subprocess.run(
        [sys.executable, *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout, check=False
    )


def test_examples_found() -> None:
    assert {"quickstart.py", "compare_schemes.py", "render_team.py"} <= set(EXAMPLES)


@pytest.mark.slow
@pytest.mark.parametrize("example", EXAMPLES)
def test_example_fast_mode(example: str) -> None:
    result = _run([str(ROOT / "examples" / example), "--fast"], timeout=300)
    assert result.returncode == 0, f"{example} --fast failed:\n{result.stdout[-3000:]}\n{result.stderr[-5000:]}"


def test_scheme_figures_match_code() -> None:
    result = _run([str(ROOT / "docs" / "make_figures.py"), "--check"], timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
