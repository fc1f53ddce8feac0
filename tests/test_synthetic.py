"""The analytic point-target generator against closed forms (the oracle must be right first).

Each expectation is recomputed independently here from the signal model of docs/design.md
section 5: delay ``L/c`` with ``L = 2 |S_p - X|``, carrier ``exp(-j 4 pi R / lambda)``,
compressed pulse ``sinc(B t)``, chirp ``exp(j pi K_r t^2)`` over ``|t| <= T_p / 2``, and an
ideal azimuth beam that is a condition on ``x_target - x_antenna``.
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.core.raw import RawData
from sarmitsuba.signal.signal_model import receiver_response
from sarmitsuba.analysis.synthetic import (AzimuthBeam, PointTarget, illuminated, simulate_point_targets, spotlight,
                                           straight_track, stripmap)

FC = 9.6e9
B = 150e6
FS = 1.2 * B
WAVELENGTH = C / FC
ALT, OFFSET = 3000.0, 4000.0
R0 = float(np.hypot(ALT, OFFSET))  # closest approach to the origin, m


def track(n=201, prf=400.0, speed=100.0):
    return straight_track(n, prf, speed, center=(0.0, OFFSET, ALT))


def one_pulse(point, amplitude, *, sample=100, frac=0.0, compressed=True, **kw):
    """One pulse from (0, OFFSET, ALT); fast time placed so L/c falls at sample + frac."""
    antenna = np.array([[0.0, OFFSET, ALT]])
    length = 2 * np.linalg.norm(antenna[0] - np.asarray(point))
    t0 = length / C - (sample + frac) / FS
    raw = simulate_point_targets(PointTarget(point, amplitude), antenna, FC, B, FS, t0, 2 * sample, prf=100.0,
                                 velocity=np.array([[100.0, 0.0, 0.0]]), pulse_length=0.3e-6,
                                 compressed=compressed, **kw)
    return raw, length


def test_compressed_delay_and_phase_at_the_right_sample():
    point, amplitude = (1.3, -0.7, 0.4), 0.8 * np.exp(0.9j)
    raw, length = one_pulse(point, amplitude)
    line = raw.data[0].astype(np.complex128)
    assert isinstance(raw, RawData) and raw.range_compressed and raw.data.dtype == np.complex64
    assert int(np.argmax(np.abs(line))) == 100
    r = length / 2  # one-way range
    expected = amplitude * np.exp(-4j * np.pi * np.mod(r / WAVELENGTH, 1.0))
    assert abs(line[100] - expected) < 1e-6
    # neighbours follow sinc(B (t - L/c)): samples 1/fs apart
    k = np.arange(-20, 21)
    assert np.allclose(line[100 + k], expected * np.sinc(B * k / FS), atol=1e-6)


@pytest.mark.parametrize("frac", [0.0, 0.31, 0.5, 0.77])
def test_sub_sample_delay_is_exact(frac):
    """A band-limited interpolation (FFT zero padding) of the line peaks at L/c."""
    raw, length = one_pulse((0.0, 0.0, 0.0), 1.0, sample=256, frac=frac)
    line = raw.data[0].astype(np.complex128)
    t = raw.fast_time - length / C
    assert np.allclose(line * np.exp(4j * np.pi * np.mod(length / 2 / WAVELENGTH, 1.0)), np.sinc(B * t), atol=1e-6)


def test_phase_does_not_depend_on_distance():
    """At 800 km the float64 carrier reduced in cycles still gives the exact phase."""
    for distance in (5e3, 800e3):
        direction = np.array([0.0, OFFSET, ALT]) / R0
        antenna = (direction * distance)[None, :]
        point = np.array([0.0, 0.0, 0.0])
        # a range that is an exact number of half wavelengths plus a known remainder
        raw = simulate_point_targets(PointTarget(point, 1.0), antenna, FC, B, FS, 2 * distance / C - 50 / FS, 100,
                                     prf=100.0, velocity=np.array([[100.0, 0.0, 0.0]]), pulse_length=0.3e-6)
        cycles = np.mod(2 * distance * FC / C, 1.0)
        assert abs(np.angle(raw.data[0, 50] * np.exp(2j * np.pi * cycles), deg=True)) < 1e-3


def test_raw_chirp_is_the_formula():
    point, amplitude = (0.4, 0.2, 0.0), 0.5 - 0.2j
    raw, length = one_pulse(point, amplitude, sample=60, frac=0.37, compressed=False)
    tau = raw.fast_time - length / C
    kr = B / 0.3e-6
    expected = (amplitude * np.exp(-2j * np.pi * np.mod(FC * length / C, 1.0))
                * np.where(np.abs(tau) <= 0.15e-6, np.exp(1j * np.pi * kr * tau ** 2), 0))
    assert not raw.range_compressed and raw.chirp_rate == pytest.approx(kr)
    assert np.allclose(raw.data[0], expected, atol=2e-6)
    assert np.count_nonzero(raw.data[0]) == np.count_nonzero(np.abs(tau) <= 0.15e-6)


def test_anti_aliased_chirp_spectrum_is_the_chirp_spectrum():
    """DTFT of the received samples over the band = fs H S(f) exp(-j 2 pi f tau) with H = 1 there:
    S(f) by direct quadrature of the chirp, independent of the generator's Fresnel formula."""
    import scipy.integrate

    tp = 0.3e-6
    kr = B / tp
    raw, length = one_pulse((0.0, 0.0, 0.0), 1.0, sample=300, frac=0.4, compressed=False, anti_alias=True)
    x = raw.data[0].astype(np.complex128) * np.exp(2j * np.pi * np.mod(FC * length / C, 1.0))
    t_rel = raw.fast_time - length / C
    for f in (-70e6, -31e6, 0.0, 12e6, 74e6):
        dtft = np.sum(x * np.exp(-2j * np.pi * f * t_rel)) / FS
        re = scipy.integrate.quad(lambda t: np.cos(np.pi * kr * t * t - 2 * np.pi * f * t), -tp / 2, tp / 2,
                                  limit=400, epsabs=1e-16)[0]
        im = scipy.integrate.quad(lambda t: np.sin(np.pi * kr * t * t - 2 * np.pi * f * t), -tp / 2, tp / 2,
                                  limit=400, epsabs=1e-16)[0]
        assert abs(dtft - (re + 1j * im)) < 1e-5 * tp
    assert receiver_response(np.array([0, 75e6, 90e6, 100e6]), FS, B).tolist() == pytest.approx([1, 1, 0, 0])


