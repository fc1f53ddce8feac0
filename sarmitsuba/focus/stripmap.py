"""Straight-track stripmap geometry for the FFT focusers (omega-K, range-Doppler).

The FFT focusers of :mod:`sarmitsuba.focus.omegak` and :mod:`sarmitsuba.focus.rda` assume
what backprojection does not: a **straight, uniformly sampled, monostatic track**. On such
a track every point ``X`` is described by two cylindrical coordinates about the track line,
its *zero-Doppler* along-track coordinate ``x`` (the foot of the perpendicular from ``X`` to
the track) and its *closest-approach range* ``R0`` (the distance to the line). The range
history is the hyperbola

.. math:: R(\\eta) = \\sqrt{R_0^2 + (V \\eta - x)^2},

with ``eta`` the slow time of an antenna at along-track coordinate ``V eta``. The third
coordinate (the angle around the track) is invisible to the data: a straight-track focuser
images the scene in the *slant plane* spanned by the track and the scene centre.

This module

* extracts and validates that geometry from a :class:`~sarmitsuba.core.raw.RawData`
  (:func:`stripmap_geometry`, returning a :class:`StripmapGeometry`): track direction,
  effective velocity ``Vr``, reference closest-approach range ``R_ref`` at mid-swath,
  squint and absolute Doppler centroid (from a stated beam, or estimated from the data,
  :func:`estimate_doppler_centroid`), and raises :class:`ValueError` when the track is not
  straight and uniformly sampled within a stated tolerance (then only backprojection is
  valid);
* defines the slant-plane output grid shared by the FFT focusers
  (:func:`slant_output_grid`);
* the options, Doppler-domain helpers and output image the two focusers share live in
  :mod:`sarmitsuba.focus.fft_contract`.

Output grid convention (:func:`slant_output_grid`)
---------------------------------------------------
``SarImage.plane == "slant"``; ``origin`` is the scene centre's zero-Doppler point: the foot
of the perpendicular from the scene centre to the fitted track line (not the mid-aperture
antenna, which trails it by ``R0 tan(squint)``); ``azimuth_direction`` the unit track
direction; ``range_direction`` the unit vector perpendicular to the track, in the plane of
the track and the scene centre, toward the scene centre. Row ``i`` is the zero-Doppler
along-track coordinate ``azimuth[i]`` [m] relative to ``origin`` (the scene centre is at
azimuth 0, as in a backprojected ground image, whose azimuth axis is the same along-track
distance from the scene centre), column ``j`` the absolute closest-approach (zero-Doppler)
slant range ``range[j]`` [m] (distance from the track line), so ``origin + azimuth *
azimuth_direction + range * range_direction`` is the slant-plane position of the pixel, and
a target at ``X`` is imaged at ``StripmapGeometry.zero_doppler(X)`` whether or not it lies in
the slant plane (the data see only its cylindrical coordinates about the track;
:func:`sarmitsuba.analysis.point_target.image_coordinates` and :meth:`sarmitsuba.core.image.SarImage.pixel_of`
map world points this way). Pixel values follow backprojection's convention: the
image of a target of amplitude ``a`` is ``a`` at the target's own pixel position (carrier
phase removed there), so the three focusers agree sample by sample.

References
----------
.. [1] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar
   Data*, Artech House, 2005: ch. 4 (stripmap geometry, squint, Doppler centroid),
   ch. 12 (Doppler centroid estimation: correlation (Madsen) estimator, ambiguity
   resolution from the range walk).
.. [2] S. N. Madsen, "Estimating the Doppler centroid of SAR data", IEEE Trans. Aerosp.
   Electron. Syst. 25(2), 134-140, 1989.
.. [3] F. Wong and I. G. Cumming, "A combined SAR Doppler centroid estimation scheme
   based upon signal phase", IEEE Trans. Geosci. Remote Sens. 34(3), 696-707, 1996.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, NamedTuple, Sequence

import numpy as np
import scipy.fft

from ..core.constants import SPEED_OF_LIGHT
from ..core.raw import RawData
from ..core.arrays import readonly
from .grid import ImageGrid
from .polar import GeometryNotSupported

__all__ = ["StripmapGeometry", "stripmap_geometry", "check_monostatic", "estimate_doppler_centroid",
           "slant_output_grid"]

C = SPEED_OF_LIGHT


# ============================================================================ geometry
@dataclass(frozen=True, eq=False)
class StripmapGeometry:
    """Validated straight-track stripmap geometry of one acquisition.

    Attributes
    ----------
    origin : float64 [3], m
        Zero-Doppler point of ``scene_centre``: the foot of the perpendicular from the scene
        centre to the least-squares track line. Azimuth (along-track) coordinates are
        measured from it, so the scene centre is at azimuth 0 in every focuser's image.
    azimuth_direction : float64 [3]
        Unit track (flight) direction.
    range_direction : float64 [3]
        Unit vector perpendicular to the track, in the plane of the track and
        ``scene_centre``, pointing toward the scene centre.
    scene_centre : float64 [3], m
        Point that fixes the slant plane (stated, from metadata, or the flat-earth default).
    velocity : float, m/s
        Effective velocity ``Vr`` = pulse spacing x PRF (exact for a straight track).
    pulse_spacing : float, m
        Along-track distance between pulses.
    pulse_azimuth : float64 [n_pulses], m
        Along-track coordinate of each antenna position relative to ``origin`` (fitted);
        the mid-aperture antenna is at ``pulse_azimuth.mean()`` (``-R0 tan(squint)`` for a
        beam centred on the scene centre, ``R0`` its closest-approach range).
    prf : float, Hz
    wavelength : float, m
        ``c / fc``.
    reference_range : float, m
        ``R_ref``: closest-approach range of the mid-swath beam centre (or as stated).
    beam_centre_range : float, m
        Two-way delay of the mid-swath sample times ``c / 2``: slant range along the beam
        centre at mid-swath.
    squint : float, rad
        Along-track angle of the beam centre (positive forward), ``asin(lambda f_dc / (2 Vr))``.
    doppler_centroid : float, Hz
        Absolute (unambiguous) Doppler centroid ``f_dc = 2 Vr sin(squint) / lambda``.
    doppler_source : str
        ``"doppler_centroid"``, ``"squint"``, ``"beam_centre"``, ``"metadata"`` or ``"data"``.
    max_cross_track_error, max_along_track_error : float, m
        Largest deviation of the antenna positions from the fitted uniform straight track.
    tolerance : float, m
        Tolerance the deviations were checked against.
    """

    origin: np.ndarray
    azimuth_direction: np.ndarray
    range_direction: np.ndarray
    scene_centre: np.ndarray
    velocity: float
    pulse_spacing: float
    pulse_azimuth: np.ndarray
    prf: float
    wavelength: float
    reference_range: float
    beam_centre_range: float
    squint: float
    doppler_centroid: float
    doppler_source: str
    max_cross_track_error: float
    max_along_track_error: float
    tolerance: float

    # ------------------------------------------------------------------ predictions
    def zero_doppler(self, point: Sequence[float] | np.ndarray) -> tuple[float, float]:
        """``(azimuth, range)`` [m] of a world point: along-track coordinate of its closest
        approach relative to ``origin``, and its distance to the track line."""
        rel = np.asarray(point, dtype=np.float64).reshape(3) - self.origin
        along = float(rel @ self.azimuth_direction)
        return along, float(np.linalg.norm(rel - along * self.azimuth_direction))

    def slant_position(self, azimuth: float, range_: float) -> np.ndarray:
        """World position [m] of slant-plane image coordinates ``(azimuth, range)``."""
        return self.origin + azimuth * self.azimuth_direction + range_ * self.range_direction

    @property
    def doppler_rate_reference(self) -> float:
        """Azimuth FM rate [Hz/s] at ``reference_range`` and the beam centre,
        ``2 Vr^2 cos^3(squint) / (lambda R_ref)`` (Cumming and Wong eq. 4.38)."""
        return 2.0 * self.velocity**2 * np.cos(self.squint) ** 3 / (self.wavelength * self.reference_range)

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable summary (no per-pulse arrays)."""
        return {"origin": self.origin.tolist(), "azimuth_direction": self.azimuth_direction.tolist(),
                "range_direction": self.range_direction.tolist(), "scene_centre": self.scene_centre.tolist(),
                "velocity": self.velocity, "pulse_spacing": self.pulse_spacing, "prf": self.prf,
                "reference_range": self.reference_range, "beam_centre_range": self.beam_centre_range,
                "squint_deg": float(np.degrees(self.squint)), "doppler_centroid": self.doppler_centroid,
                "doppler_source": self.doppler_source, "max_cross_track_error": self.max_cross_track_error,
                "max_along_track_error": self.max_along_track_error, "tolerance": self.tolerance}


