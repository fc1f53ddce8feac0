"""The package's shape (docs/design.md section 2): stages in pipeline order, no private reach-ins,
short functions and files.

Each module belongs to one stage; a module may import only from its own stage or an earlier
one (imports inside functions count too). A deliberate back-reference, for instance the raw
stage importing a focuser or the test oracle, or ``image`` importing ``analysis``, fails here.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "sarmitsuba"

#: Pipeline order: a module may import from stages at or before its own.
STAGES = {
    0: ("utilities", {"constants", "arrays", "outputs", "bandlimited", "deposit", "device", "_llvm", "_variant",
                      "focus.windows", "focus.grid", "focus.range_lines", "focus.stolt"}),
    1: ("scene", {"georef", "radar", "baseline", "materials", "meshcheck", "canonical", "pyscene", "scene", "trace_inputs",
                  "effects", "planning", "radiometry", "signal_model", "fresnel",
                  "polarimetry"}),
    2: ("trace", {"physical_optics", "facets", "lattice_index", "cell_lanes", "cell_split", "cell_plan", "cell_clip", "cell_terms", "clutter_lattice", "accumulate", "returns", "kernel", "trace", "jones"}),
    3: ("raw data", {"raw", "binning", "cphd"}),
    4: ("focus", {"image", "focus", "focus.*"}),
    5: ("products", {"products", "groundtruth", "plotting", "figures_pol", "geotiff", "sicd"}),
    6: ("analysis and figures", {"analysis", "analysis.*", "figures", "figures.*", "figures_raw", "figures_point",
                                 "preview", "info", "cost",
                                 "synthetic", "reference_cases", "cut_metrics", "impulse_model",
                                 "interferometry"}),
    7: ("orchestration and CLI", {"pipeline", "distributed", "api", "cli", "__init__", "__main__"}),
}
#: Only the tracer kernel's banner-sectioned loop may be longer (docs/design.md section 5).
LONG_FUNCTION_EXEMPT = {("kernel", "launch")}
MAX_FUNCTION_LINES = 80
MAX_FILE_LINES = 620


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
        if parts[-1] == "__init__" and len(parts) > 1:
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _stage(module: str) -> int:
    for rank, (_, members) in STAGES.items():
        for m in members:
            if module == m or (m.endswith(".*") and module.startswith(m[:-1])):
                return rank
    raise AssertionError(f"module sarmitsuba.{module} has no stage: add it to STAGES in {__file__}")


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
        aliases = {a.asname or a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                   for a in n.names if _resolve(_target_of(module, path, n), a.name, modules) in modules
                   and f"{_target_of(module, path, n)}.{a.name}".strip(".") in modules}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in aliases and node.attr.startswith("_")
                    and not node.attr.startswith("__")):
                bad.append(f"sarmitsuba/{path.relative_to(PACKAGE)}:{node.lineno} uses {node.value.id}.{node.attr}")
    assert not bad, "private attributes of other modules used:\n" + "\n".join(bad)


def _target_of(module: str, path: Path, node: ast.ImportFrom) -> str:
    for target, _, line in _imports(module, path):
        if line == node.lineno:
            return target
    return ""


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
                bad.append(f"sarmitsuba/{path.relative_to(PACKAGE)}:{line} ({STAGES[own][0]}) imports "
                           f"{used} ({STAGES[_stage(used)][0]})")
    assert not bad, "imports against the pipeline's direction:\n" + "\n".join(bad)


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


@pytest.mark.parametrize("source, expected", [
    ("from .focus.stripmap import _window_spec\n", "private"),
    ("from .synthetic import receiver_response\n", "direction"),
])
def test_the_checks_catch_a_planted_violation(tmp_path, monkeypatch, source, expected):
    # the checks above must be able to fail: plant a violation in a copy of binning
    planted = tmp_path / "sarmitsuba"
    import shutil
    shutil.copytree(PACKAGE, planted, ignore=shutil.ignore_patterns("__pycache__"))
    (planted / "binning.py").write_text(source + (planted / "binning.py").read_text())
    monkeypatch.setattr(__import__(__name__), "PACKAGE", planted)
    check = (test_no_module_imports_another_modules_private_name if expected == "private"
             else test_imports_follow_the_pipeline)
    with pytest.raises(AssertionError, match="binning.py:1 "):
        check()
