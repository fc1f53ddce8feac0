"""The unit-peak impulse response of a backprojected image, from its metadata, and the RCS it gives.

A point target of RCS ``sigma`` imaged with unit peak gain carries the integrated energy
``int |I|^2 dA = sigma rho_E,az rho_E,rg`` (docs/physics.md (K2)): :func:`energy_widths` gives the
energy widths ``rho_E`` of the image's unit-peak response from the focusing recorded in its
metadata (bandwidth, windows, antenna pattern, geometry), :class:`ImpulseModel` also the share of
that energy inside a box, and :func:`integrated_rcs` the RCS by the integral method (Gray et al.,
IEEE TGRS 28(3), 1990). :func:`sarmitsuba.analysis.point_target.analyze_point_target` uses the same model.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage, image_coordinates, image_track

__all__ = ["energy_widths", "ImpulseModel", "integrated_rcs"]

#: Samples of u in [0, 1] for the azimuth energy-width quadrature (Simpson).
_QUADRATURE = 8193


def energy_widths(image: SarImage, position: Sequence[float] | None = None) -> tuple[float, float]:
    """Energy widths ``(rho_E,az, rho_E,rg)`` [m] of the image's unit-peak impulse response.

    A point target of RCS ``sigma`` imaged with unit peak gain (peak ``sqrt(sigma)``) carries the
    integrated energy ``int |I|^2 dA = sigma rho_E,az rho_E,rg`` (docs/physics.md (K2)). By
    Parseval, for a response ``I(x) = int W(s) exp(j 4 pi s x / lambda) ds / int W ds`` along the
    track and the range pulse of a window ``w_r`` over the band ``B``:

    * range: ``rho_E,rg = c / (2 B) * energy_width(w_r) / n_r``, with ``energy_width`` of
      :mod:`sarmitsuba.focus.windows` (``int w^2 / (int w)^2``, 1 for rect, 1.23 for Taylor
      4 / -35 dB) and ``n_r = n . e_rg`` the projection on the image's range axis of the unit
      vector ``n`` from the target's zero-Doppler point on the track to the target
      (``sin(theta_inc)`` for a flat ground-plane image, 1 for a slant-plane one);
    * azimuth: ``rho_E,az = (lambda / 2) int S(s)^2 cos(phi) ds / (int S(s) ds)^2`` over the
      along-track sines ``s = sin(phi)`` of the processed beam, ``S = W rho`` the Doppler
      weighting ``W`` (the azimuth window ``w(u)``, ``u = (s - sin_lo) / (sin_hi - sin_lo)``,
      times the two-way pattern ``sinc^2(L / lambda * sin(phi - squint))`` when the data carry
      one) times the pulses' density ``rho ~ cos(phi)^-3`` in ``s`` (a straight track, pulses
      evenly spaced); on a curved track the target sees the sines sweep ``kappa`` times as fast
      (``metadata["focus"]["sine_scale"]``, :func:`sarmitsuba.focus.beam.sine_scale`; 1.09 on an
      orbit at 500 km), which divides ``rho_E,az`` by ``kappa``. ``cos(phi)`` is the Jacobian of the 2-D wavenumber support (range and
      azimuth frequencies are not orthogonal under squint). For a narrow beam at broadside
      this is ``(lambda / 2) int W^2 ds / (int W ds)^2``: ``lambda / (4 sin(beta / 2))`` for a
      uniform beam of width ``beta``, ``energy_width(w)`` times that with a window. Without a
      beam (spotlight) ``u`` is the pulse's place in the aperture and ``s`` its sine seen from
      the target.

    Parameters
    ----------
    image : SarImage
        A backprojected image (:func:`sarmitsuba.focus.backproject`), whose
        ``metadata["focus"]`` records ``fc``, ``bandwidth``, ``window_range``,
        ``window_azimuth``, ``azimuth_pattern``, ``beam_sines`` and ``track``; image axes
        along the track and across it.
    position : 2 floats (azimuth, range image coordinates, m) or 3 (world, m), optional
        Where the target is (``n_r`` and, without a beam, the sines depend on it); default the
        image centre.

    Returns
    -------
    (rho_E,az, rho_E,rg) : tuple of float, m

    Raises
    ------
    ValueError
        When the metadata lack any of these keys or hold invalid values.
    """
    model = ImpulseModel(image, position)
    return model.rho_az, model.rho_rg


class ImpulseModel:
    """The unit-peak impulse response of a backprojected image at one position, from its
    metadata (see :func:`energy_widths`): energy widths and the energy fraction a box holds.

    Parameters
    ----------
    image : SarImage
        Image whose ``metadata["focus"]`` records ``fc``, ``bandwidth``, ``window_range``,
        ``window_azimuth`` and ``track`` (plus ``beam_sines``, ``azimuth_pattern``, ``squint``
        when focused over a beam).
    position : 2 floats (azimuth, range image coordinates, m) or 3 (world, m), or None
        Where the target is; None for the image centre.

    Attributes
    ----------
    rho_az, rho_rg : float, m
        Energy widths ``int |h|^2`` of the unit-peak response along the image axes.

    Raises
    ------
    ValueError
        When the metadata lack a key or hold invalid values.
    """

    def __init__(self, image: SarImage, position: Sequence[float] | None):
        from ..focus.windows import energy_width, spectral_window, window_spec
        focus = image.metadata.get("focus") if isinstance(image.metadata, dict) else None
        keys = ("fc", "bandwidth", "window_range", "window_azimuth", "track")
        if not isinstance(focus, dict) or any(k not in focus for k in keys):
            raise ValueError(f"energy widths need image.metadata['focus'] with {', '.join(keys)} (a backprojected "
                             "image); pass resolution=(rho_az, rho_rg) for other images")
        try:
            fc, bandwidth = float(focus["fc"]), float(focus["bandwidth"])
            self.w_rg = window_spec((focus["window_range"]["name"],
                                     {k: v for k, v in focus["window_range"].items() if k != "name"}))
            w_az = window_spec((focus["window_azimuth"]["name"],
                                {k: v for k, v in focus["window_azimuth"].items() if k != "name"}))
        except (TypeError, KeyError, AttributeError) as exc:
            raise ValueError(f"image.metadata['focus'] holds no valid windows ({exc})") from None
        track = image_track(image)
        if track is None or not (fc > 0 and bandwidth > 0):
            raise ValueError("image.metadata['focus'] needs fc > 0, bandwidth > 0 and the track")
        a_point, t = track
        if position is None:
            position = (float(image.azimuth[image.azimuth.size // 2]), float(image.range[image.range.size // 2]))
        az, rg = image_coordinates(image, position)
        e_r = np.asarray(image.range_direction, float)
        q = np.asarray(image.origin, float) + az * np.asarray(image.azimuth_direction, float) + rg * e_r
        foot = a_point + float((q - a_point) @ t) * t
        r0 = float(np.linalg.norm(q - foot))
        n_r = abs(float((q - foot) @ e_r)) / r0 if r0 > 0 else 0.0
        if n_r < 1e-6:
            raise ValueError("the image's range axis is normal to the line of sight: no range resolution")
        self.bandwidth, self.n_r = bandwidth, n_r
        self.rho_rg = SPEED_OF_LIGHT / (2.0 * bandwidth) * energy_width(self.w_rg[0], **self.w_rg[1]) / n_r

        u = np.linspace(0.0, 1.0, _QUADRATURE)
        w = spectral_window(w_az[0], u - 0.5, 1.0, **w_az[1])
        sines = focus.get("beam_sines")
        scale = 1.0
        if sines is not None:
            sin_lo, sin_hi = (float(v) for v in sines)
            # the target's sines per beam sine on a curved track (1 on a straight one; an orbit's
            # 1.09 at 500 km, focus.beam.sine_scale): the support is that much wider (K2), (J7)
            scale = float(focus.get("sine_scale") or 1.0)
            if not (np.isfinite(scale) and scale > 0):
                raise ValueError(f"image.metadata['focus']['sine_scale'] = {scale!r} must be a finite number > 0")
            u = _track_cut(u, focus, float((q - a_point) @ t), r0, sin_lo, sin_hi, scale)
            w = spectral_window(w_az[0], u - 0.5, 1.0, **w_az[1])
            sine = sin_lo + u * (sin_hi - sin_lo)
            slope = np.full_like(u, (sin_hi - sin_lo) * scale)            # d(target's sine) / du
            amplitude = w / (1.0 - sine ** 2) ** 1.5                      # W rho per du
            pattern = focus.get("azimuth_pattern")
            if pattern is not None:
                squint = np.radians(float(focus.get("squint") or 0.0))
                power = int(focus.get("pattern_power") or 2)        # 1: one way, a receiver of its own (B3)
                amplitude = amplitude * np.sinc(float(pattern) * np.sin(np.arcsin(sine) - squint)) ** power
        else:
            length = float(focus["track"].get("length") or 0.0) if isinstance(focus["track"], dict) else 0.0
            if not length > 0:
                raise ValueError("image.metadata['focus']['track'] needs the aperture length for a beamless image")
            along = float((q - a_point) @ t) - (u - 0.5) * length          # target minus antenna, along track
            sine = along / np.hypot(along, r0)
            slope = length * (1.0 - sine ** 2) ** 1.5 / r0                 # |ds / du|
            amplitude = w
        self.wavelength = SPEED_OF_LIGHT / fc
        self.u, self.sine, self.slope, self.amplitude = u, scale * sine, slope, amplitude
        cos_phi = np.sqrt(1.0 - sine ** 2)
        self.rho_az = float(0.5 * self.wavelength * _simpson(amplitude ** 2 * cos_phi / slope, u)
                            / _simpson(amplitude, u) ** 2)

    def response(self, d_az: np.ndarray, d_rg: np.ndarray) -> np.ndarray:
        """The unit-peak impulse response at offsets ``d_az``, ``d_rg`` [m] from the target (any
        matching shapes), complex (separable model, its carrier phase left out): azimuth
        ``int A(u) exp(j 4 pi s(u) x / lambda) du / int A du``, range the window's compressed
        pulse at ``2 n_r B d_rg / c`` (:func:`~sarmitsuba.focus.windows.compressed_pulse`)."""
        import scipy.integrate

        from ..focus.windows import compressed_pulse
        d_az, d_rg = np.broadcast_arrays(np.asarray(d_az, float), np.asarray(d_rg, float))
        phase = np.exp(4j * np.pi / self.wavelength * np.outer(d_az.ravel(), self.sine))
        az = scipy.integrate.simpson(phase * self.amplitude, x=self.u, axis=1) / _simpson(self.amplitude, self.u)
        name, params = self.w_rg
        rg = compressed_pulse(2.0 * self.n_r * self.bandwidth * d_rg.ravel() / SPEED_OF_LIGHT, 1.0, name, **params)
        return (az * rg).reshape(d_az.shape)

    def fraction(self, half_azimuth: float, half_range: float) -> float:
        """Energy fraction of the unit-peak response inside ``|d_az| <= half_azimuth``,
        ``|d_rg| <= half_range`` [m] (separable model): the box of an integrated-energy RCS.

        Range: ``int p^2`` of the window's closed-form pulse over the box, over its energy
        width. Azimuth: ``|I(x)|^2``, ``I(x) = int A(u) exp(j 4 pi s(u) x / lambda) du``,
        integrated over the box, over ``(lambda / 2) int A^2 / (ds/du) du`` (Parseval)."""
        import scipy.integrate

        from ..focus.windows import compressed_pulse, energy_width
        name, params = self.w_rg
        v_max = 2.0 * self.n_r * self.bandwidth * half_range / SPEED_OF_LIGHT   # box half-width in 1 / B
        edges = np.append(np.arange(0.0, v_max, 1.0), v_max)
        inside = 2.0 * sum(scipy.integrate.quad(lambda v: compressed_pulse(v, 1.0, name, **params) ** 2, a, b,
                                                epsabs=0, epsrel=1e-10)[0] for a, b in zip(edges[:-1], edges[1:]))
        f_rg = inside / energy_width(name, **params)
        # azimuth: the cut sampled at 1/16 of its nominal resolution, Simpson over the box
        total = 0.5 * self.wavelength * _simpson(self.amplitude ** 2 / self.slope, self.u)
        span = float(np.ptp(self.sine))
        n = 2 * int(np.ceil(16.0 * half_azimuth * 2.0 * span / self.wavelength)) + 1
        x = np.linspace(-half_azimuth, half_azimuth, max(n, 33))
        cut = np.empty(x.size)
        for k in range(0, x.size, 256):
            phase = np.exp(4j * np.pi / self.wavelength * np.outer(x[k:k + 256], self.sine))
            cut[k:k + 256] = np.abs(scipy.integrate.simpson(phase * self.amplitude, x=self.u, axis=1)) ** 2
        f_az = _simpson(cut, x) / total
        return float(min(f_az, 1.0) * min(f_rg, 1.0))


def _track_cut(u: np.ndarray, focus: dict, along: float, r0: float, sin_lo: float, sin_hi: float,
               scale: float) -> np.ndarray:
    """The beam's abscissae ``u`` (its sines ``sin_lo + u (sin_hi - sin_lo)``) that the track
    fills as seen from a point ``along`` [m] from the track's centre and ``r0`` [m] from it: a
    track shorter than the beam (a few pulses) puts the point in only part of the processed beam,
    and the window there is cut (the focusers weight each pulse by where the point sits in its
    beam). ``u`` resampled over that part, float [n]; unchanged when the track covers the beam or
    its length is unknown. The point's sine ``(x - A) . t / |x - A|`` runs over
    ``(along -+ L / 2) / hypot(along -+ L / 2, r0)`` and is ``scale`` times the beam's ((J7))."""
    track = focus.get("track")
    length = float(track.get("length") or 0.0) if isinstance(track, dict) else 0.0
    if not length > 0 or not sin_hi > sin_lo:
        return u
    ends = np.array([along - 0.5 * length, along + 0.5 * length])
    seen = ends / np.hypot(ends, r0) / scale
    u0, u1 = np.clip((seen - sin_lo) / (sin_hi - sin_lo), 0.0, 1.0)
    if u0 <= 0.0 and u1 >= 1.0:
        return u
    if not u1 > u0:
        raise ValueError("the point lies outside every pulse's processed beam: no azimuth response to model")
    return np.linspace(u0, u1, u.size)


