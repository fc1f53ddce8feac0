"""Bistatic data: backprojection and FFBP focus them on the range sum, omega-K and RDA refuse them, CPHD
carries them, and :mod:`sarmitsuba.analysis.bistatic` predicts their ground-range resolution.

Geometry: X band (9.6 GHz), 150 MHz, fs 180 MHz, unweighted (rect) range spectrum. The transmitter
flies a straight level track along +x at 100 m/s, 1000 m up, 45 deg incidence on the target; the
receiver is a drone 300 m up flying its own heading (60 deg from east) at 15 m/s, placed so that
the bistatic angle is 48 deg (geometry "A") or 58.5 deg ("B"). There the bistatic ground-range
resolution (1.73 m) is 22 % coarser than the transmitter's (or receiver's) monostatic one (1.41 m),
so a formula that uses one leg twice is caught.

Truth comes from outside the code under test: the point's own position; the range sum's ground
gradient by finite differences (its steepest direction and its rate give the resolution cell,
c / B per rate); the law of cosines for the bistatic angle; the image's measured -3 dB width
(IRW factor 0.886 of the rect window, :func:`sarmitsuba.focus.windows.impulse_response_width`);
the monostatic c / (2 B sin(theta)) by hand; and, for CPHD, a sum over the file's own PVPs.
"""
from __future__ import annotations

import importlib

import numpy as np
import pytest

from sarmitsuba.analysis.bistatic import (bistatic_angle, bistatic_bisector, bistatic_ground_range_resolution,
                                          ground_range_direction)
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.analysis.synthetic import PointTarget, simulate_point_targets
from sarmitsuba.cli import main
from sarmitsuba.core import georef
from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus import backproject, ffbp, omega_k, range_doppler
from sarmitsuba.focus.grid import ImageGrid
from sarmitsuba.focus.polar import GeometryNotSupported
from sarmitsuba.focus.stripmap import stripmap_geometry
from widths import minus_3db_width

FC, B, FS, PRF = 9.6e9, 150e6, 180e6, 1000.0
TARGET = np.array([2.5, -1.5, 0.0])
#: Receiver placement (azimuth from east [deg], ground distance [m]) at 300 m height: beta 48, 58.5 deg.
GEOMETRIES = {"A": (20.0, 300.0), "B": (10.0, 400.0)}
RECT_IRW = 0.8859          # -3 dB width of sinc^2 in 1 / B (the rect window's IRW factor)


def acquisition(geometry: str | None, n_pulses: int):
    """RawData of a unit point target at TARGET: bistatic geometry "A" or "B", or monostatic (None)."""
    t = (np.arange(n_pulses) - (n_pulses - 1) / 2) / PRF
    v_tx = np.array([100.0, 0.0, 0.0])
    tx = TARGET + np.array([0.0, 1000.0, 1000.0]) + t[:, None] * v_tx
    if geometry is None:
        rx = tx.copy()
    else:
        azimuth, distance = np.radians(GEOMETRIES[geometry][0]), GEOMETRIES[geometry][1]
        v_rx = 15.0 * np.array([np.cos(np.radians(60.0)), np.sin(np.radians(60.0)), 0.0])
        rx = TARGET + np.array([distance * np.cos(azimuth), distance * np.sin(azimuth), 300.0]) + t[:, None] * v_rx
    length = np.linalg.norm(tx - TARGET, axis=1) + np.linalg.norm(rx - TARGET, axis=1)
    n_samples = 2 * int(np.ceil((np.ptp(length) + 80.0) / C * FS / 2))
    return simulate_point_targets(PointTarget(TARGET, 1.0), tx, FC, B, FS, (length.min() - 40.0) / C, n_samples,
                                  prf=PRF, velocity=np.tile(v_tx, (n_pulses, 1)), pulse_length=2e-6,
                                  rx_position=None if geometry is None else rx)


def range_sum_gradient(tx, rx, point):
    """(unit ground direction, rate [m/m]) of the steepest ground descent of the range sum
    |T - X| + |R - X| at ``point``, by central differences over 3600 ground directions."""
    def total(x):
        return np.linalg.norm(tx - x, axis=-1) + np.linalg.norm(rx - x, axis=-1)
    angles = np.radians(np.arange(3600) / 10.0)
    dirs = np.column_stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)])
    h = 1e-3
    rate = (total(point - h * dirs) - total(point + h * dirs)) / (2 * h)
    k = int(np.argmax(rate))
    return dirs[k], float(rate[k])


