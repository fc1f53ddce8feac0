"""The manual's commands run from a fresh clone, as getting-started writes them.

In a fresh clone ``make setup`` installs the package into ``.venv``; a bare ``python -m sarmitsuba``
is the system's Python, which has no Mitsuba (``ModuleNotFoundError: No module named 'mitsuba'``).
So every user page (README, getting started, reading SAR images, the user guide) and every hint
the code prints (string literals of ``sarmitsuba/`` and ``plugins/``, docstrings aside) write
``.venv/bin/python``, and commands written that way run, exactly as written, from the repository
root in a shell whose environment has no virtual environment activated. The developers' settings
(``cancel_interior``, ``geometry``) stand apart from the user's in the plugin table and the guides.
"""
from __future__ import annotations

import ast
import importlib.util
import os
import re
import shlex
import subprocess
from pathlib import Path

import pytest

from sarmitsuba.cli import build_parser
from test_readme import code_blocks, commands       # tests/ is on sys.path

REPO = Path(__file__).resolve().parents[1]
PREFIX = ".venv/bin/python -m sarmitsuba"
#: The pages a user reads: the README, the manual's own pages and every page of the user guide.
USER_PAGES = sorted([REPO / "README.md", REPO / "docs" / "index.md", REPO / "docs" / "getting-started.md",
                     REPO / "docs" / "reading-sar-images.md", *(REPO / "docs" / "guide").glob("*.md")])
#: A Python started by a bare name: ``python -m ...``, ``python3 -m ...`` or ``python some/script.py``.
BARE_PAGE = re.compile(r"(?<![\w./-])python3? (?=-m |[\w./-]+\.py\b)")
#: A bare ``python -m sarmitsuba`` in a message of the code.
BARE_HINT = re.compile(r"(?<![\w./-])python3? -m sarmitsuba\b")
#: The settings only a developer needs (the task's list, not read from the code under test).
DEVELOPER = {"cancel_interior", "geometry"}
#: Seconds any one subprocess may take (each takes 2 to 7 s on a busy 2-core machine).
TIMEOUT = 120


def bare_on_pages() -> list[str]:
    return [f"{page.relative_to(REPO)}:{number}: {line.strip()}" for page in USER_PAGES
            for number, line in enumerate(page.read_text().splitlines(), start=1) if BARE_PAGE.search(line)]


def printed_strings(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every string literal of a module that is not a docstring (f-strings' parts
    included): what the code may print."""
    text = path.read_text()
    if "python" not in text:
        return []
    tree = ast.parse(text, str(path))
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings]


def guide_lines(start: str) -> list[str]:
    """The command lines of the user pages' bash blocks that start with ``start``."""
    return [line for page in USER_PAGES for _, block in code_blocks("bash", page) for line in commands(block)
            if line.startswith(start)]


def fresh_shell() -> dict[str, str]:
    """The environment of a new shell in a fresh clone: no virtual environment activated, no
    PYTHONPATH, no PYTHONHOME, and no Python environment's bin folder on PATH."""
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME", "CONDA_PREFIX")}
    venvs = {str(REPO / ".venv" / "bin"), os.path.join(os.environ.get("VIRTUAL_ENV", "/nonexistent"), "bin")}
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep) if p not in venvs)
    return env


def test_user_pages_start_python_from_the_venv():
    """No user page starts a bare ``python``. Planted bug: a guide command written back as ``python
    -m sarmitsuba info urban`` (choosing-settings) fails it, naming the page and line."""
    assert len(USER_PAGES) > 14 and all(page.is_file() for page in USER_PAGES)
    assert bare_on_pages() == []


def test_printed_hints_start_python_from_the_venv():
    """No message of the code names a bare ``python -m sarmitsuba``; the ones that name the
    command name getting-started's. Planted bug: the hint that ``scene from-footprints`` prints
    written back as ``(render it: python -m sarmitsuba render {path})`` fails it."""
    bare, prefixed = [], 0
    for path in sorted([*(REPO / "sarmitsuba").rglob("*.py"), *(REPO / "plugins").glob("*.py")]):
        for line, text in printed_strings(path):
            bare += [f"{path.relative_to(REPO)}:{line}: {text.strip()[:90]}"] if BARE_HINT.search(text) else []
            prefixed += text.count(PREFIX)
    assert bare == []
    assert prefixed >= 8          # the help's six examples, the from-footprints hint, the sbr plugin's


