"""The extras hint takes the form of the package's own install: editable from a checkout, or from the index."""

import json
from pathlib import Path

import pytest

from sb3_maddpg.common import install_hint


class _Distribution:
    def __init__(self, direct_url: dict | None) -> None:
        self.direct_url = direct_url

    def read_text(self, name: str) -> str | None:
        assert name == "direct_url.json"
        return None if self.direct_url is None else json.dumps(self.direct_url)


@pytest.mark.parametrize(
    ("direct_url", "command"),
    [
        (
            {"dir_info": {"editable": True}, "url": "file:///home/me/sb3%20maddpg"},
            'pip install -e "/home/me/sb3 maddpg[experiments]"',
        ),
        ({"dir_info": {}, "url": "file:///home/me/sb3-maddpg"}, 'pip install "sb3-maddpg[experiments]"'),  # pip install .
        (None, 'pip install "sb3-maddpg[experiments]"'),  # a wheel from the index
    ],
)
def test_extra_install_command_fits_the_install(monkeypatch: pytest.MonkeyPatch, direct_url, command: str) -> None:
    monkeypatch.setattr(install_hint.importlib.metadata, "distributions", lambda name: [_Distribution(direct_url)])
    assert install_hint.extra_install_command("experiments") == command


def test_editable_checkout_points_at_this_source_tree() -> None:
    # The test environment is the README's `pip install -e ".[dev]"`: the hint names this checkout.
    checkout = install_hint.editable_checkout()
    if checkout is None:
        pytest.skip("the package is not installed editable here")
    assert (Path(checkout) / "sb3_maddpg" / "common" / "install_hint.py").is_file()
