"""The user documentation states what is true now: no issue numbers and no project history in
the README, the manual's pages, the gallery's scripts or the docstrings the API reference shows."""
from __future__ import annotations

import inspect
import re
from pathlib import Path

from test_docstrings import _public_modules, public_objects     # tests/ is on sys.path (conftest.py)

ROOT = Path(__file__).resolve().parents[1]

#: phrases that tell the project's history instead of the software's behaviour
HISTORY = re.compile(
    r"\bissues? *#? *\d+|\bissue #|\b(last|this|previous) (stop|session)\b|\bused to (be|give|take)\b"
    r"|\bno longer (the default|needed|used)\b|\bwas the default\b|\bbefore the (mesh|wideband|ray-tube|tube)\b"
    r"|\bmeasured for (the )?issue\b|\bin an earlier version\b", re.IGNORECASE)


def _pages() -> list[Path]:
    docs = ROOT / "docs"
    pages = [ROOT / "README.md"] + sorted(docs.rglob("*.md")) + sorted(docs.rglob("*.rst"))
    pages += sorted((docs / "examples").rglob("*.py")) if (docs / "examples").is_dir() else []
    skipped = ("_build", "generated", "gallery")
    return [p for p in pages if not set(skipped).intersection(p.relative_to(ROOT).parts)]


def history_in(text: str) -> list[str]:
    """The history phrases in ``text``, each with a few words around it."""
    return [text[max(m.start() - 40, 0):m.end() + 20].replace("\n", " ") for m in HISTORY.finditer(text)]


def test_the_pattern_finds_history_and_passes_behaviour():
    assert history_in("measured for issue 56 on urban")
    assert history_in("the tracer before the mesh tracer")
    assert history_in("Tiles are no longer the default.")
    assert not history_in("a segment no longer than a patch")
    assert history_in("as decided in the last stop")
    assert not history_in("the issue of a square root's branch; 56 issues of a journal")
    assert not history_in("the RCS of a plate of side 0.3 m, 20 dB above the noise")


def test_pages_and_examples_have_no_issue_numbers_or_history():
    found = {str(p.relative_to(ROOT)): history_in(p.read_text(encoding="utf-8")) for p in _pages()}
    found = {page: hits for page, hits in found.items() if hits}
    assert not found, found


def test_docstrings_have_no_issue_numbers_or_history():
    found = {}
    for module in _public_modules():
        hits = history_in(module.__doc__ or "")
        if hits:
            found[module.__name__] = hits
    for name, obj in public_objects().items():
        texts = [obj.__doc__ or ""]
        if inspect.isclass(obj):
            texts += [member.__doc__ or "" for member in vars(obj).values() if callable(member)]
        hits = [hit for text in texts for hit in history_in(text)]
        if hits:
            found[name] = hits
    assert not found, found
