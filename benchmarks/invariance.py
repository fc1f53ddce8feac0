"""Benchmark: how much of the image is the scene's, and how much the tracer's lattices (issue 26).

The image should be a function of the scene alone. Three things the tracer chooses, and the
scene does not, can change it; for each scene this measures, in one run, the image NRMSE
``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB] (complex, and of magnitudes) against the default
render, with each setting's trace seconds (the faster of two runs):

* **lattice moved**: the ray-tube lattice moved by (0.37, 0.41) of a cell along track and in
  ground range. Moving every mesh by whole image pixels that are not whole lattice cells, and
  moving the image back, is the same change (the lattice is anchored at the scene centre): it
  measures the staircase that tubes leave at facet edges and shadow boundaries
  (docs/physics.md (T3));
* **dense rays**: tubes a third of the default width (nine times the rays), the reference the
  default converges to;
* **one pulse per trace**: every pulse traced from its own antenna, against the default
  sub-aperture (docs/physics.md (T3)).

Scenes: the built-in ``urban``, a smooth block of nine buildings turned 30 to 86 deg from the
track (``block``, built here), the same block rough, and Sionna's Munich as shipped (512 central
pulses; needs the ``sionna`` extra); then urban and both blocks again with ``lit_regions = cells``
(docs/physics.md (T6)), each against its own cells render, Munich at 64 pulses with tiles and with
cells (the lattice move only), and three second-bounce scenes (a wall on the ground
parallel to the track and turned 37 deg, a box turned 37 deg; :func:`wall_scenes`) with tiles and
with cells. The issue's acceptance asks for <= -30 dB in every row (magnitudes for the
lattice move, complex images otherwise); the ``meets`` column says which rows do. Writes ``invariance.csv`` and ``invariance.png`` (NRMSE against
trace seconds) into the output folder (``_table.output_dir``).

Usage: ``python benchmarks/invariance.py [--quick] [--tiny]`` (quick: urban and the block;
tiny: the block with 64 pulses, lattice move and one pulse per trace, a smoke test).
"""
from __future__ import annotations

import gc
import importlib.util
import math

import numpy as np
import trimesh
from _lattice import moved_lattice, nrmse_db
from _plot import report_per_scene
from _table import bench_main, machine

import sarmitsuba
from sarmitsuba.pipeline import simulate

NAME = "invariance"
#: Lattice offset of the "lattice moved" setting, in cells (along track, ground range).
LATTICE_SHIFT = (0.37, 0.41)
#: The dense reference's tube width, as a fraction of the default (the azimuth resolution).
DENSE = 1.0 / 3.0
#: The issue's acceptance level for every comparison [dB].
TARGET_DB = -30.0


def block(n_pulses: int | None = None, rough: bool = False) -> sarmitsuba.Scene:
    """Nine smooth concrete boxes, 14 m x 10 m x 8..25 m, on a 160 m smooth ground, each turned
    30 + 7 k deg from the track (oblique: their edges cross the ray lattice), X band, 1 km up;
    ``rough``: the ground and the walls rough (constant gamma, -15 dB and -10 dB)."""
    rng = np.random.default_rng(1)
    ground = trimesh.Trimesh([[-80, -80, 0], [80, -80, 0], [80, 80, 0], [-80, 80, 0]], [[0, 1, 2], [0, 2, 3]])
    wall = {"material": "concrete", **({"gamma_db": -10.0} if rough else {})}
    meshes = [(ground, {"material": "medium_dry_ground", **({"gamma_db": -15.0} if rough else {})}, "ground")]
    for k, (ix, iy) in enumerate((ix, iy) for ix in (-1, 0, 1) for iy in (-1, 0, 1)):
        height = float(rng.uniform(8, 25))
        jx, jy = rng.uniform(-3, 3, size=2)
        box = trimesh.creation.box((14, 10, height))
        box.apply_translation((0, 0, height / 2))
        box.apply_transform(trimesh.transformations.rotation_matrix(math.radians(30 + 7 * k), (0, 0, 1)))
        box.apply_translation((ix * 30 + jx, iy * 30 + jy, 0))
        meshes.append((box, wall, f"building{k}"))
    sensor = {"frequency": 9.6e9, "bandwidth": 150e6, "sampling_rate": 180e6, "prf": 250, "velocity": 100,
              "altitude": 1000, "incidence_angle": 45, "scene_center": (0.0, 0.0, 0.0), "azimuth_beamwidth": 1.2}
    if n_pulses:
        sensor["n_pulses"] = n_pulses
    return sarmitsuba.Scene(meshes=meshes, sensor=sensor, integrator={"max_depth": 3}, name="rough block" if rough else "block")


