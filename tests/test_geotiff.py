"""GeoTIFF of the ground-plane image (issue 17, item 3): corners on the map, bands, errors."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio")

from pyproj import Transformer  # noqa: E402

from sarmitsuba.core import georef
from sarmitsuba import pipeline  # noqa: E402
from sarmitsuba.cli import main  # noqa: E402
from sarmitsuba.formats.geotiff import GeoTiffError, write_geotiff  # noqa: E402
from sarmitsuba.core.image import SarImage  # noqa: E402


def synthetic(heading_deg, n_az=40, n_rg=60, spacing=(0.5, 0.8)):
    """A ground image whose azimuth axis points along ``heading_deg`` (ccw from east), range to its right."""
    h = np.radians(heading_deg)
    a = np.array([np.cos(h), np.sin(h), 0.0])
    r = np.array([np.sin(h), -np.cos(h), 0.0])           # right of the track
    rng = np.random.default_rng(1)
    data = (rng.normal(size=(n_az, n_rg)) + 1j * rng.normal(size=(n_az, n_rg))).astype(np.complex64)
    return SarImage(data=data, azimuth=np.arange(n_az) * spacing[0] - 7.0, range=np.arange(n_rg) * spacing[1] - 11.0,
                    origin=np.array([30.0, -20.0, 0.0]), azimuth_direction=a, range_direction=r, plane="ground",
                    algorithm="backprojection", window="rect", metadata={"units": "sqrt(m^2)"})


def corner_centres_lonlat(path):
    """Longitude, latitude of the four corner pixel centres, read with rasterio and pyproj only."""
    with rasterio.open(path) as src:
        rows, cols = [0, 0, src.height - 1, src.height - 1], [0, src.width - 1, 0, src.width - 1]
        xs, ys = rasterio.transform.xy(src.transform, rows, cols, offset="center")
        to_ll = Transformer.from_crs(src.crs, "EPSG:4326", always_xy=True)
        return np.column_stack(to_ll.transform(xs, ys)), src


# UTM zone = floor((lon + 180) / 6) + 1, EPSG 326zz north and 327zz south (by hand, not the code's formula)
MUNICH, SYDNEY = georef.GeoReference(48.1, 11.6, 520.0), georef.GeoReference(-33.9, 151.2, 40.0)
EPSG = {MUNICH: 32632, SYDNEY: 32756}


@pytest.mark.parametrize("heading, ref", [(0.0, MUNICH), (30.0, MUNICH), (-110.0, SYDNEY)])
def test_corners_on_the_map_within_a_pixel(tmp_path, heading, ref):
    """The four corner pixel centres land on the geodetic positions of the image's corner pixels."""
    image = synthetic(heading)
    path = write_geotiff(image, tmp_path / "image.tif", ref)
    got, src = corner_centres_lonlat(path)
    pos = image.positions()
    corners = np.array([pos[0, 0], pos[0, -1], pos[-1, 0], pos[-1, -1]])
    llh = georef.enu_to_geodetic(corners, ref)
    want = llh[:, [1, 0]]
    # the raster may hold the grid transposed or reversed: compare as sets of points
    d = np.linalg.norm((got[:, None, :] - want[None, :, :]) * [np.cos(np.radians(ref.latitude_deg)), 1.0], axis=2)
    metres = d.min(axis=1) * 111_320.0
    assert np.all(metres < 0.5 * min(0.5, 0.8)), metres      # well within one pixel (0.5 m)
    assert src.crs.to_epsg() == EPSG[ref]
    assert src.transform.a * src.transform.e - src.transform.b * src.transform.d < 0   # not mirrored


def test_bands_hold_db_and_linear_intensity(tmp_path):
    """Band 2 holds |s|^2 of every pixel, band 1 its dB, NaN where s = 0 (compared as value sets:
    the corner test checks where they are)."""
    image = synthetic(30.0)
    image = dataclasses.replace(image, data=image.data.copy())
    image.data[3, 4] = 0
    path = write_geotiff(image, tmp_path / "image.tif", georef.GeoReference(10.0, 20.0, 0.0))
    with rasterio.open(path) as src:
        db, lin = src.read(1), src.read(2)
        assert src.descriptions == ("intensity_db", "intensity")
    want = np.abs(image.data.astype(np.complex128)) ** 2
    np.testing.assert_allclose(np.sort(lin.ravel()), np.sort(want.ravel()), rtol=1e-6)
    np.testing.assert_allclose(db[lin > 0], 10 * np.log10(lin[lin > 0].astype(np.float64)), atol=1e-4)
    assert np.isnan(db).sum() == 1 and np.isnan(db[lin == 0]).all()


