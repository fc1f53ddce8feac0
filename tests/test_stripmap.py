"""Straight-track stripmap geometry (sarmitsuba.focus.stripmap) and the shared test cases.

The point-target cases used by ``test_omegak.py`` and ``test_rda.py`` live here
(:class:`Case`, :data:`CASES`, :func:`simulate`, :func:`analyse`). Raw data are made
analytically by :mod:`sarmitsuba.synthetic` in float64 (never by the tracer): a straight
level track along +x at altitude ``h``, the sensor on the +y side looking toward -y, an
ideal azimuth beam (all or nothing) of given width and squint, point targets on the
ground plane z = 0 (a flat earth: the 800 km spaceborne case is a straight line over a
flat earth, an approximation of an orbit that the FFT focusers treat exactly).

Targets: a 3 x 3 grid (near/centre/far x early/centre/late) placed 10 % inside the edges
of the region where a target is fully focused: its whole beam exposure lies inside the
recorded pulses and its range history inside the fast-time window (with a chip margin).
They are predicted at (zero-Doppler along-track coordinate, distance to the track line).

Squinted impulse responses: with a processed Doppler band of fixed width the 2-D spectrum
is a parallelogram whose range sides are tilted by the squint, so the range sidelobes lie
along the beam-centre line of sight, not along the zero-Doppler range axis. The range
cut is therefore measured after a deskew (each column shifted in azimuth by
``tan(squint) (R - R_target)``, an exact band-limited shift), which turns the
parallelogram into a rectangle; the zero-Doppler range IRW is then
``0.886 c / (2 B) cos(squint)`` and its line-of-sight value ``0.886 c / (2 B)``.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

from sarmitsuba import synthetic
from sarmitsuba.analysis import analyze_point_target
from sarmitsuba.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus.stripmap import (StripmapGeometry, estimate_doppler_centroid, slant_output_grid,
                                       stripmap_geometry)
from sarmitsuba.image import SarImage
from sarmitsuba.raw import RawData

# ============================================================================ cases
@dataclasses.dataclass(frozen=True)
class Case:
    """A straight-track stripmap acquisition with a 3 x 3 target grid."""

    name: str
    fc: float  # Hz
    bandwidth: float  # Hz
    fs: float  # Hz
    prf: float  # Hz
    speed: float  # m/s
    beam_range: float  # m, beam-centre slant range at mid-swath
    altitude: float  # m
    squint_deg: float  # deg, positive forward
    doppler_beam: float  # Hz, Doppler bandwidth of the beam at fc
    doppler_processed: float  # Hz, processed Doppler bandwidth (fixed band around the centroid)
    n_pulses: int
    n_samples: int
    pulse_length: float = 2.5e-6  # s

    @property
    def wavelength(self) -> float:
        return C / self.fc

    @property
    def squint(self) -> float:
        return float(np.radians(self.squint_deg))

    @property
    def beamwidth_deg(self) -> float:
        """Full angular beamwidth whose Doppler band at fc is ``doppler_beam``."""
        s = self.wavelength * self.doppler_beam / (4.0 * self.speed * np.cos(self.squint))
        return float(np.degrees(2.0 * np.arcsin(s)))

    @property
    def closest_range(self) -> float:
        return self.beam_range * np.cos(self.squint)

    @property
    def track_offset(self) -> float:
        """y of the track: the mid-swath beam centre at mid-aperture lies on y = 0."""
        return float(np.sqrt(self.closest_range**2 - self.altitude**2))

    @property
    def scene_centre(self) -> np.ndarray:
        return np.array([self.beam_range * np.sin(self.squint), 0.0, 0.0])

    @property
    def fast_time0(self) -> float:
        return 2.0 * self.beam_range / C - (self.n_samples // 2) / self.fs

    def track(self) -> synthetic.Track:
        return synthetic.straight_track(self.n_pulses, self.prf, self.speed,
                                        center=(0.0, self.track_offset, self.altitude))

    def beam(self) -> synthetic.AzimuthBeam:
        return synthetic.AzimuthBeam(self.beamwidth_deg, self.squint_deg)

    # ------------------------------------------------------------------ theory
    def range_irw(self, k_w: float = 1.0) -> float:
        """Line-of-sight slant-range IRW, 0.886 c / (2 B) x broadening."""
        return 0.886 * C / (2.0 * self.bandwidth) * k_w

    def azimuth_irw(self, band: float, k_w: float = 1.0) -> float:
        """0.886 V / B_a x broadening (along track)."""
        return 0.886 * self.speed / band * k_w

    # ------------------------------------------------------------------ targets
    def exposure(self, r0: float) -> tuple[float, float]:
        """Along-track offsets (target - antenna) [m] at the beam edges, for range ``r0``."""
        half = np.radians(self.beamwidth_deg) / 2.0
        return r0 * np.tan(self.squint - half), r0 * np.tan(self.squint + half)

    def targets(self) -> list[synthetic.PointTarget]:
        """3 x 3 grid, 10 % inside the fully focused region; amplitudes with distinct phases."""
        pos = self.track().position[:, 0]
        s_first, s_last = pos[0], pos[-1]
        dr = C / (2.0 * self.fs)
        r_lo = C * self.fast_time0 / 2.0
        r_hi = r_lo + (self.n_samples - 1) * dr
        margin = 40 * dr
        r0_mid = self.closest_range
        lo, hi = self.exposure(r0_mid)
        walk = r0_mid * abs(1 / np.cos(self.squint + np.radians(self.beamwidth_deg) / 2)
                            - 1 / np.cos(self.squint - np.radians(self.beamwidth_deg) / 2))
        rc_lo, rc_hi = r_lo + margin + walk / 2, r_hi - margin - walk / 2
        out = []
        for k, frac_r in enumerate((0.1, 0.5, 0.9)):
            r_c = rc_lo + frac_r * (rc_hi - rc_lo)  # beam-centre range
            r0 = r_c * np.cos(self.squint)
            lo, hi = self.exposure(r0)
            # antenna positions seeing the target: x - hi .. x - lo; keep them inside the track
            x_lo, x_hi = s_first + hi, s_last + lo
            for m, frac_a in enumerate((0.1, 0.5, 0.9)):
                x = x_lo + frac_a * (x_hi - x_lo)
                y = self.track_offset - np.sqrt(r0**2 - self.altitude**2)
                phase = np.radians(40.0 * (3 * k + m) - 170.0)
                out.append(synthetic.PointTarget((x, y, 0.0), np.exp(1j * phase)))
        return out


AIRBORNE_X = Case("airborne-X-10km", fc=9.6e9, bandwidth=150e6, fs=180e6, prf=125.0, speed=100.0,
                  beam_range=10e3, altitude=6000.0, squint_deg=0.0, doppler_beam=100.0, doppler_processed=90.0,
                  n_pulses=512, n_samples=512)
SPACEBORNE_C = Case("spaceborne-C-800km", fc=5.405e9, bandwidth=50e6, fs=60e6, prf=875.0, speed=7500.0,
                    beam_range=800e3, altitude=800e3 * np.cos(np.radians(30.0)), squint_deg=0.0,
                    doppler_beam=700.0, doppler_processed=630.0, n_pulses=512, n_samples=512)
# Cumming & Wong Table 6.1: R = 20 km, Vr = 150 m/s, Tr = 2.5 us, Kr = 20 MHz/us (B = 50 MHz),
# f0 = 5.3 GHz, Fr = 60 MHz, Fa = 100 Hz, Doppler bandwidth 80 Hz; more pulses than C&W's 256
# so that a 3 x 3 grid of fully exposed targets fits.
CW_LOW = Case("cw-3.5deg", fc=5.3e9, bandwidth=50e6, fs=60e6, prf=100.0, speed=150.0, beam_range=20e3,
              altitude=8000.0, squint_deg=3.5, doppler_beam=80.0, doppler_processed=72.0,
              n_pulses=512, n_samples=256)
CW_HIGH = Case("cw-21.9deg", fc=5.3e9, bandwidth=50e6, fs=60e6, prf=100.0, speed=150.0, beam_range=20e3,
               altitude=8000.0, squint_deg=21.9, doppler_beam=80.0, doppler_processed=60.0,
               n_pulses=600, n_samples=512)
CASES = {c.name: c for c in (AIRBORNE_X, SPACEBORNE_C, CW_LOW, CW_HIGH)}


@functools.lru_cache(maxsize=8)
def simulate(name: str, range_window: str = "rect") -> RawData:
    """Range-compressed analytic data of case ``name`` (cached: tests share it)."""
    case = CASES[name]
    track = case.track()
    return synthetic.simulate_point_targets(
        case.targets(), track.position, case.fc, case.bandwidth, case.fs, case.fast_time0, case.n_samples,
        prf=case.prf, velocity=track.velocity, pulse_length=case.pulse_length, beam=case.beam(),
        pulse_time=track.pulse_time, range_window=range_window)


def geometry(name: str) -> StripmapGeometry:
    case = CASES[name]
    return stripmap_geometry(simulate(name), scene_centre=case.scene_centre)


# ============================================================================ analysis helpers
def deskew(image: SarImage, geo: StripmapGeometry, r_target: float) -> SarImage:
    """Shift every column in azimuth by ``tan(squint) (R - r_target)`` (band-limited, exact),
    so that the line-of-sight range sidelobes through a target at ``r_target`` align with
    the range axis. Identity at zero squint."""
    if geo.squint == 0.0:
        return image
    n_a = image.data.shape[0]
    dx = float(np.diff(image.azimuth).mean())
    k = np.fft.fftfreq(n_a, dx)  # cycles/m, wrapped
    kc = geo.doppler_centroid / geo.velocity
    k = k + np.floor((kc + 0.5 / dx - k) * dx) / dx  # unwrapped around the Doppler centroid
    shift = np.tan(geo.squint) * (image.range - r_target)
    spec = np.fft.fft(image.data.astype(np.complex128), axis=0)
    spec *= np.exp(2j * np.pi * k[:, None] * shift[None, :])
    data = np.fft.ifft(spec, axis=0).astype(np.complex64)
    return dataclasses.replace(image, data=data)


def carrier(geo: StripmapGeometry, fc: float) -> tuple[float, float]:
    """(k_azimuth, k_range) [rad/m] of a focused stripmap image near a target after deskew:
    ``2 pi f_dc / V`` and ``4 pi fc cos(squint) / c + tan(squint) k_azimuth``."""
    k_az = 2.0 * np.pi * geo.doppler_centroid / geo.velocity
    return k_az, 4.0 * np.pi * fc * np.cos(geo.squint) / C + np.tan(geo.squint) * k_az


def analyse(image: SarImage, geo: StripmapGeometry, fc: float, target: synthetic.PointTarget, **kw):
    """Point-target report (deskewed for squint) and the predicted (azimuth, range)."""
    az, rg = geo.zero_doppler(target.position)
    return analyze_point_target(deskew(image, geo, rg), (az, rg), carrier=carrier(geo, fc), **kw), (az, rg)


def phase_error_deg(report, target: synthetic.PointTarget) -> float:
    d = report.predicted_phase_deg - np.degrees(np.angle(target.amplitude))
    return float((d + 180.0) % 360.0 - 180.0)


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """|<a, b>| / (|a| |b|) of two complex chips."""
    a = a.astype(np.complex128).ravel()
    b = b.astype(np.complex128).ravel()
    return float(abs(np.vdot(a, b)) / np.sqrt(np.vdot(a, a).real * np.vdot(b, b).real))


def chip(image: SarImage, az: float, rg: float, half: int = 12) -> np.ndarray:
    i = int(round((az - image.azimuth[0]) / (image.azimuth[1] - image.azimuth[0])))
    j = int(round((rg - image.range[0]) / (image.range[1] - image.range[0])))
    assert half <= i < image.data.shape[0] - half and half <= j < image.data.shape[1] - half, "chip off the image"
    return image.data[i - half:i + half + 1, j - half:j + half + 1]


# ============================================================================ tests
@pytest.mark.parametrize("name", list(CASES))
def test_geometry_of_cases(name):
    """Velocity, R_ref, squint and Doppler centroid come out of the data as simulated."""
    case = CASES[name]
    geo = geometry(name)
    assert geo.velocity == pytest.approx(case.speed, rel=1e-12)
    assert geo.pulse_spacing == pytest.approx(case.speed / case.prf, rel=1e-12)
    np.testing.assert_allclose(geo.azimuth_direction, [1.0, 0.0, 0.0], atol=1e-12)
    # range direction: perpendicular to the track, toward the scene centre (-y, down)
    expect = np.array([0.0, -case.track_offset, -case.altitude]) / case.closest_range
    np.testing.assert_allclose(geo.range_direction, expect, atol=1e-9)
    assert geo.squint == pytest.approx(case.squint, abs=1e-12)
    assert geo.doppler_source == "metadata"  # the generator records the beam squint
    assert geo.doppler_centroid == pytest.approx(2 * case.speed * np.sin(case.squint) / case.wavelength, rel=1e-9)
    # R_ref: closest approach of the mid-swath beam centre (window centred on beam_range +- half a sample)
    assert geo.reference_range == pytest.approx(case.closest_range, abs=C / (2 * case.fs))
    assert geo.max_cross_track_error < 1e-6 and geo.max_along_track_error < 1e-6
    # prediction: the target's closest approach
    for t in case.targets():
        az, rg = geo.zero_doppler(t.position)
        assert rg == pytest.approx(np.hypot(t.position[1] - case.track_offset, case.altitude), rel=1e-12)
        assert az == pytest.approx(t.position[0] - geo.origin[0], abs=1e-9)


@pytest.mark.parametrize("name", list(CASES))
def test_doppler_centroid_estimated_from_data(name):
    """Madsen fraction + range-walk ambiguity give the absolute centroid within 2 % of the PRF."""
    case = CASES[name]
    raw = simulate(name)
    f_dc = 2 * case.speed * np.sin(case.squint) / case.wavelength
    assert estimate_doppler_centroid(raw) == pytest.approx(f_dc, abs=0.02 * case.prf)
    bare = dataclasses.replace(raw, metadata={})
    geo = stripmap_geometry(bare, scene_centre=case.scene_centre)
    assert geo.doppler_source == "data"
    assert geo.doppler_centroid == pytest.approx(f_dc, abs=0.02 * case.prf)


def test_flat_earth_default_scene_centre():
    """Without a stated scene centre: the ground point (z = 0) on the right at the mid-swath range."""
    case = CW_HIGH
    geo = stripmap_geometry(simulate(case.name))
    np.testing.assert_allclose(geo.scene_centre, case.scene_centre, atol=2.0)
    np.testing.assert_allclose(geo.range_direction, geometry(case.name).range_direction, atol=1e-4)


def test_slant_grid_convention():
    """Origin on the track at mid-aperture, range absolute, azimuth centred on R_ref tan(squint)."""
    case = CW_HIGH
    raw = simulate(case.name)
    geo = geometry(case.name)
    grid = slant_output_grid(geo, raw)
    assert grid.plane == "slant" and grid.shape == raw.data.shape
    np.testing.assert_allclose(geo.origin, raw.tx_position.mean(axis=0), atol=1e-9)
    assert grid.range[case.n_samples // 2] == pytest.approx(geo.reference_range, rel=1e-15)
    assert np.diff(grid.range).mean() == pytest.approx(C / (2 * case.fs), rel=1e-12)
    assert grid.azimuth[case.n_pulses // 2] == pytest.approx(geo.reference_range * np.tan(case.squint), rel=1e-12)
    assert np.diff(grid.azimuth).mean() == pytest.approx(case.speed / case.prf, rel=1e-12)
    # a pixel's world position is at its range from the track line, at its zero-Doppler azimuth
    i, j = 17, 101
    p = geo.slant_position(grid.azimuth[i], grid.range[j])
    az, rg = geo.zero_doppler(p)
    assert az == pytest.approx(grid.azimuth[i], abs=1e-6) and rg == pytest.approx(grid.range[j], abs=1e-6)


def _with_positions(raw: RawData, positions: np.ndarray) -> RawData:
    return dataclasses.replace(raw, tx_position=positions, rx_position=positions.copy())


def test_curved_or_uneven_track_is_rejected():
    """Deviations beyond lambda/16 across or along the track raise ValueError naming backprojection."""
    raw = simulate(AIRBORNE_X.name)
    n = raw.n_pulses
    tol = raw.wavelength / 16
    k = np.linspace(-1.0, 1.0, n)
    bent = raw.tx_position.copy()
    bent[:, 2] += 2 * tol * (1 - k**2)  # a 2 lambda/16 sag
    with pytest.raises(ValueError, match="not straight.*backprojection"):
        stripmap_geometry(_with_positions(raw, bent))
    uneven = raw.tx_position.copy()
    uneven[:, 0] += 3 * tol * np.sin(np.pi * k)
    with pytest.raises(ValueError, match="uniformly spaced.*backprojection"):
        stripmap_geometry(_with_positions(raw, uneven))
    # within tolerance: accepted, and the deviation is reported
    wobble = raw.tx_position.copy()
    wobble[:, 1] += 0.5 * tol * np.sin(7 * np.pi * k)
    geo = stripmap_geometry(_with_positions(raw, wobble), scene_centre=(0, 0, 0))
    assert 0.3 * tol < geo.max_cross_track_error < tol  # the line fit absorbs a little of the wobble
    # an explicit tolerance relaxes the check
    geo = stripmap_geometry(_with_positions(raw, bent), scene_centre=(0, 0, 0), tolerance=3 * tol)
    assert geo.max_cross_track_error == pytest.approx(4 / 3 * tol, rel=0.01)  # sag minus its fitted mean


def test_bistatic_and_bad_prf_are_rejected():
    raw = simulate(AIRBORNE_X.name)
    with pytest.raises(ValueError, match="monostatic"):
        stripmap_geometry(dataclasses.replace(raw, rx_position=raw.tx_position + [0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="uniform PRF"):
        stripmap_geometry(dataclasses.replace(raw, prf=raw.prf * 1.01))
    with pytest.raises(ValueError, match="velocity disagrees"):
        stripmap_geometry(dataclasses.replace(raw, velocity=raw.velocity * 1.05))
    with pytest.raises(ValueError, match="squint"):
        stripmap_geometry(raw, squint=85.0)
