"""Fast factorised backprojection (:func:`sarmitsuba.focus.ffbp`) against direct backprojection and closed forms.

Raw data are analytic (:mod:`sarmitsuba.analysis.synthetic`, float64, never the tracer): point targets of
known complex amplitude seen from straight, squinted, curved and 800 km tracks. Two kinds of truth:

* the direct sum :func:`~sarmitsuba.focus.backproject` on the same data and grid (NRMSE bound);
* closed forms: -3 dB widths ``0.886 c / (2 B)`` (slant, over the ground range projection) and
  ``0.886 lambda R / (2 L)``, rect PSLR -13.26 dB, Taylor's -35 dB design level, the peak at the
  target's amplitude (normalisation, with the antenna pattern divided out) and its phase, read
  with :func:`sarmitsuba.analysis.point_target.analyze_point_target` and the true carrier
  (:func:`~sarmitsuba.analysis.point_target.carrier_ramp`).

Each test names the bug it is there to catch.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest

from sarmitsuba.analysis import synthetic
from sarmitsuba.analysis.point_target import analyze_point_target, carrier_ramp
from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus import ImageGrid, apply_range_window, backproject, ffbp
from sarmitsuba.focus.windows import pslr_theory

FC, B, FS = 9.6e9, 150e6, 180e6
WAVELENGTH = C / FC
TARGET = synthetic.PointTarget((0.31, -0.17, 0.0), 0.8 * np.exp(0.9j))
SECOND = synthetic.PointTarget((-3.1, 2.4, 0.0), 0.5 * np.exp(-2.0j))


def nrmse_db(image: np.ndarray, reference: np.ndarray) -> float:
    """``10 log10(sum |a - b|^2 / sum |b|^2)``."""
    diff = image.astype(np.complex128) - reference
    return float(10 * np.log10(np.sum(np.abs(diff) ** 2) / np.sum(np.abs(reference) ** 2)))


def grid_around(point, half: float, spacing: float) -> ImageGrid:
    """Ground grid centred on ``point``, track along +x, sensor on +y looking toward -y."""
    return ImageGrid.ground(point, (1.0, 0.0, 0.0), (0.0, -1.0, -1.0), 2 * half, 2 * half, spacing)


def track_data(targets, positions: np.ndarray, velocities: np.ndarray, *, prf: float, beam=None,
               pattern: float | None = None, range_window: str = "rect") -> synthetic.RawData:
    """Range-compressed echoes of ``targets`` from the antenna ``positions``, with a fast-time window
    that holds them all; with ``pattern`` (L / lambda) each echo also carries the two-way pattern
    ``sinc^2(pattern sin(phi - squint))`` of the pulse's look at the target."""
    lengths = [synthetic.two_way_length(positions, t.position) for t in targets]
    t_first = min(l.min() for l in lengths) / C - 80 / B
    n = int((max(l.max() for l in lengths) / C + 80 / B - t_first) * FS) + 1
    raw = synthetic.simulate_point_targets(targets, positions, FC, B, FS, t_first, n, prf=prf, velocity=velocities,
                                           pulse_length=1e-6, beam=beam, range_window=range_window)
    if pattern is None:
        return raw
    data = np.zeros_like(raw.data)
    for t in targets:
        one = synthetic.simulate_point_targets(t, positions, FC, B, FS, t_first, n, prf=prf, velocity=velocities,
                                               pulse_length=1e-6, beam=beam, range_window=range_window)
        phi = synthetic.along_track_angle(positions, velocities, t.position) - np.radians(beam.squint)
        data += one.data * (np.sinc(pattern * np.sin(phi)) ** 2).astype(np.float32)[:, None]
    return dataclasses.replace(raw, data=data)


def straight(n: int, spacing: float, range_: float, incidence_deg: float, speed: float = 100.0):
    """A level straight track along +x centred over x = 0 at slant range ``range_`` from the origin."""
    track = synthetic.straight_track(n, speed / spacing, speed, center=(
        0.0, range_ * np.sin(np.radians(incidence_deg)), range_ * np.cos(np.radians(incidence_deg))))
    return track.position, track.velocity, track.prf


