"""Mutation testing: plant deliberate bugs in the physics and signal modules and see which the tests catch.

A test suite earns trust by failing when a formula is wrong. This job copies the package into
a temporary folder, changes one thing at a time (a mutant), runs the tests that cover the
changed module, and records whether they fail ("killed") or pass ("survived"). The source
checkout is never touched.

Mutants come from two places:

* **Planted bugs** (:data:`PLANTED`): the mistakes a SAR simulator is known to make: a
  ``(4 pi)^3`` written ``(4 pi)^2``, sin for cos, a dropped factor 2 in the two-way phase, a
  window's sign. Each names its module, the exact source text and its replacement; one whose
  text is no longer in the module is reported as ``stale``.
* **Operator mutants**, drawn with a fixed seed from every arithmetic operator, comparison,
  unary minus, numeric constant and sin/cos-like call of the modules (``--per-module`` of
  them): ``+``/``-``, ``*``/``/``, ``**`` to ``*``, ``<``/``>``, dropping a unary minus,
  doubling a constant, ``sin``/``cos``, ``real``/``imag``, ``np.conj(x)`` to ``x``.

Survivors are either equivalent mutants (the change does not alter behaviour: a constant in
an error message's valid range, ``x ** 2`` with ``x == 2``) or a gap in the tests. The README's
development section lists them with the reason or the test that now kills each.

Usage::

    python benchmarks/mutation.py [--per-module N] [--only MODULE ...] [--seed S] [--list]

Writes ``mutation.csv`` (one row per mutant: module, line, kind, original, mutant, outcome,
seconds) and ``mutation.md`` (the survivors) into the benchmark output folder. Not part of
CI: one mutant runs its module's tests, a few seconds to a minute each.
"""
from __future__ import annotations

import argparse
import ast
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _table import machine, output_dir, write_csv  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: Module (path under sarmitsuba/) -> the test files that cover it, fastest first.
TARGETS: dict[str, tuple[str, ...]] = {
    "core/radar.py": ("tests/test_render_geometry.py", "tests/test_geometry_angles.py", "tests/test_antenna.py",
                 "tests/test_input_errors.py", "tests/test_acquisition_checks.py", "tests/test_info.py"),
    "scene/planning.py": ("tests/test_acquisition_checks.py", "tests/test_info.py", "tests/test_hard_cases.py"),
    "scene/radar_equation.py": ("tests/test_radiometry.py", "tests/test_effects.py"),
    "signal/radiometry.py": ("tests/test_radiometry.py", "tests/test_effects.py"),
    "scene/materials.py": ("tests/test_materials.py", "tests/test_physical_optics.py", "tests/test_clutter.py"),
    "scene/fresnel.py": ("tests/test_materials.py", "tests/test_physical_optics.py"),
    "signal/signal_model.py": ("tests/test_signal_model.py", "tests/test_range_compression.py", "tests/test_synthetic.py", "tests/test_range_kernels.py"),
    "signal/binning.py": ("tests/test_range_kernels.py", "tests/test_range_compression.py", "tests/test_trace.py",
                   "tests/test_radiometry.py"),
    "focus/windows.py": ("tests/test_windows.py", "tests/test_weighted_images.py"),
    "focus/range_compression.py": ("tests/test_range_compression.py", "tests/test_synthetic.py"),
    "focus/backprojection.py": ("tests/test_backprojection.py", "tests/test_focus_frames.py"),
    "focus/ffbp.py": ("tests/test_ffbp.py",),
    "focus/polar.py": ("tests/test_ffbp.py",),
    "focus/stripmap.py": ("tests/test_stripmap.py", "tests/test_omegak.py", "tests/test_rda.py"),
    "focus/fft_contract.py": ("tests/test_omegak.py", "tests/test_rda.py"),
    "focus/omegak.py": ("tests/test_omegak.py", "tests/test_squint.py"),
    "focus/rda.py": ("tests/test_rda.py", "tests/test_squint.py"),
    "focus/grid.py": ("tests/test_backprojection.py", "tests/test_focus_frames.py"),
}


@dataclass(frozen=True)
class Mutant:
    """One deliberate bug: replace ``original`` by ``mutated`` in ``module`` (at ``line`` for
    operator mutants; the first occurrence for planted ones)."""

    module: str
    line: int
    kind: str
    original: str
    mutated: str
    planted: bool = False


#: Known SAR mistakes: (module, kind, exact source text, replacement).
PLANTED: tuple[tuple[str, str, str, str], ...] = (
    ("scene/radar_equation.py", "(4 pi)^3 -> (4 pi)^2", "(4 * math.pi) ** 3", "(4 * math.pi) ** 2"),
    ("core/radar.py", "slant range: sin for cos", "self.altitude / math.cos(math.radians(self.incidence_angle))",
     "self.altitude / math.sin(math.radians(self.incidence_angle))"),
    ("core/radar.py", "ground range: cot for tan", "self.altitude * math.tan(math.radians(self.incidence_angle))",
     "self.altitude / math.tan(math.radians(self.incidence_angle))"),
    ("signal/signal_model.py", "chirp spectrum phase sign", "phase = np.exp(-2j * np.pi", "phase = np.exp(2j * np.pi"),
    ("focus/backprojection.py", "conjugate carrier", "cycles = np.mod(raw.fc * length", "cycles = np.mod(-raw.fc * length"),
    ("focus/windows.py", "Hamming 0.54 -> 0.5", '"hamming": {"alpha": 0.54}', '"hamming": {"alpha": 0.5}'),
    ("scene/materials.py", "TE/TM swapped", 'return r_te if pol == "te" else r_tm', 'return r_tm if pol == "te" else r_te'),
)

