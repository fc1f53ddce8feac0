"""Azimuth beam weighting of the backprojection focusers: beam gating, window, pattern, normalisation.

Shared by :func:`~sarmitsuba.focus.backproject` (direct) and :func:`~sarmitsuba.focus.ffbp`
(fast factorised), so that both sum the same weighted echoes and divide by the same gain.

* **Beam.** With a traced azimuth beam of full width ``beta`` [deg] and squint ``theta``, pulse
  ``p`` (antenna ``A_p``, beam axis ``v_p``, :func:`beam_axes`) sees pixel ``x`` when its along-track
  sine ``s = (x - A_p) . v_p / |x - A_p|`` lies in ``[sin(theta - beta / 2), sin(theta + beta / 2)]``
  (:func:`beam_sines`), the tracer's criterion. The beam axis is the nominal track's velocity when
  the data carry one: motion errors move the antenna, not its pointing (docs/physics.md (J4)).
* **Window.** The contribution of pulse ``p`` is weighted by ``w(u)``,
  ``u = (s - sin_lo) / (sin_hi - sin_lo)`` in [0, 1] across the beam (``w`` of
  :mod:`.windows` at ``u - 1/2``); without a beam (spotlight) by ``w(p / (n_pulses - 1))``.
* **Pattern.** The data carry the two-way field pattern ``g^2 = sinc^2(L / lambda sin(phi - theta))``
  (NumPy's sinc, ``phi = asin(s)``); it is not divided out per pulse but enters the expected
  gain ``sum_p w g^2`` of a point target. Data received on a platform of its own (the metadata's
  ``radar.receiver``, docs/physics.md (B3)) carry the transmitter's one-way ``g`` alone: the
  receiver stares at the scene centre, so its own pattern is 1 there, and the gain is ``sum_p w g``.
* **Normalisation.** Each range column is divided by the largest expected gain of its pixels
  (:func:`normalise_columns`): a point target of amplitude ``a`` peaks at ``a`` anywhere in the
  fully illuminated swath (docs/design.md section 8, docs/physics.md (K)).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..core.raw import RawData
from .grid import ImageGrid
from .windows import spectral_window, window_spec

__all__ = ["WINDOW_TABLE", "BeamWeighting", "beam_weighting", "beam_sines", "beam_axes", "unit_rows",
           "illumination_count", "sine_scale",
           "expected_gain", "point_gain", "column_gain", "normalise_columns", "pixel_weights", "column_scale"]

#: Samples of the beam-weight tables over u in [0, 1] (linear interpolation between them:
#: relative error below 1e-6 for every window of the windows module and patterns of up to two
#: lobes across the beam).
WINDOW_TABLE = 4097


def beam_sines(raw: RawData, azimuth_beamwidth: float | None, squint: float = 0.0) -> tuple[float, float] | None:
    """Along-track sines ``(sin(squint - beta / 2), sin(squint + beta / 2))`` bounding the ideal
    beam, or None when ``azimuth_beamwidth`` is None.

    Raises ValueError when ``azimuth_beamwidth`` is outside (0, 90) deg, ``squint`` outside
    (-60, 60) deg, or a pulse has zero velocity.
    """
    if azimuth_beamwidth is None:
        return None
    beta = float(azimuth_beamwidth)
    if not 0.0 < beta < 90.0:
        raise ValueError(f"azimuth_beamwidth = {azimuth_beamwidth!r} deg is outside the valid range (0, 90) deg")
    if not -60.0 < float(squint) < 60.0:
        raise ValueError(f"squint = {squint!r} deg is outside the valid range (-60, 60) deg")
    if not np.all(np.linalg.norm(raw.velocity, axis=1) > 0):
        raise ValueError("azimuth_beamwidth needs a non-zero platform velocity for every pulse (raw.velocity)")
    half, centre = np.radians(beta) / 2.0, np.radians(float(squint))
    return float(np.sin(centre - half)), float(np.sin(centre + half))


class BeamWeighting:
    """Azimuth weighting of one backprojection: beam sines (or None), window, pattern ``L / lambda``.

    Both the weight ``w(u)`` and the expected gain ``w(u) g^2`` are functions of the along-track
    sine ``s`` alone, so they are tabulated once over the beam (:data:`WINDOW_TABLE` samples of
    ``u``) and interpolated linearly from their samples and slopes.

    Attributes
    ----------
    sines : (float, float) or None
        ``(sin_lo, sin_hi)`` of the beam, None without one (spotlight).
    squint : float, rad
    pattern : float or None
        ``L / lambda`` of the two-way sinc^2 pattern in the data.
    power : int
        2: the data carry the pattern both ways (``g^2``); 1: one way (``g``, bistatic).
    window : (str, dict)
        The azimuth window, canonical (:func:`~.windows.check_window`).
    is_rect : bool
    u, table, gain_table : float64 [WINDOW_TABLE]
        ``u`` in [0, 1], ``w(u)`` and ``w(u) g^2``.
    """

    def __init__(self, sines: tuple[float, float] | None, squint: float, pattern: float | None,
                 window: tuple[str, dict[str, float]], power: int = 2):
        self.sines, self.squint, self.pattern, self.window, self.power = sines, squint, pattern, window, power
        self.is_rect = window[0] == "rect"
        self.u = np.linspace(0.0, 1.0, WINDOW_TABLE)
        #: w(u) sampled on [0, 1], float64
        self.table = spectral_window(window[0], self.u - 0.5, 1.0, **window[1])
        self.gain_table = self.table
        if sines is not None and pattern is not None:
            s = sines[0] + self.u * (sines[1] - sines[0])
            # sin(phi - squint) = sin(phi) cos(squint) - cos(phi) sin(squint)
            off = s * np.cos(squint) - np.sqrt(1.0 - s * s) * np.sin(squint)
            self.gain_table = self.table * np.sinc(pattern * off) ** power
        self.slope, self.gain_slope = np.diff(self.table), np.diff(self.gain_table)

    def pulse_weights(self, n_pulses: int) -> np.ndarray:
        """Without a beam: ``w(p / (n - 1))`` per pulse, float64 [n_pulses]."""
        u = np.arange(n_pulses) / (n_pulses - 1) if n_pulses > 1 else np.full(1, 0.5)
        return np.ones(n_pulses) if self.is_rect else np.interp(u, self.u, self.table)

    def weights(self, along: np.ndarray, dist: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weight ``w(u)`` (float32) and expected gain ``w(u) g^2`` (float64) of along-track
        offsets ``along`` [m] at distances ``dist`` [m] (broadcast), zero outside the beam."""
        sin_lo, sin_hi = self.sines
        if self.is_rect and self.pattern is None:
            w = ((along >= sin_lo * dist) & (along <= sin_hi * dist)).astype(np.float64)
            return w.astype(np.float32), w
        # fractional table index of u = (s - sin_lo) / (sin_hi - sin_lo); outside [0, 1] -> 0
        x = (along / dist - sin_lo) * ((WINDOW_TABLE - 1) / (sin_hi - sin_lo))
        inside = (x >= 0.0) & (x <= WINDOW_TABLE - 1)
        np.clip(x, 0.0, WINDOW_TABLE - 1, out=x)
        i = np.minimum(x.astype(np.intp), WINDOW_TABLE - 2)
        x -= i
        w = self.table[i] + x * self.slope[i]
        w *= inside
        if self.pattern is None:
            gain = w
        else:
            gain = self.gain_table[i] + x * self.gain_slope[i]
            gain *= inside
        return w.astype(np.float32), gain


