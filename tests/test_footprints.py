"""Scenes from building footprints (issue 31): reading, checking, projecting and extruding GeoJSON.

Truth used: geodesic distances and azimuths of pyproj's ``Geod`` (Karney 2013, a method independent
of the topocentric frame the code uses) to place corners and measure the scene's origin; closed-form
volumes of prisms and roofs (a roof over an a x b rectangle with ridge length c has volume
b h (2 a + c) / 6); trimesh's ``extrude_polygon`` as the second extruder; a DEM that is a known plane.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from pyproj import Geod

import sarmitsuba  # noqa: F401  (variant and plugins)
from sarmitsuba.cli import main
from sarmitsuba.scene.buildings import building_mesh, flat_building_mesh
from sarmitsuba.scene.city import build_city, write_city
from sarmitsuba.scene.footprints import FootprintError, parse_footprints

GEOD = Geod(ellps="WGS84")
LAT, LON = 48.1500, 11.5700          # centre the test files are laid out about


def _at(east: float, north: float, lat: float = LAT, lon: float = LON) -> list[float]:
    """[lon, lat] of the point ``east``, ``north`` metres from (lat, lon), by the geodesic."""
    azimuth = math.degrees(math.atan2(east, north))
    lon2, lat2, _ = GEOD.fwd(lon, lat, azimuth, math.hypot(east, north))
    return [lon2, lat2]


def rectangle(cx: float, cy: float, length: float, width: float, angle_deg: float = 0.0) -> list:
    """Closed ring [lon, lat] of a length x width rectangle centred ``cx``, ``cy`` m east/north of the
    centre, its length turned ``angle_deg`` counter-clockwise from east (metres on the ground)."""
    a = math.radians(angle_deg)
    u, v = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    corners = [np.array([cx, cy]) + su * 0.5 * length * u + sv * 0.5 * width * v
               for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1), (-1, -1))]
    return [_at(*c) for c in corners]


def feature(rings: list, fid=None, **props) -> dict:
    body = {"type": "Feature", "properties": props, "geometry": {"type": "Polygon", "coordinates": rings}}
    return body if fid is None else {"id": fid, **body}


def collection(*features) -> dict:
    return {"type": "FeatureCollection", "features": list(features)}


def write(tmp_path, data, name="city.geojson"):
    path = tmp_path / name
    path.write_text(json.dumps(data) if not isinstance(data, str) else data)
    return path


# --- heights, roofs and materials -----------------------------------------------------------------

@pytest.mark.parametrize("props, height", [({"height": 17.5}, 17.5), ({"height": "12 m"}, 12.0),
                                           ({"height": "40 ft"}, 12.192), ({"building:levels": 4}, 12.0),
                                           ({"building:levels": "7", "height": "9"}, 9.0)])
def test_height_properties(props, height):
    fs = parse_footprints(collection(feature([rectangle(0, 0, 20, 10)], **props)))
    assert fs.footprints[0].height == pytest.approx(height)
    mesh = build_city(fs).buildings[0][1]
    assert mesh.bounds[1, 2] == pytest.approx(height, abs=1e-6)          # the roof top, ground at z = 0


def test_default_height_and_refusal():
    data = collection(feature([rectangle(0, 0, 20, 10)], fid="way/7"))
    assert parse_footprints(data, default_height=8.0).footprints[0].height == 8.0
    with pytest.raises(FootprintError, match=r"feature 0 \(id way/7\): no height"):
        parse_footprints(data)


@pytest.mark.parametrize("name, itu", [("stone", "marble"), ("Brick", "brick"), ("steel", "metal"),
                                       ("glass", "glass"), ("reinforced_concrete", "concrete")])
def test_materials(name, itu):
    fs = parse_footprints(collection(feature([rectangle(0, 0, 20, 10)], height=10, **{"building:material": name})))
    assert fs.footprints[0].material == itu


def test_pitched_roofs_from_levels_sit_on_top():
    """building:levels give the walls; roof:height is added above them (OSM counts roof storeys apart)."""
    fs = parse_footprints(collection(
        feature([rectangle(0, 0, 16, 10)], **{"building:levels": 2, "roof:shape": "gabled", "roof:height": 4}),
        feature([rectangle(60, 0, 16, 10)], **{"height": 10, "roof:shape": "gabled", "roof:height": 4})))
    tops = [mesh.bounds[1, 2] for _, mesh in build_city(fs).buildings]
    assert tops == pytest.approx([10.0, 10.0], abs=1e-6)
    for _, mesh in build_city(fs).buildings:
        # gable: 16 x 10 footprint, 6 m walls from z = -1 (BASE_DEPTH) plus a 4 m roof prism of 10 x 4 / 2 x 16
        assert mesh.volume == pytest.approx(16 * 10 * 7 + 0.5 * 10 * 4 * 16, rel=1e-6)


# --- extrusion ------------------------------------------------------------------------------------

def _outline(angle_deg: float, hole: bool = True):
    from shapely import affinity
    from shapely.geometry import Polygon
    shell = [(0, 0), (30, 0), (30, 12), (0, 12)]
    polygon = Polygon(shell, [[(5, 3), (5, 7), (11, 7), (11, 3)]] if hole else None)
    return affinity.rotate(polygon, angle_deg, origin=(0, 0))


@pytest.mark.parametrize("angle", [0.0, 30.0, 57.0])
def test_flat_extrusion_matches_trimesh(angle):
    """The extruder against trimesh's extrude_polygon: volume, area, bounds; closed with outward normals."""
    polygon = _outline(angle)
    mesh, reference = building_mesh(polygon, -1.0, 9.0), flat_building_mesh(polygon, -1.0, 10.0)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    assert mesh.volume == pytest.approx(reference.volume, rel=1e-9) == (30 * 12 - 24) * 10
    assert mesh.area == pytest.approx(reference.area, rel=1e-9)
    np.testing.assert_allclose(mesh.bounds, reference.bounds, atol=1e-9)


