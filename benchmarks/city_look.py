"""Benchmark: a city as X-band radar sees it: surfaces by role, facades with windows, shadows at the
noise floor (docs/physics.md (RS8), (FA1)). Every figure measured in one run.

Scenes, all with ``--material-set roughness=city`` and the city examples' radar budget
:data:`BUDGET` (PRF 250 Hz, so that azimuth ambiguities stay below -20 dB; 1 W, 24 dBi, noise
figure 4 dB, losses 3 dB: ``info``'s NESZ -22.6 dB at Munich's centre):

1. Sionna's Munich, 512 central pulses; and its full default render (``--full``).
2. The footprint city ``scenes/footprints.geojson`` (five blocks) with windows
   (``--windows``, the default layout) and without; with ``--munich-windows`` also Munich's 512
   pulses with ``scene add-windows``'s windows (2.1 M triangles; more than 24 GiB).

For each image: sigma nought per unit ground area, multilooked 5 x 5, its median over the pixels
of each class, the classes cut from the geometry, never from the image
(:mod:`sarmitsuba.products.groundtruth`, :mod:`sarmitsuba.scene.roles`): **roofs** (the layover of
the roof shapes, away from any other elevated shape's layover and 3 pixels from any double-bounce
line), **lit streets** (ground
that is neither shadow, footprint nor layover, away from double bounces) and **shadows**
(shadow not overlaid). The **noise floor** is measured: the same render without thermal noise,
subtracted (the noise is additive and the focusing linear), multilooked alike, its median over
the same shadow pixels (the NESZ varies across a swath as ``R^3``); ``info``'s NESZ at the scene
centre beside it.

Bounds (ratios of one run): roofs' median >= 5 dB above the lit streets', >= 10 dB above the
shadows'; shadows within 2 dB of the measured noise floor; the footprint city with windows at
most 1.5x the time and the peak memory of the one without (each render in its own process).

Writes ``city_look.csv``. Needs Sionna RT for part 1. ``--quick``: the footprint city only.
Usage: ``python benchmarks/city_look.py [--quick] [--full] [--munich-windows]``
"""
from __future__ import annotations

import json
import math
import subprocess
import tempfile
import sys
import time
from pathlib import Path

import numpy as np

from _table import report_rows

NAME = "city_look"
#: The city examples' radar budget (sar sensor parameters): NESZ about -22 dB at Munich's centre.
BUDGET = {"prf": 250.0, "transmit_power": 1.0, "antenna_gain_db": 24.0, "noise_figure_db": 4.0, "losses_db": 3.0}
#: The integrator overrides of every render here: ``max_depth`` 3, the default render's depth
#: before ``max_depth = auto``, so that the speed figures stay comparable (``bounce_depth``
#: measures ``auto``).
INTEGRATOR = {"max_depth": 3}
LOOKS = 5
FOOTPRINTS = Path(__file__).resolve().parent.parent / "scenes" / "footprints.geojson"


def _db(x: float) -> float:
    return 10.0 * math.log10(x) if x > 0 else float("-inf")


def _classes(loaded, image) -> dict:
    from scipy.ndimage import binary_dilation
    from sarmitsuba.products.groundtruth import ground_truth, layover_mask
    from sarmitsuba.scene.roles import shape_roles
    gt = ground_truth(loaded, image)
    roles = shape_roles(loaded.scene).role
    roofs = layover_mask(loaded, image, shapes=[k for k, r in enumerate(roles) if r == "roof"])
    facades = layover_mask(loaded, image, shapes=[k for k, r in enumerate(roles) if r != "roof"])
    near = binary_dilation(gt.double_bounce, iterations=3)
    return {"roof": roofs & ~facades & ~near & gt.scene_area,
            "street": ~gt.footprint & ~gt.shadow & ~gt.layover & ~near & gt.scene_area,
            "shadow": gt.shadow & ~gt.layover & ~near & gt.scene_area}


def _sigma0(data: np.ndarray, image) -> np.ndarray:
    """Multilooked sigma nought per unit ground area of complex ``data`` on ``image``'s grid."""
    from scipy.ndimage import uniform_filter
    from sarmitsuba.analysis.point_target import energy_widths
    return uniform_filter(np.abs(data) ** 2, LOOKS) / float(np.prod(energy_widths(image)))