def beam_weighting(raw: RawData, azimuth_beamwidth: float | None, squint: float, azimuth_pattern: Any,
                   window_azimuth: Any) -> BeamWeighting:
    """Check the beam, pattern and window options; the :class:`BeamWeighting` of one backprojection.

    Raises ValueError for a bad beamwidth or squint (:func:`beam_sines`), an unknown window or
    window parameter, an ``azimuth_pattern`` that is not a finite number > 0, or a pattern
    without ``azimuth_beamwidth``.
    """
    window = window_spec(window_azimuth)
    sines = beam_sines(raw, azimuth_beamwidth, squint)
    pattern = None
    if azimuth_pattern is not None:
        try:
            pattern = float(azimuth_pattern)
        except (TypeError, ValueError):
            pattern = float("nan")
        if not (np.isfinite(pattern) and pattern > 0):
            raise ValueError(f"azimuth_pattern = {azimuth_pattern!r} must be a finite number > 0 "
                             "(L / lambda of the antenna pattern), or None")
        if sines is None:
            raise ValueError("azimuth_pattern needs azimuth_beamwidth (the traced beam the pattern lies in)")
    radar = raw.metadata.get("radar") if isinstance(raw.metadata, dict) else None
    one_way = isinstance(radar, dict) and bool(radar.get("receiver"))      # a receiver of its own (B3)
    return BeamWeighting(sines, float(np.radians(float(squint))), pattern, window, power=1 if one_way else 2)