def _simpson(y: np.ndarray, x: np.ndarray) -> float:
    """Simpson's rule of samples ``y`` over abscissae ``x`` (float [n] each)."""
    import scipy.integrate
    return float(scipy.integrate.simpson(y, x=x))


# ============================================================================ RCS
def integrated_rcs(image: SarImage, resolution_azimuth: float | None = None, resolution_range: float | None = None,
                   center: Sequence[float] = (0.0, 0.0), half_cells: float = 6.0) -> float:
    """RCS [m^2] by integrated point energy: ``sum |I|^2 dA / (rho_az rho_rg)`` over a box of
    +-``half_cells`` energy widths around ``center`` (docs/physics.md (K), (K2)).

    Parameters
    ----------
    image : SarImage
        A calibrated image whose unit point target has unit peak (every focuser here).
    resolution_azimuth, resolution_range : float, m, optional
        Energy widths ``rho_az``, ``rho_rg`` of the unit-peak impulse response; default (both
        None) from the image metadata at ``center``, :func:`energy_widths` (window, pattern and
        geometry included, so rect and Taylor images read the same RCS).
    center : 2 floats (azimuth, range image coordinates, m) or 3 (world point, m)
        Box centre; a world point is taken at its layover position (:func:`image_coordinates`).
    half_cells : float, default 6
        Half-size of the box in energy widths. With widths from the metadata, the share of
        the response's energy outside the box (a rect image's far sidelobes) is restored from
        the same model.

    Returns
    -------
    float, m^2 (no clutter subtraction; see :func:`sarmitsuba.analysis.point_target.analyze_point_target` for that)

    Raises
    ------
    ValueError
        When only one resolution is given, or the metadata cannot provide them.
    """
    center = image_coordinates(image, center)
    if (resolution_azimuth is None) != (resolution_range is None):
        raise ValueError("give both resolution_azimuth and resolution_range, or neither (then from the metadata)")
    model = None
    if resolution_azimuth is None:
        model = ImpulseModel(image, center)
        resolution_azimuth, resolution_range = model.rho_az, model.rho_rg
    az, rg = np.meshgrid(image.azimuth - center[0], image.range - center[1], indexing="ij")
    box = (np.abs(az) <= half_cells * resolution_azimuth) & (np.abs(rg) <= half_cells * resolution_range)
    d_az, d_rg = abs(image.azimuth[1] - image.azimuth[0]), abs(image.range[1] - image.range[0])
    fraction = 1.0 if model is None else model.fraction(0.5 * box.any(axis=1).sum() * d_az,
                                                        0.5 * box.any(axis=0).sum() * d_rg)
    return float((np.abs(image.data[box]) ** 2).sum() * d_az * d_rg
                 / (resolution_azimuth * resolution_range * fraction))
