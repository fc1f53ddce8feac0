"""Benchmark: SAR tomography (docs/physics.md (TS1)-(TS6)), every figure measured in one run.

1. **Cost on urban.** One render of the built-in urban scene (after an untimed one, so that
   Dr.Jit's kernel compilation is not counted), then stacks of N = 10 and 20 passes
   (``render_stack``, the passes spaced at 0.8 of the largest spacing that keeps urban's heights
   unambiguous), each between two single renders: the stack's seconds, and its passes' alone,
   over N times the two singles' mean (bound: 1.10x; one render's time scatters by 5 to 10 %
   over minutes on a shared 2-core machine), and the truth's seconds. The passes share
   nothing but the process: the trace is 85 % of a render, and loading and planning, which a
   shared scene would save, 1 %.
2. **A building.** A 24 x 24 x 15 m concrete block (gamma -10 dB) on rough ground (gamma
   -12 dB), 600 MHz (0.25 m of slant range: a facade, tilted against the iso-range circles,
   spreads over ``2 delta_r / sin(2 theta)`` of elevation in a cell, 0.5 m here, 2 m at 150 MHz),
   single bounce (the truth is the geometry's; a wall-ground double bounce has its phase centre
   halfway between its two bounces), 20 passes at 0.85 of the largest unambiguous spacing: the
   cells where roof, facade and ground lay over together, inverted by beamforming, Capon and
   SL1MMER (one row in 8). Per method: the share of those cells in which all three are found (a
   scatterer within 0.3 rho_s of each true crossing height, in elevation), and the median over
   the detected scatterers of ``|h - truth| / (rho_s sin(theta))``, the error in units of
   ``rho_s`` of elevation (bound: 0.1).
3. **Beamforming's two-point resolution.** Two equal scatterers at 0.8-2.5 ``rho_s`` in one cell,
   with relative phases 0, pi/2 and pi, in the Fourier model of 14 even baselines: separated or
   not, and the larger elevation error in ``rho_s``; SL1MMER on the same cells.

Writes ``tomography.csv``. ``--quick``: N = 10 only on urban, a 10 m block, part 3 at 1 and 1.5.
Usage: ``python benchmarks/tomography.py [--quick]``
"""
from __future__ import annotations

import math
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

import sarmitsuba as sm
from sarmitsuba.stacks.tomo_products import read_stack
from sarmitsuba.stacks.tomo_sparse import sl1mmer
from sarmitsuba.stacks.tomo_stack import focus_elevation
from sarmitsuba.stacks.tomography import PhaseModel, beamforming, detect_peaks
from sarmitsuba.pipeline import render
from sarmitsuba.products.elevation_truth import nearest_truth
from sarmitsuba.scene.baseline import stack_baselines
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.stack import render_stack
from _table import bench_main, report_rows

NAME = "tomography"
#: SL1MMER (about 25 ms a pixel) inverts one row in this many of the building's band.
SPARSE_ROW_STEP = 8


def _spacing(loaded, fraction: float = 0.8) -> float:
    """``fraction`` of the largest mean spacing [m] that keeps the scene's heights unambiguous."""
    p = loaded.params
    b = stack_baselines(p, span=1.0, count=3)
    extent = (float(loaded.bbox_hi[2]) - min(0.0, float(loaded.bbox_lo[2]))) / math.sin(math.radians(p.incidence_angle))
    return fraction * b.wavelength * b.slant_range / (2.0 * extent)


def _single(work: Path) -> float:
    """Seconds of one urban render."""
    start = time.perf_counter()
    render("urban", work / "single", progress=False)
    return time.perf_counter() - start


def _cost_rows(quick: bool, work: Path) -> list[dict]:
    render("urban", work / "single", progress=False)                    # untimed: Dr.Jit compiles its kernels
    d_b = _spacing(load_scene("urban"))
    rows = []
    for n in (10,) if quick else (10, 20):
        before = _single(work)                                         # the machine's speed drifts by 5-10 %
        summary = render_stack("urban", work / f"stack{n}", span=d_b * (n - 1), count=n, progress=False)
        single = 0.5 * (before + _single(work))                       # over minutes: a single render on
        rows.append({"part": "cost", "case": f"urban N={n}", "passes": n, "single_s": single,    # either side
                     "stack_s": summary.seconds, "passes_s": sum(summary.seconds_per_pass),
                     "truth_s": summary.truth_seconds, "ratio": summary.seconds / (n * single),
                     "passes_ratio": sum(summary.seconds_per_pass) / (n * single),
                     "rho_s": summary.plan.baselines.elevation_resolution})
        shutil.rmtree(work / f"stack{n}", ignore_errors=True)
    return rows


def _building(height: float, bandwidth: float = 600e6, depth: int = 1):
    import trimesh
    block = trimesh.creation.box((24.0, 24.0, height))
    block.apply_translation((0.0, 0.0, height / 2))
    ground = trimesh.Trimesh(np.array([[-45, -45, 0], [45, -45, 0], [45, 45, 0], [-45, 45, 0]], float),
                             [[0, 1, 2], [0, 2, 3]])
    sensor = {"n_pulses": 200, "bandwidth": bandwidth, "sampling_rate": 1.2 * bandwidth, "azimuth_beamwidth": 1.2,
              "prf": 250}
    return sm.Scene(meshes=[(block, {"material": "concrete", "gamma_db": -10}, "block"),
                            (ground, {"material": "medium_dry_ground", "gamma_db": -12}, "ground")],
                    sensor=sensor, integrator={"max_depth": depth})


