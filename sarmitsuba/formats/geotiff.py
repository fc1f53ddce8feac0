"""GeoTIFF of a ground-plane image: intensity in dB and linear, in the UTM zone of the scene's origin.

The file is written by rasterio (GDAL); this module only places the image. A ground-plane
:class:`~sarmitsuba.core.image.SarImage` is a rotated rectangle of the local east-north-up frame at
the sensor's ``geo_origin`` (docs/physics.md (G1)). Its pixel centres are mapped to UTM
through PROJ (:func:`sarmitsuba.core.georef.enu_to_utm`), and the grid is written as one affine
geotransform fitted to three outer pixel corners (physics.md (G3): over a scene a few
kilometres across, UTM is affine in the local frame to well under a pixel).

Layout:

- the raster holds ``image.data`` [azimuth, range] transposed and/or with rows or columns
  reversed, whichever makes it closest to north-up (columns east, rows south: exactly so for a
  track flying east, the default heading); the ``LAYOUT`` tag says which. The geotransform
  carries the rest, including the rotation by the track heading;
- pixel-is-area (``AREA_OR_POINT=Area``): the geotransform maps the outer corner of the first
  pixel, as GDAL expects: ``E = a col + b row + c``, ``N = d col + e row + f`` (GDAL's
  geotransform, UTM metres, col/row counting pixel edges), with ``a e - b d < 0``, so a
  north-up display is never mirrored;
- band 1 ``intensity_db`` = ``10 log10 |s|^2`` (NaN, the nodata value, where ``s = 0``), band 2
  ``intensity`` = ``|s|^2``, both float32, in the image's units squared
  (``metadata["units"]``); tags name the scene, polarization, carrier and ``geo_origin``.
"""
from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core import georef
from ..core.image import SarImage, SarImageError
from ..core.outputs import atomic_write

__all__ = ["GeoTiffError", "write_geotiff", "pixel_corners", "geotransform"]


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
    grid, :class:`outputs.WriteError` (an OSError) when the file cannot be written. Warns
    (UserWarning, once per call) when neither ``ref`` nor the metadata give a ``geo_origin``:
    the map then shows the placeholder 0 N 0 E (:func:`at_placeholder`).
    """
    import rasterio
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
    with np.errstate(divide="ignore"):
        db = np.where(intensity > 0, 10.0 * np.log10(intensity), np.nan).astype(np.float32)
    profile = {"driver": "GTiff", "height": intensity.shape[0], "width": intensity.shape[1], "count": 2,
               "dtype": "float32", "crs": georef.utm_crs(ref).to_wkt(), "transform": transform, "nodata": np.nan,
               "compress": "deflate", "predictor": 3}
    if min(intensity.shape) >= 256:
        profile.update(tiled=True, blockxsize=256, blockysize=256)
    tags = geotiff_tags(image, ref, layout)

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


def geotiff_tags(image: SarImage, ref: georef.GeoReference, layout: Layout) -> dict[str, str]:
    """Dataset tags: scene, polarization, carrier, geographic origin, units and layout."""
    meta = image.metadata if isinstance(image.metadata, dict) else {}
    radar = meta.get("radar", {}) if isinstance(meta.get("radar"), dict) else {}
    return {"SCENE": str(meta.get("scene", "")), "POLARIZATION": str(meta.get("polarization", "")),
            "FREQUENCY_HZ": repr(radar.get("frequency", "")), "GEO_ORIGIN": json.dumps(ref.as_tuple()),
            "UNITS": str(meta.get("units", "sqrt(m^2)")).split(" (")[0],
            "LAYOUT": layout.describe(),
            "SOFTWARE": "sarmitsuba"}