def stripmap_geometry(raw: RawData, *, scene_centre: Sequence[float] | None = None,
                      beam_centre: Sequence[float] | None = None, squint: float | None = None,
                      doppler_centroid: float | None = None, reference_range: float | None = None,
                      tolerance: float | None = None) -> StripmapGeometry:
    """Extract and validate the straight-track stripmap geometry of ``raw``.

    Parameters
    ----------
    raw : RawData
        Monostatic data (range compressed or not).
    scene_centre : 3 floats, m, optional
        Point fixing the slant plane (``range_direction`` points toward it). Default:
        ``beam_centre``, else ``metadata["radar"]["scene_center"]`` (the tracer's
        sensor), else the flat-earth default: the point of the ground plane ``z = 0``
        on the look side (``metadata["radar"]["look_side"]``, default right) whose slant
        range from the mid-aperture antenna is the mid-swath beam-centre range, at the
        squint.
    beam_centre : 3 floats, m, optional
        A point the beam centre passes through at mid-aperture; fixes the squint.
    squint : float, deg, optional
        Beam-centre along-track angle (positive forward); overrides ``beam_centre``.
    doppler_centroid : float, Hz, optional
        Absolute Doppler centroid; overrides everything else.
    reference_range : float, m, optional
        ``R_ref``; default: the closest-approach range of the mid-swath beam centre,
        ``c (t_first + t_last) / 4 * cos(squint)``.
    tolerance : float, m, optional
        Largest allowed deviation of the antenna positions from a uniformly sampled
        straight line, both across and along the track, and of the receiver from the
        transmitter. Default ``lambda / 16`` (a two-way phase error of pi/4; a quadratic
        phase error of pi/4 at the aperture edge widens an unweighted impulse response by
        about 1.3 % and lowers its peak by 0.24 dB).

    Returns
    -------
    StripmapGeometry

    Raises
    ------
    ValueError
        When the track is not straight or not uniformly sampled within ``tolerance``
        (use :func:`sarmitsuba.focus.backproject`, which is exact for any track), the data
        are bistatic (:class:`~sarmitsuba.focus.polar.GeometryNotSupported`, a ValueError, from
        :func:`check_monostatic`), the pulse times disagree with ``raw.prf``, the velocity vectors
        disagree with the track by more than 1 %, there are fewer than 2 pulses, a stated
        angle or point is invalid, or no scene centre can be found.

    Notes
    -----
    Squint and Doppler centroid are resolved in this order: ``doppler_centroid``,
    ``squint``, ``beam_centre``, the synthetic generator's ``metadata["beam"]``
    (stripmap squint), the tracer's ``metadata["radar"]["scene_center"]`` (the beam
    points at it), and finally the data (:func:`estimate_doppler_centroid`).
    "Level" here means constant velocity (uniform pulse spacing); a straight track that
    climbs at a constant rate is still a straight line, and the FFT focusers remain exact
    in the cylindrical coordinates about it (the flat-earth default scene centre,
    however, needs a horizontal track).
    """
    if not isinstance(raw, RawData):
        raise TypeError(f"raw must be a sarmitsuba.core.raw.RawData, got {type(raw).__name__}")
    wavelength = C / raw.fc
    tol = _check_sampling(raw, wavelength, tolerance)
    track = _fit_track(raw, tol)
    t_mid = 0.5 * (raw.fast_time[0] + raw.fast_time[-1])
    r_beam = 0.5 * C * t_mid
    meta = raw.metadata if isinstance(raw.metadata, Mapping) else {}
    radar = meta.get("radar") if isinstance(meta.get("radar"), Mapping) else {}
    if beam_centre is not None:
        beam_centre = _point("beam_centre", beam_centre)
    fdc, source = _resolve_doppler_centroid(raw, track, wavelength, doppler_centroid, squint, beam_centre,
                                             meta, radar)
    theta = _squint_of(fdc, track.velocity, wavelength)
    r_ref = r_beam * np.cos(theta) if reference_range is None else _finite("reference_range", reference_range)
    if not r_ref > 0:
        raise ValueError(f"reference_range must be positive, got {r_ref!r} m")
    centre, foot, range_direction = _slant_plane(track, scene_centre, beam_centre, radar, r_beam, theta)
    return StripmapGeometry(
        origin=readonly(track.mean + foot * track.u), azimuth_direction=readonly(track.u),
        range_direction=readonly(range_direction), scene_centre=readonly(centre), velocity=float(track.velocity),
        pulse_spacing=track.spacing, pulse_azimuth=readonly(track.k * track.spacing - foot), prf=float(raw.prf),
        wavelength=wavelength, reference_range=float(r_ref), beam_centre_range=float(r_beam), squint=theta,
        doppler_centroid=float(fdc), doppler_source=source, max_cross_track_error=track.cross,
        max_along_track_error=track.along, tolerance=tol)


