"""How to install one of the package's extras, in the form that fits how the package itself was installed."""

import importlib.metadata
import json
from urllib.parse import unquote, urlparse

DISTRIBUTION = "sb3_maddpg"


def editable_checkout() -> str | None:
    """
    :return: The checkout's directory if the package was installed editable (``pip install -e .``), else ``None``.
    """
    # The installed metadata, not a checkout's build-time egg-info that a run from the checkout sees first.
    texts = [dist.read_text("direct_url.json") for dist in importlib.metadata.distributions(name=DISTRIBUTION)]
    text = next((text for text in texts if text), None)
    if text is None:
        return None
    try:
        direct_url = json.loads(text)
    except ValueError:
        return None
    if not direct_url.get("dir_info", {}).get("editable"):
        return None
    url = urlparse(direct_url.get("url", ""))
    return unquote(url.path) if url.scheme == "file" else None


def extra_install_command(extra: str) -> str:
    """
    :param extra: An extra of the package, e.g. ``"experiments"``.
    :return: The pip command that installs it: ``pip install -e "<checkout>[extra]"`` for an editable install (run
        from anywhere), ``pip install "sb3-maddpg[extra]"`` otherwise.
    """
    checkout = editable_checkout()
    if checkout is not None:
        return f'pip install -e "{checkout}[{extra}]"'
    return f'pip install "sb3-maddpg[{extra}]"'
