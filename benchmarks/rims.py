"""Benchmark: lines where a scene's ground merely stops (docs/physics.md (M10)).

A ground shape's free rim is where its model was cut. Rendered with its rims as edges
(``ground_shapes = none``) a smooth ground draws bright lines of constant range there; with the
default (``auto``: the rims are truncations) it should draw nothing. For Sionna's Munich (its
default render, every pulse; ``--quick``: 256 central pulses) and the built-in ``urban`` scene,
both ways, this measures along each free rim of the ground that lies in the image:

* the median intensity of the pixels within 1 m of the rim (``rim_db``), and the median of the
  open ground's pixels 3 to 50 m inside it (``ground_db``), both in dB re the image's 99.5th
  percentile, on the azimuth lines the beam lit;
* ``excess_db = rim_db - ground_db``: how far the rim stands above the ground beside it.

Writes ``rims.csv`` (in the output folder, ``_table.output_dir``).
Usage: ``python benchmarks/rims.py [--quick]``
"""
from __future__ import annotations

import gc
import importlib.util

import numpy as np
from _table import bench_main, machine, report_rows

import sarmitsuba  # noqa: F401
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.ground import ground_shapes
from sarmitsuba.tracing.mesh.facets import scene_meshes

NAME = "rims"
#: Pixels within this distance [m] of a rim are on it.
ON_RIM = 1.0
#: The open ground beside a rim: this far inside it [m].
BESIDE = (3.0, 50.0)
#: A rim counts where at least this many of its pixels lie in the image.
MIN_PIXELS = 200
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3


def free_rims(loaded) -> list[np.ndarray]:
    """The free edges of the scene's ground shapes (``ground_shapes = auto``): world segments
    float64 [2, 3] in the tracing frame (edges of one triangle only), collinear ones joined."""
    shapes = list(loaded.scene.shapes())
    flags = ground_shapes("auto", [s.id() for s in shapes])
    rims = []
    for (vertices, faces), flag in zip(scene_meshes(loaded.scene), flags):
        if not flag or len(faces) == 0:
            continue
        edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
        unique, count = np.unique(edges, axis=0, return_counts=True)
        rims += [vertices[e] for e in unique[count == 1]]
    return rims


def measure(scene: str, sensor: dict, ground: str) -> list[dict]:
    """One render; a row per rim with enough pixels in the image."""
    sim = simulate(scene, sensor_overrides=sensor,
                   integrator_overrides={"max_depth": MAX_DEPTH, "ground_shapes": ground})
    image, loaded = sim.image, sim.loaded
    xyz = (image.origin - loaded.offset + image.azimuth[:, None, None] * image.azimuth_direction
           + image.range[None, :, None] * image.range_direction)
    power = np.abs(image.data.astype(np.complex128)) ** 2
    reference = np.percentile(power, 99.5)
    # the azimuth lines the beam lit (a part of the aperture leaves the others empty)
    lines = power.sum(axis=1)
    lit = (lines > 1e-6 * lines.max())[:, None]
    rows = []
    for k, (a, b) in enumerate(free_rims(loaded)):
        d = (b - a)[:2]
        length = float(np.hypot(*d))
        u = d / length
        rel = xyz[..., :2] - a[:2]
        along = rel @ u
        across = rel[..., 0] * u[1] - rel[..., 1] * u[0]            # > 0 on one side
        within = (along > 0) & (along < length) & lit
        rim = within & (np.abs(across) < ON_RIM)
        if rim.sum() < MIN_PIXELS:
            continue
        # the ground's side: toward the scene's centre (the grounds here are convex)
        centre = -a[:2]
        side = np.sign(centre[0] * u[1] - centre[1] * u[0]) or 1.0
        beside = within & (side * across > BESIDE[0]) & (side * across < BESIDE[1])
        rim_db = 10 * np.log10(np.median(power[rim]) / reference)
        ground_db = 10 * np.log10(np.median(power[beside]) / reference)
        rows.append({"scene": scene, "ground_shapes": ground, "rim": k, "length_m": round(length, 1),
                     "rim_pixels": int(rim.sum()), "rim_db": round(float(rim_db), 1),
                     "ground_db": round(float(ground_db), 1), "excess_db": round(float(rim_db - ground_db), 1)})
    del sim
    gc.collect()
    return rows


#: The rims' excess over the ground beside them with the default [dB] (the target of the rule).
EXCESS_BOUND_DB = 3.0


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """Every rim at most :data:`EXCESS_BOUND_DB` above the ground beside it with the default, and
    above that with its rims as edges (else the scene has no line to remove)."""
    out = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        auto = [r["excess_db"] for r in rows if r["scene"] == scene and r["ground_shapes"] == "auto"]
        none = [r["excess_db"] for r in rows if r["scene"] == scene and r["ground_shapes"] == "none"]
        out.append((f"{scene}: every rim <= {EXCESS_BOUND_DB:g} dB above the ground beside it",
                    bool(auto) and max(auto) <= EXCESS_BOUND_DB, f"{auto} dB (rims as edges: {none} dB)"))
    return out


def run(quick: bool = False) -> list[dict]:
    """Measure both ways, print and write the table; returns the rows."""
    print(machine())
    scenes = {"urban": {}}
    if importlib.util.find_spec("sionna") is not None:
        scenes["sionna:munich"] = {"n_pulses": 256} if quick else {}
    rows = []
    for scene, sensor in scenes.items():
        for ground in ("auto", "none"):
            rows += measure(scene, sensor, ground)
    return report_rows(f"{NAME}.csv", rows)


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "Munich with its 256 central pulses")
