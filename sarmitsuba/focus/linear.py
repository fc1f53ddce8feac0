"""The focusers as linear maps: float64 forward and adjoint pairs.

Every focuser is linear in the raw data: an image ``I = F d`` with ``F`` fixed by the geometry,
the grid and the options. Gradients of a loss on the image flow back to the raw data through the
adjoint (conjugate transpose) ``F^H``, and a perturbation of the raw data focuses to
``F (delta d)``. The pairs here are float64 throughout, so that the dot-product test

.. math::

    \\langle F x, y \\rangle = \\langle x, F^H y \\rangle, \\qquad
    \\langle a, b \\rangle = \\sum_k \\overline{a_k} b_k

holds to rounding (tests/test_focus_adjoints.py; docs/physics.md (AD1)).

:class:`BackprojectionOperator` is direct backprojection, eq. (S3), with the options of
:func:`~sarmitsuba.focus.backproject`: FFT upsampling in fast time, linear interpolation at each
pixel's two-way delay (zero outside the window), the carrier phase ``exp(+j 2 pi fc L / c)``, the
azimuth weight, and the normalisation (by the summed weight, or per range column by the largest
expected gain). The adjoint transposes each step in reverse: the normalisation (a real diagonal),
the phase (its conjugate), the interpolation (each pixel's value split back onto its two fine
samples with the same weights) and the upsampling (:func:`.range_lines.fft_upsample_adjoint`).
Its forward image equals :func:`~sarmitsuba.focus.backproject_reference` (which uses
:func:`numpy.interp`) to rounding.

:class:`OmegaKOperator` is :func:`~sarmitsuba.focus.omega_k` (steps 1-4 of its module) in float64
with the exact Kaiser-Bessel kernel (the fast path rounds the kernel's positions to a table,
-66 dB): the centred, deconvolved, zero-padded buffer, the 2-D FFT, the Stolt interpolation, the
analytic factors, the scatter to output bins, the range IFFT with its crop and amplitude, the
azimuth IFFT. Its adjoint runs them backward: FFTs become ``N`` times inverse FFTs and inverse
FFTs ``1 / N`` times FFTs, the interpolation a scatter with the same kernel weights, the
factors their conjugates, the crops zero-padding and the scatters gathers.

:class:`RangeDopplerOperator` is :func:`~sarmitsuba.focus.range_doppler` (C&W ch. 6) in float64
with the exact RCMC kernel: range FFT, range filter, azimuth FFT, SRC, upsampling range IFFT,
RCMC interpolation, azimuth matched filter, azimuth IFFT; its adjoint transposes them likewise.

Fast factorised backprojection's pair, :class:`~.ffbp_linear.FFBPOperator`, lives in
:mod:`.ffbp_linear` (it builds on :func:`pulse_taps`).
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.raw import RawData
from ..core.trajectory import echo_length
import scipy.fft
import scipy.special

from .fft_contract import focus_setup, unit_mean_window
from .omegak import StoltPlan, omega_k_plan
from .rda import RangeDopplerPlan, range_doppler_plan
from .stolt import kernel_transform
from .beam import BeamWeighting, beam_axes, beam_weighting, column_scale, pixel_weights
from .bp_contract import check_inputs, receiver_motion
from .grid import ImageGrid
from .range_lines import fft_upsample, fft_upsample_adjoint

__all__ = ["BackprojectionOperator", "backprojection_operator", "pulse_taps", "checked_shape", "OmegaKOperator", "omega_k_operator",
           "RangeDopplerOperator", "range_doppler_operator", "inner"]


def checked_shape(values: np.ndarray, shape: tuple, what: str) -> np.ndarray:
    """``values`` as complex128; ValueError naming ``what`` (``"data"``, ``"image"``) and the
    expected shape when it has another."""
    values = np.asarray(values, np.complex128)
    if values.shape != tuple(shape):
        raise ValueError(f"{what} shape {values.shape} must be {tuple(shape)} (the operator's)")
    return values


def inner(a: np.ndarray, b: np.ndarray) -> complex:
    """``<a, b> = sum conj(a) b`` over all elements (complex128)."""
    return complex(np.vdot(np.asarray(a, np.complex128).ravel(), np.asarray(b, np.complex128).ravel()))


@dataclasses.dataclass(frozen=True)
class BackprojectionOperator:
    """Direct backprojection of one acquisition onto one grid, as a linear map and its adjoint.

    Build with :func:`backprojection_operator`. ``forward`` maps range-compressed data complex
    [n_pulses, n_samples] to an image complex128 [n_az, n_rg]; ``adjoint`` maps an image back to
    complex128 [n_pulses, n_samples]. Both loop over pulses (float64, one pulse's pixels at a
    time): use small grids.
    """

    raw: RawData
    grid: ImageGrid
    oversample: int
    beam: BeamWeighting
    #: float64 [n_az, n_rg]: the normalisation each pixel's sum is multiplied by.
    scale: np.ndarray
    #: The fast-time axis's first sample [s] and the beam axes (:func:`.beam.beam_axes`).
    t0: float
    axes: np.ndarray

    @property
    def data_shape(self) -> tuple[int, int]:
        """``(n_pulses, n_samples)`` of the raw data the operator maps from."""
        return tuple(self.raw.data.shape)

    def _pulse(self, p: int, x: np.ndarray, receive) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`pulse_taps` of pulse ``p`` at pixels ``x``, the coefficient times the normalisation."""
        index, fraction, coefficient = pulse_taps(self.raw, self.t0, self.oversample, self.beam, self.axes, p, x,
                                                  receive)
        return index, fraction, coefficient * self.scale.reshape(-1)

    def forward(self, data: np.ndarray) -> np.ndarray:
        """The image of ``data`` complex [n_pulses, n_samples]: complex128 [n_az, n_rg]."""
        data = checked_shape(data, self.data_shape, "data")
        x = self.grid.positions().reshape(-1, 3)
        receive = receiver_motion(self.raw)
        image = np.zeros(x.shape[0], np.complex128)
        for p in range(data.shape[0]):
            line = np.zeros((data.shape[1] - 1) * self.oversample + 3, np.complex128)
            line[1:-1] = fft_upsample(data[p], self.oversample)
            index, fraction, coefficient = self._pulse(p, x, receive)
            image += coefficient * ((1.0 - fraction) * line[index] + fraction * line[index + 1])
        return image.reshape(self.grid.shape)

    def adjoint(self, image: np.ndarray) -> np.ndarray:
        """``F^H image`` for ``image`` complex [n_az, n_rg]: complex128 [n_pulses, n_samples]."""
        image = checked_shape(image, self.grid.shape, "image")
        x = self.grid.positions().reshape(-1, 3)
        receive = receiver_motion(self.raw)
        n_pulses, n_samples = self.data_shape
        n_line = (n_samples - 1) * self.oversample + 3
        out = np.zeros((n_pulses, n_samples), np.complex128)
        y = image.reshape(-1)
        for p in range(n_pulses):
            index, fraction, coefficient = self._pulse(p, x, receive)
            back = np.conj(coefficient) * y
            line = _scatter(index, (1.0 - fraction) * back, n_line) + _scatter(index + 1, fraction * back, n_line)
            out[p] = fft_upsample_adjoint(line[1:-1], n_samples, self.oversample)
        return out


