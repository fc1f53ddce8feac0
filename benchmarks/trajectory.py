"""Benchmark: what no stop-and-hop costs and removes, and phase gradient autofocus against motion errors (issue 30).

Six tables, measured in one run (docs/physics.md (J3), (J4), (PGA), (PGA4), (PGA5)):

* ``cost``: trace and focus seconds of the default render (continuous motion: every echo
  received where the antenna has moved to) against ``stop_and_hop = true``, on the built-in
  ``urban`` block (airborne) and the trihedral at 514 km (spaceborne), each after a warm-up;
* ``error``: the stop-and-hop error the receive leg removes. The trihedral is rendered with
  continuous motion (the truth) and focused twice by direct backprojection: with the recorded
  receive positions (its apex, to the analysis's precision) and as if stop-and-hop held
  (receiver at the transmitter), which images it ``v R / c`` behind its apex (0.47 mm airborne,
  18.4 m spaceborne) with a changed peak phase; and the raw data of a ``stop_and_hop = true``
  render against the truth (NRMSE);
* ``pga``: a sinusoidal cross-track motion error of growing amplitude (40 m period, a 69 m
  aperture) on the default airborne trihedral: azimuth PSLR, IRW and peak of the image focused
  (FFBP, 0.1 m pixels) on the true track, on the nominal one, and on the nominal one after PGA,
  with PGA's iterations, its rms phase estimate and seconds;
* ``pga_lines``: PGA's dominance and point-like range lines (docs/physics.md (PGA4)) on the
  nominal-track images of a trihedral in clutter, clutter alone and a wall, rectangular and
  Taylor azimuth windows, and whether PGA ran;
* ``pga_support``: PGA's azimuth PSLR against its spectral support (40, 50, 60 dB), on a
  trihedral without clutter (Taylor) beside the exact phase correction, and one in clutter;
* ``pga_points``: the scenes of tests/test_pga_points.py (docs/physics.md (PGA4), (PGA5)): a
  trihedral off the scene centre in clutter (40 and 55 deg, Taylor azimuth window, a 2 cm, 40 m
  sway), its azimuth PSLR and IRW on the true track, the nominal one and after PGA given its
  position (``reference``), the shift removed and its bound; walls on ground without a point,
  PGA's dominance, point-like lines and the NRMSE by which it changed the image (-inf: unchanged).

Writes ``trajectory.csv`` (all rows, a ``table`` column) and ``trajectory.png`` (PSLR against
motion-error amplitude) into the output folder.

Usage: ``python benchmarks/trajectory.py [--quick] [--tiny]`` (``--tiny``: the first three tables only)
"""
from __future__ import annotations

import dataclasses
import gc
import math
import time

import numpy as np
from _lattice import nrmse_db
from _plot import plot_cost
from _table import bench_main, machine, write_csv

import sarmitsuba  # noqa: F401
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.focus import ImageGrid, backproject, ffbp
from sarmitsuba.focus.autofocus import pga
from sarmitsuba.pipeline import simulate

NAME = "trajectory"
#: The spaceborne sensor: X band, 514 km, 7.6 km/s, a 0.3 deg beam at 4 kHz, the central 1501 pulses.
SPACEBORNE = {"altitude": 514e3, "velocity": 7600.0, "prf": 4000.0, "azimuth_beamwidth": 0.3, "n_pulses": 1501}
#: Sinusoidal motion-error amplitudes [m] of the PGA sweep, at this period [m].
AMPLITUDES = (0.005, 0.01, 0.02, 0.05)
PERIOD = 40.0
#: The integrator overrides of every render here: ``max_depth`` 3, the default render's depth
#: before ``max_depth = auto``, so that the speed figures stay comparable (``bounce_depth``
#: measures ``auto``).
INTEGRATOR = {"max_depth": 3}


def _timed(scene: str, sensor: dict, **kwargs) -> tuple:
    """A simulation after a warm-up (the kernels compiled): its trace and focus seconds and the simulation."""
    simulate(scene, sensor_overrides=sensor, integrator_overrides=INTEGRATOR, **kwargs)
    gc.collect()
    sim = simulate(scene, sensor_overrides=sensor, integrator_overrides=INTEGRATOR, **kwargs)
    return sim.timings["trace"], sim.timings["focus"], sim


