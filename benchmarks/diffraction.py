"""Benchmark: edge diffraction (issue 54): what the edge currents buy against full wave, and what they cost.

Four parts, in one run:

* **patterns**: the plates below at the carrier, every table angle from 0 to 60 deg: full wave
  against PO plus the edge currents evaluated by their NumPy reference
  (``edges.plate_scattering``, which the tracer's terms follow, tests/test_edges.py), and PO alone
  (``diffraction_patterns.csv``);
* **plates**: PEC plates, alone, horizontal, across incidence angles 10 to 60 deg, HH and VV: the
  RCS integrated from the focused image (``analyze``) with physical optics alone and with PO plus
  the edge currents (``sbr`` ``diffraction`` false / true), against the full-wave tables of
  ``tests/data/fullwave/`` (bempp-cl, ``benchmarks/fullwave.py``) averaged as the image weighs the
  pulses and the band. Four sweeps: the 4-wavelength square with the plane of incidence along
  an edge and turned 30 deg from it, the 4 x 2 rectangle along either side. Writes
  ``diffraction_plates.csv`` and ``diffraction_plates.png`` (the curves);
* **corners**: the full-wave dihedral (3 x 2 wavelengths) and cube (2 wavelengths) tables
  against the simulator at ``max_depth`` 3, at a few angles (``diffraction_corners.csv``);
* **cost**: the built-in ``urban`` scene and Sionna's Munich (512 central pulses; skipped without
  Sionna RT or with ``--quick``), each rendered warm with diffraction true and false, alternately,
  best of two each: the trace and render seconds and their ratio (the issue's bound for
  switching it on by default: 1.2); the image NRMSE of PO alone against PO plus edge currents,
  ``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB]; and the share of the diffraction's power (the
  image difference) in each bounce order: the edges lit through a mirror (a roof edge in the
  ground's mirror), from ``split_bounces`` (``diffraction.csv``).

Usage: ``python benchmarks/diffraction.py [--quick]`` (``--quick``: every 10 deg, urban only).
"""
from __future__ import annotations

import gc
import importlib.util
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

import sarmitsuba
from _table import bench_main, machine, output_dir, report_rows, write_csv
from sarmitsuba.pipeline import simulate

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from test_fullwave_plate import TABLES, fullwave_rcs_db  # noqa: E402
from test_patches import WAVELENGTH, rectangle, sensor  # noqa: E402

NAME = "diffraction"
#: (table, observation plane phi [deg], plate side along the table's x and y [wavelengths]).
PLATES = [("square", 0.0, 4.0, 4.0), ("square_az30", 30.0, 4.0, 4.0), ("rect", 0.0, 4.0, 2.0), ("rect", 90.0, 4.0, 2.0)]
#: Where the issue's acceptance looks: full wave within this of the sweep's peak, up to 60 deg.
WINDOW_DB = 25.0
BOUND_DB = 1.5
#: The bound for plates with a rim shorter than :data:`LONG_RIM` wavelengths. The edge currents
#: run on straight edges and carry no corner diffraction; on the 4 x 2 rectangle's 2-wavelength
#: rims the corners matter: in full wave the square minus the rectangle (the same rims, 2
#: wavelengths longer) differs from a strip's echo width by up to 5 dB in HH (0.4 dB in VV), and
#: the rectangle measures 1.5 to 2.9 dB off (README, "Edges against full wave").
SHORT_RIM_BOUND_DB = 3.0
#: Rims of at least this many wavelengths are held to :data:`BOUND_DB`.
LONG_RIM = 4.0
#: The bounce orders of the corners and the cost: 3, the default render's depth before
#: ``max_depth = auto``, so that the figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3


def _nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    return 10.0 * math.log10(float(np.sum(np.abs(a - b) ** 2)) / max(float(np.sum(np.abs(b) ** 2)), 1e-300))


def _sweep(case: str, phi: float) -> dict:
    table = json.loads((TABLES / f"{case}.json").read_text())
    return next(s for s in table["sweeps"] if abs(s["phi_deg"] - phi) < 1e-6)


def _plate(phi: float, ax: float, by: float):
    """The table's plate in the world: heading 0 looks from +y (world azimuth 90 deg), so the
    table's frame turns by ``90 - phi`` about z."""
    turn = math.radians(90.0 - phi)
    c, s = math.cos(turn), math.sin(turn)
    half_x, half_y = ax * WAVELENGTH / 2, by * WAVELENGTH / 2
    return rectangle((0, 0, 0), (half_x * c, half_x * s, 0.0), (-half_y * s, half_y * c, 0.0))


def _rcs_db(sim) -> float:
    """The image's integrated RCS at the origin: the default chip, else a wider one (near nadir the
    ground-range cell is long), else a narrower one (a short image); NaN where none fits."""
    for chip in (64, 128, 32):
        try:
            return sarmitsuba.analyze(sim.image, (0, 0, 0), raw=sim.raw, chip=chip).rcs_db
        except ValueError:
            continue
    return float("nan")


