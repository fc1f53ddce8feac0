"""Sphinx configuration of the sarmitsuba manual (``make docs``: HTML in docs/_build/html, warnings
are errors). Pages are Markdown (MyST); the API reference is generated from the numpydoc
docstrings (autodoc, autosummary, numpydoc)."""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

project = "sarmitsuba"
author = "the sarmitsuba developers"
copyright = "the sarmitsuba developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "figures", "api/generated/*.md"]

# MyST: $...$ and $$...$$ math, heading anchors for the equation paragraphs' links
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

autosummary_generate = True
autodoc_default_options = {"members": False}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_validation_checks = set()

html_theme = "pydata_sphinx_theme"
html_title = "sarmitsuba"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
html_static_path: list[str] = []