@pytest.mark.parametrize("angle", [30.0, 57.0])
@pytest.mark.parametrize("shape, ridge", [("gabled", 30.0), ("hipped", 30.0 - 12.0), ("pyramidal", None)])
def test_roof_volumes(shape, ridge, angle):
    """Roof volume over a 30 x 12 m rectangle, 4 m high: b h (2 a + c) / 6 (c the ridge length), or the
    pyramid's a b h / 3; the top at eaves + 4 m; a closed, outward mesh."""
    polygon = _outline(angle, hole=False)
    mesh = building_mesh(polygon, 0.0, 6.0, shape, 4.0)
    roof = 30 * 12 * 4 / 3 if ridge is None else 12 * 4 * (2 * 30 + ridge) / 6
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(30 * 12 * 6 + roof, rel=1e-9)
    assert mesh.bounds[1, 2] == pytest.approx(10.0)


def test_ridge_across():
    """roof:orientation = across turns the ridge: over 30 x 12 m the gable's prism then spans the 12 m side."""
    mesh = building_mesh(_outline(0.0, hole=False), 0.0, 6.0, "gabled", 4.0, across=True)
    assert mesh.volume == pytest.approx(30 * 12 * 6 + 0.5 * 30 * 4 * 12, rel=1e-9)
    top = mesh.vertices[np.isclose(mesh.vertices[:, 2], 10.0)]
    np.testing.assert_allclose(top[:, 0], 15.0, atol=1e-9)          # ridge along x = 15, across the long side


# --- frame and projection -------------------------------------------------------------------------

def test_geo_origin_and_sizes(tmp_path):
    """Two 40 x 20 m blocks at 30 deg laid out by the geodesic, point-symmetric about (LAT, LON): the
    written geo_origin is within 0.5 m of that centre, and the meshes have the sizes, angle and
    positions laid out."""
    data = collection(feature([rectangle(-60, -30, 40, 20, 30.0)], height=10),
                      feature([rectangle(60, 30, 40, 20, 30.0)], height=15))
    path = write_city(build_city(parse_footprints(data)), tmp_path / "city")
    sensor = {e.get("name"): e.get("value") for e in ET.parse(path).getroot().find("sensor")}
    lat, lon, h = (float(v) for v in sensor["geo_origin"].split(","))
    assert GEOD.inv(lon, lat, LON, LAT)[2] < 0.5 and h == 0.0
    assert sensor["scene_center"] == "0, 0, 0"
    city = build_city(parse_footprints(data))
    oblique = city.buildings[0][1]
    top = oblique.vertices[np.isclose(oblique.vertices[:, 2], 10.0)][:, :2]
    assert len(top) == 4
    pairs = [(i, j) for i in range(4) for j in range(i + 1, 4)]
    lengths = {pair: float(np.linalg.norm(top[pair[0]] - top[pair[1]])) for pair in pairs}
    np.testing.assert_allclose(sorted(lengths.values())[:4], [20, 20, 40, 40], atol=0.02)
    long_side = min((p for p in pairs if abs(lengths[p] - 40) < 1), key=lambda p: top[p[0], 1] + top[p[1], 1])
    direction = top[long_side[1]] - top[long_side[0]]
    assert math.degrees(math.atan2(direction[1], direction[0])) % 180.0 == pytest.approx(30.0, abs=0.05)
    np.testing.assert_allclose(top.mean(axis=0), [-60.0, -30.0], atol=0.05)
    other = city.buildings[1][1].vertices
    np.testing.assert_allclose(other[np.isclose(other[:, 2], 15.0)][:, :2].mean(axis=0), [60.0, 30.0], atol=0.05)


