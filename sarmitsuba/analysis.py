"""Point-target analysis of focused images (docs/design.md section 8; procedure of [1]_ and [2]_).

:func:`analyze_point_target` measures a point target's impulse response the way ISCE3
(``isce3.cal.point_target_info``) and the Aresys quality toolkit do:

1. cut a ``chip x chip`` window around the target (re-centred once on the brightest pixel
   near it);
2. estimate the linear phase ramp (spectral centroid) of the chip and remove it, so the
   chip is at baseband. A ground-plane backprojected image carries its carrier as a ramp
   of up to tens of radians per pixel, aliased by the pixel grid; without this step the
   FFT interpolation between pixels would be meaningless;
3. interpolate the baseband chip exactly as a band-limited (periodic) signal: the DFT
   interpolant with the Nyquist bin split symmetrically, evaluated by small matrix
   products at any sub-pixel position (equivalent to ``oversample``-fold FFT zero padding,
   without the ``(chip * oversample)^2`` array), and restore the ramp for phases;
4. locate the peak on the ``oversample``-fold grid, then refine it on the interpolant;
5. take azimuth and range cuts through the peak (sampled every ``1 / oversample`` pixel) and
   measure the -3 dB width (IRW), the first nulls, PSLR and ISLR, the peak magnitude and
   phase, the offset from the prediction, and the integrated energy with clutter removed.

Definitions (every report field carries its unit):

* **IRW**: -3 dB width of ``|I|^2`` along the cut, in metres along the image axis.
* **PSLR**: ``10 log10(max sidelobe / peak)`` of ``|I|^2``, sidelobes outside the first
  nulls (found by a null search: the first local minima either side of the peak) and
  within the ISLR extent below.
* **ISLR (1-D, null-bounded)**: ``10 log10(E_side / E_main)``; ``E_main`` is the energy of
  ``|I|^2`` between the first nulls, ``E_side`` the energy from the first nulls out to
  ``sidelobes`` (default 10) null distances beyond them on each side, or to the chip edge
  when that comes first (ISCE3's ``num_sidelobes`` convention). For an unweighted sinc:
  -10.11 dB at 10 null distances, -9.68 dB for infinite extent
  (:func:`sarmitsuba.focus.windows.islr_theory`).
* **Peak phase**: phase of the ramp-restored interpolant at the peak (ISCE3). Between
  pixels this is only physical when the ramp is the true carrier: an estimated ramp is
  wrapped to ``[-pi, pi)`` per pixel, so pass ``carrier`` (e.g. from :func:`carrier_ramp`)
  for ground-plane backprojected images, or read the phase at a pixel centre.
* **Integrated energy**: ``sum |I|^2 * (pixel area)`` over the pixels within
  ``energy_extent`` first-null distances of the peak on each axis (a box), minus the mean
  clutter power of the four ``chip/8``-square chip corners times the box's pixel count.
  Unit: m^2 times the image's intensity unit (m^2 x m^2 in normalised radiometry).
  **RCS** ``= integrated_energy / (rho_E,az rho_E,rg)``, with ``rho_E`` the energy widths
  ``int |h|^2`` of the unit-peak impulse response along each axis: given as ``resolution``, or
  derived from the image metadata by :func:`energy_widths` (docs/physics.md (K2)), so that the
  same target reads the same RCS whatever the focusing window.
* **Target position**: a world point (3 numbers) is looked for where the focuser puts it,
  :func:`image_coordinates`: at the intersection of its zero-Doppler plane with the image
  plane, at its closest-approach slant range from the straight track (a point above a
  ground-plane image lays over toward the sensor, docs/physics.md (G2)).

References
----------
.. [1] ISCE3, ``python/packages/isce3/cal/point_target_info.py`` (chip, ramp estimate,
   Nyquist split, null search, ``num_sidelobes``).
.. [2] Aresys, ``arepyextras-quality`` point-target analysis documentation (clutter from
   the four chip corners, RCS by the integral method).
.. [3] A. L. Gray, P. W. Vachon, C. E. Livingstone and T. I. Lukowski, "Synthetic aperture
   radar calibration using reference reflectors", IEEE TGRS 28(3), 374-383, 1990
   (integral method).
.. [4] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar Data*,
   Artech House, 2005 (sections 2.6 and 4.5: window broadening, Doppler bandwidth and
   azimuth resolution; section 4.2: zero-Doppler geometry).
.. [5] W. G. Carrara, R. S. Goodman and R. M. Majewski, *Spotlight Synthetic Aperture Radar*,
   Artech House, 1995, appendix D (Taylor weighting).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, dataclass, replace
from typing import Any, Sequence

import numpy as np
import scipy.optimize

from .bandlimited import Interpolant2D
from .constants import SPEED_OF_LIGHT
from .image import SarImage

__all__ = ["PointTargetReport", "analyze_point_target", "carrier_ramp", "image_coordinates", "layover_position",
           "energy_widths", "integrated_rcs", "add_arguments", "run", "main"]


# ============================================================================ report
@dataclass(frozen=True)
class PointTargetReport:
    """Result of :func:`analyze_point_target`. All positions are image coordinates in metres
    along the image axes (``SarImage.azimuth`` / ``SarImage.range``) unless named otherwise.

    Attributes
    ----------
    azimuth, range : float, m
        Peak position (range is ground range for ``plane == "ground"``, slant range for
        ``"slant"``).
    row, column : float
        The same as fractional pixel indices of the image.
    world_position : tuple of 3 floats, m
        ``origin + azimuth * azimuth_direction + range * range_direction`` (the image's
        linear grid model; for a slant image a point of the slant plane).
    plane : str
        ``"ground"`` or ``"slant"``.
    predicted_azimuth, predicted_range : float, m
        Where the peak was expected (``predicted``, else the ``target`` argument).
    azimuth_error, range_error : float, m
        Peak minus predicted position.
    azimuth_error_cells, range_error_cells : float
        Errors in resolution cells (divided by the measured IRW).
    irw_azimuth, irw_range : float, m
        -3 dB impulse-response widths.
    first_null_azimuth, first_null_range : float, m
        Mean distance from the peak to the first nulls (null search).
    pslr_azimuth_db, pslr_range_db : float, dB
        Peak sidelobe ratios (sidelobes outside the first nulls).
    islr_azimuth_nullbounded_db, islr_range_nullbounded_db : float, dB
        1-D ISLR with a null-bounded mainlobe and sidelobes out to ``islr_sidelobes``
        null distances beyond the nulls, or to the chip edge.
    islr_sidelobes : float
        Requested sidelobe extent, in first-null distances.
    islr_extent_azimuth, islr_extent_range : float
        Extent actually integrated (smaller when the chip edge came first).
    peak_magnitude : float
        ``|I|`` at the peak (image units; ``|a|`` for a target of amplitude ``a`` focused
        to unit gain).
    peak_phase_deg : float, deg
        Phase at the peak of the ramp-restored interpolant, in (-180, 180].
    predicted_magnitude : float or None
        ``|I|`` at the predicted position (None when it lies outside the chip).
    predicted_phase_deg : float or None, deg
        Phase of the ramp-restored interpolant at the predicted position: with the true
        carrier this is insensitive to small peak offsets, unlike ``peak_phase_deg``.
    phase_ramp_azimuth, phase_ramp_range : float, rad / pixel
        Linear phase ramp removed before interpolation.
    carrier : str
        ``"estimated"`` (spectral centroid of the chip, wrapped) or ``"given"``.
    integrated_energy : float, m^2 x intensity unit
        Clutter-corrected energy in the box of ``energy_extent`` null distances.
    clutter_level : float, intensity unit
        Mean ``|I|^2`` per pixel in the four chip corners.
    energy_extent : float
        Half-size of the energy box, in first-null distances.
    rcs : float or None, m^2
        ``integrated_energy / (rho_az rho_rg)`` when the energy widths are known (given as
        ``resolution``, or from the image metadata, :func:`energy_widths`).
    rcs_db : float or None, dBsm
        ``10 log10(rcs)``.
    chip, oversample : int
        Chip size [pixels] and oversampling factor used.
    energy_width_azimuth, energy_width_range : float or None, m
        The energy widths ``rho_az``, ``rho_rg`` the RCS was divided by.
    energy_fraction : float or None
        With energy widths from the metadata: the share of the unit-peak response's energy
        inside the integration box (model of :func:`energy_widths`), also divided out, so that
        a rect image's sidelobes beyond the box do not bias its RCS low (None when
        ``resolution`` was given: then nothing is assumed about the response's shape).
    """

    azimuth: float
    range: float
    row: float
    column: float
    world_position: tuple[float, float, float]
    plane: str
    predicted_azimuth: float
    predicted_range: float
    azimuth_error: float
    range_error: float
    azimuth_error_cells: float
    range_error_cells: float
    irw_azimuth: float
    irw_range: float
    first_null_azimuth: float
    first_null_range: float
    pslr_azimuth_db: float
    pslr_range_db: float
    islr_azimuth_nullbounded_db: float
    islr_range_nullbounded_db: float
    islr_sidelobes: float
    islr_extent_azimuth: float
    islr_extent_range: float
    peak_magnitude: float
    peak_phase_deg: float
    predicted_magnitude: float | None
    predicted_phase_deg: float | None
    phase_ramp_azimuth: float
    phase_ramp_range: float
    carrier: str
    integrated_energy: float
    clutter_level: float
    energy_extent: float
    rcs: float | None
    rcs_db: float | None
    chip: int
    oversample: int
    energy_width_azimuth: float | None = None
    energy_width_range: float | None = None
    energy_fraction: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable dict of all fields (floats, ints, strings, lists, None)."""
        out: dict[str, Any] = {}
        for key, value in asdict(self).items():
            if isinstance(value, tuple):
                value = [float(v) for v in value]
            elif isinstance(value, (np.floating, np.integer)):
                value = value.item()
            if isinstance(value, float) and not math.isfinite(value):
                value = None
            out[key] = value
        return out


