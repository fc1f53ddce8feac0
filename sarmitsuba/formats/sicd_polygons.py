"""The polygons of a SICD: ``GeoData/ImageCorners``, ``ImageData/ValidData`` with
``GeoData/ValidData``, and ``RadarCollection/Area`` (NGA.STND.0024-1, SICD Volume 1, sections
"ImageData", "GeoData", "RadarCollection"; NGA.STND.0024-3, Image Projections).

Every pixel of a sarmitsuba SICD is valid (the grid lies inside the focused image), so
``ValidData`` is the image's four corner pixels, the first at the first row and column and
clockwise on the (row, column) plane as SICD asks; ``GeoData/ValidData`` and ``ImageCorners``
are those pixels projected along their R/Rdot contours onto the WGS84 surface at the SCP's height
(sarkit's ``image_to_constant_hae_surface``; a slant-plane pixel's own latitude and longitude
would be tens of metres off). ``Area/Corner`` bounds the imaged area on the ground: the same four
points with the SCP's height, in clockwise order seen from above.
"""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["corner_pixels", "project_pixels", "set_polygons", "PolygonError"]


class PolygonError(ValueError):
    """The image's corners do not project onto the Earth."""


def corner_pixels(n_rows: int, n_cols: int) -> np.ndarray:
    """(row, col) of the four corner pixels (int [4, 2]): first row and column, then clockwise."""
    return np.array([[0, 0], [0, n_cols - 1], [n_rows - 1, n_cols - 1], [n_rows - 1, 0]])


def project_pixels(tree: Any, rowcol: np.ndarray) -> np.ndarray:
    """(lat, lon, hae) [deg, deg, m] of pixels ``rowcol`` (int [n, 2], full-image indices less
    FirstRow/FirstCol) projected onto the surface at the SCP's height. Raises PolygonError."""
    import sarkit.sicd as sksicd
    import sarkit.wgs84
    xml = sksicd.XmlHelper(tree)
    rowcol = np.asarray(rowcol) + np.array([xml.load("{*}ImageData/{*}FirstRow"), xml.load("{*}ImageData/{*}FirstCol")])
    hae = xml.load("{*}GeoData/{*}SCP/{*}LLH")[2]
    points, _, success = sksicd.image_to_constant_hae_surface(tree, sksicd.rowcol_to_xrowycol(tree, rowcol), hae)
    if not np.all(success) or not np.all(np.isfinite(points)):
        raise PolygonError("the image's corners do not project onto the Earth (is the track above the scene?)")
    return sarkit.wgs84.cartesian_to_geodetic(points)


def _clockwise(llh: np.ndarray) -> np.ndarray:
    """``llh`` [4, 3] in clockwise order seen from above (east right, north up), the first kept."""
    lat0 = np.radians(llh[0, 0])
    east, north = (llh[:, 1] - llh[0, 1]) * np.cos(lat0), llh[:, 0] - llh[0, 0]
    twice_area = float(np.sum(east * np.roll(north, -1) - np.roll(east, -1) * north))
    return llh if twice_area < 0 else np.concatenate([llh[:1], llh[:0:-1]])


def set_polygons(tree: Any) -> None:
    """Set ``GeoData/ImageCorners``, ``ImageData/ValidData``, ``GeoData/ValidData`` and
    ``RadarCollection/Area/Corner`` of the SICD XML tree (module docstring). Raises PolygonError."""
    import sarkit.sicd as sksicd
    xml = sksicd.XmlHelper(tree)
    rowcol = corner_pixels(xml.load("{*}ImageData/{*}NumRows"), xml.load("{*}ImageData/{*}NumCols"))
    llh = project_pixels(tree, rowcol)
    xml.set("{*}GeoData/{*}ImageCorners", llh[:, :2])
    wrapper = sksicd.ElementWrapper(tree.getroot())
    wrapper["ImageData"]["ValidData"] = rowcol
    wrapper["GeoData"]["ValidData"] = llh[:, :2]
    area = llh.copy()
    area[:, 2] = xml.load("{*}GeoData/{*}SCP/{*}LLH")[2]
    wrapper["RadarCollection"]["Area"] = {"Corner": _clockwise(area)}
