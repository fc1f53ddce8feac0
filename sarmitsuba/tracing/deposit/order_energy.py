"""The energy each bounce order holds, from its band-limited spectrum (docs/physics.md (D6)).

The tracer reads its histogram back after each bounce order's deposits
(:meth:`sarmitsuba.tracing.deposit.accumulate.Accumulator.order_done`), so every order has its own
histogram (``EffectSet.deposit_groups``), and reduces each to its spectrum (D5); :func:`band_energy` measures a spectrum's energy as
range-compressed samples, from the spectrum alone (Parseval), so no raw data of any single
order is ever formed unless ``split_bounces`` asks for it.
"""
from __future__ import annotations

import numpy as np
from scipy import fft as sp_fft

__all__ = ["band_energy"]


def band_energy(spectra: np.ndarray, fs: float, bandwidth: float) -> np.ndarray:
    """Energy of the range-compressed samples of each spectrum, eq. (D6).

    Parameters
    ----------
    spectra : complex [..., n_pulses, n_pad]
        Spectra of the term sum over the coarse sampling band (FFT order,
        ``scipy.fft.fftfreq(n_pad, 1 / fs)``), as :func:`sarmitsuba.tracing.deposit.fast_time.reduce_deposit`
        returns them.
    fs, bandwidth : float, Hz
        Coarse sampling rate and transmitted bandwidth ``B`` (``0 < B <= fs``).

    Returns
    -------
    float64 [...]
        ``sum_p (n_pad / n_B^2) sum_{|f| <= B/2} |S_p(f)|^2`` [m^2]: by Parseval's theorem the
        sum over pulses of ``|s_p[n]|^2`` over the padded grid of the samples that range
        compression with the unit-peak filter ``rect(f / B) n_pad / n_B`` gives (docs/physics.md
        (S2), (D6)).

    Raises
    ------
    ValueError
        No bin of the padded grid lies in the band (``bandwidth`` not positive).
    """
    spectra = np.asarray(spectra)
    n_pad = spectra.shape[-1]
    band = np.abs(sp_fft.fftfreq(n_pad, d=1.0 / fs)) <= 0.5 * bandwidth
    n_band = int(band.sum())
    if n_band == 0:
        raise ValueError(f"bandwidth = {bandwidth} Hz: no bin of the {n_pad}-point grid at fs = {fs} Hz lies "
                         "in the band; give a positive bandwidth")
    power = np.abs(spectra[..., band].astype(np.complex128)) ** 2
    return power.sum(axis=(-2, -1)) * (n_pad / n_band ** 2)
