"""GeoTIFF of a ground-plane image: intensity in dB and linear, in the UTM zone of the scene's origin.

The file is written by rasterio (GDAL); this module only places the image. A ground-plane
:class:`~sarmitsuba.core.image.SarImage` is a rotated rectangle of the local east-north-up frame at
the sensor's ``geo_origin`` (docs/physics.md (GEO1)). Its pixel centres are mapped to UTM
through PROJ (:func:`sarmitsuba.core.georef.enu_to_utm`), and the grid is fitted with one affine
geotransform to three outer pixel corners (physics.md (GEO3): over a scene a few kilometres
across, UTM is affine in the local frame to well under a pixel).

Grids (``north_up`` of :func:`write_geotiff`):

- north-up (the default): the linear intensity is resampled (bilinear, GDAL's warper through
  ``rasterio.warp.reproject``) from the image's grid onto a north-up UTM grid of square pixels
  (the finer of the two ground spacings, corners on multiples of it) covering the image's
  footprint; outside the footprint both bands hold NaN (the nodata value). The dB band is
  computed from the resampled linear band, never interpolated in dB. Every GIS and web map
  reads it (``b = d = 0`` in the geotransform). Tag ``LAYOUT`` says so;
- rotated (``north_up=False``): the image's own samples, unresampled, with a geotransform that
  carries the rotation by the track heading. The raster holds ``image.data`` [azimuth, range]
  transposed and/or with rows or columns reversed, whichever makes it closest to north-up
  (columns east, rows south: exactly so for a track flying east, the default heading); the
  ``LAYOUT`` tag says which. Tools that ignore rotation terms misplace it.

Both: pixel-is-area (``AREA_OR_POINT=Area``): the geotransform maps the outer corner of the
first pixel, as GDAL expects: ``E = a col + b row + c``, ``N = d col + e row + f`` (GDAL's
geotransform, UTM metres, col/row counting pixel edges), with ``a e - b d < 0``, so a north-up
display is never mirrored. Band 1 ``intensity_db`` = ``10 log10 |s|^2`` (NaN where ``s = 0``),
band 2 ``intensity`` = ``|s|^2``, both float32, in the image's units squared: the image has unit
peak gain for a point target, so with amplitudes in sqrt(m^2) band 2 is the radar cross-section
per sample in m^2 (not sigma nought) and band 1 is in dBsm. The bands carry these units as
GDAL unit types (``rio info`` shows ``"units"``) and as band ``UNITS`` tags; dataset tags name the
scene, polarization, carrier, ``geo_origin`` and, as ``AMPLITUDE_UNITS`` (not ``UNITS``, which
would contradict the bands' units), the units of the focused image's amplitudes that the bands square.

An image whose smaller raster side is :data:`TILE` pixels or more is written as a Cloud-Optimized
GeoTIFF (GDAL's COG driver): 256 x 256 tiles, deflate, and overviews by factors 2, 4, 8, ...
(averaged, each band on its own: the dB band's overviews are means of dB) until one fits in a
tile. Smaller ones are plain deflated GeoTIFFs. Writing is atomic (:func:`atomic_write`).
"""
from __future__ import annotations

import json
import math
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core import georef
from ..core.image import SarImage, SarImageError
from ..core.outputs import atomic_write
from . import provenance

__all__ = ["GeoTiffError", "write_geotiff", "pixel_corners", "geotransform", "north_up_grid", "band_units",
           "TILE"]

#: Tile side [pixels] of a Cloud-Optimized GeoTIFF, and the smaller raster side from which one is written.
TILE = 256
#: GDAL resampling of the north-up grid (linear intensity) and of the overviews.
RESAMPLING, OVERVIEW_RESAMPLING = "bilinear", "average"


class GeoTiffError(SarImageError):
    """An image that cannot be written as a map (names the reason and the fix).

    A :class:`~sarmitsuba.core.image.SarImageError` (so a ValueError): the image does not honour the
    GeoTIFF's contract, and the CLI reports it as bad input (exit 2, one message)."""


def reference_of(image: SarImage) -> georef.GeoReference:
    """The image's geographic reference: ``geo_origin`` of ``metadata["radar"]``, else the default."""
    radar = image.metadata.get("radar", {}) if isinstance(image.metadata, dict) else {}
    return georef.of(radar if isinstance(radar, dict) else {})


def at_placeholder(image: SarImage) -> bool:
    """True when the image's radar metadata give no ``geo_origin``, so that it sits at the placeholder
    :data:`georef.DEFAULT` (an origin given as 0, 0, 0 on purpose is not one)."""
    radar = image.metadata.get("radar", {}) if isinstance(image.metadata, dict) else {}
    return georef.parse(radar.get("geo_origin") if isinstance(radar, dict) else None) is None


