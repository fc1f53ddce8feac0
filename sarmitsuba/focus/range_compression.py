"""Range compression of raw chirps, and range weighting of compressed data (docs/design.md section 8).

:func:`range_compress` turns raw LFM echoes ``a rect((tau - L/c)/T_p) exp(j pi K_r (tau -
L/c)^2) exp(-j 2 pi fc L/c)`` into the range-compressed echoes of the RawData contract,
``a p_r(tau - L/c) exp(-j 2 pi fc L/c)``, where ``p_r`` is the unit-peak compressed pulse of
the chosen range window over the band (``sinc(B t)`` for rect;
:func:`sarmitsuba.focus.windows.compressed_pulse`). :func:`apply_range_window` weights
data that are already compressed (rect spectrum) with a window.

Both work in the frequency domain along fast time, on zero-padded FFTs, and keep the
fast-time axis unchanged (same ``t0``, ``fs`` and ``n_samples``): the reference chirp is
centred on zero delay (the transmitted pulse is ``rect(t / T_p) exp(j pi K_r t^2)``,
docs/design.md section 5), so a target at delay ``L/c`` peaks at ``fast_time = L/c`` with
value ``a`` (at its continuous peak; the samples are those of ``a p_r``).

Filters (``method``), with ``S(f)`` the exact spectrum of the continuous chirp
(:func:`sarmitsuba.signal.signal_model.chirp_spectrum`, Fresnel integrals) as the reference:

* ``"inverse"`` (default): ``H(f) = w(f/B) / S(f)`` on the band ``|f| <= B/2``, zero
  outside. A chirp's spectrum has Fresnel ripple, so this is the matched filter ``S*``
  followed by the equaliser ``1/|S|^2``: for a band-limited (properly sampled) echo the
  output spectrum of a target is exactly the windowed rect and its response exactly
  ``p_r``, so raw and pre-compressed data of the same scene agree (docs/design.md
  section 5). The equaliser colours white noise by ``1/|S|^2`` (a small SNR loss, under 0.2 dB for a
  time-bandwidth product above about 100).
* ``"matched"``: ``H(f) = w(f/B) S*(f)`` on the band (the windowed matched filter, best
  SNR); the response keeps the chirp's Fresnel ripple and differs from ``p_r`` by
  roughly -15 to -25 dB NRMSE at a time-bandwidth product of 300.

*Aliasing.* A chirp with a rect envelope is not band-limited: sampled directly (as the
formula above), its spectrum folds from beyond ``+-fs/2`` into the band, at a relative level
of about ``1 / (2 pi sqrt(B T_p) (fs/B - 1))`` (-27 dB for ``B T_p = 300``,
``fs = 1.2 B``). No filter can undo that, so compressed directly-sampled chirps match
``p_r`` only to that level; echoes that went through an anti-aliasing receiver filter
(``simulate_point_targets(..., anti_alias=True)``) match it to better than -90 dB.

Both are normalised so that a target of amplitude ``a`` compresses to a peak ``a``.

*Fast-time window and FFT length.* The raw data are a window of fast time; a chirp cut by
the window edge compresses to a weaker, broader response (as in a real receiver). The FFT
length ``N`` is at least ``n_samples + n_chirp`` so that the chirp never wraps. The ideal
compressed pulse has ``1/t`` sidelobe tails of unlimited length; a periodic (FFT) filter
makes it the periodic sinc ``sin(pi B t) / (M sin(pi t fs / N))`` instead, which departs
from ``sinc(B t)`` by about ``(pi t fs / N)^2 / 6`` relative. With ``method="inverse"``
the FFT is padded until that error, over an ``n``-sample window, is below
``accuracy_db`` (NRMSE, default -60 dB): ``NRMSE^2 ~ pi^2 n^3 fs / (108 B N^4)``, i.e.
``N ~ 2.3 n`` for ``n = 4096``, ``fs = 1.2 B``. The bound is conservative (measured
errors are 5-20 dB lower).

References
----------
.. [1] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar
   Data*, Artech House, 2005, chapter 3 (matched filtering in the frequency domain,
   weighting over the band) and section 3.2 (chirp spectrum, Fresnel integrals).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import scipy.fft

from ..core.raw import RawData
from ..signal.signal_model import chirp_spectrum
from .windows import check_window, spectral_window, window_mean

__all__ = ["range_compress", "apply_range_window"]

#: Pulses processed per FFT block (bounds the working set at N x 256 x 16 bytes).
_BLOCK = 256
_METHODS = ("inverse", "matched")


def _windowed_band_fraction(n_fft: int, fs: float, bandwidth: float, name: str, params: dict[str, Any]) -> np.ndarray:
    """Window times the fraction of each DFT cell inside ``|f| <= B/2`` (float64 [n_fft])."""
    f = scipy.fft.fftfreq(n_fft, 1.0 / fs)
    df = fs / n_fft
    frac = np.clip((bandwidth / 2.0 - np.abs(f)) / df + 0.5, 0.0, 1.0)
    w = spectral_window(name, np.clip(f, -bandwidth / 2.0, bandwidth / 2.0), bandwidth, **params)
    return w * frac


def _check_raw(raw: Any, compressed: bool) -> None:
    if not isinstance(raw, RawData):
        raise ValueError(f"raw must be a sarmitsuba.core.raw.RawData, got {type(raw).__name__}")
    if raw.range_compressed != compressed:
        if compressed:
            raise ValueError("apply_range_window needs range-compressed data (raw.range_compressed is False); "
                             "use range_compress(raw, window) on raw chirps")
        raise ValueError("range_compress needs raw chirps, but raw.range_compressed is True; use "
                         "apply_range_window(raw, window) to weight compressed data")
    step = np.diff(raw.fast_time)
    if step.size and not np.allclose(step, 1.0 / raw.fs, rtol=1e-6, atol=0.0):
        raise ValueError(f"raw.fast_time must be t0 + i / fs with fs = raw.fs = {raw.fs} Hz")
    if raw.bandwidth > raw.fs * (1 + 1e-9):
        raise ValueError(f"raw.bandwidth = {raw.bandwidth} Hz exceeds the complex sampling rate raw.fs = "
                         f"{raw.fs} Hz: the band is aliased")


def _filter_blocks(data: np.ndarray, h: np.ndarray, n_fft: int, shift: int, workers: int | None) -> np.ndarray:
    """``IFFT(FFT(data, n_fft) * h)`` per row, returning samples ``shift .. shift + n - 1``, complex64."""
    n_pulses, n = data.shape
    out = np.empty((n_pulses, n), np.complex64)
    for p0 in range(0, n_pulses, _BLOCK):
        block = scipy.fft.fft(data[p0:p0 + _BLOCK].astype(np.complex128), n_fft, axis=1, workers=workers)
        block *= h
        y = scipy.fft.ifft(block, axis=1, workers=workers)
        out[p0:p0 + _BLOCK] = y[:, shift:shift + n]
    return out


def _window_metadata(raw: RawData, name: str, params: dict[str, Any], **extra: Any) -> dict[str, Any]:
    meta = dict(raw.metadata)
    meta["range_window"] = {"name": name, **params}
    meta["range_compression"] = extra
    return meta


def range_compress(raw: RawData, window: str = "rect", *, method: str = "inverse", accuracy_db: float = -60.0,
                   workers: int | None = None, **window_params: Any) -> RawData:
    """Range-compress raw chirps with a windowed frequency-domain filter.

    Parameters
    ----------
    raw : RawData
        Raw LFM echoes (``raw.range_compressed`` False), chirp ``raw.chirp_rate`` over
        ``raw.pulse_length``, uniform fast time ``t0 + i / fs``.
    window : str, default "rect"
        Range window over the band ``|f| <= raw.bandwidth / 2``
        (:func:`sarmitsuba.focus.windows.spectral_window`).
    method : {"inverse", "matched"}, default "inverse"
        Filter; see the module docstring. ``"inverse"`` gives exactly ``a p_r``.
    accuracy_db : float, default -60
        ``method="inverse"``: bound on the NRMSE between the periodic (FFT) and the
        aperiodic compressed pulse, which sets the FFT padding (in [-120, -20] dB).
    workers : int, optional
        Threads for :func:`scipy.fft.fft`.
    **window_params
        Window parameters (``nbar``, ``sll``, ``beta``, ``alpha``).

    Returns
    -------
    RawData
        ``range_compressed=True``, same fast time, geometry and scalars; complex64 data
        ``a p_r(tau - L/c) exp(-j 2 pi fc L/c)`` per target. ``metadata`` gains
        ``"range_window"`` and ``"range_compression"`` (method, FFT length).

    Raises
    ------
    ValueError
        Data already compressed, non-uniform fast time, bad window or method, a band
        wider than the chirp's ``|K_r| T_p`` or than ``fs``, or (``"inverse"``) a chirp
        spectrum too weak somewhere in the band to invert (time-bandwidth product too
        small; use ``method="matched"``).

    Examples
    --------
    >>> compressed = range_compress(raw, "taylor", nbar=4, sll=-35)  # doctest: +SKIP
    """
    _check_raw(raw, compressed=False)
    name, params = check_window(window, **window_params)
    if method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS}, got {method!r}")
    acc = float(accuracy_db)
    if not (np.isfinite(acc) and -120.0 <= acc <= -20.0):
        raise ValueError(f"accuracy_db must be in [-120, -20] dB, got {accuracy_db!r}")
    swept = abs(raw.chirp_rate) * raw.pulse_length
    if raw.bandwidth > swept * (1 + 1e-6):
        raise ValueError(f"raw.bandwidth = {raw.bandwidth} Hz exceeds the swept band |chirp_rate| * pulse_length = "
                         f"{swept} Hz: nothing to compress outside the chirp")
    n = raw.n_samples
    h = int(math.ceil(raw.pulse_length * raw.fs / 2.0))  # chirp half-length in samples
    n_min = n + 2 * h + 1
    if method == "inverse":
        # periodic vs aperiodic compressed pulse: NRMSE^2 ~ pi^2 n^3 fs / (108 B N^4)
        fold = (math.pi ** 2 * n ** 3 * raw.fs / (108.0 * raw.bandwidth * 10.0 ** (acc / 10.0))) ** 0.25
        n_min = max(n_min, int(math.ceil(fold)))
    n_fft = scipy.fft.next_fast_len(n_min)
    # reference: the exact spectrum of the continuous chirp centred on zero delay
    spec = chirp_spectrum(scipy.fft.fftfreq(n_fft, 1.0 / raw.fs), raw.pulse_length, raw.chirp_rate) * raw.fs
    weights = _windowed_band_fraction(n_fft, raw.fs, raw.bandwidth, name, params)
    band = weights > 0
    if method == "inverse":
        mag = np.abs(spec[band])
        if mag.min() < 1e-3 * mag.max():
            raise ValueError(f"the chirp spectrum drops to {mag.min() / mag.max():.1e} of its peak inside the band "
                             f"(time-bandwidth product {raw.bandwidth * raw.pulse_length:.1f}); use method='matched'")
        filt = np.zeros(n_fft, np.complex128)
        filt[band] = weights[band] / spec[band]
        gain = weights.sum() / n_fft  # zero-delay response of the weighted band
    else:
        filt = weights * np.conj(spec)
        gain = (weights * np.abs(spec) ** 2).sum() / n_fft
    filt /= gain
    data = _filter_blocks(raw.data, filt, n_fft, 0, workers)
    meta = _window_metadata(raw, name, params, method=method, fft_length=n_fft, accuracy_db=acc,
                            reference_half_length=h)
    return dataclasses.replace(raw, data=data, range_compressed=True, metadata=meta)


def apply_range_window(raw: RawData, window: str, *, workers: int | None = None, **window_params: Any) -> RawData:
    """Weight range-compressed data with a window over the band, keeping a unit peak.

    Parameters
    ----------
    raw : RawData
        Range-compressed data with a rect spectrum over ``|f| <= raw.bandwidth / 2``
        (e.g. ``sinc(B t)`` pulses).
    window : str
        Window name (:func:`sarmitsuba.focus.windows.check_window`).
    workers : int, optional
        Threads for :func:`scipy.fft.fft`.
    **window_params
        Window parameters.

    Returns
    -------
    RawData
        Same contract; each pulse's spectrum multiplied by ``w(f/B)`` over the band and
        divided by the band mean of ``w`` (:func:`~sarmitsuba.focus.windows.window_mean`),
        so a unit-peak rect pulse becomes the unit-peak windowed pulse ``p_r``. Outside the
        band, where band-limited data hold only the artefacts of their truncation to the
        fast-time window, ``w`` continues ``B``-periodically (for a cosine-series window
        the filter is exactly a weighted sum of the data shifted by ``m / B``; rect is the
        identity). FFT zero-padded to ``2 n``. ``metadata["range_window"]`` records the
        window.

    Raises
    ------
    ValueError
        Data not compressed, bad window, non-uniform fast time.
    """
    _check_raw(raw, compressed=True)
    name, params = check_window(window, **window_params)
    n = raw.n_samples
    n_fft = scipy.fft.next_fast_len(2 * n)
    f = scipy.fft.fftfreq(n_fft, 1.0 / raw.fs)
    b = raw.bandwidth
    # B-periodic extension of the window: over the band it is w(f/B); outside (where band-
    # limited data have nothing but truncation artefacts) it continues periodically, so the
    # filter is a sum of copies of the data shifted by m / B, and rect is the identity
    wrapped = np.mod(f + b / 2.0, b) - b / 2.0
    filt = spectral_window(name, wrapped, b, **params) / window_mean(name, **params)
    data = _filter_blocks(raw.data, filt, n_fft, 0, workers)
    meta = _window_metadata(raw, name, params, method="window on compressed data", fft_length=n_fft)
    return dataclasses.replace(raw, data=data, metadata=meta)
