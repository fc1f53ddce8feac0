"""CPHD's frequency (FX) domain: range-compressed fast-time samples as the deramped phase history
that vendors deliver (Umbra, Capella, ICEYE) and FX readers (FastSAR) take, and back.

Used by :mod:`sarmitsuba.formats.cphd` (``write_cphd(..., domain="fx")``, ``read_cphd``). The FX
signal of a vector is the Fourier transform along fast time of its range-compressed echo, with the
scene reference point's (SRP's) delay taken out: docs/physics.md (GEO2'),

    X[v, k] = exp(+j 2 pi fc tau_srp[v]) exp(-j 2 pi f_k (t0 - tau_srp[v])) sum_i s[v, i] exp(-j 2 pi k i / M)

for the samples ``s[v, i]`` at ``t_i = t0 + i / fs`` (RawData, absolute carrier phase), ``M`` the
fast-time length zero-padded to at least :data:`FX_OVERSAMPLING` times the samples (so that
CPHD's ``FX_OSR = 1 / (SCSS (TOA2 - TOA1))`` is at least 1.25), ``f_k = k fs / M`` and
``fx_k = fc + f_k`` for all ``M`` bins ``k = -(M // 2) .. M - 1 - M // 2`` of the sampled band
``fs``: ``SC0 = fc - (M // 2) fs / M``, ``SCSS = fs / M``. ``FX1``, ``FX2`` are the transmitted
band's edges ``fc -+ B / 2``, inside the sampled one; the bins beyond them hold what band-limited
echoes have there, the leakage of their truncation to the fast-time window, which the TOA samples hold too
(and which focusing keeps, :func:`sarmitsuba.focus.apply_range_window`), so that both domains
focus to the same image. A point at the SRP gives ``X = fs P_r(f_k)`` times one constant
phase (phase-flat: ``SGN = -1``, a point at ``dTOA`` reads ``exp(-j 2 pi fx dTOA)``); ``TOA1``,
``TOA2`` are the delays of the first and last fast-time samples relative to the SRP, as in the TOA
domain.

The inverse (:func:`toa_from_fx`) puts the bins back (zero where a file has none) and transforms
back: for each vector the samples of its valid window ``[TOA1, TOA2] + tau_srp`` on one fast-time
axis for all vectors (a fractional shift is a phase ramp over the bins, so vectors whose windows do
not share a sample grid, as in vendors' spotlight files, read too). For the files of
:func:`fx_from_toa` it gives the fast-time samples back within float32 rounding.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft

__all__ = ["FX_OVERSAMPLING", "FxGrid", "fx_grid", "fx_from_toa", "toa_from_fx", "FxLayout", "fx_layout"]

#: Zero padding of fast time before the transform: the FFT length is at least this times the
#: samples, so ``FX_OSR = M / (N - 1)`` exceeds the 1.2 that sarkit's and sarpy's checks want.
FX_OVERSAMPLING = 1.25
#: Pulses transformed at once (bounds the complex128 working array).
_BLOCK = 512
#: Samples [fraction of 1 / fs] by which a sample may lie outside a vector's TOA window and still be
#: read: a TOAFixed file of :mod:`sarmitsuba.formats.cphd` moves the window's edges by up to
#: ``TOA_FIXED_TOLERANCE`` (2e-11 s, 0.004 samples at 180 MHz).
_EDGE_TOLERANCE = 0.05


@dataclass(frozen=True)
class FxGrid:
    """The FX bins of a fast-time axis: ``n_fft`` (the zero-padded FFT length ``M``, also the samples
    per FX vector, ``NumSamples``) and ``df = fs / M`` [Hz] (``SCSS``); the bins are
    ``k = -(M // 2) .. M - M // 2 - 1``."""

    n_fft: int
    df: float

    @property
    def bins(self) -> np.ndarray:
        """int64 [n_fft]: the bins ``k`` (baseband frequency ``k df``), lowest frequency first."""
        return np.arange(self.n_fft) - self.n_fft // 2

    @property
    def n_bins(self) -> int:
        """Samples per FX vector (``NumSamples``)."""
        return self.n_fft

    def band(self, fc: float, bandwidth: float) -> tuple[float, float]:
        """(FX1, FX2) [Hz]: the band ``fc -+ bandwidth / 2``, cut to the sampled one (the first and
        last bins) where ``bandwidth`` exceeds ``fs``."""
        low, high = fc + self.bins[0] * self.df, fc + self.bins[-1] * self.df
        return max(fc - 0.5 * bandwidth, low), min(fc + 0.5 * bandwidth, high)


def fx_grid(n_samples: int, fs: float) -> FxGrid:
    """The :class:`FxGrid` of ``n_samples`` fast-time samples at ``fs`` [Hz]:
    ``M = next_fast_len(ceil(1.25 n_samples))``, ``df = fs / M``."""
    n_fft = scipy.fft.next_fast_len(int(math.ceil(FX_OVERSAMPLING * n_samples)))
    return FxGrid(n_fft=n_fft, df=fs / n_fft)


def fx_from_toa(data: np.ndarray, t0: float, fs: float, fc: float, tau: np.ndarray, grid: FxGrid) -> np.ndarray:
    """complex64 [n_pulses, grid.n_bins]: the FX signal of docs/physics.md (GEO2') from the
    range-compressed samples ``data`` complex [n_pulses, n_samples] at fast times ``t0 + i / fs`` [s],
    carrier ``fc`` [Hz], compensated to the SRP delays ``tau`` float64 [n_pulses] [s]; the bins of
    ``grid`` (:func:`fx_grid`), lowest frequency first. Phases are formed in float64."""
    tau = np.asarray(tau, dtype=np.float64)
    f = grid.bins * grid.df
    out = np.empty((data.shape[0], grid.n_bins), dtype=np.complex64)
    carrier = np.mod(fc * tau, 1.0)                 # cycles: exp(+j 2 pi fc tau) (GEO2)
    for start in range(0, data.shape[0], _BLOCK):
        rows = slice(start, min(start + _BLOCK, data.shape[0]))
        spectrum = scipy.fft.fftshift(scipy.fft.fft(np.asarray(data[rows], dtype=np.complex128), n=grid.n_fft,
                                                    axis=1), axes=1)
        cycles = carrier[rows, None] - f[None, :] * (t0 - tau[rows])[:, None]
        out[rows] = spectrum * np.exp(2j * np.pi * cycles)
    return out


@dataclass(frozen=True)
class FxLayout:
    """Where an FX file's samples sit: ``fc`` [Hz] the carrier (a bin), ``first`` the bin of the first
    sample relative to it (``SC0 = fc + first SCSS``), ``fs`` [Hz] the fast-time rate and ``n_fft`` the
    transform length (``fs = n_fft SCSS``)."""

    fc: float
    first: int
    fs: float
    n_fft: int


def fx_layout(sc0: np.ndarray, scss: np.ndarray, n_bins: int, fxc: float, sample_rate: float | None) -> FxLayout:
    """The :class:`FxLayout` of FX vectors with ``n_bins`` samples at ``SC0 + n SCSS`` (float64 [n_vectors]
    each, Hz), ``FxC`` [Hz] and the receiver's ``SampleRate`` [Hz] (None when the file gives none).

    The carrier is ``FxC`` when it lies on a sample (within 1e-6 of ``SCSS``; files of
    :func:`fx_from_toa`), else the sample nearest to it. The fast-time rate is ``SampleRate`` when it
    is a whole multiple of ``SCSS`` no smaller than ``n_bins``, else ``SCSS`` times the next FFT length
    from ``1.25 n_bins`` (the TOA samples oversample the band by 1.25).

    Raises ValueError when the vectors' frequency axes differ (``FXFixed`` false: ``SC0`` or ``SCSS``
    varies by more than 1e-6 of ``SCSS``), which needs resampling.
    """
    sc0, scss = np.asarray(sc0, dtype=np.float64), np.asarray(scss, dtype=np.float64)
    step = float(scss[0])
    if np.ptp(sc0) > 1e-6 * step or np.ptp(scss) > 1e-9 * step:
        raise ValueError(f"the vectors' frequency axes differ (SC0 varies by {np.ptp(sc0):.3g} Hz, SCSS by "
                         f"{np.ptp(scss):.3g} Hz); RawData needs one axis, resampling is not supported")
    offset = (fxc - float(sc0[0])) / step
    centre = int(round(offset))
    fc = float(fxc) if abs(offset - centre) <= 1e-6 else float(sc0[0]) + centre * step
    ratio = None if not sample_rate else float(sample_rate) / step
    if ratio is not None and abs(ratio - round(ratio)) <= 1e-6 * ratio and round(ratio) >= n_bins:
        n_fft, fs = int(round(ratio)), float(sample_rate)
    else:
        n_fft = scipy.fft.next_fast_len(int(math.ceil(FX_OVERSAMPLING * n_bins)))
        fs = n_fft * step
    return FxLayout(fc=fc, first=-centre, fs=fs, n_fft=n_fft)


def toa_from_fx(signal: np.ndarray, layout: FxLayout, toa1: np.ndarray, toa2: np.ndarray,
                tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(data complex64 [n_vectors, n_samples], fast_time float64 [n_samples] s): the fast-time samples of
    the FX vectors ``signal`` complex [n_vectors, n_bins] laid out as ``layout`` (:func:`fx_layout`),
    the inverse of :func:`fx_from_toa` (docs/physics.md (GEO2')). Each vector fills the samples of
    one fast-time axis (from the earliest ``TOA1 + tau`` to the latest ``TOA2 + tau``, at
    ``layout.fs``) that lie in its window ``[TOA1, TOA2] + tau`` (``toa1``, ``toa2``, ``tau`` float64
    [n_vectors] s; ``tau`` the SRP delay), zero elsewhere.

    Raises ValueError when a window is longer than the ``1 / SCSS`` the FX samples resolve
    (``FX_OSR`` below 1: the transform would fold it)."""
    toa1, toa2, tau = (np.asarray(a, dtype=np.float64) for a in (toa1, toa2, tau))
    fs, n_fft = layout.fs, layout.n_fft
    if np.max(toa2 - toa1) * fs >= n_fft:
        raise ValueError(f"a vector's TOA window ({np.max(toa2 - toa1):.4g} s) exceeds the {n_fft / fs:.4g} s "
                         "that its frequency spacing SCSS resolves (FX_OSR below 1)")
    tol = _EDGE_TOLERANCE
    t0 = float(np.min(toa1 + tau))
    first = np.ceil((toa1 + tau - t0) * fs - tol).astype(np.int64)       # each vector's first sample
    count = np.floor((toa2 + tau - t0) * fs + tol).astype(np.int64) - first + 1
    n_samples = int(np.max(first + count))
    f = (layout.first + np.arange(signal.shape[1])) * (fs / n_fft)      # baseband frequencies [Hz]
    data = np.zeros((signal.shape[0], n_samples), dtype=np.complex64)
    carrier = np.mod(layout.fc * tau, 1.0)
    for start in range(0, signal.shape[0], _BLOCK):
        rows = slice(start, min(start + _BLOCK, signal.shape[0]))
        d0 = t0 + first[rows] / fs - tau[rows]          # dTOA of each vector's first sample
        spectrum = np.zeros((rows.stop - rows.start, n_fft), dtype=np.complex128)
        spectrum[:, (layout.first + np.arange(signal.shape[1])) % n_fft] = (
            signal[rows] * np.exp(2j * np.pi * (f[None, :] * d0[:, None] - carrier[rows, None])))
        samples = scipy.fft.ifft(spectrum, axis=1)
        i0, n = first[rows], count[rows]
        if np.ptp(i0) == 0 and np.ptp(n) == 0:          # one window for all (files of fx_from_toa)
            data[rows, i0[0]:i0[0] + n[0]] = samples[:, :n[0]]
            continue
        for v in range(len(i0)):
            data[rows.start + v, i0[v]:i0[v] + n[v]] = samples[v, :n[v]]
    return data, t0 + np.arange(n_samples) / fs