_SWAP_BINOP = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult, ast.Pow: ast.Mult}
_SWAP_CMP = {ast.Lt: ast.Gt, ast.Gt: ast.Lt, ast.LtE: ast.GtE, ast.GtE: ast.LtE, ast.Eq: ast.NotEq, ast.NotEq: ast.Eq}
_SWAP_CALL = {"sin": "cos", "cos": "sin", "arcsin": "arccos", "arccos": "arcsin", "asin": "acos", "acos": "asin",
              "real": "imag", "imag": "real", "floor": "ceil", "ceil": "floor", "minimum": "maximum",
              "maximum": "minimum"}


def _skipped(tree: ast.AST) -> set[int]:
    """ids of nodes whose mutation tests nothing: error messages, raise and assert statements,
    module-level tables and integer knobs (block sizes), array shapes of empty buffers."""
    out: set[int] = set()
    for node in tree.body:             # module-level tables and integer knobs (block sizes, caches)
        if isinstance(node, (ast.Assign, ast.AnnAssign)) and isinstance(node.value, (ast.Dict, ast.Tuple, ast.List,
                                                                                    ast.Constant, ast.BinOp)):
            if not (isinstance(node.value, ast.Constant) and isinstance(node.value.value, float)):
                out.update(id(n) for n in ast.walk(node))
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, "attr", "") in ("empty", "zeros", "ones", "full"):
            out.update(id(n) for n in ast.walk(node.args[0]) if node.args)
        if isinstance(node, (ast.Raise, ast.JoinedStr, ast.Assert)) or (
                isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) in
                ("warn", "print", "write", "ValueError", "ParameterError", "TypeError")):
            out.update(id(n) for n in ast.walk(node))
    return out


def operator_sites(source: str) -> list[tuple[int, str, int]]:
    """Every mutable site of ``source``: (line, kind, index of the node in ``ast.walk`` order)."""
    tree = ast.parse(source)
    skip = _skipped(tree)
    sites = []
    for index, node in enumerate(ast.walk(tree)):
        if id(node) in skip:
            continue
        if isinstance(node, ast.BinOp) and type(node.op) in _SWAP_BINOP:
            sites.append((node.lineno, f"{type(node.op).__name__}->{_SWAP_BINOP[type(node.op)].__name__}", index))
        elif isinstance(node, ast.Compare) and type(node.ops[0]) in _SWAP_CMP:
            sites.append((node.lineno, f"{type(node.ops[0]).__name__}->{_SWAP_CMP[type(node.ops[0])].__name__}",
                          index))
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            sites.append((node.lineno, "drop unary minus", index))
        elif (isinstance(node, ast.Constant) and type(node.value) in (int, float) and node.value not in (0, 1)
              and not isinstance(node.value, bool)):
            sites.append((node.lineno, "constant x2", index))
        elif isinstance(node, ast.Attribute) and node.attr in _SWAP_CALL:
            sites.append((node.lineno, f"{node.attr}->{_SWAP_CALL[node.attr]}", index))
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", "") in ("conj", "conjugate") and node.args:
            sites.append((node.lineno, "drop conj", index))
    return sites


class _Apply(ast.NodeTransformer):
    def __init__(self, target: int) -> None:
        self.target, self.index = target, -1

    def mutate(self, tree: ast.AST) -> ast.AST:
        nodes = list(ast.walk(tree))
        node = nodes[self.target]
        if isinstance(node, ast.BinOp):
            node.op = _SWAP_BINOP[type(node.op)]()
        elif isinstance(node, ast.Compare):
            node.ops[0] = _SWAP_CMP[type(node.ops[0])]()
        elif isinstance(node, ast.UnaryOp):
            node.op = ast.UAdd()
        elif isinstance(node, ast.Constant):
            node.value = node.value * 2
        elif isinstance(node, ast.Attribute):
            node.attr = _SWAP_CALL[node.attr]
        elif isinstance(node, ast.Call):          # np.conj(x) -> (+x)
            nodes_parent = [n for n in nodes if any(c is node for c in ast.iter_child_nodes(n))]
            for parent in nodes_parent:
                for field, value in ast.iter_fields(parent):
                    if value is node:
                        setattr(parent, field, ast.UnaryOp(ast.UAdd(), node.args[0]))
                    elif isinstance(value, list):
                        value[:] = [ast.UnaryOp(ast.UAdd(), node.args[0]) if v is node else v for v in value]
        return ast.fix_missing_locations(tree)


