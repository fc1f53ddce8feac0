"""The ground of a footprint scene: a flat plane, or terrain from a DEM GeoTIFF.

:func:`read_dem` reads a digital elevation model with rasterio (any CRS PROJ knows: geographic
or projected) over a lon/lat box, and :class:`Dem` meshes it in the scene's local ENU frame at its
own resolution: one vertex per DEM pixel centre, two triangles per 2 x 2 pixels, clipped to the
pixels whose centres cover the box (one more pixel on each side). Heights are the DEM's, less the
frame origin's height (the DEM at the scene centre), so the terrain passes through z = 0 there.
A DEM's heights are usually above the geoid (orthometric), not the WGS84 ellipsoid; the frame
keeps them as they are, which moves the map placement of the products by far less than a
resolution cell (the height enters the horizontal position only through the ellipsoid normal).

:func:`flat_ground` is the plane used without a DEM.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from ..core import georef
from .loader import SceneError

__all__ = ["DemError", "Dem", "read_dem", "flat_ground", "GroundSurface"]


class DemError(SceneError):
    """A DEM that cannot be read, or does not cover the scene; the message names the file and the fix."""


@dataclass(frozen=True)
class Dem:
    """Heights of a DEM window.

    Attributes
    ----------
    path : str
    heights : float64 [rows, cols], m
        The window's heights (no nodata inside).
    transform : affine.Affine
        Pixel (col, row) -> DEM CRS (x, y) of the window's pixel corners (rasterio convention).
    crs : rasterio.crs.CRS
    """

    path: str
    heights: np.ndarray
    transform: object
    crs: object

    def _to_dem(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        from pyproj import Transformer
        to_dem = Transformer.from_crs("EPSG:4326", self.crs.to_wkt(), always_xy=True)
        return to_dem.transform(np.asarray(lon, np.float64), np.asarray(lat, np.float64))

    def height_at(self, lon: np.ndarray, lat: np.ndarray) -> np.ndarray:
        """DEM height [m] at WGS84 ``lon``, ``lat`` [deg] (bilinear between pixel centres); float64
        of their shape. Raises DemError for a point outside the window."""
        from scipy.ndimage import map_coordinates
        x, y = self._to_dem(lon, lat)
        col, row = (~self.transform) @ (np.asarray(x), np.asarray(y))
        row, col = np.asarray(row) - 0.5, np.asarray(col) - 0.5          # pixel centres at integers
        rows, cols = self.heights.shape
        if np.any((row < 0) | (col < 0) | (row > rows - 1) | (col > cols - 1)):
            raise DemError(f"{self.path}: a point lies outside the DEM's window; give a DEM that covers the "
                           "footprints and their margin")
        return map_coordinates(self.heights, [np.ravel(row), np.ravel(col)], order=1).reshape(np.shape(lon))

    def mesh(self, ref: georef.GeoReference) -> trimesh.Trimesh:
        """The window as a triangle mesh in the local ENU frame at ``ref`` (m): one vertex per pixel
        centre, z = DEM height - ``ref.height_m``."""
        from pyproj import Transformer
        rows, cols = self.heights.shape
        col, row = np.meshgrid(np.arange(cols) + 0.5, np.arange(rows) + 0.5)
        x, y = self.transform @ (col.ravel(), row.ravel())
        to_lonlat = Transformer.from_crs(self.crs.to_wkt(), "EPSG:4326", always_xy=True)
        lon, lat = to_lonlat.transform(np.asarray(x), np.asarray(y))
        local = georef.geodetic_to_enu(np.column_stack([lat, lon, np.full(len(lon), ref.height_m)]), ref)
        vertices = np.column_stack([local[:, :2], self.heights.ravel() - ref.height_m])
        index = np.arange(rows * cols).reshape(rows, cols)
        a, b, c, d = index[:-1, :-1].ravel(), index[:-1, 1:].ravel(), index[1:, 1:].ravel(), index[1:, :-1].ravel()
        faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        if np.mean(mesh.face_normals[:, 2]) < 0.0:                   # rows run south: wind up
            mesh.invert()
        return mesh


def read_dem(path: str | Path, bounds: tuple[float, float, float, float]) -> Dem:
    """The window of the DEM GeoTIFF at ``path`` covering ``bounds`` (lon0, lat0, lon1, lat1) [deg].

    Band 1 holds heights [m]. Raises DemError (naming the file) when it cannot be read, has no
    CRS, does not cover ``bounds`` with one pixel to spare, or has nodata inside the window.
    """
    import rasterio
    from affine import Affine
    from rasterio.windows import Window
    from pyproj import Transformer
    path = Path(path)
    try:
        dataset = rasterio.open(path)
    except (rasterio.errors.RasterioIOError, OSError) as exc:
        raise DemError(f"--dem {path}: cannot read it as a GeoTIFF ({exc}); give a DEM GeoTIFF") from None
    with dataset:
        if dataset.crs is None:
            raise DemError(f"--dem {path}: the file has no CRS; give a georeferenced DEM (e.g. EPSG:4326 or UTM)")
        to_dem = Transformer.from_crs("EPSG:4326", dataset.crs.to_wkt(), always_xy=True)
        lon = np.array([bounds[0], bounds[2], bounds[2], bounds[0]])
        lat = np.array([bounds[1], bounds[1], bounds[3], bounds[3]])
        x, y = to_dem.transform(lon, lat)
        cols, rows = (~dataset.transform) @ (np.asarray(x), np.asarray(y))       # fractional pixel corners
        col0, row0 = int(np.floor(np.min(cols))) - 1, int(np.floor(np.min(rows))) - 1
        col1, row1 = int(np.ceil(np.max(cols))) + 1, int(np.ceil(np.max(rows))) + 1
        if col0 < 0 or row0 < 0 or col1 > dataset.width or row1 > dataset.height:
            raise DemError(f"--dem {path}: the DEM ({dataset.width} x {dataset.height} pixels) does not cover the "
                           f"footprints and their margin (lon {bounds[0]:.5f}..{bounds[2]:.5f}, lat "
                           f"{bounds[1]:.5f}..{bounds[3]:.5f}); give a larger DEM or a smaller --margin")
        window = Window(col0, row0, col1 - col0, row1 - row0)
        data = dataset.read(1, window=window, masked=True).astype(np.float64)
        transform = dataset.transform @ Affine.translation(col0, row0)
        crs = dataset.crs
    if np.ma.count_masked(data) or not np.all(np.isfinite(data)):
        raise DemError(f"--dem {path}: {int(np.ma.count_masked(data) + np.sum(~np.isfinite(data.filled(0))))} "
                       "pixels over the area have no data; fill the DEM's voids first (e.g. gdal_fillnodata)")
    return Dem(str(path), np.asarray(data.filled(0.0)), transform, crs)


def flat_ground(x0: float, y0: float, x1: float, y1: float) -> trimesh.Trimesh:
    """The rectangle [x0, x1] x [y0, y1] at z = 0 [m]: two triangles, normal +z."""
    vertices = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
    return trimesh.Trimesh(vertices, np.array([[0, 1, 2], [0, 2, 3]]), process=False)


class GroundSurface:
    """Heights of a ground mesh (a plane, a DEM mesh, a scene's ground) under building outlines:
    shapely's STRtree finds the triangles under a point, trimesh's barycentric coordinates give
    the height on them. ``mesh`` None is the plane z = 0."""

    def __init__(self, mesh) -> None:
        import shapely
        self.mesh = mesh
        if mesh is not None:
            self.tree = shapely.STRtree(shapely.polygons(mesh.triangles[:, :, :2]))

    def lowest_under(self, outline) -> float:
        """Lowest ground height [m] at the outline's vertices and the ground vertices inside it;
        the ground's lowest vertex when the outline lies off the ground."""
        import shapely
        import trimesh
        if self.mesh is None:
            return 0.0
        rings = [np.asarray(r.coords)[:, :2] for p in getattr(outline, "geoms", [outline])
                 for r in (p.exterior, *p.interiors)]
        xy = np.vstack(rings)
        point_index, tri_index = self.tree.query(shapely.points(xy), predicate="intersects")
        heights = []
        if len(point_index):
            tri = self.mesh.triangles[tri_index]
            plan = tri.copy()
            plan[:, :, 2] = 0.0
            points = np.column_stack([xy[point_index], np.zeros(len(point_index))])
            bary = trimesh.triangles.points_to_barycentric(plan, points)
            heights.append(np.einsum("ij,ij->i", bary, tri[:, :, 2]))
        inside = shapely.contains_xy(outline, self.mesh.vertices[:, 0], self.mesh.vertices[:, 1])
        heights.append(self.mesh.vertices[inside, 2])
        heights = np.concatenate(heights)
        return float(heights.min()) if heights.size else float(self.mesh.vertices[:, 2].min())
