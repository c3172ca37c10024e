"""The suite turns the package's own warnings into errors (pyproject.toml's filterwarnings), so that a new, unexpected
one fails the test that triggers it; expected ones are asserted or filtered by name (tests/settings.py)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

PROBE = """
import warnings

import pytest

from sb3_maddpg.common.package_warnings import SB3MADDPGDeprecationWarning, SB3MADDPGWarning


def test_an_unexpected_package_warning():
    warnings.warn("a warning no test expects", SB3MADDPGWarning)


def test_an_unexpected_package_deprecation():
    warnings.warn("a name no test expects to go", SB3MADDPGDeprecationWarning)


def test_an_expected_package_warning():
    with pytest.warns(SB3MADDPGWarning, match="expected"):
        warnings.warn("an expected warning", SB3MADDPGWarning)


def test_another_library_s_warning():
    warnings.warn("not ours", UserWarning)
"""


def test_the_package_s_warnings_fail_the_test_that_did_not_expect_them(tmp_path: Path) -> None:
    probe = tmp_path / "test_probe.py"
    probe.write_text(PROBE)
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-rf",
            "-p",
            "no:cacheprovider",
            "-c",
            str(ROOT / "pyproject.toml"),
            str(probe),
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )
    failed = [line for line in done.stdout.splitlines() if line.startswith("FAILED")]
    assert len(failed) == 2, done.stdout
    assert "test_an_unexpected_package_warning" in failed[0] and "test_an_unexpected_package_deprecation" in failed[1]
    assert "2 failed, 2 passed" in done.stdout, done.stdout