def check_monostatic(raw: RawData, focuser: str, tolerance: float = 0.0) -> None:
    """Refuse bistatic stop-and-hop data (a receiver on another platform) with one message.

    Parameters
    ----------
    raw : RawData
        Data to focus; ``raw.rx_time`` given (continuous motion: one antenna that moves during
        the echo, docs/physics.md (J3)) is not bistatic and passes.
    focuser : str
        Name of the focuser that refuses, for the message (e.g. ``"ffbp"``).
    tolerance : float, m, default 0
        Largest distance between ``raw.tx_position`` and ``raw.rx_position`` still taken as
        monostatic.

    Raises
    ------
    GeometryNotSupported
        (a ValueError) When the receiver is farther than ``tolerance`` from the transmitter at some
        pulse: the focuser forms the monostatic two-way range ``2 R``, not the bistatic range sum
        ``R_t + R_r``; the message names :func:`sarmitsuba.focus.backproject`, exact on the range sum.
    """
    if raw.rx_time is not None:
        return
    apart = float(np.max(np.linalg.norm(raw.tx_position - raw.rx_position, axis=1)))
    if apart > tolerance:
        limit = f", tolerance {tolerance:.3g} m" if tolerance > 0 else ""
        raise GeometryNotSupported(
            f"bistatic data: the receiver is not at the transmitter (up to {apart:.4g} m apart{limit}), and "
            f"{focuser} cannot focus them (it forms the monostatic two-way range 2 R, not the bistatic range sum "
            f"R_t + R_r). Use backproject (sarmitsuba.focus.backproject; on the command line --algorithm bp), "
            f"exact on the range sum")


