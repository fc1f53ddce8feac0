"""Polar coordinates of fast factorised backprojection for bistatic data (docs/physics.md (F10)).

A bistatic stop-and-hop sub-aperture (transmitters ``T_p``, receivers ``R_p`` on their own
platform) has two phase centres, ``T_c`` and ``R_c`` (the mean positions), and velocities ``V_T``,
``V_R``. Its polar image is taken on the half bistatic range sum and a weighted along-track sine,

.. math:: \\rho = (|\\mathbf{x} - \\mathbf{T}_c| + |\\mathbf{x} - \\mathbf{R}_c|) / 2, \\qquad
          s = \\frac{\\mathbf{V}_T \\cdot \\mathbf{u}_T + \\mathbf{V}_R \\cdot \\mathbf{u}_R}
                   {|\\mathbf{V}_T| + |\\mathbf{V}_R|},

(ellipsoids of revolution about the two centres, not spheres about one; ``u_T``, ``u_R`` the unit
vectors from ``T_c``, ``R_c`` to ``x``) and stored demodulated by ``exp(-j kappa rho)``, ``kappa =
4 pi fc / c``. Each pulse's residual ``L_p / 2 - rho`` is then small (at most ``(|T_p - T_c| +
|R_p - R_c|) / 2``) and, to first order, ``-tau_p (|V_T| + |V_R|) s / 2``: constant along the lines
of constant ``s``, so that the image is band limited as the monostatic one (F3). With ``R_p = T_p``
the coordinates are the monostatic ``(s, r)`` of :class:`~.polar.PolarFrame` (F2), which monostatic
data keep using.

:class:`BistaticFrame` maps ``(s, rho)`` back to plane points (:meth:`BistaticFrame.locate`,
Newton on the plane), measures the angular band (:meth:`BistaticFrame.residual_rate`), forms the
first-stage residuals without cancellation (:meth:`BistaticFrame.coarse_geometry`, on a lattice
sheared along the transmitter's beam) and gives the last step the points of a grid line at given
``rho`` (a line meets an ellipsoid of revolution in a quadratic, closed form) and the pixels' ``rho``
(:meth:`BistaticFrame.row_sines`, :meth:`BistaticFrame.pixel_ranges`). :func:`prepare_samples` and
:func:`row_coefficients` are the image's preparation and the lines' range prefilter.
"""
from __future__ import annotations

import threading

import numpy as np
import scipy.ndimage

from .grid import ImageGrid
from .polar import BEAM_TABLE, GeometryNotSupported, PolarAxes, PolarFrame, PolarImage, spline_prefilter

__all__ = ["BistaticFrame", "prepare_samples", "row_coefficients", "NEWTON_STEPS", "NEWTON_TOLERANCE",
           "PREFILTER_REACH", "ROW_STEP"]

#: Fine range samples beyond a block's own that the row prefilter of :func:`row_coefficients` reads
#: (its impulse response ``sqrt(3) (sqrt(3) - 2)^|n|`` is below 1e-5 beyond them).
PREFILTER_REACH = 9

#: Largest number of Newton steps of :meth:`BistaticFrame.locate`.
NEWTON_STEPS = 20
#: Largest ``|rho(x) - rho|`` [m] at which :meth:`BistaticFrame.locate` stops (1e-8 m: 4e-6 rad at X band;
#: the first stage adds the misfit left to its residuals, so only ``s`` carries it).
NEWTON_TOLERANCE = 1e-8
#: Fine range samples between the exact row points of :meth:`BistaticFrame.row_sines`.
ROW_STEP = 8
#: Zero sines padded at each end of a gather table (as :func:`~.polar.prepare`: the spline reaches 2 out).
_EDGE = 4


