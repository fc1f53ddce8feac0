"""Geographic reference (issue 17, item 1): ENU <-> ECEF <-> geodetic <-> UTM against closed forms."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sarmitsuba.core import georef
from sarmitsuba.cli import main
from sarmitsuba.core.radar import ParameterError, RadarParameters

A, F = 6378137.0, 1.0 / 298.257223563          # WGS84 (NIMA TR8350.2)
E2 = F * (2.0 - F)


def ecef_closed_form(lat_deg, lon_deg, h):
    """Geodetic to ECEF by the textbook formula (Hofmann-Wellenhof et al., GNSS, eq. 5.7)."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    n = A / math.sqrt(1.0 - E2 * math.sin(lat) ** 2)
    return np.array([(n + h) * math.cos(lat) * math.cos(lon), (n + h) * math.cos(lat) * math.sin(lon),
                     (n * (1.0 - E2) + h) * math.sin(lat)])


@pytest.mark.parametrize("lat, lon, h", [(30.0, -60.0, 10.0), (60.0, 100.0, 520.0), (-33.9, 151.2, 40.0)])
def test_origin_and_axes_against_the_closed_form(lat, lon, h):
    """The origin lands on the closed-form ECEF point; x east, y north, z along the ellipsoid normal."""
    ref = georef.GeoReference(lat, lon, h)
    points = georef.enu_to_ecef(np.array([[0.0, 0, 0], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]), ref)
    np.testing.assert_allclose(points[0], ecef_closed_form(lat, lon, h), atol=1e-6)
    phi, lam = math.radians(lat), math.radians(lon)
    east = [-math.sin(lam), math.cos(lam), 0.0]
    north = [-math.sin(phi) * math.cos(lam), -math.sin(phi) * math.sin(lam), math.cos(phi)]
    up = [math.cos(phi) * math.cos(lam), math.cos(phi) * math.sin(lam), math.sin(phi)]
    np.testing.assert_allclose(points[1:] - points[0], [east, north, up], atol=1e-8)


def test_a_point_100_m_up_is_100_m_higher_and_north_is_a_meridian_arc():
    """1 km north at 45 deg moves latitude by 1000 / M(45) (meridian radius of curvature)."""
    ref = georef.GeoReference(45.0, 7.0, 0.0)
    llh = georef.enu_to_geodetic(np.array([[0.0, 0.0, 100.0], [0.0, 1000.0, 0.0]]), ref)
    np.testing.assert_allclose(llh[0], [45.0, 7.0, 100.0], atol=1e-9)
    m = A * (1 - E2) / (1 - E2 * math.sin(math.radians(45.0)) ** 2) ** 1.5
    assert llh[1, 0] - 45.0 == pytest.approx(math.degrees(1000.0 / m), rel=1e-4)
    assert llh[1, 1] == pytest.approx(7.0, abs=1e-12)


def test_round_trip_and_rigidity_far_from_the_origin():
    """ENU -> ECEF -> ENU at 800 km keeps every coordinate to 0.1 mm, and distances exactly."""
    ref = georef.GeoReference(48.1, 11.6, 520.0)
    rng = np.random.default_rng(3)
    pts = rng.uniform(-8e5, 8e5, (50, 3))
    back = georef.ecef_to_enu(georef.enu_to_ecef(pts, ref), ref)
    np.testing.assert_allclose(back, pts, atol=1e-4)
    ecef = georef.enu_to_ecef(pts, ref)
    np.testing.assert_allclose(np.linalg.norm(ecef[1:] - ecef[0], axis=1), np.linalg.norm(pts[1:] - pts[0], axis=1),
                               rtol=1e-12)


@pytest.mark.parametrize("lat, lon, epsg, northing0", [(0.0, 3.0, 32631, 0.0), (-1e-9, 9.0, 32732, 1e7)])
def test_utm_on_a_central_meridian_at_the_equator(lat, lon, epsg, northing0):
    """On a zone's central meridian at the equator: easting 500 km, northing 0 (north) or 10,000 km (south)."""
    ref = georef.GeoReference(lat, lon, 0.0)
    assert georef.utm_crs(ref).to_epsg() == epsg
    east, north = georef.enu_to_utm(np.zeros(3), ref)
    assert east == pytest.approx(500000.0, abs=1e-3)
    assert north == pytest.approx(northing0, abs=1e-3)


def test_utm_scale_on_the_central_meridian_is_0_9996():
    """1 km north on a central meridian is 999.6 m of UTM northing (k0 = 0.9996)."""
    ref = georef.GeoReference(45.0, 9.0, 0.0)
    utm = georef.enu_to_utm(np.array([[0.0, 0.0, 0.0], [0.0, 1000.0, 0.0]]), ref)
    assert utm[1, 1] - utm[0, 1] == pytest.approx(999.6, abs=0.01)
    assert utm[1, 0] - utm[0, 0] == pytest.approx(0.0, abs=1e-6)


def test_parameter_parsing_and_errors():
    assert RadarParameters.from_mapping({"geo_origin": "48.1, 11.6, 520"}).geo_origin == (48.1, 11.6, 520.0)
    assert georef.of(RadarParameters()) == georef.DEFAULT
    assert georef.of({"geo_origin": [10.0, 20.0]}) == georef.GeoReference(10.0, 20.0, 0.0)
    for bad, word in (("95, 10, 0", "latitude"), ("10, 200", "longitude"), ("10", "latitude, longitude"),
                      ("a, b, c", "latitude, longitude")):
        with pytest.raises(ParameterError, match=word):
            RadarParameters.from_mapping({"geo_origin": bad})


def test_info_prints_the_origin_and_a_bad_one_exits_2(capsys):
    assert main(["info", "trihedral", "--set", "geo_origin=-33.9, 151.2, 40"]) == 0
    out = capsys.readouterr().out
    assert "33.90000 S, 151.20000 E, 40.0 m" in out and "EPSG:32756" in out and "placeholder" not in out
    assert main(["info", "trihedral"]) == 0
    assert "placeholder" in capsys.readouterr().out
    assert main(["info", "trihedral", "--set", "geo_origin=48, 190, 0"]) == 2
    err = capsys.readouterr().err
    assert "geo_origin" in err and "longitude" in err and "Traceback" not in err
