"""The default SICD is a slant-plane grid; an independent reader sees straight and circular products
alike, with the trihedral away from the scene reference point (issue 55, items 3 to 5).

The trihedral sits 2.6 m along track and 1.8 m across it from the SRP / SCP (a few resolution
cells both ways), where a wrong position or sign no longer focuses by accident, at 35 deg
incidence (straight track), 55 deg (a 3 deg circular arc) and 50 deg looking left: sin and cos
of the angles differ.

- sarpy's SICD validity and consistency checks and its CPHD consistency check log no ERROR and no
  "want"; sarkit's ``sicdcheck`` and ``cphdcheck`` find nothing.
- ``Grid/Row`` is the line of sight from the antenna at the SCP's centre of aperture (from the
  raw data's positions by hand), ``Col`` the velocity across it; sarkit's scene-to-image
  projection of the trihedral's apex lands on the SICD peak within 0.1 of the impulse-response
  width.
- The trihedral's RCS: the point-target analysis of the SICD, the integral method with
  ``BetaZeroSFPoly`` (sum of pixel power times the pixel area), and sarpy's RCS tool read the
  same RCS as ``analyze`` on the focused image, within 0.2 dB, and the closed form 4 pi a^4 /
  (3 lambda^2) within 0.3 dB. sarpy's RCS tool divides the pixel power by the oversampling
  ratios only: on a SICD with the image's own weighting (``weighting="image"``) and sarpy's own
  ``BetaZeroSF = RCSSF / A`` (A with the weighting factors mean(w^2)/mean(w)^2) it reads the RCS
  times those factors, exactly; on the default uniform SICD it reads the RCS
  (tests/test_sicd_calibration.py).
- A circular CPHD whose fast-time window follows the SRP says ``TOAFixed``.
- ``DeltaKCOAPoly`` is the local spectral centre of the pixels around the off-SCP trihedral
  (the power spectrum's centroid over a 16 x 48 chip).
- A backprojection written from the CPHD standard alone (PVPs, SC0, SCSS, SGN) focuses on the
  off-SRP apex.

Expected values come from the geometry, the closed form or an independent reader (sarpy, sarkit).
"""
from __future__ import annotations

import logging
import math

import numpy as np
import pytest

sksicd = pytest.importorskip("sarkit.sicd")
pytest.importorskip("sarpy")

from sarmitsuba import Scene, simulate  # noqa: E402
from sarmitsuba.analysis.point_target import analyze_point_target  # noqa: E402
from sarmitsuba.core import georef  # noqa: E402
from sarmitsuba.core.constants import SPEED_OF_LIGHT  # noqa: E402
from sarmitsuba.formats.cphd import check_cphd, write_cphd  # noqa: E402
from sarmitsuba.formats.sicd import check_sicd, read_sicd, write_sicd  # noqa: E402

from test_circular_sar import MESH  # noqa: E402

APEX = np.array([2.6, -1.8, 0.0])          # along track, toward the sensor's side: off the SRP both ways
EDGE = 1.5
FREQUENCY = 9.6e9
CASES = {"straight": {"incidence_angle": 35.0},
         "circular": {"incidence_angle": 55.0, "trajectory": "circular", "arc_deg": 3.0},
         "left": {"incidence_angle": 50.0, "look_side": "left"}}
SARPY_GROUND_AREA = "RadiometricType: The BetaZeroSFPoly and RCSSFPoly are not consistent."


def trihedral(apex: np.ndarray, incidence: float, turn: float = 0.0):
    """The built-in 1.5 m trihedral (scenes/meshes/trihedral.obj), its boresight tilted up to the
    sensor at ``incidence`` deg (the mesh's axis rises 35.26 deg), turned by ``turn`` rad about the
    vertical from the +y side, apex at ``apex``."""
    import trimesh
    mesh = trimesh.load(MESH, force="mesh")
    mesh.apply_scale(EDGE)
    tilt = 90.0 - incidence - math.degrees(math.atan(1.0 / math.sqrt(2.0)))
    mesh.apply_transform(trimesh.transformations.rotation_matrix(math.radians(tilt), [1, 0, 0]))
    mesh.apply_transform(trimesh.transformations.rotation_matrix(turn, [0, 0, 1]))
    mesh.apply_translation(apex)
    return mesh


def closed_form_db() -> float:
    wavelength = SPEED_OF_LIGHT / FREQUENCY
    return 10 * math.log10(4 * math.pi * EDGE ** 4 / (3 * wavelength ** 2))


