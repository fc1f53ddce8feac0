"""Footprint scenes: holes a mutation audit left open (issue 55, item 6).

- ``roof:levels`` sets a pitched roof's height (levels x 3 m, OpenStreetMap's storey), and a
  roof without a height gets a 30 deg pitch: ridge = half the short side x tan(30 deg), worked
  by hand (2.8868 m over a 10 m wide gable; sin would give 2.5 m).
- A DEM is read over the footprints plus ``margin`` metres on every side, east-west included at
  70 deg latitude, where a degree of longitude is cos(70 deg) = 0.342 of one at the equator:
  the buildings' corners are placed with pyproj's geodesic (``Geod.fwd``), independent of the
  frame the code uses.
- ``mesh_footprints`` gives a building the mean height of its roof over its plan area: a 10 x 10
  m flat roof at 10 m beside a 20 x 10 m shed roof rising from 10 to 20 m (45 deg) has mean
  height (100 x 10 + 200 x 15) / 300 = 13.333 m, worked by hand (an unweighted mean of its
  triangles gives 12.5 m, weighting by sloped area instead of plan area 13.69 m).

Each test's docstring names the bug it catches; each was seen failing on that bug (monkeypatched).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh
from pyproj import Geod

import sarmitsuba  # noqa: F401  (variant and plugins)
from sarmitsuba.scene.city import build_city
from sarmitsuba.scene.footprints import parse_footprints
from sarmitsuba.scene.mesh_footprints import footprints_from_scene

GEOD = Geod(ellps="WGS84")
#: tan(30 deg) = 1 / sqrt(3), by hand.
TAN_30 = 1.0 / math.sqrt(3.0)


def _at(east: float, north: float, lat: float, lon: float) -> list[float]:
    """[lon, lat] of the point ``east``, ``north`` metres from (lat, lon), along the geodesic."""
    azimuth = math.degrees(math.atan2(east, north))
    lon2, lat2, _ = GEOD.fwd(lon, lat, azimuth, math.hypot(east, north))
    return [lon2, lat2]


def _rectangle(length: float, width: float, lat: float = 48.15, lon: float = 11.57) -> list:
    """Closed ring of a length (east) x width (north) rectangle centred on (lat, lon)."""
    corners = [(-1, -1), (1, -1), (1, 1), (-1, 1), (-1, -1)]
    return [_at(0.5 * length * a, 0.5 * width * b, lat, lon) for a, b in corners]


def _collection(*features) -> dict:
    return {"type": "FeatureCollection", "features": list(features)}


def _feature(ring: list, **props) -> dict:
    return {"type": "Feature", "properties": props, "geometry": {"type": "Polygon", "coordinates": [ring]}}


# --- roof:levels and the default pitch ------------------------------------------------------------

@pytest.mark.parametrize("props, top", [
    # walls 2 x 3 m, roof 2 roof storeys x 3 m on top
    ({"building:levels": 2, "roof:shape": "gabled", "roof:levels": 2}, 6.0 + 6.0),
    ({"building:levels": 1, "roof:shape": "hipped", "roof:levels": 1}, 3.0 + 3.0),
    # no roof height: 30 deg over half the 10 m side, 5 tan(30 deg) = 2.8868 m
    ({"building:levels": 2, "roof:shape": "gabled"}, 6.0 + 5.0 * TAN_30),
    ({"building:levels": 3, "roof:shape": "pyramidal"}, 9.0 + 5.0 * TAN_30),
])
def test_roof_levels_and_the_default_pitch_set_the_ridge(props, top):
    """The top of a 16 x 10 m building whose walls come from building:levels: + roof:levels x 3 m,
    else + 5 m tan(30 deg). Catches roof:levels ignored (the pitch used instead: 8.89 m, not 12 m;
    5.89 m, not 6 m) and the pitch's height taken as sin(30 deg) (8.5 m, not 8.887 m)."""
    fs = parse_footprints(_collection(_feature(_rectangle(16.0, 10.0), **props)))
    mesh = build_city(fs).buildings[0][1]
    assert mesh.bounds[1, 2] == pytest.approx(top, abs=1e-6)


@pytest.mark.parametrize("width", [8.0, 12.0])
def test_a_measured_height_keeps_the_default_pitch_within_it(width):
    """height = 12 m measured to the ridge, a gabled 20 m x ``width`` roof with no roof height: the
    roof is (width / 2) tan(30 deg) high within those 12 m. The closed mesh's volume (from
    BASE_DEPTH = 1 m below the ground) is that of the wall prism plus the roof prism,
    20 w (12 - r + 1) + w r 20 / 2, worked by hand. Catches sin for tan (the roof 4 % to 13 %
    lower, the volume off by 0.3 to 1 %)."""
    roof = 0.5 * width * TAN_30
    fs = parse_footprints(_collection(_feature(_rectangle(20.0, width), height=12, **{"roof:shape": "gabled"})))
    mesh = build_city(fs).buildings[0][1]
    assert mesh.bounds[1, 2] == pytest.approx(12.0, abs=1e-6)
    assert mesh.volume == pytest.approx(20 * width * (12.0 - roof + 1.0) + 0.5 * width * roof * 20, rel=1e-6)