class BistaticFrame(PolarFrame):
    """Bistatic polar coordinates ``(s, rho)`` of the plane of ``grid`` for one sub-aperture (F10).

    Parameters
    ----------
    transmitters, receivers : float64 [P, 3]
        The pulses' transmit and receive positions [m] (``receivers != transmitters``).
    tx_velocity, rx_velocity : float64 [3]
        The sub-aperture's transmitter and receiver velocities ``V_T``, ``V_R`` [m/s] (the weights
        and axes of ``s``; ``V_T`` needs a component in the image plane).
    grid : ImageGrid
        The image; its plane and the side of the transmitter's track it lies on.

    ``s = (V_T . u_T + V_R . u_R) / (|V_T| + |V_R|)`` with ``u_T``, ``u_R`` the unit vectors from
    ``T_c``, ``R_c`` to the point: to first order pulse ``p`` (at ``tau_p`` from the sub-aperture's
    middle) has the residual ``-tau_p (|V_T| + |V_R|) s / 2``, constant along the lines of constant
    ``s``, so that the residual carrier leaves the range band alone, as the monostatic sine does.
    Attributes: ``centre`` (``T_c``), ``receiver`` (``R_c``), ``spread`` (m: the largest
    ``(|T_p - T_c| + |R_p - R_c|) / 2``, a bound on ``|L_p / 2 - rho|``) and ``tx_spread`` (m: the
    largest ``|T_p - T_c|``). Raises GeometryNotSupported as :class:`~.polar.PolarFrame`.
    """

    def __init__(self, transmitters: np.ndarray, receivers: np.ndarray, tx_velocity: np.ndarray,
                 rx_velocity: np.ndarray, grid: ImageGrid):
        self.transmitters = np.asarray(transmitters, float)
        self.receivers = np.asarray(receivers, float)
        v_t, v_r = np.asarray(tx_velocity, float), np.asarray(rx_velocity, float)
        speed_t, speed_r = float(np.linalg.norm(v_t)), float(np.linalg.norm(v_r))
        if speed_t <= 0.0:
            raise GeometryNotSupported("fast backprojection of bistatic data needs a moving transmitter; "
                                       "use backproject")
        super().__init__(self.transmitters.mean(axis=0), v_t / speed_t, grid)
        self.receiver = self.receivers.mean(axis=0)
        self.offset = self.receiver - self.centre                  # R_c - T_c
        self.w_t, self.w_r = speed_t / (speed_t + speed_r), speed_r / (speed_t + speed_r)
        self.rx_axis = v_r / speed_r if speed_r > 0 else np.zeros(3)
        tx_off = np.linalg.norm(self.transmitters - self.centre, axis=1)
        rx_off = np.linalg.norm(self.receivers - self.receiver, axis=1)
        self.spread = float(np.max(0.5 * (tx_off + rx_off)))
        self.tx_spread = float(np.max(tx_off))
        self.beam_span = (-np.inf, np.inf)             # the transmitter sines the image covers (set by the plan)
        self.shear = (np.zeros(1), 0.0)                # (a, rho_mid): the lattice's s' = s - a(rho - rho_mid)
        self._fit_start(grid)

    # ------------------------------------------------------------------------ the map and its inverse
    def coordinates(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(s, rho)`` of world points ``x`` float64 [..., 3]: float64 [...] each."""
        return self._coordinates(np.asarray(x, float) - self.centre)[:2]

    def lattice_shift(self, rho: np.ndarray) -> np.ndarray:
        """``a(rho - rho_mid)`` float64 [...]: the polar lattice's sines are ``s' = s - a(rho - rho_mid)``
        (``shear = (a, rho_mid)``, ``a`` the coefficients of a polynomial, highest first: by the plan,
        a line)."""
        return np.polyval(self.shear[0], np.asarray(rho, float) - self.shear[1])

    def tx_sine(self, x: np.ndarray) -> np.ndarray:
        """The transmitter's along-track sine ``(x - T_c) . v_T / |x - T_c|`` of points ``x`` [..., 3] (the beam's)."""
        d = np.asarray(x, float) - self.centre
        return (d @ self.direction) / np.sqrt(np.square(d).sum(axis=-1))

    def _coordinates(self, d: np.ndarray):
        """``(s, rho, r_T, r_R, x - R_c)`` of the points ``x = T_c + d``."""
        back = d - self.offset
        r_t = np.sqrt(np.square(d).sum(axis=-1))
        r_r = np.sqrt(np.square(back).sum(axis=-1))
        s = self.w_t * (d @ self.direction) / r_t + self.w_r * (back @ self.rx_axis) / r_r
        return s, 0.5 * (r_t + r_r), r_t, r_r, back

    def _fit_start(self, grid: ImageGrid) -> None:
        """Least-squares quadratic map from ``(s, rho)`` to the plane coordinates ``(xi1, xi2)`` over a
        17 x 17 lattice of the grid: the start of :meth:`locate`'s Newton iteration."""
        a = np.linspace(grid.azimuth[0], grid.azimuth[-1], 17)
        r = np.linspace(grid.range[0], grid.range[-1], 17)
        x = (grid.origin + a[:, None, None] * grid.azimuth_direction + r[None, :, None] * grid.range_direction)
        d = x.reshape(-1, 3) - self.centre
        s, rho = self._coordinates(d)[:2]
        self._scale = (float(s.mean()), float(np.ptp(s)) or 1.0, float(rho.mean()), float(np.ptp(rho)) or 1.0)
        self._coef = np.linalg.lstsq(self._features(s, rho), np.stack([d @ self.e1, d @ self.e2], -1), rcond=None)[0]

    def _features(self, s: np.ndarray, rho: np.ndarray) -> np.ndarray:
        u = (s - self._scale[0]) / self._scale[1]
        v = (rho - self._scale[2]) / self._scale[3]
        return np.stack([np.ones_like(u), u, v, u * u, u * v, v * v], axis=-1)

    def locate(self, s: np.ndarray, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Plane points at ``(s, rho)`` (broadcast, float64): ``x - T_c`` float64 [..., 3], the misfit
        ``rho(x) - rho`` [m] and the validity (converged, on the grid's side of the transmitter's
        track). Newton in the plane coordinates ``x = T_c + h n + xi1 e1 + xi2 e2`` from a fitted
        quadratic start; each step solves the 2 x 2 system of the gradients of ``rho`` and ``s``."""
        s, rho = np.broadcast_arrays(np.asarray(s, float), np.asarray(rho, float))
        shape = s.shape
        s, rho = s.reshape(-1), rho.reshape(-1)
        xi = self._features(s, rho) @ self._coef                                       # [n, 2]
        active, last = np.arange(s.size), np.full(s.size, np.inf)
        for k in range(NEWTON_STEPS):                  # only the points not yet converged
            step, done = self._newton_step(xi[active], s[active], rho[active])
            xi[active] -= step
            size = np.sqrt(np.square(step).sum(axis=-1))
            if k >= 3:                                 # quadratic convergence or none: no point there
                done |= size > 0.5 * last
            active, last = active[~done], size[~done]
            if active.size == 0:
                break
        d = self.h * self.normal + xi[:, :1] * self.e1 + xi[:, 1:] * self.e2
        s_x, rho_x = self._coordinates(d)[:2]
        valid = (np.abs(rho_x - rho) <= 1e-6) & (np.abs(s_x - s) <= 1e-9) & (xi[:, 1] * self.side > 0)
        return d.reshape(shape + (3,)), (rho_x - rho).reshape(shape), valid.reshape(shape)

    def _newton_step(self, xi: np.ndarray, s: np.ndarray, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One Newton step [n, 2] of :meth:`locate` from the plane coordinates ``xi`` [n, 2] (at most a
        quarter of the transmitter's range long), and whether the point has converged (bool [n]: the
        step is the last one it needs)."""
        d = self.h * self.normal + xi[:, :1] * self.e1 + xi[:, 1:] * self.e2
        s_x, rho_x, (a11, a12, a21, a22), r_t, _, _ = self._jacobian(d)
        f_rho, f_s = rho_x - rho, s_x - s
        det = a11 * a22 - a12 * a21
        det = np.where(np.abs(det) > 1e-300, det, 1e-300)
        step = np.stack([(a22 * f_rho - a12 * f_s) / det, (a11 * f_s - a21 * f_rho) / det], axis=-1)
        size = np.sqrt(np.square(step).sum(axis=-1))
        step *= np.minimum(1.0, 0.25 * r_t / np.maximum(size, 1e-300))[:, None]
        # quadratic convergence: a step below 1e-4 m leaves an error near 1e-8 m / (distance)
        done = (np.abs(f_rho) <= NEWTON_TOLERANCE) & (np.abs(f_s) <= 1e-11) | (size <= 1e-5)
        return step, done


    def s_rate(self, s: np.ndarray, rho: np.ndarray) -> np.ndarray:
        """float64 [...]: :meth:`residual_rate` at the plane points ``(s, rho)`` (:meth:`locate`); inf
        where there is none."""
        d, _, valid = self.locate(s, rho)
        return np.where(valid, self.residual_rate(self.centre + d), np.inf)

    def residual_rate(self, x: np.ndarray) -> np.ndarray:
        """float64 [n]: ``max_p |d (L_p / 2 - rho) / d s| / spread`` at fixed ``rho`` at the plane points
        ``x`` [n, 3] (the bistatic counterpart of :meth:`PolarFrame.s_rate`: ``spread x rate`` is the
        largest rate at which a pulse's residual changes with ``s``, (F3), (F10)): the gradient of the
        residual, ``((u_Tp - u_T) + (u_Rp - u_R)) / 2``, along the plane's direction of constant
        ``rho`` and unit rate of ``s`` (the 2 x 2 system of :meth:`locate`)."""
        d = np.asarray(x, float).reshape(-1, 3) - self.centre
        _, _, a, r_t, r_r, back = self._jacobian(d)
        det = a[0] * a[3] - a[1] * a[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            dx = (-a[1] / det)[:, None] * self.e1 + (a[0] / det)[:, None] * self.e2      # d rho = 0, d s = 1
        grad = 0.0
        legs = ((d, r_t, self.transmitters - self.centre), (back, r_r, self.receivers - self.receiver))
        for leg, dist, offsets in legs:
            rel = leg[None] - offsets[:, None, :]                                          # x - a_p [P, n, 3]
            grad = grad + rel / np.sqrt(np.square(rel).sum(axis=-1))[..., None] - (leg / dist[:, None])[None]
        rate = np.max(np.abs(np.einsum("pnk,nk->pn", grad, dx)), axis=0) / (2.0 * max(self.spread, 1e-300))
        return np.where(np.isfinite(rate), rate, np.inf)

    def _jacobian(self, d: np.ndarray):
        """``(s, rho, (a11, a12, a21, a22), r_T, r_R, x - R_c)`` at ``x = T_c + d`` [n, 3]: the gradients
        of ``rho`` (row 1) and ``s`` (row 2) along ``e1`` and ``e2``."""
        s_x, rho_x, r_t, r_r, back = self._coordinates(d)
        u_t, u_r = d / r_t[:, None], back / r_r[:, None]
        grad_rho = 0.5 * (u_t + u_r)
        grad_s = (self.w_t * (self.direction - (u_t @ self.direction)[:, None] * u_t) / r_t[:, None]
                  + self.w_r * (self.rx_axis - (u_r @ self.rx_axis)[:, None] * u_r) / r_r[:, None])
        return s_x, rho_x, (grad_rho @ self.e1, grad_rho @ self.e2, grad_s @ self.e1, grad_s @ self.e2), r_t, r_r, back

    def _residuals(self, d: np.ndarray) -> np.ndarray:
        """float64 [P, ...]: ``L_p(x) / 2 - rho(x)`` at ``x = T_c + d`` (no cancellation)."""
        r_t = np.sqrt(np.square(d).sum(axis=-1))
        back = d - self.offset
        r_r = np.sqrt(np.square(back).sum(axis=-1))
        out = []
        legs = ((d, r_t, self.transmitters - self.centre), (back, r_r, self.receivers - self.receiver))
        for leg, dist, offsets in legs:
            q = (np.einsum("pk,pk->p", offsets, offsets)[(...,) + (None,) * dist.ndim]
                 - 2.0 * np.einsum("pk,...k->p...", offsets, leg))                       # |x - a_p|^2 - |x - c|^2
            out.append(q / (np.sqrt(q + dist * dist) + dist))
        return 0.5 * (out[0] + out[1])

    # ------------------------------------------------------------------------ first stage
    def coarse_geometry(self, axes: PolarAxes, coarse: np.ndarray, antennas: np.ndarray, velocities: np.ndarray,
                        beam: tuple[np.ndarray, float, float] | None, receivers=None
                        ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """As :func:`~.polar.pulses_to_polar`'s coarse geometry (float64 [P, n_s, n_c] residuals, float32
        beam-table positions or None, validity [n_s, n_c]) with the bistatic residual
        ``(|x - T_p| + |x - R_p|) / 2 - rho`` (``antennas``: the transmitters ``T_p``; the receivers are
        the frame's), each leg as ``q / (|x - a| + |x - c|)`` plus the Newton misfit, and the beam
        position of the transmitter's sine ``(x - T_p) . v_p / |x - T_p|``. ``receivers`` (continuous
        motion) must be None."""
        if receivers is not None:
            raise ValueError("a bistatic frame takes stop-and-hop data (no rx_time)")
        d, misfit, valid = self.locate(axes.s[:, None] + self.lattice_shift(coarse)[None, :],
                                       coarse[None, :])                                   # [n_s, n_c, 3]
        excess = self._residuals(d) + misfit[None]
        position = None
        if beam is not None:
            _, sin_lo, sin_hi = beam
            rel = antennas - self.centre
            q = np.einsum("pk,pk->p", rel, rel)[:, None, None] - 2.0 * np.einsum("pk,ijk->pij", rel, d)
            dist = np.sqrt(q + np.square(d).sum(axis=-1)[None])
            sine = np.einsum("pk,ijk->pij", velocities, d) - np.einsum("pk,pk->p", rel, velocities)[:, None, None]
            sine /= dist
            position = ((sine - sin_lo) * (BEAM_TABLE / (sin_hi - sin_lo)) + 1.5).astype(np.float32)
        return excess, position, valid

    # ------------------------------------------------------------------------ last step
    def _rows(self, grid: ImageGrid, rows: slice, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(p, h2)`` float64 [n]: ``|x - centre|^2 = (t + p)^2 + h2`` for the pixel at range ``t`` of each row."""
        rel = grid.origin - centre
        e_a, e_r = grid.azimuth_direction, grid.range_direction
        a = grid.azimuth[rows]
        p = rel @ e_r + a * (e_a @ e_r)
        q = rel @ rel + 2.0 * a * (rel @ e_a) + a * a
        return p, q - p * p

    def along_azimuth(self, grid: ImageGrid, rows: slice, cols: slice) -> bool:
        """Whether the last step should run along the grid's azimuth axis over the pixels ``rows x cols``:
        the unit gradient of ``rho`` at the block's four corners has a larger least component along
        it than along the range axis (a line nearly along a contour of ``rho`` moves its point at
        ``rho_k`` fast with ``k``, and the values along it would alias)."""
        a, r = grid.azimuth[[rows.start, rows.stop - 1]], grid.range[[cols.start, cols.stop - 1]]
        x = (grid.origin + a[:, None, None] * grid.azimuth_direction + r[None, :, None] * grid.range_direction)
        g = ((x - self.centre) / np.linalg.norm(x - self.centre, axis=-1, keepdims=True)
             + (x - self.receiver) / np.linalg.norm(x - self.receiver, axis=-1, keepdims=True)).reshape(-1, 3)
        g /= np.linalg.norm(g, axis=1, keepdims=True)
        return bool(np.min(np.abs(g @ grid.azimuth_direction)) > np.min(np.abs(g @ grid.range_direction)))

    def pixel_ranges(self, grid: ImageGrid, rows: slice, cols: slice) -> tuple[np.ndarray, float]:
        """``rho`` of the pixels ``rows x cols`` (float64 [n_rows, n_cols], m; a view of this thread's
        scratch buffer, valid until the next call) and the side (+1 or -1)
        of each row's least ``rho`` on which they lie. Raises GeometryNotSupported when a row's pixels
        lie on both sides of it (the grid straddles the baseline's ground track)."""
        t = grid.range[cols]
        slope, dist = 0.0, []
        for slot, centre in enumerate((self.centre, self.receiver)):      # in place, in reused buffers
            p, h2 = self._rows(grid, rows, centre)
            a = np.add.outer(p, t, out=_scratch(slot, p.size * t.size).reshape(p.size, t.size))   # t + p
            ends = a[:, [0, -1]].copy()
            np.square(a, out=a)
            a += h2[:, None]
            np.sqrt(a, out=a)
            slope = slope + ends / a[:, [0, -1]]                            # 2 d rho / d t at the ends
            dist.append(a)
        side = 1.0 if slope[0, 0] > 0 else -1.0
        if np.any(slope * side <= 0):
            raise GeometryNotSupported("ffbp: an image row crosses its least bistatic range sum inside the grid "
                                       "(the grid straddles the baseline); use backproject")
        rho = dist[0]
        rho += dist[1]
        rho *= 0.5
        return rho, side

    def row_sines(self, grid: ImageGrid, rows: slice, rho: np.ndarray, side: float,
                  part: tuple[slice, slice] | None = None, table: np.ndarray | None = None,
                  out: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """float64 [n_rows, n_k]: the lattice sines ``s'`` of the points of each row at the half range
        sums ``rho`` [n_k] (evenly spaced): :meth:`exact_row_sines` at every :data:`ROW_STEP`-th of them
        and the last (``table``, when given: those exact values, computed once for several calls),
        linearly interpolated in between (the sine bends by less than 0.02 of a sine step over them,
        or the line runs along the other axis, :meth:`along_azimuth`). ``part``: (rows, samples) of
        the result wanted, relative to ``rows`` and ``rho`` (default all); ``out``: two float64
        buffers of at least its size (the result is a view of the first)."""
        n = rho.size
        coarse = np.unique(np.r_[np.arange(0, n, ROW_STEP), n - 1])
        exact = self.exact_row_sines(grid, rows, rho[coarse], side) if table is None else table
        lines, samples = part if part is not None else (slice(0, exact.shape[0]), slice(0, n))
        k = np.arange(samples.start, samples.stop)
        j = np.minimum(k // ROW_STEP, coarse.size - 2) if coarse.size > 1 else np.zeros(k.size, int)
        if coarse.size == 1:
            return exact[lines][:, j].copy()
        w = (k - coarse[j]) / (coarse[j + 1] - coarse[j])
        left = exact[lines]
        shape = (left.shape[0], k.size)
        a, b = (np.empty(shape), np.empty(shape)) if out is None else \
            (out[0].reshape(-1)[:k.size * shape[0]].reshape(shape), out[1].reshape(-1)[:k.size * shape[0]].reshape(shape))
        np.take(left, j, axis=1, out=a)
        np.take(left, j + 1, axis=1, out=b)
        b -= a
        b *= w
        a += b
        return a

    def row_sine_table(self, grid: ImageGrid, rows: slice, rho: np.ndarray, side: float) -> np.ndarray:
        """The exact values :meth:`row_sines` interpolates (float64 [n_rows, n_coarse]), for reuse."""
        n = rho.size
        return self.exact_row_sines(grid, rows, rho[np.unique(np.r_[np.arange(0, n, ROW_STEP), n - 1])], side)

    def exact_row_sines(self, grid: ImageGrid, rows: slice, rho: np.ndarray, side: float) -> np.ndarray:
        """float64 [n_rows, n_k]: ``s`` of the point of each row at half range sum ``rho`` [n_k]
        on ``side`` of its least ``rho`` (the nearest point where the row does not reach ``rho``).

        The row ``x = o + t e`` meets the ellipsoid ``rho^2 |y|^2 - (y . f)^2 = rho^2 (rho^2 - |f|^2)``
        (``y = x - (T_c + R_c) / 2``, ``f = (T_c - R_c) / 2``) where ``A t^2 + 2 B t + C = 0``; the
        root is taken in the form without cancellation (``q = -(B + sign(B) sqrt(B^2 - A C))``,
        roots ``q / A`` and ``C / q``)."""
        a = grid.azimuth[rows][:, None]
        e = grid.range_direction
        f = -0.5 * self.offset
        y0 = grid.origin - (self.centre - f)                              # row origins less the midpoint
        y0_e = (y0 @ e) + a * (grid.azimuth_direction @ e)
        y0_f = (y0 @ f) + a * (grid.azimuth_direction @ f)
        y0_y0 = y0 @ y0 + 2.0 * a * (y0 @ grid.azimuth_direction) + a * a
        e_f, f_f = float(e @ f), float(f @ f)
        a2 = (rho * rho)[None, :]
        big_a = a2 - e_f * e_f
        big_b = a2 * y0_e - y0_f * e_f
        big_c = a2 * ((y0_y0 - a2) + f_f) - y0_f * y0_f
        root = np.sqrt(np.maximum(big_b * big_b - big_a * big_c, 0.0))
        sign = np.where(big_b >= 0, 1.0, -1.0)
        q = -(big_b + sign * root)
        with np.errstate(divide="ignore", invalid="ignore"):
            far = np.where(-sign == side, q / big_a, np.where(q != 0, big_c / q, -big_b / big_a))
        t = far                                                            # the root on `side`
        out = np.zeros(t.shape)
        for centre, axis, weight in ((self.centre, self.direction, self.w_t), (self.receiver, self.rx_axis, self.w_r)):
            p, h2 = self._rows(grid, rows, centre)
            along = (grid.origin - centre) @ axis + a * (grid.azimuth_direction @ axis)
            out += weight * (along + t * (e @ axis)) / np.sqrt((t + p[:, None]) ** 2 + h2[:, None])
        out -= self.lattice_shift(rho)[None, :]
        return out


_LOCAL = threading.local()


def _scratch(slot: int, size: int) -> np.ndarray:
    """This thread's float64 buffer ``slot`` (0 or 1) of at least ``size`` elements (reused: fresh
    arrays of a block's size cost a page fault per 4 kB, as :class:`~.polar.Workspace` notes)."""
    buffers = getattr(_LOCAL, "buffers", None)
    if buffers is None:
        buffers = _LOCAL.buffers = [np.empty(0), np.empty(0)]
    if buffers[slot].size < size:
        buffers[slot] = np.empty(size)
    return buffers[slot][:size]


def prepare_samples(image: PolarImage) -> PolarImage:
    """Make a bistatic polar image (formed at its final range step, (F10)) ready for the s-pass: cubic
    B-spline prefilter along ``s`` only (its values along range are read as they are, then
    prefiltered along each grid row by :func:`row_coefficients`), stored range-major as complex128
    pairs of neighbouring sines with 4 zeros at each end of every column, as
    :func:`~.polar.prepare` stores its tables. Returns ``image`` (``fine`` = ``axes``)."""
    axes = image.axes
    coeffs = spline_prefilter(image.data.astype(np.complex128), axis=0)
    padded = np.zeros((axes.n_r, axes.n_s + 2 * _EDGE, 2), np.complex64)
    padded[:, _EDGE:_EDGE + axes.n_s, 0] = coeffs.T
    padded[:, _EDGE - 1:_EDGE + axes.n_s - 1, 1] = coeffs.T
    image.table = np.ascontiguousarray(padded[:, :-1]).reshape(-1).view(np.complex128)
    image.fine = axes
    return image


def row_coefficients(values: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Cubic B-spline coefficients (complex128 [rows, n]; in ``out``, a complex128 buffer of at least
    that size, when given) of the image values along rows at the fine range samples (complex64
    [rows, n]): the exact recursive prefilter, mirror ends (F10). Along a
    row of a bistatic image ``s`` drifts with range (the receiver's sine), so the polar image's own
    range coefficients, taken at the row's sines, would not be the row's (the s-pass and the range
    prefilter commute only while ``s`` is constant along the row: -26 dB against -45 dB measured
    for a drone receiver 450 m from the scene)."""
    target = np.complex128 if out is None else out.reshape(-1)[:values.size].reshape(values.shape)
    result = scipy.ndimage.spline_filter1d(values, order=3, axis=1, mode="mirror", output=target)
    return target if out is not None else result
