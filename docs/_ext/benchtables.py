"""Benchmark tables of the manual, read from the files the benchmark suite writes.

``.venv/bin/python -m sarmitsuba bench --out docs/benchmarks/data`` writes ``<name>.csv``, ``<name>.png``,
``checks.csv`` and ``machine.json`` there; the pages of docs/benchmarks/ show them through three
directives, so a rerun of the suite updates the pages:

``bench-table``
    A CSV file as a table (docutils' ``csv-table`` with the header row taken from the file).
    Options: ``:columns:`` the columns shown, in order, each ``name`` or ``name=Header``
    (default: all); ``:where:`` rows kept, ``column=value``, ``column!=value``, ``column~=text``
    (contains) or ``column!~=text``, several separated by ``;`` (all must hold);
    ``:digits:`` significant digits of long floating-point cells (default 4; cells of at most
    one digit more are shown as written); ``:ninf:`` the text of ``-inf`` (an NRMSE against
    itself; default ``reference``); plus ``:widths:``,
    ``:class:`` and the title argument of ``csv-table``.
``bench-run``
    The run that wrote a data folder: machine, packages, date, command, commit, and the seconds
    of the benchmarks named by ``:benchmarks:`` (default: all in ``machine.json``). The argument
    is the folder (relative to the page).
``bench-figure``
    ``figure`` of a benchmark's plot, or a note naming the command that writes it where the
    file does not exist yet.
``bench-checks``
    The suite's PASS/FAIL checks of the benchmarks named by ``:benchmarks:`` (default: all), from
    ``checks.csv`` in the folder given as the argument.

A file that does not exist renders as a note naming it and the command that writes it, and is a
warning (an error in ``make docs``).
"""
from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import directives
from docutils.parsers.rst.directives.images import Figure
from docutils.parsers.rst.directives.tables import CSVTable
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

logger = logging.getLogger(__name__)



def _format(cell: str, digits: int, ninf: str = "reference") -> str:
    """A CSV cell for display: long floats to ``digits`` significant digits (short ones as
    written), integers of five digits or more with thousands separators, ``-inf`` as ``ninf``."""
    text = cell.strip()
    if text == "":
        return ""
    try:
        value = float(text)
    except ValueError:
        return {"True": "yes", "False": "no"}.get(text, text)
    if math.isinf(value):
        return ninf if value < 0 else "∞"
    if math.isnan(value):
        return ""
    if text.lstrip("+-").isdigit():
        return f"{int(text):,}" if abs(int(text)) >= 10000 else text
    if value == int(value) and abs(value) >= 100:
        return f"{int(value):,}" if abs(value) >= 10000 else str(int(value))
    mantissa = text.lower().split("e")[0].lstrip("+-").replace(".", "").lstrip("0")
    if len(mantissa) <= digits + 1 and "e" not in text.lower():
        return text
    if abs(value) >= 10 ** digits:
        return f"{value:,.0f}"
    if abs(value) < 1e-4:
        return f"{value:.{digits}g}"
    decimals = max(0, digits - 1 - math.floor(math.log10(abs(value))))
    return f"{value:.{decimals}f}".rstrip("0").rstrip(".") if "." in f"{value:.{decimals}f}" else f"{value:.{decimals}f}"


def _note(what: str, path: Path) -> list[nodes.Node]:
    """A note in place of data not yet written: the file and the command that writes it. Also a
    warning, so that a manual built with warnings as errors has every page's data."""
    folder = path.parent.name
    logger.warning("benchmark %s %s does not exist", what, path, type="sarmitsuba", subtype="benchdata")
    command = f".venv/bin/python -m sarmitsuba bench{' --quick' if folder.startswith('quick') else ''} --out docs/benchmarks/data/{folder}"
    para = nodes.paragraph()
    para += nodes.Text(f"No {what} yet: {path.name} is written by ")
    para += nodes.literal(text=command)
    para += nodes.Text(" (add ")
    para += nodes.literal(text="--only NAME")
    para += nodes.Text(" to run one benchmark).")
    note = nodes.note()
    note += para
    return [note]


def _resolve(directive: SphinxDirective, name: str) -> Path:
    rel, absolute = directive.env.relfn2path(name, directive.env.docname)
    directive.env.note_dependency(rel)
    return Path(absolute)


