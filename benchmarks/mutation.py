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
    "stacks/tomo_sparse.py": ("tests/test_tomography.py",),
    "stacks/tomo_products.py": ("tests/test_tomography_inputs.py", "tests/test_stack_tomography.py"),
    "stacks/tomo_pixels.py": ("tests/test_tomography_inputs.py", "tests/test_stack_tomography.py"),
    "stacks/tomography.py": ("tests/test_tomography.py", "tests/test_stack_tomography.py"),
    "cli_stack.py": ("tests/test_stack_checks.py",),
    "products/elevation_truth.py": ("tests/test_elevation_truth_links.py", "tests/test_elevation_truth.py"),
    "focus/ffbp_plan.py": ("tests/test_ffbp_bistatic_crop.py", "tests/test_ffbp_bistatic.py", "tests/test_ffbp.py"),
    "core/geometry.py": ("tests/test_bistatic.py", "tests/test_render_geometry.py", "tests/test_geometry_angles.py"),
    "scene/motion.py": ("tests/test_moving_primitives.py", "tests/test_moving_shapes.py"),
    "scene/track_checks.py": ("tests/test_receiver_doppler.py", "tests/test_acquisition_checks.py"),
    "tracing/driver/kernel.py": ("tests/test_shadow_rays.py", "tests/test_trace.py"),
    "tracing/mesh/facets.py": ("tests/test_moving_primitives.py", "tests/test_facets.py"),
    "tracing/deposit/fixed_point.py": ("tests/test_solid_angle_tally.py", "tests/test_determinism.py"),
    "tracing/fused/boundary.py": ("tests/test_fused_boundary.py",),
    "products/groundtruth.py": ("tests/test_groundtruth_frame.py", "tests/test_groundtruth.py"),
    "analysis/ambiguities.py": ("tests/test_ambiguity_windows.py", "tests/test_ambiguities.py"),
    "scene/roughness.py": ("tests/test_roughness.py", "tests/test_rough_tables.py", "tests/test_rough_validity.py"),
    "scene/rough_tables.py": ("tests/test_rough_tables.py", "tests/test_rough_tangents.py"),
    "scene/rough_presets.py": ("tests/test_rough_presets.py", "tests/test_rough_validity.py"),
    "scene/effects.py": ("tests/test_rough_validity.py", "tests/test_effects.py"),
    "tracing/derivatives/rough_tangents.py": ("tests/test_rough_tangents.py",),
    "tracing/integration/clutter_terms.py": ("tests/test_rough_bistatic.py", "tests/test_clutter_bistatic.py"),
    "focus/pga_kernel.py": ("tests/test_pga_kernel.py", "tests/test_pga_pulses.py"),
    "focus/pga_clutter.py": ("tests/test_pga_clutter.py",),
    "focus/autofocus_pulses.py": ("tests/test_pga_strong_clutter.py", "tests/test_autofocus_pulses.py"),
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
    ("stacks/tomo_products.py", "render folders' elevation interval h sin(theta), not h / sin(theta)",
     "return lo / sin_theta, hi / sin_theta + 1e-3", "return lo * sin_theta, hi * sin_theta + 1e-3"),
    ("cli_stack.py", "uniform and random baselines swapped",
     '"spacing": "uniform" if args.random_baselines is None else "random"',
     '"spacing": "random" if args.random_baselines is None else "uniform"'),
    ("products/elevation_truth.py", "elevation truth's linking tolerance 100x looser", "_JUMP = 6.0", "_JUMP = 600.0"),
    ("stacks/tomo_products.py", "truth_height paired by elevation, not height",
     'sc["col"]].astype(np.float64), sc["height"])', 'sc["col"]].astype(np.float64), sc["elevation"])'),
    ("stacks/tomo_sparse.py", "SL1MMER's regularisation without its conjugate", "np.max(np.abs(np.conj(a).T @ y))",
     "np.max(np.abs(a.T @ y))"),
    ("stacks/tomo_sparse.py", "SL1MMER's scatterers weakest first", "order = np.argsort(-np.abs(gamma))",
     "order = np.argsort(np.abs(gamma))"),
    ("stacks/tomography.py", "a reference point calibrates on an empty pixel", "    _check_reference(images, q, p)\n",
     ""),
    ("stacks/tomo_pixels.py", "pixels relative to the brightest, not the clutter level",
     "floor = clutter_level(power) * 10.0 ** (-CLUTTER_MARGIN_DB / 10.0)",
     "floor = brightest * 10.0 ** (-30.0 / 10.0)"),
    ("tracing/driver/kernel.py", "shadow rays: the monostatic first bounce's one ray counted twice, a bistatic "
     "receiver's rays not told apart", "if depth > 0 or self.effects.bistatic))", "if True))"),
    ("tracing/driver/kernel.py", "the receiver's first-bounce rays not counted", "if depth > 0 or self.effects.bistatic))",
     "if depth > 0))"),
    ("products/groundtruth.py", "ground truth without the frame offset",
     "    if np.any(offset):\n        image = dataclasses.replace(", "    if False:\n        image = dataclasses.replace("),
    ("tracing/mesh/facets.py", "a moving rectangle's to_world left as it was",
     "mi.AffineTransform4f((motion @ matrix).astype(np.float32))", "mi.AffineTransform4f((matrix).astype(np.float32))"),
    ("tracing/mesh/facets.py", "a moving rectangle's turn left out", "motion[:3, :3] = rotation.as_matrix()",
     "motion[:3, :3] = np.eye(3)"),
    ("scene/motion.py", "the speed that stays: |v| - 2 excess / T (wrong off the axes)",
     "allowed, edge = _staying_speed(v, room, motion.duration)",
     "allowed, edge = max(float(np.linalg.norm(v[:2])) - 2.0 * outside / max(motion.duration, 1e-300), 0.0), 'x'"),
    ("scene/motion.py", "the speed that stays rounded to the nearest, not down",
     "return math.floor(speed / digits) * digits, axis", "return round(speed / digits) * digits, axis"),
    ("scene/motion.py", "a moving sphere let through to the tracer", "        if not shapes[index].is_mesh():",
     "        if False:"),
    ("core/geometry.py", "the receiver's clock a nanosecond off the transmitter's", "    at_tx = path.position(t)",
     "    at_tx = path.position(t + 1e-9)"),
    ("signal/radiometry.py", "bistatic effective pulses with g^2, not g_t g_r", "power = 1 if params.bistatic else 2",
     "power = 2"),
    ("analysis/ambiguities.py", "AASR without the azimuth window given",
     "aasr, rasr = azimuth_ambiguity_ratio(p, window), range_ambiguity_ratio(p)",
     "aasr, rasr = azimuth_ambiguity_ratio(p), range_ambiguity_ratio(p)"),
    ("analysis/ambiguities.py", "azimuth window over half the band", "(f / scale - sin_lo) / (sin_hi - sin_lo) - 0.5",
     "(f / scale - sin_lo) / (sin_hi - sin_lo) - 1.0"),
    ("tracing/deposit/fixed_point.py", "solid angle with the energy tallies' quantum 2^-40",
     "SOLID_ANGLE = FixedPoint(fraction_bits=80", "SOLID_ANGLE = FixedPoint(fraction_bits=40"),
    ("focus/ffbp_plan.py", "bistatic crop margin without the receiver's excursion",
     "+ np.linalg.norm(rx - rx.mean(axis=0), axis=1))))", "+ 0.0 * np.linalg.norm(rx - rx.mean(axis=0), axis=1))))"),
    ("scene/track_checks.py", "the receiver speed named rounded to the nearest of two digits",
     "{_round_down(speed * (params.prf - own) / (band - own), 3):.3g} m/s", "{speed * (params.prf - own) / (band - own):.2g} m/s"),
    ("tracing/fused/boundary.py", "maximum keeping the first of two equal zeros", "return dr.select(x > y, x, y)",
     "return dr.select(x >= y, x, y)"),
    ("scene/effects.py", "rough surfaces outside the I2EM's range not warned",
     "    warn_rough_surfaces(loaded, decided.cross_polarised)", "    None"),
    ("tracing/integration/clutter_terms.py", "a separate receiver's clutter read from the monostatic table",
     "depth == 0 and not self.bistatic)", "depth == 0)"),
    ("tracing/derivatives/rough_tangents.py", "rough sigma nought's conductivity derivative, sign flipped",
     "else -1j / (2.0 * math.pi * frequency * VACUUM_PERMITTIVITY)", "else 1j / (2.0 * math.pi * frequency * VACUUM_PERMITTIVITY)"),
    ("scene/roughness.py", "cross-polarised single-scattering shadowing dropped",
     "out.flat[i] = total / (1.0 + _smith(ci, m))", "out.flat[i] = total"),
    ("scene/roughness.py", "slope average by the 32-point rule alone, near grazing too",
     "    steep = turn > -edge", "    steep = turn < -1e300"),
    ("scene/roughness.py", "HV's k s <= 1 bound applied where HV is not traced",
     "if cross and CROSS_KS_LIMIT < ks", "if CROSS_KS_LIMIT < ks"),
    ("scene/rough_tables.py", "HH and VV swapped in the monostatic table",
     'for p in ("HH", "VV", "HV")], np.float32)', 'for p in ("VV", "HH", "HV")], np.float32)'),
    ("scene/rough_presets.py", "city preset: wood's rms height doubled", '"wood": _row(1.0, 10.0', '"wood": _row(2.0, 10.0'),
    ("focus/pga_kernel.py", "PGA's circular distance dropped", "    return np.minimum(k, n - k)", "    return k"),
    ("focus/pga_clutter.py", "PGA from the clutter: steps taken where the beam leaves the scene",
     "inside[whole[0]:whole[-1] + 1] = True", "inside[:] = True"),
    ("focus/pga_clutter.py", "PGA from the clutter: bins weighed by their energy",
     "data = np.asarray(data)[:, lit] / np.sqrt(level[lit])", "data = np.asarray(data)[:, lit]"),
    ("focus/autofocus_pulses.py", "PGA without the round from the clutter",
     "kept = self._across_range(sharp, level)", "kept = None"),
    ("focus/autofocus_pulses.py", "PGA's round from the clutter tried over a dominant scatterer",
     "if not level >= DOMINANCE_DB:", "if True:"),
    ("focus/autofocus_pulses.py", "PGA learning from a target whose window holds as much clutter",
     "if not found.window_scr_db >= WINDOW_SCR_DB:", "if False:"),
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