def cost(scenes: dict) -> list[dict]:
    """Trace and focus seconds with and without the stop-and-hop approximation."""
    rows = []
    for scene, sensor in scenes.items():
        times = {}
        for hop in (True, False):
            trace_s, focus_s, sim = _timed(scene.split("@")[0], {**sensor, "stop_and_hop": hop})
            times[hop] = (trace_s, focus_s)
            del sim
            gc.collect()
        rows.append({"table": "cost", "scene": scene, "trace_s_stop_and_hop": round(times[True][0], 3),
                     "trace_s_continuous": round(times[False][0], 3),
                     "trace_ratio": round(times[False][0] / times[True][0], 3),
                     "focus_s_stop_and_hop": round(times[True][1], 3), "focus_s_continuous": round(times[False][1], 3),
                     "focus_ratio": round(times[False][1] / max(times[True][1], 1e-9), 3)})
    return rows


def error(geometries: dict) -> list[dict]:
    """Where the trihedral images when continuous-motion data are processed as stop-and-hop."""
    rows = []
    for label, sensor in geometries.items():
        truth = simulate("trihedral", sensor_overrides=sensor, integrator_overrides=INTEGRATOR, focuser="bp",
                         image_size=(112, 48))
        raw, image = truth.raw, truth.image
        grid = ImageGrid(origin=image.origin, azimuth_direction=image.azimuth_direction,
                         range_direction=image.range_direction, azimuth=image.azimuth, range=image.range,
                         plane="ground")
        slant = float(np.linalg.norm(raw.tx_position[raw.n_pulses // 2]))
        expected = -float(np.linalg.norm(raw.velocity[0])) * slant / SPEED_OF_LIGHT
        right = analyze_point_target(backproject(raw, grid), (0.0, 0.0, 0.0), chip=32)   # same focuser, both legs
        hop = backproject(dataclasses.replace(raw, rx_position=raw.tx_position.copy(), rx_time=None), grid)
        wrong = analyze_point_target(hop, (expected, 0.0), chip=32, search_radius=8)
        flat = simulate("trihedral", sensor_overrides={**sensor, "stop_and_hop": True},
                        integrator_overrides=INTEGRATOR, focuser="bp", image_size=(8, 8)).raw
        rows.append({"table": "error", "scene": f"trihedral {label}", "v_R_over_c_m": round(expected, 6),
                     "azimuth_error_m": round(right.azimuth_error, 6),
                     "azimuth_shift_as_stop_and_hop_m": round(wrong.azimuth, 6),
                     "shift_over_closed_form": round(wrong.azimuth / expected, 4),
                     "peak_phase_change_deg": round(((wrong.peak_phase_deg - right.peak_phase_deg) + 180) % 360 - 180, 2),
                     "peak_loss_db": round(20 * math.log10(wrong.peak_magnitude / right.peak_magnitude), 2),
                     "raw_nrmse_stop_and_hop_db": round(nrmse_db(flat.data, raw.data), 1)})
    return rows


def _fine_grid(image, n_azimuth: int = 256) -> ImageGrid:
    """0.1 m pixels about the scene centre in the frame of ``image`` (25.6 m of azimuth: room for
    the paired echoes of the motion error)."""
    return ImageGrid(origin=image.origin, azimuth_direction=image.azimuth_direction,
                     range_direction=image.range_direction, azimuth=(np.arange(n_azimuth) - n_azimuth // 2) * 0.1,
                     range=(np.arange(64) - 32) * 0.2, plane="ground")


def pga_sweep(amplitudes: tuple) -> list[dict]:
    """The trihedral's azimuth response on the true track, the nominal one and after PGA."""
    rows = []
    for amplitude in amplitudes:
        sim = simulate("trihedral", sensor_overrides={"motion_error": f"{amplitude}, {PERIOD}"},
                       integrator_overrides=INTEGRATOR, focuser="ffbp", image_size=(32, 32))
        grid = _fine_grid(sim.image)
        row = {"table": "pga", "scene": "trihedral airborne", "amplitude_m": amplitude, "period_m": PERIOD}
        images = {"true": ffbp(sim.raw, grid), "nominal": ffbp(sim.raw.on_track("nominal"), grid)}
        start = time.perf_counter()
        images["pga"], report = pga(images["nominal"])
        row["pga_s"] = round(time.perf_counter() - start, 3)
        for name, image in images.items():
            try:
                measured = analyze_point_target(image, (0.0, 0.0, 0.0), chip=32, search_radius=16)
            except ValueError:                        # broken up beyond a point response: nothing to measure
                row.update({f"pslr_{name}_db": "", f"irw_{name}_m": "", f"peak_{name}": ""})
                continue
            row[f"pslr_{name}_db"] = round(measured.pslr_azimuth_db, 2)
            row[f"irw_{name}_m"] = round(measured.irw_azimuth, 4)
            row[f"peak_{name}"] = round(measured.peak_magnitude, 3)
        row["pga_iterations"] = report.iterations
        row["pga_rms_phase_rad"] = round(report.rms_phase_error, 3)
        rows.append(row)
        del sim
        gc.collect()
    return rows


#: docs/physics.md (PGA4)'s table: scenes of tests/test_pga_points.py._scene (the radar looks toward -y).
LINE_SCENES = {
    "trihedral on ground, gamma -14 dB, 45 deg": dict(incidence=45.0, trihedral=(0.0, 0.0), gamma_db=-14.0),
    "trihedral on ground, gamma 0 dB, 45 deg": dict(incidence=45.0, trihedral=(0.0, 0.0), gamma_db=0.0),
    "trihedral at (4, -2) m on ground, gamma -20 dB, 40 deg": dict(incidence=40.0, trihedral=(4.0, -2.0)),
    "rough ground alone, gamma -14 dB, 45 deg": dict(incidence=45.0, gamma_db=-14.0),
    "20 m of it, a third of a 16 x 60 m image": dict(incidence=45.0, gamma_db=-14.0, plate=10.0,
                                                     pixels=((160, 0.1), (120, 0.5))),
    "PEC wall 20 m x 6 m on ground, gamma -14 dB, 45 deg": dict(incidence=45.0, wall=True, gamma_db=-14.0),
}


def pga_lines() -> list[dict]:
    """PGA's dominance (PGA3) and point-like lines (PGA4) on nominal-track images, both windows."""
    import sys
    import warnings
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from test_pga_points import _scene
    rows = []
    for name, options in LINE_SCENES.items():
        for window in ("rect", "taylor"):
            _, nominal = _scene(**options, window=window)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out, report = pga(nominal)
            change = float(np.linalg.norm(out.data - nominal.data) / np.linalg.norm(nominal.data))
            rows.append({"table": "pga_lines", "scene": name, "window": window, "applied": report.applied,
                         "dominance_db": round(report.dominance_db, 2), "point_lines": report.lines,
                         "nrmse_db": round(20 * math.log10(change), 2) if change > 0 else "-inf"})
    return rows


def pga_points() -> list[dict]:
    """PGA with a reference point against the true track, and PGA on walls without a point."""
    import sys
    import warnings
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from test_pga_points import CLUTTER, POINTS, _scene
    rows = []
    for name, (incidence, (x, y)) in POINTS.items():
        true, nominal = _scene(incidence, trihedral=(x, y))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            images = {"true": true, "nominal": nominal}
            images["pga_ref"], report = pga(nominal, reference=(x, y, 0.0))
            bound = pga(nominal)[0].metadata["autofocus"]["linear_part"]["bound_m"]
        row = {"table": "pga_points", "scene": f"trihedral {name}", "dominance_db": round(report.dominance_db, 2),
               "point_lines": report.lines, "shift_m": round(report.linear_shift_m, 4), "shift_bound_m": bound}
        for track, image in images.items():
            measured = analyze_point_target(image, (x, y, 0.0), chip=32, search_radius=4)
            row[f"pslr_{track}_db"] = round(measured.pslr_azimuth_db, 2)
            row[f"irw_{track}_m"] = round(measured.irw_azimuth, 4)
            row[f"azimuth_{track}_m"] = round(measured.azimuth, 4)
        rows.append(row)
    rows += pga_support()
    for name, options in CLUTTER.items():
        for track, image in zip(("true", "nominal"), _scene(**options)):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out, report = pga(image)
            change = float(np.linalg.norm(out.data - image.data) / np.linalg.norm(image.data))
            rows.append({"table": "pga_points", "scene": f"{name}, {track} track", "applied": report.applied,
                         "dominance_db": round(report.dominance_db, 2), "point_lines": report.lines,
                         "nrmse_db": round(20 * math.log10(change), 2) if change > 0 else "-inf"})
    return rows


def pga_support() -> list[dict]:
    """Azimuth PSLR after PGA (with the reference) against its spectral support (SUPPORT_DB): the
    built-in trihedral without clutter (Taylor window; with the exact phase correction of every
    pulse from the recorded tracks) and the trihedral at (4, -2) m in clutter (rectangular window)."""
    import sys
    import warnings
    from pathlib import Path

    import sarmitsuba.focus.autofocus as autofocus
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from test_pga_points import _scene, trihedral_alone
    cases = {"trihedral alone, 45 deg, taylor": (trihedral_alone("taylor"), (0.0, 0.0)),
             "trihedral at (4, -2) m, 40 deg, rect": (_scene(40.0, trihedral=(4.0, -2.0), window="rect"), (4.0, -2.0))}
    rows, default = [], autofocus.SUPPORT_DB
    for name, (images, (x, y)) in cases.items():
        row = {"table": "pga_support", "scene": name}
        for track, image in zip(("true", "nominal", "exact"), images):
            if track != "nominal":
                row[f"pslr_{track}_db"] = round(analyze_point_target(image, (x, y, 0.0), chip=32,
                                                                    search_radius=4).pslr_azimuth_db, 2)
        for support in (40.0, 50.0, 60.0):
            autofocus.SUPPORT_DB = support
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    fixed, _ = pga(images[1], reference=(x, y, 0.0))
            finally:
                autofocus.SUPPORT_DB = default
            row[f"pslr_pga_support{support:g}_db"] = round(analyze_point_target(
                fixed, (x, y, 0.0), chip=32, search_radius=4).pslr_azimuth_db, 2)
        rows.append(row)
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """Continuous motion costs at most 1.25x the approximation's trace; the stop-and-hop shift is
    v R / c within 2 %; with a 2 cm error PGA restores the azimuth PSLR within 2 dB and the IRW
    within 10 % of the true track's, which the nominal track misses."""
    out = []
    for r in rows:
        if r["table"] == "cost":
            out.append((f"{r['scene']}: continuous motion traces within 1.25x stop-and-hop", r["trace_ratio"] <= 1.25,
                        f"{r['trace_ratio']}x"))
        elif r["table"] == "error":
            out.append((f"{r['scene']}: processed as stop-and-hop, the shift is v R / c within 2 %",
                        abs(r["shift_over_closed_form"] - 1.0) <= 0.02, f"{r['shift_over_closed_form']}"))
        elif r["table"] == "pga" and r["amplitude_m"] == 0.02:
            restored = abs(r["pslr_pga_db"] - r["pslr_true_db"]) <= 2.0 and \
                abs(r["irw_pga_m"] / r["irw_true_m"] - 1.0) <= 0.10
            out.append(("2 cm motion error: PGA within 2 dB PSLR and 10 % IRW of the true track", restored,
                        f"PSLR {r['pslr_pga_db']} vs {r['pslr_true_db']} dB (nominal {r['pslr_nominal_db']}), IRW "
                        f"{r['irw_pga_m']} vs {r['irw_true_m']} m"))
        elif r["table"] == "pga_points" and "pslr_pga_ref_db" in r and r["pslr_pga_ref_db"] != "":
            reached = abs(r["pslr_pga_ref_db"] - r["pslr_true_db"]) <= 3.0 and \
                abs(r["irw_pga_ref_m"] / r["irw_true_m"] - 1.0) <= 0.05
            out.append((f"{r['scene']}: PGA with a reference within 3 dB PSLR and 5 % IRW of the true track", reached,
                        f"PSLR {r['pslr_pga_ref_db']} vs {r['pslr_true_db']} dB, IRW {r['irw_pga_ref_m']} vs "
                        f"{r['irw_true_m']} m"))
        elif r["table"] == "pga_points" and r.get("applied", "") is False:
            out.append((f"{r['scene']}: no point, PGA hands the image back", r["nrmse_db"] == "-inf", "unchanged"))
    return out


def run(quick: bool = False, tiny: bool = False) -> list[dict]:
    """All six tables: print, write CSV and PNG; returns the rows."""
    print(machine())
    scenes = {"trihedral": {"n_pulses": 101}} if tiny else \
        {"urban": {}, "trihedral@spaceborne": SPACEBORNE} if not quick else {"trihedral@spaceborne": SPACEBORNE}
    geometries = {"airborne": {"n_pulses": 101}} if tiny else {"airborne": {}, "spaceborne": SPACEBORNE}
    rows = cost(scenes) + error(geometries) + pga_sweep((0.02,) if tiny or quick else AMPLITUDES)
    if not tiny:                                    # the point-like lines and the reference: about a minute
        rows += pga_lines() + pga_points()
    for row in rows:
        print("  ".join(f"{k}={v}" for k, v in row.items()))
    name = f"{NAME}{'_tiny' if tiny else ''}"
    columns = sorted({k for r in rows for k in r}, key=lambda k: (k not in ("table", "scene"), k))
    rows = [{k: r.get(k, "") for k in columns} for r in rows]            # one set of columns, "" where n/a
    write_csv(f"{name}.csv", rows)
    sweep = [r for r in rows if r["table"] == "pga"]
    plot_cost(f"{name}.png", {track: [(r["amplitude_m"], r[f"pslr_{track}_db"], f"{1e3 * r['amplitude_m']:g} mm")
                                      for r in sweep if r[f"pslr_{track}_db"] != ""] for track in ("true", "nominal", "pga")},
              xlabel="motion error amplitude [m] (40 m period)", ylabel="azimuth PSLR [dB]",
              title="trihedral: focused on the true track, the nominal one, and after PGA")
    return rows


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "trihedral only, one amplitude", "small renders (smoke test)")
