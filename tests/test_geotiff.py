"""GeoTIFF of the ground-plane image (issue 17, item 3; issue 29): corners on the map, bands, errors;
north-up by default (resampled), the rotated grid on request, band units, COG layout for large images."""
from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio")

from pyproj import Transformer  # noqa: E402

from sarmitsuba.core import georef
from sarmitsuba import pipeline  # noqa: E402
from sarmitsuba.cli import main  # noqa: E402
from sarmitsuba.formats.geotiff import GeoTiffError, band_units, write_geotiff  # noqa: E402
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
    """Rotated grid: the four corner pixel centres land on the geodetic positions of the image's corner pixels."""
    image = synthetic(heading)
    path = write_geotiff(image, tmp_path / "image.tif", ref, north_up=False)
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
    """Rotated grid: band 2 holds |s|^2 of every pixel, band 1 its dB, NaN where s = 0 (compared as
    value sets: the corner test checks where they are)."""
    image = synthetic(30.0)
    image = dataclasses.replace(image, data=image.data.copy())
    image.data[3, 4] = 0
    path = write_geotiff(image, tmp_path / "image.tif", georef.GeoReference(10.0, 20.0, 0.0), north_up=False)
    with rasterio.open(path) as src:
        db, lin = src.read(1), src.read(2)
        assert src.descriptions == ("intensity_db", "intensity")
    want = np.abs(image.data.astype(np.complex128)) ** 2
    np.testing.assert_allclose(np.sort(lin.ravel()), np.sort(want.ravel()), rtol=1e-6)
    np.testing.assert_allclose(db[lin > 0], 10 * np.log10(lin[lin > 0].astype(np.float64)), atol=1e-4)
    assert np.isnan(db).sum() == 1 and np.isnan(db[lin == 0]).all()


def test_a_track_flying_east_gives_a_north_up_raster(tmp_path):
    """Rotated grid, heading 0 (east), looking right (south): columns run east, rows south, turned only by the
    UTM grid convergence, gamma = dlambda sin(phi) to first order (Snyder 1987, eq. 8-14 ff.)."""
    image = synthetic(0.0)
    path = write_geotiff(image, tmp_path / "image.tif", georef.GeoReference(48.1, 9.5, 0.0), north_up=False)
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
        row, col = np.unravel_index(np.nanargmax(band), band.shape)
        x, y = rasterio.transform.xy(src.transform, [row], [col], offset="center")
        lon, lat = Transformer.from_crs(src.crs, "EPSG:4326", always_xy=True).transform(x[0], y[0])
        pixel = max(np.hypot(src.transform.a, src.transform.d), np.hypot(src.transform.b, src.transform.e))
        assert src.transform.b == src.transform.d == 0 and src.transform.e < 0      # north-up by default
    north = (lat + 33.9) * 110_900.0
    east = (lon - 151.2) * 111_320.0 * np.cos(np.radians(33.9))
    assert np.hypot(north, east) <= pixel
    assert main(["focus", str(out / "raw.npz"), "--geotiff", "--geotiff-rotated", "--out", str(tmp_path / "f"),
                 "--no-progress"]) == 0                      # the flag reaches the writer: a rotated raster
    with rasterio.open(tmp_path / "f" / "image.tif") as src:
        assert abs(src.transform.b) > 0.1 * abs(src.transform.a)            # heading 30: tan(30) of a pixel


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
    path = write_geotiff(image, tmp_path / "image.tif", MUNICH, north_up=False)
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
    """Acceptance on a render, rotated grid: the corner pixel centres lie on the image's corner pixels
    (within a pixel), and the brightest pixel (the trihedral, at the local origin) on geo_origin."""
    path = write_geotiff(trihedral, tmp_path / "image.tif", north_up=False)           # ref from metadata["radar"]
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


def test_no_dataset_units_tag_contradicts_the_bands(tmp_path, trihedral):
    """Issue 55: the dataset tag ``UNITS=sqrt(m^2)`` (the amplitudes') contradicted the bands' dBsm and
    m^2 in every reader that shows dataset metadata (gdalinfo, rio info --tags). Catches a dataset
    ``UNITS`` tag: the amplitude unit travels as ``AMPLITUDE_UNITS``, each band keeps its own."""
    path = write_geotiff(trihedral, tmp_path / "image.tif")
    with rasterio.open(path) as src:
        assert "UNITS" not in src.tags()
        assert [src.tags(band)["UNITS"] for band in (1, 2)] == list(src.units) == ["dBsm", "m^2"]
        assert src.tags()["AMPLITUDE_UNITS"] == "sqrt(m^2)"