class _Track(NamedTuple):
    """Least-squares uniform straight track ``mean + k * spacing * u`` (:func:`_fit_track`)."""

    k: np.ndarray           # float64 [n_pulses]: pulse index about the middle of the aperture
    mean: np.ndarray        # float64 [3], m: mid-aperture point of the fitted line
    u: np.ndarray           # float64 [3]: unit track direction
    spacing: float          # m per pulse
    velocity: float         # m/s, spacing x PRF
    cross: float            # m, largest deviation across the fitted line
    along: float            # m, largest deviation from uniform spacing along it


def _check_sampling(raw: RawData, wavelength: float, tolerance: float | None) -> float:
    """Step 1: >= 2 pulses, monostatic within the tolerance, uniform PRF; returns the tolerance [m]."""
    n = raw.n_pulses
    if n < 2:
        raise ValueError(f"straight-track focusing needs >= 2 pulses, got {n}")
    tol = wavelength / 16.0 if tolerance is None else float(tolerance)
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tolerance must be a positive number of metres, got {tolerance!r}")
    check_monostatic(raw, "omega-K and range-Doppler (the FFT focusers)", tol)
    dt = np.diff(raw.pulse_time)
    if not np.allclose(dt, 1.0 / raw.prf, rtol=1e-6, atol=0.0):
        raise ValueError(f"pulse_time steps span [{dt.min()!r}, {dt.max()!r}] s, not 1 / prf = {1.0 / raw.prf!r} s: "
                         f"the FFT focusers need a uniform PRF; use backprojection")
    return tol