# ============================================================================ geometry helpers
def _axis_step(name: str, axis: np.ndarray) -> float:
    if axis.size < 2:
        raise ValueError(f"image.{name} must have >= 2 samples for point-target analysis, got {axis.size}")
    step = np.diff(axis)
    d = float(step.mean())
    if not np.allclose(step, d, rtol=1e-6, atol=0.0) or d <= 0:
        raise ValueError(f"image.{name} must be uniformly spaced and increasing; steps span "
                         f"[{step.min()!r}, {step.max()!r}] m")
    return d


def image_coordinates(image: SarImage, point: Sequence[float] | np.ndarray, *,
                      layover: bool = True) -> tuple[float, float]:
    """``(azimuth, range)`` image coordinates [m] where a world point appears, or a coordinate pair.

    Parameters
    ----------
    image : SarImage
    point : 3 floats (world position, m) or 2 floats (azimuth, range in m)
        A world point is mapped through the range / zero-Doppler geometry when the image
        metadata record the straight track (``metadata["focus"]["track"]`` of a
        backprojected image, ``metadata["focus"]["geometry"]`` of an omega-K or RDA image,
        or sarmitsuba's ``metadata["radar"]``): see
        :func:`layover_position`. Otherwise, or with ``layover=False``, it is projected
        orthogonally on the image axes, ``((x - origin) . azimuth_direction,
        (x - origin) . range_direction)``. Both agree for a point on the image plane.
    layover : bool, default True
        Map world points through the imaging geometry when it is known.

    Raises
    ------
    ValueError
        When ``point`` is not 2 or 3 finite numbers, or the point's closest-approach circle
        does not meet the image plane.
    """
    p = np.asarray(point, dtype=np.float64).reshape(-1)
    if p.size not in (2, 3) or not np.all(np.isfinite(p)):
        raise ValueError(f"a target must be 3 finite numbers (world x, y, z in m) or 2 (azimuth, range in m), "
                         f"got {point!r}")
    if p.size == 2:
        return float(p[0]), float(p[1])
    if layover and _track_of(image) is not None:
        return layover_position(image, p)
    rel = p - image.origin
    return float(rel @ image.azimuth_direction), float(rel @ image.range_direction)