def plates(quick: bool) -> list[dict]:
    """Image RCS of each plate sweep against the table, PO alone and with the edge currents."""
    angles = np.arange(10.0, 61.0, 10.0) if quick else np.arange(10.0, 60.1, 2.5)
    rows = []
    for case, phi, ax, by in PLATES:
        sweep = _sweep(case, phi)
        plate = _plate(phi, ax, by)
        for pol in ("HH", "VV"):
            for incidence in angles:
                got = {}
                for on in (True, False):
                    start = time.perf_counter()
                    sim = simulate(sarmitsuba.Scene([(plate, "pec", "plate")],
                                                    sensor=sensor(0.0, incidence_angle=float(incidence), polarization=pol),
                                                    integrator={"max_depth": 1, "diffraction": on}))
                    got[on] = (_rcs_db(sim), time.perf_counter() - start)
                reference = fullwave_rcs_db(sim, sweep, pol)
                rows.append(dict(case=case, phi_deg=phi, polarization=pol, incidence_deg=float(incidence),
                                 fullwave_dbsm=round(reference, 2), po_edges_dbsm=round(got[True][0], 2),
                                 po_dbsm=round(got[False][0], 2), po_edges_error_db=round(got[True][0] - reference, 2),
                                 po_error_db=round(got[False][0] - reference, 2), seconds_on=round(got[True][1], 2),
                                 seconds_off=round(got[False][1], 2)))
                print(rows[-1], flush=True)
            gc.collect()
    write_csv(f"{NAME}_plates.csv", rows)
    return rows


def patterns() -> list[dict]:
    """The plates' monostatic patterns at the carrier, every table angle to 60 deg: full wave
    against the edge currents' NumPy reference (:func:`sarmitsuba.tracing.integration.edges.plate_scattering`,
    which the tracer's terms equal, tests/test_edges.py) and against PO alone [dB over lambda^2]."""
    from sarmitsuba.tracing.integration.edges import plate_scattering
    from sarmitsuba.tracing.integration.physical_optics import polygon_integral
    rows = []
    for case, phi, ax, by in PLATES:
        sweep = _sweep(case, phi)
        corners = np.array([[-ax / 2, -by / 2, 0], [ax / 2, -by / 2, 0], [ax / 2, by / 2, 0], [-ax / 2, by / 2, 0]])
        theta = np.asarray(sweep["theta_deg"])
        theta = theta[theta <= 60.0]
        t, p = np.radians(theta), math.radians(phi)
        toward = np.stack([np.sin(t) * math.cos(p), np.sin(t) * math.sin(p), np.cos(t)], axis=1)
        model = plate_scattering(corners, 2 * math.pi, toward)
        po = np.array([-1j * abs(u[2]) * polygon_integral(corners, np.array([0, 0, 1.0]), 4 * math.pi * u) for u in toward])
        for pol in ("HH", "VV"):
            c = pol.lower()
            for i, angle in enumerate(theta):
                rows.append(dict(case=case, phi_deg=phi, polarization=pol, incidence_deg=float(angle),
                                 fullwave_db=round(float(sweep[f"sigma_{c}_db"][i]), 2),
                                 po_edges_db=round(float(10 * np.log10(4 * np.pi * abs(model[c][i]) ** 2)), 2),
                                 po_db=round(float(10 * np.log10(max(4 * np.pi * abs(po[i]) ** 2, 1e-10))), 2)))
    write_csv(f"{NAME}_patterns.csv", rows)
    return rows


def _peak_dbsm(case: str, phi: float) -> float:
    """The sweep's co-polar peak (normal incidence for a plate) [dBsm at the carrier]."""
    sweep = _sweep(case, phi)
    return max(max(sweep["sigma_hh_db"]), max(sweep["sigma_vv_db"])) + 20 * math.log10(WAVELENGTH)


def _in_window(rows: list[dict], case: str, phi: float) -> np.ndarray:
    """Where full wave (as the image weighs it) lies within WINDOW_DB of the sweep's peak."""
    sweep = [r for r in rows if r["case"] == case and r["phi_deg"] == phi]
    return np.array([r["fullwave_dbsm"] >= _peak_dbsm(case, phi) - WINDOW_DB for r in sweep])