def wall_scenes() -> dict:
    """Second-bounce cases, 256 pulses, depth 2, the block's sensor: a 14 m x 10 m concrete wall
    on a 160 m smooth ground parallel to the track and turned 37 deg (a dihedral), and a
    14 m x 10 m x 15 m box turned 37 deg on the ground."""
    sensor = dict(block().sensor, n_pulses=256)
    ground = trimesh.Trimesh([[-80, -80, 0], [80, -80, 0], [80, 80, 0], [-80, 80, 0]], [[0, 1, 2], [0, 2, 3]])
    scenes = {}
    for label, turn in (("wall parallel to the track", 0.0), ("wall turned 37 deg", 37.0)):
        wall = trimesh.Trimesh([[-7, 0, 0], [7, 0, 0], [7, 0, 10], [-7, 0, 10]], [[0, 2, 1], [0, 3, 2]])
        wall.apply_transform(trimesh.transformations.rotation_matrix(math.radians(turn), (0, 0, 1)))
        scenes[label] = [(wall, {"material": "concrete"}, "wall")]
    box = trimesh.creation.box((14, 10, 15))
    box.apply_translation((0, 0, 7.5))
    box.apply_transform(trimesh.transformations.rotation_matrix(math.radians(37), (0, 0, 1)))
    scenes["box turned 37 deg"] = [(box, {"material": "concrete"}, "box")]
    return {label: sarmitsuba.Scene(meshes=[(ground, {"material": "medium_dry_ground"}, "ground"), *meshes],
                                    sensor=sensor, integrator={"max_depth": 2}, name="wall")
            for label, meshes in scenes.items()}


def _run(scene, sensor: dict, integrator: dict, shift=None) -> tuple[dict, np.ndarray, float]:
    """One simulation, run twice: its numbers (the faster trace's seconds), image and azimuth
    resolution (the simulation itself is dropped: a live scene slows later traces)."""
    with moved_lattice(shift):
        seconds = []
        for _ in range(2):
            sim = simulate(scene, sensor_overrides=sensor, integrator_overrides=integrator)
            seconds.append(sim.timings["trace"])
            numbers = {"trace_s": round(min(seconds), 3), "closest_hit_casts": int(sim.trace.rays_per_order.sum()),
                       "pulses": sim.raw.n_pulses}
            image, resolution = sim.image.data.copy(), sim.loaded.params.azimuth_resolution
            del sim
            gc.collect()
    return numbers, image, resolution


