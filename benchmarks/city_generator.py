"""A synthetic city of a given triangle count, built from footprints over a DEM (issue 56).

The city is made the way a user makes one from OpenStreetMap data: GeoJSON building footprints
(WGS84 longitude, latitude) and a DEM GeoTIFF go through the project's own path,
:func:`sarmitsuba.scene.city.build_city` (footprints, :mod:`sarmitsuba.scene.footprints`; terrain,
:func:`sarmitsuba.scene.terrain.read_dem`) and :func:`sarmitsuba.scene.city.write_city`
(``scene.xml`` + one PLY per building + the ground). Only this script is committed, not its output.

Layout (every number below is a module constant; the draw is seeded, so a size and a seed give
one city, bit for bit):

* a square of side ``L`` about the origin (:data:`ORIGIN`), cut into lots of :data:`LOT` m; every
  :data:`BLOCK`-th row and column of lots is a street (no building), so blocks of
  ``(BLOCK - 1)^2`` lots;
* one building per lot: a rectangle (7-11 m a side) with a gabled or a flat roof, or an
  L-shaped outline (10-12 m, a 4-6 m notch) with a flat roof, :data:`MIX` of them; 2-5 storeys
  (``building:levels``, 3 m each) to the eaves, pitched roofs on top at
  :data:`~sarmitsuba.scene.footprints.ROOF_PITCH_DEG` (30 deg); concrete or brick;
* the ground: a DEM GeoTIFF (UTM, :data:`DEM_PIXEL` m pixels) of gentle hills, a sum of
  :data:`HILLS` sinusoids of 150-600 m wavelength and 1-4 m amplitude, meshed by
  :meth:`sarmitsuba.scene.terrain.Dem.mesh` (two triangles per pixel).

Triangle count, closed form: each building's mesh is closed and genus 0 with a fixed count per
kind, :data:`TRIANGLES_PER_KIND` (a rectangle's box: 12; a gable adds 8; the L's prism: 20), and the terrain ``2 (rows - 1) (cols - 1)`` for the DEM window of ``rows x cols`` pixels
that covers the footprints and the 10 m margin. ``L`` is chosen from the requested count with
the expected density (:func:`side_for`): about 0.56 triangles per square metre, so 1 M
triangles is a 1.34 km square of ~5,800 buildings, 100 k 420 m, 10 k 130 m.

Usage: ``python benchmarks/city_generator.py --triangles 1e6 --out DIR [--seed 56]``; then
``python -m sarmitsuba info DIR`` and ``python -m sarmitsuba render DIR``.
"""
from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sarmitsuba.core import georef

#: WGS84 origin of the city (latitude, longitude [deg], height of the DEM there [m]).
ORIGIN = (48.0, 11.0, 500.0)
#: m: lot pitch; every BLOCK-th lot row and column is a street.
LOT = 14.0
BLOCK = 5
#: m: DEM pixel (UTM metres) and its extra cover beyond the city's square and margin.
DEM_PIXEL = 2.0
DEM_PAD = 60.0
#: m of ground around the footprints (build_city's ``margin``).
MARGIN = 10.0
#: (kind, share): rectangle gabled / flat, L-shape flat.
#: (A hipped roof is left out: on a projected outline, rectangular only to rounding, about 10 % of
#: hipped meshes gain sliver triangles, 22-28 instead of 20, which breaks the closed form.)
MIX = (("rect_gabled", 0.55), ("rect_flat", 0.2), ("l_flat", 0.25))
#: Triangles of each kind's closed mesh (:func:`sarmitsuba.scene.buildings.building_mesh`): box 12,
#: a gabled box (two roof planes, gable walls to the ridge) 20, the L prism (6 walls, 4 + 4 caps) 20.
TRIANGLES_PER_KIND = {"rect_gabled": 20, "rect_flat": 12, "l_flat": 20}
#: Hills of the DEM: this many sinusoids (seeded wavelengths 150-600 m, amplitudes 1-4 m).
HILLS = 6