def facing(sensor: dict) -> float:
    """The turn [rad] about the vertical from +y to the mid-aperture antenna seen from the scene
    centre (only orients the trihedral; every expected value comes from elsewhere)."""
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.core.radar import RadarParameters
    positions = acquisition_geometry(RadarParameters.from_mapping({**sensor, "n_pulses": 3})).positions
    east, north = positions[len(positions) // 2][:2]
    return math.atan2(north, east) - math.pi / 2


@pytest.fixture(scope="module")
def products(tmp_path_factory):
    """{case: (simulation, SICD path, CPHD path)}: the off-SRP trihedral on a straight track at 35 deg
    and on a 3 deg circular arc at 55 deg, 96 x 96 ground pixels, backprojected."""
    out = {}
    for name, overrides in CASES.items():
        sensor = {"frequency": FREQUENCY, "bandwidth": 150e6, "sampling_rate": 180e6, "prf": 250.0,
                  "velocity": 100.0, "altitude": 1000.0, "azimuth_beamwidth": 1.2,
                  "scene_center": (0.0, 0.0, 0.0), "geo_origin": "48.1, 11.5, 520", **overrides}
        mesh = trihedral(APEX, overrides["incidence_angle"], facing(sensor))
        scene = Scene(meshes=[(mesh, "pec", "tri")], sensor=sensor,
                      integrator={"max_depth": 3})
        sim = simulate(scene, image_size=(96, 96), focuser="bp")
        folder = tmp_path_factory.mktemp(name)
        out[name] = (sim, write_sicd(sim.image, folder / "image.nitf", raw=sim.raw),
                     write_cphd(sim.raw, folder / "raw.cphd"))
    return out


def parts(path):
    with open(path, "rb") as f, sksicd.NitfReader(f) as reader:
        tree = reader.metadata.xmltree
        return sksicd.XmlHelper(tree), tree, reader.read_image()


def sarpy_sicd_findings(path, caplog) -> list[str]:
    """sarpy's validity and consistency checks of a SICD file: the messages at ERROR and those that say "want"."""
    from sarpy.consistency.sicd_consistency import check_file
    from sarpy.io.complex.converter import open_complex
    caplog.clear()
    with caplog.at_level(logging.INFO):
        open_complex(str(path)).sicd_meta.is_valid(recursive=True, stack=False)
        check_file(str(path))
    return [r.getMessage().strip() for r in caplog.records
            if r.levelno >= logging.ERROR or "want" in r.getMessage().lower()]


def sarpy_cphd_failures(path) -> dict:
    from sarpy.consistency.cphd_consistency import CphdConsistency
    con = CphdConsistency.from_file(str(path), check_signal_data=False)
    con.check()
    return con.failures()


# -- independent readers: no error, no want ----------------------------------------------------------

@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("case", list(CASES))
def test_sarpy_and_sarkit_find_nothing_in_the_sicd_and_the_cphd(products, case, caplog):
    """Catches: the ground-plane grid's BetaZeroSF against RCSSF off by cos(SlopeAng) in sarpy's
    reading (the SICD of today's code), a circular CPHD that says TOAFixed false with constant
    TOA1/TOA2 (two sarpy "want"s), anything sicdcheck or cphdcheck reports."""
    _, sicd_path, cphd_path = products[case]
    xml, _, _ = parts(sicd_path)
    assert xml.load("{*}Grid/{*}ImagePlane") == "SLANT" and xml.load("{*}Grid/{*}Type") == "PLANE"
    assert sarpy_sicd_findings(sicd_path, caplog) == []
    assert sarpy_cphd_failures(cphd_path) == {}
    assert check_sicd(sicd_path) == [] and check_cphd(cphd_path) == []


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_the_ground_plane_option_is_the_one_sarpy_reads_off_by_the_plane_cosine(products, tmp_path, caplog):
    """``plane="image"`` keeps the former ground-plane SICD (documented convention difference):
    GROUND, and sarpy's only complaint is its slant-plane area taken without the plane cosine."""
    sim, _, _ = products["straight"]
    path = write_sicd(sim.image, tmp_path / "ground.nitf", raw=sim.raw, plane="image")
    assert parts(path)[0].load("{*}Grid/{*}ImagePlane") == "GROUND"
    assert set(sarpy_sicd_findings(path, caplog)) == {SARPY_GROUND_AREA}
    with pytest.raises(ValueError, match=r"plane = 'ground'.*slant, image"):
        write_sicd(sim.image, tmp_path / "bad.nitf", raw=sim.raw, plane="ground")


def test_a_circular_cphd_whose_window_follows_the_srp_is_toa_fixed(products):
    """Catches TOAFixed false beside TOA1/TOA2 that do not change (circular track: the SRP's range is
    constant), and TOAFixed true on a straight track, whose SRP range changes."""
    import sarkit.cphd as skcphd
    for case, fixed in (("circular", True), ("straight", False)):
        with open(products[case][2], "rb") as f, skcphd.Reader(f) as reader:
            xml = skcphd.XmlHelper(reader.metadata.xmltree)
            pvp = reader.read_pvps("1")
        assert xml.load("{*}Channel/{*}Parameters/{*}TOAFixed") is fixed, case
        assert xml.load("{*}Channel/{*}TOAFixedCPHD") is fixed, case
        spread = max(np.ptp(pvp["TOA1"]), np.ptp(pvp["TOA2"]))
        assert (spread == 0.0) if fixed else (spread > 1e-9), (case, spread)
        # the saved interval lies inside every vector's samples
        assert np.all(pvp["TOA1"] >= pvp["SC0"] - 1e-15)
        n = reader.metadata.xmltree.findtext("{*}Data/{*}Channel/{*}NumSamples")
        assert np.all(pvp["TOA2"] <= pvp["SC0"] + (int(n) - 1) * pvp["SCSS"] + 1e-15)


# -- the slant-plane grid ----------------------------------------------------------------------------

def coa_state(sim, xml):
    """(antenna position, velocity) [local m, m/s] at the SCP's centre of aperture, interpolated from
    the raw data's transmit positions at CollectStart + TimeCOAPoly(0, 0)."""
    t = float(xml.load("{*}Grid/{*}TimeCOAPoly")[0, 0])
    times = sim.raw.pulse_time - sim.raw.pulse_time[0]
    position = np.array([np.interp(t, times, sim.raw.tx_position[:, k]) for k in range(3)])
    velocity = np.array([np.interp(t, times, sim.raw.velocity[:, k]) for k in range(3)])
    return position, velocity


@pytest.mark.parametrize("case", list(CASES))
def test_row_is_the_line_of_sight_and_col_the_velocity_across_it(products, case):
    """Row = the unit line of sight from the antenna at the SCP's COA (raw positions, by hand), Col =
    the velocity there less its part along the row, along the flight looking right and against it
    looking left (Row x Col away from the Earth, which sicdcheck requires). Catches the
    ground-plane grid of today's code (horizontal rows) and a column vector that is not orthogonal
    to the row."""
    sim, path, _ = products[case]
    xml, _, _ = parts(path)
    ref = georef.of(sim.raw.metadata["radar"])
    scp = georef.ecef_to_enu(xml.load("{*}GeoData/{*}SCP/{*}ECF"), ref)
    antenna, velocity = coa_state(sim, xml)
    los = (scp - antenna) / np.linalg.norm(scp - antenna)
    across = velocity - (velocity @ los) * los
    axes = georef.enu_axes(ref)
    np.testing.assert_allclose(xml.load("{*}Grid/{*}Row/{*}UVectECF"), los @ axes, atol=2e-4)
    sense = -1.0 if CASES[case].get("look_side") == "left" else 1.0
    np.testing.assert_allclose(xml.load("{*}Grid/{*}Col/{*}UVectECF"),
                               sense * across / np.linalg.norm(across) @ axes, atol=2e-4)
    incidence = math.radians(CASES[case]["incidence_angle"])
    assert -los[2] == pytest.approx(math.cos(incidence), abs=0.01)       # looks down at the set incidence


@pytest.mark.parametrize("case", list(CASES))
def test_sarkit_projects_the_apex_onto_the_sicd_peak(products, case):
    """sarkit's scene-to-image projection (R/Rdot from the COA) of the apex against the peak the
    point-target analysis finds in the SICD pixels, within 0.1 of the impulse-response width.
    Catches the ground image sampled at the slant point dropped vertically onto the ground (ground
    range x sin(theta) for x / sin(theta): a wrong plane cosine) and a reversed look side in the
    range / range-rate projection."""
    import sarkit.sicd.projection as skproj
    sim, path, _ = products[case]
    xml, tree, _ = parts(path)
    ref = georef.of(sim.raw.metadata["radar"])
    params = skproj.MetadataParams.from_xml(tree)
    locations, _, _ = skproj.scene_to_image(params, georef.enu_to_ecef(APEX, ref))
    x_row, y_col = (float(v) for v in locations)
    image = read_sicd(path)                       # its azimuth along the flight: against Col looking left
    sense = float(np.sign(image.azimuth_direction @ (xml.load("{*}Grid/{*}Col/{*}UVectECF") @ georef.enu_axes(ref).T)))
    report = analyze_point_target(image, (sense * y_col, x_row), chip=16)
    assert report.range == pytest.approx(x_row, abs=0.1 * xml.load("{*}Grid/{*}Row/{*}ImpRespWid"))
    assert report.azimuth == pytest.approx(sense * y_col, abs=0.1 * xml.load("{*}Grid/{*}Col/{*}ImpRespWid"))
    assert math.hypot(x_row, y_col) > 1.5 * xml.load("{*}Grid/{*}Row/{*}ImpRespWid")      # off the SCP


# -- radiometry: every reader, one RCS ---------------------------------------------------------------

def box(pixels, half=10):
    i, j = np.unravel_index(int(np.argmax(np.abs(pixels))), pixels.shape)
    return pixels[i - half:i + half + 1, j - half:j + half + 1].astype(np.complex128), (i, j)


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("case", list(CASES))
def test_every_reader_reads_the_trihedral_rcs_alike(products, case, tmp_path):
    """The trihedral's RCS as ``analyze`` reads it on the focused image, against, on a SICD with the
    image's own weighting (``weighting="image"``; the default uniform one:
    tests/test_sicd_calibration.py): ``analyze`` on the SICD (0.2 dB), the integral method
    BetaZeroSF sum |p|^2 SS_row SS_col (0.2 dB), sarpy's RCS tool's TotalRCS over its own
    weighting factors (0.2 dB) and the closed form (0.3 dB).
    Catches the weighting factor applied twice in BetaZeroSF (3.7 dB), a plane cosine in a
    slant-plane grid's BetaZeroSF (2.4 and 0.9 dB at 55 and 35 deg), the ground-plane grid of
    today's code (0.9 and 2.4 dB), and the response sampled at the wrong ground points (a
    vertical drop of the slant pixel, a reversed look side)."""
    from sarpy.annotation.rcs import create_rcs_value_collection_for_reader
    from sarpy.geometry.geometry_elements import Polygon
    from sarpy.io.complex.converter import open_complex
    sim, _, _ = products[case]
    path = write_sicd(sim.image, tmp_path / "weighted.nitf", raw=sim.raw, weighting="image")
    xml, _, pixels = parts(path)
    reference = analyze_point_target(sim.image, APEX, chip=32).rcs_db
    assert reference == pytest.approx(closed_form_db(), abs=0.3)
    assert analyze_point_target(read_sicd(path), APEX, chip=16).rcs_db == pytest.approx(reference, abs=0.2)
    chip, (i, j) = box(pixels)
    spacing = xml.load("{*}Grid/{*}Row/{*}SS") * xml.load("{*}Grid/{*}Col/{*}SS")
    integral = xml.load("{*}Radiometric/{*}BetaZeroSFPoly")[0, 0] * np.sum(np.abs(chip) ** 2) * spacing
    assert 10 * math.log10(integral) == pytest.approx(reference, abs=0.2)
    reader = open_complex(str(path))
    polygon = Polygon(coordinates=[[[i - 10, j - 10], [i - 10, j + 11], [i + 11, j + 11], [i + 11, j - 10],
                                    [i - 10, j - 10]]])
    values = create_rcs_value_collection_for_reader(reader, polygon)
    total = [e for e in values.elements if e.units == "TotalRCS"][0].value.mean
    grid = reader.sicd_meta.Grid
    weighting = grid.get_slant_plane_area() * grid.Row.ImpRespBW * grid.Col.ImpRespBW    # sarpy's W_row W_col
    assert weighting > 1.5                                                             # Taylor windows
    assert 10 * math.log10(total / weighting) == pytest.approx(reference, abs=0.2)
    assert 10 * math.log10(total / weighting) == pytest.approx(closed_form_db(), abs=0.3)


def test_rcssf_reads_the_peak_and_beta_the_pixel_area(products):
    """RCSSF |peak|^2 is the RCS (unit peak gain, docs/physics.md (K)); BetaZeroSF = RCSSF / A with A
    the slant-plane energy area of a cell, W_row W_col / (BW_row BW_col), the weighting factors
    of the declared WgtFunct (1 without one: the default uniform SICD); SigmaZeroSF = Beta
    cos(slope) with the slope from the geometry by hand (55 deg: sin and cos differ)."""
    sim, path, _ = products["circular"]
    xml, _, _ = parts(path)
    report = analyze_point_target(read_sicd(path), APEX, chip=16)
    rcs_sf = xml.load("{*}Radiometric/{*}RCSSFPoly")[0, 0]
    assert 10 * math.log10(rcs_sf * report.peak_magnitude ** 2) == pytest.approx(report.rcs_db, abs=0.05)
    area = 1.0
    for direction in ("Row", "Col"):
        w = xml.load(f"{{*}}Grid/{{*}}{direction}/{{*}}WgtFunct")
        factor = 1.0 if w is None else np.mean(w ** 2) / np.mean(w) ** 2
        area *= factor / xml.load(f"{{*}}Grid/{{*}}{direction}/{{*}}ImpRespBW")
    beta = xml.load("{*}Radiometric/{*}BetaZeroSFPoly")[0, 0]
    assert beta == pytest.approx(rcs_sf / area, rel=1e-3)
    ref = georef.of(sim.raw.metadata["radar"])
    scp = georef.ecef_to_enu(xml.load("{*}GeoData/{*}SCP/{*}ECF"), ref)
    antenna, velocity = coa_state(sim, xml)
    normal = np.cross(scp - antenna, velocity)
    cos_slope = abs(normal[2]) / np.linalg.norm(normal)
    assert xml.load("{*}Radiometric/{*}SigmaZeroSFPoly")[0, 0] == pytest.approx(beta * cos_slope, rel=2e-3)


# -- the carrier -------------------------------------------------------------------------------------

def spectral_centre(chip: np.ndarray, axis: int, spacing: float) -> float:
    """Centroid [cycles/m] of the chip's power spectrum along ``axis`` (circular mean over the band
    1 / spacing, so a support across the band edge is not split)."""
    power = (np.abs(np.fft.fft(chip, axis=axis)) ** 2).sum(axis=1 - axis)
    f = np.fft.fftfreq(chip.shape[axis], spacing)
    return float(np.angle(np.sum(power * np.exp(2j * np.pi * f * spacing)))) / (2 * np.pi * spacing)


@pytest.mark.parametrize("case", list(CASES))
def test_deltakcoapoly_is_the_spectral_centre_around_the_off_scp_trihedral(products, case):
    """Issue 55 measured DeltaKCOAPoly up to 6 % of the bandwidth from the carrier on a circular arc,
    from a 16-pixel chip. Over a 16 x 48 chip around the trihedral (off the SCP) the power
    spectrum's centroid is DeltaKCOAPoly there within 3 % of ImpRespBW in both directions.
    Catches the pixels conjugated (the wrong SGN: the azimuth centre mirrored on the arc) and the
    slant pixels sampled at the wrong ground points (a vertical drop, a reversed look side)."""
    _, path, _ = products[case]
    xml, _, pixels = parts(path)
    spacing = (xml.load("{*}Grid/{*}Row/{*}SS"), xml.load("{*}Grid/{*}Col/{*}SS"))
    scp_row, scp_col = xml.load("{*}ImageData/{*}SCPPixel")
    i, j = np.unravel_index(int(np.argmax(np.abs(pixels))), pixels.shape)
    chip = pixels[i - 8:i + 8, j - 24:j + 24].astype(np.complex128)
    assert chip.shape == (16, 48)
    x, y = (i - scp_row) * spacing[0], (j - scp_col) * spacing[1]
    for axis, direction in enumerate(("Row", "Col")):
        declared = np.polynomial.polynomial.polyval2d(x, y, xml.load(f"{{*}}Grid/{{*}}{direction}/{{*}}DeltaKCOAPoly"))
        error = spectral_centre(chip, axis, spacing[axis]) - declared
        error = (error + 0.5 / spacing[axis]) % (1 / spacing[axis]) - 0.5 / spacing[axis]
        assert abs(error) < 0.03 * xml.load(f"{{*}}Grid/{{*}}{direction}/{{*}}ImpRespBW"), (direction, error)


# -- the CPHD read as the standard says, off the SRP -------------------------------------------------

def enu_to_ecef_by_hand(points: np.ndarray, lat: float, lon: float, h: float) -> np.ndarray:
    """docs/physics.md (GEO1) written out: the origin through pyproj's geodetic-to-ECEF, the axes by formula."""
    import pyproj
    x0 = np.array(pyproj.Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True).transform(lon, lat, h))
    p, l = math.radians(lat), math.radians(lon)
    east = np.array([-math.sin(l), math.cos(l), 0.0])
    north = np.array([-math.sin(p) * math.cos(l), -math.sin(p) * math.sin(l), math.cos(p)])
    up = np.array([math.cos(p) * math.cos(l), math.cos(p) * math.sin(l), math.sin(p)])
    return x0 + points[..., :1] * east + points[..., 1:2] * north + points[..., 2:] * up


