"""Tomography products of a stack folder (or of render folders): profiles, scatterers, the point
cloud, its truth and the figures (docs/physics.md (TS1)-(TS7); the guide's tomography page).

:func:`write_products` reads the passes (:func:`read_stack`), focuses them in elevation
(:func:`sarmitsuba.stacks.tomo_stack.focus_elevation`) and writes, all or none
(:data:`PRODUCT_FILES`):

* ``profiles.npz``: ``elevation`` float64 [S] m, ``rows``, ``cols`` int64 [P], ``profiles`` float32
  [P, S] (power over elevation), ``perpendicular`` float64 [N] m, ``calibration`` float64 [N] rad
  and a JSON ``metadata`` string;
* ``scatterers.npz`` and ``points.csv``: one entry a detected scatterer: pixel, elevation,
  height above the grid plane, world position, power, geographic position (with a
  ``geo_origin``) and ``truth_height``, the nearest height at which the pixel's iso-range circle
  meets the scene's geometry (from the stack's ``truth.npz``; NaN without one);
* ``tomography.json``: the method, the stack's ``rho_s`` and ambiguity, counts, the median
  ``|height - truth_height|`` and the seconds;
* ``tomogram.png`` (one range line) and ``point_cloud.png``.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..core.image import SarImage
from ..core.outputs import OutputDirectory, atomic_savez, json_default
from .insar_products import read_render
from .interferometry import InterferometryError
from .tomo_stack import TomographyResult, focus_elevation
from .tomography import TomographyError

__all__ = ["PRODUCT_FILES", "STACK_FILE", "TRUTH_FILE", "pass_folder", "StackInput", "read_stack", "TomographyProducts", "write_products"]

#: The description a stack folder holds (written last by :func:`sarmitsuba.stack.render_stack`).
STACK_FILE = "stack.json"
#: The geometric truth of the reference pass's pixels in a stack folder.
TRUTH_FILE = "truth.npz"


def pass_folder(n: int) -> str:
    """The folder name of a stack's pass ``n``: ``pass-00``, ``pass-01``, ..."""
    return f"pass-{n:02d}"


#: Files :func:`write_products` writes.
PRODUCT_FILES = {"profiles": "profiles.npz", "scatterers": "scatterers.npz", "points": "points.csv",
                 "summary": "tomography.json", "tomogram": "tomogram.png", "point_cloud": "point_cloud.png"}


@dataclass(frozen=True)
class StackInput:
    """The passes of a stack as read: ``images``, ``raws`` (one per pass), ``folders``, the
    ``reference`` pass (None: mid-span), the elevation ``interval`` [m] and the ``truth`` heights
    float32 [n_az, n_rg, K] (None when the stack has none)."""

    images: tuple
    raws: tuple
    folders: tuple
    reference: int | None
    interval: tuple[float, float]
    truth: np.ndarray | None


def read_stack(paths: Sequence[str | os.PathLike]) -> StackInput:
    """Read a stack: one folder written by ``sarmitsuba stack`` (with ``stack.json``), or three or
    more render folders (the elevation interval then spans the scene's bounding box, from the
    raw data's metadata, and no truth is read).

    Raises
    ------
    TomographyError
        No folder, a stack folder without ``stack.json`` or a pass, more than one folder of which
        one is a stack folder, fewer than 3 render folders, or a missing ``image.npz`` /
        ``raw.npz`` (naming the folder).
    SarImageError, RawDataError
        A damaged file.
    """
    folders = [Path(p) for p in paths]
    stacks = [f for f in folders if (f / STACK_FILE).is_file()]
    if len(folders) > 1 and stacks:
        raise TomographyError(f"{len(stacks)} of the {len(folders)} folders given are stack folders (with "
                              f"{STACK_FILE}: {', '.join(repr(str(f)) for f in stacks)}): tomography takes one stack "
                              "folder, or three or more render folders of one scene; invert each stack on its own")
    if len(folders) == 1 and stacks:
        body = json.loads((folders[0] / STACK_FILE).read_text())
        passes = tuple(folders[0] / entry["folder"] for entry in body["passes"])
        truth = None
        if body.get("truth") and (folders[0] / body["truth"]).is_file():
            with np.load(folders[0] / body["truth"]) as f:
                truth = np.asarray(f["heights"])
        images, raws = _read_passes(passes)
        return StackInput(images, raws, passes, int(body["reference"]), tuple(body["elevation_interval"]), truth)
    if len(folders) == 1:
        raise TomographyError(f"{str(folders[0])!r} is not a stack folder (no {STACK_FILE}): give a folder written by "
                              "`sarmitsuba stack`, or three or more render folders of one scene")
    images, raws = _read_passes(tuple(folders))
    return StackInput(images, raws, tuple(folders), None, _interval_of(images[0], raws[0]), None)


