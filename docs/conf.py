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
import warnings  # noqa: E402

# the gallery's scripts print their warnings as the command line does ("warning: ..."), without the
# file and line of the build machine's checkout
warnings.formatwarning = lambda message, category, *args, **kwargs: f"warning: {message}\n"

project = "sarmitsuba"
author = "the sarmitsuba developers"
copyright = "the sarmitsuba developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "pluginparameters",          # docs/_ext: the plugins' parameter tables
    "docstringcheck",            # docs/_ext: a public callable without a docstring is a warning
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
# a numpydoc section of an unknown name or out of order is a warning (GL06, GL07); docs/_ext/docstringcheck
# makes a public callable without a docstring one
numpydoc_validation_checks = {"GL06", "GL07"}
# numpydoc renames a References section's labels per object; those a docstring does not cite in
# its text would each warn
suppress_warnings = ["ref.citation"]

html_theme = "pydata_sphinx_theme"
html_title = "sarmitsuba"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2, "header_links_before_dropdown": 6,
                      "collapse_navigation": True}    # the sidebar lists a section's own pages, not every page of the API
# the front page shows the whole table of contents in its sidebar (the theme gives a section's
# pages their own navigation there, and the front page none)
html_sidebars = {"index": ["globaltoc.html"], "getting-started": [], "reading-sar-images": [], "physics": [],
                 "plugins": [], "design": []}        # single pages: no section navigation to show
# light mode unless the reader chooses (the theme's first page load otherwise logs an empty mode as
# an error), and an icon of the urban image, so that browsers do not ask the server for favicon.ico
html_context = {"default_mode": "light"}
html_favicon = "img/favicon.png"
html_static_path: list[str] = []

# Math: MathJax 3 served from the built manual itself (sphinx-mathjax-offline bundles MathJax 3.2
# and copies it to _static/mathjax), so equations display without network access; MyST's
# $$...$$ blocks with \tag{..} carry docs/physics.md's labels. docs/_ext/physicslabels.py gives
# each labelled paragraph of physics.md an anchor (physics.html#eq-m5, {ref}`eq-m5`) and links
# the labels that docstrings cite to it.
extensions += ["sphinx.ext.mathjax", "sphinx-mathjax-offline", "physicslabels"]
mathjax3_config = {"tex": {"tags": "none"}}

# sphinx-gallery: docs/examples/plot_*.py are run during the build and become docs/gallery/ (not
# committed), one page per example with its figures and its run time; ``-D plot_gallery=0`` builds
# the pages without running them
extensions.append("sphinx_gallery.gen_gallery")
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "gallery",
    "filename_pattern": r"/plot_",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "show_memory": False,
    # each example page gives its own run time; the summary pages would load DataTables from a CDN
    "write_computation_times": False,
}
exclude_patterns.append("examples")        # the scripts' folder: its header becomes gallery/index
