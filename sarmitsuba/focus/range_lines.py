"""Range lines for time-domain focusing: band-limited upsampling and carrier tables.

Shared by :func:`~sarmitsuba.focus.backproject` and :func:`~sarmitsuba.focus.ffbp`. A
range-compressed line ``d(tau)`` sampled at ``t0 + i / fs`` is upsampled by FFT zero-padding
(:func:`fft_upsample`), padded with :data:`PAD` zeros at each end, and stored as pairs
``(T0[k], T1[k]) = (s[k] E[k], (s[k + 1] - s[k]) E[k])`` (:func:`premodulated_pairs`), with
``E[k] = exp(+j 2 pi fc (t0 + (k - PAD) / fine_rate))`` (:func:`carrier_table`). The echo times
the carrier at fine position ``k + w`` (``0 <= w < 1``) is then
``(T0 + w T1) exp(j kh w) = T0 P0(w) + T1 P1(w)``, ``kh = 2 pi fc / fine_rate``, with
``(P0, P1)`` from :func:`residual_carrier_table`: linear interpolation and the carrier in two
gathers and one complex multiply, and the absolute phase formed in float64 (docs/design.md
sections 5 and 8; docs/physics.md (S3)).
"""
from __future__ import annotations

import numpy as np
import scipy.fft

__all__ = ["PAD", "FFT_GUARD", "MAX_OVERSAMPLE", "MAX_QUANTUM_PHASE", "MAX_WEIGHT_BITS", "fft_upsample",
           "fft_upsample_adjoint", "carrier_table", "residual_carrier_table", "premodulated_pairs"]

#: Zero samples added before and after every upsampled range line. Linear interpolation
#: between the first (last) sample and these zeros is the "masked" edge of the window.
PAD = 2
#: Zero samples appended in fast time before the upsampling FFT, so the periodic
#: interpolation kernel does not wrap the end of the window onto its start.
FFT_GUARD = 32
#: Largest range upsampling factor accepted by the focusers.
MAX_OVERSAMPLE = 64
#: Largest phase error [rad] of a quantised residual-carrier table (:func:`residual_carrier_table`).
MAX_QUANTUM_PHASE = 2e-3
#: Largest number of bits of a residual-carrier table (2**16 bins).
MAX_WEIGHT_BITS = 16