def unit_rows(v: np.ndarray) -> np.ndarray:
    """Each row of ``v`` [n, 3] divided by its norm (unit vectors, float64)."""
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _coarse_points(grid: ImageGrid, step: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every ``step``-th row and column (and the last ones) and their world positions [n, 3]."""
    n_az, n_rg = grid.shape
    rows = np.unique(np.r_[np.arange(0, n_az, step), n_az - 1])
    cols = np.unique(np.r_[np.arange(0, n_rg, step), n_rg - 1])
    pts = (grid.origin + grid.azimuth[rows, None, None] * grid.azimuth_direction
           + grid.range[None, cols, None] * grid.range_direction).reshape(-1, 3)
    return rows, cols, pts


def _bilinear(coarse: np.ndarray, rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Interpolate values on (rows x cols) bilinearly onto every pixel of ``shape``."""
    n_az, n_rg = shape
    along_range = np.array([np.interp(np.arange(n_rg), cols, line) for line in coarse])   # [rows, n_rg]
    return np.array([np.interp(np.arange(n_az), rows, column) for column in along_range.T]).T


def beam_axes(raw: RawData) -> np.ndarray:
    """Unit along-track axis of the antenna at each pulse, float64 [n_pulses, 3], which its beam and
    pattern follow: the nominal track's velocity when the data carry one (``raw.nominal_velocity``,
    motion errors: the antenna moves across the track but keeps pointing along the nominal one, as
    the tracer illuminates, docs/physics.md (J4)), else ``raw.velocity``. Weighting by the swaying
    velocity instead cost a trihedral 1.17 dB of peak and RCS on the true track (2 cm, 40 m sway)."""
    return unit_rows(raw.nominal_velocity if raw.has_nominal_track else raw.velocity)


def sine_scale(raw: RawData, point: np.ndarray, sines: tuple[float, float] | None) -> float:
    """How fast the along-track sine seen from ``point`` [m] sweeps against the beam's, over the
    processed beam: the least-squares slope ``kappa`` of ``(x - A_p) . t / |x - A_p|`` (``t`` the
    unit mid-aperture velocity, the straight reference track of ``metadata["focus"]["track"]``) on
    the beam's sines ``(x - A_p) . v_p / |x - A_p|`` (``v_p`` of :func:`beam_axes`) of the pulses
    whose beam holds ``point``. 1 on a straight track. On an orbit the velocity turns with the
    Earth's curvature, and the target sees the antenna sweep ``kappa = v^2 / (v^2 - (x - A) . a)``
    times the beam (``a`` the acceleration; 1.087 at 500 km and 40 deg): the azimuth bandwidth is
    ``kappa`` times the beam's, the energy width ``1 / kappa`` times (docs/physics.md (J7), (K2)).
    1.0 without a beam (``sines`` None) or with fewer than 3 pulses in it. Returns a float."""
    if sines is None:
        return 1.0
    e = np.asarray(point, np.float64) - raw.tx_position
    dist = np.linalg.norm(e, axis=1)
    beam = np.einsum("pk,pk->p", e, beam_axes(raw)) / dist
    mid = np.asarray(raw.velocity[raw.n_pulses // 2], np.float64)
    seen = e @ (mid / np.linalg.norm(mid)) / dist
    inside = (beam >= sines[0]) & (beam <= sines[1])
    if np.count_nonzero(inside) < 3 or np.ptp(beam[inside]) <= 0:
        return 1.0
    return float(np.polyfit(beam[inside], seen[inside], 1)[0])


def illumination_count(raw: RawData, grid: ImageGrid, azimuth_beamwidth: float, step: int = 16,
                       squint: float = 0.0) -> np.ndarray:
    """Number of pulses whose ideal beam contains each pixel, float64 [n_az, n_rg].

    A pixel ``x`` is in the beam of pulse ``p`` when
    ``sin(squint - beta / 2) |x - A_p| <= (x - A_p) . v_p <= sin(squint + beta / 2) |x - A_p|``
    (``v_p`` the unit velocity): its angle from the zero-Doppler plane is within half the
    beamwidth of the squint, the criterion the tracer uses. Counted exactly on every ``step``-th row and
    column (and the last ones) and interpolated bilinearly in between (the count varies
    smoothly, with the slant range).
    """
    sin_lo, sin_hi = beam_sines(raw, azimuth_beamwidth, squint)
    rows, cols, pts = _coarse_points(grid, step)
    v = beam_axes(raw)
    counts = np.zeros(pts.shape[0])
    for p0 in range(0, raw.n_pulses, 32):
        e = pts[:, None, :] - raw.tx_position[None, p0:p0 + 32, :]
        along = np.einsum("npk,pk->np", e, v[p0:p0 + 32])
        dist = np.linalg.norm(e, axis=2)
        counts += ((along >= sin_lo * dist) & (along <= sin_hi * dist)).sum(axis=1)
    return _bilinear(counts.reshape(rows.size, cols.size), rows, cols, grid.shape)


def column_gain(raw: RawData, grid: ImageGrid, beam: BeamWeighting, step: int = 32) -> np.ndarray:
    """Largest expected point-target gain of each range column, float64 [n_rg]: the maximum over
    every ``step``-th row (and the last) of :func:`expected_gain`'s exact values on every
    ``step``-th column, interpolated linearly along range (the normalisation of
    :func:`normalise_columns` without the per-pixel gain image)."""
    rows, cols, pts = _coarse_points(grid, step)
    coarse = _coarse_gain(raw, beam, pts).reshape(rows.size, cols.size).max(axis=0)
    return np.interp(np.arange(grid.shape[1]), cols, coarse)


def _coarse_gain(raw: RawData, beam: BeamWeighting, pts: np.ndarray, pulse_block: int = 64) -> np.ndarray:
    """``sum_p w g^2`` at the points ``pts`` [n, 3] (see :func:`expected_gain`)."""
    sin_lo, sin_hi = beam.sines
    v = beam_axes(raw)
    gain = np.zeros(pts.shape[0])
    for p0 in range(0, raw.n_pulses, pulse_block):
        p1 = min(p0 + pulse_block, raw.n_pulses)
        ends = np.array([p0, p1 - 1])
        e = pts[:, None, :] - raw.tx_position[None, ends, :]
        s = np.einsum("npk,pk->np", e, v[ends]) / np.linalg.norm(e, axis=2)
        turn = float(np.linalg.norm(v[p1 - 1] - v[p0]))
        near = (s.max(axis=1) >= sin_lo - 1e-3 - turn) & (s.min(axis=1) <= sin_hi + 1e-3 + turn)
        if not near.any():
            continue
        e = pts[near, None, :] - raw.tx_position[None, p0:p1, :]
        along = np.einsum("npk,pk->np", e, v[p0:p1])
        gain[near] += beam.weights(along, np.linalg.norm(e, axis=2))[1].sum(axis=1)
    return gain


def point_gain(raw: RawData, beam: BeamWeighting, points: np.ndarray) -> np.ndarray:
    """Expected point-target gain ``sum_p w(u_p) g(phi_p)^2`` at world points ``points`` float64
    [n, 3] (m), float64 [n], evaluated exactly (the gain :func:`normalise_columns` divides a fully
    illuminated column by). Without a beam (spotlight) every pulse sees every point: the summed
    window ``sum_p w(p / (N - 1))``."""
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    if beam.sines is None:
        axes = beam_axes(raw)
        return sum(pixel_weights(raw, beam, axes, p, pts)[1] for p in range(raw.n_pulses))
    return _coarse_gain(raw, beam, pts)


def expected_gain(raw: RawData, grid: ImageGrid, beam: BeamWeighting, step: int = 16,
                  pulse_block: int = 64) -> np.ndarray:
    """Expected point-target gain ``sum_p w(u_p) g(phi_p)^2`` of each pixel, float64 [n_az, n_rg].

    ``u_p``, ``phi_p`` from pulse ``p``'s along-track sine of the pixel (the weights of
    :meth:`BeamWeighting.weights`, per pixel, no tiles). Evaluated exactly on every ``step``-th
    row and column (and the last ones) and interpolated bilinearly (the gain varies smoothly;
    with a rect window and no pattern it is :func:`illumination_count`). Blocks of
    ``pulse_block`` pulses whose beams miss every coarse pixel are skipped (checked from the
    block's first and last pulse, whose sines bracket the block's on a smooth track), so the
    cost is about (coarse pixels) x (pulses in the beam). Needs ``beam.sines``.
    """
    rows, cols, pts = _coarse_points(grid, step)
    gain = _coarse_gain(raw, beam, pts, pulse_block)
    return _bilinear(gain.reshape(rows.size, cols.size), rows, cols, grid.shape)


def pixel_weights(raw: RawData, beam: BeamWeighting, axes: np.ndarray, p: int,
                  x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The exact (untabulated) weight ``w(u)`` and expected gain ``w(u) g^2`` of pulse ``p`` at
    pixels ``x`` float64 [m, 3], float64 [m] each: the per-pixel form of the module's rules
    that the float64 references use (:func:`~sarmitsuba.focus.backproject_reference`,
    :class:`~sarmitsuba.focus.linear.BackprojectionOperator`). ``axes``: :func:`beam_axes`."""
    w_name, w_params = beam.window
    n_pulses = raw.data.shape[0]
    if beam.sines is None:
        u = np.full(x.shape[0], p / (n_pulses - 1) if n_pulses > 1 else 0.5)
        pattern = np.ones(x.shape[0])
    else:
        sin_lo, sin_hi = beam.sines
        los = x - raw.tx_position[p]
        sine = los @ axes[p] / np.linalg.norm(los, axis=1)          # along the beam's axis (J4)
        u = np.where((sine >= sin_lo) & (sine <= sin_hi), (sine - sin_lo) / (sin_hi - sin_lo), -1.0)
        phi = np.arcsin(np.clip(sine, -1.0, 1.0))
        pattern = (np.sinc(beam.pattern * np.sin(phi - beam.squint)) ** beam.power if beam.pattern is not None
                   else np.ones(x.shape[0]))
    weight = spectral_window(w_name, u - 0.5, 1.0, **w_params)     # zero for u outside [0, 1]
    return weight, weight * pattern


def column_scale(gain: np.ndarray) -> tuple[np.ndarray, float]:
    """The factor :func:`normalise_columns` multiplies each range column by: float64 [1, n_rg],
    ``1 / max(full, floor)`` where the column's full-aperture gain ``full`` exceeds ``floor =
    1e-6`` of the largest, else 0; and the largest gain."""
    full = gain.max(axis=0, keepdims=True)
    norm = float(full.max()) if full.size else 0.0
    floor = 1e-6 * norm if norm > 0 else 1.0
    return np.where(full > floor, 1.0 / np.maximum(full, floor), 0.0), norm


def normalise_columns(image: np.ndarray, gain: np.ndarray) -> tuple[np.ndarray, float]:
    """Divide each range column by its full-aperture gain (the largest expected point-target
    gain ``sum_p w g^2`` of its pixels): exact for fully illuminated pixels; pixels whose
    aperture the end of the track cuts keep their reduced gain instead of being amplified.

    Parameters
    ----------
    image : complex [n_az, n_rg]
        Weighted sums.
    gain : float64 [n_az, n_rg]
        Expected gain of each pixel.

    Returns
    -------
    complex64 [n_az, n_rg], float
        The normalised image (columns without gain, below 1e-6 of the largest, are zero)
        and the largest gain.
    """
    full = gain.max(axis=0, keepdims=True)
    norm = float(full.max()) if full.size else 0.0
    floor = 1e-6 * norm if norm > 0 else 1.0
    data = np.where(full > floor, image / np.maximum(full, floor), 0.0).astype(np.complex64)
    return data, norm