# ============================================================================ fixtures
def _spotlight(n_targets: int):
    positions, velocities, prf = straight(401, 0.25, 5000.0, 50.0)
    raw = track_data([TARGET, SECOND][:n_targets], positions, velocities, prf=prf)
    grid = grid_around((0.0, 0.0, 0.0), 10.0, 0.25)
    return raw, grid, backproject(raw, grid), ffbp(raw, grid)


@pytest.fixture(scope="module", params=[1, 2], ids=["one target", "two targets"])
def spotlight(request):
    """Every pulse sees the targets (no beam): 401 pulses over 100 m at 5 km, rect windows; one
    target or two."""
    return _spotlight(request.param)


@pytest.fixture(scope="module")
def one_target():
    """The spotlight data with one target (for the closed forms: a second one's sidelobes would
    cross its cuts)."""
    return _spotlight(1)


BEAM, SQUINT = 0.8, 0.0
PATTERN = 1.0 / np.sin(np.radians(BEAM) / 2)          # first nulls on the traced beam's edges


@pytest.fixture(scope="module")
def beam_limited():
    """Stripmap: a 0.8 deg beam with the tapered pattern in the data, 601 pulses over 150 m, so the
    targets see the whole beam (70 m); focused with the beam, the pattern and a Taylor window."""
    positions, velocities, prf = straight(601, 0.25, 5000.0, 50.0)
    beam = synthetic.AzimuthBeam(BEAM, SQUINT)
    raw = track_data([TARGET, SECOND], positions, velocities, prf=prf, beam=beam, pattern=PATTERN)
    grid = grid_around((0.0, 0.0, 0.0), 10.0, 0.25)
    kw = dict(azimuth_beamwidth=BEAM, azimuth_pattern=PATTERN, window_azimuth="taylor")
    return raw, grid, backproject(raw, grid, **kw), ffbp(raw, grid, **kw), kw


# ============================================================================ against direct backprojection
def test_spotlight_matches_direct_backprojection(spotlight):
    """Catches any wrong phase in the factorisation (carrier sign or reference range at the last
    step, a wrong sub-aperture centre or polar map): each throws the NRMSE to about 0 dB."""
    raw, grid, direct, fast = spotlight
    assert nrmse_db(fast.data, direct.data) < -38.0


def test_beam_limited_matches_direct_backprojection(beam_limited):
    """Catches wrong beam gating or window weights in the first stage (a gate on the sub-aperture
    centre instead of each pulse, the window evaluated at the wrong sine): -20 dB or worse."""
    raw, grid, direct, fast, _ = beam_limited
    assert nrmse_db(fast.data, direct.data) < -40.0


def test_ideal_beam_gates_each_pulse():
    """An ideal (all or nothing) beam in the data and in the focusing, rect window: the pulses are
    gated per pixel and pulse, not per sub-aperture. A gate evaluated at the sub-aperture centre
    for all its pulses misses up to half a sub-aperture at each beam edge (-20 dB); the per-pulse
    gate, interpolated from the polar samples, leaves steps of single pulses (documented: about
    -33 dB at the default 16 pulses, -39 dB at 32)."""
    positions, velocities, prf = straight(601, 0.25, 5000.0, 50.0)
    raw = track_data([TARGET, SECOND], positions, velocities, prf=prf, beam=synthetic.AzimuthBeam(BEAM, 0.0))
    grid = grid_around((0.0, 0.0, 0.0), 10.0, 0.25)
    direct = backproject(raw, grid, azimuth_beamwidth=BEAM)
    assert nrmse_db(ffbp(raw, grid, azimuth_beamwidth=BEAM).data, direct.data) < -30.0
    assert nrmse_db(ffbp(raw, grid, azimuth_beamwidth=BEAM, subaperture=32).data, direct.data) < -36.0


