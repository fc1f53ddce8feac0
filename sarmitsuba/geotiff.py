"""GeoTIFF of a ground-plane image: intensity in dB and linear, in the UTM zone of the scene's origin.

The file is written by rasterio (GDAL); this module only places the image. A ground-plane
:class:`~sarmitsuba.image.SarImage` is a rotated rectangle of the local east-north-up frame at
the sensor's ``geo_origin`` (docs/physics.md (G1)). Its pixel centres are mapped to UTM
through PROJ (:func:`sarmitsuba.georef.enu_to_utm`), and the grid is written as one affine
geotransform fitted to three outer pixel corners (physics.md (G3): over a scene a few
kilometres across, UTM is affine in the local frame to well under a pixel).

Layout:

- raster row = azimuth index ``i``, raster column = range index ``j`` of ``image.data``; the
  rows are reversed when that keeps the geotransform's determinant negative (the orientation of
  a north-up map, so that viewers that ignore rotation do not show a mirror image); the
  geotransform carries the rest, including the rotation by the track heading;
- pixel-is-area (``AREA_OR_POINT=Area``): the geotransform maps the outer corner of the first
  pixel, as GDAL expects;
- band 1 ``intensity_db`` = ``10 log10 |s|^2`` (NaN, the nodata value, where ``s = 0``), band 2
  ``intensity`` = ``|s|^2``, both float32, in the image's units squared
  (``metadata["units"]``); tags name the scene, polarization, carrier and ``geo_origin``.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from . import georef
from .image import SarImage
from .outputs import atomic_write

__all__ = ["GeoTiffError", "write_geotiff", "pixel_corners", "geotransform"]


class GeoTiffError(ValueError):
    """An image that cannot be written as a map (names the reason and the fix)."""


def reference_of(image: SarImage) -> georef.GeoReference:
    """The image's geographic reference: ``geo_origin`` of ``metadata["radar"]``, else the default."""
    radar = image.metadata.get("radar", {}) if isinstance(image.metadata, dict) else {}
    return georef.of(radar if isinstance(radar, dict) else {})


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


def geotransform(image: SarImage, ref: georef.GeoReference) -> tuple[Any, bool]:
    """(rasterio Affine from (column, row) to UTM metres, whether the rows are reversed)."""
    from rasterio.transform import Affine
    corner, col_end, row_end = georef.enu_to_utm(pixel_corners(image), ref)
    n_az, n_rg = image.data.shape
    a, d = (col_end - corner) / n_rg
    b, e = (row_end - corner) / n_az
    if a * e - b * d < 0:
        return Affine(a, b, corner[0], d, e, corner[1]), False
    # reversed rows: row 0 is the last azimuth line, whose outer corner is ``row_end``
    return Affine(a, -b, row_end[0], d, -e, row_end[1]), True


def write_geotiff(image: SarImage, path: str | os.PathLike, ref: georef.GeoReference | None = None) -> Path:
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

    Returns the path written. Raises GeoTiffError for a slant-plane image or an irregular
    grid, :class:`outputs.WriteError` (an OSError) when the file cannot be written.
    """
    import rasterio
    if image.plane != "ground":
        raise GeoTiffError(f"a GeoTIFF needs a ground-plane image, and this one lies in the {image.plane!r} plane: "
                           "focus with backprojection (bp or ffbp), which images onto the ground grid")
    ref = reference_of(image) if ref is None else ref
    transform, reversed_rows = geotransform(image, ref)
    intensity = (np.abs(image.data.astype(np.complex64)) ** 2).astype(np.float32)
    intensity = intensity[::-1] if reversed_rows else intensity
    with np.errstate(divide="ignore"):
        db = np.where(intensity > 0, 10.0 * np.log10(intensity), np.nan).astype(np.float32)
    profile = {"driver": "GTiff", "height": intensity.shape[0], "width": intensity.shape[1], "count": 2,
               "dtype": "float32", "crs": georef.utm_crs(ref).to_wkt(), "transform": transform, "nodata": np.nan,
               "compress": "deflate", "predictor": 3}
    if min(intensity.shape) >= 256:
        profile.update(tiled=True, blockxsize=256, blockysize=256)
    tags = geotiff_tags(image, ref, reversed_rows)

    def write(tmp: Path) -> None:
        with rasterio.open(tmp, "w", **profile) as dst:
            dst.write(db, 1)
            dst.write(intensity, 2)
            dst.set_band_description(1, "intensity_db")
            dst.set_band_description(2, "intensity")
            units = str(tags["UNITS"])
            dst.update_tags(1, UNITS=f"dB of {units} squared")
            dst.update_tags(2, UNITS=f"{units} squared")
            dst.update_tags(AREA_OR_POINT="Area", **tags)
    return atomic_write(Path(path), write, "GeoTIFF")


def geotiff_tags(image: SarImage, ref: georef.GeoReference, reversed_rows: bool) -> dict[str, str]:
    """Dataset tags: scene, polarization, carrier, geographic origin, units and layout."""
    meta = image.metadata if isinstance(image.metadata, dict) else {}
    radar = meta.get("radar", {}) if isinstance(meta.get("radar"), dict) else {}
    return {"SCENE": str(meta.get("scene", "")), "POLARIZATION": str(meta.get("polarization", "")),
            "FREQUENCY_HZ": repr(radar.get("frequency", "")), "GEO_ORIGIN": json.dumps(ref.as_tuple()),
            "UNITS": str(meta.get("units", "sqrt(m^2)")).split(" (")[0],
            "LAYOUT": ("rows: azimuth lines, last first; columns: range samples" if reversed_rows
                       else "rows: azimuth lines; columns: range samples"),
            "SOFTWARE": "sarmitsuba"}
