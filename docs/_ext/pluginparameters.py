"""The ``pluginparameters`` directive of the plugins' docstrings, as Mitsuba's manual writes it:
a list table of the plugin's parameters (name, type with its unit, what it does), rendered with a
header row. The directive's body is the rows of a ``list-table``.

Rows that name a setting of :data:`DEVELOPER_PARAMETERS` leave the user's table for a second one
under "For developers", after it: settings that check the fast kernels against their references
or help debugging, which a user leaves at their defaults.
"""
from __future__ import annotations

import re

from docutils import nodes
from docutils.parsers.rst.directives.tables import ListTable
from docutils.statemachine import StringList

#: Settings only a developer needs (``sbr`` integrator): each checks a fast path against its
#: reference and buys no accuracy (docs/guide/rendering.md, "For developers").
DEVELOPER_PARAMETERS = ("cancel_interior", "geometry")
#: What the developers' table is for, printed above it.
DEVELOPER_NOTE = ("Settings for checking the fast kernels against their references and for debugging: they buy "
                  "no accuracy, and a render leaves them at their defaults.")
_ROW = re.compile(r"^\s*\* - (?P<names>.*)$")


def split_rows(lines: list[str]) -> tuple[list[int], list[int]]:
    """The indices of ``lines`` (a ``pluginparameters`` body) in the user's rows and in the
    developers' rows. A row starts at a ``* - name[, name ...]`` line and runs to the next; it is
    the developers' when one of its names is in :data:`DEVELOPER_PARAMETERS`. Lines before the
    first row stay with the user's."""
    user, developer, target = [], [], None
    for index, line in enumerate(lines):
        match = _ROW.match(line)
        if match:
            names = {name.strip().strip("`") for name in match["names"].split(",")}
            target = developer if names & set(DEVELOPER_PARAMETERS) else user
        (target if target is not None else user).append(index)
    return user, developer


class PluginParameters(ListTable):
    """``.. pluginparameters::`` followed by ``* - name / - type / - description`` rows."""

    has_content = True
    required_arguments = 0
    optional_arguments = 0

    def _table(self, body: StringList) -> list:
        self.content = StringList(["* - Parameter", "  - Type", "  - Description"], source="pluginparameters") + body
        self.options = {"header-rows": 1, "widths": [18, 14, 68], "class": ["plugin-parameters"]}
        return super().run()

    def run(self):
        body = self.content
        user, developer = split_rows(list(body))
        out = self._table(StringList([body[i] for i in user], items=[body.items[i] for i in user]))
        if developer:
            out += [nodes.rubric(text="For developers"), nodes.paragraph(text=DEVELOPER_NOTE)]
            out += self._table(StringList([body[i] for i in developer], items=[body.items[i] for i in developer]))
        return out


def setup(app):
    app.add_directive("pluginparameters", PluginParameters)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