@pytest.mark.parametrize("squint", [-12.0, 20.0])
def test_squinted_beam_matches_direct_backprojection(squint):
    """Squinted stripmap (the beam centre at ``squint`` forward): catches a squint ignored in the
    beam or in the polar sines' span (the image would be cut, 0 dB), and checks the position."""
    positions, velocities, prf = straight(481, 0.25, 5000.0, 45.0)
    # targets at the beam centre of the middle pulse: shifted along track by R tan(squint)
    shift = 5000.0 * np.tan(np.radians(squint))
    target = synthetic.PointTarget((shift + 0.21, -0.13, 0.0), 1.0 * np.exp(0.4j))
    raw = track_data([target], positions, velocities, prf=prf, beam=synthetic.AzimuthBeam(1.0, squint),
                     pattern=1.0 / np.sin(np.radians(0.5)))
    grid = grid_around((shift, 0.0, 0.0), 5.0, 0.25)
    kw = dict(azimuth_beamwidth=1.0, squint=squint, azimuth_pattern=1.0 / np.sin(np.radians(0.5)),
              window_azimuth="taylor")
    direct, fast = backproject(raw, grid, **kw), ffbp(raw, grid, **kw)
    assert nrmse_db(fast.data, direct.data) < -38.0
    report = analyze_point_target(fast, target.position, chip=32,
                                  carrier=carrier_ramp(raw, fast, target.position))
    reference = analyze_point_target(direct, target.position, chip=32,
                                     carrier=carrier_ramp(raw, direct, target.position))
    assert abs(report.azimuth - reference.azimuth) < 0.01 and abs(report.range - reference.range) < 0.01
    assert report.peak_magnitude == pytest.approx(reference.peak_magnitude, rel=0.01)


