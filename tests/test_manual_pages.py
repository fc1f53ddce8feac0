"""The manual's getting-started and user-guide pages (:data:`MANUAL_PAGES`) run as written: every
command of their ``bash`` blocks, in page order in one folder, with the README's small settings
(tests/test_readme.py's :class:`Runner`: 16 pulses, one bounce, Munich's renders on Sionna's street
canyon), and every ``python`` block, page by page, in one namespace per page. The worked inverse
problem of the gradients page runs once, with its result checked against the truth it recovers.

``make setup``, ``make render``, ``make test``, ``make docs``, ``make docs-browser`` and ``make
bench`` are the lines that do not run here: CI runs ``make test`` on a clean clone, and
tests/test_manual.py builds the manual.
"""
from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import pytest

from test_readme import DASK, FRESH_CLONE, PYTHON, Runner, code_blocks, commands   # tests/ is on sys.path

REPO = Path(__file__).resolve().parents[1]
#: make lines the pages show, which do not run here (see the module docstring)
MAKE_LINES = FRESH_CLONE | {"make setup", "make docs", "make docs-browser", "make bench"}
#: The pages whose blocks run, in this order in one folder (a later page may focus what an earlier
#: one rendered): getting started, then the user guide.
MANUAL_PAGES = ["getting-started.md"] + [f"guide/{name}.md" for name in (
    "scenes", "sensor", "rendering", "focusing", "polarimetry", "interferometry", "tomography", "formats", "gradients",
    "dask", "gpu", "choosing-settings", "limits")]
#: A command line's start: a sarmitsuba command through the checkout's venv or an activated one, or dask.
KNOWN = re.compile(rf"([A-Z_]+=\S+ )*(({re.escape(PYTHON)}|python) -m sarmitsuba|({re.escape(DASK)}|dask)) ")
#: The Python block of a page that :func:`test_inverse_example_converges` runs (by a line it holds).
INVERSE = ("guide/gradients.md", "scipy.optimize.minimize(")


def page(name: str) -> Path:
    return REPO / "docs" / name


def working_folder(path: Path) -> Path:
    """A folder with the repository's ``scenes/`` and ``my_scene.xml`` (the built-in dihedral)."""
    (path / "scenes").symlink_to(REPO / "scenes", target_is_directory=True)
    shutil.copy(REPO / "scenes" / "dihedral.xml", path / "my_scene.xml")
    return path


def test_every_page_exists_and_its_command_lines_are_of_a_known_kind():
    assert [name for name in MANUAL_PAGES if not page(name).is_file()] == []
    lines = [line for name in MANUAL_PAGES for _, block in code_blocks("bash", page(name)) for line in commands(block)]
    assert [line for line in lines if line not in MAKE_LINES and not KNOWN.match(line)] == []
    assert len(lines) > 40


def test_bash_blocks_run_in_order(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(working_folder(tmp_path))
    runner = Runner(tmp_path, capsys, monkeypatch)
    ran = []
    try:
        for name in MANUAL_PAGES:
            for start, block in code_blocks("bash", page(name)):
                for line in commands(block):
                    if line not in MAKE_LINES:
                        runner.run(line)
                        ran.append((name, start, line))
    finally:
        runner.close()
    assert len(ran) > 40


@pytest.mark.parametrize("name", MANUAL_PAGES)
def test_python_blocks_run(name, tmp_path, monkeypatch):
    """A page's Python blocks run as written, in order, in one namespace (a later block may use an
    earlier one's names); the inverse problem is left to its own test."""
    monkeypatch.chdir(working_folder(tmp_path))
    namespace: dict = {"__name__": "__manual__"}
    environment = dict(os.environ)             # the GPU page sets SARMITSUBA_VARIANT for its process
    try:
        for start, block in code_blocks("python", page(name)):
            if (name, True) != (INVERSE[0], INVERSE[1] in block):
                exec(compile(block, f"{name}:{start}", "exec"), namespace)
    finally:
        os.environ.clear()
        os.environ.update(environment)


def test_inverse_example_converges(tmp_path, monkeypatch):
    """The gradients page's worked inverse problem (a wall's permittivity and a building's height),
    run as written: ``eps_r`` within 2 % and the height within 0.1 m of the truth (4.5, 5 m) from
    30 % off (5.85, 6.5 m). At the start both derivatives are positive (the truth lies below in
    both). Catches a gradient of the wrong sign, a detached parameter (its derivative 0, the
    parameter left at its start), a derivative scaled wrongly enough to stall the descent. From an
    empty kernel cache about 2 minutes (the first evaluation compiles for about 100 s), warm about
    15 s."""
    blocks = [block for _, block in code_blocks("python", page(INVERSE[0])) if INVERSE[1] in block]
    assert len(blocks) == 1
    monkeypatch.chdir(working_folder(tmp_path))
    namespace: dict = {}
    exec(compile(blocks[0], "inverse example", "exec"), namespace)
    found, loss_and_gradient = namespace["found"], namespace["loss_and_gradient"]
    start_loss, start_gradient = loss_and_gradient([5.85, 6.5])
    assert start_loss > 0 and (start_gradient > 0).all(), start_gradient
    eps_r, height = found.x
    assert abs(eps_r - 4.5) <= 0.02 * 4.5, found
    assert abs(height - 5.0) <= 0.1, found
    assert found.fun < 1e-3 * start_loss
