"""Sphinx configuration of the polyenvs documentation (MyST Markdown, the furo theme).

Build it from the repository root (README, "Documentation")::

    MUJOCO_GL=egl python -m sphinx -W --keep-going -b html docs docs/_build/html

The environment pages, their gallery and the BibTeX of ``CITATION.cff`` are generated at build time
(``_ext/polyenvs_pages.py``, ``_ext/polyenvs_bibtex.py``); nothing reaches the network:
``linkcheck`` checks the internal links and skips every external URL.
"""

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS.parent))  # the checkout's polyenvs and baselines, also without an install
sys.path.insert(0, str(DOCS / "_ext"))
os.environ.setdefault("MUJOCO_GL", "egl")  # the beasts' recordings render headless
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import polyenvs  # noqa: E402

project = "polyenvs"
author = "the polyenvs authors"
copyright = "2026, the polyenvs authors"
version = release = polyenvs.__version__

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "polyenvs_pages"]
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build", "_ext"]
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]

# The API reference documents modules that import the training stack; it builds without it.
autodoc_mock_imports = ["stable_baselines3", "sb3_contrib", "torch", "tensorboard", "ray", "yaml"]
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_typehints = "description"

html_theme = "furo"
html_title = f"polyenvs {release}"
html_static_path = ["_static"]
html_css_files = ["polyenvs.css"]  # the environment index's gallery

# linkcheck: internal links only (this project's machines reach no network).
linkcheck_ignore = [r"https?://.*"]