def test_tags_name_the_scene_and_the_conventions(tmp_path, trihedral):
    """Scene, polarization, carrier, origin and units travel as tags; pixel-is-area; NaN nodata; deflate."""
    path = write_geotiff(trihedral, tmp_path / "image.tif")
    with rasterio.open(path) as src:
        tags = src.tags()
        assert tags["SCENE"] == "trihedral" and tags["POLARIZATION"] == "VV"
        assert float(tags["FREQUENCY_HZ"]) == 9.6e9
        assert json.loads(tags["GEO_ORIGIN"]) == [48.1, 11.6, 520.0]
        assert tags["AREA_OR_POINT"] == "Area" and tags["AMPLITUDE_UNITS"] == "sqrt(m^2)"
        assert src.tags(1)["UNITS"] == "dBsm" and src.tags(2)["UNITS"] == "m^2"
        assert np.isnan(src.nodata) and src.dtypes == ("float32", "float32")
        assert src.compression.value.lower() == "deflate"


def test_large_images_are_tiled(tmp_path):
    image = synthetic(30.0, n_az=300, n_rg=260)
    for north_up in (True, False):
        with rasterio.open(write_geotiff(image, tmp_path / f"image{north_up}.tif", MUNICH, north_up=north_up)) as src:
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



# ---- issue 29: north-up by default, band units, COG layout --------------------------------------------------------

@pytest.fixture(scope="module")
def renders():
    """32-pulse trihedral renders at 48.1 N 11.6 E by track heading [deg], made once each."""
    cache = {}

    def render(heading):
        if heading not in cache:
            cache[heading] = pipeline.simulate("trihedral", sensor_overrides={
                "n_pulses": 32, "geo_origin": "48.1, 11.6, 520", "heading": heading}).image
        return cache[heading]
    return render


@pytest.mark.parametrize("heading", [0.0, 30.0])
def test_north_up_by_default_with_the_trihedral_on_geo_origin(tmp_path, renders, heading):
    """The default GeoTIFF is north-up (no rotation terms, rows south), and its brightest pixel's
    centre lies within one pixel of geo_origin, both taken to the file's CRS by pyproj alone.
    At heading 0 the rotated grid is turned only by the grid convergence (1.9 deg here), at 30 deg
    by the track too."""
    path = write_geotiff(renders(heading), tmp_path / "image.tif")
    with rasterio.open(path) as src:
        t, band = src.transform, src.read(2)
        assert t.b == 0 and t.d == 0 and t.e < 0 < t.a and t.a == pytest.approx(-t.e)
        row, col = np.unravel_index(np.nanargmax(band), band.shape)
        (x,), (y,) = rasterio.transform.xy(t, [row], [col], offset="center")
        east, north = Transformer.from_crs("EPSG:4326", src.crs, always_xy=True).transform(11.6, 48.1)
        assert src.crs.to_epsg() == 32632
    assert np.hypot(x - east, y - north) <= t.a, (x - east, y - north, t.a)


def test_bands_carry_units_that_rio_info_shows(tmp_path, renders):
    """Both bands have GDAL unit types: |s|^2 of sqrt(m^2) amplitudes in m^2, its dB in dBsm;
    `rio info` (rasterio's CLI) prints them."""
    path = write_geotiff(renders(30.0), tmp_path / "image.tif")
    with rasterio.open(path) as src:
        assert src.units == ("dBsm", "m^2")
    rio = "import sys; from rasterio.rio.main import main_group; sys.exit(main_group())"
    info = subprocess.run([sys.executable, "-c", rio, "info", str(path)], capture_output=True, text=True, check=True)
    assert json.loads(info.stdout)["units"] == ["dBsm", "m^2"]


def test_band_units_of_other_amplitude_units():
    assert band_units("sqrt(m^2)") == ("dBsm", "m^2")
    assert band_units("sqrt(W) at the receiver, unit-energy matched filter") == ("dBW", "W")
    assert band_units("V") == ("dB re 1 (V)^2", "(V)^2") and band_units("sqrt(J)") == ("dB re 1 J", "J")


def test_rotated_on_request_keeps_the_image_samples(tmp_path):
    """north_up=False: the image's own samples (no resampling) on a geotransform with rotation
    terms at heading 30 deg; the default at the same heading has none and resampled values."""
    image = unique_image(30.0)
    with rasterio.open(write_geotiff(image, tmp_path / "rot.tif", MUNICH, north_up=False)) as src:
        t, lin = src.transform, src.read(2)
    assert abs(t.b) > 0.1 and abs(t.d) > 0.1
    np.testing.assert_allclose(np.sort(lin.ravel()), np.sort(np.abs(image.data.ravel()) ** 2), rtol=1e-6)
    with rasterio.open(write_geotiff(image, tmp_path / "up.tif", MUNICH)) as src:
        assert src.transform.b == src.transform.d == 0 and "north-up" in src.tags()["LAYOUT"]


