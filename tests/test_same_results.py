"""Short fixed-seed training runs give, bit for bit, the buffer, weights and optimiser states recorded before the
refactoring of issue 19, on this machine's CPU and library versions (see ``tests/same_results.py``)."""

import json

import pytest

from tests.same_results import CONFIGS, REFERENCE, recording_for, run, versions

RECORDINGS = json.loads(REFERENCE.read_text())["recordings"]


@pytest.mark.filterwarnings("ignore:critic_sharing='selected' with k=2")
@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_same_results_as_recorded(name: str) -> None:
    recorded = recording_for(RECORDINGS, versions())
    if recorded is None:
        pytest.skip(
            f"no recording for {versions()} (recorded: {[r['versions'] for r in RECORDINGS]}): bit-identity is not expected"
        )
    expected = recorded["runs"][name]
    actual = run(CONFIGS[name])
    differing = sorted(key for key in expected.keys() | actual.keys() if expected.get(key) != actual.get(key))
    assert not differing, f"{len(differing)} of {len(expected)} fingerprints differ, e.g. {differing[:8]}"