def test_a_track_flying_east_gives_a_north_up_raster(tmp_path):
    """Heading 0 (east), looking right (south): columns run east, rows south, turned only by the
    UTM grid convergence, gamma = dlambda sin(phi) to first order (Snyder 1987, eq. 8-14 ff.)."""
    image = synthetic(0.0)
    path = write_geotiff(image, tmp_path / "image.tif", georef.GeoReference(48.1, 9.5, 0.0))
    with rasterio.open(path) as src:
        t = src.transform
        assert (src.width, src.height) == (image.data.shape[0], image.data.shape[1])   # columns: azimuth
    assert t.a > 0 and t.e < 0
    gamma = 0.5 * np.sin(np.radians(48.1))                   # deg: 0.5 deg east of the central meridian 9 E
    assert abs(np.degrees(np.arctan2(t.d, t.a))) == pytest.approx(gamma, abs=0.01)
    assert abs(np.degrees(np.arctan2(t.b, -t.e))) == pytest.approx(gamma, abs=0.01)


def test_a_slant_plane_image_is_refused(tmp_path):
    image = dataclasses.replace(synthetic(0.0), plane="slant")
    with pytest.raises(GeoTiffError, match="ground"):
        write_geotiff(image, tmp_path / "image.tif")
    assert not (tmp_path / "image.tif").exists()


def test_render_geotiff_puts_the_trihedral_on_the_geo_origin(tmp_path, capsys):
    """The trihedral's apex is the local origin: its brightest pixel lies on geo_origin within a pixel."""
    out = tmp_path / "r"
    assert main(["render", "trihedral", "--pulses", "32", "--geotiff", "--out", str(out), "--no-progress",
                 "--set", "geo_origin=-33.9, 151.2, 40", "--set", "heading=30"]) == 0
    assert "Traceback" not in capsys.readouterr().err
    with rasterio.open(out / "image.tif") as src:
        band = src.read(2)
        row, col = np.unravel_index(np.argmax(band), band.shape)
        x, y = rasterio.transform.xy(src.transform, [row], [col], offset="center")
        lon, lat = Transformer.from_crs(src.crs, "EPSG:4326", always_xy=True).transform(x[0], y[0])
        pixel = max(np.hypot(src.transform.a, src.transform.d), np.hypot(src.transform.b, src.transform.e))
    north = (lat + 33.9) * 110_900.0
    east = (lon - 151.2) * 111_320.0 * np.cos(np.radians(33.9))
    assert np.hypot(north, east) <= pixel


def unique_image(heading_deg, left_looking=False):
    """:func:`synthetic` with |s|^2 = 1 + i n_range + j at pixel (i, j), so a raster value names its pixel;
    ``left_looking`` mirrors the range axis (a left-handed azimuth-range frame)."""
    image = synthetic(heading_deg)
    n_az, n_rg = image.data.shape
    data = np.sqrt(1.0 + np.arange(n_az * n_rg, dtype=np.float64)).reshape(n_az, n_rg).astype(np.complex64)
    r = -image.range_direction if left_looking else image.range_direction
    return dataclasses.replace(image, data=data, range_direction=r)


@pytest.mark.parametrize("heading, left", [(0, False), (30, False), (100, False), (170, False), (200, False),
                                           (260, False), (315, False), (30, True), (200, True),
                                           (80, True), (280, True)])         # all eight layouts
def test_every_pixel_lies_where_the_image_puts_it(tmp_path, heading, left):
    """Each raster pixel's centre, read back through rasterio and pyproj, lies on the geodetic
    position of the image pixel whose value it holds (within a tenth of a pixel), and shows
    north up without a mirror. Catches a layout (transpose / reversal) that disagrees with the
    geotransform, at headings that need each of the layouts."""
    image = unique_image(heading, left)
    path = write_geotiff(image, tmp_path / "image.tif", MUNICH)
    with rasterio.open(path) as src:
        lin, db, t = src.read(2).astype(np.float64), src.read(1).astype(np.float64), src.transform
        rows, cols = np.indices(lin.shape)
        xs, ys = rasterio.transform.xy(t, rows.ravel(), cols.ravel(), offset="center")
        lon, lat = Transformer.from_crs(src.crs, "EPSG:4326", always_xy=True).transform(xs, ys)
    k = np.rint(lin.ravel() - 1.0).astype(int)
    assert np.array_equal(np.sort(k), np.arange(image.data.size))      # every pixel once, |s|^2 exact
    np.testing.assert_allclose(db, 10.0 * np.log10(lin), atol=1e-4)
    i, j = np.divmod(k, image.data.shape[1])
    want = georef.enu_to_geodetic(image.positions()[i, j], MUNICH)
    north = (np.asarray(lat) - want[:, 0]) * 111_200.0
    east = (np.asarray(lon) - want[:, 1]) * 111_320.0 * np.cos(np.radians(MUNICH.latitude_deg))
    assert np.max(np.hypot(north, east)) < 0.1 * 0.5
    assert t.a * t.e - t.b * t.d < 0                                   # columns then rows turn clockwise on the map