def _read_passes(folders: tuple) -> tuple[tuple, tuple]:
    if len(folders) < 3:
        raise TomographyError(f"tomography takes one stack folder or three or more render folders, got "
                              f"{len(folders)} render folders: it resolves elevation from 3 or more baselines "
                              "(2 passes: use `interferogram`)")
    pairs = []
    for n, folder in enumerate(folders):
        try:
            pairs.append(read_render(folder, f"pass {n}"))
        except InterferometryError as exc:
            raise TomographyError(str(exc)) from None
    return tuple(p[0] for p in pairs), tuple(p[1] for p in pairs)


def _interval_of(image: SarImage, raw: Any) -> tuple[float, float]:
    """Elevations of the scene's bounding box above the grid plane (render folders without a stack)."""
    info = raw.metadata.get("scene_info", {})
    offset = np.asarray(raw.metadata.get("frame_offset", (0.0, 0.0, 0.0)), float)
    z0 = float(image.origin[2])
    lo = min(0.0, float(info.get("bbox_min", (0, 0, z0))[2]) + offset[2] - z0)
    hi = max(0.0, float(info.get("bbox_max", (0, 0, z0))[2]) + offset[2] - z0)
    sin_theta = math.sin(math.radians(float(raw.metadata.get("radar", {}).get("incidence_angle", 45.0))))
    return lo / sin_theta, hi / sin_theta + 1e-3


@dataclass(frozen=True)
class TomographyProducts:
    """What :func:`write_products` wrote: ``paths`` (name -> Path), the ``result`` and a ``summary`` dict."""

    paths: dict
    result: TomographyResult
    summary: dict

    def line(self) -> str:
        """One-line summary for the CLI."""
        s = self.summary
        truth = "" if s["median_truth_error"] is None else f", median |h - truth| {s['median_truth_error']:.2f} m"
        return (f"tomography ({s['method']}) of {s['passes']} passes: rho_s {s['elevation_resolution']:.2f} m, "
                f"{s['pixels']} pixels, {s['scatterers']} scatterers{truth}; {s['seconds']:.1f} s -> "
                f"{self.paths['summary'].parent}")


def write_products(out_dir: str | os.PathLike, paths: Sequence[str | os.PathLike] | StackInput, *,
                   progress: bool = False, tomogram_row: int | None = None, **options: Any) -> TomographyProducts:
    """Focus a stack in elevation and write the module's files into ``out_dir``.

    ``paths``: see :func:`read_stack`, or the :class:`StackInput` it returned; ``options``: those of
    :func:`~sarmitsuba.stacks.tomo_stack.focus_elevation` (``method``, ``region``,
    ``calibration_point``, ...); ``tomogram_row``: the azimuth row of the tomogram (default: the
    row with the most scatterers).

    Raises
    ------
    TomographyError
        Bad input (:func:`read_stack`, :func:`~sarmitsuba.stacks.tomo_stack.focus_elevation`)
        or a ``tomogram_row`` outside the image.
    OSError
        ``out_dir`` cannot be written.
    """
    from ..products.elevation_truth import nearest_truth
    start = time.perf_counter()
    stack = paths if isinstance(paths, StackInput) else read_stack(paths)
    n_az = stack.images[0].data.shape[0]
    if tomogram_row is not None:                  # checked before the (maybe long) inversion
        _tomogram_row(None, n_az, tomogram_row)
    result = focus_elevation(stack.images, stack.raws, stack.interval, reference=stack.reference,
                             progress=progress, **options)
    sc = dict(result.scatterers)
    if stack.truth is not None and sc["row"].size:
        sc["truth_height"] = nearest_truth(stack.truth[sc["row"], sc["col"]].astype(np.float64), sc["height"])
    else:
        sc["truth_height"] = np.full(sc["row"].size, np.nan)
    result = dataclasses.replace(result, scatterers=sc)
    row = _tomogram_row(result, n_az, tomogram_row)
    error = np.abs(sc["height"] - sc["truth_height"])
    summary = {"method": result.method, "passes": len(stack.images), "reference": result.reference,
               "elevation_resolution": result.elevation_resolution, "elevation_ambiguity": result.elevation_ambiguity,
               "interval": list(stack.interval), "pixels": int(result.rows.size), "scatterers": int(sc["row"].size),
               "median_truth_error": float(np.nanmedian(error)) if np.any(np.isfinite(error)) else None,
               "tomogram_row": row, "folders": [str(f) for f in stack.folders],
               "calibration": result.calibration.tolist(), "perpendicular": result.perpendicular.tolist()}
    with OutputDirectory(out_dir) as out:
        written = _write(out, stack, result, summary, row)
        summary["seconds"] = time.perf_counter() - start
        written["summary"] = out.write(PRODUCT_FILES["summary"], lambda p: p.write_text(
            json.dumps(summary, indent=2, default=json_default)))
    return TomographyProducts(paths=written, result=result, summary=summary)


