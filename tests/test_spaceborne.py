"""A spaceborne acquisition without stop-and-hop (issue 30 acceptance; docs/physics.md (J3)).

X band at 514 km altitude and 7.6 km/s, 45 deg incidence (slant range 727 km): the echo takes
4.85 ms, during which the antenna moves 36.9 m. The ray-traced trihedral must then be:

- received where the antenna is at each echo's arrival: ``|rx - tx| = v tau`` (within 1 %);
- imaged within 0.1 azimuth resolution cell of its apex by backprojection with both legs;
- imaged ``v R / c`` = 18.43 m behind its apex (within 1 %) when the same data are processed as
  if stop-and-hop held (receiver at the transmitter): the error the tracer's receive leg removes.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.focus import ImageGrid, backproject, ffbp
from sarmitsuba.focus.backprojection import backproject_reference
from sarmitsuba.pipeline import simulate

SPACEBORNE = {"altitude": 514e3, "velocity": 7600.0, "prf": 4000.0, "azimuth_beamwidth": 0.3, "n_pulses": 1501}


@pytest.fixture(scope="module")
def spaceborne():
    return simulate("trihedral", sensor_overrides=SPACEBORNE, focuser="bp", image_size=(112, 48))


def test_the_receiver_moves_v_tau_during_each_echo(spaceborne):
    raw = spaceborne.raw
    tau = raw.rx_time - raw.pulse_time
    slant = 514e3 / math.cos(math.radians(45.0))
    assert np.allclose(tau, 2 * slant / SPEED_OF_LIGHT, rtol=1e-3)
    moved = np.linalg.norm(raw.rx_position - raw.tx_position, axis=1)
    assert np.allclose(moved, 7600.0 * tau, rtol=0.01) and 36.0 < moved.mean() < 38.0


def test_the_trihedral_is_imaged_at_its_apex(spaceborne):
    report = analyze_point_target(spaceborne.image, (0.0, 0.0, 0.0), chip=32)
    assert abs(report.azimuth_error_cells) < 0.1 and abs(report.range_error_cells) < 0.1


def test_processing_as_stop_and_hop_shifts_it_by_v_r_over_c(spaceborne):
    raw, image = spaceborne.raw, spaceborne.image
    hop = dataclasses.replace(raw, rx_position=raw.tx_position.copy(), rx_time=None)
    grid = ImageGrid(origin=image.origin, azimuth_direction=image.azimuth_direction,
                     range_direction=image.range_direction, azimuth=image.azimuth, range=image.range, plane="ground")
    shifted = backproject(hop, grid)
    slant = float(np.linalg.norm(raw.tx_position[raw.n_pulses // 2]))
    expected = -7600.0 * slant / SPEED_OF_LIGHT                 # the target seen from the midpoints, behind
    report = analyze_point_target(shifted, (expected, 0.0), chip=32, search_radius=8)
    assert abs(report.azimuth - expected) < 0.01 * abs(expected), (report.azimuth, expected)


def _pvp_backprojection(signal, pvp, fc, points, oversample=8):
    """A backprojection that reads only the CPHD's PVPs and samples (NGA.STND.0068 1.1, sec. 6):
    each point's delay from TxPos to it and back to the receiver at the echo's arrival (RcvPos moved
    with RcvVel from RcvTime, fixed point), less the SRP's ``(|TxPos - SRP| + |RcvPos - SRP|) / c``,
    read in the line at ``(dTOA - SC0) / SCSS`` (FFT-upsampled, linear) with ``exp(+j 2 pi fc dTOA)``."""
    import scipy.signal
    image = np.zeros(points.shape[0], complex)
    n_up = signal.shape[1] * oversample
    for p in range(signal.shape[0]):
        line = scipy.signal.resample(signal[p].astype(complex), n_up)
        tx, rx, vel, srp = pvp["TxPos"][p], pvp["RcvPos"][p], pvp["RcvVel"][p], pvp["SRPPos"][p]
        out = np.linalg.norm(points - tx, axis=1)
        tau = 2.0 * out / SPEED_OF_LIGHT
        for _ in range(3):
            arrival = pvp["TxTime"][p] + tau
            tau = (out + np.linalg.norm(rx + vel * (arrival - pvp["RcvTime"][p])[:, None] - points,
                                        axis=1)) / SPEED_OF_LIGHT
        dtoa = tau - (np.linalg.norm(tx - srp) + np.linalg.norm(rx - srp)) / SPEED_OF_LIGHT
        where = (dtoa - pvp["SC0"][p]) / pvp["SCSS"][p] * oversample
        image += np.interp(where, np.arange(n_up), line, left=0, right=0) * np.exp(2j * np.pi * fc * dtoa)
    return image / signal.shape[0]


def test_the_cphd_focuses_with_an_independent_backprojection_of_its_pvps(spaceborne, tmp_path):
    """The CPHD written from the spaceborne data, read with sarkit and focused by
    :func:`_pvp_backprojection` in ECEF about the SRP (the trihedral's apex): its RcvPos lies
    ``|RcvVel| (RcvTime - TxTime)`` from TxPos, and the peak lies on the SRP within 0.1 of its own
    resolution in both axes."""
    import sarkit.cphd as skcphd
    import sarkit.wgs84

    from sarmitsuba.formats.cphd import read_cphd, write_cphd
    path = write_cphd(spaceborne.raw, tmp_path / "spaceborne.cphd")
    with open(path, "rb") as f, skcphd.Reader(f) as reader:
        signal, pvp = reader.read_channel("1")
        fc = float(reader.metadata.xmltree.findtext("{*}Channel/{*}Parameters/{*}FxC"))
    back = read_cphd(path)                                              # our reader gives the receive times back
    assert np.allclose(back.rx_time, spaceborne.raw.rx_time, rtol=0.0, atol=1e-9)
    assert np.allclose(back.rx_position, spaceborne.raw.rx_position, rtol=0.0, atol=1e-4)
    moved = np.linalg.norm(pvp["RcvPos"] - pvp["TxPos"], axis=1)
    assert np.allclose(moved, np.linalg.norm(pvp["RcvVel"], axis=1) * (pvp["RcvTime"] - pvp["TxTime"]), rtol=0.01)
    srp = pvp["SRPPos"][0]
    up = sarkit.wgs84.up(sarkit.wgs84.cartesian_to_geodetic(srp))
    along = pvp["TxVel"][len(pvp) // 2] - (pvp["TxVel"][len(pvp) // 2] @ up) * up
    along /= np.linalg.norm(along)
    across = np.cross(up, along)
    mid = len(pvp) // 2
    length = np.linalg.norm(pvp["TxPos"][-1] - pvp["TxPos"][0])
    resolution = 0.886 * SPEED_OF_LIGHT / fc * np.linalg.norm(pvp["TxPos"][mid] - srp) / (2 * length)  # unweighted
    offsets = np.linspace(-6.0, 6.0, 121)                                    # 0.1 m steps
    for axis, expected in ((along, resolution), (across, None)):
        cut = np.abs(_pvp_backprojection(signal, pvp, fc, srp + offsets[:, None] * axis))
        k = int(np.argmax(cut))
        assert 0 < k < offsets.size - 1
        peak = offsets[k] + 0.1 * 0.5 * (cut[k - 1] - cut[k + 1]) / (cut[k - 1] - 2 * cut[k] + cut[k + 1])
        half = offsets[cut ** 2 >= 0.5 * cut[k] ** 2]
        width = half[-1] - half[0]
        assert abs(peak) < 0.1 * width, (peak, width)
        assert (abs(width / expected - 1) < 0.1) if expected else (0.3 < width < 3.0), (width, expected)


def test_omega_k_on_the_midpoint_track_images_it_at_its_apex(spaceborne):
    """Omega-K keeps stop-and-hop but processes the midpoints ``(tx + rx) / 2`` (docs/physics.md (J3)):
    the trihedral, at the scene centre whose echo ``rx_time`` was solved for, lands on its apex; the
    transmitter track alone would put it ``v R / c`` = 18.4 m (~10 cells) behind."""
    from sarmitsuba.pipeline import refocus
    image = refocus(spaceborne.raw, "omegak", window="rect")
    report = analyze_point_target(image, (0.0, 0.0, 0.0), chip=32)
    assert abs(report.azimuth_error_cells) < 0.1, report.azimuth_error_cells


def test_fast_focusers_agree_with_the_per_pixel_reference(spaceborne):
    """The float64 reference moves the receiver to every pixel's own echo arrival (eq. (J3),
    ``trajectory.echo_length``); the fast backprojection does it per pixel tile and FFBP per polar
    sample. Measured: -81 dB and -52 dB NRMSE; a focuser that kept the receiver at the transmitter
    (stop-and-hop) would image the trihedral 10 cells away."""
    image = spaceborne.image
    grid = ImageGrid(origin=image.origin, azimuth_direction=image.azimuth_direction,
                     range_direction=image.range_direction, azimuth=image.azimuth, range=image.range, plane="ground")
    reference = backproject_reference(spaceborne.raw, grid, azimuth_beamwidth=0.3).data
    for focuser, bound in ((backproject, -60.0), (ffbp, -45.0)):
        data = focuser(spaceborne.raw, grid, azimuth_beamwidth=0.3).data
        nrmse = 10 * np.log10(np.sum(np.abs(data - reference) ** 2) / np.sum(np.abs(reference) ** 2))
        assert nrmse < bound, (focuser.__name__, nrmse)
