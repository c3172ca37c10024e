"""Sphinx configuration for the sb3-maddpg documentation.

Build with ``python -m sphinx -W --keep-going -b html docs docs/_build/html`` (or ``make doc``).
"""

import os
import sys
import warnings
from pathlib import Path

DOCS_DIR = Path(__file__).resolve().parent
ROOT_DIR = DOCS_DIR.parent
sys.path.insert(0, str(ROOT_DIR))
sys.path.insert(0, str(DOCS_DIR / "_ext"))

# Headless: mpe2 imports pygame, which must not try to open a display or an audio device.
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

from sb3_maddpg.version import __version__  # noqa: E402

project = "sb3-maddpg"
author = "sb3-maddpg contributors"
copyright = "2026, sb3-maddpg contributors"
version = __version__
release = __version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "sphinx_autodoc_typehints",
    "sphinx_rtd_theme",
    "sb3_maddpg_docs",
]

templates_path: list[str] = []
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "_static/paper_small/*.rst"]
source_suffix = {".rst": "restructuredtext"}
master_doc = "index"
language = "en"
pygments_style = "sphinx"

# Autodoc: the public API, in source order, with SB3's ``:param:`` docstrings.
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_mock_imports: list[str] = []
autoclass_content = "class"
typehints_fully_qualified = False
always_document_param_types = False
typehints_document_rtype = True
set_type_checking_flag = False

intersphinx_mapping = {
    "python": ("https://docs.python.org/3", None),
    "numpy": ("https://numpy.org/doc/stable/", None),
    "torch": ("https://pytorch.org/docs/stable/", None),
    "gymnasium": ("https://gymnasium.farama.org/", None),
    "sb3": ("https://stable-baselines3.readthedocs.io/en/master/", None),
}
# CI has no network: cross-project links are opt-in, so an unreachable inventory never fails a ``-W`` build.
if os.environ.get("SB3_MADDPG_DOCS_INTERSPHINX") != "1":
    intersphinx_mapping = {}
nitpicky = False
# SB3's ``MaybeCallback`` alias names ``BaseCallback`` as a string that cannot be resolved from our modules.
suppress_warnings = ["config.cache", "sphinx_autodoc_typehints.forward_reference"]
# A deprecation inside sphinx-autodoc-typehints itself (a Python warning, not a Sphinx one): keep the log readable.
warnings.filterwarnings("ignore", message=".*set_application.*is deprecated", category=DeprecationWarning)
warnings.filterwarnings("ignore", message=".*set_application.*is deprecated", category=PendingDeprecationWarning)

html_theme = "sphinx_rtd_theme"
html_theme_options = {"navigation_depth": 3, "collapse_navigation": False}
html_static_path = ["_static"]
html_css_files = ["css/custom.css"]
html_title = f"sb3-maddpg {release}"
html_show_sourcelink = True