def _fit_track(raw: RawData, tol: float) -> _Track:
    """Step 2: the least-squares uniform straight line through the antenna positions, checked
    against ``tol`` across and along the track and against ``raw.velocity`` (1 %).

    Continuous-motion data (``raw.rx_time``) are fitted through the midpoints ``(tx + rx) / 2``,
    the effective monostatic phase centres (docs/physics.md (J3)): exact at the range of the echo
    ``rx_time`` was solved for, a target at a range ``R`` elsewhere lies ``|v| (R - R_c) / c``
    further along track."""
    tx = raw.tx_position if raw.rx_time is None else 0.5 * (raw.tx_position + raw.rx_position)
    n = raw.n_pulses
    k = np.arange(n, dtype=np.float64) - (n - 1) / 2.0
    mean = tx.mean(axis=0)
    step = (k @ (tx - mean)) / (k @ k)  # float64 [3], m per pulse
    spacing = float(np.linalg.norm(step))
    if not spacing > 0:
        raise ValueError("the antenna does not move: straight-track focusing needs a moving platform")
    u = step / spacing
    resid = tx - mean - k[:, None] * step[None, :]
    along = resid @ u
    cross = float(np.max(np.linalg.norm(resid - along[:, None] * u[None, :], axis=1)))
    along_err = float(np.max(np.abs(along)))
    if cross > tol:
        raise ValueError(f"the track is not straight: antenna positions deviate up to {cross:.4g} m across the "
                         f"fitted line (tolerance {tol:.4g} m = lambda/16 by default); omega-K and range-Doppler "
                         f"are invalid here, use bp or ffbp (sarmitsuba.focus.backproject, ffbp), exact for any track")
    if along_err > tol:
        raise ValueError(f"the pulses are not uniformly spaced along the track (constant velocity): positions "
                         f"deviate up to {along_err:.4g} m from uniform spacing (tolerance {tol:.4g} m); "
                         f"use bp or ffbp (sarmitsuba.focus.backproject, ffbp)")
    velocity = spacing * raw.prf
    v_data = raw.velocity @ u
    if np.any(np.abs(v_data - velocity) > 0.01 * velocity) or \
            np.any(np.linalg.norm(raw.velocity - v_data[:, None] * u, axis=1) > 0.01 * velocity):
        raise ValueError(f"raw.velocity disagrees by more than 1 % with the track (pulse spacing x PRF = "
                         f"{velocity:.6g} m/s along {u.round(6).tolist()}); check prf and velocity")
    return _Track(k, mean, u, spacing, velocity, cross, along_err)


def _resolve_doppler_centroid(raw: RawData, track: _Track, wavelength: float, doppler_centroid: Any, squint: Any,
                              beam_centre: np.ndarray | None, meta: Mapping[str, Any],
                              radar: Mapping[str, Any]) -> tuple[float, str]:
    """Step 3: absolute Doppler centroid [Hz] ``f_dc = 2 Vr sin(squint) / lambda`` (C&W ch. 4)
    and its source, from the first of: stated centroid, stated squint, beam centre, metadata, data."""
    velocity, mean, u = track.velocity, track.mean, track.u
    if doppler_centroid is not None:
        return _finite("doppler_centroid", doppler_centroid), "doppler_centroid"
    if squint is not None:
        return 2.0 * velocity * np.sin(np.radians(_angle("squint", squint))) / wavelength, "squint"
    if beam_centre is not None:
        return 2.0 * velocity * _sin_along(beam_centre - mean, u) / wavelength, "beam_centre"
    if _metadata_squint(meta) is not None:
        return 2.0 * velocity * np.sin(np.radians(_metadata_squint(meta))) / wavelength, "metadata"
    if radar.get("scene_center") is not None:
        centre = _point("metadata scene_center", radar["scene_center"])
        return 2.0 * velocity * _sin_along(centre - mean, u) / wavelength, "metadata"
    return estimate_doppler_centroid(raw), "data"


def _squint_of(fdc: float, velocity: float, wavelength: float) -> float:
    """Step 4: squint [rad] ``asin(lambda f_dc / (2 Vr))`` (C&W ch. 4), checked to be a stripmap angle."""
    sin_sq = wavelength * fdc / (2.0 * velocity)
    if not abs(sin_sq) < 0.99:
        raise ValueError(f"Doppler centroid {fdc:.6g} Hz implies |sin(squint)| = {abs(sin_sq):.3g} >= 0.99 "
                         f"(Vr = {velocity:.6g} m/s, lambda = {wavelength:.4g} m): not a stripmap geometry")
    return float(np.arcsin(sin_sq))