def pulse_taps(raw: RawData, t0: float, oversample: int, beam: BeamWeighting, axes: np.ndarray, p: int,
               x: np.ndarray, receive) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pulse ``p``'s two taps at points ``x`` float64 [m, 3] in its padded fine line (sample ``k`` at
    fast time ``t0 + (k - 1) dt``, ``dt = 1 / (fs oversample)``, zeros at both ends): the fine sample
    below each delay (int64 [m]), the linear interpolation fraction (float64 [m]) and the coefficient
    ``w exp(+j 2 pi fc L / c)`` (complex128 [m]; eq. (S3)); a delay outside the padded line gets
    coefficient 0. ``axes``: :func:`.beam.beam_axes`; ``receive``: :func:`.bp_contract.receiver_motion`."""
    n_samples = raw.data.shape[1]
    dt = 1.0 / (raw.fs * oversample)
    n_up = (n_samples - 1) * oversample + 1
    length = echo_length(raw.tx_position[p], raw.rx_position[p], raw.velocity[p],
                         None if receive is None else receive[1][p], x)
    position = (length / SPEED_OF_LIGHT - t0) / dt + 1.0
    inside = (position >= 0.0) & (position <= n_up + 1)
    index = np.clip(np.floor(position), 0, n_up).astype(np.int64)
    fraction = np.where(inside, position - index, 0.0)
    weight, _ = pixel_weights(raw, beam, axes, p, x)
    cycles = np.mod(raw.fc * length / SPEED_OF_LIGHT, 1.0)
    return index, fraction, np.where(inside, weight * np.exp(2j * np.pi * cycles), 0.0)


def _scatter(index: np.ndarray, values: np.ndarray, size: int) -> np.ndarray:
    """complex128 [size]: ``values`` summed into the bins ``index`` (the transpose of a gather)."""
    return (np.bincount(index, values.real, minlength=size)[:size]
            + 1j * np.bincount(index, values.imag, minlength=size)[:size])


def backprojection_operator(raw: RawData, grid: ImageGrid, *, oversample: int = 8,
                            azimuth_beamwidth: float | None = None, squint: float = 0.0,
                            azimuth_pattern: float | None = None, window_azimuth: Any = "rect") -> BackprojectionOperator:
    """Direct backprojection of ``raw``'s geometry onto ``grid`` as a :class:`BackprojectionOperator`
    (the options and errors of :func:`~sarmitsuba.focus.backproject`). The normalisation depends
    on the geometry only, so it is computed here once, as
    :func:`~sarmitsuba.focus.backproject_reference` computes it."""
    t0, oversample, _, _ = check_inputs(raw, grid, oversample, 1, 1)
    beam = beam_weighting(raw, azimuth_beamwidth, squint, azimuth_pattern, window_azimuth)
    x = grid.positions().reshape(-1, 3)
    axes = beam_axes(raw)
    gain = np.zeros(x.shape[0])
    for p in range(raw.data.shape[0]):
        gain += pixel_weights(raw, beam, axes, p, x)[1]
    if beam.sines is None:
        total = gain[0] if gain.size else 0.0
        scale = np.full(grid.shape, 1.0 / total if total > 0 else 0.0)
    else:
        scale = np.broadcast_to(column_scale(gain.reshape(grid.shape))[0], grid.shape).copy()
    return BackprojectionOperator(raw, grid, oversample, beam, scale, t0, axes)


@dataclasses.dataclass(frozen=True)
class OmegaKOperator:
    """:func:`~sarmitsuba.focus.omega_k` of one acquisition as a float64 linear map and its adjoint.

    Build with :func:`omega_k_operator`. ``forward`` maps range-compressed data complex
    [n_pulses, n_samples] to the slant image complex128 [n_pulses, n_samples] on ``grid``;
    ``adjoint`` maps such an image back.
    """

    plan: StoltPlan
    grid: Any
    data_shape: tuple
    #: Per output sample of the Stolt grid [n_pulses, M]: the first kernel tap's bin (int64, not
    #: yet wrapped), the kernel weights float64 [taps, n_pulses, M] (0 beyond a row's band), the
    #: analytic factors complex128, and the output bin ``(k0 + m) mod n_out`` (int64).
    first: np.ndarray
    weights: np.ndarray
    factors: np.ndarray
    bins: np.ndarray
    #: Step 1's factor ``(-1)^n / Phi`` per data sample and its buffer column.
    prefactor: np.ndarray
    columns: np.ndarray

    def forward(self, data: np.ndarray) -> np.ndarray:
        """The slant image of ``data`` complex [n_pulses, n_samples]: complex128, same shape."""
        data = checked_shape(data, self.data_shape, "data")
        plan, (n_a, n_r) = self.plan, self.data_shape
        buffer = np.zeros((n_a, plan.n_pad), np.complex128)
        buffer[:, self.columns] = data * self.prefactor
        spec = scipy.fft.fft(scipy.fft.fft(buffer, axis=1), axis=0)
        rows = np.arange(n_a)[:, None]
        values = sum(w * spec[rows, (self.first + t) % plan.n_pad] for t, w in enumerate(self.weights))
        values = values * self.factors
        out = np.zeros((n_a, plan.n_out), np.complex128)
        out[rows, self.bins] = values                     # distinct bins per row (width <= n_out)
        image = scipy.fft.ifft(out, axis=1)[:, :n_r] * plan.amplitude.astype(np.float64)
        return scipy.fft.ifft(image, axis=0)

    def adjoint(self, image: np.ndarray) -> np.ndarray:
        """``F^H image`` for a slant image complex [n_pulses, n_samples]: complex128, same shape."""
        image = checked_shape(image, self.data_shape, "image")
        plan, (n_a, n_r) = self.plan, self.data_shape
        image = scipy.fft.fft(image, axis=0) / n_a                          # ifft^H = fft / N
        out = np.zeros((n_a, plan.n_out), np.complex128)
        out[:, :n_r] = image * plan.amplitude.astype(np.float64)
        out = scipy.fft.fft(out, axis=1) / plan.n_out
        rows = np.arange(n_a)[:, None]
        values = out[rows, self.bins] * np.conj(self.factors)
        spec = np.zeros(n_a * plan.n_pad, np.complex128)
        offset = rows * plan.n_pad
        for t, w in enumerate(self.weights):
            spec += _scatter((offset + (self.first + t) % plan.n_pad).reshape(-1), (w * values).reshape(-1), spec.size)
        spec = spec.reshape(n_a, plan.n_pad)
        buffer = scipy.fft.ifft(scipy.fft.ifft(spec, axis=0), axis=1) * (n_a * plan.n_pad)   # fft^H = N ifft
        return buffer[:, self.columns] * self.prefactor


def omega_k_operator(raw: RawData, *, window_range: Any = "rect", window_azimuth: Any = "rect",
                     reference_range: float | None = None, doppler_bandwidth: float | None = None,
                     geometry: Any = None, scene_centre: Any = None, squint: float | None = None, taps: int = 12,
                     oversample: float = 1.5, azimuth_pattern: float | None = None) -> OmegaKOperator:
    """:func:`~sarmitsuba.focus.omega_k` of ``raw``'s geometry as an :class:`OmegaKOperator` (its
    options and errors; ``raw`` must be range compressed, ValueError otherwise)."""
    if not raw.range_compressed:
        raise ValueError("the omega-K operator maps range-compressed data; range-compress the raw chirps first")
    geo, w_r, w_a, _, band_a = focus_setup(raw, geometry, scene_centre, squint, reference_range, window_range,
                                           window_azimuth, doppler_bandwidth, 1)
    grid, plan = omega_k_plan(raw, geo, w_r, w_a, band_a, taps, oversample, azimuth_pattern)
    n_a, n_r = raw.data.shape
    width = int(plan.n_valid.max())
    k = plan.k0f[:, None] + np.arange(width)
    kept = np.arange(width)[None, :] < plan.n_valid[:, None]
    # the Stolt change of variable (C&W eq. 8.5): output bin q = k df_out, input f_tau = sqrt(q^2 + alpha^2) - f0
    q = np.minimum(k * plan.df_out, plan.q_hi[:, None])
    f_total = np.sqrt(q * q + plan.alpha2[:, None])
    f_tau = f_total - plan.f0
    position = f_tau / plan.df + plan.n_pad / 2
    whole = np.floor(position)
    taps_n, half = plan.interp.taps, plan.interp.taps // 2
    distance = (position - whole)[None] + (half - 1) - np.arange(taps_n)[:, None, None]
    scale = float(kernel_transform(0.0, taps_n, plan.interp.beta))
    weights = scipy.special.i0(plan.interp.beta * np.sqrt(np.clip(1.0 - (2.0 * distance / taps_n) ** 2, 0.0, None)))
    weights = weights / scale * kept[None]
    gain = q / f_total * plan.row_gain.astype(np.float64)[:, None]
    if plan.w_r[0] != "rect":
        gain = gain * unit_mean_window(plan.w_r, f_tau, plan.bw)
    cycles = k * plan.range_cycles_per_bin - f_tau * plan.tau_ref + plan.row_cycles[:, None]
    factors = gain * np.exp(2j * np.pi * (cycles - np.round(cycles)))
    n = np.arange(n_r) - n_r // 2
    prefactor = np.where(n % 2 == 0, 1.0, -1.0) * plan.prefilter
    return OmegaKOperator(plan, grid, (n_a, n_r), whole.astype(np.int64) - (half - 1), weights, factors,
                          ((plan.k0[:, None] + np.arange(width)) % plan.n_out).astype(np.int64), prefactor, n % plan.n_pad)


@dataclasses.dataclass(frozen=True)
class RangeDopplerOperator:
    """:func:`~sarmitsuba.focus.range_doppler` of one acquisition as a float64 linear map and its
    adjoint (build with :func:`range_doppler_operator`; shapes as :class:`OmegaKOperator`)."""

    plan: RangeDopplerPlan
    data_shape: tuple
    #: complex128 [n_pulses, n1] or None: SRC option 2's factor.
    src: np.ndarray | None
    #: RCMC per output sample [n_pulses, n_samples]: the sample of tap 0 (int64, unclipped) and
    #: the weights float64 [taps, n_pulses, n_samples]; step 5's factors complex128.
    first: np.ndarray
    weights: np.ndarray
    factors: np.ndarray

    def _taps(self, n2: int):
        """Per tap: its samples (clipped into the upsampled row) and weights (0 outside it)."""
        for t, w in enumerate(self.weights):
            index = self.first + t
            inside = (index >= 0) & (index < n2)
            yield np.clip(index, 0, n2 - 1), np.where(inside, w, 0.0)

    def forward(self, data: np.ndarray) -> np.ndarray:
        """The slant image of ``data`` complex [n_pulses, n_samples]: complex128, same shape."""
        data = checked_shape(data, self.data_shape, "data")
        plan, (n_a, _) = self.plan, self.data_shape
        n1, n2 = plan.n1, plan.n1 * plan.upsample
        spec = scipy.fft.fft(scipy.fft.fft(data, n=n1, axis=1) * plan.range_filter, axis=0)
        if self.src is not None:
            spec = spec * self.src
        big = np.zeros((n_a, n2), np.complex128)
        half = (n1 + 1) // 2
        big[:, :half], big[:, n2 - (n1 - half):] = spec[:, :half], spec[:, half:]
        rd = scipy.fft.ifft(big, axis=1) * plan.upsample
        rows = np.arange(n_a)[:, None]
        values = sum(w * rd[rows, index] for index, w in self._taps(n2))
        return scipy.fft.ifft(values * self.factors, axis=0)

    def adjoint(self, image: np.ndarray) -> np.ndarray:
        """``F^H image`` for a slant image complex [n_pulses, n_samples]: complex128, same shape."""
        image = checked_shape(image, self.data_shape, "image")
        plan, (n_a, n_r) = self.plan, self.data_shape
        n1, n2 = plan.n1, plan.n1 * plan.upsample
        values = scipy.fft.fft(image, axis=0) / n_a * np.conj(self.factors)
        offset = np.arange(n_a)[:, None] * n2
        rd = np.zeros(n_a * n2, np.complex128)
        for index, w in self._taps(n2):
            rd += _scatter((offset + index).reshape(-1), (w * values).reshape(-1), rd.size)
        big = scipy.fft.fft(rd.reshape(n_a, n2), axis=1) * (plan.upsample / n2)
        half = (n1 + 1) // 2
        spec = np.concatenate([big[:, :half], big[:, n2 - (n1 - half):]], axis=1)
        if self.src is not None:
            spec = spec * np.conj(self.src)
        spec = scipy.fft.ifft(spec, axis=0) * n_a * np.conj(plan.range_filter)
        return (scipy.fft.ifft(spec, axis=1) * n1)[:, :n_r]


def range_doppler_operator(raw: RawData, *, window_range: Any = "rect", window_azimuth: Any = "rect",
                           src: Any = False, reference_range: float | None = None,
                           doppler_bandwidth: float | None = None, geometry: Any = None, scene_centre: Any = None,
                           squint: float | None = None, taps: int = 8, upsample: int = 2,
                           azimuth_pattern: float | None = None) -> RangeDopplerOperator:
    """:func:`~sarmitsuba.focus.range_doppler` of ``raw``'s geometry as a
    :class:`RangeDopplerOperator` (its options and errors; ``raw`` range compressed)."""
    if not raw.range_compressed:
        raise ValueError("the range-Doppler operator maps range-compressed data; range-compress the raw chirps first")
    geo, w_r, w_a, _, band_a = focus_setup(raw, geometry, scene_centre, squint, reference_range, window_range,
                                           window_azimuth, doppler_bandwidth, 1)
    plan = range_doppler_plan(raw, geo, w_r, w_a, band_a, src, taps, upsample, azimuth_pattern)
    n_a, n_r = raw.data.shape
    filt, grid = plan.filter, plan.grid
    source = None
    if plan.src_mode == "2d":
        source = np.exp(2j * np.pi * plan.src_phase(slice(0, n_a), raw.fc))
    # RCMC (C&W eq. 6.23): output gate R reads R / D(f_eta), in upsampled samples
    position = (2.0 * grid.range[None, :] / (SPEED_OF_LIGHT * filt.d_eta[:, None]) - float(raw.fast_time[0])) \
        * raw.fs * plan.upsample
    whole = np.floor(position)
    cycles = (filt.row_cycles[:, None] + filt.col_cycles[None, :]
              + 2.0 * filt.d_r[None, :] * (filt.q0[:, None] - raw.fc + filt.residual[:, None]) / SPEED_OF_LIGHT)
    factors = np.exp(2j * np.pi * (cycles - np.round(cycles))) * filt.row_gain[:, None] \
        * filt.col_gain.astype(np.float64)[None, :]
    return RangeDopplerOperator(plan, (n_a, n_r), source, whole.astype(np.int64) - (plan.interp.taps // 2 - 1),
                                plan.interp.weights(position - whole), factors)
