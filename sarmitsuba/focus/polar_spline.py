"""Cubic B-spline interpolation of the polar images of fast factorised backprojection
(:mod:`sarmitsuba.focus.polar`): the prefilter that turns samples into coefficients, range
upsampling with the prefilter applied in the spectrum, and the tap weights of the two 1-D passes
(with the carrier folded in for the range pass).

References
----------
.. [1] M. Unser, "Splines: a perfect fit for signal and image processing", IEEE Signal
   Process. Mag. 16(6), 22-38, 1999 (cubic B-spline interpolation and its prefilter).
"""
from __future__ import annotations

import functools

import numpy as np
import scipy.fft

from .range_lines import FFT_GUARD, MAX_WEIGHT_BITS

__all__ = ["SPLINE_POLE", "CARRIER_PHASE", "spline_prefilter", "range_coefficients", "cubic_bspline", "spline_tables",
           "carrier_bits"]


#: Pole of the cubic B-spline prefilter, ``sqrt(3) - 2`` (Unser 1999).
SPLINE_POLE = float(np.sqrt(3.0) - 2.0)


#: Largest carrier phase error [rad] of the r-pass tables (16 bits at X band with dr = c / (4 fs);
#: 8e-3 rad, 14 bits, left a -51 dB floor against a 64x-oversampled direct sum).
CARRIER_PHASE = 2e-3


def spline_prefilter(data: np.ndarray, axis: int) -> np.ndarray:
    """Cubic B-spline coefficients of ``data`` along a (short) ``axis``, in place (causal and
    anti-causal first-order recursions with pole :data:`SPLINE_POLE`, mirror-symmetric start;
    Unser 1999). Returns ``data``."""
    z = SPLINE_POLE
    x = np.moveaxis(data, axis, 0)
    n = x.shape[0]
    if n < 2:
        return data
    x *= (1.0 - z) * (1.0 - 1.0 / z)
    start = x[0].copy()                     # sum_k z^k x[k] (no BLAS: its threads cost more than the sum)
    for k in range(1, min(n, 24)):
        start += z ** k * x[k]
    x[0] = start
    for k in range(1, n):
        x[k] += z * x[k - 1]
    x[n - 1] = (z / (z * z - 1.0)) * (x[n - 1] + z * x[n - 2])
    for k in range(n - 2, -1, -1):
        x[k] = z * (x[k + 1] - x[k])
    return data


def range_coefficients(lines: np.ndarray, factor: int, workers: int = 1, dtype: type = np.complex64) -> np.ndarray:
    """Cubic B-spline coefficients of range lines complex [rows, n] on a grid ``factor`` times finer:
    ``dtype`` [rows, (n - 1) factor + 1]. FFT upsampling (zero padding to a fast length, the Nyquist
    bin split) with the prefilter ``3 / (2 + cos(2 pi f))`` of the fine grid applied in the spectrum;
    linear in ``lines``."""
    n_r = lines.shape[1]
    n_fft = scipy.fft.next_fast_len(n_r + FFT_GUARD)
    spec = scipy.fft.fft(lines, n=n_fft, axis=1, workers=workers)
    n_big = n_fft * factor
    big = np.zeros((lines.shape[0], n_big), dtype)
    half = (n_fft + 1) // 2
    big[:, :half] = spec[:, :half]
    n_neg = n_fft - half
    if n_fft % 2 == 0:
        n_neg -= 1
        big[:, n_fft // 2] = big[:, n_big - n_fft // 2] = 0.5 * spec[:, n_fft // 2]
    if n_neg:
        big[:, n_big - n_neg:] = spec[:, n_fft - n_neg:]
    f = np.fft.fftfreq(n_big)
    big *= (factor * 3.0 / (2.0 + np.cos(2.0 * np.pi * f))).astype(big.real.dtype)[None, :]
    return scipy.fft.ifft(big, axis=1, workers=workers, overwrite_x=True)[:, :(n_r - 1) * factor + 1]


def cubic_bspline(x: np.ndarray) -> np.ndarray:
    """The centred cubic B-spline ``beta3(x)`` (float64; Unser 1999, eq. (8))."""
    a = np.abs(x)
    return np.where(a < 1.0, 2.0 / 3.0 - a * a + 0.5 * a ** 3, np.where(a < 2.0, (2.0 - a) ** 3 / 6.0, 0.0))


@functools.lru_cache(maxsize=8)
def spline_tables(bits: int, phase_per_sample: float = 0.0) -> tuple[np.ndarray, np.ndarray, int]:
    """Weights of the four taps ``k - 1 .. k + 2`` at the fraction ``f`` of position ``k + f``:
    ``beta3(f - b) exp(j phase_per_sample (f - b))``, ``b = -1 .. 2``, at the bin centres
    ``(n + 0.5) / 2**bits``. Returns two complex128 [2**bits] tables packing the complex64 pairs
    (taps -1, 0) and (1, 2), and ``2**bits``. With ``phase_per_sample = kappa dr`` the weights carry
    the carrier from each tap to the point (:func:`r_pass`). Cached: the tables are read-only."""
    m = 1 << bits
    f = (np.arange(m) + 0.5) / m
    b = np.arange(-1, 3)
    x = f[:, None] - b[None, :]
    w = (cubic_bspline(x) * np.exp(1j * phase_per_sample * x)).astype(np.complex64)
    lo = np.ascontiguousarray(w[:, :2]).reshape(-1).view(np.complex128)
    hi = np.ascontiguousarray(w[:, 2:]).reshape(-1).view(np.complex128)
    lo.flags.writeable = hi.flags.writeable = False
    return lo, hi, m


def carrier_bits(phase_per_sample: float) -> int:
    """Bits (10 .. 16) of a :func:`spline_tables` table whose quantised carrier errs by at most
    :data:`CARRIER_PHASE`: the fraction is quantised to its bin centre, ``phase_per_sample / (2 2**bits)``."""
    need = np.log2(max(phase_per_sample, 1e-30) / (2.0 * CARRIER_PHASE))
    return int(np.clip(np.ceil(need), 10, MAX_WEIGHT_BITS))
