"""Sub-aperture polar images of fast factorised backprojection (:mod:`sarmitsuba.focus.ffbp`).

A sub-aperture ``j`` (consecutive pulses, phase centre ``c`` = mean antenna position, axis
``v`` = unit mean velocity) is imaged on a polar grid of the image plane (Ulander, Hellsten and
Stenstrom 2003, section III): a point ``x`` of the plane has the coordinates

.. math:: r = |\\mathbf{x} - \\mathbf{c}|, \\qquad s = (\\mathbf{x} - \\mathbf{c}) \\cdot \\hat{\\mathbf{v}} / r,

(range and along-track sine), and the sub-aperture image is stored demodulated,

.. math:: S_j(s, r) = e^{-j \\kappa r} \\sum_{p \\in j} w_p(\\mathbf{x})\\, d_p(L_p(\\mathbf{x}) / c)\\,
          e^{+j 2 \\pi f_c L_p(\\mathbf{x}) / c}, \\qquad \\kappa = 4 \\pi f_c / c,

so that ``S_j`` is band limited: in ``r`` to the signal band (``|f_r| <= B / c``), in ``s`` to
``|f_s| <= 2 |p - c|_max / lambda_min`` cycles per unit sine (the sub-aperture's angular
resolution). :class:`PolarFrame` maps ``(s, r)`` to plane points exactly for any track (on the
grid's side of the track); bistatic data use :class:`~.polar_bistatic.BistaticFrame` (eq. (F10)).
This module holds the frame, the first stage (:func:`pulses_to_polar`), the preparation of a polar
image (:func:`prepare`: range upsampling and cubic B-spline coefficients) and the two 1-D passes
that resample it onto rows of target points (:func:`s_pass`, :func:`r_pass`); the cubic B-spline
interpolation they use is :mod:`.polar_spline`.

References
----------
.. [1] L. M. H. Ulander, H. Hellsten and G. Stenstrom, "Synthetic-aperture radar processing
   using fast factorized back-projection", IEEE Trans. Aerosp. Electron. Syst. 39(3),
   760-776, 2003.
.. [2] M. Unser, "Splines: a perfect fit for signal and image processing", IEEE Signal
   Process. Mag. 16(6), 22-38, 1999 (cubic B-spline interpolation and its prefilter).
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from .grid import ImageGrid
from .polar_spline import (CARRIER_PHASE, SPLINE_POLE, carrier_bits, cubic_bspline, range_coefficients,  # noqa: F401
                           spline_prefilter, spline_tables)
from .range_lines import PAD


class GeometryNotSupported(ValueError):
    """An acquisition the factorisation does not handle (a grid that straddles the track or reaches its vertical
    plane, a velocity normal to the image plane): :func:`~sarmitsuba.focus.backproject` focuses it."""

__all__ = ["PolarFrame", "PolarAxes", "PolarImage", "pulses_to_polar", "prepare", "s_pass", "r_pass",
           "premodulated_rows", "range_coefficients", "range_taper", "spline_tables", "carrier_bits", "beam_table",
           "spline_prefilter", "Workspace", "workspace", "SPLINE_POLE", "BEAM_TABLE", "CARRIER_PHASE", "TAPER",
           "CHUNK", "RSTEP", "cubic_bspline"]

#: Samples of the beam-weight table over u in [0, 1] (nearest sample: error below 2e-4 of the
#: largest slope of w g^2 across the beam).
BEAM_TABLE = 1 << 14
#: Zero samples padded at each end of a gather table (a cubic spline reaches 2 samples out).
_EDGE = 4
#: Range samples of a polar image tapered to zero at each end before range upsampling.
TAPER = 12
#: Elements per vectorised step (cache-sized: gathers from larger arrays run 2-3x slower).
CHUNK = 1 << 15
#: Pixel-pulses per vectorised step of the first stage.
_STEP = CHUNK
#: Range samples between the float64 geometry points of the first stage.
RSTEP = 16


# ============================================================================ geometry
class PolarFrame:
    """Polar coordinates ``(s, r)`` of the plane of ``grid`` around ``centre`` with axis ``direction``.

    With ``n`` the plane normal, ``h`` the signed height of the plane over ``centre`` along ``n``,
    ``e1`` the unit in-plane part of the axis (``|v_in|`` its length) and ``e2 = n x e1``, a plane
    point is ``c + h n + xi1 e1 + xi2 e2`` with ``xi1 = (s r - h v.n) / |v_in|`` and
    ``xi2 = side sqrt(r^2 - h^2 - xi1^2)``; ``side`` (+1 or -1) is the side of the track the grid
    lies on. Raises ValueError when the axis is (nearly) normal to the plane.
    """

    def __init__(self, centre: np.ndarray, direction: np.ndarray, grid: ImageGrid):
        self.centre = np.asarray(centre, float)
        self.direction = np.asarray(direction, float)
        n = np.cross(grid.azimuth_direction, grid.range_direction)
        self.normal = n / np.linalg.norm(n)
        self.h = float((grid.origin - self.centre) @ self.normal)
        self.v_n = float(self.direction @ self.normal)
        v_in = self.direction - self.v_n * self.normal
        self.v_in = float(np.linalg.norm(v_in))
        if self.v_in < 1e-6:
            raise GeometryNotSupported("fast backprojection needs a platform velocity with a component in the "
                                       "image plane; use backproject")
        self.e1 = v_in / self.v_in
        self.e2 = np.cross(self.normal, self.e1)
        middle = grid.origin + grid.azimuth.mean() * grid.azimuth_direction + grid.range.mean() * grid.range_direction
        self.side = 1.0 if (middle - self.centre) @ self.e2 >= 0 else -1.0

    def in_plane(self, s: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(xi1, xi2, valid)`` of the points ``(s, r)`` (broadcast, float64); invalid points
        (no plane point at that range and sine) get ``xi2 = 0``."""
        xi1 = (s * r - self.h * self.v_n) / self.v_in
        rho2 = r * r - self.h * self.h - xi1 * xi1
        valid = rho2 > 0.0
        return xi1, self.side * np.sqrt(np.where(valid, rho2, 0.0)), valid

    def units(self, s: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit vectors from the centre to the points ``(s, r)``: float64 [..., 3], and validity."""
        xi1, xi2, valid = self.in_plane(s, r)
        x = (self.h * self.normal + xi1[..., None] * self.e1 + xi2[..., None] * self.e2)
        return x / np.asarray(r)[..., None], valid

    def coordinates(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(s, r)`` of world points ``x`` [..., 3] (float64)."""
        d = x - self.centre
        r = np.sqrt(np.square(d).sum(axis=-1))
        return (d * self.direction).sum(axis=-1) / r, r

    def coarse_geometry(self, *args):
        """:func:`_coarse_geometry` about this frame (:class:`~.polar_bistatic.BistaticFrame` has its own)."""
        return _coarse_geometry(self, *args)

    def s_rate(self, s: np.ndarray, r: np.ndarray) -> np.ndarray:
        """``|d u / d s|`` at fixed ``r``: ``sqrt(1 + (xi1 / xi2)^2) / |v_in|`` (the factor turning
        an antenna offset into cycles per unit sine); inf where ``xi2`` vanishes."""
        xi1, xi2, valid = self.in_plane(s, r)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(valid & (xi2 != 0), xi1 / xi2, np.inf)
        return np.sqrt(1.0 + ratio * ratio) / self.v_in


@dataclass(frozen=True)
class PolarAxes:
    """Uniform axes of a polar image: ``s_m = s0 + m ds`` (m < n_s), ``r_k = r0 + k dr`` (k < n_r)."""

    s0: float
    ds: float
    n_s: int
    r0: float
    dr: float
    n_r: int

    @property
    def s(self) -> np.ndarray:
        """The angular axis ``s0 + m ds``, float64 [n_s]."""
        return self.s0 + self.ds * np.arange(self.n_s)

    @property
    def r(self) -> np.ndarray:
        """The range axis ``r0 + k dr`` [m], float64 [n_r]."""
        return self.r0 + self.dr * np.arange(self.n_r)


@dataclass
class PolarImage:
    """One sub-aperture's polar image: frame, axes, demodulated data and, after :func:`prepare`,
    the gather table of its cubic B-spline coefficients (range upsampled by ``factor``).

    ``s_span``: the sines ``(lo, hi)`` outside which the image is zero (the union of its pulses'
    beams; the whole axis without a beam); ``r_span``: the ranges ``(lo, hi)`` outside which every
    pulse's delay lies outside the fast-time window (there ``backproject`` masks to zero).
    """

    frame: PolarFrame
    axes: PolarAxes
    data: np.ndarray                  # complex64 [n_s, n_r]
    s_span: tuple[float, float]
    r_span: tuple[float, float] = (-np.inf, np.inf)
    table: np.ndarray | None = None   # complex128 [n_r_up * (n_s + 2 EDGE - 1)]: s-pairs per range sample
    fine: PolarAxes | None = None     # axes of the coefficients (range step dr / factor)


# ============================================================================ first stage
def pulses_to_polar(frame: PolarFrame, axes: PolarAxes, antennas: np.ndarray, velocities: np.ndarray,
                    lines: np.ndarray, carrier: tuple[np.ndarray, int], t0: float, fs: float, oversample: int,
                    fc: float, beam: tuple[np.ndarray, float, float] | None,
                    receivers: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                    ) -> tuple[np.ndarray, tuple[float, float]]:
    """Backproject pulses onto a polar grid (the first stage): complex64 [n_s, n_r] ``S_j``, and the
    smallest and largest one-way residual ``|x - A_p| - r`` [m] over its samples and pulses.

    Parameters
    ----------
    frame, axes : PolarFrame, PolarAxes
        The polar grid (a :class:`~.polar_bistatic.BistaticFrame`: ``r`` the half range sum, its receivers,
        eq. (F10)); ``axes.dr`` must be ``c / (2 fs m)`` (``m`` dividing ``oversample``: 1, or a bistatic
        image's own range upsampling) and ``axes.n_r`` a multiple of :data:`RSTEP`.
    antennas, velocities : float64 [P, 3]
        Transmitter positions [m] and unit beam axes of the pulses.
    lines : complex128 [P * n_tab]
        :func:`~.range_lines.premodulated_pairs` of the pulses' lines upsampled ``oversample`` times.
    carrier : (complex128 [m], int)
        :func:`~.range_lines.residual_carrier_table` for ``kh = 2 pi fc / (fs oversample)`` and its size.
    t0, fs, fc : float
        Fast time of the first sample [s], the sampling rate [Hz] and the carrier [Hz].
    beam : (float32 table, sin_lo, sin_hi) or None
        :func:`beam_table` of ``w(u)`` and the beam sines, or None (every pulse sees every point).
    receivers : (float64 [P, 3], float64 [P, 3], float64 [P]) or None
        Continuous-motion data: the receive positions [m] at ``rx_delay`` after transmission, the
        velocities [m/s] and ``rx_delay`` [s]. The residual is then half the two-way length of
        eq. (J3) of docs/physics.md less ``r`` (``antennas`` transmit). None: monostatic.

    Notes
    -----
    The one-way residual ``Delta_p = |x - A_p| - r`` of every sample and pulse, and with a beam
    the table position of the sample's along-track sine from pulse ``p``,
    ``(x - A_p) . v_p / |x - A_p|``, are formed in float64 at every :data:`RSTEP`-th range sample
    and interpolated linearly in between in float32 (both vary slowly along range: the
    interpolation error of ``Delta`` is below ``|A_p - c|^2 (RSTEP dr)^2 / (8 r^3)``, 1e-7 m for a
    16-pulse airborne sub-aperture). With ``dr = c / (2 fs)`` the fine-sample index of the echo
    is ``(2 r_k / c - t0) fs oversample + 2 Delta_p fs oversample / c``, whose first term is
    ``I_0 + k oversample + phi`` exactly, so only ``phi + 2 Delta_p fs oversample / c`` (a few
    fine samples) is ever rounded in float32. The echo is then interpolated linearly in the
    upsampled line with the carrier from the tables, as in :func:`~sarmitsuba.focus.backproject`,
    weighted, summed over the pulses and demodulated by ``exp(-j kappa r_k)`` (float64 phase).
    """
    n_s, n_r, n_pulses = axes.n_s, axes.n_r, antennas.shape[0]
    n_c = n_r // RSTEP
    fine_rate = fs * oversample
    coarse = axes.r0 + axes.dr * RSTEP * np.arange(n_c + 1)
    offset = (2.0 * axes.r0 / SPEED_OF_LIGHT - t0) * fine_rate
    whole = float(np.floor(offset))
    psi, position, valid = frame.coarse_geometry(axes, coarse, antennas, velocities, beam, receivers)
    residuals = (float(psi.min()), float(psi.max()))
    psi = psi * (2.0 * fine_rate / SPEED_OF_LIGHT) + (offset - whole)       # fine samples past sample `whole`
    table, m = carrier
    bits = m.bit_length() - 1
    bias = float(np.ceil(max(-psi.min(), 0.0))) + 1.0                      # keeps the fixed point positive
    n_tab = lines.size // n_pulses
    index_dtype = np.int32 if lines.size < 2**31 else np.int64
    first = whole + PAD + round(2.0 * axes.dr * fine_rate / SPEED_OF_LIGHT) * np.arange(n_r)   # index of psi = 0
    base = (first[None, :] - bias + (np.arange(n_pulses) * n_tab)[:, None]).astype(index_dtype)
    clip = (psi.min() + first[0] < 1) or (psi.max() + first[-1] > n_tab - 2)
    low = ((bias - first) * m).astype(np.float32)
    high = ((n_tab - 1 - first + bias) * m).astype(np.float32)
    fixed = ((psi + bias) * m).astype(np.float32)                           # fixed point: fine sample * m
    t = (np.arange(RSTEP) / RSTEP).astype(np.float32)
    acc = np.zeros((n_s, n_r), np.complex64)
    rows = max(1, _STEP // max(1, n_pulses * n_r))
    ws = workspace(n_pulses * rows * n_r)
    for m0 in range(0, n_s, rows):
        sl = slice(m0, min(m0 + rows, n_s))
        n = n_pulses * (sl.stop - sl.start) * n_r
        shape = (n_pulses, sl.stop - sl.start, n_r)
        iota = _lerp(fixed[:, sl], t, ws.f32[0, :n].reshape(shape))                   # fixed point [P, M, n_r]
        if clip:
            np.clip(iota, low, high, out=iota)
        index = (ws.index32 if index_dtype == np.int32 else ws.i64)[:n].reshape(shape)
        np.copyto(index, iota, casting="unsafe")
        bins = ws.i32[:n]
        np.bitwise_and(index.reshape(-1), m - 1, out=bins, casting="unsafe")
        np.right_shift(index, bits, out=index)
        np.add(index, base[:, None, :], out=index)
        product = np.take(lines, index.reshape(-1), out=ws.c128[0, :n], mode="clip").view(np.complex64).reshape(-1, 2)
        weights = np.take(table, bins, out=ws.c128[1, :n], mode="clip").view(np.complex64).reshape(-1, 2)
        np.multiply(product, weights, out=product)
        value = np.add(product[:, 0], product[:, 1], out=ws.c64[0, :n])
        if beam is not None:
            where = _lerp(position[:, sl], t, ws.f32[0, :n].reshape(shape))
            np.clip(where, 0.0, BEAM_TABLE + 2.0, out=where)
            np.copyto(bins, where.reshape(-1), casting="unsafe")
            np.multiply(value, np.take(beam[0], bins, out=ws.f32[1, :n], mode="clip"), out=value)
        acc[sl] += value.reshape(shape).sum(axis=0)
    acc *= np.exp(-2j * np.pi * np.mod(2.0 * fc * axes.r / SPEED_OF_LIGHT, 1.0)).astype(np.complex64)[None, :]
    acc[~np.repeat(valid[:, :-1] & valid[:, 1:], RSTEP, axis=1)] = 0.0
    return acc, residuals


def _coarse_geometry(frame: PolarFrame, axes: PolarAxes, coarse: np.ndarray, antennas: np.ndarray,
                     velocities: np.ndarray, beam: tuple[np.ndarray, float, float] | None,
                     receivers: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                     ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """float64 [P, n_s, n_c] residuals ``|x - A_p| - r`` (with ``receivers``: ``(|x - t_p| +
    |x - r_p'|) / 2 - r``, ``r_p'`` the receiver at the echo's arrival, eq. (J3)) and (with a beam)
    beam-table positions ``(s_p - sin_lo) / (sin_hi - sin_lo) BEAM_TABLE + 1.5`` at the coarse
    ranges, and the validity [n_s, n_c] of the points.

    Every distance comes from dot products with the points' directions ``u`` from the centre (the
    point is ``x = c + r u``): ``|x - a|^2 - r^2 = q = r^2 (|u|^2 - 1) + |a - c|^2 - 2 r u.(a - c)``
    and ``|x - a| - r = q / (|x - a| + r)`` (no cancellation); the receiver's leg at the arrival,
    ``|x - b - tau v|^2 = |x - b|^2 - 2 tau (x - b).v + tau^2 |v|^2``, the same way. Equal to
    :func:`_coarse_geometry_reference` to float64 rounding (it differs by ``r eps`` there)."""
    u, valid = frame.units(axes.s[:, None], coarse[None, :])                         # [n_s, n_c, 3]
    u = np.ascontiguousarray(np.moveaxis(u, -1, 0))                                  # [3, n_s, n_c]
    r = coarse[None, None, :]
    lift = r * r * (np.einsum("kij,kij->ij", u, u) - 1.0)                            # r^2 (|u|^2 - 1)

    def dot(vectors: np.ndarray) -> np.ndarray:                                      # [P, 3] -> [P, n_s, n_c]
        return np.einsum("pk,kij->pij", vectors, u)

    def leg(offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:                  # (|x - a|, |x - a|^2 - r^2)
        q = dot(offset)
        q *= -2.0 * r
        q += lift
        q += np.einsum("pk,pk->p", offset, offset)[:, None, None]
        return np.sqrt(q + r * r), q

    rel = antennas - frame.centre
    dist, q = leg(rel)
    excess = q / (dist + r)                                                          # |x - A_p| - r
    if receivers is not None:
        rx, velocity, delay = receivers
        back_rel = rx - frame.centre
        back, q_back = leg(back_rel)
        shift = (dist + back) / SPEED_OF_LIGHT - delay[:, None, None]
        # |x - b - shift v|^2 - r^2, with (x - b).v = r u.v - b.v
        along = dot(velocity) * r - np.einsum("pk,pk->p", back_rel, velocity)[:, None, None]
        q_rx = q_back - 2.0 * shift * along + shift * shift * np.einsum("pk,pk->p", velocity, velocity)[:, None, None]
        excess = 0.5 * (excess + q_rx / (np.sqrt(q_rx + r * r) + r))
    position = None
    if beam is not None:
        _, sin_lo, sin_hi = beam
        sine = (dot(velocities) * r - np.einsum("pk,pk->p", rel, velocities)[:, None, None]) / dist
        position = ((sine - sin_lo) * (BEAM_TABLE / (sin_hi - sin_lo)) + 1.5).astype(np.float32)
    return excess, position, valid


def _coarse_geometry_reference(frame: PolarFrame, axes: PolarAxes, coarse: np.ndarray, antennas: np.ndarray,
                     velocities: np.ndarray, beam: tuple[np.ndarray, float, float] | None,
                     receivers: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
                     ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """float64 [P, n_s, n_c] residuals ``|x - A_p| - r`` (with ``receivers``: ``(|x - t_p| +
    |x - r_p'|) / 2 - r``, ``r_p'`` the receiver at the echo's arrival, eq. (J3)) and (with a beam)
    beam-table positions ``(s_p - sin_lo) / (sin_hi - sin_lo) BEAM_TABLE + 1.5`` at the coarse
    ranges, and the validity [n_s, n_c] of the points: the readable reference of
    :func:`_coarse_geometry` (vectors to every point, tests/test_ffbp_speed_paths.py)."""
    u, valid = frame.units(axes.s[:, None], coarse[None, :])                         # [n_s, n_c, 3]
    points = coarse[None, None, :, None] * u[None]                                   # relative to the centre
    rel = points - (antennas - frame.centre)[:, None, None, :]
    dist = np.sqrt(np.square(rel).sum(axis=-1))
    if receivers is not None:
        rx, velocity, delay = receivers
        back = np.sqrt(np.square(points - (rx - frame.centre)[:, None, None, :]).sum(axis=-1))
        shift = (dist + back) / SPEED_OF_LIGHT - delay[:, None, None]
        moved = points - (rx - frame.centre)[:, None, None, :] - shift[..., None] * velocity[:, None, None, :]
        dist_rx = np.sqrt(np.square(moved).sum(axis=-1))
        sine_dist, dist = dist, 0.5 * (dist + dist_rx)
    else:
        sine_dist = dist
    position = None
    if beam is not None:
        _, sin_lo, sin_hi = beam
        sine = (rel * velocities[:, None, None, :]).sum(axis=-1) / sine_dist
        position = ((sine - sin_lo) * (BEAM_TABLE / (sin_hi - sin_lo)) + 1.5).astype(np.float32)
    return dist - coarse, position, valid


def _lerp(coarse: np.ndarray, t: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Linear interpolation along the last axis into ``out``: [..., n_c + 1] samples every ``t.size``
    fine samples to [..., n_c t.size] (float32). Returns ``out``."""
    left = coarse[..., :-1, None]
    fine = out.reshape(coarse.shape[:-1] + (-1, t.size))
    np.multiply(coarse[..., 1:, None] - left, t, out=fine)
    np.add(fine, left, out=fine)
    return out


class Workspace:
    """Scratch buffers of one thread, reused across chunks (fresh arrays of this size come from mmap
    and cost a page fault per 4 kB). Grows on demand."""

    def __init__(self) -> None:
        self.size = 0

    def ensure(self, size: int) -> "Workspace":
        """The workspace with buffers of at least ``size`` elements (reallocated only to grow)."""
        if size > self.size:
            self.size = size
            self.f32 = np.empty((2, size), np.float32)
            self.f64 = np.empty((2, size), np.float64)
            self.i32 = np.empty(size, np.int32)       # fraction bins
            self.i64 = np.empty(size, np.int64)       # table indices
            self.index32 = np.empty(size, np.int32)   # table indices of the first stage
            self.c64 = np.empty((3, size), np.complex64)
            self.c128 = np.empty((3, size), np.complex128)
        return self


_LOCAL = threading.local()


def workspace(size: int = 0) -> Workspace:
    """This thread's :class:`Workspace`, at least ``size`` elements."""
    ws = getattr(_LOCAL, "workspace", None)
    if ws is None:
        ws = _LOCAL.workspace = Workspace()
    return ws.ensure(max(size, CHUNK))


def beam_table(weights_u: np.ndarray, values: np.ndarray) -> np.ndarray:
    """float32 [BEAM_TABLE + 3]: ``values`` (sampled at ``weights_u`` in [0, 1]) at ``u = i / BEAM_TABLE``
    for table index ``i + 1``, with zeros at index 0 and the last two (outside the beam)."""
    out = np.zeros(BEAM_TABLE + 3, np.float32)
    out[1:BEAM_TABLE + 2] = np.interp(np.arange(BEAM_TABLE + 1) / BEAM_TABLE, weights_u, values)
    return out


# ============================================================================ preparation
def prepare(image: PolarImage, factor: int, workers: int = 1) -> PolarImage:
    """Make a polar image ready for :func:`s_pass`: taper the ends of its range lines over
    :data:`TAPER` samples, upsample them ``factor`` times by FFT with the cubic B-spline prefilter
    ``3 / (2 + cos(2 pi f))`` of the fine grid applied in the spectrum, prefilter along ``s``, and
    store the coefficients transposed (range-major) as complex128 pairs of neighbouring sines with
    :data:`_EDGE` zeros at each end of every range sample's column. Returns ``image``."""
    axes = image.axes
    # along s first (it commutes with the range FFT); in complex128: the recursion decays into
    # float32 subnormals over the empty parts of the image, which are 100x slower
    lines = spline_prefilter(image.data * range_taper(axes.n_r).astype(np.float64)[None, :], axis=0)
    coeffs = range_coefficients(lines, factor, workers)
    n_up = coeffs.shape[1]
    padded = np.zeros((n_up, axes.n_s + 2 * _EDGE), np.complex64)
    padded[:, _EDGE:_EDGE + axes.n_s] = coeffs.T
    image.table = _pairs(padded)
    image.fine = PolarAxes(axes.s0, axes.ds, axes.n_s, axes.r0, axes.dr / factor, n_up)
    return image


def range_taper(n: int) -> np.ndarray:
    """float32 [n]: 1 inside, a raised cosine over the outer :data:`TAPER` samples of each end."""
    w = np.ones(n, np.float32)
    k = min(TAPER, n // 2)
    if k:
        ramp = (0.5 - 0.5 * np.cos(np.pi * (np.arange(k) + 0.5) / k)).astype(np.float32)
        w[:k], w[n - k:] = ramp, ramp[::-1]
    return w


def _pairs(rows: np.ndarray) -> np.ndarray:
    """complex128 [n_rows * (n - 1)]: element ``i (n - 1) + k`` packs ``(rows[i, k], rows[i, k + 1])``."""
    n_rows, n = rows.shape
    out = np.empty((n_rows, n - 1, 2), np.complex64)
    out[:, :, 0] = rows[:, :-1]
    out[:, :, 1] = rows[:, 1:]
    return out.reshape(-1).view(np.complex128)


# ============================================================================ the two passes
def _gather4(pairs: np.ndarray, index: np.ndarray, tables: tuple[np.ndarray, np.ndarray, int],
             bins: np.ndarray, ws: Workspace, out: np.ndarray) -> np.ndarray:
    """``out`` (complex64 [n]) = ``sum_b W_b(f) D[k + b]`` from the pair table (``index``, int64, points
    at the pair of taps (-1, 0); +2 at (1, 2)) and the weight tables at the fraction ``bins``."""
    w_lo, w_hi, _ = tables
    n = index.size
    product = np.take(pairs, index, out=ws.c128[0, :n], mode="clip").view(np.complex64).reshape(-1, 2)
    weights = np.take(w_lo, bins, out=ws.c128[1, :n], mode="clip").view(np.complex64).reshape(-1, 2)
    np.multiply(product, weights, out=product)
    np.add(product[:, 0], product[:, 1], out=out)
    index += 2
    product = np.take(pairs, index, out=ws.c128[0, :n], mode="clip").view(np.complex64).reshape(-1, 2)
    weights = np.take(w_hi, bins, out=ws.c128[1, :n], mode="clip").view(np.complex64).reshape(-1, 2)
    np.multiply(product, weights, out=product)
    out += product[:, 0]
    out += product[:, 1]
    return out


def _locate(position: np.ndarray, m: int, ws: Workspace) -> tuple[np.ndarray, np.ndarray]:
    """Integer part (int64) and fraction bin (int32, ``m = 2**bits`` bins) of non-negative
    fractional sample positions (float64, scaled in place), from one fixed-point conversion."""
    n = position.size
    position *= float(m)
    q = ws.i64[:n].reshape(position.shape)
    np.copyto(q, position, casting="unsafe")
    bins = ws.i32[:n]
    np.bitwise_and(q.reshape(-1), m - 1, out=bins, casting="unsafe")
    np.right_shift(q, int(m).bit_length() - 1, out=q)
    return q, bins


def s_pass(image: PolarImage, s: np.ndarray, k0: int, tables: tuple[np.ndarray, np.ndarray, int],
           out: np.ndarray) -> np.ndarray:
    """Interpolate a prepared polar image along ``s`` at fixed fine range samples.

    ``s`` float64 [rows, n] (overwritten): the sine of the target point of each row at fine range
    sample ``k0 + column``. Fills ``out`` (complex64 [rows, n]) with the cubic-spline value there
    (still spline coefficients along range, since the range prefilter commutes with the pass to
    first order: B-splines reproduce linear functions). Sines beyond the axis by more than two
    samples read zeros. At most :data:`CHUNK` points per call (cache-sized gathers)."""
    fine = image.fine
    ws = workspace(s.size)
    position = s
    position -= fine.s0
    position *= 1.0 / fine.ds
    np.clip(position, -2.0, fine.n_s + 1.0, out=position)
    position += 2.0                                                    # non-negative for _locate
    whole, bins = _locate(position, tables[2], ws)
    whole += (np.arange(k0, k0 + s.shape[1]) * (fine.n_s + 2 * _EDGE - 1) + (_EDGE - 3))[None, :]
    _gather4(image.table, whole.reshape(-1), tables, bins, ws, out.reshape(-1))
    return out


def premodulated_rows(coeffs: np.ndarray, carrier: np.ndarray, ws: Workspace) -> np.ndarray:
    """The gather table of :func:`r_pass`: complex128 pairs of neighbouring range coefficients times
    the carrier ``exp(+j kappa r_k)`` (complex64 [n]), :data:`_EDGE` zeros at each end of each row
    (in ``ws.c128[2]``)."""
    rows, n = coeffs.shape
    width = n + 2 * _EDGE
    padded = ws.c64[2, :rows * width].reshape(rows, width)
    padded[:, :_EDGE] = 0.0
    padded[:, _EDGE + n:] = 0.0
    np.multiply(coeffs, carrier[None, :], out=padded[:, _EDGE:_EDGE + n])
    pairs = ws.c128[2, :rows * (width - 1)].view(np.complex64).reshape(rows, width - 1, 2)
    pairs[:, :, 0] = padded[:, :-1]
    pairs[:, :, 1] = padded[:, 1:]
    return ws.c128[2, :rows * (width - 1)]


def r_pass(table: np.ndarray, n: int, position: np.ndarray,
           tables: tuple[np.ndarray, np.ndarray, int], out: np.ndarray) -> np.ndarray:
    """Interpolate rows of range coefficients with the carrier restored.

    ``table`` from :func:`premodulated_rows` of ``n`` coefficients per row at ranges ``r_k``;
    ``position`` float64 [rows, m] (overwritten), the target ranges in samples of ``r_k``, within
    [-2, n + 1] (beyond the row's ends the spline reads the zero edges); ``tables`` from
    :func:`spline_tables` with ``phase_per_sample = kappa dr``. Fills ``out`` (complex64
    [rows, m]) with ``S(r) exp(+j kappa r)``."""
    ws = workspace(position.size)
    position += 2.0                                                    # non-negative for _locate
    whole, bins = _locate(position, tables[2], ws)
    whole += (np.arange(position.shape[0]) * (n + 2 * _EDGE - 1) + (_EDGE - 3))[:, None]
    _gather4(table, whole.reshape(-1), tables, bins, ws, out.reshape(-1))
    return out