# --- the DEM's east-west margin -------------------------------------------------------------------

def _geographic_dem(path, lat: float, lon: float, half_deg: float = 0.03, step: float = 2e-4):
    """A flat 100 m DEM in EPSG:4326, ``step`` deg pixels, +- ``half_deg`` about (lat, lon)."""
    import rasterio
    from affine import Affine
    n = int(round(2 * half_deg / step))
    transform = Affine(step, 0.0, lon - half_deg, 0.0, -step, lat + half_deg)
    with rasterio.open(path, "w", driver="GTiff", height=n, width=n, count=1, dtype="float64",
                       crs="EPSG:4326", transform=transform) as dst:
        dst.write(np.full((n, n), 100.0), 1)
    return path


@pytest.mark.parametrize("lat", [0.0, 70.0, -70.0])
def test_the_dem_ground_reaches_the_margin_east_and_west(tmp_path, lat):
    """A 40 x 20 m building with margin = 100 m on a geographic DEM: the DEM's ground mesh reaches at
    least 100 m beyond the building's walls on all four sides (the walls at +-20 m east and +-10 m
    north, placed by the geodesic). Catches the margin's longitude span taken without 1 / cos(lat):
    at 70 deg the ground then stops 45 m east and west of the walls."""
    lon, margin = 25.0, 100.0
    dem = _geographic_dem(tmp_path / "dem.tif", lat, lon)
    fs = parse_footprints(_collection(_feature(_rectangle(40.0, 20.0, lat, lon), height=10)))
    ground = build_city(fs, dem=dem, margin=margin, origin=(lat, lon, 100.0)).ground
    (x0, y0, _), (x1, y1, _) = ground.bounds
    assert x0 <= -20.0 - margin and x1 >= 20.0 + margin, (x0, x1)
    assert y0 <= -10.0 - margin and y1 >= 10.0 + margin, (y0, y1)


# --- mesh_footprints: the roof's plan-area mean ----------------------------------------------------

def _ply(mesh, path) -> None:
    path.write_bytes(trimesh.exchange.ply.export_ply(mesh, encoding="binary"))


def _two_part_building(tmp_path, angle_deg: float):
    """Scene XML of one building ``house`` in two shapes, turned ``angle_deg`` about z: a 10 x 10 m
    flat-roofed box 10 m high, and beside it a 20 (along x) x 10 m shed roofed from 10 m to 20 m
    across its 10 m (45 deg)."""
    flat = trimesh.creation.box([10.0, 10.0, 10.0])
    flat.apply_translation([-5.0, 5.0, 5.0])                       # x -10..0, y 0..10
    base = np.array([[0, 0], [20, 0], [20, 10], [0, 10]], float)
    tops = np.array([10.0, 10.0, 20.0, 20.0])                      # rising with y
    shed = trimesh.convex.convex_hull(np.vstack([np.column_stack([base, np.zeros(4)]),
                                                 np.column_stack([base, tops])]))
    turn = trimesh.transformations.rotation_matrix(math.radians(angle_deg), [0, 0, 1])
    for mesh, name in ((flat, "flat"), (shed, "shed")):
        mesh.apply_transform(turn)
        _ply(mesh, tmp_path / f"{name}.ply")
    xml = ['<scene version="2.1.0">',
           '<bsdf type="itu-radio-material" id="concrete"><string name="type" value="concrete"/></bsdf>',
           '<bsdf type="itu-radio-material" id="metal"><string name="type" value="metal"/></bsdf>',
           '<shape type="ply" id="mesh-house-itu_concrete"><string name="filename" value="flat.ply"/>'
           '<ref id="concrete" name="bsdf"/></shape>',
           '<shape type="ply" id="mesh-house-itu_metal"><string name="filename" value="shed.ply"/>'
           '<ref id="metal" name="bsdf"/></shape>', '</scene>']
    (tmp_path / "scene.xml").write_text("\n".join(xml))
    return tmp_path / "scene.xml"


@pytest.mark.parametrize("angle", [0.0, 33.0])
def test_roof_height_is_the_plan_area_mean_of_two_parts(tmp_path, angle):
    """The building's height is (100 m^2 x 10 m + 200 m^2 x 15 m) / 300 m^2 = 13.333 m (the shed's
    mean height is 15 m over its plan). Catches an unweighted mean of the roof triangles (12.5 m),
    weights by sloped area instead of plan area (13.69 m), the highest vertex (20 m)."""
    fc = footprints_from_scene(_two_part_building(tmp_path, angle), (48.1, 11.6, 0.0), ground=None)
    json.dumps(fc)
    (feature,) = fc["features"]
    assert feature["properties"]["height"] == pytest.approx(40.0 / 3.0, abs=2e-3)

