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

__all__ = ["ENERGY_STRIDE", "band_energy", "spectra_by_order"]

#: The orders' energies are measured on every ``ENERGY_STRIDE``-th pulse of a batch (scaled to
#: the batch's pulses): the reduction (D5) of each order's histogram costs a zero-padded FFT per
#: pulse, and on every pulse it made urban's render about 11 % slower; a share is an average
#: over the aperture, which a regular subsample of it estimates.
ENERGY_STRIDE = 8


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


def spectra_by_order(hist: np.ndarray, n_channels: int, kept: bool, reduce, fs: float,
                     bandwidth: float) -> tuple[np.ndarray, np.ndarray]:
    """A batch's spectra from its histograms, one per channel and bounce order, and each order's
    energy (D6).

    Parameters
    ----------
    hist : complex64 [n_spectral_orders, n_channels x n_bounce_orders, n_pulses, n_fine]
        Channel-major (:meth:`sarmitsuba.tracing.deposit.accumulate.Accumulator.collect`).
    n_channels : int
    kept : bool
        Keep every bounce order's spectra (``split_bounces``); else the orders are summed before
        the reduction (it is linear) and their energies measured on every
        :data:`ENERGY_STRIDE`-th pulse.
    reduce : callable
        The reduction (D5) of one ``[n_spectral_orders, n_pulses, n_fine]`` histogram to its
        spectra ``[n_pulses, n_pad]``.
    fs, bandwidth : float, Hz
        As :func:`band_energy`.

    Returns
    -------
    spectra : complex [n_channels (x n_bounce_orders if kept), n_pulses, n_pad]
    energy : float64 [n_bounce_orders], m^2
        Each bounce order's energy over the batch's pulses, the mean over channels.
    """
    n_pulses = hist.shape[2]
    parts = hist.reshape(hist.shape[0], n_channels, -1, n_pulses, hist.shape[-1])
    if kept:
        spectra = np.stack([[reduce(parts[:, c, d]) for d in range(parts.shape[2])] for c in range(n_channels)])
        return spectra.reshape(-1, n_pulses, spectra.shape[-1]), band_energy(spectra, fs, bandwidth).mean(axis=0)
    spectra = np.stack([reduce(parts[:, c].sum(axis=1)) for c in range(n_channels)])
    sample = slice(min(ENERGY_STRIDE // 2, n_pulses - 1), None, ENERGY_STRIDE)    # midpoints of the strides
    sampled = np.stack([[reduce(np.ascontiguousarray(parts[:, c, d, sample])) for d in range(parts.shape[2])]
                        for c in range(n_channels)])
    return spectra, band_energy(sampled, fs, bandwidth).mean(axis=0) * (n_pulses / len(range(n_pulses)[sample]))
