"""What a command imports (issue 45): a run imports neither run groups, the report nor Ray's code; a report imports
no run group. Each in a fresh interpreter, as a user's command runs."""

import json
import subprocess
import sys
from pathlib import Path

LISTED = """
import json, sys
from sb3_maddpg.cli.main import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
print(json.dumps(sorted(m for m in sys.modules if m.startswith("sb3_maddpg"))))
"""


def modules_imported(*args: str) -> list[str]:
    """:return: The package's modules imported by ``sb3-maddpg <args>`` in a fresh interpreter."""
    done = subprocess.run([sys.executable, "-c", LISTED, *args], capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def test_a_dry_run_imports_no_run_group_report_or_ray_code(tmp_path: Path) -> None:
    imported = modules_imported("run", "--config", "exp1", "--seeds", "[0]", "--dry-run", "--results", str(tmp_path))
    assert "sb3_maddpg.experiments.runner" in imported  # the run's own code is there
    heavy_modules = ("run_group", "results", "experiments.ray_tasks", "tuning")
    for heavy in (f"sb3_maddpg.{name}" for name in heavy_modules):
        assert heavy not in imported, heavy


def test_importing_the_experiments_package_imports_no_run_group_ray_or_report_code() -> None:
    code = "import json, sys, sb3_maddpg.experiments as e; print(json.dumps(sorted(sys.modules)))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    imported = json.loads(done.stdout.strip().splitlines()[-1])
    assert "sb3_maddpg.experiments.sweep" in imported  # its public names are there
    for heavy in ("sb3_maddpg.run_group", "sb3_maddpg.results", "sb3_maddpg.experiments.ray_tasks", "ray", "matplotlib"):
        assert heavy not in imported, heavy
