"""SICD files other tools read (issue 29): version, grid, weighting, radiometry, polygons, times, paths.

- sarpy (NGA's older library, independent of sarkit) opens the ``image.nitf`` of ``render
  trihedral``, of a small ``urban``, of a quad-pol render and of an RDA slant-plane focus, reads
  the same pixels as sarkit, and its SICD validity and consistency checks log no ERROR but one
  for the ground-plane images: sarpy takes the slant-plane area of a GROUND grid's resolution
  cell from its ground-plane bandwidths, so it finds ``BetaZeroSFPoly`` and ``RCSSFPoly``
  inconsistent by exactly the cosine between the image and slant planes (checked here by hand);
  sarkit's ``sicdcheck`` exits 0 for all of them (no advisory finding either).
- Row ``ImpRespBW`` is ``2 B sin(theta) / c`` at 30 and 60 deg incidence (at 45 deg a projection
  by the cosine passes too), Col ``ImpRespBW`` ``2 (s2 - s1) / lambda`` over the sines of the
  track's ends (32 pulses) or of the beam's first nulls (the default render); the grid samples
  each 1.1 to 2.2 times, so a lost factor shows.
- ``TimeCOAPoly`` gives a pixel 60 columns either side of the SCP the UTC time at which the
  track passes broadside of it, computed here from the antenna positions.
- The pixels' local spectrum sits where ``DeltaKCOAPoly`` says (the carrier drifts with the
  incidence angle across the urban swath), and the trihedral analyses from the NITF as from
  the ``.npz``.
- ``WgtFunct``, ``ImpRespWid``, ``Radiometric``, ``ValidData``, ``RadarCollection/Area``,
  ``CollectStart``, ``ImageCreation/DateTime`` against values computed here; no absolute path in
  the file; a SICD 1.4.0 file of the former square-pixel layout still reads.

Expected values are computed here from the geometry, not by the code under test.
"""
from __future__ import annotations

import datetime
import logging
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sksicd = pytest.importorskip("sarkit.sicd")

from sarmitsuba import pipeline  # noqa: E402
from sarmitsuba.cli import main  # noqa: E402
from sarmitsuba.core import georef  # noqa: E402
from sarmitsuba.core.constants import SPEED_OF_LIGHT  # noqa: E402
from sarmitsuba.core.image import SarImage  # noqa: E402
from sarmitsuba.core.raw import RawData  # noqa: E402
from sarmitsuba.formats.sicd import SicdError, check_sicd, load_image, read_sicd, write_sicd  # noqa: E402

START = "2026-11-24T23:40:16.123456+00:00"
OLD_FILE = Path(__file__).parent / "data" / "sicd_1.4.0_square_pixels.nitf"
FILES = ["trihedral/image.nitf", "urban/image.nitf", "slant/image.nitf"] + [
    f"quad/image_{p}.nitf" for p in ("HH", "HV", "VH", "VV")]
#: The one ERROR sarpy logs for a GROUND grid (its slant-plane area is the ground-plane one).
SARPY_GROUND_AREA = "RadiometricType: The BetaZeroSFPoly and RCSSFPoly are not consistent."


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    """Folder of `render --sicd` runs: trihedral (default, collection_start set), urban (32 pulses,
    depth 1), quad-pol trihedral (16 pulses), and an RDA slant-plane focus of the trihedral; the
    trihedral's and urban's images also as ``weighted.nitf``, written with their own weighting."""
    root = tmp_path_factory.mktemp("renders")
    runs = {"trihedral": ["trihedral", "--set", f"collection_start={START}"],
            "urban": ["urban", "--pulses", "32", "--max-depth", "1"],
            "quad": ["trihedral", "--pulses", "16", "--set", "polarization=quad"]}
    root.joinpath("before").write_text(datetime.datetime.now(datetime.timezone.utc).isoformat())
    for name, args in runs.items():
        assert main(["render", *args, "--sicd", "--out", str(root / name), "--no-progress"]) == 0
    assert main(["focus", str(root / "trihedral" / "raw.npz"), "--algorithm", "rda", "--sicd", "--out",
                 str(root / "slant"), "--no-progress"]) == 0
    for name in ("trihedral", "urban"):        # the image's own weighting (WgtFunct), beside the default uniform
        write_sicd(SarImage.load(root / name / "image.npz"), root / name / "weighted.nitf",
                   raw=RawData.load(root / name / "raw.npz"), weighting="image")
    return root