def uniform_spacing(axis: np.ndarray, name: str) -> float:
    """The step [m] of a uniformly sampled axis; GeoTiffError naming ``name`` otherwise."""
    axis = np.asarray(axis, dtype=np.float64)
    if axis.size < 2:
        raise GeoTiffError(f"the image's {name} axis has {axis.size} sample(s); a GeoTIFF needs at least 2")
    steps = np.diff(axis)
    if np.ptp(steps) > 1e-6 * abs(steps.mean()):
        raise GeoTiffError(f"the image's {name} axis is not uniformly sampled; a GeoTIFF needs a regular grid")
    return float(steps.mean())


def pixel_corners(image: SarImage) -> np.ndarray:
    """float64 [3, 3] local-frame points: outer corners of pixel (0, 0), of row 0 past the last
    column, and of column 0 past the last row (rows = azimuth, columns = range)."""
    da, dr = uniform_spacing(image.azimuth, "azimuth"), uniform_spacing(image.range, "range")
    n_az, n_rg = image.data.shape
    a, r = np.asarray(image.azimuth_direction, float), np.asarray(image.range_direction, float)
    first = np.asarray(image.origin, float) + (image.azimuth[0] - 0.5 * da) * a + (image.range[0] - 0.5 * dr) * r
    return np.array([first, first + n_rg * dr * r, first + n_az * da * a])


@dataclass(frozen=True)
class Layout:
    """How the raster holds ``image.data`` [n_azimuth, n_range]: ``transpose`` (rows = range),
    then ``flip_rows`` / ``flip_cols`` (reversed order)."""

    transpose: bool
    flip_rows: bool
    flip_cols: bool

    def apply(self, array: np.ndarray) -> np.ndarray:
        """``array`` [n_azimuth, n_range] in this layout."""
        out = array.T if self.transpose else array
        return out[::-1 if self.flip_rows else 1, ::-1 if self.flip_cols else 1]

    def describe(self) -> str:
        """The LAYOUT tag: what raster rows and columns are."""
        rows, cols = ("range samples", "azimuth lines") if self.transpose else ("azimuth lines", "range samples")
        return (f"rows: {rows}{', last first' if self.flip_rows else ''}; "
                f"columns: {cols}{', last first' if self.flip_cols else ''}")


def geotransform(image: SarImage, ref: georef.GeoReference) -> tuple[Any, Layout]:
    """(rasterio Affine from (column, row) to UTM metres, raster layout).

    Of the eight layouts (transposed or not, rows and columns reversed or not) the one whose
    columns run most nearly east and rows most nearly south is taken, so that the raster is as
    close to north-up as the grid's rotation allows (exactly north-up for a track flying east).
    """
    from rasterio.transform import Affine
    corner, col_end, row_end = georef.enu_to_utm(pixel_corners(image), ref)
    n_az, n_rg = image.data.shape
    step_rg, step_az = (col_end - corner) / n_rg, (row_end - corner) / n_az
    best = None
    for transpose in (False, True):
        for flip_rows in (False, True):
            for flip_cols in (False, True):
                layout = Layout(transpose, flip_rows, flip_cols)
                col_step, n_col, row_step, n_row = ((step_az, n_az, step_rg, n_rg) if transpose
                                                    else (step_rg, n_rg, step_az, n_az))
                origin = corner + (n_row * row_step if flip_rows else 0.0) + (n_col * col_step if flip_cols else 0.0)
                col_step = -col_step if flip_cols else col_step
                row_step = -row_step if flip_rows else row_step
                score = col_step[0] / np.linalg.norm(col_step) - row_step[1] / np.linalg.norm(row_step)
                if best is None or score > best[0] + 1e-9:
                    best = (score, Affine(col_step[0], row_step[0], origin[0], col_step[1], row_step[1], origin[1]),
                            layout)
    return best[1], best[2]