def test_render_takes_the_folder(tmp_path):
    data = collection(feature([rectangle(0, 0, 20, 10)], height=10))
    out = tmp_path / "city"
    assert main(["scene", "from-footprints", str(write(tmp_path, data)), "--out", str(out)]) == 0
    # each building's walls and roof are shapes of their own (the city preset tells them apart)
    assert sorted(p.name for p in (out / "meshes").iterdir()) == ["b0-roof.ply", "b0.ply", "ground.ply"]
    from sarmitsuba.scene.loader import load_scene
    for source in (out, out / "scene.xml"):
        loaded = load_scene(str(source))
        assert loaded.params.geo_origin is not None and loaded.n_shapes == 3     # walls, roof, ground


# --- bad input: exit 2, one line per feature, nothing written ----------------------------------------

BAD = collection(
    feature([[_at(0, 0), _at(20, 20), _at(20, 0), _at(0, 20), _at(0, 0)]], fid="way/1", height=10),     # bow-tie
    {"type": "Feature", "properties": {"name": "Fountain", "height": 3},
     "geometry": {"type": "Point", "coordinates": _at(0, 0)}},
    feature([rectangle(50, 0, 10, 10)], height=10, name="Mud hut", **{"building:material": "adobe"}),
    feature([], fid=4, height=10),
    feature([rectangle(80, 0, 10, 10)], height=8))


