"""SICD export and import through sarkit (issue 17, item 2): checker, geometry, round trip, analyze."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

sksicd = pytest.importorskip("sarkit.sicd")

from sarmitsuba import georef, pipeline  # noqa: E402
from sarmitsuba.cli import main  # noqa: E402
from sarmitsuba.sicd import SicdError, check_sicd, read_sicd, write_sicd  # noqa: E402
from test_cphd import reports_close  # noqa: E402
from test_georef import ecef_closed_form  # noqa: E402

LAT, LON, H = 48.1, 11.6, 520.0
HEADING = 30.0
#: Only advisory findings are expected: sarmitsuba's square ground pixels sample range 4.3 times
#: and azimuth 1.0 times their bandwidth (SICD advises 1.1 to 2.2).
ADVISORY = {"check_iprbw_to_ss_osr_row", "check_iprbw_to_ss_osr_col"}


def enu_closed_form(lat_deg, lon_deg):
    """East, north, up unit vectors in ECEF (docs/physics.md (G1), by hand)."""
    phi, lam = math.radians(lat_deg), math.radians(lon_deg)
    return (np.array([-math.sin(lam), math.cos(lam), 0.0]),
            np.array([-math.sin(phi) * math.cos(lam), -math.sin(phi) * math.sin(lam), math.cos(phi)]),
            np.array([math.cos(phi) * math.cos(lam), math.cos(phi) * math.sin(lam), math.sin(phi)]))


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """(Simulation of the trihedral flying 30 deg north of east, path of its image.nitf)."""
    sim = pipeline.simulate("trihedral", sensor_overrides={"n_pulses": 32, "geo_origin": f"{LAT}, {LON}, {H}",
                                                           "heading": HEADING})
    path = tmp_path_factory.mktemp("sicd") / "image.nitf"
    write_sicd(sim.image, path, raw=sim.raw)
    return sim, path


def xml_of(path):
    with open(path, "rb") as f, sksicd.NitfReader(f) as reader:
        return sksicd.XmlHelper(reader.metadata.xmltree), reader.read_image()


def test_sicdcheck_finds_no_errors(written):
    failed = check_sicd(written[1])
    assert "Error" not in failed.values(), failed
    assert set(failed) <= ADVISORY


def test_grid_vectors_point_along_track_and_to_its_right(written):
    """Col = azimuth = heading 30 deg from east; Row = range = right of the track; both horizontal."""
    xml, _ = xml_of(written[1])
    east, north, up = enu_closed_form(LAT, LON)
    h = math.radians(HEADING)
    col, row = xml.load("{*}Grid/{*}Col/{*}UVectECF"), xml.load("{*}Grid/{*}Row/{*}UVectECF")
    np.testing.assert_allclose(col, math.cos(h) * east + math.sin(h) * north, atol=1e-9)
    np.testing.assert_allclose(row, math.sin(h) * east - math.cos(h) * north, atol=1e-9)
    assert abs(row @ up) < 1e-9 and abs(col @ up) < 1e-9 and abs(row @ col) < 1e-12
    assert xml.load("{*}Grid/{*}Type") == "PLANE" and xml.load("{*}Grid/{*}ImagePlane") == "GROUND"


def test_scp_is_the_centre_pixel_on_the_ellipsoid(written):
    sim, path = written
    xml, array = xml_of(path)
    image = sim.image
    assert array.shape == image.data.T.shape
    row, col = xml.load("{*}ImageData/{*}SCPPixel")
    local = image.positions()[col, row]
    east, north, up = enu_closed_form(LAT, LON)
    want = ecef_closed_form(LAT, LON, H) + local[0] * east + local[1] * north + local[2] * up
    np.testing.assert_allclose(xml.load("{*}GeoData/{*}SCP/{*}ECF"), want, atol=1e-3)
    assert array[row, col] == image.data[col, row]


def test_the_trihedral_sits_on_the_geo_origin_by_the_sicd_fields_alone(written):
    """Brightest pixel -> SCP + offsets along Row/Col (standard fields only) -> lat, lon of the origin."""
    import sarkit.wgs84
    xml, array = xml_of(written[1])
    row, col = np.unravel_index(np.argmax(np.abs(array)), array.shape)
    scp_row, scp_col = xml.load("{*}ImageData/{*}SCPPixel")
    ss_row, ss_col = xml.load("{*}Grid/{*}Row/{*}SS"), xml.load("{*}Grid/{*}Col/{*}SS")
    point = (xml.load("{*}GeoData/{*}SCP/{*}ECF") + (row - scp_row) * ss_row * xml.load("{*}Grid/{*}Row/{*}UVectECF")
             + (col - scp_col) * ss_col * xml.load("{*}Grid/{*}Col/{*}UVectECF"))
    lat, lon, _ = sarkit.wgs84.cartesian_to_geodetic(point)
    metres = np.hypot((lat - LAT) * 111_200.0, (lon - LON) * 111_320.0 * math.cos(math.radians(LAT)))
    assert metres <= max(ss_row, ss_col)


def test_round_trip_gives_the_image_back(written):
    sim, path = written
    back = read_sicd(path)
    np.testing.assert_array_equal(back.data, sim.image.data)
    np.testing.assert_allclose(back.positions(), sim.image.positions(), atol=1e-6)
    assert back.plane == "ground" and back.metadata["radar"]["heading"] == HEADING


def test_range_bandwidth_is_the_ground_projection_of_the_band(written):
    """Row ImpRespBW = 2 B sin(theta) / c with theta the incidence at the scene centre (45 deg here)."""
    sim, path = written
    xml, _ = xml_of(path)
    bw = xml.load("{*}Grid/{*}Row/{*}ImpRespBW")
    assert bw == pytest.approx(2 * sim.raw.bandwidth * math.sin(math.radians(45.0)) / 299_792_458.0, rel=0.01)


def test_render_and_focus_write_sicd_and_analyze_reads_it(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["render", "trihedral", "--pulses", "32", "--sicd", "--out", str(out), "--no-progress"]) == 0
    assert (out / "image.nitf").is_file()
    assert main(["focus", str(out / "raw.npz"), "--algorithm", "bp", "--sicd", "--out", str(tmp_path / "f"),
                 "--no-progress"]) == 0
    assert (tmp_path / "f" / "image.nitf").is_file()
    capsys.readouterr()
    reports = []
    for name in ("image.npz", "image.nitf"):
        assert main(["analyze", str(out / name), "--target", "0,0,0", "--raw", str(out / "raw.npz")]) == 0
        reports.append(json.loads(capsys.readouterr().out))
    assert reports_close(reports[0], reports[1])


def test_a_file_that_is_no_sicd_is_named(tmp_path, capsys):
    bad = tmp_path / "image.nitf"
    bad.write_bytes(b"NITF02.10 but not really")
    with pytest.raises(SicdError, match="image.nitf"):
        read_sicd(bad)
    assert main(["analyze", str(bad), "--target", "0,0,0"]) == 2
    err = capsys.readouterr().err
    assert "image.nitf" in err and "Traceback" not in err