def write_geotiff(image: SarImage, path: str | os.PathLike, ref: georef.GeoReference | None = None,
                  north_up: bool = True) -> Path:
    """Write ``image``'s intensity as a two-band GeoTIFF in UTM at ``path`` (atomically).

    Parameters
    ----------
    image : SarImage
        Ground-plane image: complex64 [n_azimuth, n_range] on uniform axes [m].
    path : path-like
        The ``.tif`` to write.
    ref : GeoReference, optional
        WGS84 origin of the image's world frame (default: ``geo_origin`` of
        ``image.metadata["radar"]``, else :data:`georef.DEFAULT`).
    north_up : bool, default True
        Resample onto a north-up UTM grid (square pixels of the finer ground spacing [m], NaN
        outside the footprint; :func:`north_up_grid`). False: the image's own grid, unresampled,
        with a rotated geotransform (:func:`geotransform`).

    Band 1 holds ``10 log10 |s|^2`` (dB, e.g. dBsm), band 2 ``|s|^2`` (e.g. m^2; :func:`band_units`).
    Returns the path written. Raises GeoTiffError for a slant-plane image or an irregular
    grid, :class:`outputs.WriteError` (an OSError) naming ``path`` when the file cannot be
    written. Warns (UserWarning, once per call) when neither ``ref`` nor the metadata give a
    ``geo_origin``: the map then shows the placeholder 0 N 0 E (:func:`at_placeholder`).
    """
    if image.plane != "ground":
        raise GeoTiffError(f"--geotiff: a GeoTIFF needs a ground-plane image, and this {image.algorithm} image lies "
                           f"in the {image.plane!r} plane: focus with backprojection (focus --algorithm bp or ffbp), "
                           "which images onto the scene's ground grid when the raw data carry sarmitsuba's radar "
                           "parameters, or leave out --geotiff")
    if ref is None and at_placeholder(image):
        warnings.warn(f"--geotiff: the sensor's geo_origin is not set, so {Path(path).name} places the scene at the "
                      f"placeholder {georef.DEFAULT.describe()} (null island, in the Gulf of Guinea); set it with "
                      "--set geo_origin=LAT,LON[,H] (degrees north, degrees east, metres above WGS84) or the "
                      "sar sensor's <string name=\"geo_origin\" value=\"LAT, LON, H\"/> in the scene XML",
                      UserWarning, stacklevel=2)
    ref = reference_of(image) if ref is None else ref
    transform, layout = geotransform(image, ref)
    intensity = (np.abs(image.data.astype(np.complex64)) ** 2).astype(np.float32)
    intensity = np.ascontiguousarray(layout.apply(intensity))
    crs = georef.utm_crs(ref).to_wkt()
    layout_tag = layout.describe()
    if north_up:
        intensity, transform = resample_north_up(intensity, transform, crs)
        layout_tag = (f"north-up: rows south, columns east; {RESAMPLING} resampling of the linear intensity from "
                      "the image's azimuth-range grid, dB computed after it; NaN outside the image's footprint")
    with np.errstate(divide="ignore", invalid="ignore"):
        db = np.where(intensity > 0, 10.0 * np.log10(intensity), np.nan).astype(np.float32)
    tags = {**geotiff_tags(image, ref, layout), "LAYOUT": layout_tag}
    return atomic_write(Path(path), lambda tmp: write_raster(tmp, db, intensity, crs, transform, tags), "GeoTIFF")


def band_units(units: str) -> tuple[str, str]:
    """(dB band unit, linear band unit) of an image whose amplitudes are in ``units``.

    The linear band holds ``|s|^2``: ``sqrt(m^2)`` gives ``m^2`` and ``dBsm`` (dB relative to
    1 m^2), ``sqrt(W)`` gives ``W`` and ``dBW``, another ``sqrt(U)`` ``U`` and ``dB re 1 U`` (words
    after the unit, which the ``UNITS`` tag keeps, are left out); anything else ``(units)^2`` and
    ``dB re 1 (units)^2``."""
    match = re.match(r"\s*sqrt\(([^()]+)\)", units)
    if not match:
        return f"dB re 1 ({units.strip()})^2", f"({units.strip()})^2"
    unit = match.group(1).strip()
    return {"m^2": "dBsm", "W": "dBW"}.get(unit, f"dB re 1 {unit}"), unit


def north_up_grid(transform: Any, shape: tuple[int, int]) -> tuple[Any, tuple[int, int]]:
    """(north-up rasterio Affine, (height, width)) covering a raster of ``shape`` placed by ``transform``.

    Square pixels of the finer of its two pixel spacings [CRS units, UTM m]; the grid's edges lie
    on multiples of that spacing (like ``gdalwarp -tap``) and enclose the raster's four outer corners.
    """
    from rasterio.transform import Affine
    height, width = shape
    step = min(math.hypot(transform.a, transform.d), math.hypot(transform.b, transform.e))
    cols, rows = np.array([0, width, 0, width], float), np.array([0, 0, height, height], float)
    xs = transform.a * cols + transform.b * rows + transform.c
    ys = transform.d * cols + transform.e * rows + transform.f
    tol = 1e-6 * step                                 # a corner on a grid line does not add a column of NaN
    west, north = math.floor((min(xs) + tol) / step) * step, math.ceil((max(ys) - tol) / step) * step
    n_cols = max(1, math.ceil((max(xs) - tol - west) / step))
    n_rows = max(1, math.ceil((north - min(ys) - tol) / step))
    return Affine(step, 0.0, west, 0.0, -step, north), (n_rows, n_cols)


