"""Benchmark: what the range kernel costs and what it buys (nearest, linear, sinc, exact).

The range kernel is how a traced path reaches the fast-time samples (docs/physics.md
(D1)-(D4)). For each kernel and fine-grid ``oversample`` (2 and 8), measured in one run after
a warm-up run of the same setting:

* **point target** (the built-in PEC trihedral): range-cut PSLR and IRW of the focused image
  against the closed forms (-13.26 dB; ``0.886 c / (2 B sin theta)`` on the ground grid) and
  the raw-data NRMSE against the ``exact`` kernel, with trace + binning seconds;
* **cost on a city block** (the built-in urban scene, 64 pulses): trace + binning seconds and
  the raw-data NRMSE against ``exact`` — where ``exact`` (paths x samples) shows its price.

Writes ``range_kernel.csv`` (in the output folder, ``_table.output_dir``) and ``range_kernel.png`` (raw NRMSE against
seconds, one point per kernel and oversample).

Usage: ``python benchmarks/range_kernel.py [--quick]``
"""
from __future__ import annotations

import gc
import math

import numpy as np

import sarmitsuba  # noqa: F401
from _plot import plot_cost
from _table import bench_main, machine, write_csv
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.pipeline import simulate

KERNELS = ("nearest", "linear", "sinc", "exact")
PSLR_RECT_DB = -13.26
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the speed figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3


def _sim(scene: str, kernel: str, oversample: int, sensor: dict):
    overrides = {"max_depth": MAX_DEPTH, "range_kernel": kernel, "oversample": oversample}
    # rect window: the range IRW and PSLR are compared with the unweighted sinc's closed forms
    simulate(scene, sensor_overrides=sensor, integrator_overrides=overrides, window="rect")   # warm-up (compile)
    gc.collect()
    return simulate(scene, sensor_overrides=sensor, integrator_overrides=overrides, window="rect")


def _nrmse_db(a: np.ndarray, ref: np.ndarray) -> float:
    return round(20 * math.log10(max(float(np.linalg.norm(a - ref) / np.linalg.norm(ref)), 1e-15)), 1)


def sweep(scene: str, sensor: dict, oversamples: tuple[int, ...], point_target: bool) -> list[dict]:
    """One row per (oversample, kernel). Each simulation is dropped once measured (a live
    Mitsuba scene slows the tracing of later ones); ``exact`` runs first, as the reference."""
    rows = []
    for oversample in oversamples:
        ref = None
        for kernel in ("exact",) + tuple(k for k in KERNELS if k != "exact"):
            sim = _sim(scene, kernel, oversample, sensor)
            if ref is None:
                ref = sim.raw.data
            row = {"scene": scene, "kernel": kernel, "oversample": oversample,
                   "seconds": round(sim.timings["trace"] + sim.timings["bin"], 3),
                   "raw_nrmse_vs_exact_db": _nrmse_db(sim.raw.data, ref) if kernel != "exact" else float("-inf")}
            if point_target:
                p = sim.loaded.params
                irw_theory = 0.886 * SPEED_OF_LIGHT / (2 * p.bandwidth * math.sin(math.radians(p.incidence_angle)))
                rep = analyze_point_target(sim.image, [0.0, 0.0, 0.0])
                row.update(pslr_range_db=round(rep.pslr_range_db, 3),
                           pslr_range_error_db=round(rep.pslr_range_db - PSLR_RECT_DB, 3),
                           irw_range_error_pct=round(100 * (rep.irw_range / irw_theory - 1), 3))
            rows.append(row)
            del sim
            gc.collect()
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The interpolation orders of the three kernels (raw NRMSE against ``exact``):

    * at the lowest oversampling, ``sinc < linear < nearest`` (from 8 on, both below ``nearest``);
    * ``nearest`` errs by about a bin fraction (first order): from each oversampling to the next
      its error falls by at least 0.7 of ``20 log10`` of their ratio;
    * ``linear`` errs by the curvature over a bin (second order): by at least 0.7 of
      ``40 log10`` of the ratio;
    * ``sinc`` (an 8-tap Lanczos window) has a floor of its own, the window's truncation, that
      oversampling does not lower: at or below -45 dB at every oversampling. Past the
      oversampling where ``linear`` falls below that floor (about 8: README, "Range kernel"),
      ``linear`` may be the closer of the two, and no ordering of them is asserted there.
    """
    err = {(r["scene"], r["kernel"], int(r["oversample"])): r["raw_nrmse_vs_exact_db"] for r in rows}
    out = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        factors = sorted({int(r["oversample"]) for r in rows if r["scene"] == scene})
        e = {k: err[scene, k, factors[0]] for k in ("nearest", "linear", "sinc")}
        if factors[0] <= 4:
            out.append((f"{scene} oversample {factors[0]}: sinc < linear < nearest (raw NRMSE vs exact)",
                        e["sinc"] < e["linear"] < e["nearest"], str(e)))
        else:
            out.append((f"{scene} oversample {factors[0]}: sinc and linear < nearest (raw NRMSE vs exact)",
                        max(e["sinc"], e["linear"]) < e["nearest"], str(e)))
        for lo, hi in zip(factors, factors[1:]):
            octave = 20.0 * math.log10(hi / lo)
            for kernel, order in (("nearest", 1), ("linear", 2)):
                fall = err[scene, kernel, lo] - err[scene, kernel, hi]
                out.append((f"{scene}: {kernel} falls as oversample^-{order} ({lo} -> {hi}: at least "
                            f"{0.7 * order * octave:.1f} dB)", fall >= 0.7 * order * octave, f"{fall:.1f} dB"))
        worst = max(err[scene, "sinc", f] for f in factors)
        out.append((f"{scene}: sinc at or below its -45 dB floor at every oversampling", worst <= -45.0,
                    f"worst {worst} dB"))
    return out


def run(quick: bool = False) -> list[dict]:
    """Run both sweeps, print, write CSV and PNG; returns the rows."""
    print(machine())
    rows = sweep("trihedral", {"n_pulses": 64 if quick else 256}, (2, 8), point_target=True)
    if not quick:
        rows += sweep("urban", {"n_pulses": 64}, (8,), point_target=False)
    keys = list(dict.fromkeys(k for r in rows for k in r))
    rows = [{k: r.get(k, "") for k in keys} for r in rows]
    for row in rows:
        print("  ".join(f"{k}={v}" for k, v in row.items() if v != ""))
    write_csv("range_kernel.csv", rows)
    series = {}
    for r in rows:
        if r["kernel"] != "exact":
            series.setdefault(f"{r['scene']}, oversample {r['oversample']}", []).append(
                (r["seconds"], r["raw_nrmse_vs_exact_db"], r["kernel"]))
    plot_cost("range_kernel.png", series, xlabel="trace + binning time [s]", ylabel="raw NRMSE vs exact [dB]",
              title="range kernel: accuracy against time (exact kernel = reference)")
    return rows


def main() -> None:
    bench_main(__doc__, run, checks, quick_help="trihedral only, 64 pulses")


if __name__ == "__main__":
    main()