def fft_upsample(lines: np.ndarray, factor: int, *, workers: int | None = None) -> np.ndarray:
    """Band-limited upsampling of the last axis by ``factor`` (dtype preserved).

    Returns ``(n - 1) * factor + 1`` samples: sample ``i * factor`` equals input sample
    ``i`` (to rounding). The line is zero-padded by :data:`FFT_GUARD` samples, transformed,
    its spectrum zero-padded in the middle (an even transform's Nyquist bin split half
    and half between the positive and negative ends) and transformed back, times
    ``factor`` to keep amplitudes.
    """
    n = lines.shape[-1]
    if factor == 1:
        return np.array(lines, copy=True)
    n_fft = scipy.fft.next_fast_len(n + FFT_GUARD)
    spec = scipy.fft.fft(lines, n=n_fft, axis=-1, workers=workers)
    n_big = n_fft * factor
    big = np.zeros(lines.shape[:-1] + (n_big,), dtype=spec.dtype)
    half = (n_fft + 1) // 2  # DC and positive frequencies (no Nyquist)
    big[..., :half] = spec[..., :half]
    n_neg = n_fft - half
    if n_fft % 2 == 0:
        n_neg -= 1
        nyquist = 0.5 * spec[..., n_fft // 2]
        big[..., n_fft // 2] = nyquist
        big[..., n_big - n_fft // 2] = nyquist
    if n_neg:
        big[..., n_big - n_neg:] = spec[..., n_fft - n_neg:]
    out = scipy.fft.ifft(big, axis=-1, workers=workers, overwrite_x=True)
    out = out[..., :(n - 1) * factor + 1]
    out *= factor
    return out


def fft_upsample_adjoint(fine: np.ndarray, n: int, factor: int) -> np.ndarray:
    """The adjoint of :func:`fft_upsample` (its conjugate transpose): float64 lines ``fine``
    [..., (n - 1) * factor + 1] back to [..., n], complex128, so that
    ``<fft_upsample(x), y> = <x, fft_upsample_adjoint(y)>`` for every ``x`` [..., n].

    Each step of :func:`fft_upsample` transposed in reverse order: the truncation becomes
    zero-padding to ``n_fft * factor``; ``ifft`` (``W^H / N``) becomes ``fft / N``; the spectrum's
    zero-padding becomes its truncation (the split Nyquist bin summed half and half); the
    zero-padded ``fft`` (``W[:, :n]``) becomes ``n_fft * ifft`` truncated to ``n``.
    """
    fine = np.asarray(fine, np.complex128)
    if factor == 1:
        return np.array(fine, copy=True)
    n_fft = scipy.fft.next_fast_len(n + FFT_GUARD)
    n_big = n_fft * factor
    big = np.zeros(fine.shape[:-1] + (n_big,), np.complex128)
    big[..., :fine.shape[-1]] = fine
    big = scipy.fft.fft(big, axis=-1) * (factor / n_big)
    spec = np.zeros(fine.shape[:-1] + (n_fft,), np.complex128)
    half = (n_fft + 1) // 2
    spec[..., :half] = big[..., :half]
    n_neg = n_fft - half
    if n_fft % 2 == 0:
        n_neg -= 1
        spec[..., n_fft // 2] = 0.5 * (big[..., n_fft // 2] + big[..., n_big - n_fft // 2])
    if n_neg:
        spec[..., n_fft - n_neg:] = big[..., n_big - n_neg:]
    return (scipy.fft.ifft(spec, axis=-1) * n_fft)[..., :n]


def carrier_table(fc: float, t0: float, cycles_per_sample: float, n_tab: int) -> np.ndarray:
    """``exp(+j 2 pi fc (t0 + (k - PAD) / fine_rate))`` for table index ``k`` in ``[0, n_tab)``,
    complex64; ``cycles_per_sample = fc / fine_rate``. Formed in float64 with both terms reduced
    modulo one cycle before the cast."""
    k = np.arange(n_tab, dtype=np.float64) - PAD
    cycles = np.mod(fc * t0, 1.0) + np.mod(cycles_per_sample * k, 1.0)
    return np.exp(2j * np.pi * cycles).astype(np.complex64)


def residual_carrier_table(kh: float) -> tuple[np.ndarray, int]:
    """Residual carrier and interpolation weight as a function of the fraction ``w``.

    Returns complex128 ``[m]`` packing the complex64 pair
    ``(exp(j kh w_n), w_n exp(j kh w_n))`` at the bin centres ``w_n = (n + 0.5) / m``, and
    ``m = 2**b`` with ``b`` the smallest number of bits (8 .. :data:`MAX_WEIGHT_BITS`) that keeps
    the phase error ``kh / (2 m)`` below :data:`MAX_QUANTUM_PHASE` (b = 14 at X band,
    fs = 180 MHz, oversample 8). Truncating ``w * m`` then picks the nearest bin centre; the
    weight error is at most ``1 / (2 m)`` fine sample.
    """
    bits = int(np.clip(np.ceil(np.log2(max(kh, 1e-30) / (2 * MAX_QUANTUM_PHASE))), 8, MAX_WEIGHT_BITS))
    m = 1 << bits
    w = (np.arange(m) + 0.5) / m
    pairs = np.empty((m, 2), np.complex64)
    pairs[:, 0] = np.exp(1j * kh * w)
    pairs[:, 1] = w * np.exp(1j * kh * w)
    return pairs.reshape(-1).view(np.complex128), m


def premodulated_pairs(lines: np.ndarray, modulation: np.ndarray) -> np.ndarray:
    """The gather table of upsampled lines.

    Parameters
    ----------
    lines : complex64 [n_lines, n_up]
        Upsampled range lines.
    modulation : complex64 [n_up + 2 PAD]
        :func:`carrier_table` of the fine samples.

    Returns
    -------
    complex128 [n_lines * (n_up + 2 PAD)]
        Element ``line * n_tab + k`` packs the complex64 pair ``(s[k] E[k], (s[k + 1] - s[k]) E[k])``
        of the zero-padded line ``s`` (``PAD`` zeros at each end).
    """
    n_lines, n_up = lines.shape
    n_tab = modulation.size
    tab = np.zeros((n_lines, n_tab, 2), np.complex64)
    tab[:, PAD:PAD + n_up, 0] = lines
    np.subtract(tab[:, 1:, 0], tab[:, :-1, 0], out=tab[:, :-1, 1])
    tab *= modulation[None, :, None]
    return tab.reshape(-1).view(np.complex128)