def resample_north_up(intensity: np.ndarray, transform: Any, crs: str) -> tuple[np.ndarray, Any]:
    """(float32 [rows, cols] linear intensity on :func:`north_up_grid`, its Affine): the raster
    ``intensity`` placed by ``transform`` in ``crs`` resampled (:data:`RESAMPLING`) by GDAL's
    warper; NaN where a pixel centre falls outside the raster's footprint."""
    from rasterio.warp import Resampling, reproject
    dst_transform, shape = north_up_grid(transform, intensity.shape)
    out = np.full(shape, np.nan, dtype=np.float32)
    reproject(source=intensity, destination=out, src_transform=transform, src_crs=crs, dst_transform=dst_transform,
              dst_crs=crs, src_nodata=None, dst_nodata=np.nan, init_dest_nodata=True,
              resampling=Resampling[RESAMPLING])
    return out, dst_transform


def cog_driver() -> bool:
    """True when GDAL has its COG driver (GDAL >= 3.1)."""
    import rasterio
    with rasterio.Env() as env:
        return "COG" in env.drivers()


def overview_factors(shape: tuple[int, int]) -> list[int]:
    """2, 4, 8, ... while the previous level's smaller side is above :data:`TILE` pixels."""
    factors, side = [], min(shape)
    while side > TILE:
        factors.append(2 * factors[-1] if factors else 2)
        side //= 2
    return factors


def write_raster(path: Path, db: np.ndarray, intensity: np.ndarray, crs: str, transform: Any,
                 tags: dict[str, str]) -> None:
    """Write the two float32 bands, units, descriptions and tags to ``path`` with rasterio: a COG
    (tiled, overviews) when the smaller side is :data:`TILE` or more, a plain GeoTIFF otherwise."""
    import rasterio
    from rasterio.enums import Resampling
    profile = {"height": db.shape[0], "width": db.shape[1], "count": 2, "dtype": "float32", "crs": crs,
               "transform": transform, "nodata": np.nan, "compress": "deflate"}
    cog = min(db.shape) >= TILE and cog_driver()
    if cog:
        profile.update(driver="COG", blocksize=TILE, predictor="YES", overview_resampling=OVERVIEW_RESAMPLING.upper())
    else:
        profile.update(driver="GTiff", predictor=3)
        if min(db.shape) >= TILE:                     # GDAL without COG: tiles and overviews in a GTiff
            profile.update(tiled=True, blockxsize=TILE, blockysize=TILE)
    units = band_units(str(tags["AMPLITUDE_UNITS"]))
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(db, 1)
        dst.write(intensity, 2)
        dst.descriptions = ("intensity_db", "intensity")
        dst.units = units
        for band, unit in enumerate(units, start=1):
            dst.update_tags(band, UNITS=unit)
        dst.update_tags(AREA_OR_POINT="Area", **tags)
        if min(db.shape) >= TILE and not cog:
            dst.build_overviews(overview_factors(db.shape), Resampling[OVERVIEW_RESAMPLING])
            dst.update_tags(ns="rio_overview", resampling=OVERVIEW_RESAMPLING)


def geotiff_tags(image: SarImage, ref: georef.GeoReference, layout: Layout) -> dict[str, str]:
    """Dataset tags: scene, polarization, carrier, geographic origin, the amplitudes' units
    (``AMPLITUDE_UNITS``; the bands carry their own ``UNITS``), layout, the collection's
    start (``ACQUISITION_START_TIME``, ISO 8601 UTC, :func:`provenance.collection_start`) and the
    file's making (``TIFFTAG_DATETIME``, the TIFF DateTime tag). Raises GeoTiffError for a
    ``collection_start`` that is no ISO 8601 time with a UTC offset."""
    meta = image.metadata if isinstance(image.metadata, dict) else {}
    radar = meta.get("radar", {}) if isinstance(meta.get("radar"), dict) else {}
    try:
        start = provenance.collection_start(meta)
    except ValueError as exc:
        raise GeoTiffError(f"cannot write a GeoTIFF: metadata radar {exc}") from None
    return {"SCENE": str(meta.get("scene", "")), "POLARIZATION": str(meta.get("polarization", "")),
            "ACQUISITION_START_TIME": start.isoformat(),
            "TIFFTAG_DATETIME": provenance.utc_now().strftime("%Y:%m:%d %H:%M:%S"),
            "FREQUENCY_HZ": repr(radar.get("frequency", "")), "GEO_ORIGIN": json.dumps(ref.as_tuple()),
            "AMPLITUDE_UNITS": str(meta.get("units", "sqrt(m^2)")).split(" (")[0],
            "LAYOUT": layout.describe(),
            "SOFTWARE": "sarmitsuba"}