def _slant_plane(track: _Track, scene_centre: Any, beam_centre: np.ndarray | None, radar: Mapping[str, Any],
                 r_beam: float, theta: float) -> tuple[np.ndarray, float, np.ndarray]:
    """Step 5: scene centre, the along-track coordinate of its closest approach (from the
    mid-aperture point) and the unit range direction toward it, perpendicular to the track."""
    mean, u = track.mean, track.u
    if scene_centre is not None:
        centre = _point("scene_centre", scene_centre)
    elif beam_centre is not None:
        centre = beam_centre
    elif radar.get("scene_center") is not None:
        centre = _point("metadata scene_center", radar["scene_center"])
    else:
        centre = _flat_earth_centre(mean, u, r_beam, theta, str(radar.get("look_side", "right")))
    rel = centre - mean
    foot = float(rel @ u)  # along-track coordinate of the scene centre's closest approach
    perp = rel - foot * u
    norm = float(np.linalg.norm(perp))
    if not norm > 1e-6:
        raise ValueError("the scene centre lies on the track line: it cannot fix the slant plane")
    return centre, foot, perp / norm


def estimate_doppler_centroid(raw: RawData) -> float:
    """Absolute Doppler centroid [Hz] of range-compressed data (or raw chirps).

    The fractional part (modulo PRF) comes from the correlation (Madsen) estimator,
    ``f_frac = PRF / (2 pi) arg sum s(eta + 1, tau) s*(eta, tau)``. The ambiguity number
    comes from the multilook cross-correlation idea of Wong and Cumming: the Doppler
    centroid scales with the transmitted frequency, ``f_dc (f0 + f_tau) / f0``, so the
    same correlation computed separately on the lower and upper halves of the range band
    differs in phase by ``2 pi f_dc Delta f / (f0 PRF)`` (``Delta f`` the distance of the
    two looks' centre frequencies), which gives an unambiguous coarse ``f_dc``; the
    estimate is the ``f_frac + M PRF`` nearest to it.

    Parameters
    ----------
    raw : RawData

    Returns
    -------
    float, Hz

    Raises
    ------
    ValueError
        Fewer than 3 pulses, or zero data.

    Notes
    -----
    One ambiguity corresponds to a look phase difference of ``2 pi Delta f / f0`` (about
    1.7 deg at C band and 25 MHz), so the coarse estimate needs a coherent scene (point
    targets, or clutter averaged over many samples): on noisy or low-contrast data state
    the squint instead (``stripmap_geometry(..., squint=...)``).
    """
    data = raw.data
    n_a, n_r = data.shape
    if n_a < 3:
        raise ValueError("Doppler centroid estimation needs >= 3 pulses")
    n_fft = scipy.fft.next_fast_len(n_r)
    spec = scipy.fft.fft(data, n_fft, axis=1)
    corr = np.einsum("ij,ij->j", np.conj(spec[:-1]), spec[1:])  # per range frequency bin
    freqs = np.fft.fftfreq(n_fft, 1.0 / raw.fs)
    power = np.einsum("ij,ij->j", np.conj(spec), spec).real
    total = corr[np.abs(freqs) <= raw.bandwidth / 2].sum()
    if total == 0:
        raise ValueError("the data are zero: cannot estimate the Doppler centroid; state the squint instead")
    f_frac = raw.prf * float(np.angle(total)) / (2.0 * np.pi)
    lower = (freqs < 0) & (freqs >= -raw.bandwidth / 2)
    upper = (freqs >= 0) & (freqs <= raw.bandwidth / 2)
    d_f = (freqs[upper] @ power[upper] / power[upper].sum() - freqs[lower] @ power[lower] / power[lower].sum())
    d_phi = float(np.angle(corr[upper].sum() * np.conj(corr[lower].sum())))
    f_coarse = d_phi * raw.fc * raw.prf / (2.0 * np.pi * d_f)
    m = np.round((f_coarse - f_frac) / raw.prf)
    return float(f_frac + m * raw.prf)


