"""Accurate omega-K (wavenumber-domain) focusing with Stolt interpolation.

Cumming and Wong (2005) ch. 8. For a straight track at constant velocity ``Vr`` the 2-D
spectrum of a point target at zero-Doppler coordinate ``x`` and closest-approach range
``R0`` is, by the principle of stationary phase and exactly for the hyperbolic range
history (C&W eq. 8.1),

.. math::

    S(f_\\tau, f_\\eta) = a\\, P(f_\\tau)\\, W(f_\\eta)\\,
        \\exp\\!\\Big(-j \\frac{4 \\pi R_0}{c} Q(f_\\tau, f_\\eta)\\Big)
        \\exp\\!\\Big(-j 2 \\pi f_\\eta \\frac{x}{V_r}\\Big),
    \\qquad Q = \\sqrt{(f_0 + f_\\tau)^2 - \\Big(\\frac{c f_\\eta}{2 V_r}\\Big)^2}.

The Stolt change of variable ``f0 + f' = Q(f_tau, f_eta)`` (C&W eq. 8.5) makes the phase
linear in ``f'`` for *every* ``R0``; the reference function ``exp(+j 4 pi R_ref Q / c)``
(C&W eq. 8.3, bulk focus at ``R_ref``, including the squint through the absolute,
unwrapped Doppler frequency) then becomes a linear phase too, and a 2-D inverse FFT
focuses the whole scene. Steps here:

1. place each range line circularly centred in a zero-padded buffer (``oversample``,
   default 1.5, so that the spectrum is sampled finely enough for the interpolator) and
   take the 2-D FFT (complex64, ``scipy.fft`` with threads);
2. for each block of Doppler rows (true Doppler ``f_eta``, unwrapped around the Doppler
   centroid) and each output range frequency ``q = f0 + f'`` on the grid
   ``k * Delta f`` (the band of the row only), find ``f_tau = sqrt(q^2 + (c f_eta / 2Vr)^2) - f0``
   and interpolate the spectrum there with a Kaiser-windowed sinc (``taps``, default 12;
   worst-case error about -55 dB for the default ``oversample``), vectorised over the
   block;
3. multiply by the analytic factors at the mapped positions: the reference function
   and the output-range origin (together ``exp(+j 4 pi R_start q / c)``), the fast-time
   origin ``exp(-j 2 pi f_tau tau_ref)``, the range window ``w_r(f_tau)``, the Stolt
   Jacobian ``q / (f0 + f_tau)``, the azimuth window, the azimuth origin and the
   amplitude normalisation; all phases formed in float64 and reduced modulo 2 pi;
4. scatter row ``k`` to FFT bin ``k mod n`` and take the range IFFT (which lands column
   ``m`` at ``R_start + m c / (2 fs)``) and the azimuth IFFT.

Validity
--------
* Exact (to the interpolation error) for a **straight, uniformly sampled, monostatic
  track** with range-invariant ``Vr``, at any squint and aperture, with stop-and-hop
  echoes: :func:`~sarmitsuba.focus.stripmap.stripmap_geometry` checks the track and
  raises ``ValueError`` otherwise (use backprojection).
* **Spaceborne data**: on a real orbit the effective velocity ``Vr`` varies with range
  (the hyperbolic model with one ``Vr`` holds at each range separately), so this
  algorithm is exact only near ``R_ref``; wide swaths need range blocks with their own
  ``Vr``. sarmitsuba's synthetic orbits are straight lines over a flat earth, for which it
  is exact everywhere.
* The Doppler spectrum (over the whole range band) must fit in one PRF around the Doppler
  centroid; the Stolt-mapped range band ``B / cos(squint)`` must be below ``fs``.
* Images are periodic in azimuth and range (FFT): targets whose zero-Doppler position
  lies outside the output grid wrap around; targets whose aperture is cut by the start or
  end of the data are partially focused.

References
----------
.. [1] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar
   Data*, Artech House, 2005, ch. 8 (eqs. 8.1-8.5: 2-D spectrum, reference function
   multiply, Stolt interpolation).
.. [2] C. Cafforio, C. Prati and F. Rocca, "SAR data focusing using seismic migration
   techniques", IEEE Trans. Aerosp. Electron. Syst. 27(2), 194-207, 1991.
"""
from __future__ import annotations

import copy
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Sequence

import numpy as np
import scipy.fft

from ..constants import SPEED_OF_LIGHT
from ..image import SarImage
from ..raw import RawData
from .stripmap import (StripmapGeometry, _band_weights, _cis, _doppler_axis, _Interpolator, _window_label,
                       _focus_setup, slant_output_grid)

__all__ = ["omega_k"]

C = SPEED_OF_LIGHT
#: Doppler rows per vectorised block (per-thread working set ~ 40 bytes x rows x n_pad).
_BLOCK_ROWS = 64