class BenchTable(CSVTable):
    """``csv-table`` of a benchmark CSV with column selection, row filters and rounded floats."""

    required_arguments = 1          # the CSV file
    optional_arguments = 0
    final_argument_whitespace = False
    option_spec = {"columns": directives.unchanged, "where": directives.unchanged,
                   "digits": directives.nonnegative_int, "ninf": directives.unchanged, "widths": directives.value_or(("auto",),
                                                                                      directives.positive_int_list),
                   "class": directives.class_option, "name": directives.unchanged, "title": directives.unchanged}

    def run(self) -> list[nodes.Node]:
        env = self.state.document.settings.env
        rel, absolute = env.relfn2path(self.arguments[0], env.docname)
        env.note_dependency(rel)
        self.csv_path = Path(absolute)
        if not self.csv_path.is_file():
            return _note("data", self.csv_path)
        self.options["header-rows"] = 1
        self.arguments = [self.options["title"]] if "title" in self.options else []
        return super().run()

    def get_csv_data(self):
        with open(self.csv_path, newline="") as f:
            rows = list(csv.reader(f))
        header, body = rows[0], rows[1:]
        for clause in filter(None, (c.strip() for c in self.options.get("where", "").split(";"))):
            for op in ("!~=", "!=", "~=", "="):
                if op in clause:
                    column, _, value = clause.partition(op)
                    break
            else:
                raise self.error(f"bench-table: :where: clause {clause!r} is not column=value, column!=value "
                                 "or column~=text")
            if column.strip() not in header:
                raise self.error(f"bench-table: {self.csv_path.name} has no column {column.strip()}")
            index, value = header.index(column.strip()), value.strip()
            keep = {"=": lambda cell: cell == value, "!=": lambda cell: cell != value,
                    "~=": lambda cell: value in cell, "!~=": lambda cell: value not in cell}[op]
            body = [row for row in body if keep(row[index] if index < len(row) else "")]
        if "columns" in self.options:
            picks = [c.strip() for c in self.options["columns"].split(",") if c.strip()]
            names = [p.partition("=")[0].strip() for p in picks]
            missing = [n for n in names if n not in header]
            if missing:
                raise self.error(f"bench-table: {self.csv_path.name} has no column {', '.join(missing)} "
                                 f"(it has {', '.join(header)})")
            indices = [header.index(n) for n in names]
            header = [p.partition("=")[2].strip() or p.partition("=")[0].strip() for p in picks]
            body = [[row[i] if i < len(row) else "" for i in indices] for row in body]
        digits, ninf = self.options.get("digits", 4), self.options.get("ninf", "reference")
        body = [[_format(cell, digits, ninf) for cell in row] for row in body]
        text = io.StringIO()
        csv.writer(text).writerows([header, *body])
        return text.getvalue().splitlines(), str(self.csv_path)


class BenchFigure(Figure):
    """``figure`` of a plot the suite writes; a note where the file is missing (not yet run)."""

    def run(self) -> list[nodes.Node]:
        env = self.state.document.settings.env
        rel, absolute = env.relfn2path(self.arguments[0], env.docname)
        if not Path(absolute).is_file():
            env.note_dependency(rel)
            return _note("plot", Path(absolute))
        return super().run()


class BenchRun(SphinxDirective):
    """The machine, date, command and seconds of the run that wrote a data folder (``machine.json``)."""

    required_arguments = 1
    option_spec = {"benchmarks": directives.unchanged}

    def run(self) -> list[nodes.Node]:
        path = _resolve(self, str(Path(self.arguments[0]) / "machine.json"))
        if not path.is_file():
            return _note("data", path)
        info = json.loads(path.read_text())
        wanted = self.options.get("benchmarks", "").split() or list(info.get("seconds", {}))
        packages = ", ".join(f"{p} {info[p]}" for p in ("mitsuba", "drjit", "numpy") if info.get(p))
        memory = f", {info['memory_gib']} GiB memory" if info.get("memory_gib") else ""
        seconds = ", ".join(f"{n} {info['seconds'][n]:.0f} s" for n in wanted if n in info.get("seconds", {}))
        fields = [
            ("Machine", f"{info.get('cpu')}, {info.get('cpus')} CPUs{memory}; {info.get('system')}"),
            ("Software", f"Python {info.get('python')}, {packages}"),
            ("Date", f"{info.get('started_utc')} to {info['finished_utc']}" if info.get("finished_utc") else
             f"started {info.get('started_utc')}; stopped before the end, after the benchmarks timed below"),
            ("Command", info.get("command", "")),
            ("Settings", "--quick" if info.get("quick") else "full"),
            ("Commit", info.get("commit") or "unknown"),
            ("Wall seconds", seconds or "not recorded"),
        ]
        field_list = nodes.field_list()
        for name, value in fields:
            body = nodes.paragraph()
            body += nodes.literal(text=value) if name in ("Command", "Settings") else nodes.Text(value)
            field_list += nodes.field("", nodes.field_name(text=name), nodes.field_body("", body))
        return [field_list]


class BenchChecks(SphinxDirective):
    """The PASS/FAIL checks of some benchmarks, from ``checks.csv``."""

    required_arguments = 1
    option_spec = {"benchmarks": directives.unchanged}

    def run(self) -> list[nodes.Node]:
        path = _resolve(self, str(Path(self.arguments[0]) / "checks.csv"))
        if not path.is_file():
            return _note("data", path)
        wanted = self.options.get("benchmarks", "").split()
        with open(path, newline="") as f:
            rows = [r for r in csv.DictReader(f) if not wanted or r["benchmark"] in wanted]
        if not rows:
            para = nodes.paragraph(text="This run recorded no checks for "
                                        f"{', '.join(wanted) or 'any benchmark'}.")
            return [para]
        columns = (["benchmark"] if not wanted else []) + ["result", "check", "measured"]
        widths = ([14] if not wanted else []) + [8, 40, 50]
        table = nodes.table()
        group = nodes.tgroup(cols=len(columns))
        table += group
        for width in widths:
            group += nodes.colspec(colwidth=width)
        head, body = nodes.thead(), nodes.tbody()
        group += head
        group += body

        def row(cells):
            r = nodes.row()
            for cell in cells:
                entry = nodes.entry()
                entry += nodes.paragraph(text=cell)
                r += entry
            return r

        head += row(columns)
        for r in rows:
            cells = ["PASS" if r["ok"] == "True" else "FAIL", r["check"], r["detail"]]
            body += row(([r["benchmark"]] if not wanted else []) + cells)
        return [table]


def setup(app):
    app.add_directive("bench-table", BenchTable)
    app.add_directive("bench-figure", BenchFigure)
    app.add_directive("bench-run", BenchRun)
    app.add_directive("bench-checks", BenchChecks)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