# -- the module's geometry against independent truth ----------------------------------------------
@pytest.mark.parametrize("geometry", list(GEOMETRIES) + [None])
def test_angle_bisector_and_ground_resolution_match_the_range_sums_gradient(geometry):
    """beta by the law of cosines; the ground direction and cell c / (B |grad_ground L|) by finite
    differences of the range sum; monostatic: c / (2 B sin 45 deg) and beta = 0."""
    raw = acquisition(geometry, 3)
    tx, rx = raw.tx_position[1], raw.rx_position[1]
    a, b, c = np.linalg.norm(tx - TARGET), np.linalg.norm(rx - TARGET), np.linalg.norm(tx - rx)
    beta = np.arccos(np.clip((a * a + b * b - c * c) / (2 * a * b), -1, 1))
    assert bistatic_angle(tx, rx, TARGET) == pytest.approx(beta, abs=1e-7)
    direction, rate = range_sum_gradient(tx, rx, TARGET)
    np.testing.assert_allclose(ground_range_direction(tx, rx, TARGET), direction, atol=2e-3)
    assert bistatic_ground_range_resolution(B, tx, rx, TARGET) == pytest.approx(C / (B * rate), rel=1e-5)
    bisector = bistatic_bisector(tx, rx, TARGET)          # equal angles to both legs
    assert bisector @ (tx - TARGET) / a == pytest.approx(bisector @ (rx - TARGET) / b, abs=1e-12)
    if geometry is None:
        assert bistatic_angle(tx, rx, TARGET) == pytest.approx(0.0, abs=1e-7)
        assert bistatic_ground_range_resolution(B, tx, rx, TARGET) == pytest.approx(
            C / (2 * B * np.sin(np.radians(45.0))), rel=1e-5)
    else:
        assert np.degrees(beta) == pytest.approx({"A": 47.9, "B": 58.5}[geometry], abs=0.1)


# -- backprojection: position and resolution -----------------------------------------------------
@pytest.mark.parametrize("geometry", list(GEOMETRIES))
def test_backprojection_puts_a_bistatic_point_at_its_position(geometry):
    """300 pulses (0.3 s): the point-target analysis finds the peak within 0.05 m of the target, with
    the unit amplitude (within 0.1 dB)."""
    raw = acquisition(geometry, 300)
    grid = ImageGrid.ground(TARGET, (1, 0, 0), (0, -1, -1), 30.0, 30.0, 0.2)
    report = analyze_point_target(backproject(raw, grid), TARGET)
    assert np.linalg.norm(np.subtract(report.world_position, TARGET)) <= 0.05, report.world_position
    assert 20 * np.log10(report.peak_magnitude) == pytest.approx(0.0, abs=0.1)


@pytest.mark.parametrize("geometry", list(GEOMETRIES) + [None])
def test_ground_range_irw_along_the_bisector_is_the_bistatic_resolution(geometry):
    """The image sampled every 1 cm along the ground direction of steepest range-sum change (found by
    finite differences) through the target: its -3 dB width is 0.886 rho_g within 5 %, rho_g from
    :func:`bistatic_ground_range_resolution` (monostatic: c / (2 B sin 45 deg) by hand). 20 pulses:
    the azimuth response (about 30 m) does not narrow the cut. The peak sits within 0.05 m."""
    raw = acquisition(geometry, 20)
    tx, rx = raw.tx_position.mean(axis=0), raw.rx_position.mean(axis=0)
    direction, _ = range_sum_gradient(tx, rx, TARGET)
    offsets = np.arange(-600, 601) * 0.01
    line = ImageGrid(TARGET, np.cross([0.0, 0.0, 1.0], direction), direction, np.array([0.0]), offsets)
    irw, peak = minus_3db_width(offsets, backproject(raw, line).data[0])
    expected = RECT_IRW * (C / (2 * B * np.sin(np.radians(45.0))) if geometry is None
                           else bistatic_ground_range_resolution(B, tx, rx, TARGET))
    assert irw == pytest.approx(expected, rel=0.05), (irw, expected)
    assert abs(peak) <= 0.05


