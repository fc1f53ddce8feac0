"""From the tracer's fine fast-time deposit to range-compressed raw data (DESIGN.md section 5).

Per pulse ``p`` the tracer deposits ``sum_i a_i exp(-j k (L_i - L_ref,p))`` on a fine grid of
step ``1 / (oversample fs)``. This stage

1. restores the reference carrier phase ``exp(-j k L_ref,p)``, formed in float64 and reduced
   mod 2 pi before the cast (eq. (S1) of ``docs/physics.md``);
2. band-limits the deposit to the transmitted band ``|f| <= B / 2`` with a unit-peak compressed
   pulse ``p_r(t) = sinc(B t)`` (rect spectrum), dividing out the deposit kernel's spectral
   droop (``sinc^2(f / fs_fine)`` for linear splatting);
3. keeps the spectral bins of the coarse grid, i.e. decimates to ``fs`` exactly.

The result is ``sum_i a_i p_r(tau - L_i / c) exp(-j 2 pi fc L_i / c)`` sampled at
``t0 + n / fs``: the RawData contract of DESIGN.md section 3.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import fft as sp_fft

from .radar import AcquisitionGeometry, RadarParameters
from .raw import RawData
from .trace import FastTimeWindow, TraceResult

__all__ = ["compressed_pulse_spectrum", "range_compress", "to_raw_data"]


def compressed_pulse_spectrum(window: FastTimeWindow, bandwidth: float, range_kernel: str) -> np.ndarray:
    """Filter applied to the coarse spectrum, float64 [n_samples] in FFT order.

    ``H(f) = rect(f / B) / D(f) / g`` with ``D`` the deposit kernel's droop (1 for
    ``nearest``, ``sinc^2(f / fs_fine)`` for ``linear``) and ``g`` the normalisation that gives
    the compressed pulse a unit peak: ``g = sum(rect) / n_samples``.
    """
    f = sp_fft.fftfreq(window.n_samples, d=1.0 / window.fs)
    band = (np.abs(f) <= 0.5 * bandwidth).astype(np.float64)
    droop = np.sinc(f / (window.fs * window.oversample)) ** 2 if range_kernel == "linear" else 1.0
    return band / droop / (band.sum() / window.n_samples)


def range_compress(deposit: np.ndarray, reference_length: np.ndarray, window: FastTimeWindow,
                   frequency: float, bandwidth: float, range_kernel: str) -> np.ndarray:
    """Range-compressed samples from the fine deposit.

    Parameters
    ----------
    deposit : complex64 [n_pulses, n_fine]
    reference_length : float64 [n_pulses], m
    window : FastTimeWindow
    frequency, bandwidth : float, Hz
    range_kernel : {"linear", "nearest"}

    Returns
    -------
    complex64 [n_pulses, n_samples]
    """
    from .constants import SPEED_OF_LIGHT
    k = 2.0 * math.pi * frequency / SPEED_OF_LIGHT
    phase = np.mod(-k * reference_length, 2.0 * math.pi)           # float64, reduced before use
    spectrum = sp_fft.fft(deposit, axis=1, workers=-1)
    n, n_fine = window.n_samples, window.n_fine
    keep = np.concatenate([np.arange(0, (n + 1) // 2), np.arange(n_fine - n // 2, n_fine)])
    coarse = spectrum[:, keep] * compressed_pulse_spectrum(window, bandwidth, range_kernel)[None, :]
    coarse *= np.exp(1j * phase)[:, None]
    out = sp_fft.ifft(coarse, axis=1, workers=-1)
    return out.astype(np.complex64)


def to_raw_data(result: TraceResult, window: FastTimeWindow, params: RadarParameters,
                geometry: AcquisitionGeometry, range_kernel: str, metadata: dict) -> RawData:
    """Package the range-compressed tracer output as :class:`RawData`."""
    data = range_compress(result.deposit, result.reference_length, window, params.frequency,
                          params.bandwidth, range_kernel)
    return RawData(
        data=data, fast_time=window.fast_time, pulse_time=geometry.pulse_time.copy(),
        tx_position=geometry.positions.copy(), rx_position=geometry.positions.copy(),
        velocity=geometry.velocity.copy(), fc=params.frequency, bandwidth=params.bandwidth,
        chirp_rate=params.chirp_rate, pulse_length=params.pulse_length, fs=params.sampling_rate,
        prf=params.prf, range_compressed=True, metadata=metadata)
