"""The transmitted pulse and the receiver: the signal model that raw data and focusing share
(docs/physics.md (S1), (S2); docs/design.md section 5).

The radar transmits ``rect(t / T_p) exp(j pi K_r t^2)``, centred on zero delay. A chirped echo
(sensor ``output = raw``) is the range-compressed echo of (S2) before range compression: its
spectrum is the band's spectrum times the chirp's (:func:`chirp_spectrum`) and the receiver's
anti-aliasing response (:func:`receiver_response`), :func:`received_chirp_spectrum`.
:mod:`sarmitsuba.signal.binning` forms chirped raw data with it, :mod:`sarmitsuba.analysis.synthetic` its
analytic point-target oracle, and :func:`sarmitsuba.focus.range_compression.range_compress`
inverts it exactly. One definition, so the three cannot drift apart.

Plain NumPy/SciPy, float64/complex128, no state.

References
----------
.. [1] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar Data*,
   Artech House, 2005, section 3.2 (chirp spectrum, Fresnel integrals).
"""
from __future__ import annotations

import numpy as np
import scipy.special

__all__ = ["chirp_spectrum", "receiver_response", "received_chirp_spectrum"]


def chirp_spectrum(freqs: np.ndarray, pulse_length: float, chirp_rate: float) -> np.ndarray:
    """Exact Fourier transform of the transmitted pulse ``rect(t / T_p) exp(j pi K_r t^2)``
    (the chirp whose matched filter and receiver turn an echo into (S2)).

    Parameters
    ----------
    freqs : array_like of float, Hz
    pulse_length : float, s
    chirp_rate : float, Hz/s (either sign)

    Returns
    -------
    complex128, shape of ``freqs``
        ``S(f) = int_{-T_p/2}^{T_p/2} exp(j pi K_r t^2 - j 2 pi f t) dt``, in s.

    Notes
    -----
    Completing the square, with ``v = sqrt(2 |K_r|) (t - f / K_r)``:
    ``S(f) = exp(-j pi f^2 / K_r) / sqrt(2 |K_r|) [C(v) + j sgn(K_r) S(v)]`` between
    ``v(-T_p/2)`` and ``v(T_p/2)``, with the Fresnel integrals ``C``, ``S``
    (:func:`scipy.special.fresnel`; Cumming and Wong 2005, section 3.2).
    """
    f = np.asarray(freqs, dtype=np.float64)
    k = float(chirp_rate)
    scale = np.sqrt(2.0 * abs(k))
    v1 = scale * (-pulse_length / 2.0 - f / k)
    v2 = scale * (pulse_length / 2.0 - f / k)
    s1, c1 = scipy.special.fresnel(v1)
    s2, c2 = scipy.special.fresnel(v2)
    # pi f^2 / K_r can be ~1e6 rad: reduce in cycles first
    phase = np.exp(-2j * np.pi * np.mod(0.5 * f * f / k, 1.0))
    return phase / scale * ((c2 - c1) + 1j * np.sign(k) * (s2 - s1))


def receiver_response(freqs: np.ndarray, fs: float, bandwidth: float) -> np.ndarray:
    """The receiver's anti-aliasing filter ``R(f)``: 1 over the band ``|f| <= B/2`` of (S2), a
    raised-cosine roll-off to 0 at ``|f| = fs/2`` (a brick wall when ``fs == B``), 0 beyond.

    Parameters
    ----------
    freqs : array_like of float, Hz
    fs : float, Hz
        Complex sampling rate.
    bandwidth : float, Hz

    Returns
    -------
    float64, shape of ``freqs``
    """
    f = np.abs(np.asarray(freqs, dtype=np.float64))
    edge = bandwidth / 2.0
    width = fs / 2.0 - edge
    if width <= 0:
        return (f <= edge).astype(np.float64)
    x = np.clip((f - edge) / width, 0.0, 1.0)
    return np.cos(0.5 * np.pi * x) ** 2


def received_chirp_spectrum(freqs: np.ndarray, fs: float, bandwidth: float, pulse_length: float,
                            chirp_rate: float) -> np.ndarray:
    """What a chirped echo's spectrum is multiplied by relative to the band-limited echo of (S2):
    ``fs S(f) R(f)`` (:func:`chirp_spectrum` times :func:`receiver_response`; the factor ``fs``
    turns the continuous transform ``S`` into the DFT of the chirp's samples at rate ``fs``).

    Parameters
    ----------
    freqs : array_like of float, Hz
    fs, bandwidth : float, Hz
    pulse_length : float, s
    chirp_rate : float, Hz/s

    Returns
    -------
    complex128, shape of ``freqs``, dimensionless
    """
    return fs * chirp_spectrum(freqs, pulse_length, chirp_rate) * receiver_response(freqs, fs, bandwidth)