def omega_k(raw: RawData, *, window_range: Any = "rect", window_azimuth: Any = "rect",
            reference_range: float | None = None, doppler_bandwidth: float | None = None,
            geometry: StripmapGeometry | None = None, scene_centre: Sequence[float] | None = None,
            squint: float | None = None, taps: int = 12, oversample: float = 1.5,
            workers: int | None = None) -> SarImage:
    """Focus straight-track stripmap data with the accurate omega-K algorithm.

    Parameters
    ----------
    raw : RawData
        Monostatic straight-track data; range compressed, or raw chirps (then range
        compressed first by :mod:`sarmitsuba.focus.range_compression`, unweighted).
    window_range, window_azimuth : str or (str, dict), default "rect"
        Windows over the range band ``|f_tau| <= B/2`` and the processed Doppler band
        (:mod:`sarmitsuba.focus.windows` names, e.g. ``("kaiser", {"beta": 2.5})``), scaled
        to unit mean so a point target keeps its peak amplitude.
    reference_range : float, m, optional
        ``R_ref``: bulk-focus range and centre of the output range axis. Default: the
        closest-approach range of the mid-swath beam centre. For this straight-track
        model the focus is exact at every range whatever ``R_ref``.
    doppler_bandwidth : float, Hz, optional
        Processed Doppler bandwidth ``B_a`` centred on the Doppler centroid (the azimuth
        window spans it; zero outside). Default: the whole PRF.
    geometry : StripmapGeometry, optional
        Precomputed geometry; default ``stripmap_geometry(raw, scene_centre=...,
        squint=..., reference_range=...)``.
    scene_centre : 3 floats, m, optional
        Fixes the slant plane (see :func:`~sarmitsuba.focus.stripmap.stripmap_geometry`).
    squint : float, deg, optional
        Beam squint, when it is not recorded in the metadata (else estimated from data).
    taps : int, default 12
        Stolt interpolation kernel length (even, 4..32).
    oversample : float, default 1.5
        Range zero-padding factor before the range FFT (>= 1.1): the spectrum is sampled
        ``oversample`` times more finely than the data need, which is what lets a short
        kernel interpolate it accurately (worst-case kernel error about -55 dB at 12 taps,
        1.5; -35 dB at 12 taps, 1.25).
    workers : int, optional
        Threads for the FFTs and the row blocks; default all available CPUs.

    Returns
    -------
    SarImage
        complex64 ``[n_pulses, n_samples]`` on :func:`~sarmitsuba.focus.stripmap.slant_output_grid`
        (``plane="slant"``, ``algorithm="omega-k"``). A point target of amplitude ``a``
        whose Doppler spectrum fills the processed band has peak ``a`` at its predicted
        position, with the carrier removed there (as in backprojection).
        ``metadata["focus"]`` records the parameters, geometry and ``seconds``.

    Raises
    ------
    ValueError
        Invalid geometry (not straight/uniform/monostatic, see ``stripmap_geometry``),
        a Stolt band wider than ``fs``, or a bad option.

    Notes
    -----
    Cost: two 2-D FFT passes on ``n_pulses x oversample n_samples`` and ``taps`` gather /
    multiply-add passes (the interpolation, which dominates in NumPy, as focusing.md
    section 5a found for RCMC), plus a few float64 passes for the exact phases.
    """
    t_start = time.perf_counter()
    raw = _range_compressed(raw)
    geo, w_r, w_a, workers, band_a = _focus_setup(raw, geometry, scene_centre, squint, reference_range,
                                                  window_range, window_azimuth, doppler_bandwidth, workers)
    oversample = float(oversample)
    if not (np.isfinite(oversample) and 1.1 <= oversample <= 4.0):
        raise ValueError(f"oversample must be in [1.1, 4], got {oversample!r}")
    n_a, n_r = raw.data.shape
    f0, bw, fs, prf, vel = raw.fc, raw.bandwidth, raw.fs, raw.prf, geo.velocity
    if bw > fs:
        raise ValueError(f"bandwidth {bw:g} Hz exceeds fs = {fs:g} Hz: the range spectrum is aliased")
    grid = slant_output_grid(geo, raw)

    # ---- 1. centred, zero-padded 2-D FFT; (-1)^n puts f_tau = (j - n/2) df at column j
    n_pad = int(scipy.fft.next_fast_len(int(np.ceil(n_r * oversample))))
    n_pad += n_pad % 2
    df = fs / n_pad
    half = n_r // 2
    sign = np.where((np.arange(n_r) - half) % 2 == 0, 1.0, -1.0).astype(np.float32)
    spec = np.zeros((n_a, n_pad), np.complex64)
    np.multiply(raw.data[:, half:], sign[half:], out=spec[:, :n_r - half])
    np.multiply(raw.data[:, :half], sign[:half], out=spec[:, n_pad - half:])
    spec = scipy.fft.fft2(spec, workers=workers, overwrite_x=True)
    tau_ref = raw.fast_time[0] + half / fs  # fast time of buffer sample 0

    # ---- 2.-3. Stolt interpolation and analytic factors, row block by row block
    f_eta = _doppler_axis(n_a, prf, geo.doppler_centroid)
    alpha = C * f_eta / (2.0 * vel)
    if np.any(np.abs(alpha) >= f0 - bw / 2):
        raise ValueError("the Doppler band reaches the evanescent region (c f_eta / 2Vr >= fc - B/2)")
    q_lo = np.sqrt((f0 - bw / 2) ** 2 - alpha**2)
    q_hi = np.sqrt((f0 + bw / 2) ** 2 - alpha**2)
    if np.max(q_hi - q_lo) >= fs:
        raise ValueError(f"the Stolt-mapped range band (up to {np.max(q_hi - q_lo):.4g} Hz = B / cos(squint)) "
                         f"exceeds fs = {fs:.4g} Hz: the output would alias; sample faster or reduce the squint")
    k0 = np.ceil(q_lo / df).astype(np.int64)
    n_k = int(np.max(np.floor(q_hi / df).astype(np.int64) - k0)) + 1
    r_start = float(grid.range[0])
    range_cycles_per_bin = np.mod(2.0 * r_start * df / C, 1.0)  # exp(j 4 pi R_start q / c), q = k df
    # azimuth: FFT origin at the first pulse, output origin at grid.azimuth[0]
    # (+1/8 cycle: the -pi/4 of the stationary-phase azimuth spectrum, concave range history)
    row_cycles = f_eta * (grid.azimuth[0] - geo.pulse_azimuth[0]) / vel + 0.125
    d_eta = np.sqrt(1.0 - (alpha / f0) ** 2)
    row_gain = (_band_weights(w_a, f_eta - geo.doppler_centroid, band_a)
                * d_eta**1.5 * np.sqrt(2.0 * f0 * vel**2 / (C * geo.reference_range)) / band_a)
    interp = _Interpolator(taps, passband=n_r / n_pad)
    j = np.arange(n_k, dtype=np.int64)

    def run_block(rows: slice) -> None:
        kk = k0[rows, None] + j[None, :]  # int64 [R, n_k]
        q = kk * df
        f_tau = np.sqrt(q * q + alpha[rows, None] ** 2) - f0
        values = interp(spec[rows], f_tau / df + n_pad / 2)
        gain = _band_weights(w_r, f_tau, bw) * (q / (f0 + f_tau)) * row_gain[rows, None]
        cycles = kk * range_cycles_per_bin - f_tau * tau_ref + row_cycles[rows, None]  # reduced in _cis
        values *= _cis(cycles)
        values *= gain.astype(np.float32)
        spec[rows] = 0
        np.put_along_axis(spec[rows], np.mod(kk, n_pad), values, axis=1)

    blocks = [slice(i, min(i + _BLOCK_ROWS, n_a)) for i in range(0, n_a, _BLOCK_ROWS)]
    if workers > 1:
        with ThreadPoolExecutor(workers) as pool:
            list(pool.map(run_block, blocks))
    else:
        for block in blocks:
            run_block(block)

    # ---- 4. range IFFT (column m at grid.range[m]), amplitude vs range, azimuth IFFT
    image = scipy.fft.ifft(spec, axis=1, workers=workers, overwrite_x=True)[:, :n_r]
    image *= np.sqrt(geo.reference_range / grid.range).astype(np.float32)
    image = scipy.fft.ifft(image, axis=0, workers=workers, overwrite_x=True).astype(np.complex64, copy=False)

    seconds = time.perf_counter() - t_start
    window = f"range={_window_label(*w_r)}, azimuth={_window_label(*w_a)}"
    focus = {"algorithm": "omega-k", "window": window, "taps": int(taps), "kaiser_beta": interp.beta,
             "oversample": oversample, "n_pad": n_pad, "doppler_bandwidth": band_a,
             "geometry": geo.to_dict(), "workers": workers, "seconds": seconds,
             "interpolation": "Stolt, Kaiser-windowed sinc", "normalisation": "peak = a over the processed band"}
    return _make_image(raw, grid, image, "omega-k", window, focus)


# ============================================================================ shared with rda
def _range_compressed(raw: RawData) -> RawData:
    """``raw`` itself when range compressed, else its matched-filter output (unweighted)."""
    if not isinstance(raw, RawData):
        raise TypeError(f"raw must be a sarmitsuba.raw.RawData, got {type(raw).__name__}")
    if raw.range_compressed:
        return raw
    from .range_compression import range_compress  # written alongside; imported only when needed
    return range_compress(raw)


def _make_image(raw: RawData, grid: Any, data: np.ndarray, algorithm: str, window: str,
                focus: dict[str, Any]) -> SarImage:
    metadata = copy.deepcopy(raw.metadata)
    metadata["focus"] = focus
    return SarImage(data=np.ascontiguousarray(data, dtype=np.complex64), azimuth=np.array(grid.azimuth),
                    range=np.array(grid.range), origin=np.array(grid.origin),
                    azimuth_direction=np.array(grid.azimuth_direction),
                    range_direction=np.array(grid.range_direction), plane="slant", algorithm=algorithm,
                    window=window, metadata=metadata)