def test_north_up_resampling_conserves_intensity_and_footprint(tmp_path):
    """An independent check of the resampling: at heading 30 deg, with 0.5 x 0.8 m image pixels,
    the north-up raster's linear band integrates (sum x pixel area) to the rotated raster's
    within 2 %, its valid (non-NaN) pixels cover the image's footprint within 2 %, NaN lies
    outside (its corners), and band 1 is 10 log10 of band 2 pixel by pixel (dB computed after
    resampling, not interpolated)."""
    image = synthetic(30.0, n_az=160, n_rg=120)
    with rasterio.open(write_geotiff(image, tmp_path / "rot.tif", MUNICH, north_up=False)) as src:
        t = src.transform
        total_rot = src.read(2).astype(np.float64).sum() * abs(t.a * t.e - t.b * t.d)
    with rasterio.open(write_geotiff(image, tmp_path / "up.tif", MUNICH)) as src:
        t, db, lin = src.transform, src.read(1).astype(np.float64), src.read(2).astype(np.float64)
    assert t.b == t.d == 0 and t.a == pytest.approx(0.5, rel=1e-3)
    valid = ~np.isnan(lin)
    assert np.nansum(lin) * t.a * -t.e == pytest.approx(total_rot, rel=0.02)
    assert valid.sum() * t.a * -t.e == pytest.approx(160 * 0.5 * 120 * 0.8, rel=0.02)
    assert np.isnan(lin[[0, 0, -1, -1], [0, -1, 0, -1]]).all() and np.array_equal(np.isnan(db), ~valid)
    np.testing.assert_allclose(db[valid], 10 * np.log10(lin[valid]), atol=1e-4)


def test_a_large_image_is_a_cloud_optimized_geotiff(tmp_path):
    """2048 x 2048 pixels: 256 x 256 tiles in every band, overviews 2, 4, 8 (the last 256 pixels
    on a side), COG layout; a small image stays a plain striped GeoTIFF."""
    image = synthetic(0.0, n_az=2048, n_rg=2048, spacing=(0.5, 0.5))
    with rasterio.open(write_geotiff(image, tmp_path / "big.tif", georef.GeoReference(0.0, 3.0, 0.0))) as src:
        assert src.block_shapes == [(256, 256), (256, 256)] and src.profile["tiled"]
        assert src.overviews(1) == src.overviews(2) == [2, 4, 8]
        assert src.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") == "COG"
        assert src.transform.b == src.transform.d == 0
        assert src.units == ("dBsm", "m^2") and src.descriptions == ("intensity_db", "intensity")
    with rasterio.open(write_geotiff(synthetic(0.0), tmp_path / "small.tif", MUNICH)) as src:
        assert not src.profile.get("tiled") and src.overviews(1) == []


def test_without_the_cog_driver_a_large_image_is_a_tiled_geotiff_with_overviews(tmp_path, monkeypatch):
    """GDAL without its COG driver: tiles and overviews 2, 4 (factors while the level's smaller
    side is above 256) in a plain GeoTIFF, averaged."""
    from sarmitsuba.formats import geotiff
    monkeypatch.setattr(geotiff, "cog_driver", lambda: False)
    image = synthetic(0.0, n_az=600, n_rg=600, spacing=(0.5, 0.5))
    with rasterio.open(write_geotiff(image, tmp_path / "big.tif", georef.GeoReference(0.0, 3.0, 0.0))) as src:
        assert src.block_shapes == [(256, 256), (256, 256)] and src.overviews(2) == [2, 4]
        assert src.tags(ns="rio_overview") == {"resampling": "average"} and src.units == ("dBsm", "m^2")


def test_the_geotiff_dates_the_collection_and_the_file(tmp_path):
    """ACQUISITION_START_TIME is the sensor's collection_start in UTC (given with a +02:00 offset:
    10:00 UTC written by hand), TIFFTAG_DATETIME (the TIFF DateTime tag) the moment of writing."""
    import datetime
    out = tmp_path / "r"
    before = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    assert main(["render", "trihedral", "--pulses", "32", "--geotiff", "--out", str(out), "--no-progress",
                 "--set", "geo_origin=48.1,11.6,520", "--set", "collection_start=2026-11-24T12:00:00+02:00"]) == 0
    with rasterio.open(out / "image.tif") as src:
        tags = src.tags()
    assert tags["ACQUISITION_START_TIME"] == "2026-11-24T10:00:00+00:00"
    made = datetime.datetime.strptime(tags["TIFFTAG_DATETIME"], "%Y:%m:%d %H:%M:%S").replace(
        tzinfo=datetime.timezone.utc)
    assert before <= made <= datetime.datetime.now(datetime.timezone.utc)

