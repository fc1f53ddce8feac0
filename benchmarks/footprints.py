"""Benchmark: Sionna RT's Munich back to footprints and rebuilt (issue 31): what a footprint city keeps.

Munich's buildings (``munich.xml``, 1,188 buildings of PLY walls and pitched roofs) are turned
into GeoJSON footprints (:func:`sarmitsuba.scene.mesh_footprints.footprints_from_scene`: plan
outline, mean roof height, wall material), rebuilt as flat-roofed blocks in Munich's own frame
(:func:`sarmitsuba.scene.city.build_city` with ``origin`` = Munich's) and written
(:func:`~sarmitsuba.scene.city.write_city`). The original and the rebuilt scene are rendered with
one sensor (the default, aimed at the origin: ``scene_center = 0, 0, 0``; the rebuilt one flies the
original's track, ``n_pulses`` and image grid) and one roughness (every material's
``scattering_coefficient`` 0.3), bounce orders apart (``split_bounces``). A rebuild whose
footprints are moved three ground-range resolution cells away from the sensor is rendered too:
what a wrong city scores.

Measured, per rebuild (one row each):

* ``double_bounce_*``: the order-2 images' strong pixels (at or above the 95th intensity
  percentile), the fraction of the original's within one ground-range resolution cell of the
  rebuilt's (``original_in_rebuilt``) and the reverse;
* ``single_bounce_*``: the same on the order-1 images (facades laid over, roofs, ground);
* footprint count, derived heights (mean) against each building's mesh top above the ground
  (mean, and how far the derived height lies below it: mean and 95th percentile; the derived
  height is the mean roof height, so pitched roofs and towers lie below their top);
* seconds: deriving the footprints, building, writing, and rendering the original and the rebuild
  (each render whole and its tracing; after a short warm-up render that compiles the kernels).

Writes ``footprints.csv`` and ``footprints.png`` (order-2 images and the masks: original red,
rebuild green, both yellow) into the output folder. ``--quick``: a 300 m x 300 m crop about the
Frauenkirche with a coarse short-track sensor (25 MHz, 6 m antenna, 50 Hz PRF); ``--tiny`` (the
smoke test): the 200 m crop of ``tests/test_munich_footprints.py``, without the warm-up. Needs
Sionna RT's scenes (``pip install sionna-rt``; sionna itself is never imported).

Usage: ``python benchmarks/footprints.py [--quick] [--tiny]``
"""
from __future__ import annotations

import copy
import gc
import math
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import trimesh
from _table import bench_main, machine, output_dir, write_csv
from scipy import ndimage

import sarmitsuba  # noqa: F401
from sarmitsuba.core import georef
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.builder import Scene
from sarmitsuba.scene.city import build_city, write_city
from sarmitsuba.scene.footprints import parse_footprints
from sarmitsuba.scene.loader import sionna_scenes
from sarmitsuba.scene.mesh_footprints import footprints_from_scene, scene_buildings, write_scene_subset

NAME = "footprints"
ORIGIN = georef.SCENE_ORIGINS["munich"]
#: Every material's Lambertian scattering coefficient, in both renders.
ROUGHNESS = 0.3
#: The bounce orders traced, in every render: 3, the default render's depth before
#: ``max_depth = auto``, so that the figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3
#: Strong pixels: at or above this percentile of an image's intensity.
PERCENTILE = 95.0
#: The crops' short-track sensor (test_munich_footprints): 8.5 m ground range, 3 m azimuth.
COARSE = {"bandwidth": 25e6, "antenna_length": 6.0, "prf": 50.0}
#: (centre x, y, half-size) [m] of the crops in Munich's frame.
CROPS = {"quick": (-150.0, 50.0, 150.0), "tiny": (-150.0, 50.0, 100.0)}


def strong_mask(amplitude: np.ndarray) -> np.ndarray:
    """Pixels at or above the image's :data:`PERCENTILE` of intensity."""
    intensity = np.abs(amplitude).astype(np.float64) ** 2
    return intensity >= np.percentile(intensity, PERCENTILE)


def overlap(mask: np.ndarray, other: np.ndarray, spacing: tuple, radius: float) -> float:
    """Fraction of ``mask``'s pixels within ``radius`` [m] of a pixel of ``other``."""
    distance = ndimage.distance_transform_edt(~other, sampling=spacing)
    return float(np.mean(distance[mask] <= radius))


