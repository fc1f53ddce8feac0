"""Mitsuba's scene-loading errors made readable: the file and line they name, the message without
its parser prefix or a Python plugin's traceback (docs/design.md section 8: one clear message)."""
from __future__ import annotations

import re
from pathlib import Path

__all__ = ["mitsuba_message", "located", "parameter_line"]


def mitsuba_message(exc: Exception) -> str:
    """The message of a Mitsuba loading error without its source prefix and Python traceback frames,
    led by ``FILE, line N:`` when it names a place in a file (see :func:`located`)."""
    file, line, message = located(exc)
    return message if file is None else f"{file}, line {line}: {message}"


#: Where Mitsuba's scene parser says an error happened: ``At FILE (line N, col M): ...`` (a plugin's
#: constructor failed) or ``Error while loading FILE (line N, col M): ...`` (a malformed value).
_MITSUBA_AT = re.compile(r"^(?:At|Error while loading) (?P<file>.+?) \(line (?P<line>\d+), col \d+\): (?P<rest>.*)$",
                         re.S)
#: ``Parsing of XML file "FILE" failed: MESSAGE (line N, col M)``: malformed XML.
_MITSUBA_XML = re.compile(r'^Parsing of XML file "(?P<file>.*?)" failed: (?P<rest>.*) \(line (?P<line>\d+), col \d+\)$',
                          re.S)
#: The plugin that failed: ``failed to instantiate sensor plugin of type "sar": ...``.
_MITSUBA_PLUGIN = re.compile(r'^failed to instantiate (?P<tag>\w+) plugin of type "[^"]*": (?P<rest>.*)$', re.S)
#: The parameter an error message names: ``name = value ...``, ``unknown parameter 'name'``, ``parameter name:``.
_NAMED_PARAMETER = re.compile(r"^(?P<a>\w+) = |unknown parameter '(?P<b>\w+)'|parameter (?P<c>\w+):")


def located(exc: Exception) -> tuple[str | None, int | None, str]:
    """``(file, line, message)`` of a Mitsuba loading error (file and line None when it names none).

    The message drops Mitsuba's ``[parser.cpp:1718]`` prefix, its ``At FILE (line, col)`` and
    "failed to instantiate" framing, and the traceback of a Python plugin (frames and the
    exception's class name). The line is that of the offending parameter's element when the
    message names one that the failing plugin's element sets (``<float name="frequency" .../>``),
    else the plugin's element."""
    text = re.sub(r"^\[[\w.]+:\d+\]\s*", "", str(exc).strip())
    file = line = tag = None
    while (match := _MITSUBA_AT.match(text) or _MITSUBA_XML.match(text)) is not None:
        file, line, text = match["file"], int(match["line"]), match["rest"].strip()
        plugin = _MITSUBA_PLUGIN.match(text)
        if plugin is not None:
            tag, text = plugin["tag"], plugin["rest"].strip()
    message = _without_traceback(text)
    named = _NAMED_PARAMETER.search(message)
    if file is not None and line is not None and tag is not None and named is not None:
        line = parameter_line(file, line, tag, named["a"] or named["b"] or named["c"])
    return file, line, message


def _without_traceback(text: str) -> str:
    """The exception message at the end of a Python traceback (frames and, for sarmitsuba's own
    errors, the class name dropped); ``text`` itself when it holds no traceback."""
    if "Traceback (most recent call last)" not in text:
        return text
    lines = text.splitlines()
    frames = [i for i, line in enumerate(lines) if line.startswith("  File ")]
    i = frames[-1] + 1 if frames else 1
    while i < len(lines) - 1 and lines[i].startswith("    "):       # source lines and carets of the last frame
        i += 1
    message = "\n".join(lines[i:]).strip()
    return re.sub(r"^(?:\w+\.)*(?:ParameterError|SceneError|MaterialError|ValueError): ", "", message)


def parameter_line(file: str, line: int, tag: str, name: str) -> int:
    """Line of the first element ``name="NAME"`` from the plugin element ``<TAG`` on ``line`` to its
    closing tag; ``line`` when there is none (a default or derived value) or the file is unreadable."""
    try:
        lines = Path(file).read_text(errors="replace").splitlines()
    except OSError:
        return line
    pattern = re.compile(rf"""name\s*=\s*["']{re.escape(name)}["']""")
    for number in range(line, len(lines) + 1):
        if pattern.search(lines[number - 1]):
            return number
        if f"</{tag}" in lines[number - 1] or (number > line and re.search(rf"<{tag}\b", lines[number - 1])):
            break
    return line
