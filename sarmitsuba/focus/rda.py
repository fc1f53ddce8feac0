"""Range-Doppler algorithm (RDA) with interpolated RCMC and optional SRC.

Cumming and Wong (2005) ch. 6. In the range-Doppler domain (range time ``tau``, azimuth
frequency ``f_eta``) a point target at closest-approach range ``R0`` sits on the range
``R0 / D(f_eta)`` with ``D = sqrt(1 - (c f_eta / (2 Vr f0))^2)`` (C&W eq. 6.23, range cell
migration), with azimuth phase ``-4 pi R0 f0 D / c`` (eq. 6.26). Expanding the exact 2-D
spectrum phase ``-(4 pi R0 / c) sqrt((f0 + f_tau)^2 - (c f_eta / 2 Vr)^2)`` in ``f_tau``
gives these two terms plus a range-azimuth coupling of second and higher order in
``f_tau`` that grows with squint and bandwidth; *secondary range compression* (SRC)
removes it at a reference range. Steps here:

1. range FFT (with a small zero guard), range window ``w_r(f_tau)`` over ``|f_tau| <= B/2``;
   optional SRC ``"range"`` (C&W option 3: a range-frequency filter evaluated at the
   Doppler centroid, before the azimuth FFT);
2. azimuth FFT (true Doppler, unwrapped around the centroid); optional SRC ``"2d"``
   (C&W option 2: in the 2-D frequency domain, exact at ``R_src`` for every ``f_eta``:
   ``exp(+j 4 pi R_src / c [Q - Q(0) - f_tau f0 / Q(0)])``, all orders, not only the
   quadratic);
3. range IFFT, zero-padded by ``upsample`` (default 2) so the signal occupies less than
   half the band of the RCMC kernel;
4. **RCMC** by an 8-tap Kaiser-windowed sinc: output range gate ``R`` reads the range
   ``R / D(f_eta)``: range-varying, exact for the linear term at every range, in a block of
   rows at a time (vectorised passes, not a loop over samples);
5. azimuth matched filter per range gate, ``exp(+j 4 pi R f0 D(f_eta) / c)`` (exact for the
   hyperbolic history), azimuth window over the processed band, amplitude normalisation,
   azimuth output origin, all phases in float64 reduced modulo 2 pi; with SRC, also the
   band-mean of the residual coupling ``(R - R_src) x coupling`` per range gate (it would
   otherwise bias the peak phase away from ``R_src``: about 3 deg at +-400 m in the
   21.9 deg case);
6. azimuth IFFT.

Where RDA fails
---------------
RCMC and the azimuth filter above are exact; what RDA approximates is the *range-azimuth
coupling* (the ``f_tau^2`` and higher terms). Without SRC the quadratic phase error at the
band edge is ``(pi R0 / c) (c f_eta / 2 Vr)^2 / Q0^3 * B^2 / 2``, i.e. for the Cumming and
Wong Table 6.1 case (C band, 50 MHz, R = 20 km, Vr = 150 m/s) about 10 deg at 3.5 deg
squint (harmless) but about 460 deg at 21.9 deg squint: the range response defocuses
(IRW several times wider, PSLR destroyed). At 3.5 deg the focus is within tolerance but
the band-mean of that quadratic phase, ``(2 pi R0 / c) (alpha^2 / Q0^3) B^2 / 12`` (about
3.5 deg), biases the peak phase: use SRC where phase matters (interferometry). With SRC
the error is that of the SRC
reference: exact at ``R_src``, growing as ``|R0 - R_src| / R_src`` across the swath
(option 2), plus the Doppler variation of the coupling for option 3. High-squint,
wide-band or wide-swath cases beyond that need omega-K (:func:`sarmitsuba.focus.omega_k`)
or backprojection. Like omega-K, RDA needs a straight, uniformly sampled, monostatic
track (checked) and range-invariant ``Vr``.

References
----------
.. [1] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar
   Data*, Artech House, 2005, ch. 6 (RDA; eqs. 6.22-6.32 RCMC and azimuth matched filter,
   section 6.2.3 SRC options 1-3, Table 6.1 simulation parameters).
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Sequence

import numpy as np
import scipy.fft

from ..constants import SPEED_OF_LIGHT
from ..image import SarImage
from ..raw import RawData
from .omegak import _make_image, _range_compressed
from .stripmap import (StripmapGeometry, _azimuth_weights, _band_weights, _cis, _doppler_axis, _Interpolator,
                       _window_label, _focus_setup, slant_output_grid)

__all__ = ["range_doppler"]

C = SPEED_OF_LIGHT
_BLOCK_ROWS = 64
#: Zero samples appended in range before the FFT so the upsampling does not wrap the
#: end of the window onto its start.
_GUARD = 16
_SRC_MODES = {False: None, None: None, "none": None, True: "2d", "2d": "2d", "range": "range"}


def range_doppler(raw: RawData, *, window_range: Any = "rect", window_azimuth: Any = "rect",
                  src: bool | str = False, reference_range: float | None = None,
                  doppler_bandwidth: float | None = None, geometry: StripmapGeometry | None = None,
                  scene_centre: Sequence[float] | None = None, squint: float | None = None,
                  taps: int = 8, upsample: int = 2, workers: int | None = None,
                  azimuth_pattern: float | None = None) -> SarImage:
    """Focus straight-track stripmap data with the range-Doppler algorithm.

    Parameters
    ----------
    raw : RawData
        Monostatic straight-track data; range compressed, or raw chirps (then range
        compressed first, unweighted).
    window_range, window_azimuth : str or (str, dict), default "rect"
        Windows over the range band and the processed Doppler band, scaled to unit mean.
    src : bool or str, default False
        Secondary range compression: ``False``/``"none"``; ``True`` or ``"2d"`` (C&W
        option 2, 2-D frequency domain, exact at the reference range for all Doppler
        frequencies); ``"range"`` (C&W option 3, range frequency domain at the Doppler
        centroid).
    reference_range : float, m, optional
        SRC reference range and centre of the output range axis; default the
        closest-approach range of the mid-swath beam centre.
    doppler_bandwidth : float, Hz, optional
        Processed Doppler bandwidth around the centroid; default the whole PRF.
    geometry, scene_centre, squint
        As in :func:`sarmitsuba.focus.omega_k`.
    taps : int, default 8
        RCMC kernel length (even, 4..32).
    upsample : int, default 2
        Range upsampling (1..8) before RCMC: with ``fs = 1.2 B`` and 2, an 8-tap kernel
        errs by less than -60 dB; with 1 it would reach -20 dB at the band edge.
    workers : int, optional
        Threads for the FFTs and the RCMC row blocks.

    azimuth_pattern : float, optional
        ``L / lambda`` of the two-way azimuth pattern ``sinc^2(L sin(phi - squint) / lambda)``
        that weights the data (the tracer's tapered beam or antenna; ``sin(phi) = lambda f_eta / (2 v)``):
        the azimuth window is normalised by the mean of window times pattern over the processed
        band, so a point target keeps its peak amplitude (as backprojection does).

    Returns
    -------
    SarImage
        Same grid and conventions as :func:`sarmitsuba.focus.omega_k` (``algorithm="rda"``).

    Raises
    ------
    ValueError
        Invalid geometry, unknown ``src``, or a bad option.
    """
    t_start = time.perf_counter()
    raw = _range_compressed(raw)
    if isinstance(src, str):
        src = src.strip().lower()
    if src not in _SRC_MODES:
        raise ValueError(f"src must be False, True, 'none', '2d' or 'range', got {src!r}")
    src_mode = _SRC_MODES[src]
    geo, w_r, w_a, workers, band_a = _focus_setup(raw, geometry, scene_centre, squint, reference_range,
                                                  window_range, window_azimuth, doppler_bandwidth, workers)
    if isinstance(upsample, bool) or not isinstance(upsample, (int, np.integer)) or not 1 <= upsample <= 8:
        raise ValueError(f"upsample must be an integer in [1, 8], got {upsample!r}")
    n_a, n_r = raw.data.shape
    f0, bw, fs, prf, vel = raw.fc, raw.bandwidth, raw.fs, raw.prf, geo.velocity
    grid = slant_output_grid(geo, raw)
    r_src = geo.reference_range
    f_eta = _doppler_axis(n_a, prf, geo.doppler_centroid)
    alpha = C * f_eta / (2.0 * vel)
    if np.any(np.abs(alpha) >= f0 - bw / 2):
        raise ValueError("the Doppler band reaches the evanescent region (c f_eta / 2Vr >= fc - B/2)")
    q0 = np.sqrt(f0**2 - alpha**2)  # Q(0, f_eta) = f0 D(f_eta)

    # ---- 1. range FFT, window, SRC option 3
    n1 = int(scipy.fft.next_fast_len(n_r + _GUARD))
    spec = scipy.fft.fft(raw.data, n=n1, axis=1, workers=workers)
    f_tau = np.fft.fftfreq(n1, 1.0 / fs)
    range_filter = _band_weights(w_r, f_tau, bw).astype(np.complex128)
    if src_mode == "range":
        a_c = C * geo.doppler_centroid / (2.0 * vel)
        range_filter *= _cis(_src_cycles(r_src, f_tau, f0, a_c))
    spec *= range_filter.astype(np.complex64)

    # ---- 2. azimuth FFT, SRC option 2
    spec = scipy.fft.fft(spec, axis=0, workers=workers, overwrite_x=True)
    if src_mode == "2d":
        for rows in _blocks(n_a):
            spec[rows] *= _cis(_src_cycles(r_src, f_tau[None, :], f0, alpha[rows, None]))

    # ---- 3. range IFFT upsampled by zero-padding the spectrum
    n2 = n1 * upsample
    if upsample > 1:
        big = np.zeros((n_a, n2), np.complex64)
        pos = (n1 + 1) // 2
        big[:, :pos] = spec[:, :pos]
        big[:, n2 - (n1 - pos):] = spec[:, pos:]
        spec = big
    rd = scipy.fft.ifft(spec, axis=1, workers=workers, overwrite_x=True)
    rd *= np.float32(upsample)
    del spec

    # ---- 4.-5. RCMC (R -> R / D) and azimuth matched filter, row block by row block
    interp = _Interpolator(taps, passband=min(0.95, bw / (fs * upsample)))
    fine_rate = fs * upsample
    t0 = float(raw.fast_time[0])
    d_r = grid.range - r_src
    col_cycles = 2.0 * f0 * d_r / C  # float64 [n_r]: 2 R f0 D / c = 2 (R_src + d) (f0 + (Q0 - f0)) / c
    row_cycles = (2.0 * r_src * q0 / C + f_eta * (grid.azimuth[0] - geo.pulse_azimuth[0]) / vel + 0.125)
    d_eta = q0 / f0
    # SRC is exact at R_src only: a target at R keeps (R - R_src) x coupling. Its band-mean
    # (the part that biases the peak phase) is removed per range gate; the zero-mean rest
    # only broadens, by far less (see module docstring).
    residual = _mean_coupling(w_r, bw, f0, alpha) if src_mode is not None else np.zeros(n_a)
    if src_mode == "range":
        applied = np.full(n_a, _mean_coupling(w_r, bw, f0, np.array([C * geo.doppler_centroid / (2.0 * vel)]))[0])
    else:
        applied = residual
    row_cycles += 2.0 * r_src * (residual - applied) / C
    row_gain = (_azimuth_weights(w_a, f_eta, geo.doppler_centroid, band_a, azimuth_pattern, C / f0, vel,
                                 geo.squint)
                * d_eta**1.5 * np.sqrt(2.0 * f0 * vel**2 / C) / band_a)
    col_gain = (1.0 / np.sqrt(grid.range)).astype(np.float32)
    image = np.empty((n_a, n_r), np.complex64)

    def run_block(rows: slice) -> None:
        pos = (2.0 * grid.range[None, :] / (C * d_eta[rows, None]) - t0) * fine_rate
        values = interp(rd[rows], pos)
        cycles = (row_cycles[rows, None] + col_cycles[None, :]
                  + 2.0 * d_r[None, :] * (q0[rows, None] - f0 + residual[rows, None]) / C)
        values *= _cis(cycles)
        values *= (row_gain[rows, None] * col_gain[None, :]).astype(np.float32)
        image[rows] = values

    blocks = _blocks(n_a)
    if workers > 1:
        with ThreadPoolExecutor(workers) as pool:
            list(pool.map(run_block, blocks))
    else:
        for block in blocks:
            run_block(block)
    del rd

    # ---- 6. azimuth IFFT
    image = scipy.fft.ifft(image, axis=0, workers=workers, overwrite_x=True).astype(np.complex64, copy=False)
    seconds = time.perf_counter() - t_start
    window = f"range={_window_label(*w_r)}, azimuth={_window_label(*w_a)}"
    focus = {"algorithm": "rda", "window": window, "src": src_mode or "none", "src_range": r_src,
             "taps": int(taps), "kaiser_beta": interp.beta, "upsample": int(upsample),
             "doppler_bandwidth": band_a, "geometry": geo.to_dict(), "workers": workers, "seconds": seconds,
             "interpolation": "RCMC, Kaiser-windowed sinc", "normalisation": "peak = a over the processed band"}
    return _make_image(raw, grid, image, "rda", window, focus)


def _blocks(n: int) -> list[slice]:
    return [slice(i, min(i + _BLOCK_ROWS, n)) for i in range(0, n, _BLOCK_ROWS)]


def _mean_coupling(w_r: tuple[str, dict[str, float]], bw: float, f0: float, alpha: np.ndarray) -> np.ndarray:
    """Band mean [Hz] of the coupling ``Q - Q(0) - f f0 / Q(0)`` per Doppler row, weighted by the range window."""
    f = (np.arange(513) / 512 - 0.5) * bw
    w = _band_weights(w_r, f, bw)
    return (_src_cycles(C / 2.0, f[None, :], f0, alpha[:, None]) * w).sum(axis=1) / w.sum()


def _src_cycles(r_src: float, f_tau: np.ndarray, f0: float, alpha: np.ndarray | float) -> np.ndarray:
    """Phase [cycles] of the SRC filter: ``2 R_src / c [Q - Q(0) - f_tau f0 / Q(0)]`` (float64),
    the range-azimuth coupling of order >= 2 in ``f_tau`` at ``R_src``, with its sign removed."""
    alpha2 = np.asarray(alpha, dtype=np.float64) ** 2
    q00 = np.sqrt(f0**2 - alpha2)
    # Q - Q(0) - f f0 / Q(0), written without cancellation:
    # Q - Q(0) = ((f0 + f)^2 - f0^2) / (Q + Q(0)) = f (2 f0 + f) / (Q + Q(0))
    q = np.sqrt((f0 + f_tau) ** 2 - alpha2)
    coupling = f_tau * (2.0 * f0 + f_tau) / (q + q00) - f_tau * f0 / q00
    return 2.0 * r_src * coupling / C
