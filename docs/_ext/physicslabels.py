"""Anchors for the labelled paragraphs of docs/physics.md, and links to them from the docstrings.

docs/physics.md heads each paragraph of the model with its label in bold, ``**(M5) Integration:
...**`` (or a list item ``* **(D1) nearest**: ...``). While Sphinx reads the page, a MyST target
is put before each such paragraph, so that ``physics.html#eq-m5`` and ``{ref}`eq-m5``` reach it
from any page (the reference's text is the label, ``(M5)``). The anchor is ``eq-`` and the label in
lower case, a prime written ``p`` (``(M1')`` -> ``eq-m1p``). Labels are unique on the page
(tests/test_physics_page.py).

In the API reference, a docstring's citations of the page's labels, ``(M5)``, ``Eq. (M5)``,
``docs/physics.md (M5)`` or ``(F1)-(F9)``, become links to the anchors: only labels that the page
has, never inside literals, literal blocks, directives or doctests, and only where the reference
role stands between whitespace or punctuation (so it parses as inline markup).

``python docs/_ext/physicslabels.py`` prints the page's labels and their anchors.
"""
from __future__ import annotations

import functools
import re
from pathlib import Path

PAGE = "physics"
PHYSICS_MD = Path(__file__).resolve().parents[1] / "physics.md"

#: A labelled paragraph's head: ``**(LABEL) ...`` at the start of a line, or of a list item.
HEAD = re.compile(r"^(?P<item>[*-] )?\*\*\((?P<label>[A-Z][A-Za-z]*[0-9]*'?)\)")
#: The shape of a label (letters, then digits, then an optional prime).
LABEL = r"[A-Z][A-Za-z]*[0-9]*'?"

def anchor(label: str) -> str:
    """The HTML anchor of a label: ``M1'`` -> ``eq-m1p``."""
    return "eq-" + label.lower().replace("'", "p")


def _outside_code(text: str):
    """``(line number, line, section)`` of each line of the page outside fenced code blocks, with
    the ``##`` heading it stands under."""
    section, fenced = "", False
    for i, line in enumerate(text.splitlines()):
        if line.startswith("```"):
            fenced = not fenced
        if fenced:
            continue
        if line.startswith("## "):
            section = line[3:].strip()
        yield i, line, section


def heads(text: str) -> list[dict]:
    """The labelled paragraph heads of the page, in order: ``label``, ``line`` (0-based),
    ``item`` (a list item's marker or ''), ``section`` (its ``##`` heading) and ``anchor``."""
    return [{"label": m["label"], "line": i, "item": m["item"] or "", "section": section, "anchor": anchor(m["label"])}
            for i, line, section in _outside_code(text) if (m := HEAD.match(line))]


TAG = re.compile(r"\\tag\{(" + LABEL + r")\}")


def equations(text: str) -> list[dict]:
    """The page's display equations (``$$`` blocks), in order: ``line`` (0-based, of the opening
    ``$$``), ``tags`` (the labels of its ``\\tag{..}``), ``head`` (the label of the paragraph it
    belongs to: the last head before it) and ``section``."""
    found, open_line, tags, head = [], None, [], None
    head_lines = {h["line"]: h["label"] for h in heads(text)}
    for i, line, section in _outside_code(text):
        if line.startswith("## "):
            head = None
        if i in head_lines:
            head = head_lines[i]
        if line.strip() == "$$":
            if open_line is None:
                open_line, tags = i, []
            else:
                found.append({"line": open_line, "tags": tags, "head": head, "section": section})
                open_line = None
        elif open_line is not None:
            tags.extend(TAG.findall(line))
    return found


def targets(text: str) -> list[dict]:
    """Every anchor of the page: the paragraph heads' (``kind`` "head") and those of equation tags
    that head no paragraph (``kind`` "equation": ``(M1')`` in the paragraph of ``(M1)``), each
    with ``label``, ``line`` (where its target goes), ``item`` and ``anchor``."""
    found = [dict(h, kind="head") for h in heads(text)]
    labels = {h["label"] for h in found}
    for eq in equations(text):
        for tag in eq["tags"]:
            if tag not in labels:
                labels.add(tag)
                found.append({"label": tag, "line": eq["line"], "item": "", "section": eq["section"],
                              "anchor": anchor(tag), "kind": "equation"})
    return sorted(found, key=lambda t: t["line"])


def with_targets(text: str) -> str:
    """The page with a MyST target ``(anchor)=`` before each labelled paragraph (inside the list
    item for a list item's head) and before each equation whose tag heads no paragraph."""
    lines = text.splitlines(keepends=True)
    for h in reversed(targets(text)):
        i, item = h["line"], h["item"]
        if item:
            indent = " " * len(item)
            lines[i] = f"{item}({h['anchor']})=\n{indent}{lines[i][len(item):]}"
        else:
            lines[i] = f"({h['anchor']})=\n{lines[i]}"
    return "".join(lines)