def test_curved_track_focuses_exactly():
    """A track that is neither straight nor level (2 m lateral and 1 m vertical wander, the velocity
    turning): a straight-track factorisation would defocus (the wander is 60 wavelengths); FFBP's
    frames follow the track. Catches a polar map or sub-aperture frame that assumes a line (the
    mean direction used for the offsets, the first pulse as the centre)."""
    n, spacing = 401, 0.25
    x = (np.arange(n) - n // 2) * spacing
    k = 2 * np.pi / 70.0
    positions = np.stack([x, 3830.0 + 2.0 * np.sin(k * x), 3214.0 + 1.0 * np.cos(0.7 * k * x)], axis=1)
    velocities = 100.0 * np.stack([np.ones(n), 2.0 * k * np.cos(k * x), -0.7 * k * np.sin(0.7 * k * x)], axis=1)
    raw = track_data([TARGET, SECOND], positions, velocities, prf=100.0 / spacing)
    grid = grid_around((0.0, 0.0, 0.0), 8.0, 0.25)
    direct, fast = backproject(raw, grid), ffbp(raw, grid)
    assert nrmse_db(fast.data, direct.data) < -38.0
    report = analyze_point_target(fast, TARGET.position, chip=48, carrier=carrier_ramp(raw, fast, TARGET.position))
    assert abs(report.azimuth_error) < 0.02 and abs(report.range_error) < 0.02
    assert report.peak_magnitude == pytest.approx(abs(TARGET.amplitude), rel=0.02)


def test_800km_matches_direct_backprojection():
    """Spaceborne range (800 km, 30 deg off nadir, C band geometry at X band): the hybrid precision
    of the first stage (float64 geometry, float32 residuals) and the float64 polar coordinates.
    A float32 range or carrier anywhere would lose the focus (a 6 cm ulp is 12 rad)."""
    positions, velocities, prf = straight(801, 5.0, 800e3, 30.0, speed=7500.0)
    target = synthetic.PointTarget((0.37, 0.21, 0.0), np.exp(-1.3j))
    raw = track_data([target], positions, velocities, prf=prf)
    grid = grid_around((0.0, 0.0, 0.0), 10.0, 0.5)
    direct, fast = backproject(raw, grid), ffbp(raw, grid)
    assert nrmse_db(fast.data, direct.data) < -38.0
    report = analyze_point_target(fast, target.position, chip=32, carrier=carrier_ramp(raw, fast, target.position))
    r0 = np.linalg.norm(positions[n_mid := positions.shape[0] // 2] - target.position)
    assert report.irw_azimuth == pytest.approx(0.886 * WAVELENGTH * r0 / (2 * 4000.0), rel=0.05)
    assert abs(report.azimuth_error) < 0.05 and abs(report.range_error) < 0.05
    assert abs(np.angle(np.exp(1j * np.radians(report.predicted_phase_deg)) / target.amplitude)) < np.radians(2.0)
    assert n_mid == 400


def test_fast_time_window_ending_inside_the_grid():
    """The recorded echoes stop short of the far range: the polar images stop there too, and pixels
    beyond read zeros, as in ``backproject`` (masked, never clamped onto the last samples). Catches
    an interpolation that reads past the end of a polar image's range line."""
    positions, velocities, prf = straight(201, 0.25, 5000.0, 50.0)
    raw = track_data([TARGET], positions, velocities, prf=prf)
    keep = int(0.55 * raw.n_samples)                    # ends 8 m of slant range past the target
    raw = dataclasses.replace(raw, data=np.ascontiguousarray(raw.data[:, :keep]), fast_time=raw.fast_time[:keep])
    grid = grid_around((0.0, 0.0, 0.0), 45.0, 0.5)       # reaches 26 m of slant range past the cut
    direct, fast = backproject(raw, grid), ffbp(raw, grid)
    far = np.abs(direct.data).max(axis=0) == 0
    # beyond the cut only the ringing of the data's hard edge in the band-limited polar lines is left
    assert far.any() and np.abs(fast.data[:, far]).max() < 1e-2 * np.abs(direct.data).max()
    # near the cut the polar images' range lines smooth that edge: compare 5 m (ground) inside it
    edge = np.flatnonzero(far)[0]
    inside = slice(0, edge - 10)
    assert nrmse_db(fast.data[:, inside], direct.data[:, inside]) < -38.0
    assert nrmse_db(fast.data, direct.data) < -28.0


# ============================================================================ closed forms
def test_rect_impulse_response_closed_forms(one_target):
    """IRW ``0.886 c / (2 B)`` over sin(incidence) and ``0.886 lambda R / (2 L)``, PSLR -13.26 dB in
    both cuts, peak ``|a|`` and its phase: catches a wrong normalisation (1 / n_pulses), a range or
    angle interpolation that broadens or shifts the response, a wrong phase at the peak."""
    raw, grid, _, fast = one_target
    report = analyze_point_target(fast, TARGET.position, chip=64, carrier=carrier_ramp(raw, fast, TARGET.position))
    r0 = float(np.linalg.norm(raw.tx_position[raw.n_pulses // 2] - TARGET.position))
    sin_inc = np.sin(np.radians(50.0))
    assert report.irw_range == pytest.approx(0.886 * C / (2 * B) / sin_inc, rel=0.03)
    assert report.irw_azimuth == pytest.approx(0.886 * WAVELENGTH * r0 / (2 * 100.0), rel=0.03)
    for pslr in (report.pslr_azimuth_db, report.pslr_range_db):
        assert pslr == pytest.approx(pslr_theory("rect"), abs=0.5)
    assert report.peak_magnitude == pytest.approx(abs(TARGET.amplitude), rel=0.02)
    assert abs(report.azimuth_error) < 0.02 and abs(report.range_error) < 0.02
    phase = np.radians(report.predicted_phase_deg)
    assert abs(np.angle(np.exp(1j * phase) / TARGET.amplitude)) < np.radians(2.0)


def test_beam_limited_peak_divides_out_the_pattern(beam_limited):
    """With the beam, the tapered pattern in the data and a Taylor window, the target still peaks at
    its amplitude: catches a normalisation without the pattern (the peak would be the pattern's
    mean, about -2.5 dB here) or without the window, and checks the width against direct BP."""
    raw, grid, direct, fast, _ = beam_limited
    report = analyze_point_target(fast, TARGET.position, chip=64, carrier=carrier_ramp(raw, fast, TARGET.position))
    reference = analyze_point_target(direct, TARGET.position, chip=64,
                                     carrier=carrier_ramp(raw, direct, TARGET.position))
    assert report.peak_magnitude == pytest.approx(abs(TARGET.amplitude), rel=0.01)
    assert report.irw_azimuth == pytest.approx(reference.irw_azimuth, rel=0.01)
    # sidelobes near -60 dB: FFBP's own interpolation error (about -47 dB of the image) shows there
    assert report.pslr_azimuth_db < -45.0
    assert report.pslr_azimuth_db == pytest.approx(reference.pslr_azimuth_db, abs=2.5)
    assert abs(np.angle(np.exp(1j * np.radians(report.predicted_phase_deg)) / TARGET.amplitude)) < np.radians(2.0)


def test_taylor_windows_give_the_design_sidelobes():
    """Range window applied to the data (as the render does) and the azimuth Taylor window over the
    aperture: both cuts' PSLR at Taylor's -35 dB design level, the peak kept at ``|a|``. Catches an
    azimuth window applied twice or not at all (-13 or -60 dB)."""
    positions, velocities, prf = straight(401, 0.25, 5000.0, 50.0)
    raw = apply_range_window(track_data([TARGET], positions, velocities, prf=prf), "taylor")
    grid = grid_around((0.0, 0.0, 0.0), 10.0, 0.25)
    fast = ffbp(raw, grid, window_azimuth="taylor")
    report = analyze_point_target(fast, TARGET.position, chip=64, carrier=carrier_ramp(raw, fast, TARGET.position))
    assert report.pslr_azimuth_db == pytest.approx(pslr_theory("taylor"), abs=1.5)
    assert report.pslr_range_db == pytest.approx(pslr_theory("taylor"), abs=1.5)
    assert report.peak_magnitude == pytest.approx(abs(TARGET.amplitude), rel=0.02)


# ============================================================================ knobs, contract, errors
def test_finer_knobs_converge_to_direct_backprojection(spotlight):
    """The error knobs do what they say: finer angular and range sampling bring FFBP closer to the
    same direct backprojection (both with 64x range upsampling, so that only FFBP's own
    interpolation is left): catches a knob that is ignored."""
    raw, grid, _, _ = spotlight
    direct = backproject(raw, grid, oversample=64)
    coarse = nrmse_db(ffbp(raw, grid, oversample=64, angle_oversample=1.5, range_oversample=1).data, direct.data)
    fine = nrmse_db(ffbp(raw, grid, oversample=64, angle_oversample=4.0, range_oversample=4).data, direct.data)
    assert fine < coarse - 10.0 and fine < -50.0


def test_metadata_and_contract(spotlight):
    raw, grid, direct, fast = spotlight
    assert fast.data.shape == grid.shape and fast.data.dtype == np.complex64
    assert fast.algorithm == "backprojection" and fast.window == direct.window
    focus = fast.metadata["focus"]
    assert focus["implementation"] == "ffbp" and focus["subaperture"] == 16
    assert focus["angle_oversample"] == 2.0 and focus["range_oversample"] == 2 and focus["oversample"] == 8
    # the throughput against a stopwatch outside the call: every pixel times every pulse, in no
    # more time than the call took (a count of rows or of pulses alone falls far below)
    start = time.perf_counter()
    timed = ffbp(raw, grid).metadata["focus"]
    elapsed = time.perf_counter() - start
    assert 0.0 < timed["seconds"] <= elapsed
    assert timed["pixel_pulses_per_second"] * elapsed >= 0.999 * grid.shape[0] * grid.shape[1] * raw.n_pulses
    assert focus["normalisation"] == direct.metadata["focus"]["normalisation"] == "1/n_pulses"
    assert focus["track"] == direct.metadata["focus"]["track"]
    assert "focus" not in raw.metadata


@pytest.mark.parametrize("kwargs, match", [
    ({"subaperture": 0}, "subaperture"), ({"subaperture": 2.5}, "subaperture"),
    ({"angle_oversample": 1.0}, "angle_oversample"), ({"range_oversample": 0}, "range_oversample"),
    ({"oversample": 0}, "oversample"), ({"workers": 0}, "workers"),
    ({"azimuth_pattern": 50.0}, "azimuth_pattern needs azimuth_beamwidth"),
    ({"window_azimuth": "triangle"}, "unknown window"),
])
def test_rejects_bad_options(spotlight, kwargs, match):
    raw, grid, _, _ = spotlight
    with pytest.raises(ValueError, match=match):
        ffbp(raw, grid, **kwargs)


def test_focuses_bistatic_data(spotlight):
    """A receiver 5 m beside the transmitter (bistatic data, tests/test_ffbp_bistatic.py for more):
    focused, not refused, within -38 dB of the direct sum."""
    raw, grid, _, _ = spotlight
    bistatic = dataclasses.replace(raw, rx_position=raw.rx_position + np.array([0.0, 5.0, 0.0]))
    assert nrmse_db(ffbp(bistatic, grid).data, backproject(bistatic, grid).data) < -38.0