def slant_output_grid(geometry: StripmapGeometry, raw: RawData, *, n_azimuth: int | None = None,
                      n_range: int | None = None) -> ImageGrid:
    """The slant-plane output grid of the FFT focusers (module docstring).

    Parameters
    ----------
    geometry : StripmapGeometry
    raw : RawData
        For ``fs`` and the default sizes.
    n_azimuth, n_range : int, optional
        Grid size; default ``raw.data.shape``.

    Returns
    -------
    ImageGrid
        ``plane == "slant"``, ``origin`` the scene centre's zero-Doppler point on the track
        (``geometry.origin``). ``range[j] = R_ref + (j - n_range // 2) c / (2 fs)`` (absolute
        zero-Doppler slant range: distance from the track line); ``azimuth[i] = x_c +
        (i - n_azimuth // 2) V / PRF`` with ``x_c = x_mid + R_ref tan(squint)``, the zero-Doppler
        along-track coordinate of the point at ``R_ref`` on the beam centre at mid-aperture
        (``x_mid = mean(pulse_azimuth)``, the mid-aperture antenna; ``x_c`` is about 0 when the
        beam centre passes through the scene centre). An FFT focuser's image is
        periodic in azimuth with period ``n_azimuth V / PRF``: in squinted geometry a
        target whose zero-Doppler coordinate falls outside the grid wraps around.
    """
    n_a = raw.n_pulses if n_azimuth is None else _count("n_azimuth", n_azimuth)
    n_r = raw.n_samples if n_range is None else _count("n_range", n_range)
    dr = C / (2.0 * raw.fs)
    x_c = float(np.mean(geometry.pulse_azimuth)) + geometry.reference_range * np.tan(geometry.squint)
    rng = geometry.reference_range + (np.arange(n_r, dtype=np.float64) - n_r // 2) * dr
    az = x_c + (np.arange(n_a, dtype=np.float64) - n_a // 2) * geometry.pulse_spacing
    if rng[0] <= 0:
        raise ValueError(f"the output range axis reaches {rng[0]:.4g} m <= 0: too many range samples for R_ref")
    return ImageGrid(origin=geometry.origin, azimuth_direction=geometry.azimuth_direction,
                     range_direction=geometry.range_direction, azimuth=az, range=rng, plane="slant")


# ============================================================================ validation helpers
def _point(name: str, value: Any) -> np.ndarray:
    arr = np.array(value, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be 3 finite numbers (x, y, z in metres), got {value!r}")
    return arr


def _finite(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if not np.isfinite(v):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return v


def _angle(name: str, value: Any) -> float:
    v = _finite(name, value)
    if not -80.0 < v < 80.0:
        raise ValueError(f"{name} must be in (-80, 80) deg, got {value!r}")
    return v


def _count(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 2:
        raise ValueError(f"{name} must be an integer >= 2, got {value!r}")
    return int(value)


def _sin_along(los: np.ndarray, u: np.ndarray) -> float:
    return float(los @ u / np.linalg.norm(los))


def _metadata_squint(meta: Mapping[str, Any]) -> float | None:
    """Squint [deg] of the synthetic generator's stripmap beam, when recorded."""
    beam = meta.get("beam")
    if isinstance(beam, Mapping) and beam.get("mode") == "stripmap" and beam.get("squint_deg") is not None:
        return _angle("metadata beam squint_deg", beam["squint_deg"])
    return None


def _flat_earth_centre(antenna: np.ndarray, u: np.ndarray, r_beam: float, theta: float, look: str) -> np.ndarray:
    """Point of the plane z = 0 at slant range ``r_beam`` and squint ``theta`` from ``antenna``."""
    if abs(u[2]) > 1e-6:
        raise ValueError("the flat-earth default scene centre needs a horizontal track; give scene_centre")
    h = float(antenna[2])
    r0 = r_beam * np.cos(theta)
    if not (h > 0 and r0 > h):
        raise ValueError(f"no flat-earth scene centre: antenna height {h:.6g} m and closest-approach range "
                         f"{r0:.6g} m (need 0 < height < range); give scene_centre")
    right = np.cross(u, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    if look == "left":
        right = -right
    ground = np.sqrt(r0**2 - h**2)
    return antenna + r_beam * np.sin(theta) * u + ground * right - np.array([0.0, 0.0, h])