def _render(source, sensor: dict, image_size) -> dict:
    """Seconds, resolution, grid and the order-1 and order-2 magnitudes (float32) of one render."""
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                          # Munich's known mesh defects
        sim = simulate(source, sensor_overrides=sensor,
                       integrator_overrides={"max_depth": MAX_DEPTH, "split_bounces": True},
                       material_overrides={"scattering_coefficient": ROUGHNESS}, image_size=image_size)
    seconds = time.perf_counter() - start
    image, p = sim.images_per_order[0], sim.loaded.params
    out = {"seconds": seconds, "trace_s": sim.timings["trace"],
           "orders": [np.abs(im.data).astype(np.float32) for im in sim.images_per_order[:2]],
           "grid": (image.origin, image.azimuth, image.range), "n_pulses": p.n_pulses,
           "spacing": (float(image.azimuth[1] - image.azimuth[0]), float(image.range[1] - image.range[0])),
           "resolution": SPEED_OF_LIGHT / (2 * p.bandwidth * math.sin(math.radians(p.incidence_angle)))}
    del sim
    gc.collect()
    return out


def _shifted(fc: dict, south_m: float) -> dict:
    """The footprints moved ``south_m`` metres south (away from the default sensor, which looks south)."""
    import shapely.affinity
    from shapely.geometry import mapping, shape
    dlat = float(georef.enu_to_geodetic(np.array([[0.0, -south_m, 0.0]]), ORIGIN)[0, 0]) - ORIGIN.latitude_deg
    moved = copy.deepcopy(fc)
    for feature in moved["features"]:
        feature["geometry"] = mapping(shapely.affinity.translate(shape(feature["geometry"]), yoff=dlat))
    return moved


def height_stats(xml: Path, fc: dict) -> dict:
    """Derived heights against each building's mesh top above the ground (the ground mesh's lowest z)."""
    buildings, ground = scene_buildings(xml)
    z0 = min(float(trimesh.load(str(s.path), process=False).vertices[:, 2].min()) for s in ground)
    derived = np.array([f["properties"]["height"] for f in fc["features"]])
    top = np.array([max(float(trimesh.load(str(s.path), process=False).vertices[:, 2].max())
                        for s in buildings[f["id"]]) - z0 for f in fc["features"]])
    below = top - derived
    return {"buildings_in_scene": len(buildings), "height_mean_m": round(float(derived.mean()), 2),
            "height_top_mean_m": round(float(top.mean()), 2), "height_below_top_mean_m": round(float(below.mean()), 2),
            "height_below_top_p95_m": round(float(np.percentile(below, 95)), 2),
            "flat_roof_fraction": round(float(np.mean(below < 0.1)), 3)}


def _scores(original: dict, rebuilt: dict) -> dict:
    """Overlaps of the strong pixels both ways, orders 2 and 1 (one resolution cell)."""
    if not all(np.allclose(a, b) for a, b in zip(original["grid"], rebuilt["grid"])):
        raise RuntimeError("the original and the rebuilt images are on different grids")
    out = {}
    for key, order in (("double_bounce", 1), ("single_bounce", 0)):
        a, b = strong_mask(original["orders"][order]), strong_mask(rebuilt["orders"][order])
        out[f"{key}_original_in_rebuilt"] = round(overlap(a, b, original["spacing"], original["resolution"]), 3)
        out[f"{key}_rebuilt_in_original"] = round(overlap(b, a, original["spacing"], original["resolution"]), 3)
    return out


def _prepare(xml: Path, crop, folder: Path) -> tuple:
    """Footprints, cities (rebuilt, shifted), the original's source and the seconds of each step."""
    seconds = {}
    start = time.perf_counter()
    box = None if crop is None else (crop[0] - crop[2], crop[1] - crop[2], crop[0] + crop[2], crop[1] + crop[2])
    fc = footprints_from_scene(xml, ORIGIN, bbox=box)
    seconds["derive_s"] = time.perf_counter() - start
    start = time.perf_counter()
    city = build_city(parse_footprints(fc, "munich"), origin=ORIGIN)
    seconds["build_s"] = time.perf_counter() - start
    start = time.perf_counter()
    written = write_city(city, folder / "rebuilt")
    seconds["write_s"] = time.perf_counter() - start
    original = "sionna:munich"
    if crop is not None:              # the crop's buildings on the rebuilt's ground (Munich's is the plane z = 0)
        (folder / "ground.ply").write_bytes(trimesh.exchange.ply.export_ply(city.ground, encoding="binary"))
        original = str(write_scene_subset(xml, folder / "crop.xml", [f["id"] for f in fc["features"]],
                                          ground_file=folder / "ground.ply"))
    return fc, city, str(written), original, seconds


