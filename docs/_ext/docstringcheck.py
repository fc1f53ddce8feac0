"""Sphinx extension: a public function, class, method or property without a docstring of its own
is a warning (so ``make docs``, whose warnings are errors, fails on it).

numpydoc's validation (``numpydoc_validation_checks`` in conf.py) reports malformed sections; this
hook reports the missing docstrings of callables only, since data attributes are described by
their class's docstring or a ``#:`` comment, which numpydoc does not see.
"""
from __future__ import annotations

from sphinx.util import logging

logger = logging.getLogger(__name__)

#: the kinds of object autodoc documents whose docstring must be their own
CHECKED = {"function", "class", "method", "property", "exception"}


def _check(app, what, name, obj, options, lines) -> None:
    if what not in CHECKED or name.rsplit(".", 1)[-1].startswith("_"):
        return
    own = getattr(getattr(obj, "fget", obj), "__doc__", None)
    if not "".join(lines).strip() or not (own or "").strip():
        logger.warning("public %s %s has no docstring; the API reference needs one", what, name,
                       type="sarmitsuba", subtype="docstring")


def setup(app):
    """Register the hook."""
    app.connect("autodoc-process-docstring", _check)
    return {"parallel_read_safe": True, "version": "1"}