def parts(path):
    """(XmlHelper, xml tree, pixels [rows, cols]) of a SICD file, straight from sarkit."""
    with open(path, "rb") as f, sksicd.NitfReader(f) as reader:
        tree = reader.metadata.xmltree
        return sksicd.XmlHelper(tree), tree, reader.read_image()


def grid_value(xml, direction, name):
    return xml.load(f"{{*}}Grid/{{*}}{direction}/{{*}}{name}")


def slant_plane_cosine(xml, raw: RawData, ref) -> float:
    """|n_image . n_slant| by hand: the slant plane through the mid-aperture line of sight to the
    SCP and the velocity; the image plane of the Row and Col vectors."""
    mid = len(raw.pulse_time) // 2
    scp = georef.ecef_to_enu(xml.load("{*}GeoData/{*}SCP/{*}ECF"), ref)
    slant = np.cross(scp - raw.tx_position[mid], raw.velocity[mid])
    axes = georef.enu_axes(ref)
    image = np.cross(grid_value(xml, "Row", "UVectECF") @ axes.T, grid_value(xml, "Col", "UVectECF") @ axes.T)
    return abs(float(image @ slant)) / float(np.linalg.norm(image) * np.linalg.norm(slant))


# -- other tools: sarpy and sicdcheck ----------------------------------------------------------------

@pytest.mark.filterwarnings("ignore:Call to deprecated class SICDReader:DeprecationWarning")
@pytest.mark.parametrize("name", FILES)
def test_sarpy_opens_the_file_and_logs_no_error_but_its_ground_plane_cell_area(renders, name, caplog):
    pytest.importorskip("sarpy")
    from sarpy.consistency.sicd_consistency import check_file
    from sarpy.io.complex.converter import open_complex
    path = renders / name
    xml, _, pixels = parts(path)
    with caplog.at_level(logging.INFO):
        reader = open_complex(str(path))
        np.testing.assert_array_equal(reader[:, :], pixels)
        reader.sicd_meta.is_valid(recursive=True, stack=False)
        check_file(str(path))
    errors = {r.getMessage().strip() for r in caplog.records if r.levelno >= logging.ERROR}
    if xml.load("{*}Grid/{*}ImagePlane") == "GROUND":
        assert errors <= {SARPY_GROUND_AREA}, errors
        raw = RawData.load(path.with_name(path.name.replace("image", "raw").replace(".nitf", ".npz")))
        meta = reader.sicd_meta
        sarpy_ratio = meta.Radiometric.RCSSFPoly[0, 0] / (meta.Radiometric.BetaZeroSFPoly[0, 0]
                                                           * meta.Grid.get_slant_plane_area())
        assert sarpy_ratio == pytest.approx(slant_plane_cosine(xml, raw, georef.of(raw.metadata["radar"])),
                                            rel=1e-3)
    else:
        assert not errors, errors