def _figure(rows: list[dict], pattern_rows: list[dict] = ()) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, len(PLATES), figsize=(4.2 * len(PLATES), 7.0), dpi=90, sharex=True)
    to_dbsm = 20 * math.log10(WAVELENGTH)
    for column, (case, phi, ax_, by) in enumerate(PLATES):
        sweep = _sweep(case, phi)
        for line, pol in enumerate(("HH", "VV")):
            ax = axes[line, column]
            theta = np.asarray(sweep["theta_deg"])
            ax.plot(theta, np.asarray(sweep[f"sigma_{pol.lower()}_db"]) + to_dbsm, color="0.75", lw=1,
                    label="full wave, carrier")
            model = [r for r in pattern_rows if r["case"] == case and r["phi_deg"] == phi and r["polarization"] == pol]
            if model:
                ax.plot([r["incidence_deg"] for r in model], [r["po_edges_db"] + to_dbsm for r in model], "-",
                        color="tab:red", lw=0.8, alpha=0.6, label="PO + edge currents, carrier")
            sel = [r for r in rows if r["case"] == case and r["phi_deg"] == phi and r["polarization"] == pol]
            x = [r["incidence_deg"] for r in sel]
            ax.plot(x, [r["fullwave_dbsm"] for r in sel], "k-", lw=1.5, label="full wave, as the image weighs it")
            ax.plot(x, [r["po_edges_dbsm"] for r in sel], "o-", color="tab:red", ms=3, label="PO + edge currents")
            ax.plot(x, [r["po_dbsm"] for r in sel], "s--", color="tab:blue", ms=3, label="PO alone")
            peak = _peak_dbsm(case, phi)
            ax.axhline(peak - WINDOW_DB, color="0.5", ls=":", lw=1)
            ax.set_xlim(0, 62)
            ax.set_ylim(peak - 50, peak + 3)
            ax.set_title(f"{case} {ax_:g}x{by:g} wavelengths, phi {phi:g} deg, {pol}", fontsize=9)
            ax.grid(True, alpha=0.3)
            if line == 1:
                ax.set_xlabel("incidence [deg]")
            if column == 0:
                ax.set_ylabel("RCS [dBsm]")
    axes[0, 0].legend(fontsize=7, loc="upper right")
    fig.suptitle("PEC plates at 9.6 GHz: image RCS against the method-of-moments tables "
                 "(dotted: 25 dB below the peak)", fontsize=10)
    fig.tight_layout()
    path = output_dir() / f"{NAME}_plates.png"
    fig.savefig(path)
    plt.close(fig)
    print(f"wrote {path}")
    return path


def corners(quick: bool) -> list[dict]:
    """The dihedral and the cube against their tables, at depth 3 (:data:`MAX_DEPTH`), at the carrier
    (their patterns do not scale with the band as a plate's does: the table's value at the
    incidence angle)."""
    lam = WAVELENGTH
    floor = rectangle((0, lam, 0), (1.5 * lam, 0, 0), (0, lam, 0))
    wall = rectangle((0, 0, lam), (1.5 * lam, 0, 0), (0, 0, lam))
    import trimesh
    cube = trimesh.creation.box((2 * lam, 2 * lam, 2 * lam))
    cube.apply_translation((0, 0, 0))
    # the dihedral's table looks in the plane phi = 90 (the fold along x): heading 0 looks from +y;
    # the cube's in phi = 0 (any face plane: the cube is symmetric)
    scenes = {"dihedral": ([(floor, "pec", "floor"), (wall, "pec", "wall")], 90.0),
              "box": ([(cube, "pec", "cube")], 0.0)}
    angles = (30.0, 45.0) if quick else (15.0, 30.0, 45.0, 60.0)
    rows = []
    for case, (meshes, phi) in scenes.items():
        sweep = _sweep(case, phi)
        for pol in ("HH", "VV"):
            for incidence in angles:
                got = {}
                for on in (True, False):
                    sim = simulate(sarmitsuba.Scene(meshes, sensor=sensor(0.0, incidence_angle=incidence,
                                                                          polarization=pol),
                                                    integrator={"max_depth": MAX_DEPTH, "diffraction": on}))
                    got[on] = _rcs_db(sim)
                reference = float(np.interp(incidence, sweep["theta_deg"], sweep[f"sigma_{pol.lower()}_db"])) \
                    + 20 * math.log10(lam)
                rows.append(dict(case=case, polarization=pol, incidence_deg=incidence, fullwave_dbsm=round(reference, 2),
                                 po_edges_error_db=round(got[True] - reference, 2),
                                 po_error_db=round(got[False] - reference, 2)))
                print(rows[-1], flush=True)
    write_csv(f"{NAME}_corners.csv", rows)
    return rows


def _render(source: str, diffraction: bool, pulses: int | None):
    sensor_overrides = {"n_pulses": pulses} if pulses else None
    start = time.perf_counter()
    sim = simulate(source, sensor_overrides=sensor_overrides,
                   integrator_overrides={"max_depth": MAX_DEPTH, "diffraction": diffraction, "split_bounces": True})
    total = time.perf_counter() - start
    return sim, total, float(sim.timings.get("trace", float("nan")))