def mutated_source(source: str, mutant: Mutant, index: int | None) -> str | None:
    """The module's source with the mutant applied, or None when a planted text is absent."""
    if mutant.planted:
        return source.replace(mutant.original, mutant.mutated, 1) if mutant.original in source else None
    return ast.unparse(_Apply(index).mutate(ast.parse(source)))


def draw_mutants(modules: list[str], per_module: int, seed: int) -> list[tuple[Mutant, int | None]]:
    """Planted mutants of ``modules`` plus ``per_module`` operator mutants each, drawn with ``seed``."""
    rng = random.Random(seed)
    out: list[tuple[Mutant, int | None]] = []
    for module, kind, original, mutated in PLANTED:
        if module in modules:
            out.append((Mutant(module, 0, kind, original, mutated, planted=True), None))
    for module in modules:
        source = (ROOT / "sarmitsuba" / module).read_text()
        lines = source.splitlines()
        sites = operator_sites(source)
        for line, kind, index in sorted(rng.sample(sites, min(per_module, len(sites)))):
            out.append((Mutant(module, line, kind, lines[line - 1].strip()[:90], kind), index))
    return out


def copy_tree(dest: Path) -> None:
    """The package, its plugins, tests and scenes, as they are in the working tree now."""
    for name in ("sarmitsuba", "plugins", "tests", "scenes", "pyproject.toml", "docs"):
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        elif src.exists():
            shutil.copy2(src, dest / name)


def run_tests(workdir: Path, tests: tuple[str, ...], timeout: float) -> tuple[str, float]:
    """``killed`` (a test failed or errored), ``survived`` or ``timeout`` (counted killed), and seconds."""
    env = dict(os.environ, PYTHONPATH=str(workdir), PYTHONDONTWRITEBYTECODE="1")
    present = [t for t in tests if (workdir / t).exists()]
    start = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *present],
                              cwd=workdir, env=env, capture_output=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", time.perf_counter() - start
    return ("survived" if proc.returncode == 0 else "killed"), time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-module", type=int, default=8, help="operator mutants per module (default 8)")
    parser.add_argument("--only", nargs="+", choices=list(TARGETS), default=None, metavar="MODULE")
    parser.add_argument("--seed", type=int, default=14)
    parser.add_argument("--list", action="store_true", help="list the mutants and stop")
    args = parser.parse_args(argv)
    modules = [m for m in (args.only or TARGETS) if (ROOT / "sarmitsuba" / m).exists()]
    mutants = draw_mutants(modules, args.per_module, args.seed)
    print(machine())
    if args.list:
        for m, _ in mutants:
            print(f"{m.module}:{m.line}  {m.kind:24s} {m.original}")
        return 0
    rows = []
    with tempfile.TemporaryDirectory(prefix="sarmitsuba-mutation-") as tmp:
        work = Path(tmp)
        copy_tree(work)
        check = subprocess.run([sys.executable, "-c", "import sarmitsuba, sys; print(sarmitsuba.__file__)"],
                               cwd=work, env=dict(os.environ, PYTHONPATH=str(work)), capture_output=True, text=True)
        if not check.stdout.startswith(str(work)):
            print(f"the copy's package is not the one imported ({check.stdout.strip()}): stop", file=sys.stderr)
            return 2
        baseline: dict[tuple[str, ...], float] = {}
        for i, (mutant, index) in enumerate(mutants, 1):
            tests = TARGETS[mutant.module]
            if tests not in baseline:                     # the unmutated tests must pass, and set the timeout
                outcome, seconds = run_tests(work, tests, timeout=1800)
                if outcome != "survived":
                    print(f"tests for {mutant.module} fail without a mutant: stop", file=sys.stderr)
                    return 2
                baseline[tests] = seconds
            path = work / "sarmitsuba" / mutant.module
            source = path.read_text()
            text = mutated_source(source, mutant, index)
            if text is None:
                outcome, seconds = "stale", 0.0
            else:
                path.write_text(text)
                try:
                    outcome, seconds = run_tests(work, tests, timeout=3 * baseline[tests] + 30)
                finally:
                    path.write_text(source)
            rows.append({"module": mutant.module, "line": mutant.line, "kind": mutant.kind,
                         "original": mutant.original, "planted": mutant.planted, "outcome": outcome,
                         "seconds": round(seconds, 1)})
            print(f"[{i}/{len(mutants)}] {outcome:8s} {mutant.module}:{mutant.line} {mutant.kind}  {mutant.original}",
                  flush=True)
    write_csv("mutation.csv", rows)
    survivors = [r for r in rows if r["outcome"] == "survived"]
    killed = sum(r["outcome"] in ("killed", "timeout") for r in rows)
    report = output_dir() / "mutation.md"
    report.write_text("| module:line | mutation | source line |\n|---|---|---|\n" + "".join(
        f"| {r['module']}:{r['line']} | {r['kind']} | `{r['original']}` |\n" for r in survivors))
    print(f"{killed} of {len(rows)} mutants killed, {len(survivors)} survived, "
          f"{sum(r['outcome'] == 'stale' for r in rows)} stale; survivors in {report}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