@pytest.fixture(scope="module")
def trihedral():
    """A 32-pulse trihedral render at 48.1 N 11.6 E, track heading 30 deg."""
    return pipeline.simulate("trihedral", sensor_overrides={"n_pulses": 32, "geo_origin": "48.1, 11.6, 520",
                                                            "heading": 30}).image


def test_simulated_image_corners_and_trihedral_on_the_map(tmp_path, trihedral):
    """Acceptance on a render: the corner pixel centres lie on the image's corner pixels (within a
    pixel), and the brightest pixel (the trihedral, at the local origin) on geo_origin."""
    path = write_geotiff(trihedral, tmp_path / "image.tif")           # ref from metadata["radar"]
    got, src = corner_centres_lonlat(path)
    pos = trihedral.positions()
    want = georef.enu_to_geodetic(np.array([pos[0, 0], pos[0, -1], pos[-1, 0], pos[-1, -1]]), MUNICH)[:, [1, 0]]
    d = np.linalg.norm((got[:, None, :] - want[None, :, :]) * [np.cos(np.radians(48.1)) * 111_320.0, 111_200.0], axis=2)
    pixel = float(np.diff(trihedral.range[:2])[0])
    assert np.all(d.min(axis=1) < pixel), d.min(axis=1)
    assert src.crs.to_epsg() == 32632
    with rasterio.open(path) as src:
        band = src.read(2)
        row, col = np.unravel_index(np.argmax(band), band.shape)
        x, y = rasterio.transform.xy(src.transform, [row], [col], offset="center")
        lon, lat = Transformer.from_crs(src.crs, "EPSG:4326", always_xy=True).transform(x[0], y[0])
    assert np.hypot((lat - 48.1) * 111_200.0, (lon - 11.6) * 111_320.0 * np.cos(np.radians(48.1))) < pixel


def test_tags_name_the_scene_and_the_conventions(tmp_path, trihedral):
    """Scene, polarization, carrier, origin and units travel as tags; pixel-is-area; NaN nodata; deflate."""
    path = write_geotiff(trihedral, tmp_path / "image.tif")
    with rasterio.open(path) as src:
        tags = src.tags()
        assert tags["SCENE"] == "trihedral" and tags["POLARIZATION"] == "VV"
        assert float(tags["FREQUENCY_HZ"]) == 9.6e9
        assert json.loads(tags["GEO_ORIGIN"]) == [48.1, 11.6, 520.0]
        assert tags["AREA_OR_POINT"] == "Area" and tags["UNITS"] == "sqrt(m^2)"
        assert src.tags(1)["UNITS"].startswith("dB") and src.tags(2)["UNITS"] == "sqrt(m^2) squared"
        assert np.isnan(src.nodata) and src.dtypes == ("float32", "float32")
        assert src.compression.value.lower() == "deflate"


def test_large_images_are_tiled(tmp_path):
    image = synthetic(30.0, n_az=300, n_rg=260)
    with rasterio.open(write_geotiff(image, tmp_path / "image.tif", MUNICH)) as src:
        assert src.profile["tiled"] and src.block_shapes[0] == (256, 256)


def test_without_radar_metadata_the_image_sits_at_null_island(tmp_path):
    """No metadata["radar"]: georef.DEFAULT, 0 N 0 E, UTM zone 31 north, with a warning naming geo_origin."""
    with pytest.warns(UserWarning, match="geo_origin is not set"):
        path = write_geotiff(synthetic(0.0), tmp_path / "image.tif")
    got, src = corner_centres_lonlat(path)
    assert src.crs.to_epsg() == 32631
    assert np.all(np.abs(got) < 1e-3)                                 # within ~100 m of (0, 0)


def test_an_unwritable_path_leaves_nothing(tmp_path):
    with pytest.raises(OSError):
        write_geotiff(synthetic(0.0), tmp_path / "missing" / "image.tif", MUNICH)
    assert not (tmp_path / "missing").exists()


def test_focus_geotiff_of_a_slant_plane_image_exits_2(tmp_path, capsys):
    """focus --algorithm omegak --geotiff: one message naming the plane and the fix, exit 2, no output."""
    raw = pipeline.simulate("trihedral", sensor_overrides={"n_pulses": 32}).raw.save(tmp_path / "raw.npz")
    out = tmp_path / "f"
    assert main(["focus", str(raw), "--algorithm", "omegak", "--geotiff", "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "'slant'" in err and "--algorithm bp" in err
    assert not out.exists()