def sweep(label: str, scene, sensor: dict, tiny: bool = False, lit: dict | None = None,
          per_pulse: bool = True) -> list[dict]:
    """Rows of one scene: the default render and each comparison against it; with ``lit`` (for
    example ``{"lit_regions": "cells"}``) every render takes those integrator settings, and the
    rows compare the lattice move and (``per_pulse``) one pulse per trace only."""
    lit = lit or {}
    base, reference, resolution = _run(scene, sensor, dict(lit))
    rows = [{"scene": label, "setting": "default", **base, "nrmse_complex_db": float("-inf"),
             "nrmse_magnitude_db": float("-inf")}]
    settings = [("lattice moved", {}, LATTICE_SHIFT)]
    if per_pulse:
        settings.append(("one pulse per trace", {"pulses_per_trace": 1}, None))
    if not tiny and not lit:
        settings.insert(1, (f"dense rays (1/{round(1 / DENSE)} width)", {"ray_spacing": DENSE * resolution}, None))
    for setting, integrator, shift in settings:
        numbers, other, _ = _run(scene, sensor, {**lit, **integrator}, shift)
        rows.append({"scene": label, "setting": setting, **numbers,
                     "nrmse_complex_db": round(nrmse_db(reference, other), 1),
                     "nrmse_magnitude_db": round(nrmse_db(np.abs(reference), np.abs(other)), 1)})
    for row in rows:
        row["trace_ratio"] = round(row["trace_s"] / rows[0]["trace_s"], 3)
        # the acceptance compares magnitudes for lattice moves (a move in ground range changes
        # the carrier), complex images otherwise
        column = "nrmse_magnitude_db" if row["setting"] == "lattice moved" else "nrmse_complex_db"
        row["meets"] = bool(row[column] <= TARGET_DB) if row["setting"] != "default" else ""
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """Ratios that hold today: with whole tiles (the default) the sub-aperture changes the image
    less than moving the lattice does (the lattice is the larger fingerprint); with cell pieces
    the lattice move stays within the issue's -30 dB (magnitudes), and Munich's (depth 3, not
    there yet) at least 10 dB below the tiles'. The default's own -30 dB is the ``meets`` column,
    not a check: it is not met (docs/physics.md (T6))."""
    out = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        mine = {r["setting"]: r for r in rows if r["scene"] == scene}
        lattice = mine["lattice moved"]
        tiles = next((r for r in rows if r["scene"] == scene.removesuffix(", cells")
                      and r["setting"] == "lattice moved"), None)
        if scene.startswith("munich") and scene.endswith("cells") and tiles is not None:
            # Munich at depth 3: the later bounces' pieces are not invariant yet (physics.md (T6))
            out.append((f"{scene}: the lattice move is at least 10 dB below the tiles'",
                        bool(lattice["nrmse_magnitude_db"] <= tiles["nrmse_magnitude_db"] - 10.0),
                        f"{lattice['nrmse_magnitude_db']} dB against {tiles['nrmse_magnitude_db']} dB"))
        elif scene.endswith("cells"):
            out.append((f"{scene}: the lattice move stays within {TARGET_DB:g} dB", bool(lattice["meets"]),
                        f"{lattice['nrmse_magnitude_db']} dB"))
        elif "one pulse per trace" in mine:
            per_pulse = mine["one pulse per trace"]
            out.append((f"{scene}: the sub-aperture changes the image less than the lattice does",
                        bool(per_pulse["nrmse_complex_db"] <= lattice["nrmse_complex_db"]),
                        f"{per_pulse['nrmse_complex_db']} dB against {lattice['nrmse_complex_db']} dB"))
    return out


def run(quick: bool = False, tiny: bool = False) -> list[dict]:
    """Run the comparisons, print the table, write CSV and PNG; returns the rows."""
    print(machine())
    scenes = {"urban": ("urban", {}), "block": (block(), {}), "rough block": (block(rough=True), {})}
    munich = not (quick or tiny) and importlib.util.find_spec("sionna") is not None
    if munich:
        scenes["munich"] = ("sionna:munich", {"n_pulses": 512})
    if tiny:
        scenes = {"block": (block(64), {})}
    rows = []
    for label, (scene, sensor) in scenes.items():
        rows += sweep(label, scene, sensor, tiny)
    if not tiny:                  # cell pieces (T6), opt-in
        for label in ("urban", "block", "rough block"):
            rows += sweep(f"{label}, cells", *scenes[label], lit={"lit_regions": "cells"})
        if munich:                # 64 pulses: cells trace Munich at about 20 s per sub-aperture
            rows += sweep("munich (64 pulses)", "sionna:munich", {"n_pulses": 64}, per_pulse=False)
            rows += sweep("munich (64 pulses), cells", "sionna:munich", {"n_pulses": 64},
                          lit={"lit_regions": "cells"}, per_pulse=False)
        for label, scene in wall_scenes().items():         # the second bounce, tiles and cells
            rows += sweep(label, scene, {}, lit={"lit_regions": "tiles"})
            rows += sweep(f"{label}, cells", scene, {}, lit={"lit_regions": "cells"})
    report_per_scene(f"{NAME}{'_tiny' if tiny else ''}", rows, dict.fromkeys(r["scene"] for r in rows), "nrmse_magnitude_db",
                     ylabel="image NRMSE of magnitudes vs default [dB]", title="what the tracer's lattices leave in the image")
    return rows


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "urban and the block only", "the block, 200 pulses, two comparisons (smoke test)")