def test_bad_features_one_line_each(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["scene", "from-footprints", str(write(tmp_path, BAD)), "--out", str(out)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 4 and all(line.startswith("error: ") for line in lines)
    for line, words in zip(lines, (("feature 0 (id way/1)", "self-intersection", "--repair"),
                                   ("feature 1 (name Fountain)", "Point"),
                                   ("feature 2 (name Mud hut)", "adobe", "valid:"), ("feature 3 (id 4)", "empty"))):
        assert all(w in line for w in words), line
    assert not out.exists()


def test_repair_reports_each_feature(tmp_path, capsys):
    data = collection(BAD["features"][0], BAD["features"][4])
    out = tmp_path / "out"
    assert main(["scene", "from-footprints", str(write(tmp_path, data)), "--out", str(out), "--repair"]) == 0
    err = capsys.readouterr().err
    assert err.count("repaired: ") == 1 and "feature 0 (id way/1)" in err and "MultiPolygon of 2 part" in err
    assert len(list((out / "meshes").iterdir())) == 5          # two buildings' walls and roofs, the ground


@pytest.mark.parametrize("text, words", [("not json at all", "not GeoJSON"),
                                         ('{"type": "Point", "coordinates": [1, 2]}', "not a GeoJSON FeatureCollection"),
                                         ('{"type": "FeatureCollection", "features": []}', "no features")])
def test_bad_files(tmp_path, text, words):
    """A file that is not building GeoJSON: one line, exit 2, no traceback (a fresh process)."""
    result = subprocess.run([sys.executable, "-m", "sarmitsuba", "scene", "from-footprints",
                             str(write(tmp_path, text)), "--out", str(tmp_path / "out")], capture_output=True, text=True)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.count("\n") == 1 and words in result.stderr
    assert not (tmp_path / "out").exists()


def test_bad_options(tmp_path, capsys):
    path = write(tmp_path, collection(feature([rectangle(0, 0, 20, 10)], height=10)))
    for flags, words in ((["--material", "unobtanium"], "--material"), (["--ground-material", "stone"], "marble"),
                         (["--scattering-coefficient", "1.5"], "--scattering-coefficient"),
                         (["--set", "frequency=-3"], "frequency")):
        assert main(["scene", "from-footprints", str(path), "--out", str(tmp_path / "o"), *flags]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err, err
    assert not (tmp_path / "o").exists()


def test_rewrite_replaces_the_scene(tmp_path):
    """Writing again replaces scene.xml and meshes/ (no stale building is left)."""
    out = tmp_path / "city"
    two = collection(feature([rectangle(0, 0, 20, 10)], height=10), feature([rectangle(40, 0, 20, 10)], height=10))
    write_city(build_city(parse_footprints(two)), out)
    write_city(build_city(parse_footprints(collection(two["features"][0]))), out)
    assert sorted(p.name for p in (out / "meshes").iterdir()) == ["b0-roof.ply", "b0.ply", "ground.ply"]
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []


def _dem(path, east0, north0, size=40, nodata_at=None):
    """A flat 100 m DEM of ``size`` x ``size`` 5 m pixels centred on (east0, north0) in UTM 32N."""
    import rasterio
    from affine import Affine
    heights = np.full((size, size), 100.0)
    if nodata_at is not None:
        heights[nodata_at] = -9999.0
    with rasterio.open(path, "w", driver="GTiff", height=size, width=size, count=1, dtype="float64", nodata=-9999.0,
                       crs="EPSG:32632", transform=Affine(5.0, 0, east0 - 2.5 * size, 0, -5.0, north0 + 2.5 * size)) as d:
        d.write(heights, 1)
    return path


@pytest.mark.parametrize("case, words", [("small", "does not cover"), ("void", "no data"), ("text", "cannot read")])
def test_bad_dem(tmp_path, capsys, case, words):
    """A DEM that misses part of the area, has a void there, or is no GeoTIFF: one line naming --dem."""
    from pyproj import Transformer
    east0, north0 = Transformer.from_crs("EPSG:4326", "EPSG:32632", always_xy=True).transform(LON, LAT)
    dem = tmp_path / "dem.tif"
    if case == "text":
        dem.write_text("not a raster")
    else:
        _dem(dem, east0, north0, size=8 if case == "small" else 40, nodata_at=(20, 20) if case == "void" else None)
    path = write(tmp_path, collection(feature([rectangle(0, 0, 30, 20)], height=10)))
    assert main(["scene", "from-footprints", str(path), "--out", str(tmp_path / "o"), "--dem", str(dem)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--dem" in err and words in err, err
    assert not (tmp_path / "o").exists()


def test_failed_write_leaves_the_folder_as_it_was(tmp_path, monkeypatch):
    """A writer failing halfway (disk full) leaves the earlier scene.xml and meshes/ untouched."""
    import trimesh
    out = tmp_path / "city"
    write_city(build_city(parse_footprints(collection(feature([rectangle(0, 0, 20, 10)], height=10)))), out)
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    calls = []

    def full(*args, **kwargs):
        calls.append(1)
        if len(calls) > 1:
            raise OSError(28, "No space left on device")
        return export(*args, **kwargs)

    export = trimesh.exchange.ply.export_ply
    monkeypatch.setattr(trimesh.exchange.ply, "export_ply", full)
    three = collection(*(feature([rectangle(40 * i, 0, 20, 10)], height=10 + i) for i in range(3)))
    with pytest.raises(OSError, match="No space"):
        write_city(build_city(parse_footprints(three)), out)
    assert {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_multipolygon_is_one_building():
    """A MultiPolygon (a building in two parts, one with a courtyard) is one closed mesh of both parts."""
    geometry = {"type": "MultiPolygon", "coordinates": [[rectangle(-30, 0, 20, 10)],
                                                        [rectangle(30, 0, 30, 30), rectangle(30, 0, 10, 10)[::-1]]]}
    fs = parse_footprints(collection({"type": "Feature", "properties": {"height": 9}, "geometry": geometry}))
    [(footprint, mesh)] = build_city(fs).buildings
    assert mesh.is_watertight and len(mesh.split(only_watertight=True)) == 2
    assert mesh.volume == pytest.approx((20 * 10 + 30 * 30 - 10 * 10) * 10, rel=2e-3)     # 9 m + 1 m below ground