def _tomogram_row(result: TomographyResult | None, n_az: int, row: int | None) -> int:
    """The tomogram's azimuth row: ``row`` checked, or the row with the most scatterers."""
    if row is None:
        rows = result.scatterers["row"]
        return int(np.bincount(rows, minlength=n_az).argmax()) if rows.size else n_az // 2
    if isinstance(row, bool) or int(row) != row or not (0 <= int(row) < n_az):
        raise TomographyError(f"tomogram_row = {row!r}: give an azimuth row of the image, 0 to {n_az - 1} "
                              f"(it has {n_az} rows)")
    return int(row)


def _write(out: OutputDirectory, stack: StackInput, result: TomographyResult, summary: dict, row: int) -> dict:
    """The files other than ``tomography.json``."""
    from ..products.figures_tomo import write_point_cloud, write_tomogram
    sc, image = result.scatterers, stack.images[result.reference]
    meta = np.str_(json.dumps(summary, default=json_default))
    paths = {"profiles": out.write(PRODUCT_FILES["profiles"], lambda p: atomic_savez(
        p, elevation=result.elevation, rows=result.rows, cols=result.cols, profiles=result.profiles,
        perpendicular=result.perpendicular, calibration=result.calibration, metadata=meta)),
        "scatterers": out.write(PRODUCT_FILES["scatterers"], lambda p: atomic_savez(p, metadata=meta, **sc)),
        "points": out.write(PRODUCT_FILES["points"], lambda p: _write_csv(p, sc))}
    line = np.zeros((image.data.shape[1], result.elevation.size))
    on = result.rows == row
    line[result.cols[on]] = result.profiles[on]
    here = sc["row"] == row
    truth = None
    if stack.truth is not None:
        cols, k = np.nonzero(np.isfinite(stack.truth[row]))
        sin_theta = math.sin(math.radians(float(stack.raws[0].metadata.get("radar", {}).get("incidence_angle", 45))))
        truth = (image.range[cols], stack.truth[row][cols, k] / sin_theta)
    title = f"{result.method} tomogram, azimuth row {row}: rho_s {result.elevation_resolution:.2f} m"
    paths["tomogram"] = out.write(PRODUCT_FILES["tomogram"], lambda p: write_tomogram(
        image.range, result.elevation, line, p, title, (image.range[sc["col"][here]], sc["elevation"][here]), truth))
    ground = (np.column_stack([sc["x"], sc["y"], sc["z"]]) - image.origin) @ image.range_direction
    paths["point_cloud"] = out.write(PRODUCT_FILES["point_cloud"], lambda p: write_point_cloud(
        sc["x"], sc["y"], sc["height"], ground, p, f"{result.method} point cloud ({len(stack.images)} passes)"))
    return paths


def _write_csv(path: Path, scatterers: dict) -> None:
    """``points.csv``: one row a scatterer, the columns of :func:`write_products`' point cloud."""
    names = [n for n in ("x", "y", "z", "height", "truth_height", "elevation", "power", "row", "col", "latitude",
                         "longitude", "ellipsoid_height") if n in scatterers]
    table = np.column_stack([np.asarray(scatterers[n], np.float64) for n in names]) if scatterers["row"].size \
        else np.zeros((0, len(names)))
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt="%.10g")