@pytest.mark.parametrize("name", FILES)
def test_sicdcheck_exits_0(renders, name):
    script = Path(sys.executable).with_name("sicdcheck")
    command = [str(script)] if script.is_file() else [sys.executable, "-c",
                                                      "import sys; from sarkit.verification import _sicdcheck as c; "
                                                      "sys.exit(c.main())"]
    done = subprocess.run([*command, str(renders / name)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert check_sicd(renders / name) == []


def test_the_version_is_1_3_0(renders):
    xml, tree, _ = parts(renders / "trihedral" / "image.nitf")
    assert tree.getroot().tag == "{urn:SICD:1.3.0}SICD"
    content = (renders / "trihedral" / "image.nitf").read_bytes()     # the DES subheader names it too
    assert content.count(b"urn:SICD:1.3.0") >= 2 and b"urn:SICD:1.4.0" not in content


# -- grid: bandwidths, sampling, times ---------------------------------------------------------------

def simulated(tmp_path, incidence=45.0, n_pulses=32):
    """(raw, image, path) of a small trihedral at ``incidence`` written as a ground-plane SICD
    (``plane="image"``); the image on the default grid (half the finer nominal resolution, 0.33 m: 3 to 6 times the bandwidths here)."""
    sim = pipeline.simulate("trihedral", sensor_overrides={"n_pulses": n_pulses, "incidence_angle": incidence},
                            image_size=(48, 48))
    return sim.raw, sim.image, write_sicd(sim.image, tmp_path / f"i{incidence:g}.nitf", raw=sim.raw, plane="image")


def zero_doppler(raw: RawData, point: np.ndarray) -> tuple[float, np.ndarray]:
    """(time from the first pulse [s], antenna position) where the straight track passes broadside of ``point``."""
    v = raw.velocity.mean(axis=0)
    along = (point - raw.tx_position[0]) @ v / (v @ v)           # seconds after the first pulse
    return float(along), raw.tx_position[0] + along * v


def oversampling(xml, direction) -> float:
    return 1.0 / (grid_value(xml, direction, "SS") * grid_value(xml, direction, "ImpRespBW"))


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_range_bandwidth_is_the_ground_projection_by_the_sine(tmp_path, incidence):
    """Row ImpRespBW = 2 B sin(theta) / c, theta the incidence at the SCP from its zero-Doppler
    antenna position; 30 and 60 deg tell sine from cosine. The grid samples it 1.1 to 2.2 times."""
    raw, image, path = simulated(tmp_path, incidence)
    xml, _, _ = parts(path)
    scp = georef.ecef_to_enu(xml.load("{*}GeoData/{*}SCP/{*}ECF"), georef.of(image.metadata["radar"]))
    _, antenna = zero_doppler(raw, scp)
    sin_theta = np.hypot(*(scp - antenna)[:2]) / np.linalg.norm(scp - antenna)
    assert sin_theta == pytest.approx(math.sin(math.radians(incidence)), abs=0.01)
    assert grid_value(xml, "Row", "ImpRespBW") == pytest.approx(2 * raw.bandwidth * sin_theta / SPEED_OF_LIGHT,
                                                                rel=1e-4)
    assert 1.1 <= oversampling(xml, "Row") <= 2.2


def test_azimuth_bandwidth_of_a_short_track_is_its_span_seen_from_the_scp(tmp_path):
    """32 pulses (12.4 m of track at 1414 m) bound the aperture: Col ImpRespBW = 2 (s2 - s1) / lambda
    with s the along-track sines of the first and last antenna positions seen from the SCP."""
    raw, image, path = simulated(tmp_path)
    xml, _, _ = parts(path)
    scp = georef.ecef_to_enu(xml.load("{*}GeoData/{*}SCP/{*}ECF"), georef.of(image.metadata["radar"]))
    heading = raw.velocity[0] / np.linalg.norm(raw.velocity[0])
    sines = [(scp - p) @ heading / np.linalg.norm(scp - p) for p in (raw.tx_position[0], raw.tx_position[-1])]
    wavelength = SPEED_OF_LIGHT / raw.fc
    assert grid_value(xml, "Col", "ImpRespBW") == pytest.approx(2 * abs(sines[0] - sines[1]) / wavelength,
                                                                rel=1e-4)
    assert 1.1 <= oversampling(xml, "Col") <= 2.2


def test_azimuth_bandwidth_of_the_default_render_is_the_beam_to_its_first_nulls(renders):
    """174 pulses: the processed beam ends at the first nulls of the uniform aperture whose one-way
    -3 dB width is the sensor's azimuth_beamwidth (sinc^2 half power at L sin(phi) / lambda =
    0.442946), so the image's Col ImpRespBW (weighted.nitf) = 2 (2 s_null) / lambda, s_null =
    sin(beamwidth / 2) / 0.442946."""
    image = SarImage.load(renders / "trihedral" / "image.npz")
    xml, _, _ = parts(renders / "trihedral" / "weighted.nitf")
    radar = image.metadata["radar"]
    s_null = math.sin(math.radians(radar["azimuth_beamwidth"] / 2)) / 0.442946
    wavelength = SPEED_OF_LIGHT / radar["frequency"]
    assert grid_value(xml, "Col", "ImpRespBW") == pytest.approx(4 * s_null / wavelength, rel=2e-4)
    assert 1.1 <= oversampling(xml, "Col") <= 2.2 and 1.1 <= oversampling(xml, "Row") <= 2.2


def test_time_of_closest_approach_of_pixels_off_the_scp(renders):
    """A pixel 60 columns (or as many as the grid holds) after (before) the SCP is imaged when the
    track passes broadside of it: CollectStart + TimeCOAPoly(0, y) is that UTC time, later
    (earlier) than the SCP's."""
    path = renders / "trihedral" / "image.nitf"
    raw = RawData.load(renders / "trihedral" / "raw.npz")
    xml, _, _ = parts(path)
    image = read_sicd(path)
    assert xml.load("{*}Timeline/{*}CollectStart") == datetime.datetime.fromisoformat(START)
    scp_row, scp_col = xml.load("{*}ImageData/{*}SCPPixel")
    times = []
    step = min(60, int(scp_col) - 1)
    for offset in (-step, 0, step):
        y = offset * grid_value(xml, "Col", "SS")
        t_poly = np.polynomial.polynomial.polyval2d(0.0, y, xml.load("{*}Grid/{*}TimeCOAPoly"))
        t_hand, _ = zero_doppler(raw, image.positions()[scp_col + offset, scp_row])
        assert t_poly == pytest.approx(t_hand, abs=1e-4), offset
        times.append(datetime.datetime.fromisoformat(START) + datetime.timedelta(seconds=t_poly))
    assert times[0] < times[1] < times[2]


def test_creation_time_is_the_writing_moment_and_collect_start_defaults_to_2000(renders, tmp_path):
    xml, _, _ = parts(renders / "trihedral" / "image.nitf")
    before = datetime.datetime.fromisoformat((renders / "before").read_text())
    created = xml.load("{*}ImageCreation/{*}DateTime")
    assert before <= created <= datetime.datetime.now(datetime.timezone.utc)
    image = SarImage.load(renders / "urban" / "image.npz")
    image.metadata["radar"]["collection_start"] = None                  # a file of an older version
    xml, _, _ = parts(write_sicd(image, tmp_path / "old.nitf"))
    assert xml.load("{*}Timeline/{*}CollectStart") == datetime.datetime(2000, 1, 1, tzinfo=datetime.timezone.utc)
    image.metadata["radar"]["collection_start"] = "2026-11-24 23:40"                     # no UTC offset
    with pytest.raises(SicdError, match=r"bad\.nitf.*collection_start"):
        write_sicd(image, tmp_path / "bad.nitf")
    assert not (tmp_path / "bad.nitf").exists()


# -- the pixels: carrier, spectrum, analysis ---------------------------------------------------------

def data_centre(pixels, row, col, n, spacing):
    """Spectral centroid [cycles/m] of the pixels' n x n chip at (row, col), along rows and columns."""
    z = pixels[row - n // 2:row + n // 2, col - n // 2:col + n // 2].astype(np.complex128)
    return (float(np.angle(np.sum(z[1:, :] * np.conj(z[:-1, :])))) / (2 * np.pi * spacing[0]),
            float(np.angle(np.sum(z[:, 1:] * np.conj(z[:, :-1])))) / (2 * np.pi * spacing[1]))


def folded(value, spacing):
    return (value + 0.5 / spacing) % (1.0 / spacing) - 0.5 / spacing


@pytest.mark.parametrize("name, offsets, directions", [("trihedral/image.nitf", [0.0], ("Row", "Col")),
                                                       ("trihedral/weighted.nitf", [0.0], ("Row", "Col")),
                                                       ("urban/image.nitf", [-75.0, 0.0, 75.0], ("Row",)),
                                                       ("urban/weighted.nitf", [-75.0, 0.0, 75.0], ("Row",))])
def test_the_pixels_spectrum_is_centred_where_deltakcoapoly_says(renders, name, offsets, directions):
    """The local spectral centre of the SICD pixels (a chip's lag-one phase) is DeltaKCOAPoly there,
    within 5 % of the bandwidth: at the trihedral, and in range across the urban swath, where the
    incidence angle moves the carrier by over a bandwidth (its clutter's azimuth spectrum is too
    uneven over a chip for the same test), on the default uniform files and with the image's own
    weighting. Catches, on the uniform urban file, the weighting divided about one spectral centre
    for the whole image (6 to 9 % of the band off 75 m from the SCP: the division lifts the band
    edge toward which clutter above the ground plane leans; docs/physics.md (K3'))."""
    xml, _, pixels = parts(renders / name)
    spacing = (grid_value(xml, "Row", "SS"), grid_value(xml, "Col", "SS"))
    scp_row, scp_col = xml.load("{*}ImageData/{*}SCPPixel")
    for x in offsets:
        row = scp_row + int(round(x / spacing[0]))
        measured = data_centre(pixels, row, scp_col, 24, spacing)
        for k, direction in enumerate(("Row", "Col")):
            if direction not in directions:
                continue
            declared = np.polynomial.polynomial.polyval2d((row - scp_row) * spacing[0], 0.0,
                                                          grid_value(xml, direction, "DeltaKCOAPoly"))
            error = folded(measured[k] - declared, spacing[k])
            assert abs(error) < 0.05 * grid_value(xml, direction, "ImpRespBW"), (x, direction, measured, declared)


def test_the_trihedral_analyses_from_the_nitf_as_from_the_npz(renders):
    """Default chip and options: the slant-plane SICD grid with the image's own weighting keeps the
    RCS, the azimuth resolution, the sidelobes and the position of the trihedral; its range
    resolution is the slant one (the default uniform SICD: tests/test_sicd_calibration.py)."""
    from sarmitsuba.analysis.point_target import analyze_point_target
    reports = [analyze_point_target(load_image(renders / "trihedral" / name), (0.0, 0.0, 0.0)).to_dict()
               for name in ("image.npz", "weighted.nitf")]
    assert reports[1]["rcs_db"] == pytest.approx(reports[0]["rcs_db"], abs=0.02)
    for key in ("irw_azimuth", "peak_magnitude"):
        assert reports[1][key] == pytest.approx(reports[0][key], rel=0.005), key
    # slant-plane SICD: the range width is the ground one times sin(45 deg incidence)
    assert reports[1]["irw_range"] == pytest.approx(reports[0]["irw_range"] * math.sqrt(0.5), rel=0.005)
    assert reports[1]["pslr_range_db"] == pytest.approx(reports[0]["pslr_range_db"], abs=0.5)
    assert reports[1]["pslr_azimuth_db"] == pytest.approx(reports[0]["pslr_azimuth_db"], abs=1.5)
    for key in ("azimuth", "range"):
        assert reports[1][key] == pytest.approx(reports[0][key], abs=0.01), key


# -- weighting, radiometry, polygons, paths ----------------------------------------------------------

def half_power_width(weights) -> float:
    """-3 dB width of |FFT(weights)|^2 in units of 1 / support (the weights spread over the support)."""
    power = np.abs(np.fft.fft(weights, 4096 * len(weights))) ** 2
    power = power / power[0]
    k = int(np.argmax(power < 0.5))
    return 2 * (k - 1 + (power[k - 1] - 0.5) / (power[k - 1] - power[k])) / 4096


def test_weighting_functions_and_widths_are_those_of_the_impulse_response(renders):
    """With the image's own weighting: Row the Taylor window sampled (WgtFunct) and its width; Col
    the window times the two-way pattern, whose width is the azimuth IRW measured on the image
    (0.60 m, not the window's 0.39)."""
    from sarmitsuba.analysis.point_target import analyze_point_target
    xml, _, _ = parts(renders / "trihedral" / "weighted.nitf")
    report = analyze_point_target(read_sicd(renders / "trihedral" / "weighted.nitf"), (0.0, 0.0, 0.0))
    for direction, measured in (("Row", report.irw_range), ("Col", report.irw_azimuth)):
        weights = grid_value(xml, direction, "WgtFunct")
        assert weights is not None and weights.size == 512
        width = grid_value(xml, direction, "ImpRespWid")
        assert width == pytest.approx(half_power_width(weights) / grid_value(xml, direction, "ImpRespBW"), rel=2e-3)
        assert width == pytest.approx(measured, rel=0.02), direction
    assert xml.load("{*}Grid/{*}Row/{*}WgtType/{*}WindowName") == "TAYLOR"


@pytest.mark.parametrize("name", ["image.nitf", "weighted.nitf"])
def test_radiometric_scale_factors_follow_from_the_unit_peak_gain(renders, name):
    """RCSSF: the trihedral's peak power is its RCS (2 %); BetaZeroSF = RCSSF / (slant-plane energy
    area of a cell, W_row W_col / (BW_row BW_col) times |n_image . n_slant|, 1 on the slant-plane
    grid; W = 1 without a WgtFunct, the default uniform SICD); SigmaZeroSF = Beta cos(slope),
    GammaZeroSF = Sigma / cos(incidence), the slope angle between the slant plane and the ground
    (45 deg here) and the incidence from the geometry by hand."""
    from sarmitsuba.analysis.point_target import analyze_point_target
    path = renders / "trihedral" / name
    xml, _, _ = parts(path)
    raw = RawData.load(renders / "trihedral" / "raw.npz")
    ref = georef.of(raw.metadata["radar"])
    report = analyze_point_target(read_sicd(path), (0.0, 0.0, 0.0))
    rcs_sf = xml.load("{*}Radiometric/{*}RCSSFPoly")[0, 0]
    assert rcs_sf * report.peak_magnitude ** 2 == pytest.approx(report.rcs, rel=0.02)
    area = 1.0
    for direction in ("Row", "Col"):
        w = grid_value(xml, direction, "WgtFunct")
        factor = 1.0 if w is None else np.mean(w ** 2) / np.mean(w) ** 2
        area *= factor / grid_value(xml, direction, "ImpRespBW")
    assert slant_plane_cosine(xml, raw, ref) == pytest.approx(1.0, abs=1e-6)          # slant-plane grid
    beta = xml.load("{*}Radiometric/{*}BetaZeroSFPoly")[0, 0]
    assert beta == pytest.approx(rcs_sf / area, rel=1e-3)
    scp = georef.ecef_to_enu(xml.load("{*}GeoData/{*}SCP/{*}ECF"), ref)
    _, antenna = zero_doppler(raw, scp)
    slant_normal = np.cross(scp - antenna, raw.velocity[0])
    cos_slope = abs(slant_normal[2]) / np.linalg.norm(slant_normal)                   # against the local up
    assert cos_slope == pytest.approx(math.sin(math.radians(45.0)), abs=2e-3)
    cos_incidence = (antenna - scp)[2] / np.linalg.norm(antenna - scp)
    sigma = xml.load("{*}Radiometric/{*}SigmaZeroSFPoly")[0, 0]
    assert sigma == pytest.approx(beta * cos_slope, rel=1e-3)
    assert xml.load("{*}Radiometric/{*}GammaZeroSFPoly")[0, 0] == pytest.approx(sigma / cos_incidence, rel=2e-3)


def test_valid_data_and_area_are_the_image_corners_on_the_ground(renders):
    """ValidData: the four corner pixels, first row and column first, clockwise; GeoData/ValidData
    and ImageCorners their ground points; Area/Corner the same points at the SCP's height, clockwise
    seen from above, around the trihedral's geographic position."""
    path = renders / "trihedral" / "image.nitf"
    xml, tree, _ = parts(path)
    n_rows, n_cols = xml.load("{*}ImageData/{*}NumRows"), xml.load("{*}ImageData/{*}NumCols")
    np.testing.assert_array_equal(xml.load("{*}ImageData/{*}ValidData"),
                                  [[0, 0], [0, n_cols - 1], [n_rows - 1, n_cols - 1], [n_rows - 1, 0]])
    corners = xml.load("{*}GeoData/{*}ImageCorners")
    np.testing.assert_allclose(xml.load("{*}GeoData/{*}ValidData"), corners, atol=1e-12)
    acp = np.asarray(xml.load("{*}RadarCollection/{*}Area/{*}Corner"))
    assert acp.shape == (4, 3)
    np.testing.assert_allclose(acp[:, 2], xml.load("{*}GeoData/{*}SCP/{*}LLH")[2], atol=1e-6)
    assert {tuple(np.round(c, 9)) for c in acp[:, :2]} == {tuple(np.round(c, 9)) for c in corners}
    east = (acp[:, 1] - acp[0, 1]) * math.cos(math.radians(acp[0, 0]))
    north = acp[:, 0] - acp[0, 0]
    assert np.sum(east * np.roll(north, -1) - np.roll(east, -1) * north) < 0        # clockwise
    lat, lon, _ = georef.enu_to_geodetic(np.zeros(3), georef.of(
        SarImage.load(renders / "trihedral" / "image.npz").metadata["radar"]))
    assert corners[:, 0].min() < lat < corners[:, 0].max() and corners[:, 1].min() < lon < corners[:, 1].max()


def test_no_absolute_path_is_written(renders, tmp_path):
    image = SarImage.load(renders / "trihedral" / "image.npz")
    image.metadata["scene_path"] = "/home/someone/private/scenes/trihedral.xml"
    image.metadata["settings"]["nested"] = {"scene_path": "C:\\Users\\someone\\trihedral.xml"}
    path = write_sicd(image, tmp_path / "image.nitf", raw=RawData.load(renders / "trihedral" / "raw.npz"))
    content = path.read_bytes()
    assert b"someone" not in content and b"/home/" not in content
    back = read_sicd(path)
    assert back.metadata["scene_path"] == "trihedral.xml"
    assert back.metadata["settings"]["nested"]["scene_path"] == "trihedral.xml"


def test_a_sicd_1_4_0_file_of_the_former_square_pixel_layout_still_reads():
    """tests/data/sicd_1.4.0_square_pixels.nitf: written by the former writer (16 pulses, 24 x 24
    pixels of 0.5 m, the image's own pixels and phase): read as it was, and analysed."""
    xml, tree, pixels = parts(OLD_FILE)
    assert tree.getroot().tag == "{urn:SICD:1.4.0}SICD"
    image = read_sicd(OLD_FILE)
    np.testing.assert_array_equal(image.data, pixels.T)
    assert np.diff(image.range) == pytest.approx(0.5) and np.diff(image.azimuth) == pytest.approx(0.5)
    assert image.metadata["scene"] == "trihedral"
    from sarmitsuba.analysis.point_target import analyze_point_target
    report = analyze_point_target(load_image(OLD_FILE), (0.0, 0.0, 0.0), chip=16)
    assert report.peak_magnitude == pytest.approx(float(np.abs(pixels).max()), rel=0.05)
