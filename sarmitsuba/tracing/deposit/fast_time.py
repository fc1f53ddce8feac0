"""The fast-time deposit: how a traced path reaches the fine fast-time grid, and how that grid
becomes a band-limited signal (docs/physics.md (D1)-(D5)).

Shared by the tracer (:mod:`sarmitsuba.tracing.driver.kernel` deposits paths with the Dr.Jit taps below) and
the binning stage (:mod:`sarmitsuba.signal.binning`), which receives the reduced signal. Every
deposited term carries

* a delay, as a position ``x`` in fine bins (``(L - c t0) fs_fine / c``);
* a complex value at the carrier, ``a exp(-j k_c (L - L_ref))``;
* a spectral order ``m`` in {-1, 0, +1}: the term's amplitude scales as ``(f / fc)^m`` across the
  band (docs/physics.md (PO3)): +1 for a ray tube's footprint seen near specular (the physical
  optics factor ``j k / (2 pi)``), 0 for a footprint edge and for clutter scatterers, -1 for a
  footprint corner.

The grid holds one histogram per spectral order. :func:`reduce_deposit` turns them into the
path sum's spectrum over the coarse sampling band ``|f| < fs / 2``: each histogram's FFT,
divided by the kernel's droop ``D(f / fs_fine)`` (D2) and multiplied by ``(1 + f / fc)^m``, summed
over ``m``, then the coarse bins kept (decimation to ``fs``). The result is exact up to the
kernel's aliases (-50 dB for ``linear`` at oversample 8, ``fs = 1.2 B``).

:func:`deposit_reference` is the small readable NumPy version of the grid deposit that the
Dr.Jit kernel is tested against.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import fft as sp_fft

__all__ = ["LANCZOS_A", "SPECTRAL_ORDERS", "adjoint_gain", "droop", "order_factor", "reduce_deposit", "reduce_deposit_adjoint",
           "padded_length", "deposit_reference", "taps"]

#: Half-width (lobes) of the Lanczos window of the ``sinc`` kernel: ``2 * LANCZOS_A`` taps.
LANCZOS_A = 4
#: Spectral orders ``m`` of deposited terms, in histogram order (docs/physics.md (PO3)).
SPECTRAL_ORDERS = (-1, 0, 1)


def droop(nu: np.ndarray, range_kernel: str) -> np.ndarray | float:
    """Spectral response ``D(nu)`` of a deposit kernel, ``nu = f / fs_fine`` (float64, any shape).

    The continuous Fourier transform of the kernel ``h(x)`` (x in fine bins), which the deposit
    multiplies into the spectrum of the term sum (docs/physics.md (D2)): 1 for ``nearest`` (taken
    as exact; its error is the up-to-half-bin shift), ``sinc^2(nu)`` for ``linear`` (triangle), and
    for ``sinc`` (Lanczos, ``h(x) = sinc(x) sinc(x / A)``) the integral ``int h(x) cos(2 pi nu x) dx``
    evaluated with Simpson's rule on 128 points per lobe (accurate to ~1e-9).
    """
    if range_kernel == "linear":
        return np.sinc(nu) ** 2
    if range_kernel == "sinc":
        from scipy.integrate import simpson
        x = np.linspace(-LANCZOS_A, LANCZOS_A, 128 * LANCZOS_A + 1)
        h = np.sinc(x) * np.sinc(x / LANCZOS_A)
        nu = np.asarray(nu, dtype=np.float64)
        flat = nu.reshape(-1)
        out = np.empty_like(flat)
        for i0 in range(0, flat.size, 1024):            # bounded memory: 1024 frequencies at a time
            out[i0:i0 + 1024] = simpson(h[None, :] * np.cos(2 * np.pi * flat[i0:i0 + 1024, None] * x[None, :]), x=x)
        return out.reshape(nu.shape)
    return 1.0


def order_factor(f: np.ndarray, frequency: float, order: int) -> np.ndarray:
    """``(1 + f / fc)^m``: the amplitude of a spectral-order-``m`` term at baseband frequency ``f``
    [Hz] relative to the carrier ``fc`` (docs/physics.md (PO3)), float64 like ``f``."""
    return (1.0 + np.asarray(f, np.float64) / frequency) ** order


def padded_length(n_samples: int) -> int:
    """Coarse length of the padded signal: at least twice the window and 2048 samples beyond it,
    a fast FFT length, so that filtering in the frequency domain never wraps around."""
    return sp_fft.next_fast_len(max(2 * n_samples, n_samples + 2048))


def reduce_deposit(hist: np.ndarray, fs: float, oversample: int, frequency: float, range_kernel: str,
                   n_pad: int, block: int = 256) -> np.ndarray:
    """Spectrum of the deposited term sum over the coarse sampling band, eq. (D5).

    Parameters
    ----------
    hist : complex64 [n_orders, n_pulses, n_fine]
        One fine histogram per spectral order (:data:`SPECTRAL_ORDERS`), ``n_fine`` a multiple
        of ``oversample``.
    fs : float, Hz
        Coarse sampling rate.
    oversample : int
        Fine bins per coarse sample.
    frequency : float, Hz
        Carrier ``fc`` (for the spectral orders).
    range_kernel : {"nearest", "linear", "sinc"}
    n_pad : int
        Coarse length of the output (:func:`padded_length`); the fine grid is zero-padded to
        ``n_pad * oversample`` before the FFT.
    block : int
        Pulses transformed at once (bounds memory).

    Returns
    -------
    complex64 [n_pulses, n_pad]
        In FFT order (:func:`scipy.fft.fftfreq` ``(n_pad, 1 / fs)``), the spectrum of
        ``sum_i v_i (1 + f / fc)^m_i exp(-j 2 pi f tau_i)`` with ``tau_i`` relative to ``t0``: the
        DFT of the band-limited term sum sampled at ``t0 + i / fs``.
    """
    n_orders, n_pulses, n_fine = hist.shape
    n_fft = n_pad * oversample
    keep = np.concatenate([np.arange(0, (n_pad + 1) // 2), np.arange(n_fft - n_pad // 2, n_fft)])
    f = sp_fft.fftfreq(n_pad, d=1.0 / fs)
    inverse_droop = 1.0 / droop(f / (fs * oversample), range_kernel)
    filters = [(inverse_droop * order_factor(f, frequency, m)).astype(np.complex64) for m in SPECTRAL_ORDERS]
    out = np.zeros((n_pulses, n_pad), np.complex64)
    for p0 in range(0, n_pulses, block):
        rows = slice(p0, p0 + block)
        for k, filt in enumerate(filters):
            if not np.any(hist[k, rows]):
                continue
            spectrum = sp_fft.fft(hist[k, rows], n=n_fft, axis=1, workers=-1)
            out[rows] += spectrum[:, keep] * filt[None, :]
    return out


def adjoint_gain(n_pad: int, fs: float, oversample: int, frequency: float, range_kernel: str) -> float:
    """The largest filter magnitude of :func:`reduce_deposit_adjoint` over its orders and bins:
    each of its outputs is at most this times the sum of its pulse's ``|spectrum|`` (a bound,
    for scaling a seed, docs/physics.md (D7))."""
    f = sp_fft.fftfreq(n_pad, d=1.0 / fs)
    inverse_droop = 1.0 / np.abs(droop(f / (fs * oversample), range_kernel))
    return float(max(np.max(inverse_droop * np.abs(order_factor(f, frequency, m))) for m in SPECTRAL_ORDERS))


def reduce_deposit_adjoint(spectrum: np.ndarray, n_fine: int, fs: float, oversample: int, frequency: float,
                           range_kernel: str) -> np.ndarray:
    """The adjoint of :func:`reduce_deposit` (its conjugate transpose): spectra complex
    [n_pulses, n_pad] back to fine histograms complex128 [n_orders, n_pulses, n_fine], so that
    ``<reduce_deposit(h), y> = <h, reduce_deposit_adjoint(y)>``. Each order's filter conjugated,
    the kept bins put back into the zero-padded transform, and the zero-padded FFT transposed:
    ``n_fft ifft`` truncated to ``n_fine``."""
    spectrum = np.asarray(spectrum, np.complex128)
    n_pulses, n_pad = spectrum.shape
    n_fft = n_pad * oversample
    keep = np.concatenate([np.arange(0, (n_pad + 1) // 2), np.arange(n_fft - n_pad // 2, n_fft)])
    f = sp_fft.fftfreq(n_pad, d=1.0 / fs)
    inverse_droop = 1.0 / droop(f / (fs * oversample), range_kernel)
    out = np.zeros((len(SPECTRAL_ORDERS), n_pulses, n_fine), np.complex128)
    for k, m in enumerate(SPECTRAL_ORDERS):
        filt = (inverse_droop * order_factor(f, frequency, m)).astype(np.complex64).astype(np.complex128)
        full = np.zeros((n_pulses, n_fft), np.complex128)
        full[:, keep] = spectrum * np.conj(filt)[None, :]
        out[k] = (sp_fft.ifft(full, axis=1, workers=-1) * n_fft)[:, :n_fine]
    return out


def _lanczos(x: np.ndarray) -> np.ndarray:
    return np.where(np.abs(x) < LANCZOS_A, np.sinc(x) * np.sinc(x / LANCZOS_A), 0.0)


def deposit_reference(position: np.ndarray, value: np.ndarray, order: np.ndarray, n_fine: int,
                      range_kernel: str) -> np.ndarray:
    """Readable NumPy deposit of terms on a fine grid: the oracle of the Dr.Jit kernel's deposit.

    Parameters
    ----------
    position : float64 [n]
        Delay in fine bins from the window's first sample.
    value : complex [n]
        ``a exp(-j k_c (L - L_ref))`` of each term.
    order : int [n]
        Spectral order of each term (:data:`SPECTRAL_ORDERS`).
    n_fine : int
        Fine bins.
    range_kernel : {"nearest", "linear", "sinc"}

    Returns
    -------
    complex128 [n_orders, n_fine]
        The histograms; terms whose taps would leave the grid are dropped whole (masked, never
        clamped), as in the kernel.
    """
    out = np.zeros((len(SPECTRAL_ORDERS), n_fine), complex)
    for x, v, m in zip(position, value, order):
        row = out[SPECTRAL_ORDERS.index(int(m))]
        if range_kernel == "nearest":
            k = int(np.floor(x + 0.5))
            if 0 <= k < n_fine:
                row[k] += v
        elif range_kernel == "linear":
            k = int(np.floor(x))
            if 0 <= k < n_fine - 1:
                row[k] += v * (1 - (x - k))
                row[k + 1] += v * (x - k)
        else:
            k = int(np.floor(x))
            if LANCZOS_A - 1 <= k < n_fine - LANCZOS_A:
                for m_ in range(-LANCZOS_A + 1, LANCZOS_A + 1):
                    row[k + m_] += v * _lanczos(np.array(k + m_ - x))
    return out


def taps(position, range_kernel: str):
    """Dr.Jit taps of one term: ``(first_bin, [(offset, weight), ...], inside)`` helpers.

    ``position`` is the term's delay in fine bins (a Dr.Jit float). Returns ``(k0, taps)`` with
    ``k0`` the Int32 bin the offsets refer to and ``taps`` a list of ``(offset: int, weight)``;
    plus ``(lo, hi)``: the term is deposited only when ``lo <= k0 < n_fine - hi``, so that every
    tap lies on the grid (masked, never clamped). Same kernels as :func:`deposit_reference`.
    """
    import drjit as dr
    import mitsuba as mi

    if range_kernel == "nearest":
        return mi.Int32(dr.floor(position + 0.5)), [(0, mi.Float(1.0))], (0, 0)
    k_lo = dr.floor(position)
    frac = mi.Float(position - k_lo)
    k_lo = mi.Int32(k_lo)
    if range_kernel == "linear":
        return k_lo, [(0, 1.0 - frac), (1, frac)], (0, 1)
    return k_lo, _lanczos_taps(frac), (LANCZOS_A - 1, LANCZOS_A)


def _lanczos_taps(frac):
    """Taps ``(m, w_m)``, m = -A+1 .. A, of ``L(x) = sinc(x) sinc(x / A)`` at ``x = m - frac``
    (``frac`` in [0, 1), A = :data:`LANCZOS_A`); docs/physics.md (D3).

    Uses ``sin(pi (m - f)) = -(-1)^m sin(pi f)`` and the angle-sum form of ``sin(pi (m - f) / A)``:
    one ``sincos`` per term, not one per tap.
    """
    import drjit as dr
    a = LANCZOS_A
    s1 = dr.sin(math.pi * frac)
    s2, c2 = dr.sincos((math.pi / a) * frac)
    out = []
    for m in range(-a + 1, a + 1):
        x = m - frac
        num = -(1.0 if m % 2 == 0 else -1.0) * s1 * (math.sin(math.pi * m / a) * c2 - math.cos(math.pi * m / a) * s2)
        w = dr.select(dr.abs(x) < 1e-6, 1.0, num * (a / (math.pi * math.pi)) / dr.maximum(x * x, 1e-12))
        out.append((m, w))
    return out
