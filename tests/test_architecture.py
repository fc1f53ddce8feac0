"""The package's shape (docs/design.md sections 0 and 2): stage packages in pipeline order, no
import cycles, no private reach-ins, short functions and files.

Each module belongs to the stage package it sits in; the top level holds only the entry points
(``api``, ``cli`` and its argument types ``cli_types``, ``pipeline``, ``info``). A module may
import its own package's modules and those of earlier stages (``core``, the contracts, comes
first); imports inside functions count too. A deliberate back-reference, for instance the
signal stage importing the test oracle in ``analysis``, or a cycle between two modules of one
package, fails here.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "sarmitsuba"
PHYSICS = Path(__file__).resolve().parents[1] / "docs" / "physics.md"

#: The stage packages in pipeline order: a package may import from itself and the ones before it.
STAGES = ("core", "scene", "tracing", "signal", "focus", "products", "formats", "stacks", "analysis")
#: The top level: the public entry points over every stage.
TOP = {"__init__", "__main__", "api", "cli", "cli_types", "cli_stack", "cli_scene", "pipeline", "stack", "info", "info_text",
       "derivatives"}
#: Only the tracer kernel's banner-sectioned loop may be longer (docs/design.md section 5).
LONG_FUNCTION_EXEMPT = {("tracing.driver.kernel", "launch")}
MAX_FUNCTION_LINES = 80
MAX_FILE_LINES = 600


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
        if parts[-1] == "__init__" and len(parts) > 1:
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _stage(module: str) -> int:
    """Rank of a module's stage: its package's place in STAGES; the top level comes last."""
    if module in TOP:
        return len(STAGES)
    package = module.split(".")[0]
    if package in STAGES and "." in module or module in STAGES:
        return STAGES.index(package)
    raise AssertionError(f"module sarmitsuba.{module} belongs to no stage: put it in one of the stage "
                         f"packages {STAGES}, or add an entry point to TOP in {__file__}")


def _stage_name(rank: int) -> str:
    return STAGES[rank] if rank < len(STAGES) else "top level"


def _imports(module: str, path: Path) -> list[tuple[str, str, int]]:
    """(imported module, imported name or '', line) for every sarmitsuba import in the file."""
    package = module.split(".")[:-1] if path.name != "__init__.py" else module.split(".")
    if module == "__init__":
        package = []
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)] if node.level > 1 else package
                target = ".".join([*base, *([node.module] if node.module else [])])
            elif (node.module or "").startswith("sarmitsuba"):
                target = node.module[len("sarmitsuba."):] if node.module != "sarmitsuba" else ""
            else:
                continue
            for alias in node.names:
                found.append((target, alias.name, node.lineno))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("sarmitsuba."):
                    found.append((alias.name[len("sarmitsuba."):], "", node.lineno))
    return found


def _resolve(target: str, name: str, modules: dict[str, Path]) -> str:
    """The module an import refers to: ``from . import x`` names module x."""
    candidate = f"{target}.{name}" if target else name
    return candidate if candidate in modules else (target or "__init__")


def test_every_module_has_a_stage():
    for module in _modules():
        _stage(module)


def test_the_top_level_is_a_dozen_entries():
    entries = sorted(p.name for p in PACKAGE.iterdir() if not p.name.startswith((".", "__pycache__")))
    expected = sorted([*STAGES, *(f"{m}.py" for m in TOP)])
    assert entries == expected, f"sarmitsuba/ should hold the stage packages and the entry points only: {entries}"


@pytest.mark.parametrize("stage", STAGES)
def test_every_stage_package_opens_with_its_contract(stage):
    """Each package's docstring says its stage, what it takes and gives, and its physics labels,
    and every label it names exists in docs/physics.md."""
    doc = ast.get_docstring(ast.parse((PACKAGE / stage / "__init__.py").read_text())) or ""
    for heading in ("Stage:", "Takes:", "Gives:", "Physics:"):
        assert heading in doc, f"sarmitsuba/{stage}/__init__.py's docstring lacks {heading!r}"
    physics = PHYSICS.read_text()
    section = doc.split("Physics:", 1)[1]
    for label in re.findall(r"\(([A-Z]+[0-9]*[a-z]?)\)", section):
        assert f"({label})" in physics, f"sarmitsuba/{stage}: label ({label}) is not in docs/physics.md"


def test_no_module_imports_another_modules_private_name():
    bad = []
    for module, path in _modules().items():
        for target, name, line in _imports(module, path):
            if name.startswith("_") and not name.startswith("__") and target not in ("", "__init__"):
                bad.append(f"sarmitsuba/{path.relative_to(PACKAGE)}:{line} imports {target}.{name}")
    assert not bad, "private names imported across modules:\n" + "\n".join(bad)


def test_no_module_uses_another_modules_private_attribute():
    modules = _modules()
    bad = []
    for module, path in modules.items():
        tree = ast.parse(path.read_text())
        target_at = {line: target for target, _, line in _imports(module, path)}     # ImportFrom line -> module
        aliases = {a.asname or a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                   for a in n.names if _resolve(target_at.get(n.lineno, ""), a.name, modules) in modules
                   and f"{target_at.get(n.lineno, '')}.{a.name}".strip(".") in modules}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in aliases and node.attr.startswith("_")
                    and not node.attr.startswith("__")):
                bad.append(f"sarmitsuba/{path.relative_to(PACKAGE)}:{node.lineno} uses {node.value.id}.{node.attr}")
    assert not bad, "private attributes of other modules used:\n" + "\n".join(bad)


def _graph() -> dict[str, set[str]]:
    """Module -> the sarmitsuba modules it imports (a package's ``__init__`` counts as the package)."""
    modules = _modules()
    graph = {}
    for module, path in modules.items():
        used = {_resolve(target, name, modules) for target, name, _ in _imports(module, path)}
        graph[module] = {u for u in used if u in modules and u != module and u != "__init__"
                         and not module.startswith(u + ".")}
    return graph


def test_imports_follow_the_pipeline():
    modules = _modules()
    bad = []
    for module, path in modules.items():
        own = _stage(module)
        for target, name, line in _imports(module, path):
            used = _resolve(target, name, modules)
            if used.startswith("__init__") or used == "" or used == "__version__":
                continue
            if used == module or module.startswith(used + "."):   # a package's own __init__
                continue
            if _stage(used) > own:
                bad.append(f"sarmitsuba/{path.relative_to(PACKAGE)}:{line} ({_stage_name(own)}) imports "
                           f"{used} ({_stage_name(_stage(used))})")
    assert not bad, "imports against the pipeline's direction:\n" + "\n".join(bad)


def test_the_import_graph_has_no_cycles():
    """Depth-first search for a back edge (Tarjan's colouring); a cycle names its modules."""
    graph = _graph()
    colour = dict.fromkeys(graph, 0)                 # 0 new, 1 on the stack, 2 done
    cycles = []

    def visit(node, stack):
        colour[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if colour[nxt] == 1:
                cycles.append(" -> ".join(stack[stack.index(nxt):] + [nxt]))
            elif colour[nxt] == 0:
                visit(nxt, stack)
        stack.pop()
        colour[node] = 2

    for node in sorted(graph):
        if colour[node] == 0:
            visit(node, [])
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def _function_lengths():
    for module, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = node.body[0]
                docstring = isinstance(first, ast.Expr) and isinstance(getattr(first, "value", None), ast.Constant) \
                    and isinstance(first.value.value, str)
                start = first.end_lineno + 1 if docstring and len(node.body) > 1 else first.lineno
                yield module, path, node, node.end_lineno - start + 1


def test_function_bodies_are_short():
    long = [f"sarmitsuba/{p.relative_to(PACKAGE)}:{n.lineno} {n.name}: {length} lines"
            for module, p, n, length in _function_lengths()
            if length > MAX_FUNCTION_LINES and (module, n.name) not in LONG_FUNCTION_EXEMPT]
    assert not long, f"function bodies over {MAX_FUNCTION_LINES} lines (docstring excluded):\n" + "\n".join(long)


def test_files_are_short():
    long = [f"sarmitsuba/{p.relative_to(PACKAGE)}: {n} lines" for p in PACKAGE.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_FILE_LINES]
    assert not long, f"files over {MAX_FILE_LINES} lines:\n" + "\n".join(long)


@pytest.mark.parametrize("module, source, expected", [
    ("signal/binning.py", "from ..focus.stripmap import _window_spec\n", "private"),
    ("signal/binning.py", "from ..analysis.synthetic import receiver_response\n", "direction"),
    ("core/raw.py", "from ..scene.effects import EffectSet\n", "direction"),
    ("core/outputs.py", "from .raw import RawData\n", "cycle"),
])
def test_the_checks_catch_a_planted_violation(tmp_path, monkeypatch, module, source, expected):
    # the checks above must be able to fail: plant a violation in a copy of the package
    planted = tmp_path / "sarmitsuba"
    import shutil
    shutil.copytree(PACKAGE, planted, ignore=shutil.ignore_patterns("__pycache__"))
    (planted / module).write_text(source + (planted / module).read_text())
    monkeypatch.setattr(__import__(__name__), "PACKAGE", planted)
    check = {"private": test_no_module_imports_another_modules_private_name,
             "direction": test_imports_follow_the_pipeline,
             "cycle": test_the_import_graph_has_no_cycles}[expected]
    match = "core.outputs -> core.raw -> core.outputs" if expected == "cycle" else f"{module}:1 "
    with pytest.raises(AssertionError, match=match):
        check()


def test_former_module_paths_import_their_new_modules():
    """``sarmitsuba.raw`` and the other former top-level modules import as their new module (the
    same object) with a DeprecationWarning naming the new path; a fresh interpreter, so that no
    earlier import has cached them."""
    import subprocess
    import sys
    code = (
        "import warnings, importlib, sarmitsuba\n"
        "for old, new in sarmitsuba.MOVED_MODULES.items():\n"
        "    with warnings.catch_warnings(record=True) as caught:\n"
        "        warnings.simplefilter('always')\n"
        "        module = importlib.import_module('sarmitsuba.' + old)\n"
        "    assert module is importlib.import_module('sarmitsuba.' + new), old\n"
        "    assert any('sarmitsuba.' + new in str(w.message) and w.category is DeprecationWarning\n"
        "               for w in caught), (old, [str(w.message) for w in caught])\n"
        "from sarmitsuba.raw import RawData\n"
        "from sarmitsuba.image import SarImage\n"
        "from sarmitsuba.scene import load_scene\n"
        "from sarmitsuba.analysis import analyze_point_target\n"
        "from sarmitsuba.products import write_exr\n"
        "from sarmitsuba.scene import materials\n"
        "assert RawData.__module__ == 'sarmitsuba.core.raw' and SarImage.__module__ == 'sarmitsuba.core.image'\n"
        "assert load_scene.__module__ == 'sarmitsuba.scene.loader'\n"
        "assert analyze_point_target.__module__ == 'sarmitsuba.analysis.point_target'\n"
        "assert write_exr.__module__ == 'sarmitsuba.products.image_files'\n"
        "assert materials.__name__ == 'sarmitsuba.scene.materials'\n"
        "try:\n"
        "    import sarmitsuba.no_such_module\n"
        "except ModuleNotFoundError:\n"
        "    pass\n"
        "else:\n"
        "    raise AssertionError('an unknown module imported')\n"
        "print('ok')\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and run.stdout.strip().endswith("ok"), run.stderr[-2000:]


def test_every_former_module_is_listed_and_gone_from_the_top():
    """MOVED_MODULES's targets exist, and none of its old names is left at the top level."""
    import sarmitsuba
    modules = _modules()
    for old, new in sarmitsuba.MOVED_MODULES.items():
        assert new in modules, f"MOVED_MODULES[{old!r}] = {new!r} is not a module"
        assert old not in modules, f"sarmitsuba.{old} is both a module and a moved name"