def measure(source: str, pulses: int | None = None) -> dict:
    """Seconds with and without diffraction (best of two, alternating), the image change and the
    share of the diffraction's power per bounce order."""
    times = {True: [], False: []}
    sims = {}
    for _ in range(2):
        for on in (True, False):
            sim, total, trace = _render(source, on, pulses)
            times[on].append((total, trace))
            sims[on] = sim
            gc.collect()
    (t_on, tr_on), (t_off, tr_off) = (min(times[k]) for k in (True, False))
    on, off = sims[True], sims[False]
    row = dict(scene=source, pulses=int(on.raw.data.shape[0]), render_on_s=round(t_on, 2), render_off_s=round(t_off, 2),
               render_ratio=round(t_on / t_off, 3), trace_on_s=round(tr_on, 2), trace_off_s=round(tr_off, 2),
               image_change_db=round(_nrmse_db(off.image.data, on.image.data), 1))
    powers = [float(np.sum(np.abs(a.data - b.data) ** 2)) for a, b in zip(on.images_per_order, off.images_per_order)]
    total = sum(powers) or 1.0
    for k, p in enumerate(powers, start=1):
        row[f"order{k}_share_db"] = round(10 * math.log10(max(p / total, 1e-30)), 1)
    return row


def cost(quick: bool) -> list[dict]:
    rows = [measure("urban")]
    if not quick and importlib.util.find_spec("sionna") is not None:
        rows.append(measure("sionna:munich", pulses=512))
    return report_rows(f"{NAME}.csv", rows)


def run(quick: bool = False) -> list[dict]:
    """All three parts; each row carries its part's name."""
    print(machine())
    pattern_rows = patterns()
    plate_rows = plates(quick)
    _figure(plate_rows, pattern_rows)
    rows = [dict(part="patterns", **r) for r in pattern_rows]
    rows += [dict(part="plates", **r) for r in plate_rows]
    rows += [dict(part="corners", **r) for r in corners(quick)]
    rows += [dict(part="cost", **r) for r in cost(quick)]
    return rows


def checks(rows):
    """The plates within 1.5 dB of full wave (3 dB with 2-wavelength rims: :data:`SHORT_RIM_BOUND_DB`) wherever it lies within 25 dB of
    its peak (per sweep and polarisation), in the pattern at the carrier from 0 deg and in the
    image from 10 deg; and diffraction's render time at most 1.2 x without."""
    to_dbsm = 20 * math.log10(WAVELENGTH)
    for case, phi, a, b in PLATES:
        bound = BOUND_DB if min(a, b) >= LONG_RIM else SHORT_RIM_BOUND_DB
        peak = _peak_dbsm(case, phi) - to_dbsm
        for pol in ("HH", "VV"):
            sel = [r for r in rows if r["part"] == "patterns" and r["case"] == case and r["phi_deg"] == phi
                   and r["polarization"] == pol and r["fullwave_db"] >= peak - WINDOW_DB]
            errors = [abs(r["po_edges_db"] - r["fullwave_db"]) for r in sel]
            po = [abs(r["po_db"] - r["fullwave_db"]) for r in sel]
            worst = max(errors, default=0.0)
            yield (f"pattern {case} phi {phi:g} {pol}: PO + edges within {bound} dB of full wave (within "
                   f"{WINDOW_DB:g} dB of its peak, 0 to 60 deg)", worst <= bound,
                   f"max {worst:.2f} dB over {len(errors)} angles (PO alone: {max(po, default=0.0):.2f} dB)")
    plate_rows = [r for r in rows if r["part"] == "plates"]
    for case, phi, a, b in PLATES:
        bound = BOUND_DB if min(a, b) >= LONG_RIM else SHORT_RIM_BOUND_DB
        window = _in_window(plate_rows, case, phi)
        sweep = [r for r in plate_rows if r["case"] == case and r["phi_deg"] == phi]
        for pol in ("HH", "VV"):
            errors = [abs(r["po_edges_error_db"]) for r, w in zip(sweep, window) if w and r["polarization"] == pol]
            po = [abs(r["po_error_db"]) for r, w in zip(sweep, window) if w and r["polarization"] == pol]
            worst = max(errors, default=0.0)
            yield (f"image {case} phi {phi:g} {pol}: PO + edges within {bound} dB of full wave (within "
                   f"{WINDOW_DB:g} dB of its peak, 10 to 60 deg)", worst <= bound,
                   f"max {worst:.2f} dB over {len(errors)} angles (PO alone: {max(po, default=0.0):.2f} dB)")
    for row in (r for r in rows if r["part"] == "cost"):
        yield (f"{row['scene']}: render with diffraction <= 1.2 x without", row["render_ratio"] <= 1.2,
               f"{row['render_on_s']} s / {row['render_off_s']} s = {row['render_ratio']}")


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "every 10 deg, urban only (no Munich)")
