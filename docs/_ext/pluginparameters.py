"""The ``pluginparameters`` directive of the plugins' docstrings, as Mitsuba's manual writes it:
a list table of the plugin's parameters (name, type with its unit, what it does), rendered with a
header row. The directive's body is the rows of a ``list-table``."""
from __future__ import annotations

from docutils.parsers.rst.directives.tables import ListTable
from docutils.statemachine import StringList


class PluginParameters(ListTable):
    """``.. pluginparameters::`` followed by ``* - name / - type / - description`` rows."""

    has_content = True
    required_arguments = 0
    optional_arguments = 0

    def run(self):
        header = StringList(["* - Parameter", "  - Type", "  - Description"], source="pluginparameters")
        self.content = header + self.content
        self.options = {"header-rows": 1, "widths": [18, 14, 68], "class": ["plugin-parameters"]}
        return super().run()


def setup(app):
    app.add_directive("pluginparameters", PluginParameters)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