# -- the focusers that cannot focus bistatic data refuse them ------------------------------------
def refusal_words(message: str) -> None:
    assert message.startswith("bistatic data: the receiver is not at the transmitter"), message
    assert "monostatic" in message and "R_t + R_r" in message and "backproject" in message, message


@pytest.mark.parametrize("focuser", ["omega_k", "range_doppler"])
def test_omega_k_and_range_doppler_refuse_bistatic_data_naming_backproject(focuser):
    raw = acquisition("A", 64)
    with pytest.raises(GeometryNotSupported) as info:
        {"omega_k": omega_k, "range_doppler": range_doppler}[focuser](raw)
    refusal_words(str(info.value))


def test_ffbp_focuses_bistatic_data_where_backprojection_does():
    """FFBP takes bistatic data (polar images on the range sum, docs/physics.md (F10)): geometry "A",
    300 pulses, its image within -40 dB of backproject's and the peak on the target (0.05 m)."""
    raw = acquisition("A", 300)
    grid = ImageGrid.ground(TARGET, (1, 0, 0), (0, -1, -1), 30.0, 30.0, 0.2)
    fast, direct = ffbp(raw, grid), backproject(raw, grid)
    diff = np.sum(np.abs(fast.data.astype(complex) - direct.data) ** 2) / np.sum(np.abs(direct.data) ** 2)
    assert 10 * np.log10(diff) < -40.0
    report = analyze_point_target(fast, TARGET)
    assert np.linalg.norm(np.subtract(report.world_position, TARGET)) <= 0.05, report.world_position


@pytest.mark.parametrize("focuser", [omega_k, range_doppler])
def test_a_monostatic_geometry_given_with_bistatic_data_is_refused_too(focuser):
    """The geometry of the monostatic twin, passed in, skips stripmap_geometry's check: the focuser's own
    check still refuses."""
    geometry = stripmap_geometry(acquisition(None, 64))
    with pytest.raises(GeometryNotSupported) as info:
        focuser(acquisition("A", 64), geometry=geometry)
    refusal_words(str(info.value))