@pytest.fixture(scope="module")
def ran(tmp_path_factory) -> dict[str, subprocess.CompletedProcess]:
    """Two guide commands run at once, each by bash from the repository root in a fresh shell, as
    written: the rendering guide's ``info trihedral`` line and the scenes guide's ``scene
    from-footprints`` line (its ``--out`` a temporary folder, so nothing is written into the
    checkout)."""
    if not (REPO / ".venv" / "bin" / "python").exists():
        pytest.skip("no .venv in the checkout: the manual's commands run through `make setup`'s .venv")
    out = tmp_path_factory.mktemp("footprints") / "scene"
    info = guide_lines(f"{PREFIX} info trihedral --set transmit_power=")
    footprints = guide_lines(f"{PREFIX} scene from-footprints scenes/footprints.geojson --out ")
    assert len(info) == 1 and len(footprints) == 1, (info, footprints)
    lines = {"info": info[0],
             "footprints": re.sub(r"--out \S+", f"--out {shlex.quote(str(out))}", footprints[0])}
    started = {name: subprocess.Popen(["bash", "-c", line], cwd=REPO, env=fresh_shell(), text=True,
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE) for name, line in lines.items()}
    results = {}
    for name, process in started.items():
        stdout, stderr = process.communicate(timeout=TIMEOUT)
        results[name] = subprocess.CompletedProcess(lines[name], process.returncode, stdout, stderr)
    return results


def test_the_guides_commands_run_as_written(ran):
    """``.venv/bin/python -m sarmitsuba ...`` runs from the repository root without an activated
    environment: ``info`` plans the trihedral. Planted bug: the fixture's prefix for picking the
    line made ``python -m sarmitsuba`` and the guide's line written so: exit 1, "No module named
    'mitsuba'" (or 127 where no ``python`` is on PATH)."""
    info = ran["info"]
    assert info.returncode == 0, info.stderr[-2000:]
    assert info.stdout.startswith("scene trihedral") and "Radiometry" in info.stdout


def test_the_help_examples_use_the_venv():
    """Every example line ``--help`` prints starts with getting-started's prefix. Planted bug: the
    epilog's first example written back as ``python -m sarmitsuba render`` fails it."""
    epilog = build_parser().format_help().split("examples:\n", 1)[1].split("exit codes:", 1)[0]
    examples = [line.strip() for line in epilog.splitlines() if line.strip()]
    assert len(examples) == 6
    assert [line for line in examples if not line.startswith(PREFIX + " ")] == []


def test_the_footprints_hint_names_a_command_that_runs(ran):
    """``scene from-footprints`` ends by printing how to render the folder: getting-started's
    prefix and the scene it wrote. Planted bug: the hint's bare ``python -m sarmitsuba`` fails it."""
    done = ran["footprints"]
    assert done.returncode == 0, done.stderr[-2000:]
    hint = re.search(r"\(render it: (.+)\)\s*$", done.stdout)
    assert hint, done.stdout
    words = shlex.split(hint[1])
    assert " ".join(words[:4]) == f"{PREFIX} render" and Path(words[4]).is_file(), words


def load_plugin_table():
    spec = importlib.util.spec_from_file_location("pluginparameters", REPO / "docs" / "_ext" / "pluginparameters.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def table_names(lines: list[str], indices: list[int]) -> set[str]:
    return {name.strip() for i in indices if (m := re.match(r"\s*\* - (.*)", lines[i])) for name in m[1].split(",")}


def test_developer_settings_stand_apart():
    """The ``sbr`` table's developer rows are exactly ``cancel_interior`` and ``geometry``, both
    real tracer settings; the rendering guide lists them (and ``overflow_rows``) under "For
    developers" only, and the settings guide's table of goals leaves them out. Planted bugs:
    ``geometry`` dropped from ``DEVELOPER_PARAMETERS`` (its row back in the user's table), and
    the ``cancel_interior`` bullet moved back into the rendering guide's user list; each fails it."""
    from sarmitsuba.scene.trace_inputs import TraceSettings
    table = load_plugin_table()
    docstring = ast.get_docstring(ast.parse((REPO / "plugins" / "sbr_integrator.py").read_text()))
    body = docstring.split(".. pluginparameters::", 1)[1].splitlines()
    user, developer = table.split_rows(body)
    assert table_names(body, developer) == DEVELOPER and DEVELOPER <= set(TraceSettings.names())
    assert not table_names(body, user) & DEVELOPER and {"max_depth", "seed", "lit_regions"} <= table_names(body, user)
    rendering = (REPO / "docs" / "guide" / "rendering.md").read_text()
    settings = rendering.split("## The tracer's settings", 1)[1].split("\n## ", 1)[0]
    users, developers = settings.split("### For developers", 1)
    assert not re.findall(r"\*\*`(cancel_interior|geometry|overflow_rows)`\*\*", users)
    assert set(re.findall(r"\*\*`(\w+)`\*\*", developers)) == DEVELOPER | {"overflow_rows"}
    goals = (REPO / "docs" / "guide" / "choosing-settings.md").read_text().split("## Settings by goal", 1)[1]
    assert "cancel_interior" not in goals.split("\n## ", 1)[0]
