"""Sphinx configuration of the sarmitsuba manual (``make docs``: HTML in docs/_build/html, warnings
are errors). Pages are Markdown (MyST); the API reference is generated from the numpydoc
docstrings (autodoc, autosummary, numpydoc)."""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

import sarmitsuba  # noqa: E402,F401  (finds libLLVM before the plugins' pages import drjit)

project = "sarmitsuba"
author = "the sarmitsuba developers"
copyright = "the sarmitsuba developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "pluginparameters",          # docs/_ext: the plugins' parameter tables
    "benchtables",               # docs/_ext: the benchmark pages' tables, read from docs/benchmarks/data
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"

# MyST: $...$ and $$...$$ math, heading anchors for the equation paragraphs' links
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# the module pages (docs/_templates/autosummary/module.rst) list each module's ``__all__`` through
# autodoc and recurse into its public submodules
templates_path = ["_templates"]
autosummary_generate = True
# modules whose package attribute of the same name is a function (``sarmitsuba.focus.ffbp``):
# autosummary would import the function, so their package's page documents them instead
autosummary_context = {"shadowed": ["sarmitsuba.focus.ffbp"]}
exclude_patterns = ["_build", "figures", "api/generated/sarmitsuba.focus.ffbp.rst"]   # the stub of the function
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_validation_checks = set()
# numpydoc renames a References section's labels per object; those a docstring does not cite in
# its text would each warn
suppress_warnings = ["ref.citation"]

html_theme = "pydata_sphinx_theme"
html_title = "sarmitsuba"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
html_static_path: list[str] = []