def test_straight_track_geometry():
    tr = straight_track(5, 200.0, 50.0, center=(1.0, 2.0, 3.0), direction=(0.0, 2.0, 0.0))
    assert np.allclose(tr.position[:, 1], 2.0 + np.array([-0.5, -0.25, 0, 0.25, 0.5]))
    assert np.allclose(tr.velocity, [0.0, 50.0, 0.0]) and np.allclose(tr.pulse_time, np.arange(-2, 3) / 200.0)
    tr = straight_track(3, 10.0, (1.0, 1.0, 0.0), start=(0.0, 0.0, 100.0))
    assert np.allclose(tr.position[-1], [0.2, 0.2, 100.0]) and np.allclose(tr.pulse_time, [0.0, 0.1, 0.2])
    with pytest.raises(ValueError, match="exactly one"):
        straight_track(3, 10.0, 1.0)
    with pytest.raises(ValueError, match="n_pulses"):
        straight_track(0, 10.0, 1.0, start=(0, 0, 0))
    with pytest.raises(ValueError, match="prf"):
        straight_track(3, -1.0, 1.0, start=(0, 0, 0))


@pytest.mark.parametrize("width, squint", [(2.0, 0.0), (3.0, 5.0), (1.5, -8.0)])
def test_stripmap_beam_sees_the_right_pulses(width, squint):
    """Illuminated <=> x_t - x_p in [R0 tan(squint - w/2), R0 tan(squint + w/2)] for a target
    abeam of the track (its along-track angle is asin((x_t - x_p) / R))."""
    tr = track(n=2001, prf=20.0)  # 10 km of track, 5 m spacing
    x_t = 250.0
    target = PointTarget((x_t, 0.0, 0.0), 1.0)
    beam = AzimuthBeam(width, squint)
    seen = illuminated(beam, tr.position, tr.velocity, target.position)
    ahead = x_t - tr.position[:, 0]
    lo, hi = R0 * np.tan(np.deg2rad(squint - width / 2)), R0 * np.tan(np.deg2rad(squint + width / 2))
    assert np.array_equal(seen, (ahead >= lo) & (ahead <= hi))
    raw = stripmap(target, fc=FC, bandwidth=B, fs=FS, prf=20.0, speed=100.0, n_pulses=2001,
                   center=(0.0, OFFSET, ALT), beamwidth=width, squint=squint)
    assert np.array_equal(np.any(raw.data != 0, axis=1), seen)
    assert raw.metadata["beam"]["squint_deg"] == squint