def one(case: str) -> dict:
    """One render in this process: seconds, peak memory and the class medians."""
    import resource
    import sarmitsuba as sm
    from sarmitsuba.pipeline import simulate
    from sarmitsuba.scene.facades import FacadeLayout
    overrides = {"roughness": "city"}
    if case == "munich-512-windows":
        from sarmitsuba.scene.loader import resolve_source
        from sarmitsuba.scene.windowed import write_windowed
        folder = Path(tempfile.mkdtemp(prefix="city_look_"))
        source = str(write_windowed(resolve_source("sionna:munich"), folder / "munich", FacadeLayout()).path)
        sensor = dict(BUDGET, n_pulses=512)
    elif case.startswith("munich"):
        source = "sionna:munich"
        sensor = dict(BUDGET, **({} if case == "munich-full" else {"n_pulses": 512}))
    else:
        source = sm.Scene.from_footprints(str(FOOTPRINTS), facade=FacadeLayout() if case == "footprints-windows"
                                          else None)
        sensor = dict(BUDGET)
    start = time.perf_counter()
    sim = simulate(source, sensor_overrides=sensor, integrator_overrides=INTEGRATOR, material_overrides=overrides)
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    image = sim.image
    if case in ("munich-full", "footprints-windows"):    # the quicklooks the guides show
        from _table import output_dir
        from sarmitsuba.products.figures import image_figure
        image_figure(image, output_dir() / f"{NAME}_{case}.png")
    sigma0 = _sigma0(image.data, image)
    row = {"case": case, "seconds": round(seconds, 1), "peak_mib": round(peak), "pixels": int(image.data.size),
           "triangles": int(sim.loaded.n_triangles)}
    noise = None
    if case not in ("munich-full", "munich-512-windows"):   # the noise alone: the render without it, subtracted
        quiet = simulate(source, sensor_overrides={k: v for k, v in sensor.items() if k != "noise_figure_db"},
                         integrator_overrides=INTEGRATOR, material_overrides=overrides)
        noise = _sigma0(image.data - quiet.image.data, image)
    # the pixels the aperture focuses (512 pulses light a strip of the grid): where the noise is
    from scipy.ndimage import binary_erosion
    support = binary_erosion((noise if noise is not None else sigma0) > 0, iterations=2 * LOOKS)
    for name, mask in _classes(sim.loaded, image).items():
        mask = mask & support
        row[f"{name}_db"] = round(_db(float(np.median(sigma0[mask]))), 2) if mask.any() else None
        row[f"{name}_pixels"] = int(mask.sum())
        if noise is not None and name == "shadow" and mask.any():
            row["noise_db"] = round(_db(float(np.median(noise[mask]))), 2)     # where the shadows are
    from sarmitsuba.info import scene_info
    row["nesz_db"] = round(scene_info(source, sensor_overrides=sensor,
                                      integrator_overrides=INTEGRATOR).radiometry.nesz_db, 2)
    return row


def run(quick: bool, full: bool = False, munich_windows: bool = False) -> list[dict]:
    cases = ["footprints-plain", "footprints-windows"] + ([] if quick else ["munich-512"]) + \
        (["munich-full"] if full else []) + (["munich-512-windows"] if munich_windows else [])
    rows = []
    for case in cases:           # each in its own process: its own peak memory
        done = subprocess.run([sys.executable, __file__, "--one", case], capture_output=True, text=True)
        if done.returncode:
            raise RuntimeError(f"{case}: {done.stderr[-2000:]}")
        rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
    return report_rows(f"{NAME}.csv", rows)


def checks(rows: list[dict]):
    by = {r["case"]: r for r in rows}
    noise = {r["case"]: r.get("noise_db") for r in rows}
    for case, r in by.items():
        floor = noise.get(case)
        if r.get("roof_db") is None:
            continue
        yield (f"{case}: roofs >= 5 dB over lit streets", r["roof_db"] - r["street_db"] >= 5.0,
               f"{r['roof_db']} vs {r['street_db']} dB")
        yield (f"{case}: roofs >= 10 dB over shadows", r["roof_db"] - r["shadow_db"] >= 10.0,
               f"{r['roof_db']} vs {r['shadow_db']} dB")
        if floor is not None:
            yield (f"{case}: shadows within 2 dB of the noise floor", abs(r["shadow_db"] - floor) <= 2.0,
                   f"{r['shadow_db']} vs {floor} dB (info NESZ {r['nesz_db']} dB)")
    for windows, plain in (("footprints-windows", "footprints-plain"), ("munich-512-windows", "munich-512")):
        if windows in by and plain in by:
            w, p = by[windows], by[plain]
            yield (f"{windows}: cost <= 1.5x time", w["seconds"] <= 1.5 * p["seconds"],
                   f"{w['seconds']} / {p['seconds']} s = {w['seconds'] / p['seconds']:.2f}x")
            yield (f"{windows}: cost <= 1.5x memory", w["peak_mib"] <= 1.5 * p["peak_mib"],
                   f"{w['peak_mib']} / {p['peak_mib']} MiB = {w['peak_mib'] / p['peak_mib']:.2f}x")


if __name__ == "__main__":
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the footprint city only")
    parser.add_argument("--full", action="store_true", help="also Munich's full default render")
    parser.add_argument("--munich-windows", action="store_true", help="also Munich's 512 pulses with windows")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one(args.one)))
        sys.exit(0)
    rows = run(args.quick, args.full, args.munich_windows)
    for check, ok, detail in checks(rows):
        print(f"{'PASS' if ok else 'FAIL'}  {check}  {detail}")
