"""Fast factorised backprojection of bistatic data (:mod:`sarmitsuba.focus.polar_bistatic`, docs/physics.md (F10)).

A receiver on its own platform: polar images on the half range sum ``rho = (|x - T_c| + |x - R_c|) / 2``
and the weighted sine ``s = (V_T . u_T + V_R . u_R) / (|V_T| + |V_R|)``. Raw data are analytic
(:mod:`sarmitsuba.analysis.synthetic`, never the tracer): a unit point target at a known position seen
by an X-band transmitter flying a level straight track along +x (100 m/s, 1000 m up, 1000 m to the
side) and two receivers that differ in every respect:

* ``drone``: 450 m from the scene, west of it, 300 m up, flying north at 15 m/s (its sine sweeps
  fast along range: the case that breaks a coordinate without the receiver's velocity);
* ``beside``: a second aircraft 1200 m up, 100 m/s on a heading 20 deg off the transmitter's.

Truth comes from outside the code under test: the target's own position (closed form: where it was
put), direct backprojection (:func:`~sarmitsuba.focus.backproject`, exact on the range sum) on the
same data and grid, the monostatic sine and range of (F2) by hand, and distances and roots found by
brute force. Each test names the bugs it catches.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sarmitsuba.analysis import synthetic
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus import ImageGrid, backproject, ffbp
from sarmitsuba.focus import polar_bistatic
from sarmitsuba.focus.dispatch import backprojector
from sarmitsuba.focus.ffbp_plan import bistatic_frame, is_bistatic

FC, B, FS, PRF = 9.6e9, 150e6, 180e6, 250.0
TARGET = np.array([0.31, 150.17, 0.0])
RECEIVERS = {"drone": (np.array([-300.0, 0.0, 300.0]), np.array([0.0, 15.0, 0.0])),
             "beside": (np.array([300.0, 600.0, 1200.0]),
                        100.0 * np.array([np.cos(np.radians(20.0)), np.sin(np.radians(20.0)), 0.0]))}


def nrmse_db(image: np.ndarray, reference: np.ndarray) -> float:
    """``10 log10(sum |a - b|^2 / sum |b|^2)``."""
    diff = image.astype(np.complex128) - reference
    return float(10 * np.log10(np.sum(np.abs(diff) ** 2) / np.sum(np.abs(reference) ** 2)))


def acquisition(receiver: str | None, n_pulses: int = 200, beam=None, pattern: float | None = None):
    """RawData of a unit point at TARGET; ``receiver`` None: monostatic. With ``beam`` (an ideal gate
    on the transmitter's along-track angle) and ``pattern`` (L / lambda) the echoes carry the two-way
    pattern ``sinc^2(pattern sin(phi))`` of the transmitter's look."""
    t = (np.arange(n_pulses) - (n_pulses - 1) / 2) / PRF
    v_tx = np.array([100.0, 0.0, 0.0])
    tx = np.array([0.0, 1000.0, 1000.0]) + t[:, None] * v_tx
    rx = tx.copy() if receiver is None else RECEIVERS[receiver][0] + t[:, None] * RECEIVERS[receiver][1]
    length = np.linalg.norm(tx - TARGET, axis=1) + np.linalg.norm(rx - TARGET, axis=1)
    n_samples = 2 * int(np.ceil((np.ptp(length) + 80.0) / C * FS / 2))
    velocity = np.tile(v_tx, (n_pulses, 1))
    raw = synthetic.simulate_point_targets(synthetic.PointTarget(TARGET, 1.0), tx, FC, B, FS,
                                           (length.min() - 40.0) / C, n_samples, prf=PRF, velocity=velocity,
                                           pulse_length=2e-6, beam=beam,
                                           rx_position=None if receiver is None else rx)
    if pattern is not None:
        phi = synthetic.along_track_angle(tx, velocity, TARGET)
        gain = (np.sinc(pattern * np.sin(phi)) ** 2).astype(np.float32)
        raw = dataclasses.replace(raw, data=raw.data * gain[:, None])
    return raw


def grid_around(point, half: float = 10.0, spacing: float = 0.25) -> ImageGrid:
    return ImageGrid.ground(np.round(point), (1.0, 0.0, 0.0), (0.0, -1.0, -1.0), 2 * half, 2 * half, spacing)


# ============================================================================ point targets
@pytest.mark.parametrize("receiver", list(RECEIVERS))
def test_point_target_at_its_position_and_within_40_db_of_direct_backprojection(receiver):
    """Two receivers (a slow close drone, a fast distant aircraft on another heading): the FFBP image
    lies within -40 dB NRMSE of ``backproject``'s and its peak at the target's true position (within
    5 cm) with the unit amplitude (0.1 dB). Catches the monostatic carrier or residual (one leg used
    twice: the point defocuses, 0 dB), swapped transmitter and receiver centres, a sine without the
    receiver's velocity (the drone's image at -9 dB: its residual carrier leaves the range band),
    the polar image's range coefficients taken along the rows (-26 dB on the drone), a wrong sign of
    the lattice shear or of the side of the row roots, an angular band from one leg, and lines run
    along the grid axis that follows the range sum's contours."""
    raw = acquisition(receiver)
    grid = grid_around(TARGET)
    direct, fast = backproject(raw, grid), ffbp(raw, grid)
    assert nrmse_db(fast.data, direct.data) < -40.0
    report = analyze_point_target(fast, TARGET, chip=32)
    assert np.linalg.norm(np.subtract(report.world_position, TARGET)) <= 0.05, report.world_position
    assert 20 * np.log10(report.peak_magnitude) == pytest.approx(0.0, abs=0.1)
    assert fast.metadata["focus"]["monostatic"] is False and "fallback" not in fast.metadata["focus"]


def test_beam_limited_drone_matches_direct_backprojection():
    """Stripmap: a 2.7 deg transmit beam with its tapered pattern in the data, focused with the beam,
    the pattern and a Taylor window (the urban render's settings), 400 pulses so that the target sees
    the whole beam. Within -40 dB of ``backproject``. Catches a beam cut on the weighted sine instead
    of the transmitter's (parts of the beam dropped) and rows reached from the weighted sine."""
    width = 2.7
    pattern = 1.0 / np.sin(np.radians(width) / 2)
    raw = acquisition("drone", 400, beam=synthetic.AzimuthBeam(width, 0.0), pattern=pattern)
    grid = grid_around(TARGET, half=12.0)
    kw = dict(azimuth_beamwidth=width, azimuth_pattern=pattern, window_azimuth="taylor")
    assert nrmse_db(ffbp(raw, grid, **kw).data, backproject(raw, grid, **kw).data) < -40.0


def test_dispatch_focuses_bistatic_data_with_ffbp_itself():
    """``backprojector("ffbp")`` no longer hands bistatic data to direct backprojection."""
    raw = acquisition("beside", 48)
    image = backprojector("ffbp")(raw, grid_around(TARGET, half=4.0, spacing=0.5))
    assert image.metadata["focus"].get("implementation") == "ffbp"
    assert "fallback" not in image.metadata["focus"]


# ============================================================================ the coordinates (F10)
def test_coordinates_reduce_to_the_monostatic_sine_and_range():
    """With the receiver at the transmitter (same positions, same velocity) ``s`` is the along-track
    sine ``(x - c) . v / |x - c|`` and ``rho`` the range ``|x - c|`` of (F2), by hand; and
    :meth:`locate` inverts them to 1e-6 m. Catches a range sum not halved, a sine not normalised by
    the two speeds' sum, and an inverse map that misses the point."""
    raw = acquisition(None, 16)
    grid = grid_around(TARGET)
    frame = polar_bistatic.BistaticFrame(raw.tx_position, raw.rx_position, raw.velocity.mean(axis=0),
                                         raw.velocity.mean(axis=0), grid)
    x = grid.positions().reshape(-1, 3)[::97]
    c = raw.tx_position.mean(axis=0)
    r = np.linalg.norm(x - c, axis=1)
    s, rho = frame.coordinates(x)
    np.testing.assert_allclose(rho, r, rtol=0, atol=1e-9)
    np.testing.assert_allclose(s, (x - c) @ np.array([1.0, 0.0, 0.0]) / r, rtol=0, atol=1e-14)
    d, misfit, valid = frame.locate(s, rho)
    assert valid.all() and np.abs(misfit).max() < 1e-8
    np.testing.assert_allclose(frame.centre + d, x, rtol=0, atol=1e-6)


@pytest.mark.parametrize("receiver", list(RECEIVERS))
def test_row_points_and_pixel_ranges_by_brute_force(receiver):
    """On grid rows: :meth:`pixel_ranges` equals ``(|x - T_c| + |x - R_c|) / 2`` computed point by point,
    and :meth:`row_sines` at a half range sum equals the sine of the row's point found by bisection
    on that range sum (then less the lattice shear). Catches the wrong root of the row's quadratic,
    a wrong leg in ``s`` and a shear applied with the wrong sign."""
    raw = acquisition(receiver, 16)
    grid = grid_around(TARGET)
    frame = bistatic_frame(raw, grid, slice(0, 16))
    frame.shear = (np.array([3e-4, 0.0]), 1500.0)
    rows, cols = slice(5, 9), slice(0, grid.shape[1])
    rho, side = frame.pixel_ranges(grid, rows, cols)
    x = grid.positions()[rows, cols]
    truth = 0.5 * (np.linalg.norm(x - frame.centre, axis=-1) + np.linalg.norm(x - frame.receiver, axis=-1))
    np.testing.assert_allclose(rho, truth, rtol=0, atol=1e-9)
    targets = np.linspace(rho.min() + 1.0, rho.max() - 1.0, 17)
    sines = frame.exact_row_sines(grid, rows, targets, side)
    for i, row in enumerate(range(rows.start, rows.stop)):
        origin = grid.origin + grid.azimuth[row] * grid.azimuth_direction
        for k, level in enumerate(targets):
            lo, hi = grid.range[0] - 5.0, grid.range[-1] + 5.0          # the range sum is monotone on the row
            for _ in range(80):
                mid = 0.5 * (lo + hi)
                value = frame.coordinates(origin + mid * grid.range_direction)[1]
                lo, hi = (mid, hi) if (value - level) * side < 0 else (lo, mid)
            s = frame.coordinates(origin + lo * grid.range_direction)[0]
            assert sines[i, k] == pytest.approx(s - 3e-4 * (level - 1500.0), abs=1e-10)
    kept = np.arange(0, targets.size, polar_bistatic.ROW_STEP)                 # exact there, interpolated between
    np.testing.assert_allclose(frame.row_sines(grid, rows, targets, side)[:, kept], sines[:, kept], rtol=0, atol=1e-12)


# ============================================================================ the monostatic path
def test_monostatic_data_never_take_the_bistatic_path(monkeypatch):
    """Monostatic and continuous-motion data keep the monostatic polar images bit for bit (the bistatic
    frame is never built: the image equals the one focused with it made to raise), so their images
    are the ones before bistatic FFBP existed (checked bit for bit against the previous commit when
    this was written). Catches a monostatic acquisition routed through the slower bistatic code."""
    raw = acquisition(None, 64)
    grid = grid_around(TARGET, half=4.0, spacing=0.5)
    moving = dataclasses.replace(raw, rx_time=raw.pulse_time + 1e-5, rx_position=raw.tx_position + raw.velocity * 1e-5)
    assert not is_bistatic(raw) and not is_bistatic(moving) and is_bistatic(acquisition("drone", 4))
    before = [ffbp(raw, grid).data, ffbp(moving, grid).data]

    def refuse(*args, **kwargs):
        raise AssertionError("a monostatic acquisition built a bistatic frame")
    monkeypatch.setattr(polar_bistatic.BistaticFrame, "__init__", refuse)
    after = [ffbp(raw, grid).data, ffbp(moving, grid).data]
    for a, b in zip(before, after):
        assert np.array_equal(a, b)


def test_800km_bistatic_pair_matches_direct_backprojection():
    """Spaceborne: the transmitter 800 km away (7.5 km/s, 30 deg off nadir), the receiver on a second
    satellite 70 km from it drifting 750 m/s across its track: within -40 dB of ``backproject`` and
    the peak on the target. Catches a float32 half range sum anywhere (a 6 cm ulp at 800 km is 25
    rad at X band). (A residual formed as the plain difference of two 800 km distances would lose
    only 2e-10 m in float64: the cancellation-free form is kept for agreement to rounding.)"""
    n, speed, spacing = 801, 7500.0, 5.0
    look = np.radians(30.0)
    tx = np.zeros((n, 3))
    tx[:, 0] = (np.arange(n) - (n - 1) / 2) * spacing
    tx[:, 1], tx[:, 2] = 800e3 * np.sin(look), 800e3 * np.cos(look)
    rx = tx + np.array([30e3, -60e3, 20e3]) + (np.arange(n) - (n - 1) / 2)[:, None] * np.array([0.0, 0.5, 0.0])
    target = synthetic.PointTarget((0.37, 0.21, 0.0), np.exp(-1.3j))
    length = np.linalg.norm(tx - target.position, axis=1) + np.linalg.norm(rx - target.position, axis=1)
    t_first = length.min() / C - 80 / B
    raw = synthetic.simulate_point_targets([target], tx, FC, B, FS, t_first, int((np.ptp(length) / C + 160 / B) * FS) + 1,
                                           prf=speed / spacing, velocity=np.tile([speed, 0.0, 0.0], (n, 1)),
                                           pulse_length=1e-6, rx_position=rx)
    grid = ImageGrid.ground((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, -1.0, -1.0), 20.0, 20.0, 0.5)
    fast = ffbp(raw, grid)
    assert nrmse_db(fast.data, backproject(raw, grid).data) < -40.0
    report = analyze_point_target(fast, target.position, chip=32)
    assert np.linalg.norm(np.subtract(report.world_position, target.position)) <= 0.05
