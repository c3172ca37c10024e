"""Migrate the committed results' stored configs to 0.3.0's format, once (issue 58, item 3).

0.3.0 is the first version of sb3-maddpg whose saves and stored configs are read: 0.1 and 0.2 were never released,
and 0.3 drops their readers. The results committed under ``benchmarks/*/results`` were written by them or by 0.3's
development versions before the version was written (no ``sb3_maddpg_version``). This script gives each such
``config.json`` and ``experiment.json`` what the reader of those versions (``sb3_maddpg.compat.migrate_stored_config``
at this commit) gave it when read:

- the values its version ran with for what it lacks (``vec_env="mpe2"``, ``n_envs=1``: runs before 0.2 stepped one
  mpe2 env each);
- 0.3's names for the renamed ``model_kwargs`` (``selection`` -> ``selector``), in ``scheme_model_kwargs`` too;
- ``sb3_maddpg_version``: the version that now reads it (the installed one, 0.3.0.dev0). Not ``sb3_maddpg_commit``:
  the migrating commit did not make the run.

Each file keeps its keys in their order (a renamed key where it was, added keys at the end) and its format (JSON
indented by 2, as ``write_json_atomic`` writes it). A file that holds a version is left alone, and so are the runs in
progress of ``paper_n5i_exp1`` (seeds 5-9, written by a running sweep). Every migrated file is checked to read back
as the same config as before through the reader of this commit.

Run once from the repository root (``python benchmarks/migrate_stored_configs.py``), then removed with the files it
migrated.
"""

import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

from sb3_maddpg.compat import migrate_stored_config
from sb3_maddpg.experiments.results import write_json_atomic
from sb3_maddpg.experiments.setting import ExperimentConfig, RunConfig
from sb3_maddpg.version import __version__

VERSION_KEY = "sb3_maddpg_version"
STORED_BEFORE_0_2 = {"vec_env": "mpe2", "n_envs": 1}
RENAMED_IN_0_3 = {"selection": "selector"}
IN_PROGRESS = re.compile(r"^benchmarks/paper_n5_independent/results/paper_n5i_exp1/[^/]+/seed_00[5-9]/")
STORED = ("benchmarks/*/results/**/config.json", "benchmarks/*/results/**/experiment.json")


def renamed(kwargs: dict[str, Any]) -> dict[str, Any]:
    """:return: ``kwargs`` with 0.3's names for the renamed ones, each where the old one was (the new name wins)."""
    out = {}
    for key, value in kwargs.items():
        new = RENAMED_IN_0_3.get(key)
        if new is None:
            out[key] = value
        elif new not in kwargs:
            out[new] = value
    return out


def migrated(stored: dict[str, Any]) -> dict[str, Any]:
    """:return: A stored config written without a version, as 0.3.0's format holds it."""
    fields = dict(stored)
    if isinstance(fields.get("model_kwargs"), dict):
        fields["model_kwargs"] = renamed(fields["model_kwargs"])
    if isinstance(fields.get("scheme_model_kwargs"), dict):
        fields["scheme_model_kwargs"] = {
            scheme: renamed(kwargs) if isinstance(kwargs, dict) else kwargs
            for scheme, kwargs in fields["scheme_model_kwargs"].items()
        }
    for key, value in STORED_BEFORE_0_2.items():
        fields.setdefault(key, value)
    fields[VERSION_KEY] = __version__
    return fields


def main() -> int:
    root = Path(__file__).resolve().parents[1]
    listed = subprocess.run(["git", "ls-files", *STORED], cwd=root, capture_output=True, text=True, check=True).stdout
    paths = [path for path in listed.split() if not IN_PROGRESS.match(path)]
    changed = 0
    for path in paths:
        file = root / path
        text = file.read_text()
        stored = json.loads(text)
        assert json.dumps(stored, indent=2) == text, f"{path} is not as write_json_atomic writes"
        if VERSION_KEY in stored:
            continue
        new = migrated(stored)
        config_type = RunConfig if file.name == "config.json" else ExperimentConfig
        assert migrate_stored_config(new, path) == migrate_stored_config(stored, path), path
        assert config_type.from_dict(new) == config_type.from_dict(stored), path
        write_json_atomic(file, new)
        assert json.loads(file.read_text()) == new and list(json.loads(file.read_text())) == list(new), path
        changed += 1
    print(f"{changed} of {len(paths)} stored configs migrated to {__version__}'s format")
    return 0


if __name__ == "__main__":
    sys.exit(main())
