"""SICD export and import through sarkit (issue 17, item 2): checker, geometry, round trip, analyze.

Since issue 29 the SICD holds the image resampled onto its own grid (about twice the impulse
response's bandwidth in both directions, docs/design.md): the tests compare with the image read
back (:func:`read_sicd`) where they compared with the focused image's own pixels.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

sksicd = pytest.importorskip("sarkit.sicd")

from sarmitsuba.core import georef
from sarmitsuba import pipeline  # noqa: E402
from sarmitsuba.cli import main  # noqa: E402
from sarmitsuba.formats.sicd import SicdError, check_sicd, read_sicd, write_sicd  # noqa: E402
from test_georef import ecef_closed_form  # noqa: E402

LAT, LON, H = 48.1, 11.6, 520.0
HEADING = 30.0
#: 1 m pixels of the focused image; the SICD grid samples the 1.41 m (ground range) and 1.78 m
#: (azimuth: 32 pulses, 12.4 m of track at 1414 m) unweighted resolution cells about twice.
SPACING = 1.0


def enu_closed_form(lat_deg, lon_deg):
    """East, north, up unit vectors in ECEF (docs/physics.md (GEO1), by hand)."""
    phi, lam = math.radians(lat_deg), math.radians(lon_deg)
    return (np.array([-math.sin(lam), math.cos(lam), 0.0]),
            np.array([-math.sin(phi) * math.cos(lam), -math.sin(phi) * math.sin(lam), math.cos(phi)]),
            np.array([math.cos(phi) * math.cos(lam), math.cos(phi) * math.sin(lam), math.sin(phi)]))


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """(Simulation of the trihedral flying 30 deg north of east on 1 m pixels, path of its image.nitf on
    the image's own ground plane, ``plane="image"``; the default slant-plane grid: test_sicd_slant.py)."""
    sim = pipeline.simulate("trihedral", sensor_overrides={"n_pulses": 32, "geo_origin": f"{LAT}, {LON}, {H}",
                                                           "heading": HEADING},
                            image_size=(40, 40), image_spacing=SPACING)
    path = tmp_path_factory.mktemp("sicd") / "image.nitf"
    write_sicd(sim.image, path, raw=sim.raw, plane="image")
    return sim, path


def xml_of(path):
    with open(path, "rb") as f, sksicd.NitfReader(f) as reader:
        return sksicd.XmlHelper(reader.metadata.xmltree), reader.read_image()


def test_sicdcheck_finds_nothing(written):
    """Schema, NITF headers and every consistency check (advisory ones included) pass."""
    assert check_sicd(written[1]) == []


def test_declared_resolution_is_the_measured_one(written):
    """Row/Col ImpRespWid against the -3 dB widths the point-target analysis measures on the SICD's
    pixels (uniform by default: 0.886 / ImpRespBW): catches a bandwidth taken from the beam when 32
    pulses of track bound the aperture (4x too narrow a width), a missing ground projection, the
    window's width declared for pixels whose weighting was taken out, or the weighting left in."""
    from sarmitsuba.analysis.point_target import analyze_point_target
    sim, path = written
    xml, _ = xml_of(path)
    assert xml.load("{*}Grid/{*}Row/{*}WgtType/{*}WindowName") == "UNIFORM"
    report = analyze_point_target(read_sicd(path), (0.0, 0.0, 0.0), chip=16).to_dict()
    assert xml.load("{*}Grid/{*}Row/{*}ImpRespWid") == pytest.approx(report["irw_range"], rel=0.03)
    assert xml.load("{*}Grid/{*}Col/{*}ImpRespWid") == pytest.approx(report["irw_azimuth"], rel=0.04)


def test_without_raw_data_the_radar_parameters_give_the_track(written, tmp_path):
    """ARPPoly of a file written from the image alone passes through the traced antenna positions."""
    sim, _ = written
    path = write_sicd(sim.image, tmp_path / "image.nitf", plane="image")
    assert check_sicd(path) == []
    xml, _ = xml_of(path)
    times = sim.raw.pulse_time - sim.raw.pulse_time[0]
    arp = np.polynomial.polynomial.polyval(times, xml.load("{*}Position/{*}ARPPoly")).T     # [order+1, 3] poly
    np.testing.assert_allclose(arp, georef.enu_to_ecef(sim.raw.tx_position, georef.GeoReference(LAT, LON, H)),
                               atol=1e-3)


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
    """The SCP is the focused image's centre pixel, the SICD grid's middle pixel."""
    sim, path = written
    xml, array = xml_of(path)
    image = read_sicd(path)
    assert array.shape == image.data.T.shape
    row, col = xml.load("{*}ImageData/{*}SCPPixel")
    assert (row, col) == (array.shape[0] // 2, array.shape[1] // 2)
    local = image.positions()[col, row]
    n_az, n_rg = sim.image.data.shape
    np.testing.assert_allclose(local, sim.image.positions()[n_az // 2, n_rg // 2], atol=1e-6)
    east, north, up = enu_closed_form(LAT, LON)
    want = ecef_closed_form(LAT, LON, H) + local[0] * east + local[1] * north + local[2] * up
    np.testing.assert_allclose(xml.load("{*}GeoData/{*}SCP/{*}ECF"), want, atol=1e-3)
    assert array[row, col] == image.data[col, row]
    import sarkit.wgs84
    lat, lon, hae = xml.load("{*}GeoData/{*}SCP/{*}LLH")          # vs sarkit's own ECEF -> geodetic
    want_llh = sarkit.wgs84.cartesian_to_geodetic(want)
    assert abs(lat - want_llh[0]) < 1e-8 and abs(lon - want_llh[1]) < 1e-8 and abs(hae - want_llh[2]) < 1e-3


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


def test_round_trip_gives_the_image_back(written, tmp_path):
    """read_sicd gives the image on the SICD grid, inside the focused one, the trihedral where it
    was with its peak and phase; writing that image again changes no pixel (its grid is the SICD grid)."""
    from sarmitsuba.analysis.point_target import analyze_point_target
    sim, path = written
    back = read_sicd(path)
    assert back.plane == "ground" and back.metadata["radar"]["heading"] == HEADING
    assert sim.image.range[0] <= back.range[0] and back.range[-1] <= sim.image.range[-1]
    assert sim.image.azimuth[0] <= back.azimuth[0] and back.azimuth[-1] <= sim.image.azimuth[-1]
    before, after = (analyze_point_target(im, (0.0, 0.0, 0.0), chip=16) for im in (sim.image, back))
    # unit peak gain, the weighting taken out (docs/physics.md (K3)): within the 0.3 % by which the
    # weighting seen from the trihedral differs from the one at the SCP that was divided out
    assert after.peak_magnitude == pytest.approx(before.peak_magnitude, rel=5e-3)
    assert abs(after.peak_phase_deg - before.peak_phase_deg) < 0.5
    assert abs(after.azimuth - before.azimuth) < 0.01 and abs(after.range - before.range) < 0.01
    again = read_sicd(write_sicd(back, tmp_path / "again.nitf", raw=sim.raw, plane="image"))
    np.testing.assert_array_equal(again.data, back.data)
    np.testing.assert_allclose(again.positions(), back.positions(), atol=1e-6)


def test_range_bandwidth_is_the_ground_projection_of_the_band(written):
    """Row ImpRespBW = 2 B sin(theta) / c with theta the incidence at the scene centre (45 deg here)."""
    sim, path = written
    xml, _ = xml_of(path)
    bw = xml.load("{*}Grid/{*}Row/{*}ImpRespBW")
    assert bw == pytest.approx(2 * sim.raw.bandwidth * math.sin(math.radians(45.0)) / 299_792_458.0, rel=0.01)


def test_render_and_focus_write_sicd_and_analyze_reads_it(tmp_path, capsys):
    """`render --sicd`, `focus --sicd`, `analyze` of the (uniform) file against the npz: the peak, the
    RCS its peak power, uniform widths and sidelobes. 32 pulses: the track, not the beam, bounds
    the aperture. Catches the file's metadata giving the beam's sines for that aperture (analyze
    models a 5 times wider band: the RCS 2.8 dB high) and the weighting left in (Taylor sidelobes)."""
    out = tmp_path / "r"
    assert main(["render", "trihedral", "--pulses", "32", "--sicd", "--out", str(out), "--no-progress"]) == 0
    assert (out / "image.nitf").is_file()
    assert main(["focus", str(out / "raw.npz"), "--algorithm", "bp", "--sicd", "--out", str(tmp_path / "f"),
                 "--no-progress"]) == 0
    assert (tmp_path / "f" / "image.nitf").is_file()
    assert check_sicd(out / "image.nitf") == []                     # advisory checks included
    capsys.readouterr()
    reports = []
    # 32 pulses: the SICD grid's columns leave too few of them for the default 64-pixel chip
    for name, chip in (("image.npz", "64"), ("image.nitf", "16")):
        assert main(["analyze", str(out / name), "--target", "0,0,0", "--raw", str(out / "raw.npz"),
                     "--chip", chip]) == 0
        reports.append(json.loads(capsys.readouterr().out))
    # unit peak gain on both; the SICD's weighting is taken out (uniform, docs/physics.md (K3)):
    # its RCS is the peak power, its widths 0.886 / ImpRespBW, its sidelobes the sinc's -13.26 dB
    assert reports[1]["peak_magnitude"] == pytest.approx(reports[0]["peak_magnitude"], rel=0.01)
    assert reports[1]["rcs"] == pytest.approx(reports[1]["peak_magnitude"] ** 2, rel=0.05)
    xml, _ = xml_of(out / "image.nitf")
    # (azimuth within 4 %: ImpRespBW spans the 31 intervals from the first to the last of the 32
    # pulses, the samples' own support 32 of them)
    for key, direction in (("irw_range", "Row"), ("irw_azimuth", "Col")):
        assert reports[1][key] == pytest.approx(0.8859 / xml.load(f"{{*}}Grid/{{*}}{direction}/{{*}}ImpRespBW"),
                                                rel=0.04), key
    for key in ("pslr_range_db", "pslr_azimuth_db"):
        assert reports[1][key] == pytest.approx(-13.26, abs=0.5), key


def test_a_file_that_is_no_sicd_is_named(tmp_path, capsys):
    bad = tmp_path / "image.nitf"
    bad.write_bytes(b"NITF02.10 but not really")
    with pytest.raises(SicdError, match="image.nitf"):
        read_sicd(bad)
    assert main(["analyze", str(bad), "--target", "0,0,0"]) == 2
    err = capsys.readouterr().err
    assert "image.nitf" in err and "Traceback" not in err


def test_a_foreign_plane_sicd_reads_from_the_standard_fields_alone(written):
    """Without sarmitsuba's Parameters the image comes back in the ENU frame of its SCP: every
    pixel at the same place on Earth (ECEF within 1 mm), the same samples (the SICD grid makes
    KCtr SS whole, so the pixels carry the image's own phase: no carrier to restore)."""
    from sarmitsuba.formats.sicd import image_from_parts
    _, path = written
    ours = read_sicd(path)
    with open(path, "rb") as f, sksicd.NitfReader(f) as reader:
        tree, array = reader.metadata.xmltree, reader.read_image()
    for param in tree.findall("{*}CollectionInfo/{*}Parameter"):
        param.getparent().remove(param)
    back = image_from_parts("foreign.nitf", tree, array)
    scp_llh = sksicd.XmlHelper(tree).load("{*}GeoData/{*}SCP/{*}LLH")
    theirs = georef.enu_to_ecef(back.positions(), georef.GeoReference(*map(float, scp_llh)))
    np.testing.assert_allclose(theirs, georef.enu_to_ecef(ours.positions(), georef.GeoReference(LAT, LON, H)),
                               atol=1e-3)
    np.testing.assert_array_equal(back.data, ours.data)


def test_a_grid_other_than_plane_is_refused_by_name(written):
    from sarmitsuba.formats.sicd import image_from_parts
    with open(written[1], "rb") as f, sksicd.NitfReader(f) as reader:
        tree, array = reader.metadata.xmltree, reader.read_image()
    tree.find("{*}Grid/{*}Type").text = "RGZERO"
    with pytest.raises(SicdError, match=r"foreign\.nitf.*PLANE.*RGZERO"):
        image_from_parts("foreign.nitf", tree, array)


def test_a_slant_image_has_its_corners_on_the_ground(tmp_path):
    """An RDA slant-plane image (heading 0: track along east at y = 1000 m, z = 1000 m, looking
    right): ImagePlane SLANT, Row along the slant range (down), no required check failing, and
    each ImageCorner where that corner pixel's zero-Doppler range circle meets the surface at the
    SCP's height (flat-earth closed form, within 1 cm). Catches the corner's own lat/lon written
    for a slant pixel that sits tens of metres above or below that surface."""
    import sarkit.wgs84
    sim = pipeline.simulate("trihedral", sensor_overrides={"n_pulses": 32, "geo_origin": f"{LAT}, {LON}, {H}"})
    image = pipeline.refocus(sim.raw, "rda")
    assert image.plane == "slant"
    path = write_sicd(image, tmp_path / "slant.nitf", raw=sim.raw)
    assert check_sicd(path) == []
    xml, _ = xml_of(path)
    assert xml.load("{*}Grid/{*}ImagePlane") == "SLANT" and xml.load("{*}SCPCOA/{*}SideOfTrack") == "R"
    east, north, up = enu_closed_form(LAT, LON)
    np.testing.assert_allclose(xml.load("{*}Grid/{*}Row/{*}UVectECF") @ np.array([east, north, up]).T,
                               image.range_direction, atol=1e-9)
    track_y, track_z = sim.raw.tx_position[:, 1].mean(), sim.raw.tx_position[:, 2].mean()
    sicd_image = read_sicd(path)                               # on the SICD grid
    pixels = sicd_image.positions()                            # [n_azimuth, n_range, 3]
    n_az, n_rg = sicd_image.data.shape
    ref = georef.GeoReference(LAT, LON, H)
    height = xml.load("{*}GeoData/{*}SCP/{*}LLH")[2] - H        # of the SCP above the geo origin
    for (lat, lon), (row, col) in zip(xml.load("{*}GeoData/{*}ImageCorners"),
                                      [(0, 0), (0, n_az - 1), (n_rg - 1, n_az - 1), (n_rg - 1, 0)]):
        p = pixels[col, row]
        slant = math.hypot(p[1] - track_y, p[2] - track_z)
        ground = np.array([p[0], track_y - math.sqrt(slant ** 2 - (track_z - height) ** 2), height])
        got = georef.ecef_to_enu(sarkit.wgs84.geodetic_to_cartesian([lat, lon, H + height]), ref)
        assert np.hypot(*(got - ground)[:2]) < 0.01, (row, col, got, ground)