def _track_of(image: SarImage) -> tuple[np.ndarray, np.ndarray] | None:
    """(a point of the straight track, its unit direction), float64 [3] each, from the image
    metadata: the backprojection's ``focus["track"]`` (mid-aperture transmitter, unit velocity),
    else the FFT focusers' ``focus["geometry"]`` (its ``origin`` lies on the fitted track line,
    ``azimuth_direction`` along it), else the acquisition geometry of sarmitsuba's ``radar``
    parameters; None when none of them."""
    meta = image.metadata if isinstance(image.metadata, dict) else {}
    focus = meta.get("focus") if isinstance(meta.get("focus"), dict) else {}
    for record, point_key, direction_key in ((focus.get("track"), "position", "direction"),
                                             (focus.get("geometry"), "origin", "azimuth_direction")):
        line = _line_of(record, point_key, direction_key)
        if line is not None:
            return line
    params = _radar_of(image)
    if params is None:
        return None
    from .radar import acquisition_geometry
    geometry = acquisition_geometry(replace(params, n_pulses=max(params.n_pulses, 1)))
    return geometry.positions[len(geometry.positions) // 2], geometry.track_direction


def _line_of(record: Any, point_key: str, direction_key: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(point, unit direction) of a track line recorded as ``record[point_key]``,
    ``record[direction_key]`` (3 finite numbers each); None when absent or malformed."""
    if not isinstance(record, dict) or record.get(point_key) is None or record.get(direction_key) is None:
        return None
    try:
        point = np.asarray(record[point_key], float).reshape(3)
        direction = np.asarray(record[direction_key], float).reshape(3)
    except (TypeError, ValueError):
        return None
    norm = float(np.linalg.norm(direction))
    if not (np.all(np.isfinite(point)) and np.isfinite(norm) and norm > 0):
        return None
    return point, direction / norm


def _radar_of(image: SarImage):
    """The RadarParameters recorded in the image metadata (sarmitsuba renders), or None."""
    meta = image.metadata if isinstance(image.metadata, dict) else {}
    if not isinstance(meta.get("radar"), dict):
        return None
    from .radar import RadarParameters
    try:
        params = RadarParameters.from_mapping({k: v for k, v in meta["radar"].items() if v is not None})
    except (TypeError, ValueError, KeyError):
        return None
    return params if params.scene_center is not None else None


def layover_position(image: SarImage, point: Sequence[float] | np.ndarray) -> tuple[float, float]:
    """``(azimuth, range)`` image coordinates [m] at which a focuser puts a world point.

    For a straight track (point ``A``, unit direction ``t``, from the image metadata, see
    :func:`image_coordinates`), every point of the circle about the track through ``X`` has the
    same range history as ``X``: the same closest-approach range ``R0 = |X - F|``, at the same
    along-track position ``F = A + ((X - A) . t) t`` (its zero-Doppler point). A focuser matched
    to that history (backprojection, omega-K) therefore images ``X`` where this circle meets the
    image plane, on ``X``'s side of the track: ``Q = origin + a e_az + r e_rg`` with
    ``(Q - F) . t = 0`` and ``|Q - F| = R0`` (Cumming and Wong 2005, section 4.2). For a point at
    height ``h`` above a flat ground-plane image, a track at height ``H`` and ground distance ``Y``
    this is the layover ``sqrt(Y^2 - 2 H h + h^2) ~ Y - h / tan(theta)``: toward the sensor by
    ``h / tan(theta)`` in ground range (docs/physics.md (G2)). A point on the plane maps to itself.

    Parameters
    ----------
    image : SarImage
        Image whose metadata record the track.
    point : 3 floats, m
        World position.

    Returns
    -------
    (azimuth, range) : tuple of float, m

    Raises
    ------
    ValueError
        When the metadata record no track, the image plane contains the track direction in
        neither axis, or the circle does not reach the image plane.
    """
    x = np.asarray(point, dtype=np.float64).reshape(-1)
    if x.size != 3 or not np.all(np.isfinite(x)):
        raise ValueError(f"point must be 3 finite numbers (world x, y, z in m), got {point!r}")
    track = _track_of(image)
    if track is None:
        raise ValueError("the image metadata record no track (focus['track'] or radar parameters): "
                         "give the target in image coordinates (azimuth, range)")
    a_point, t = track
    foot = a_point + float((x - a_point) @ t) * t
    r0 = float(np.linalg.norm(x - foot))
    e_a, e_r = np.asarray(image.azimuth_direction, float), np.asarray(image.range_direction, float)
    d = np.asarray(image.origin, float) - foot
    # (d + a e_a + r e_r) . t = 0: a line in (a, r); least-norm point plus a direction along it
    g = np.array([e_a @ t, e_r @ t])
    if np.linalg.norm(g) < 1e-12:
        raise ValueError("the image plane is normal to the track: no zero-Doppler line to map the target onto")
    base = -float(d @ t) * g / float(g @ g)
    step = np.array([g[1], -g[0]]) / np.linalg.norm(g)
    v0 = d + base[0] * e_a + base[1] * e_r
    v1 = step[0] * e_a + step[1] * e_r
    qa, qb, qc = float(v1 @ v1), 2.0 * float(v0 @ v1), float(v0 @ v0) - r0 * r0
    disc = qb * qb - 4.0 * qa * qc
    if qa <= 0 or disc < 0:
        raise ValueError(f"the point {x.tolist()} lies {r0:.3f} m from the track, which the image plane does "
                         "not reach along its zero-Doppler line: it cannot appear in this image")
    best = None
    for lam in ((-qb + np.sqrt(disc)) / (2 * qa), (-qb - np.sqrt(disc)) / (2 * qa)):
        ar = base + lam * step
        q = d + ar[0] * e_a + ar[1] * e_r                   # Q - F
        score = float(q @ (x - foot))                       # on the point's side of the track
        if best is None or score > best[0]:
            best = (score, ar)
    a, r = best[1]
    return float(a), float(r)


def carrier_ramp(raw: Any, image: SarImage, point: Sequence[float], *,
                 pulses: np.ndarray | None = None) -> tuple[float, float]:
    """Carrier phase gradient [rad/m] of a backprojected image around a world point.

    A backprojected image of a target at ``X`` is, near ``X``, ``a e(x) exp(j k . (x - X))``
    with ``k = (2 pi fc / c) <grad L_p(X)>`` the pulse-averaged gradient of the two-way
    length, and ``e`` a smooth envelope. Pass the result as ``carrier=`` to
    :func:`analyze_point_target` to read phases between pixels correctly.

    Parameters
    ----------
    raw : RawData
        The data that were focused (``tx_position``, ``rx_position``, ``fc``).
    image : SarImage
        The image (its axis directions).
    point : 3 floats, m
        World position of the target.
    pulses : bool [n_pulses] or index array, optional
        Pulses that contributed (e.g. those in the beam); default all.

    Returns
    -------
    (k_azimuth, k_range) : tuple of float, rad/m
        ``k`` projected on ``image.azimuth_direction`` and ``image.range_direction``.
    """
    x = np.asarray(point, dtype=np.float64).reshape(3)
    tx, rx = raw.tx_position, raw.rx_position
    if pulses is not None:
        tx, rx = tx[pulses], rx[pulses]
    if tx.shape[0] == 0:
        raise ValueError("carrier_ramp: no pulses selected")
    grad = ((x - tx) / np.linalg.norm(x - tx, axis=1)[:, None]
            + (x - rx) / np.linalg.norm(x - rx, axis=1)[:, None]).mean(axis=0)
    k = 2.0 * np.pi * raw.fc / SPEED_OF_LIGHT * grad
    return float(k @ image.azimuth_direction), float(k @ image.range_direction)


# ============================================================================ energy widths
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
      evenly spaced). ``cos(phi)`` is the Jacobian of the 2-D wavenumber support (range and
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
    model = _ImpulseModel(image, position)
    return model.rho_az, model.rho_rg


class _ImpulseModel:
    """The unit-peak impulse response of a backprojected image at one position, from its
    metadata (see :func:`energy_widths`): energy widths and the energy fraction a box holds."""

    def __init__(self, image: SarImage, position: Sequence[float] | None):
        from .focus.stripmap import _window_spec
        from .focus.windows import energy_width, spectral_window
        focus = image.metadata.get("focus") if isinstance(image.metadata, dict) else None
        keys = ("fc", "bandwidth", "window_range", "window_azimuth", "track")
        if not isinstance(focus, dict) or any(k not in focus for k in keys):
            raise ValueError(f"energy widths need image.metadata['focus'] with {', '.join(keys)} (a backprojected "
                             "image); pass resolution=(rho_az, rho_rg) for other images")
        try:
            fc, bandwidth = float(focus["fc"]), float(focus["bandwidth"])
            self.w_rg = _window_spec((focus["window_range"]["name"],
                                      {k: v for k, v in focus["window_range"].items() if k != "name"}))
            w_az = _window_spec((focus["window_azimuth"]["name"],
                                 {k: v for k, v in focus["window_azimuth"].items() if k != "name"}))
        except (TypeError, KeyError, AttributeError) as exc:
            raise ValueError(f"image.metadata['focus'] holds no valid windows ({exc})") from None
        track = _track_of(image)
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
        if sines is not None:
            sin_lo, sin_hi = (float(v) for v in sines)
            sine = sin_lo + u * (sin_hi - sin_lo)
            slope = np.full_like(u, sin_hi - sin_lo)                      # ds / du
            amplitude = w / (1.0 - sine ** 2) ** 1.5                      # W rho per du
            pattern = focus.get("azimuth_pattern")
            if pattern is not None:
                squint = np.radians(float(focus.get("squint") or 0.0))
                amplitude = amplitude * np.sinc(float(pattern) * np.sin(np.arcsin(sine) - squint)) ** 2
        else:
            length = float(focus["track"].get("length") or 0.0) if isinstance(focus["track"], dict) else 0.0
            if not length > 0:
                raise ValueError("image.metadata['focus']['track'] needs the aperture length for a beamless image")
            along = float((q - a_point) @ t) - (u - 0.5) * length          # target minus antenna, along track
            sine = along / np.hypot(along, r0)
            slope = length * (1.0 - sine ** 2) ** 1.5 / r0                 # |ds / du|
            amplitude = w
        self.wavelength = SPEED_OF_LIGHT / fc
        self.u, self.sine, self.slope, self.amplitude = u, sine, slope, amplitude
        cos_phi = np.sqrt(1.0 - sine ** 2)
        self.rho_az = float(0.5 * self.wavelength * _simpson(amplitude ** 2 * cos_phi / slope, u)
                            / _simpson(amplitude, u) ** 2)

    def fraction(self, half_azimuth: float, half_range: float) -> float:
        """Energy fraction of the unit-peak response inside ``|d_az| <= half_azimuth``,
        ``|d_rg| <= half_range`` [m] (separable model): the box of an integrated-energy RCS.

        Range: ``int p^2`` of the window's closed-form pulse over the box, over its energy
        width. Azimuth: ``|I(x)|^2``, ``I(x) = int A(u) exp(j 4 pi s(u) x / lambda) du``,
        integrated over the box, over ``(lambda / 2) int A^2 / (ds/du) du`` (Parseval)."""
        import scipy.integrate

        from .focus.windows import compressed_pulse, energy_width
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


def _simpson(y: np.ndarray, x: np.ndarray) -> float:
    import scipy.integrate
    return float(scipy.integrate.simpson(y, x=x))


# ============================================================================ band-limited chip
def _refine_peak(interp: Interpolant2D, u: float, v: float, step: float) -> tuple[float, float]:
    """Maximise ``|interp|^2`` from a grid maximum by alternating parabolic (log-power) vertex
    fits along each axis, with shrinking steps; each vertex move is limited to one step."""
    for h in (step, step / 8.0, step / 64.0, step / 512.0):
        for _ in range(2):
            for axis in (0, 1):
                offsets = np.array([-h, 0.0, h])
                if axis == 0:
                    values = np.abs(interp(u + offsets, v)[:, 0]) ** 2
                else:
                    values = np.abs(interp(u, v + offsets)[0, :]) ** 2
                y0, y1, y2 = np.log(np.maximum(values, 1e-300))
                curvature = y0 - 2.0 * y1 + y2
                shift = 0.5 * (y0 - y2) / curvature * h if curvature < 0 else 0.0
                shift = float(np.clip(shift, -h, h))
                if axis == 0:
                    u += shift
                else:
                    v += shift
    return float(u), float(v)


# ============================================================================ 1-D cut metrics
@dataclass(frozen=True)
class _CutMetrics:
    irw: float  # pixels
    null: float  # pixels, mean peak-to-null distance
    pslr_db: float
    islr_db: float
    extent: float  # null distances actually integrated


def _first_null(power: np.ndarray, k0: int, step: int) -> int:
    """Index of the first local minimum of ``power`` walking from ``k0`` by ``step`` (+-1)."""
    k = k0
    n = power.size
    while 0 <= k + step < n and power[k + step] <= power[k]:
        k += step
    if k + step < 0 or k + step >= n:
        raise ValueError("no null found in a cut through the peak before the chip edge: the target is not "
                         "resolved in this chip (increase chip or check the focus)")
    return k


def _cut_metrics(profile: np.ndarray, k0: int, ov: int, sidelobes: float,
                 half_power_root: Any) -> _CutMetrics:
    power = np.abs(profile) ** 2
    left = _first_null(power, k0, -1)
    right = _first_null(power, k0, +1)
    null = 0.5 * (right - left) / ov
    # -3 dB points refined on the exact interpolant (brentq between bracketing samples)
    half = power[k0] / 2.0
    lo = k0
    while power[lo - 1] > half:
        lo -= 1
        if lo <= left:
            raise ValueError("the -3 dB point lies beyond the first null: not a point-target response")
    hi = k0
    while power[hi + 1] > half:
        hi += 1
        if hi >= right:
            raise ValueError("the -3 dB point lies beyond the first null: not a point-target response")
    x_lo = half_power_root(lo - 1, lo)
    x_hi = half_power_root(hi, hi + 1)
    irw = (x_hi - x_lo) / ov
    span_l = (k0 - left) * sidelobes
    span_r = (right - k0) * sidelobes
    side_lo = max(0, int(round(left - span_l)))
    side_hi = min(power.size - 1, int(round(right + span_r)))
    extent = min((left - side_lo) / max(k0 - left, 1), (side_hi - right) / max(right - k0, 1))
    main = power[left:right + 1].sum()
    side = power[side_lo:left].sum() + power[right + 1:side_hi + 1].sum()
    side_max = max(power[side_lo:left].max(initial=0.0), power[right + 1:side_hi + 1].max(initial=0.0))
    with np.errstate(divide="ignore"):
        pslr = 10.0 * np.log10(side_max / power[k0]) if side_max > 0 else -np.inf
        islr = 10.0 * np.log10(side / main) if side > 0 else -np.inf
    return _CutMetrics(irw=irw, null=null, pslr_db=float(pslr), islr_db=float(islr), extent=float(extent))


# ============================================================================ analysis
def analyze_point_target(image: SarImage, target: Sequence[float] | np.ndarray, *, chip: int = 64,
                         oversample: int = 32, predicted: Sequence[float] | np.ndarray | None = None,
                         resolution: tuple[float, float] | None = None,
                         carrier: tuple[float, float] | None = None, sidelobes: float = 10.0,
                         energy_extent: float = 5.0, search_radius: int | None = None) -> PointTargetReport:
    """Measure a point target's impulse response in a focused image (ISCE3/Aresys practice).

    Parameters
    ----------
    image : SarImage
        Focused image with uniformly spaced axes; ``plane`` ``"slant"`` or ``"ground"``.
    target : 3 floats (world position, m) or 2 floats (azimuth, range image coordinates, m)
        Where to cut the chip: a world point at its position in the image,
        :func:`image_coordinates` (its layover position when the metadata record the track).
        The chip is re-centred on the brightest pixel within ``search_radius`` pixels of it.
    chip : int, default 64
        Chip size in pixels (both axes), even, in [16, 1024]; the chip must fit in the
        image (a target nearer than ``chip / 2`` pixels to an edge is an error).
    oversample : int, default 32
        Sampling of the cuts and of the coarse peak grid, per pixel; in [4, 1024].
    predicted : 3 or 2 floats, optional
        Expected peak position (world, or image coordinates); default ``target``.
    resolution : (float, float), m, optional
        ``(rho_az, rho_rg)``: impulse-response energy widths ``int |h|^2`` of the unit-peak
        response along each image axis (rect spectrum: the reciprocal bandwidths,
        ``c / (2 B)`` in slant range, ``/ sin(incidence)`` in ground range; with a window,
        times :func:`sarmitsuba.focus.windows.energy_width`). Default: from the image
        metadata at the peak (:func:`energy_widths`), when it records the focusing; else no
        ``rcs``; the energy outside the integration box is then also restored
        (``energy_fraction``).
    carrier : (float, float), rad/m, optional
        True linear phase gradient of the image along (azimuth, range) near the target,
        e.g. :func:`carrier_ramp` for a backprojected image. Default: estimated from the
        chip (spectral centroid, wrapped to one pixel).
    sidelobes : float, default 10
        ISLR/PSLR sidelobe extent beyond each first null, in first-null distances.
    energy_extent : float, default 5
        Half-size of the energy integration box, in first-null distances (1 = mainlobe
        only; 5 = the Aresys "side area" of about +-5 resolutions).
    search_radius : int, optional
        Pixels around ``target`` searched for the brightest pixel; default ``chip // 4``.

    Returns
    -------
    PointTargetReport

    Raises
    ------
    ValueError
        On a bad argument, non-uniform axes, a chip that does not fit, a zero chip, or a
        response with no null inside the chip.

    Notes
    -----
    Cost: one ``chip x chip`` FFT and a few hundred small matrix-vector products; about
    10 ms for the defaults.

    Examples
    --------
    >>> report = analyze_point_target(image, (0.0, 0.0, 0.0))  # doctest: +SKIP
    >>> report.irw_range, report.pslr_range_db  # doctest: +SKIP
    """
    if not isinstance(image, SarImage):
        raise ValueError(f"image must be a sarmitsuba.image.SarImage, got {type(image).__name__}")
    chip = _int_in("chip", chip, 16, 1024)
    if chip % 2:
        raise ValueError(f"chip must be even (Nyquist-bin split of the interpolant), got {chip}")
    ov = _int_in("oversample", oversample, 4, 1024)
    sidelobes = _float_in("sidelobes", sidelobes, 0.0, 1e3, open_low=True)
    energy_extent = _float_in("energy_extent", energy_extent, 0.0, 1e3, open_low=True)
    radius = chip // 4 if search_radius is None else _int_in("search_radius", search_radius, 0, chip // 2)
    d_az = _axis_step("azimuth", image.azimuth)
    d_rg = _axis_step("range", image.range)
    n_az, n_rg = image.data.shape
    az0, rg0 = image_coordinates(image, target)
    pred_az, pred_rg = (az0, rg0) if predicted is None else image_coordinates(image, predicted)
    row_t = (az0 - image.azimuth[0]) / d_az
    col_t = (rg0 - image.range[0]) / d_rg
    if not (0 <= row_t <= n_az - 1 and 0 <= col_t <= n_rg - 1):
        raise ValueError(f"target at image coordinates ({az0:.3f}, {rg0:.3f}) m lies outside the image "
                         f"(azimuth [{image.azimuth[0]:.3f}, {image.azimuth[-1]:.3f}] m, range "
                         f"[{image.range[0]:.3f}, {image.range[-1]:.3f}] m)")

    # ---- chip, re-centred on the brightest pixel near the target
    r, c = int(round(row_t)), int(round(col_t))
    r_lo, r_hi = max(0, r - radius), min(n_az, r + radius + 1)
    c_lo, c_hi = max(0, c - radius), min(n_rg, c + radius + 1)
    window = np.abs(image.data[r_lo:r_hi, c_lo:c_hi])
    if not np.any(window):
        raise ValueError(f"the image is zero within {radius} pixels of the target: nothing to analyse")
    i, j = np.unravel_index(int(np.argmax(window)), window.shape)
    r, c = r_lo + int(i), c_lo + int(j)
    i0, j0 = r - chip // 2, c - chip // 2
    if i0 < 0 or j0 < 0 or i0 + chip > n_az or j0 + chip > n_rg:
        raise ValueError(f"the target peak at pixel ({r}, {c}) is closer than chip/2 = {chip // 2} pixels to the "
                         f"edge of the {n_az} x {n_rg} image; reduce chip or enlarge the image")
    z = image.data[i0:i0 + chip, j0:j0 + chip].astype(np.complex128)

    # ---- phase ramp (spectral centroid) -> baseband
    if carrier is None:
        w_az = float(np.angle(np.sum(z[1:, :] * np.conj(z[:-1, :]))))
        w_rg = float(np.angle(np.sum(z[:, 1:] * np.conj(z[:, :-1]))))
        carrier_source = "estimated"
    else:
        k = np.asarray(carrier, dtype=np.float64).reshape(-1)
        if k.shape != (2,) or not np.all(np.isfinite(k)):
            raise ValueError(f"carrier must be 2 finite numbers (k_azimuth, k_range) in rad/m, got {carrier!r}")
        w_az, w_rg = float(k[0] * d_az), float(k[1] * d_rg)
        carrier_source = "given"
    n = np.arange(chip, dtype=np.float64)
    base = z * np.exp(-1j * (w_az * n[:, None] + w_rg * n[None, :]))
    interp = Interpolant2D(base)

    def value(u: float, v: float) -> complex:
        """Ramp-restored image value at chip-local fractional pixel (u, v)."""
        return complex(interp(u, v)[0, 0]) * np.exp(1j * (w_az * u + w_rg * v))

    # ---- peak: oversampled grid +-2 pixels around the brightest pixel, then refined
    pr, pc = chip // 2, chip // 2
    fine = np.arange(-2 * ov, 2 * ov + 1) / ov
    grid = np.abs(interp(pr + fine, pc + fine))
    a, b = np.unravel_index(int(np.argmax(grid)), grid.shape)
    u_pk, v_pk = _refine_peak(interp, pr + fine[a], pc + fine[b], 1.0 / ov)
    peak = value(u_pk, v_pk)

    # ---- cuts through the peak, sampled every 1/ov pixel, the peak exactly a sample
    metrics = []
    for axis, centre, other in ((0, u_pk, v_pk), (1, v_pk, u_pk)):
        k_lo = -int(np.floor(centre * ov))
        k_hi = int(np.floor((chip - 1 - centre) * ov))
        pos = centre + np.arange(k_lo, k_hi + 1) / ov
        prof = interp(pos, other)[:, 0] if axis == 0 else interp(other, pos)[0, :]

        def along(x: float, _axis: int = axis, _c: float = centre, _o: float = other, _k: int = k_lo) -> float:
            t = _c + (x + _k) / ov
            val = interp(t, _o)[0, 0] if _axis == 0 else interp(_o, t)[0, 0]
            return abs(val) ** 2 - abs(peak) ** 2 / 2.0

        def root(k1: int, k2: int, _f: Any = along) -> float:
            return scipy.optimize.brentq(_f, k1, k2, xtol=1e-9)

        metrics.append(_cut_metrics(prof, -k_lo, ov, sidelobes, root))
    m_az, m_rg = metrics

    # ---- predicted position: magnitude and phase there
    u_pred = (pred_az - image.azimuth[0]) / d_az - i0
    v_pred = (pred_rg - image.range[0]) / d_rg - j0
    if 0 <= u_pred <= chip - 1 and 0 <= v_pred <= chip - 1:
        at_pred: complex | None = value(u_pred, v_pred)
    else:
        at_pred = None

    # ---- integrated energy with corner clutter removed
    power = np.abs(z) ** 2
    corner = max(2, chip // 8)
    clutter = float(np.mean(np.concatenate([
        power[:corner, :corner].ravel(), power[:corner, -corner:].ravel(),
        power[-corner:, :corner].ravel(), power[-corner:, -corner:].ravel()])))
    box = ((np.abs(n - u_pk) <= energy_extent * m_az.null)[:, None]
           & (np.abs(n - v_pk) <= energy_extent * m_rg.null)[None, :])
    pixel_area = d_az * d_rg * float(np.linalg.norm(np.cross(image.azimuth_direction, image.range_direction)))
    energy = float((power[box].sum() - clutter * box.sum()) * pixel_area)
    row, col = i0 + u_pk, j0 + v_pk
    az = float(image.azimuth[0] + row * d_az)
    rg = float(image.range[0] + col * d_rg)
    rcs = rcs_db = fraction = None
    rho = None
    if resolution is not None:
        rho = np.asarray(resolution, dtype=np.float64).reshape(-1)
        if rho.shape != (2,) or not np.all(np.isfinite(rho)) or np.any(rho <= 0):
            raise ValueError(f"resolution must be 2 positive numbers (rho_az, rho_rg) in m, got {resolution!r}")
    else:
        try:
            model = _ImpulseModel(image, (az, rg))
        except ValueError:
            model = None
        if model is not None:
            rho = np.array([model.rho_az, model.rho_rg])
            fraction = model.fraction(0.5 * box.any(axis=1).sum() * d_az, 0.5 * box.any(axis=0).sum() * d_rg)
    if rho is not None:
        rcs = energy / float(rho[0] * rho[1] * (fraction or 1.0))
        rcs_db = 10.0 * math.log10(rcs) if rcs > 0 else None

    # ---- assemble
    world = image.origin + az * image.azimuth_direction + rg * image.range_direction
    irw_az, irw_rg = m_az.irw * d_az, m_rg.irw * d_rg
    return PointTargetReport(
        azimuth=az, range=rg, row=float(row), column=float(col),
        world_position=tuple(float(x) for x in world), plane=image.plane,
        predicted_azimuth=float(pred_az), predicted_range=float(pred_rg),
        azimuth_error=az - pred_az, range_error=rg - pred_rg,
        azimuth_error_cells=(az - pred_az) / irw_az, range_error_cells=(rg - pred_rg) / irw_rg,
        irw_azimuth=irw_az, irw_range=irw_rg,
        first_null_azimuth=m_az.null * d_az, first_null_range=m_rg.null * d_rg,
        pslr_azimuth_db=m_az.pslr_db, pslr_range_db=m_rg.pslr_db,
        islr_azimuth_nullbounded_db=m_az.islr_db, islr_range_nullbounded_db=m_rg.islr_db,
        islr_sidelobes=sidelobes, islr_extent_azimuth=m_az.extent, islr_extent_range=m_rg.extent,
        peak_magnitude=abs(peak), peak_phase_deg=float(np.degrees(np.angle(peak))),
        predicted_magnitude=None if at_pred is None else abs(at_pred),
        predicted_phase_deg=None if at_pred is None else float(np.degrees(np.angle(at_pred))),
        phase_ramp_azimuth=w_az, phase_ramp_range=w_rg, carrier=carrier_source,
        integrated_energy=energy, clutter_level=clutter, energy_extent=energy_extent,
        rcs=rcs, rcs_db=rcs_db, chip=chip, oversample=ov,
        energy_width_azimuth=None if rho is None else float(rho[0]),
        energy_width_range=None if rho is None else float(rho[1]), energy_fraction=fraction)


def _int_in(name: str, value: Any, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    return int(value)


def _float_in(name: str, value: Any, low: float, high: float, open_low: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    ok = np.isfinite(v) and (v > low if open_low else v >= low) and v <= high
    if not ok:
        bracket = "(" if open_low else "["
        raise ValueError(f"{name} must be a number in {bracket}{low}, {high}], got {value!r}")
    return v


# ============================================================================ command line
def _floats(text: str) -> list[float]:
    try:
        values = [float(x) for x in text.replace(" ", "").split(",") if x]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
    return values


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add the ``analyze`` arguments to ``parser`` (a sub-command parser); returns it."""
    parser.add_argument("image", help="focused image (.npz written by SarImage.save)")
    parser.add_argument("--target", required=True, type=_floats, metavar="X,Y,Z|AZ,RG",
                        help="target: world position [m] (looked for at its layover position in the image) or "
                             "image coordinates (azimuth, range) [m]; write --target=-1,2,0 when the first value "
                             "is negative")
    parser.add_argument("--predicted", type=_floats, default=None, metavar="X,Y,Z|AZ,RG",
                        help="expected peak position (default: the target)")
    parser.add_argument("--chip", type=int, default=64, help="chip size in pixels (even; default 64)")
    parser.add_argument("--oversample", type=int, default=32, help="cut sampling per pixel (default 32)")
    parser.add_argument("--resolution", type=_floats, default=None, metavar="RHO_AZ,RHO_RG",
                        help="impulse-response energy widths [m] along the image axes for the RCS (default: from "
                             "the image metadata: bandwidth, windows, antenna pattern, geometry)")
    parser.add_argument("--carrier", type=_floats, default=None, metavar="K_AZ,K_RG",
                        help="true carrier phase gradient [rad/m] (default: estimated from the chip)")
    parser.add_argument("--sidelobes", type=float, default=10.0,
                        help="ISLR/PSLR sidelobe extent in first-null distances (default 10)")
    parser.add_argument("--energy-extent", type=float, default=5.0,
                        help="energy box half-size in first-null distances (default 5)")
    return parser


def run(args: argparse.Namespace, figure=None) -> int:
    """Analyse ``args.image`` and print the report as JSON; returns the exit code (0, or 2 on bad input).

    ``figure``, if given, is called as ``figure(image, report)`` after a successful analysis.
    """
    from .image import SarImageError
    try:
        image = SarImage.load(args.image)
        report = analyze_point_target(
            image, args.target, chip=args.chip, oversample=args.oversample, predicted=args.predicted,
            resolution=None if args.resolution is None else tuple(args.resolution),
            carrier=None if args.carrier is None else tuple(args.carrier),
            sidelobes=args.sidelobes, energy_extent=args.energy_extent)
    except (SarImageError, ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(report.to_dict(), indent=2))
    if figure is not None:
        figure(image, report)
    return 0


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
    float, m^2 (no clutter subtraction; see :func:`analyze_point_target` for that)

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
        model = _ImpulseModel(image, center)
        resolution_azimuth, resolution_range = model.rho_az, model.rho_rg
    az, rg = np.meshgrid(image.azimuth - center[0], image.range - center[1], indexing="ij")
    box = (np.abs(az) <= half_cells * resolution_azimuth) & (np.abs(rg) <= half_cells * resolution_range)
    d_az, d_rg = abs(image.azimuth[1] - image.azimuth[0]), abs(image.range[1] - image.range[0])
    fraction = 1.0 if model is None else model.fraction(0.5 * box.any(axis=1).sum() * d_az,
                                                        0.5 * box.any(axis=0).sum() * d_rg)
    return float((np.abs(image.data[box]) ** 2).sum() * d_az * d_rg
                 / (resolution_azimuth * resolution_range * fraction))


def main(argv: list[str] | None = None) -> int:
    """``python -m sarmitsuba.analysis IMAGE.npz --target X,Y,Z``: print the report as JSON."""
    parser = add_arguments(argparse.ArgumentParser(prog="sarmitsuba analyze",
                                                   description="point-target analysis of a focused image"))
    return run(parser.parse_args(argv))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