@pytest.mark.parametrize("algorithm", ["omegak", "rda"])
def test_cli_focus_of_bistatic_data_exits_2_with_one_line(tmp_path, capsys, algorithm):
    path = acquisition("B", 64).save(tmp_path / "raw.npz")
    assert main(["focus", str(path), "--algorithm", algorithm, "--out", str(tmp_path / "out"),
                 "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and 'File "' not in err and "\n" not in err, err
    refusal_words(err.removeprefix("error: "))


# -- CPHD ---------------------------------------------------------------------------------------
REF = georef.GeoReference(48.1, 11.6, 520.0)


def enu_to_ecef_by_hand(points):
    """Local ENU [m] at REF to ECEF [m]: the origin through pyproj, the axes by formula
    (tests/test_sicd_slant.py's oracle, docs/physics.md (GEO1))."""
    from test_sicd_slant import enu_to_ecef_by_hand as by_hand
    return by_hand(points, REF.latitude_deg, REF.longitude_deg, REF.height_m)


@pytest.fixture(scope="module")
def bistatic_cphd(tmp_path_factory):
    """(RawData of geometry "A", 200 pulses; the CPHD file written from it)."""
    pytest.importorskip("sarkit.cphd")
    from sarmitsuba.formats.cphd import write_cphd
    raw = acquisition("A", 200)
    return raw, write_cphd(raw, tmp_path_factory.mktemp("bistatic") / "raw.cphd", REF)


@pytest.mark.filterwarnings("ignore:Call to deprecated class CPHDReader:DeprecationWarning")
def test_cphd_writes_two_antennas_as_bistatic_and_passes_sarkit_and_sarpy(bistatic_cphd):
    """TxPos / RcvPos are the transmitter and the receiver (ECEF by hand, 1 mm), RcvVel the drone's
    15 m/s (not the transmitter's 100 m/s), CollectType BISTATIC in sarkit's and sarpy's reading,
    ReferenceGeometry/Bistatic's angle the law-of-cosines angle at the SRP; both checkers pass."""
    import sarkit.cphd as skcphd
    from sarmitsuba.formats.cphd import check_cphd
    raw, path = bistatic_cphd
    with open(path, "rb") as f, skcphd.Reader(f) as reader:
        _, pvp = reader.read_channel("1")
        tree = reader.metadata.xmltree
    np.testing.assert_allclose(pvp["TxPos"], enu_to_ecef_by_hand(raw.tx_position), atol=1e-3)
    np.testing.assert_allclose(pvp["RcvPos"], enu_to_ecef_by_hand(raw.rx_position), atol=1e-3)
    assert np.all(np.linalg.norm(pvp["TxPos"] - pvp["RcvPos"], axis=1) > 1000.0)
    np.testing.assert_allclose(np.linalg.norm(pvp["TxVel"], axis=1), 100.0, rtol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(pvp["RcvVel"], axis=1), 15.0, rtol=1e-6)
    assert tree.findtext("{*}CollectionID/{*}CollectType") == "BISTATIC"
    v = raw.n_pulses // 2
    legs = pvp["TxPos"][v] - pvp["SRPPos"][v], pvp["RcvPos"][v] - pvp["SRPPos"][v]
    beta = np.degrees(np.arccos(legs[0] @ legs[1] / np.linalg.norm(legs[0]) / np.linalg.norm(legs[1])))
    assert float(tree.findtext("{*}ReferenceGeometry/{*}Bistatic/{*}BistaticAngle")) == pytest.approx(beta, abs=1e-6)
    assert tree.find("{*}ReferenceGeometry/{*}Monostatic") is None
    assert check_cphd(path) == []
    pytest.importorskip("sarpy")
    import sarpy.io.phase_history
    from sarpy.consistency.cphd_consistency import CphdConsistency
    assert sarpy.io.phase_history.open(str(path)).cphd_meta.CollectionID.CollectType == "BISTATIC"
    con = CphdConsistency.from_file(str(path))
    con.check()
    assert not con.failures(), str(con.failures())[:2000]


def test_the_srp_of_bistatic_data_without_a_scene_centre_is_on_the_windows_middle_range_sum(bistatic_cphd):
    """No scene centre in the metadata: the SRP is the ground point right of the transmitter whose range
    sum (from the file's TxPos, RcvPos and SRPPos) is the middle of the fast-time window (within
    0.5 m of a 82 m window), and the ImageArea holds the target. Catches the monostatic fallback
    (the Tx-Rcv midpoint as one antenna: 40 m of range sum off, the target 100 m outside the area)."""
    import sarkit.cphd as skcphd
    raw, path = bistatic_cphd
    with open(path, "rb") as f, skcphd.Reader(f) as reader:
        _, pvp = reader.read_channel("1")
        xml = skcphd.XmlHelper(reader.metadata.xmltree)
    v = raw.n_pulses // 2
    total = np.linalg.norm(pvp["TxPos"][v] - pvp["SRPPos"][v]) + np.linalg.norm(pvp["RcvPos"][v] - pvp["SRPPos"][v])
    assert total == pytest.approx(0.5 * C * (raw.fast_time[0] + raw.fast_time[-1]), abs=0.5)
    (x1, y1), (x2, y2) = (xml.load(f"{{*}}SceneCoordinates/{{*}}ImageArea/{{*}}{k}") for k in ("X1Y1", "X2Y2"))
    assert x1 < TARGET[0] < x2 and y1 < TARGET[1] < y2, (x1, y1, x2, y2)


def test_cphd_reads_back_as_stop_and_hop_bistatic_data_that_focus_alike(bistatic_cphd):
    """read_cphd gives rx_time None (a second antenna, not one that moved during the echo) and the
    positions (1 mm): backproject of the read-back data puts the point within 0.05 m."""
    from sarmitsuba.formats.cphd import read_cphd
    raw, path = bistatic_cphd
    back = read_cphd(path)
    assert back.rx_time is None
    np.testing.assert_allclose(back.tx_position, raw.tx_position, atol=1e-3)
    np.testing.assert_allclose(back.rx_position, raw.rx_position, atol=1e-3)
    grid = ImageGrid.ground(TARGET, (1, 0, 0), (0, -1, -1), 30.0, 30.0, 0.2)
    report = analyze_point_target(backproject(back, grid), TARGET)
    assert np.linalg.norm(np.subtract(report.world_position, TARGET)) <= 0.05, report.world_position


def test_a_backprojection_from_the_cphd_fields_alone_focuses_on_the_point(bistatic_cphd):
    """Every vector's samples at the point's dTOA (range sum from TxPos and RcvPos less the SRP's, SC0 +
    s SCSS) phased by exp(-j SGN 2 pi fc dTOA) (CPHD 1.1 sec. 4, 6), summed over a 0.6 m square every
    2 cm: the peak is within 0.05 m of the target with 90 % of the incoherent sum."""
    import sarkit.cphd as skcphd
    from scipy.signal import resample
    _, path = bistatic_cphd
    with open(path, "rb") as f, skcphd.Reader(f) as reader:
        signal, pvp = reader.read_channel("1")
        sgn = skcphd.XmlHelper(reader.metadata.xmltree).load("{*}Global/{*}SGN")
    fc, up = 0.5 * (pvp["FX1"][0] + pvp["FX2"][0]), 8
    fine = resample(signal.astype(np.complex128), signal.shape[1] * up, axis=1)
    offsets = np.arange(-15, 16) * 0.02
    local = TARGET + np.stack(np.meshgrid(offsets, offsets, [0.0], indexing="ij"), axis=-1).reshape(-1, 3)
    points = enu_to_ecef_by_hand(local)
    srp = np.linalg.norm(pvp["TxPos"] - pvp["SRPPos"], axis=1) + np.linalg.norm(pvp["RcvPos"] - pvp["SRPPos"], axis=1)
    coherent, incoherent = np.zeros(len(points), complex), np.zeros(len(points))
    for v in range(signal.shape[0]):
        total = np.linalg.norm(points - pvp["TxPos"][v], axis=1) + np.linalg.norm(points - pvp["RcvPos"][v], axis=1)
        dtoa = (total - srp[v]) / C
        index = (dtoa - pvp["SC0"][v]) / pvp["SCSS"][v] * up
        k = np.clip(np.floor(index).astype(int), 0, fine.shape[1] - 2)
        value = fine[v, k] * (1 - (index - k)) + fine[v, k + 1] * (index - k)
        coherent += value * np.exp(-1j * sgn * 2 * np.pi * fc * dtoa)
        incoherent += np.abs(value)
    best = int(np.argmax(np.abs(coherent)))
    assert np.linalg.norm(local[best] - TARGET) <= 0.05, local[best]
    assert abs(coherent[best]) >= 0.9 * incoherent[best]


def test_ffbp_plan_takes_bistatic_data_and_its_float64_operator_refuses_them():
    """ffbp's plan (check_knobs, shared with the float64 operator) lets bistatic data through; the
    operator, whose polar maps are the monostatic ones, refuses them with the common message."""
    plan = importlib.import_module("sarmitsuba.focus.ffbp_plan")
    raw = acquisition("B", 8)
    assert plan.check_knobs(raw, 4, 2.0, 2)["subaperture"] == 4 and plan.is_bistatic(raw)
    from sarmitsuba.focus.ffbp_linear import ffbp_operator
    with pytest.raises(GeometryNotSupported) as info:
        ffbp_operator(raw, ImageGrid.ground(TARGET, (1, 0, 0), (0, -1, -1), 4.0, 4.0, 0.5))
    refusal_words(str(info.value))


def test_a_receiver_flying_in_formation_reads_back_as_a_second_antenna(tmp_path):
    """A receiver 50 m beside the transmitter with the same velocity: CollectType BISTATIC, so the reader
    does not take it for one antenna that moved during the echo (rx_time stays None)."""
    pytest.importorskip("sarkit.cphd")
    import dataclasses
    from sarmitsuba.formats.cphd import read_cphd, write_cphd
    raw = acquisition(None, 16)
    raw = dataclasses.replace(raw, rx_position=raw.tx_position + np.array([0.0, 50.0, 0.0]))
    back = read_cphd(write_cphd(raw, tmp_path / "raw.cphd", REF))
    assert back.rx_time is None
    np.testing.assert_allclose(back.rx_position, raw.rx_position, atol=1e-3)