def _building_rows(quick: bool, work: Path) -> list[dict]:
    height = 10.0 if quick else 15.0
    scene = _building(height)
    n = 20
    d_b = _spacing(load_scene(scene), 0.85)
    summary = render_stack(scene, work / "building", span=d_b * (n - 1), count=n, progress=False)
    st = read_stack([work / "building"])
    three = np.sum(np.isfinite(st.truth), axis=2) >= 3                     # roof, facade and ground together
    rows3, cols3 = np.nonzero(three)
    sin_theta = math.sin(math.radians(summary.plan.baselines.incidence))
    out = []
    for method in ("beamforming", "capon", "sparse"):
        step = SPARSE_ROW_STEP if method == "sparse" else 1            # SL1MMER: one row in SPARSE_ROW_STEP
        region = (slice(rows3.min(), rows3.max() + 1, step), slice(cols3.min(), cols3.max() + 1))
        cells = three & (np.arange(three.shape[0]) % step == rows3.min() % step)[:, None]
        start = time.perf_counter()
        result = focus_elevation(st.images, st.raws, st.interval, reference=st.reference, method=method,
                                 region=region, min_power_db=-40.0, max_scatterers=3)
        seconds = time.perf_counter() - start
        sc, rho = result.scatterers, result.elevation_resolution
        true_h = nearest_truth(st.truth[sc["row"], sc["col"]].astype(np.float64), sc["height"])
        error = np.abs(sc["height"] - true_h) / (rho * sin_theta)
        found_all = 0
        for r, c in zip(*np.nonzero(cells)):
            at = (sc["row"] == r) & (sc["col"] == c)
            crossings = st.truth[r, c][np.isfinite(st.truth[r, c])]
            found_all += all(np.any(np.abs(sc["height"][at] - h) / sin_theta < 0.3 * rho) for h in crossings)
        out.append({"part": "building", "case": method, "passes": n, "rho_s": rho, "cells": int(cells.sum()),
                    "all_three_share": found_all / max(1, cells.sum()), "scatterers": int(sc["row"].size),
                    "median_error_rho": float(np.nanmedian(error)),
                    "p90_error_rho": float(np.nanpercentile(error, 90)), "seconds": seconds,
                    "stack_s": summary.seconds})
    return out


def _resolution_rows(quick: bool) -> list[dict]:
    n, d, lam, r = 14, 1.0, 0.031, 1400.0
    b = d * (np.arange(n) - (n - 1) / 2)
    rho = lam * r / (2 * d * (n - 1))
    s = np.arange(-3 * rho, 6 * rho, rho / 16)
    phase = 4 * math.pi * np.outer(b, s) / (lam * r)
    a = np.exp(-1j * phase)[None]
    model = PhaseModel(phase=np.stack([np.zeros(n), 4 * math.pi * b / (lam * r), np.zeros(n), np.zeros(n)],
                                      axis=1)[:, :, None], height=np.array([[0.0], [1.0], [0.0], [0.0]]),
                       scale=1.0, interval=(float(s[0]), float(s[-1])), fit_error=0.0)
    rows = []
    for ratio in (1.0, 1.5) if quick else (0.8, 1.0, 1.2, 1.3, 1.5, 2.0, 2.5):
        for relative in (0.0, math.pi / 2, math.pi):
            truth = np.array([0.0, ratio * rho])
            y = (a[0][:, np.argmin(np.abs(s))] + np.exp(1j * relative) * np.exp(-1j * 4 * math.pi * b * truth[1]
                                                                                   / (lam * r)))[None]
            elev, _ = detect_peaks(beamforming(y, a), s, max_scatterers=2)
            sparse = sl1mmer(y, model, s, max_scatterers=3).elevations
            for method, found in (("beamforming", elev[0]), ("sparse", sparse[0])):
                found = np.sort(found[np.isfinite(found)])
                ok = found.size == 2
                rows.append({"part": "resolution", "case": method, "separation_rho": ratio, "phase": relative,
                             "separated": ok,
                             "error_rho": float(np.max(np.abs(found - truth)) / rho) if ok else None})
    return rows


def run(quick: bool = False) -> list[dict]:
    work = Path(tempfile.mkdtemp(prefix="tomography-"))
    try:
        rows = _resolution_rows(quick) + _building_rows(quick, work) + _cost_rows(quick, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    keys = list(dict.fromkeys(key for row in rows for key in row))
    return report_rows(f"{NAME}.csv", [{key: row.get(key) for key in keys} for row in rows])


def checks(rows: list[dict]):
    for row in rows:
        if row["part"] == "cost":
            yield (f"{row['case']}: a stack costs N single renders, within 10 %", row["ratio"] <= 1.10,
                   f"{row['ratio']:.3f}x (passes alone {row['passes_ratio']:.3f}x)")
        elif row["part"] == "building":
            yield (f"building, {row['case']}: median |h - truth| at most 0.1 rho_s", row["median_error_rho"] <= 0.1,
                   f"{row['median_error_rho']:.3f} rho_s")
        elif row["part"] == "resolution" and row["case"] == "sparse" and row["separation_rho"] >= 0.5:
            yield (f"sparse separates two points at {row['separation_rho']} rho_s, phase {row['phase']:.2f}",
                   bool(row["separated"]) and row["error_rho"] <= 0.1, f"{row['error_rho']}")


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "N = 10 on urban, a 10 m block, two separations")
