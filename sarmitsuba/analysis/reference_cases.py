"""Reference stripmap point-target acquisitions: the shared cases of the focusing tests and benchmarks.

Four straight-track stripmap acquisitions (:class:`Case`), each with a 3 x 3 grid of point
targets (:meth:`Case.targets`), whose raw data :func:`simulate_case` makes analytically with
:mod:`sarmitsuba.analysis.synthetic` in float64 (never by the tracer):

=====================  ==================================================================
:data:`AIRBORNE_X`     airborne X band: 9.6 GHz, 150 MHz, 100 m/s, 10 km beam-centre range,
                       6 km altitude, broadside; 512 pulses x 512 samples
:data:`SPACEBORNE_C`   spaceborne C band: 5.405 GHz, 50 MHz, 7500 m/s, 800 km beam-centre
                       range at 30 deg off nadir, broadside; 512 pulses x 512 samples
:data:`CW_LOW`         Cumming & Wong (2005) Table 6.1 at 3.5 deg squint; 512 x 256
:data:`CW_HIGH`        the same at 21.9 deg squint; 600 x 512
=====================  ==================================================================

:data:`CASES` maps each case's ``name`` to it. The airborne and spaceborne cases are
representative systems chosen for this project, not taken from a publication. The
Cumming & Wong cases take the radar parameters of their Table 6.1 (R = 20 km,
Vr = 150 m/s, Tr = 2.5 us, Kr = 20 MHz/us so B = 50 MHz, f0 = 5.3 GHz, Fr = 60 MHz,
Fa = 100 Hz, Doppler bandwidth 80 Hz, squint 3.5 or 21.9 deg); the altitude (8 km), the
processed Doppler bands and the numbers of pulses are ours (more pulses than their 256, so
that a 3 x 3 grid of fully exposed targets fits).

Geometry: a straight level track along +x at altitude ``altitude``, the sensor on the +y
side looking toward -y, an ideal azimuth beam (all or nothing, no antenna pattern) of the
width whose Doppler band at ``fc`` is ``doppler_beam`` and of the given squint, point
targets on the ground plane z = 0. The earth is flat: the 800 km spaceborne case is a
straight line over a flat earth, an approximation of an orbit that the FFT focusers treat
exactly. At mid-aperture the beam centre at mid-swath (slant range ``beam_range``) lies on
the line y = 0; the fast-time window is centred on ``beam_range``.

Targets: a 3 x 3 grid (near/centre/far x early/centre/late), placed 10 % inside the edges
of the region where a target is fully focused: its whole beam exposure lies inside the
recorded pulses and its range history inside the fast-time window (with a margin of 40
range samples). Amplitudes have unit magnitude and distinct phases. A focused target is
predicted at its zero-Doppler along-track coordinate and its distance to the track line
(:meth:`~sarmitsuba.focus.stripmap.StripmapGeometry.zero_doppler`).

Squinted impulse responses: with a processed Doppler band of fixed width the 2-D spectrum
is a parallelogram whose range sides are tilted by the squint, so the range sidelobes lie
along the beam-centre line of sight, not along the zero-Doppler range axis. The range cut
is therefore measured after :func:`deskew` (each column shifted in azimuth by
``tan(squint) (R - R_target)``, an exact band-limited shift), which turns the
parallelogram into a rectangle; the zero-Doppler range IRW is then
``0.886 c / (2 B) cos(squint)`` and its line-of-sight value ``0.886 c / (2 B)``
(:meth:`Case.range_irw`). :func:`focused_carrier` gives the phase ramp of the deskewed
image near a target, for :func:`sarmitsuba.analysis.point_target.analyze_point_target`.

References
----------
.. [1] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar
   Data*, Artech House, 2005: Table 6.1 (simulation parameters of the range-Doppler
   chapter).
"""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from . import synthetic
from ..core.constants import SPEED_OF_LIGHT as C
from ..focus.stripmap import StripmapGeometry
from ..core.image import SarImage
from ..core.raw import RawData

if TYPE_CHECKING:
    from .point_target import PointTargetReport

__all__ = ["Case", "AIRBORNE_X", "SPACEBORNE_C", "CW_LOW", "CW_HIGH", "CASES", "simulate_case", "deskew",
           "focused_carrier", "phase_error_deg"]