@dataclass(frozen=True)
class CityPlan:
    """The drawn city, before any mesh: ``side`` [m], building outlines in local metres
    (x east, y north; list of float64 [k, 2] rings), their kinds and storeys and materials,
    and the DEM's hill parameters (float64 [HILLS, 5]: kx, ky [rad/m], phase x, phase y, amplitude [m])."""

    side: float
    seed: int
    outlines: list
    kinds: list
    levels: list
    materials: list
    hills: np.ndarray

    def building_triangles(self) -> int:
        """Closed-form triangles of the buildings: :data:`TRIANGLES_PER_KIND` summed over kinds."""
        return sum(TRIANGLES_PER_KIND[k] for k in self.kinds)

    def terrain_triangles(self) -> int:
        """Closed-form estimate of the terrain's triangles: two per DEM pixel over the square,
        the margin and :meth:`sarmitsuba.scene.terrain.read_dem`'s window rounding (10 % of the
        margin and one pixel on each side), ``2 (n - 1)^2`` with ``n`` pixels a side (exact to
        a pixel row either way: the window is cut in UTM, not along the local axes)."""
        n = self.terrain_pixels()
        return 2 * (n - 1) ** 2

    def terrain_pixels(self) -> int:
        """DEM pixels along one side of the window :func:`build_city` reads (see :meth:`terrain_triangles`)."""
        boxes = np.array([[o[:, 0].min(), o[:, 1].min(), o[:, 0].max(), o[:, 1].max()] for o in self.outlines])
        width = max(boxes[:, 2].max() - boxes[:, 0].min(), boxes[:, 3].max() - boxes[:, 1].min())
        # the window is cut along UTM's grid, turned by the grid convergence gamma from the local axes
        lat, lon = math.radians(ORIGIN[0]), ORIGIN[1]
        gamma = math.atan(math.tan(math.radians(lon - (6 * math.floor((lon + 180) / 6) - 177))) * math.sin(lat))
        return math.ceil((width + 2 * 1.1 * MARGIN) * (math.cos(gamma) + abs(math.sin(gamma))) / DEM_PIXEL) + 2

    def triangles(self) -> int:
        return self.building_triangles() + self.terrain_triangles()


def density() -> float:
    """Expected triangles per square metre of the city's square (buildings and terrain)."""
    lots = ((BLOCK - 1) / BLOCK) ** 2 / LOT ** 2
    per_building = sum(TRIANGLES_PER_KIND[k] * w for k, w in MIX)
    return lots * per_building + 2.0 / DEM_PIXEL ** 2


def side_for(triangles: float) -> float:
    """Side [m] of the square whose city has about ``triangles`` triangles (:func:`density`),
    rounded to whole blocks (at least one)."""
    side = math.sqrt(max(triangles, 1.0) / density())
    return LOT * BLOCK * max(1, round(side / (LOT * BLOCK)))


def plan_city(triangles: float = 1e6, seed: int = 56) -> CityPlan:
    """Draw the city of about ``triangles`` triangles (module docstring); deterministic in ``seed``."""
    side = side_for(triangles)
    n = int(round(side / LOT))
    rng = np.random.default_rng(seed)
    kinds_all = [k for k, _ in MIX]
    shares = np.array([w for _, w in MIX])
    outlines, kinds, levels, materials = [], [], [], []
    for i in range(n):
        for j in range(n):
            if i % BLOCK == BLOCK - 1 or j % BLOCK == BLOCK - 1:
                continue                                      # street
            kind = kinds_all[int(rng.choice(len(kinds_all), p=shares))]
            cx, cy = -side / 2 + LOT * (i + 0.5), -side / 2 + LOT * (j + 0.5)
            if kind.startswith("rect"):
                w, d = rng.uniform(7.0, 11.0, 2)
                ring = np.array([[-w, -d], [w, -d], [w, d], [-w, d]]) / 2
            else:
                w, d = rng.uniform(10.0, 12.0, 2)
                a, b = rng.uniform(4.0, 6.0, 2)
                ring = np.array([[0, 0], [w, 0], [w, b], [a, b], [a, d], [0, d]]) - [w / 2, d / 2]
                ring = _rotate_quarter(ring, int(rng.integers(4)))
            outlines.append(ring + [cx, cy])
            kinds.append(kind)
            levels.append(int(rng.integers(2, 6)))
            materials.append("brick" if rng.random() < 0.3 else "concrete")
    k = rng.uniform(2 * math.pi / 600.0, 2 * math.pi / 150.0, (HILLS, 2))
    hills = np.column_stack([k, rng.uniform(0, 2 * math.pi, (HILLS, 2)), rng.uniform(1.0, 4.0, HILLS)])
    return CityPlan(side, seed, outlines, kinds, levels, materials, hills)


def _rotate_quarter(ring: np.ndarray, turns: int) -> np.ndarray:
    """``ring`` float64 [k, 2] turned by ``turns`` quarter turns counter-clockwise (exact)."""
    for _ in range(turns):
        ring = np.column_stack([-ring[:, 1], ring[:, 0]])
    return ring