def label_table(text: str) -> dict[str, str]:
    """label -> its anchor."""
    return {h["label"]: h["anchor"] for h in targets(text)}


# -- Sphinx: targets in the page ----------------------------------------------------------------

def _source_read(app, docname, source):
    if docname == PAGE:
        source[0] = with_targets(source[0])


def _doctree_read(app, doctree):
    """Give each anchor a title (its label), so that ``{ref}`eq-m5``` needs no explicit text; and
    display every tagged equation as it is written (Sphinx would put a multi-line one into a
    ``split`` environment, where MathJax refuses ``\\tag``)."""
    from docutils import nodes

    for node in doctree.findall(nodes.math_block):
        text = node.astext()
        if r"\tag{" in text and not node.get("nowrap"):
            node["nowrap"] = True
            node.children = [nodes.Text("\\[" + text + "\\]")]
    env = app.env
    if env.docname != PAGE:
        return
    std = env.domains.standard_domain
    for h in targets(Path(env.doc2path(PAGE)).read_text(encoding="utf-8")):
        name = h["anchor"]
        labelid = doctree.nameids.get(name)
        if labelid:
            std.anonlabels[name] = PAGE, labelid
            std.labels[name] = PAGE, labelid, f"({h['label']})"


# -- Sphinx: links from the docstrings ------------------------------------------------------------

#: ``(LABEL)``: the role covers the parenthesised label only (``Eq.`` or ``docs/physics.md`` before
#: it stay text).
CITE = re.compile(r"\((" + LABEL + r")\)")
#: A role may start after these (or a line's start) and end before these (or a line's end).
BEFORE = set(" \t([{<-/:'\"")
AFTER = set(" \t)]}>-/:;,.!?'\"\\")


def _link_plain(text: str, table, module: str) -> str:
    """Turn the citations in a stretch of plain rST text (no literals) into references."""
    out, pos = [], 0
    for m in CITE.finditer(text):
        label = m[1]
        target = table.get(label)
        if target is None:
            continue
        before = text[m.start() - 1] if m.start() > 0 else " "
        after = text[m.end()] if m.end() < len(text) else " "
        if before not in BEFORE or after not in AFTER:
            continue
        out.append(text[pos:m.start()])
        out.append(f":ref:`({label}) <{target}>`")
        pos = m.end()
    out.append(text[pos:])
    return "".join(out)


_LITERAL = re.compile(r"(``.*?``|`[^`]*`_{0,2}|:[\w:.-]+:`[^`]*`)")


def link_citations(lines: list[str], table, module: str) -> list[str]:
    """The docstring's lines with the page's labels linked; literals (``` ``x`` ```, any
    interpreted text or role), literal blocks after ``::``, directives' bodies and doctest lines
    are left alone, as is any line inside a literal that runs over several lines."""
    result, block_indent, open_literal = [], None, False
    for line in lines:
        stripped = line.lstrip()
        indent = len(line) - len(stripped)
        if block_indent is not None:
            if stripped and indent <= block_indent:
                block_indent = None
            else:
                result.append(line)
                continue
        if open_literal or not stripped or stripped.startswith((">>>", "...", ".. ")) or line.count("``") % 2:
            if line.count("``") % 2:
                open_literal = not open_literal
            if stripped.startswith(".. ") or line.rstrip().endswith("::"):
                block_indent = indent
            result.append(line)
            continue
        if line.count("`") % 2:            # a single-backquote literal or role across lines
            result.append(line)
            continue
        parts = _LITERAL.split(line)
        linked = "".join(p if i % 2 else _link_plain(p, table, module) for i, p in enumerate(parts))
        result.append(linked)
        if line.rstrip().endswith("::"):
            block_indent = indent
    return result


@functools.lru_cache(maxsize=4)
def _table(text: str):
    return label_table(text)


def _process_docstring(app, what, name, obj, options, lines):
    table = _table(PHYSICS_MD.read_text(encoding="utf-8"))
    module = getattr(obj, "__module__", None) or name
    if what == "module":
        module = name
    lines[:] = link_citations(list(lines), table, module)


def setup(app):
    app.connect("source-read", _source_read)
    app.connect("doctree-read", _doctree_read)
    # after numpydoc (priority 500) has rendered its sections into rST
    app.connect("autodoc-process-docstring", _process_docstring, priority=600)
    return {"parallel_read_safe": True, "parallel_write_safe": True}


if __name__ == "__main__":
    for h in targets(PHYSICS_MD.read_text(encoding="utf-8")):
        print(f"{h['line'] + 1:5d}  ({h['label']})  #{h['anchor']}  {h['kind']}")
