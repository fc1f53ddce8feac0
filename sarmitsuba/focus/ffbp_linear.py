"""Fast factorised backprojection as a float64 linear map and its adjoint.

:func:`~sarmitsuba.focus.ffbp` is linear in the raw data: per sub-aperture ``j`` a chain of fixed
linear steps, summed over the sub-apertures and normalised per range column,

.. math::

    I = N \\sum_j L_j \\, (P_s \\, T \\, A_j \\, U \\, d_j) \\, R, \\qquad
    F^H I' = \\sum_j U^H A_j^H \\, T \\, (P_s^T (L_j^H N I') R^H)

(docs/physics.md (AD1), (F1)-(F9)), with ``U`` the FFT upsampling of each pulse's range line
(:func:`.range_lines.fft_upsample`), ``A_j`` the first stage (the pulses of ``j`` backprojected by
linear interpolation onto the polar samples ``(s_m, r_k)`` of its grid, demodulated by
``exp(-j kappa r_k)``, (F4)), ``T`` the range taper, ``P_s`` the cubic B-spline prefilter along
the sines (:func:`.polar.spline_prefilter`, real), ``R`` the range upsampling with the prefilter in
the spectrum (:func:`.polar.range_coefficients`; real, its spectral weights being even), ``L_j``
the cubic B-spline interpolation of the coefficients at each pixel (the s-pass at the four fine
ranges around the pixel's range, then the r-pass, the carrier ``exp(+j kappa |x - c_j|)``
restored) and ``N`` the normalisation
(:func:`.ffbp_plan.normalisation`). The polar grids, the rows each reaches and the normalisation
are :func:`~sarmitsuba.focus.ffbp`'s own (:mod:`.ffbp_plan`).

Where the operator differs from the fast focuser (both are the same map up to these): it upsamples
each whole range line (``ffbp`` a tapered crop), uses the exact delays, beam weights and spline
weights (``ffbp`` interpolates them from coarse geometry and tables) and evaluates everything in
float64. ``A_j`` and ``L_j`` are sparse matrices (:mod:`scipy.sparse`), ``P_s`` and ``R`` dense ones
formed by applying the prefilter and the upsampler to unit vectors; the adjoint applies their
conjugate transposes in reverse order. Small grids only: the matrices hold every tap.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import scipy.sparse

from ..core.constants import SPEED_OF_LIGHT
from ..core.raw import RawData
from .beam import BeamWeighting, beam_axes, beam_weighting
from .bp_contract import check_inputs, receiver_motion
from .ffbp_plan import (BLOCK_COLUMNS, SUBAPERTURE, check_knobs, grid_edge_points, normalisation, plan_polar,
                        row_geometry, rows_reached, subaperture_spans)
from .grid import ImageGrid
from .linear import checked_shape, pulse_taps
from .polar import GeometryNotSupported, PolarAxes, PolarImage, cubic_bspline, range_coefficients, range_taper, \
    spline_prefilter
from .range_lines import fft_upsample, fft_upsample_adjoint
from .stripmap import check_monostatic

__all__ = ["FFBPOperator", "SubapertureMaps", "ffbp_operator"]


@dataclasses.dataclass(frozen=True)
class SubapertureMaps:
    """The fixed linear steps of one sub-aperture (see the module docstring)."""

    pulses: slice
    #: ``A_j`` with ``T``: [n_s n_r, P n_line] sparse, the pulses' padded fine lines to the tapered,
    #: demodulated polar samples (s-major).
    first: scipy.sparse.csr_matrix
    #: ``P_s``: float64 [n_s, n_s].
    along: np.ndarray
    #: ``R``: complex128 [n_r, n_up], range samples to range coefficients (``C = P_s S R``).
    across: np.ndarray
    #: ``L_j``: [n_az n_rg, n_s n_up] sparse, the coefficients (s-major) to the pixels.
    last: scipy.sparse.csr_matrix


@dataclasses.dataclass(frozen=True)
class FFBPOperator:
    """Fast factorised backprojection of one acquisition onto one grid, as a linear map and its
    adjoint. Build with :func:`ffbp_operator`. ``forward`` maps range-compressed data complex
    [n_pulses, n_samples] to an image complex128 [n_az, n_rg]; ``adjoint`` an image back to
    complex128 [n_pulses, n_samples]."""

    raw: RawData
    grid: ImageGrid
    oversample: int
    #: float64 [n_rg]: the normalisation ``N`` of each range column.
    scale: np.ndarray
    maps: tuple[SubapertureMaps, ...]

    @property
    def data_shape(self) -> tuple[int, int]:
        """``(n_pulses, n_samples)`` of the raw data the operator maps from."""
        return tuple(self.raw.data.shape)

    def _n_line(self) -> int:
        return (self.data_shape[1] - 1) * self.oversample + 3

    def forward(self, data: np.ndarray) -> np.ndarray:
        """The image of ``data`` complex [n_pulses, n_samples]: complex128 [n_az, n_rg]. ValueError
        naming the shape when ``data`` has another."""
        data = checked_shape(data, self.data_shape, "data")
        lines = np.zeros((data.shape[0], self._n_line()), np.complex128)
        lines[:, 1:-1] = fft_upsample(data, self.oversample)
        image = np.zeros(self.grid.shape[0] * self.grid.shape[1], np.complex128)
        for m in self.maps:
            polar = (m.first @ lines[m.pulses].reshape(-1)).reshape(m.along.shape[0], -1)
            image += m.last @ (m.along @ polar @ m.across).reshape(-1)
        return image.reshape(self.grid.shape) * self.scale[None, :]

    def adjoint(self, image: np.ndarray) -> np.ndarray:
        """``F^H image`` for ``image`` complex [n_az, n_rg]: complex128 [n_pulses, n_samples].
        ValueError naming the shape when ``image`` has another."""
        image = checked_shape(image, self.grid.shape, "image")
        y = (image * self.scale[None, :]).reshape(-1)
        lines = np.zeros((self.data_shape[0], self._n_line()), np.complex128)
        for m in self.maps:
            coeffs = (m.last.conj().T @ y).reshape(m.along.shape[0], -1)
            polar = m.along.T @ coeffs @ m.across.conj().T
            lines[m.pulses] += (m.first.conj().T @ polar.reshape(-1)).reshape(-1, lines.shape[1])
        return fft_upsample_adjoint(lines[:, 1:-1], self.data_shape[1], self.oversample)


def ffbp_operator(raw: RawData, grid: ImageGrid, *, subaperture: int | None = None, angle_oversample: float = 2.0,
                  range_oversample: int = 2, oversample: int = 8, azimuth_beamwidth: float | None = None,
                  squint: float = 0.0, azimuth_pattern: float | None = None,
                  window_azimuth: Any = "rect") -> FFBPOperator:
    """:func:`~sarmitsuba.focus.ffbp` of ``raw``'s geometry onto ``grid`` as an :class:`FFBPOperator`
    (its options, polar grids and normalisation; the module docstring says where the two differ).

    Raises
    ------
    ValueError
        As ``ffbp``: bad data, grid or knobs.
    GeometryNotSupported
        As ``ffbp``: a grid straddling the track; and bistatic stop-and-hop data (``ffbp`` focuses
        them on bistatic polar images, (F10), which this float64 operator does not form).
    """
    check_monostatic(raw, "ffbp_operator (its float64 polar maps are the monostatic ones; ffbp itself "
                          "focuses bistatic data)")
    t0, oversample, _, _ = check_inputs(raw, grid, oversample, 1, 1)
    knobs = check_knobs(raw, min(SUBAPERTURE, raw.n_pulses) if subaperture is None else subaperture,
                        angle_oversample, range_oversample)
    beam = beam_weighting(raw, azimuth_beamwidth, squint, azimuth_pattern, window_azimuth)
    edges = grid_edge_points(grid)
    maps = []
    for span in subaperture_spans(raw.n_pulses, knobs["subaperture"]):
        planned = plan_polar(raw, grid, beam, slice(*span), knobs["angle_oversample"], edges)
        if planned is not None:
            maps.append(_subaperture(raw, grid, beam, slice(*span), planned, t0, oversample,
                                     knobs["range_oversample"]))
    scale, _ = normalisation(raw, grid, beam)
    return FFBPOperator(raw, grid, oversample, scale, tuple(m for m in maps if m is not None))


def _subaperture(raw: RawData, grid: ImageGrid, beam: BeamWeighting, pulses: slice, planned, t0: float,
                 oversample: int, factor: int) -> SubapertureMaps | None:
    """The maps of one planned sub-aperture, or None when it reaches no pixel."""
    frame, axes, s_span, window = planned
    kappa = 4.0 * np.pi * raw.fc / SPEED_OF_LIGHT
    units, valid = frame.units(axes.s[:, None], axes.r[None, :])
    points = (frame.centre + axes.r[None, :, None] * units).reshape(-1, 3)
    r = np.broadcast_to(axes.r[None, :], valid.shape).reshape(-1)
    demodulate = (valid * range_taper(axes.n_r)[None, :]).reshape(-1) * np.exp(-1j * np.mod(kappa * r, 2.0 * np.pi))
    receive, beam_axis = receiver_motion(raw), beam_axes(raw)
    n_line = (raw.data.shape[1] - 1) * oversample + 3
    rows, cols, values = [], [], []
    near, far = np.inf, -np.inf                        # the one-way residuals |x - A_p| - r (for r_span)
    for k, p in enumerate(range(pulses.start, pulses.stop)):
        index, fraction, coefficient = pulse_taps(raw, t0, oversample, beam, beam_axis, p, points, receive)
        coefficient = coefficient * demodulate
        for tap, weight in ((index, 1.0 - fraction), (index + 1, fraction)):
            rows.append(np.arange(points.shape[0]))
            cols.append(k * n_line + tap)
            values.append(coefficient * weight)
        residual = (np.linalg.norm(points - raw.tx_position[p], axis=1) - r)[valid.reshape(-1)]
        near, far = min(near, residual.min(initial=np.inf)), max(far, residual.max(initial=-np.inf))
    first = scipy.sparse.csr_matrix((np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))),
                                    shape=(points.shape[0], (pulses.stop - pulses.start) * n_line))
    along = spline_prefilter(np.eye(axes.n_s), axis=0)
    across = range_coefficients(np.eye(axes.n_r, dtype=np.complex128), factor, dtype=np.complex128)
    fine = PolarAxes(axes.s0, axes.ds, axes.n_s, axes.r0, axes.dr / factor, across.shape[1])
    guard = SPEED_OF_LIGHT / (2.0 * raw.fs * oversample)
    r_span = (window[0] - far - guard, window[1] - near + guard)
    last = _last_map(grid, PolarImage(frame, axes, None, s_span, r_span), fine, kappa)
    if last is None:
        return None
    return SubapertureMaps(pulses, first, along, across, last)


def _last_map(grid: ImageGrid, image: PolarImage, fine: PolarAxes, kappa: float) -> scipy.sparse.csr_matrix | None:
    """``L_j``: each pixel of the rows the image reaches (per range block, as ``ffbp``) from the
    16 coefficients around it, ``beta3(rho - k) beta3(sigma_k - m) exp(+j kappa |x - c|)`` with
    ``rho`` the pixel's range and ``sigma_k`` the sine of its row's point at range ``r_k`` (both in
    samples of the fine axes); pixels whose range lies outside ``image.r_span`` read 0. None when
    no pixel is reached."""
    frame = image.frame
    n_rg = grid.shape[1]
    blocks = [slice(b, min(b + BLOCK_COLUMNS, n_rg)) for b in range(0, n_rg, BLOCK_COLUMNS)]
    p_all, q_all = row_geometry(grid, frame.centre)
    v = frame.direction
    along_all = (grid.origin - frame.centre) @ v + grid.azimuth * (grid.azimuth_direction @ v)
    taps = np.arange(-1, 3)
    entries = []
    for block, rows in zip(blocks, rows_reached(grid, image, blocks)):
        if rows is None:
            continue
        i = np.arange(rows.start, rows.stop)[:, None]
        c = np.arange(block.start, block.stop)[None, :]
        p, h2 = p_all[i], q_all[i] - p_all[i] ** 2
        ends = grid.range[[block.start, block.stop - 1]][None, :] + p
        side = 1.0 if ends[0, 0] > 0 else -1.0
        if np.any(ends * side <= 0):
            raise GeometryNotSupported("ffbp: an image row crosses the closest point to a sub-aperture centre inside "
                                       "the grid (the grid straddles the track); use backproject")
        dist = np.sqrt((grid.range[c] + p) ** 2 + h2)                                   # [rows, cols]
        rho = (dist - fine.r0) / fine.dr
        k = np.floor(rho)[..., None] + taps                                              # [rows, cols, 4]
        r_k = fine.r0 + fine.dr * k
        w_r = cubic_bspline(rho[..., None] - k) * ((k >= 0) & (k < fine.n_r))
        w_r *= ((dist >= image.r_span[0]) & (dist <= image.r_span[1]))[..., None]
        on_row = side * np.sqrt(np.maximum(r_k * r_k - h2[..., None], 0.0)) - p[..., None]
        sigma = ((along_all[i][..., None] + on_row * (grid.range_direction @ v)) / r_k - fine.s0) / fine.ds
        m = np.floor(sigma)[..., None] + taps                                            # [rows, cols, 4, 4]
        w_s = cubic_bspline(sigma[..., None] - m) * ((m >= 0) & (m < fine.n_s))
        weight = w_r[..., None] * w_s * np.exp(1j * np.mod(kappa * dist, 2.0 * np.pi))[..., None, None]
        pixel = np.broadcast_to((i * n_rg + c)[..., None, None], weight.shape)
        column = np.clip(m, 0, fine.n_s - 1) * fine.n_r + np.clip(k, 0, fine.n_r - 1)[..., None]
        entries.append((weight.reshape(-1), pixel.reshape(-1), column.astype(np.int64).reshape(-1)))
    if not entries:
        return None
    weight, pixel, column = (np.concatenate(e) for e in zip(*entries))
    keep = weight != 0
    return scipy.sparse.csr_matrix((weight[keep], (pixel[keep], column[keep])),
                                   shape=(grid.shape[0] * n_rg, fine.n_s * fine.n_r))