def test_squint_sets_the_doppler_centroid():
    """Pulse-to-pulse phase of a squinted stripmap echo: f_dc = 2 v sin(squint) / lambda."""
    speed, prf, squint = 100.0, 2000.0, 4.0
    raw = stripmap(PointTarget((0.0, 0.0, 0.0), 1.0), fc=FC, bandwidth=B, fs=FS, prf=prf, speed=speed,
                   n_pulses=4001, center=(-R0 * np.tan(np.deg2rad(squint)), OFFSET, ALT), beamwidth=1.0,
                   squint=squint)
    d = raw.data.astype(np.complex128)
    lag = np.sum(d[1:] * np.conj(d[:-1]))
    f_dc = np.angle(lag) * prf / (2 * np.pi)
    assert f_dc == pytest.approx(2 * speed * np.sin(np.deg2rad(squint)) / WAVELENGTH, rel=0.01)


def test_spotlight_beam_follows_the_spot():
    tr = track(n=801, prf=8.0)  # 10 km of track
    spot = np.array([0.0, 0.0, 0.0])
    near = PointTarget((30.0, 0.0, 0.0), 1.0)
    beam = AzimuthBeam(1.0, center=spot)
    assert beam.mode == "spotlight"
    # the spot itself is always in the beam; a target off the spot is seen while its along-track
    # angle is within w/2 of the spot's
    assert np.all(illuminated(beam, tr.position, tr.velocity, spot))
    theta = lambda x: np.arcsin((x - tr.position[:, 0]) / np.linalg.norm(  # noqa: E731
        np.array([x, 0.0, 0.0]) - tr.position, axis=1))
    expected = np.abs(theta(30.0) - theta(0.0)) <= np.deg2rad(0.5)
    assert np.array_equal(illuminated(beam, tr.position, tr.velocity, near.position), expected)
    far = PointTarget((150.0, 0.0, 0.0), 1.0)
    raw = spotlight([PointTarget(spot, 1.0), far], fc=FC, bandwidth=B, fs=FS, prf=8.0, speed=100.0, n_pulses=801,
                    center=(0.0, OFFSET, ALT), spot=spot, beamwidth=1.0)
    assert raw.metadata["beam"]["mode"] == "spotlight" and np.all(np.any(raw.data != 0, axis=1))


def test_window_metadata_and_linearity():
    t1, t2 = PointTarget((0.0, 0.0, 0.0), 1.0), PointTarget((3.0, -2.0, 0.0), -0.4j)
    kw = dict(fc=FC, bandwidth=B, fs=FS, prf=400.0, speed=100.0, n_pulses=21, center=(0.0, OFFSET, ALT),
              margin=2e-6, range_window="kaiser", range_window_params={"beta": 2.5})
    both = stripmap([t1, t2], **kw)
    assert both.metadata["range_window"] == {"name": "kaiser", "beta": 2.5}
    assert both.metadata["units"] == "sqrt(m^2)" and len(both.metadata["targets"]) == 2
    # superposition, on the fast-time window of the two-target data
    other = simulate_point_targets(t2, both.tx_position, FC, B, FS, both.fast_time[0], both.n_samples,
                                   prf=400.0, velocity=both.velocity, pulse_length=1e-6,
                                   range_window="kaiser", range_window_params={"beta": 2.5})
    first = simulate_point_targets(t1, both.tx_position, FC, B, FS, both.fast_time[0], both.n_samples,
                                   prf=400.0, velocity=both.velocity, pulse_length=1e-6,
                                   range_window="kaiser", range_window_params={"beta": 2.5})
    assert np.allclose(both.data, first.data + other.data, atol=1e-6)


@pytest.mark.parametrize("kwargs, match", [
    ({"fc": -1.0}, "fc"), ({"n_samples": 1}, "n_samples"), ({"range_window": "gauss"}, "window"),
    ({"velocity": np.zeros((2, 3))}, "velocity"), ({"pulse_length": 0.0}, "pulse_length"),
])
def test_rejects_bad_input(kwargs, match):
    args = dict(targets=PointTarget((0, 0, 0), 1.0), tx_position=np.zeros((3, 3)) + [0, 1e3, 1e3], fc=FC,
                bandwidth=B, fs=FS, fast_time0=0.0, n_samples=16, prf=100.0, velocity=np.ones((3, 3)),
                pulse_length=1e-6)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        simulate_point_targets(**args)


def test_point_target_and_beam_validation():
    with pytest.raises(ValueError, match="position"):
        PointTarget((0.0, 1.0), 1.0)
    with pytest.raises(ValueError, match="amplitude"):
        PointTarget((0.0, 1.0, 2.0), np.nan)
    with pytest.raises(ValueError, match="width"):
        AzimuthBeam(0.0)
    with pytest.raises(ValueError, match="squint"):
        AzimuthBeam(1.0, squint=95.0)
    p = PointTarget([1, 2, 3], 2)
    assert p.position.dtype == np.float64 and p.amplitude == 2 + 0j and not p.position.flags.writeable
