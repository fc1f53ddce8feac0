"""docs/physics.md as a page of the manual: every labelled paragraph has an anchor, the labels are
unique, each display equation's ``\\tag`` is its paragraph's label, and every label the code cites
exists (docs/_ext/physicslabels.py makes the anchors and links the docstrings' citations to them).
Reads the Markdown and the sources only; tests/test_manual.py builds the manual."""
from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))

import physicslabels as pl  # noqa: E402

TEXT = pl.PHYSICS_MD.read_text(encoding="utf-8")

#: Tags of equations inside another label's paragraph (besides the primed variants, ``(M1')`` in
#: ``(M1)``): the PEC dihedral's matrix in (P5).
EXTRA_TAGS = {"PEC": "P5"}
#: Citations in the code of labels the page does not have: (file, label). Each must still be cited
#: there (remove the entry once the code is fixed).
STALE: set[tuple[str, str]] = set()


def test_every_labelled_paragraph_has_an_anchor():
    heads = pl.heads(TEXT)
    assert len(heads) > 80
    out = pl.with_targets(TEXT).splitlines()
    shift = 0
    for h in pl.targets(TEXT):
        line = h["line"] + shift
        if h["item"]:
            assert out[line] == f"{h['item']}({h['anchor']})=", out[line]
            assert out[line + 1].lstrip().startswith(f"**({h['label']})")
        else:
            assert out[line] == f"({h['anchor']})=", out[line]
        shift += 1
        assert re.fullmatch(r"eq-[a-z0-9]+(p)?(-[a-z]+)?", h["anchor"]), h["anchor"]
    assert pl.anchor("M1'") == "eq-m1p" and pl.anchor("M5") == "eq-m5"


def test_labels_and_anchors_are_unique():
    seen: dict[str, list[str]] = {}
    for h in pl.heads(TEXT):
        seen.setdefault(h["label"], []).append(h["section"])
    for label, sections in seen.items():
        assert len(sections) == len(set(sections)), f"({label}) heads two paragraphs of one section"
    assert {label for label, sections in seen.items() if len(sections) > 1} == set()
    anchors = [t["anchor"] for t in pl.targets(TEXT)]
    assert len(anchors) == len(set(anchors))


def test_each_display_equation_is_tagged_with_its_paragraphs_label():
    equations = pl.equations(TEXT)
    assert len(equations) > 50
    tags = [tag for eq in equations for tag in eq["tags"]]
    assert len(tags) == len(set(tags)), "a tag on two equations"
    for eq in equations:
        assert len(eq["tags"]) <= 1, eq
        for tag in eq["tags"]:
            own = tag in (eq["head"], f"{eq['head']}'") or EXTRA_TAGS.get(tag) == eq["head"]
            assert own, f"\\tag{{{tag}}} (line {eq['line'] + 1}) in the paragraph of ({eq['head']})"
    # no display equation is left as an indented plain-text line ending with its label
    plain = [line for line in TEXT.splitlines() if re.match(r"^ {4}\S.*\(" + pl.LABEL + r"\)\s*$", line)]
    assert not plain, plain[:3]
    # every $$ block is closed
    assert sum(line.strip() == "$$" for line in TEXT.splitlines()) == 2 * len(equations)


def _labels() -> set[str]:
    return {t["label"] for t in pl.targets(TEXT)}


def cited(source: str, labels: set[str]) -> set[str]:
    """The labels a source cites: ``(M5)``, ``(P3')``, ``(F1)-(F9)`` (letters of a page label's
    prefix, then digits), and the bare ones (``(R)``, ``(PGA)``) after ``Eq.``, ``eq.`` or
    ``physics.md``."""
    prefixes = {re.match(r"[A-Z]+", label)[0] for label in labels}
    found = set()
    for m in re.finditer(r"\(([A-Z]{1,3})([0-9]{1,2}'?)\)", source):
        if m[1] in prefixes:
            found.add(m[1] + m[2])
    for m in re.finditer(r"(?:\b[Ee]qs?\.|physics\.md)\s*\(([A-Z]{1,4}'?)\)", source):
        found.add(m[1])
    return found


def test_every_label_the_code_cites_exists():
    labels = _labels()
    missing, stale_seen = [], set()
    for path in sorted((ROOT / "sarmitsuba").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        for label in cited(path.read_text(encoding="utf-8"), labels) - labels:
            if (rel, label) in STALE:
                stale_seen.add((rel, label))
            else:
                missing.append(f"{rel}: ({label})")
    assert not missing, f"labels cited in the code but not in docs/physics.md: {missing}"
    assert stale_seen == STALE, f"fixed in the code, drop from STALE: {STALE - stale_seen}"


def test_a_wrong_label_fails_the_citation_check():
    labels = _labels()
    source = "# the pulse's phase (docs/physics.md (S1), Eq. (M55), (PO9)-(PO1)); eq. (Q) and (ZZ1)"
    assert cited(source, labels) - labels == {"M55", "PO9", "Q"}


def test_docstring_citations_link_to_the_anchors():
    table = pl.label_table(TEXT)
    link = lambda text, module="sarmitsuba.tracing.mesh": pl.link_citations([text], table, module)[0]  # noqa: E731
    assert link("exact (docs/physics.md (M5)).") == "exact (docs/physics.md :ref:`(M5) <eq-m5>`)."
    assert link("Eq. (M1'), (F1)-(F9)", "sarmitsuba.focus.ffbp") == (
        "Eq. :ref:`(M1') <eq-m1p>`, :ref:`(F1) <eq-f1>`-:ref:`(F9) <eq-f9>`")
    assert link("(GEO1) local frame", "sarmitsuba.formats.cphd") == ":ref:`(GEO1) <eq-geo1>` local frame"
    for text in ("``(M5)`` and `(M5)` and :math:`(M5)`", "f(A) and (M99) and (T6)", "x(M5)y"):
        assert link(text) == text
    block = ["Example::", "", "    (M5) in a literal block", "", "after (C)"]
    assert pl.link_citations(block, table, "m") == block[:4] + ["after :ref:`(C) <eq-c>`"]
    assert pl.link_citations([">>> f(1)  # (M5)"], table, "m") == [">>> f(1)  # (M5)"]


def test_mathjax_is_served_with_the_manual():
    conf = (ROOT / "docs" / "conf.py").read_text(encoding="utf-8")
    assert '"sphinx-mathjax-offline"' in conf and "http" not in conf.split("# Math:")[1]
    offline = pytest.importorskip("sphinx-mathjax-offline")
    static = Path(importlib.import_module(offline.__name__).__file__).parent / "static" / "mathjax"
    assert (static / "tex-chtml.js").is_file()
    assert any((static / "output" / "chtml" / "fonts" / "woff-v2").glob("*.woff"))