@pytest.mark.parametrize("case", list(CASES))
def test_a_backprojection_from_the_cphd_fields_alone_focuses_on_the_off_srp_apex(products, case):
    """Every vector's samples interpolated at the apex's dTOA (TxPos, RcvPos, SRPPos of the PVPs,
    SC0 + s SCSS) and phased by exp(-j SGN 2 pi fc dTOA) (CPHD 1.1 sec. 4 and 6): the coherent sum
    over a 2 x 2 m grid around the apex peaks within 0.15 m of it, with 90 % of the incoherent sum.
    Off the SRP a wrong position or sign no longer focuses: catches east and north exchanged on
    the way to ECEF, the data's phase of the other sign under SGN = -1, and a missing SRP
    compensation (straight track; on the circle the SRP delay is constant and so is its phase)."""
    import sarkit.cphd as skcphd
    from scipy.signal import resample
    _, _, path = products[case]
    with open(path, "rb") as f, skcphd.Reader(f) as reader:
        signal, pvp = reader.read_channel("1")
        xml = skcphd.XmlHelper(reader.metadata.xmltree)
    sgn = xml.load("{*}Global/{*}SGN")
    fc = 0.5 * (pvp["FX1"][0] + pvp["FX2"][0])
    up = 8
    fine = resample(signal.astype(np.complex128), signal.shape[1] * up, axis=1)
    offsets = np.arange(-10, 11) * 0.1
    grid = APEX + np.stack(np.meshgrid(offsets, offsets, [0.0], indexing="ij"), axis=-1).reshape(-1, 3)
    points = enu_to_ecef_by_hand(grid, 48.1, 11.5, 520.0)                                   # [n, 3]
    srp = np.linalg.norm(pvp["TxPos"] - pvp["SRPPos"], axis=1) + np.linalg.norm(pvp["RcvPos"] - pvp["SRPPos"], axis=1)
    coherent, incoherent = np.zeros(len(points), complex), np.zeros(len(points))
    for v in range(signal.shape[0]):
        path_length = (np.linalg.norm(points - pvp["TxPos"][v], axis=1)
                       + np.linalg.norm(points - pvp["RcvPos"][v], axis=1))
        dtoa = (path_length - srp[v]) / SPEED_OF_LIGHT
        index = (dtoa - pvp["SC0"][v]) / pvp["SCSS"][v] * up
        k = np.clip(np.floor(index).astype(int), 0, fine.shape[1] - 2)
        frac = index - k
        value = fine[v, k] * (1 - frac) + fine[v, k + 1] * frac
        coherent += value * np.exp(-1j * sgn * 2 * np.pi * fc * dtoa)
        incoherent += np.abs(value)
    best = int(np.argmax(np.abs(coherent)))
    assert np.linalg.norm(grid[best] - APEX) <= 0.15, grid[best]
    assert abs(coherent[best]) >= 0.9 * incoherent[best]


@pytest.mark.parametrize("case", ["straight", "left"])
def test_a_slant_sicd_read_and_written_again_keeps_its_grid_and_pixels(products, case, tmp_path):
    """read_sicd gives the slant-plane image (its azimuth along the flight, so a left-looking file's
    columns come back reversed); writing it again keeps the plane, the vectors and every pixel.
    Catches a reader that reverses the columns without reversing the axis (the pixels of a
    left-looking file mirrored) and a writer that resamples a slant-plane image again."""
    sim, path, _ = products[case]
    image = read_sicd(path)
    assert image.plane == "slant" and image.azimuth_direction @ sim.raw.velocity.mean(axis=0) > 0
    again = write_sicd(image, tmp_path / "again.nitf", raw=sim.raw)
    (xml, _, pixels), (xml2, _, pixels2) = parts(path), parts(again)
    np.testing.assert_array_equal(pixels2, pixels)
    for name in ("Row/{*}UVectECF", "Col/{*}UVectECF"):
        np.testing.assert_allclose(xml2.load(f"{{*}}Grid/{{*}}{name}"), xml.load(f"{{*}}Grid/{{*}}{name}"), atol=1e-9)