def compare(label: str, crop, sensor: dict, image_size=None, warm_up: bool = True) -> tuple[list[dict], dict]:
    """Derive, build, write and render one area; rows for the rebuild and the shifted rebuild
    (``warm_up`` false: no warm-up render, the smoke test's untimed run)."""
    xml = sionna_scenes()["munich"]
    with tempfile.TemporaryDirectory() as tmp:
        fc, _, written, source, seconds = _prepare(xml, crop, Path(tmp))
        if warm_up:
            _render(source, {**sensor, "n_pulses": 64}, (65, 65))       # warm-up: the kernels compiled
        original = _render(source, sensor, image_size)
        same = {**sensor, "n_pulses": original["n_pulses"]}
        size = original["orders"][0].shape
        shifted_fc = _shifted(fc, 3 * original["resolution"])
        renders = {"rebuilt": _render(written, same, size),
                   "shifted 3 cells": _render(Scene.from_city(build_city(parse_footprints(shifted_fc, "shifted"),
                                                                          origin=ORIGIN)), same, size)}
    stats = height_stats(xml, fc)
    rows = []
    for case, render in renders.items():
        rows.append({"scene": label, "case": case, "footprints": len(fc["features"]), **stats,
                     **{k: round(v, 3) for k, v in seconds.items()},
                     "render_original_s": round(original["seconds"], 2),
                     "render_rebuilt_s": round(render["seconds"], 2),
                     "trace_original_s": round(original["trace_s"], 2), "trace_rebuilt_s": round(render["trace_s"], 2),
                     "resolution_m": round(original["resolution"], 3), "pixels": int(np.prod(size)),
                     **_scores(original, render)})
    return rows, {"original": original, **renders}


def plot(name: str, label: str, images: dict) -> Path:
    """Order-2 images (dB, 40 dB span) of the original and the rebuild, and both masks."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    original, rebuilt = images["original"], images["rebuilt"]
    step = max(1, max(original["orders"][1].shape) // 800)
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.4), dpi=110)
    extent = None
    for ax, (title, image) in zip(axes, (("original", original), ("rebuilt", rebuilt))):
        db = 20 * np.log10(np.maximum(image["orders"][1][::step, ::step], 1e-30))
        _, az, rg = image["grid"]
        extent = (az[0], az[-1], rg[-1], rg[0])
        top = np.percentile(db, 99.9)
        ax.imshow(db.T, cmap="gray", vmin=top - 40, vmax=top, extent=extent)
        ax.set_title(f"{label}: {title}, double bounce", fontsize=9)
    a, b = strong_mask(original["orders"][1]), strong_mask(rebuilt["orders"][1])
    rgb = np.stack([a, b, np.zeros_like(a)], axis=-1)[::step, ::step].astype(float)
    axes[2].imshow(rgb.transpose(1, 0, 2), extent=extent)
    axes[2].set_title(f"strong pixels (top {100 - PERCENTILE:g} %): original red, rebuilt green", fontsize=9)
    for ax in axes:
        ax.set_xlabel("azimuth [m]")
        ax.set_ylabel("ground range [m]")
    fig.tight_layout()
    path = output_dir() / name
    fig.savefig(path)
    plt.close(fig)
    print(f"wrote {path}")
    return path


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The rebuild's double bounce overlaps the original's by at least 0.5 both ways, and the
    shifted rebuild's by at least 0.15 less."""
    out = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        ok = {r["case"]: r for r in rows if r["scene"] == scene}
        good, bad = ok["rebuilt"], ok["shifted 3 cells"]
        both = min(good["double_bounce_original_in_rebuilt"], good["double_bounce_rebuilt_in_original"])
        worse = max(bad["double_bounce_original_in_rebuilt"], bad["double_bounce_rebuilt_in_original"])
        out.append((f"{scene}: rebuilt double bounce overlaps the original's >= 0.5 both ways", both >= 0.5,
                    f"{good['double_bounce_original_in_rebuilt']} / {good['double_bounce_rebuilt_in_original']}"))
        out.append((f"{scene}: footprints moved 3 cells overlap >= 0.15 less", worse <= both - 0.15,
                    f"{bad['double_bounce_original_in_rebuilt']} / {bad['double_bounce_rebuilt_in_original']}"))
    return out


def run(quick: bool = False, tiny: bool = False) -> list[dict]:
    """Derive, rebuild and render Munich (or a crop); print, write CSV and PNG; returns the rows."""
    print(machine())
    if tiny or quick:
        x, y, half = CROPS["tiny" if tiny else "quick"]
        sensor = {**COARSE, "scene_center": f"{x}, {y}, 0", "n_pulses": int(2 * half + 40) // 2 + 1}
        side = int(2.4 * half / 1.5) | 1                                # 1.5 m pixels (half the 3 m azimuth cell)
        rows, images = compare(f"munich {2 * half:.0f} m crop", (x, y, half), sensor, (side, side), warm_up=not tiny)
    else:
        rows, images = compare("munich", None, {"scene_center": "0, 0, 0"})
    for row in rows:
        print("  ".join(f"{k}={v}" for k, v in row.items()))
    name = f"{NAME}{'_tiny' if tiny else ''}"
    write_csv(f"{name}.csv", rows)
    plot(f"{name}.png", rows[0]["scene"], images)
    return rows


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "a 300 m crop, coarse sensor", "the 200 m crop of the test (smoke test)")