def hill_height(plan: CityPlan, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Terrain height above the origin's [m] at local ``x``, ``y`` [m] (float64 arrays)."""
    z = np.zeros(np.broadcast(x, y).shape)
    for kx, ky, px, py, amp in plan.hills:
        z += amp * np.sin(kx * x + px) * np.cos(ky * y + py)
    return z


def footprints_geojson(plan: CityPlan) -> dict:
    """The plan's footprints as a GeoJSON FeatureCollection (WGS84 lon/lat, OSM properties)."""
    ref = georef.GeoReference(*ORIGIN)
    rings = [np.vstack([o, o[:1]]) for o in plan.outlines]
    flat = np.vstack(rings)
    llh = georef.enu_to_geodetic(np.column_stack([flat, np.zeros(len(flat))]), ref)
    features, start = [], 0
    for index, (ring, kind, levels, material) in enumerate(zip(rings, plan.kinds, plan.levels, plan.materials)):
        lonlat = llh[start:start + len(ring), [1, 0]]
        start += len(ring)
        roof = kind.split("_")[1]
        features.append({"type": "Feature", "id": f"b{index}",
                         "properties": {"building:levels": levels, "roof:shape": roof, "building:material": material},
                         "geometry": {"type": "Polygon", "coordinates": [lonlat.tolist()]}})
    return {"type": "FeatureCollection", "features": features}


def write_dem(plan: CityPlan, path: Path) -> Path:
    """The plan's hills as a float32 GeoTIFF in the origin's UTM zone, :data:`DEM_PIXEL` m pixels,
    heights ``ORIGIN[2] + hill_height`` [m]."""
    import rasterio
    from affine import Affine
    ref = georef.GeoReference(*ORIGIN)
    crs = georef.utm_crs(ref)
    half = plan.side / 2 + MARGIN + DEM_PAD
    n = int(math.ceil(2 * half / DEM_PIXEL))
    e0, n0 = georef.enu_to_utm(np.array([[0.0, 0.0, 0.0]]), ref)[0, :2]
    west, north = e0 - half, n0 + half
    col, row = np.meshgrid(np.arange(n) + 0.5, np.arange(n) + 0.5)
    east, northing = west + DEM_PIXEL * col, north - DEM_PIXEL * row
    # local frame of the UTM pixel centres (grid convergence turns it by a fraction of a degree)
    heights = ORIGIN[2] + hill_height(plan, east - e0, northing - n0)
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="float32",
                       crs=crs.to_wkt() if hasattr(crs, "to_wkt") else crs,
                       transform=Affine.translation(west, north) @ Affine.scale(DEM_PIXEL, -DEM_PIXEL)) as dst:
        dst.write(heights.astype(np.float32), 1)
    return path


def generate(out: str | Path, triangles: float = 1e6, seed: int = 56, sensor: dict | None = None) -> tuple:
    """Write the city of about ``triangles`` triangles into ``out`` (``footprints.geojson``,
    ``dem.tif``, ``scene.xml``, ``meshes/``); returns ``(scene.xml path, CityPlan, City)``."""
    from sarmitsuba.scene.city import build_city, write_city
    from sarmitsuba.scene.footprints import parse_footprints
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    plan = plan_city(triangles, seed)
    data = footprints_geojson(plan)
    (out / "footprints.geojson").write_text(json.dumps(data))
    dem = write_dem(plan, out / "dem.tif")
    city = build_city(parse_footprints(data, str(out / "footprints.geojson")), dem=dem, margin=MARGIN,
                      origin=ORIGIN, sensor=sensor)
    return write_city(city, out), plan, city


def count_triangles(xml: str | Path) -> int:
    """Triangles of the written city (trimesh, every PLY under ``meshes/``)."""
    import trimesh
    return sum(len(trimesh.load(p, process=False).faces) for p in sorted((Path(xml).parent / "meshes").glob("*.ply")))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", type=float, default=1e6, help="about this many triangles (default 1e6)")
    parser.add_argument("--seed", type=int, default=56)
    parser.add_argument("--out", required=True, help="folder for scene.xml, meshes/, footprints.geojson, dem.tif")
    args = parser.parse_args()
    start = time.perf_counter()
    xml, plan, city = generate(args.out, args.triangles, args.seed)
    built = time.perf_counter() - start
    print(f"{xml}: {city.summary()}; closed form {plan.triangles():,} (buildings {plan.building_triangles():,}, "
          f"terrain {plan.terrain_triangles():,}); trimesh counts {count_triangles(xml):,}; built in {built:.1f} s")


if __name__ == "__main__":
    main()