# ============================================================================ cases
@dataclasses.dataclass(frozen=True)
class Case:
    """A straight-track stripmap acquisition with a 3 x 3 target grid (see the module docstring)."""

    name: str
    fc: float  # Hz, carrier
    bandwidth: float  # Hz, chirp bandwidth
    fs: float  # Hz, range sampling rate
    prf: float  # Hz
    speed: float  # m/s, along the track (+x)
    beam_range: float  # m, beam-centre slant range at mid-swath
    altitude: float  # m, of the track above the ground plane z = 0
    squint_deg: float  # deg, positive forward
    doppler_beam: float  # Hz, Doppler bandwidth of the beam at fc
    doppler_processed: float  # Hz, processed Doppler bandwidth (fixed band around the centroid)
    n_pulses: int
    n_samples: int
    pulse_length: float = 2.5e-6  # s

    @property
    def wavelength(self) -> float:
        """Carrier wavelength [m]."""
        return C / self.fc

    @property
    def squint(self) -> float:
        """Squint [rad], positive forward."""
        return float(np.radians(self.squint_deg))

    @property
    def beamwidth_deg(self) -> float:
        """Full angular beamwidth [deg] whose Doppler band at fc is ``doppler_beam``."""
        s = self.wavelength * self.doppler_beam / (4.0 * self.speed * np.cos(self.squint))
        return float(np.degrees(2.0 * np.arcsin(s)))

    @property
    def closest_range(self) -> float:
        """Closest-approach range [m] of the mid-swath beam centre."""
        return self.beam_range * np.cos(self.squint)

    @property
    def track_offset(self) -> float:
        """y [m] of the track: the mid-swath beam centre at mid-aperture lies on y = 0."""
        return float(np.sqrt(self.closest_range**2 - self.altitude**2))

    @property
    def scene_centre(self) -> np.ndarray:
        """Ground point [m], shape (3,), of the mid-swath beam centre at mid-aperture."""
        return np.array([self.beam_range * np.sin(self.squint), 0.0, 0.0])

    @property
    def fast_time0(self) -> float:
        """Fast time [s] of the first range sample: the window is centred on ``beam_range``."""
        return 2.0 * self.beam_range / C - (self.n_samples // 2) / self.fs

    def track(self) -> synthetic.Track:
        """The straight level track: ``n_pulses`` positions along +x, centred at x = 0."""
        return synthetic.straight_track(self.n_pulses, self.prf, self.speed,
                                        center=(0.0, self.track_offset, self.altitude))

    def beam(self) -> synthetic.AzimuthBeam:
        """The ideal azimuth beam (``beamwidth_deg`` wide, squinted by ``squint_deg``)."""
        return synthetic.AzimuthBeam(self.beamwidth_deg, self.squint_deg)

    # ------------------------------------------------------------------ theory
    def range_irw(self, k_w: float = 1.0) -> float:
        """Line-of-sight slant-range IRW [m], ``0.886 c / (2 B)`` x window broadening ``k_w``."""
        return 0.886 * C / (2.0 * self.bandwidth) * k_w

    def azimuth_irw(self, band: float, k_w: float = 1.0) -> float:
        """Along-track IRW [m] for a processed Doppler band ``band`` [Hz], ``0.886 V / band`` x ``k_w``."""
        return 0.886 * self.speed / band * k_w

    # ------------------------------------------------------------------ targets
    def exposure(self, r0: float) -> tuple[float, float]:
        """Along-track offsets (target - antenna) [m] at the beam edges, for closest range ``r0`` [m]."""
        half = np.radians(self.beamwidth_deg) / 2.0
        return r0 * np.tan(self.squint - half), r0 * np.tan(self.squint + half)

    def targets(self) -> list[synthetic.PointTarget]:
        """The 3 x 3 grid (range-major: near, centre, far; early, centre, late within each),
        10 % inside the fully focused region, on z = 0; unit amplitudes with distinct phases."""
        pos = self.track().position[:, 0]
        s_first, s_last = pos[0], pos[-1]
        dr = C / (2.0 * self.fs)
        r_lo = C * self.fast_time0 / 2.0
        r_hi = r_lo + (self.n_samples - 1) * dr
        margin = 40 * dr
        r0_mid = self.closest_range
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
#: name -> case, for the four cases above
CASES: dict[str, Case] = {c.name: c for c in (AIRBORNE_X, SPACEBORNE_C, CW_LOW, CW_HIGH)}


def simulate_case(case: Case, range_window: str = "rect") -> RawData:
    """Range-compressed analytic raw data of ``case`` (its targets, track and beam), float64-exact,
    shape ``(case.n_pulses, case.n_samples)``, compressed with ``range_window``."""
    track = case.track()
    return synthetic.simulate_point_targets(
        case.targets(), track.position, case.fc, case.bandwidth, case.fs, case.fast_time0, case.n_samples,
        prf=case.prf, velocity=track.velocity, pulse_length=case.pulse_length, beam=case.beam(),
        pulse_time=track.pulse_time, range_window=range_window)


# ============================================================================ measuring the impulse responses
def deskew(image: SarImage, geo: StripmapGeometry, r_target: float) -> SarImage:
    """Shift every column of a slant image in azimuth by ``tan(squint) (R - r_target)`` [m]
    (band-limited, exact), so that the line-of-sight range sidelobes through a target at
    closest range ``r_target`` [m] align with the range axis. Identity at zero squint."""
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


def focused_carrier(geo: StripmapGeometry, fc: float) -> tuple[float, float]:
    """(k_azimuth, k_range) [rad/m] of a focused slant image near a target after :func:`deskew`:
    ``2 pi f_dc / V`` and ``4 pi fc cos(squint) / c + tan(squint) k_azimuth`` (``fc`` in Hz).
    At broadside ``(0, 4 pi fc / c)``."""
    k_az = 2.0 * np.pi * geo.doppler_centroid / geo.velocity
    return k_az, 4.0 * np.pi * fc * np.cos(geo.squint) / C + np.tan(geo.squint) * k_az


def phase_error_deg(report: PointTargetReport, target: synthetic.PointTarget) -> float:
    """Measured minus true peak phase [deg], wrapped to [-180, 180)."""
    d = report.predicted_phase_deg - np.degrees(np.angle(target.amplitude))
    return float((d + 180.0) % 360.0 - 180.0)
