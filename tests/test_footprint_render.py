"""Acceptance of issue 31: footprint scenes render, and each wall facing the sensor images its
double-bounce line at its foot.

Truth: the feet are where the footprints put them, laid out in metres by pyproj's geodesic
(``test_footprints.rectangle``), independent of the code's topocentric frame; a wall-ground
dihedral images at its fold line (docs/physics.md (G1)), and a fold line at height ``h`` is laid
over toward the sensor by ``h / tan(theta)`` in ground range (G2). The tolerance is one
ground-range resolution cell, ``c / (2 B sin(theta))``. Buildings: a block turned 30 deg from the
track, a courtyard block (a hole) with its height from ``building:levels``, a block turned 60 deg;
and, on a sloping DEM, a block whose feet lie below and above the image plane.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry.polygon import orient
from test_footprints import LAT, LON, collection, feature, rectangle

import sarmitsuba  # noqa: F401
from sarmitsuba.core import georef
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.core.image import image_coordinates
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.builder import Scene
from sarmitsuba.scene.city import build_city
from sarmitsuba.scene.footprints import parse_footprints

INCIDENCE = 40.0
SENSOR = {"incidence_angle": INCIDENCE, "bandwidth": 100e6}
RESOLUTION = SPEED_OF_LIGHT / (2 * 100e6 * math.sin(math.radians(INCIDENCE)))      # ground range [m]


def _walls_facing(city, image):
    """(building label, start, end) of every outline edge whose outward normal has a horizontal
    component toward the sensor (> 0.2), holes included; ends in the local frame [m]."""
    toward = -np.asarray(image.range_direction)[:2]
    walls = []
    for footprint, _ in city.buildings:
        from shapely import transform
        outline = transform(footprint.polygon, lambda ll: georef.geodetic_to_enu(
            np.column_stack([ll[:, 1], ll[:, 0], np.zeros(len(ll))]), city.geo_origin)[:, :2])
        for part in getattr(outline, "geoms", [outline]):
            part = orient(part, 1.0)              # exterior counter-clockwise, holes clockwise: outside on the right
            for ring in (part.exterior, *part.interiors):
                xy = np.asarray(ring.coords)
                for p0, p1 in zip(xy[:-1], xy[1:]):
                    d = (p1 - p0) / np.linalg.norm(p1 - p0)
                    if np.array([d[1], -d[0]]) @ toward > 0.2:
                        walls.append((footprint.label, p0, p1))
    return walls


def _foot_offsets(image, p0, p1, height_of=lambda xy: 0.0):
    """Ground-range offset [m] of the double-bounce peak from the predicted foot, and the peak's level
    over the cut's median within 15 m [dB], at five points along the wall's middle half."""
    amplitude = np.abs(image.data)
    tan = math.tan(math.radians(INCIDENCE))
    rows = []
    for t in np.linspace(0.25, 0.75, 5):
        p = p0 + t * (p1 - p0)
        azimuth, ground_range = image_coordinates(image, [p[0], p[1], 0.0])
        ground_range -= height_of(p) / tan                      # (G2): laid over toward the sensor
        cut = amplitude[int(np.argmin(np.abs(image.azimuth - azimuth)))]
        near = np.abs(image.range - ground_range)
        peak = int(np.argmax(np.where(near <= 3 * RESOLUTION, cut, 0.0)))
        level = 20 * np.log10(cut[peak] / np.median(cut[near <= 15.0]))
        rows.append((image.range[peak] - ground_range, level))
    return np.array(rows)


@pytest.fixture(scope="module")
def city_render():
    data = collection(
        feature([rectangle(-70, 0, 36, 14, 30.0)], fid="way/30", height=20),
        feature([rectangle(0, 0, 44, 36), rectangle(0, 0, 24, 18)[::-1]], fid="way/2", name="Courtyard",
                **{"building:levels": 4, "building:material": "brick"}),
        feature([rectangle(70, 0, 30, 12, 60.0)], fid="way/60", **{"building:levels": 6}))
    assert parse_footprints(data).footprints[1].height == 12.0
    city = build_city(parse_footprints(data), sensor=SENSOR)
    sim = simulate(Scene.from_city(city), integrator_overrides={"split_bounces": True}, progress=False)
    return city, sim.images_per_order[1]


def test_double_bounce_at_every_sensor_facing_foot(city_render):
    city, order2 = city_render
    walls = _walls_facing(city, order2)
    labels = [w[0] for w in walls]
    # the 30 and 60 deg blocks show two walls each, the courtyard its north wall and its hole's south wall
    assert sorted(labels) == sorted(["feature 0 (id way/30)"] * 2 + ["feature 1 (id way/2)"] * 2
                                    + ["feature 2 (id way/60)"] * 2)
    for label, p0, p1 in walls:
        rows = _foot_offsets(order2, p0, p1)
        assert np.all(np.abs(rows[:, 0]) <= RESOLUTION), (label, p0, p1, rows)
        assert np.median(rows[:, 1]) > 10.0, (label, p0, p1, rows)


def test_hole_wall_is_not_the_outer_wall(city_render):
    """The courtyard's inner (hole) wall images 27 m behind the outer north wall: a mesher that dropped
    holes would leave no line there."""
    city, order2 = city_render
    inner = [w for w in _walls_facing(city, order2) if w[0] == "feature 1 (id way/2)"]
    feet = sorted(image_coordinates(order2, [*(0.5 * (p0 + p1)), 0.0])[1] for _, p0, p1 in inner)
    assert feet[1] - feet[0] == pytest.approx(27.0, abs=0.1)


def test_feet_on_terrain_are_laid_over(tmp_path):
    """On a DEM sloping 12 % to the east, a 100 m block along the track has its north foot 3 m below
    the image plane at a quarter of its length and 3 m above at three quarters: the double bounce
    follows the foot's layover, -h / tan(theta), within a resolution cell along the wall."""
    import rasterio
    from pyproj import Transformer
    from affine import Affine
    to_utm = Transformer.from_crs("EPSG:4326", "EPSG:32632", always_xy=True)
    east0, north0 = to_utm.transform(LON, LAT)
    x = east0 - 300 + 2.5 + 5.0 * np.arange(120)
    heights = np.repeat(500.0 + 0.12 * (x[None, :] - east0), 120, axis=0)
    with rasterio.open(tmp_path / "dem.tif", "w", driver="GTiff", height=120, width=120, count=1, dtype="float64",
                       crs="EPSG:32632", transform=Affine(5.0, 0.0, east0 - 300, 0.0, -5.0, north0 + 300)) as dem:
        dem.write(heights, 1)
    data = collection(feature([rectangle(0, 0, 100, 16)], fid="way/1", height=15))
    city = build_city(parse_footprints(data), dem=tmp_path / "dem.tif", sensor=SENSOR)
    assert city.geo_origin.height_m == pytest.approx(500.0, abs=0.05)

    def terrain(p):          # the plane, through UTM (pyproj) and back: the foot's local height
        lat, lon, _ = georef.enu_to_geodetic(np.array([p[0], p[1], 0.0]), city.geo_origin)
        return 0.12 * (to_utm.transform(lon, lat)[0] - east0)

    # OSM's height is from the lowest ground: the roof 15 m above the plane at the west corners
    mesh = city.buildings[0][1]
    top = mesh.vertices[mesh.vertices[:, 2] > mesh.vertices[:, 2].max() - 1e-6]
    assert mesh.bounds[1, 2] == pytest.approx(min(terrain(p) for p in top[:, :2]) + 15.0, abs=0.02)
    sim = simulate(Scene.from_city(city), integrator_overrides={"split_bounces": True}, progress=False)
    [(label, p0, p1)] = _walls_facing(city, sim.images_per_order[1])
    rows = _foot_offsets(sim.images_per_order[1], p0, p1, terrain)
    assert np.all(np.abs(rows[:, 0]) <= RESOLUTION) and np.median(rows[:, 1]) > 10.0, rows
    flat = _foot_offsets(sim.images_per_order[1], p0, p1)         # ignoring the terrain misses at the ends
    assert np.abs(flat[[0, -1], 0]).min() > 2.0
