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
   default 1.5, so that the spectrum is sampled finely enough for a short interpolation
   kernel), multiplied by the kernel's deconvolution weights ``1 / Phi`` (NUFFT style,
   :mod:`sarmitsuba.focus.stolt`), and take the 2-D FFT (complex64; range FFTs per block
   of rows in threads, azimuth FFT with ``scipy.fft`` workers);
2. for each block of Doppler rows (true Doppler ``f_eta``, unwrapped around the Doppler
   centroid) and each output range frequency ``q = f0 + f'`` on the grid
   ``k * fs / n_out`` (the band of the row only), find
   ``f_tau = sqrt(q^2 + (c f_eta / 2Vr)^2) - f0`` and interpolate the spectrum there with
   the deconvolved Kaiser-Bessel kernel (``taps``, default 12; weights from a table,
   ``taps`` gather / multiply-add passes over the block, float32 weights and complex64
   data). With deconvolution the only kernel error is aliasing: worst case -76 dB at 6
   taps and below float32 precision at 12 taps for ``oversample`` 1.5 (-84 dB at 12 taps,
   1.1; table in :mod:`sarmitsuba.focus.stolt`); the table rounds positions to 1/8192 bin
   (a phase error below -70 dB). Against the exact non-uniform DFT, point-target images
   differ by less than -100 dB of the peak at 12 taps and -90 dB at 6 taps (the
   Kaiser-windowed sinc without deconvolution used before: about -55 dB at 12 taps);
3. multiply by the analytic factors at the mapped positions: the reference function
   and the output-range origin (together ``exp(+j 4 pi R_start q / c)``), the fast-time
   origin ``exp(-j 2 pi f_tau tau_ref)``, the range window ``w_r(f_tau)``, the Stolt
   Jacobian ``q / (f0 + f_tau)``, the azimuth window, the azimuth origin and the
   amplitude normalisation; all phases formed in float64 per output sample and reduced
   modulo 1 cycle before one float32 cos/sin;
4. scatter row ``k`` to FFT bin ``k mod n_out`` and take the range IFFT (which lands
   column ``m`` at ``R_start + m c / (2 fs)``; first ``n_samples`` columns kept, still per
   block of rows) and the azimuth IFFT.

The Stolt output is sampled on ``n_out`` range bins, not the ``n_pad`` of the input: data
inside the fast-time window focus within the closest-approach ranges
``c tau / 2 * q / sqrt(q^2 + (c f_eta / 2Vr)^2)`` over the window, band and Doppler rows,
and ``n_out = next_fast_len(that support + guard)``, the guard being ``max(128,
n_samples / 8)`` samples (images up to 1024 samples: 128; 4096: 512), over which the range
sidelobes of a target at one edge of the window decay before they wrap onto the other
edge (to about ``1 / (pi guard B / fs)``: -62 dB for 4096 samples at ``B / fs`` = 0.83,
unweighted). Fewer output bins mean fewer interpolated samples (``B n_out / fs`` per row).

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
  lies outside the output grid wrap around (in range beyond the guard above); targets
  whose aperture is cut by the start or end of the data are partially focused.

References
----------
.. [1] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar
   Data*, Artech House, 2005, ch. 8 (eqs. 8.1-8.5: 2-D spectrum, reference function
   multiply, Stolt interpolation).
.. [2] C. Cafforio, C. Prati and F. Rocca, "SAR data focusing using seismic migration
   techniques", IEEE Trans. Aerosp. Electron. Syst. 27(2), 194-207, 1991.
"""
from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import scipy.fft

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.raw import RawData
from .fft_contract import (azimuth_weights, doppler_rows, focus_setup, range_compressed, slant_image,
                           unit_mean_window, windows_label)
from .stolt import Scratch, StoltInterpolator, centred_buffer
from .stripmap import StripmapGeometry, check_monostatic, slant_output_grid

__all__ = ["omega_k", "omega_k_plan", "StoltPlan"]

C = SPEED_OF_LIGHT
#: Doppler rows per vectorised block (per-thread working set ~ 60 bytes x rows x n_out).
_BLOCK_ROWS = 32
#: Range guard of the Stolt output beyond the focused support: max(_GUARD_MIN, n / _GUARD_FRACTION).
_GUARD_MIN = 128
_GUARD_FRACTION = 8


def omega_k(raw: RawData, *, window_range: Any = "rect", window_azimuth: Any = "rect",
            reference_range: float | None = None, doppler_bandwidth: float | None = None,
            geometry: StripmapGeometry | None = None, scene_centre: Sequence[float] | None = None,
            squint: float | None = None, taps: int = 12, oversample: float = 1.5,
            workers: int | None = None, azimuth_pattern: float | None = None) -> SarImage:
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
        Stolt interpolation kernel length (even, 4..32): Kaiser-Bessel with deconvolution
        (:mod:`sarmitsuba.focus.stolt`). Worst-case kernel error at ``oversample`` 1.5:
        -45 dB at 4 taps, -76 dB at 6, -107 dB at 8, below float32 precision at 12. Cost:
        about 1.5 ns per tap and output sample (one core), the largest part of the run.
    oversample : float, default 1.5
        Range zero-padding factor before the range FFT (>= 1.1): the spectrum is sampled
        ``oversample`` times more finely than the data need, which is what lets a short
        kernel interpolate it accurately (worst-case kernel error at 12 taps: -84 dB at
        1.1, -127 dB at 1.25; at 6 taps: -58 dB at 1.25).
    workers : int, optional
        Threads for the FFTs and the row blocks; default all available CPUs.

    azimuth_pattern : float, optional
        ``L / lambda`` of the two-way azimuth pattern ``sinc^2(L sin(phi - squint) / lambda)``
        that weights the data (the tracer's tapered beam or antenna; ``sin(phi) = lambda f_eta / (2 v)``):
        the azimuth window is normalised by the mean of window times pattern over the processed
        band, so a point target keeps its peak amplitude (as backprojection does).

    Returns
    -------
    SarImage
        complex64 ``[n_pulses, n_samples]`` on :func:`~sarmitsuba.focus.stripmap.slant_output_grid`
        (``plane="slant"``, ``algorithm="omega-k"``): origin the scene centre's closest-approach
        point on the track, rows the zero-Doppler along-track coordinate from it, columns the
        absolute closest-approach slant range (docs/design.md section 8, Frames). A point target
        of amplitude ``a`` at ``X`` whose Doppler spectrum fills the processed band has peak ``a``
        at ``geometry.zero_doppler(X)`` (``SarImage.pixel_of(X)``), with the carrier removed there
        (as in backprojection).
        ``metadata["focus"]`` records the parameters, geometry and ``seconds``.

    Raises
    ------
    ValueError
        Invalid geometry (not straight/uniform/monostatic, see ``stripmap_geometry``),
        a Stolt band wider than ``fs``, or a bad option.
    GeometryNotSupported
        (a ValueError) Bistatic data (``rx_position`` farther than the tolerance from
        ``tx_position``, no ``rx_time``): omega-K forms the monostatic range ``2 R``, not the
        range sum ``R_t + R_r``; the message names ``backproject``
        (:func:`~sarmitsuba.focus.stripmap.check_monostatic`).

    Notes
    -----
    Cost: the FFT passes (range and azimuth FFT on ``n_pulses x n_pad``, ``n_pad`` about
    ``oversample n_samples``; range IFFT on ``n_pulses x n_out``; azimuth IFFT on
    ``n_pulses x n_samples``), plus per interpolated sample (``B n_out / fs`` per row)
    ``taps`` gather / multiply-add passes (the interpolation, which dominates in NumPy, as
    it does for RCMC: an 8-tap RCMC gather took 5.1 s of a 5.9 s 4096 x 4096 range-Doppler
    skeleton on a 2-core VM, the four FFT passes about 0.4 s) and about 10 float64/float32
    passes for the exact positions, phases and gains. All temporaries are per-thread buffers reused from
    block to block (fresh arrays would page-fault as much as the arithmetic costs). On
    4096 x 4096 with 2 threads (shared 2-core VM) that is about 2.3 times the FFT passes
    alone at 12 taps and 1.9 times at 6 taps (``benchmarks/focus_bench.py``; 8 to 9 times
    with the previous windowed-sinc gather).
    """
    t_start = time.perf_counter()
    tolerance = geometry.tolerance if isinstance(geometry, StripmapGeometry) else C / raw.fc / 16.0
    check_monostatic(raw, "omega-K", tolerance)          # before the work: bistatic data are refused
    raw = range_compressed(raw)
    geo, w_r, w_a, workers, band_a = focus_setup(raw, geometry, scene_centre, squint, reference_range,
                                                 window_range, window_azimuth, doppler_bandwidth, workers)
    grid, plan = omega_k_plan(raw, geo, w_r, w_a, band_a, taps, oversample, azimuth_pattern)
    oversample = float(oversample)
    image = _range_focus(raw, plan, workers)                                      # steps 1-4 in range
    image = scipy.fft.ifft(image, axis=0, workers=workers, overwrite_x=True)     # step 4: azimuth IFFT

    seconds = time.perf_counter() - t_start
    window = windows_label(w_r, w_a)
    focus = {"algorithm": "omega-k", "window": window, "taps": int(taps), "kaiser_beta": plan.interp.beta,
             "oversample": oversample, "n_pad": plan.n_pad, "n_out": plan.n_out, "doppler_bandwidth": band_a,
             "geometry": geo.to_dict(), "workers": workers, "seconds": seconds,
             "interpolation": "Stolt, deconvolved Kaiser-Bessel kernel",
             "interpolation_error_bound": plan.interp.error_bound, "normalisation": "peak = a over the processed band"}
    return slant_image(raw, grid, image, "omega-k", window, focus)


# ============================================================================ plan: sizes, bands, per-row factors
def omega_k_plan(raw: RawData, geo: StripmapGeometry, w_r: Any, w_a: Any, band_a: float, taps: int, oversample: Any,
                 azimuth_pattern: float | None) -> tuple[Any, "StoltPlan"]:
    """The output grid (:func:`~sarmitsuba.focus.stripmap.slant_output_grid`) and the
    :class:`StoltPlan` of :func:`omega_k` for range-compressed ``raw`` and the options
    :func:`~sarmitsuba.focus.fft_contract.focus_setup` checked; shared with its float64 linear
    map (:mod:`sarmitsuba.focus.linear`).

    Raises ValueError for ``oversample`` outside [1.1, 4], a bandwidth above ``fs`` or a Stolt
    band wider than ``fs``."""
    oversample = float(oversample)
    if not (np.isfinite(oversample) and 1.1 <= oversample <= 4.0):
        raise ValueError(f"oversample must be in [1.1, 4], got {oversample!r}")
    if raw.bandwidth > raw.fs:
        raise ValueError(f"bandwidth {raw.bandwidth:g} Hz exceeds fs = {raw.fs:g} Hz: the range spectrum is aliased")
    grid = slant_output_grid(geo, raw)
    return grid, _stolt_plan(raw, geo, grid, taps, oversample, w_r, w_a, band_a, azimuth_pattern)


@dataclass(frozen=True, eq=False)
class StoltPlan:
    """Layout and factors of :func:`omega_k`'s steps 1-4; arrays are per Doppler row (float64
    unless stated)."""

    n_r: int                      # range samples of the data and the image
    n_pad: int                    # zero-padded range FFT length of step 1
    n_out: int                    # range FFT length of the Stolt output (_output_length)
    f0: float                     # carrier [Hz]
    bw: float                     # range bandwidth [Hz]
    df: float                     # input range-frequency bin fs / n_pad [Hz]
    df_out: float                 # output range-frequency bin fs / n_out [Hz]
    tau_ref: float                # fast time of buffer sample 0 [s]
    interp: StoltInterpolator
    prefilter: np.ndarray         # kernel deconvolution weights 1 / Phi of step 1
    w_r: tuple                    # range window spec
    alpha2: np.ndarray            # (c f_eta / 2Vr)^2 [Hz^2]
    q_hi: np.ndarray              # upper edge of the row's Stolt band [Hz]
    k0: np.ndarray                # int64: first output bin of the row
    k0f: np.ndarray               # k0 as float64
    n_valid: np.ndarray           # int64: output bins of the row
    range_cycles_per_bin: float   # 2 R_start df_out / c modulo 1
    row_cycles: np.ndarray        # azimuth-origin phase [cycles]
    row_gain: np.ndarray          # float32: azimuth window and amplitude normalisation
    amplitude: np.ndarray         # float32 [n_r]: point-target amplitude vs range, sqrt(R_ref / R)


def _stolt_plan(raw: RawData, geo: StripmapGeometry, grid: Any, taps: int, oversample: float, w_r: Any, w_a: Any,
                band_a: float, pattern: float | None) -> StoltPlan:
    """Sizes, Stolt bands, output bins and the per-row factors of steps 1-4."""
    n_r = raw.data.shape[1]
    fs = raw.fs
    n_pad = int(scipy.fft.next_fast_len(int(np.ceil(n_r * oversample))))
    n_pad += n_pad % 2
    interp = StoltInterpolator(taps, n_r, n_pad)
    prefilter = interp.prefilter()
    f_eta, alpha, q_lo, q_hi = _stolt_bands(raw, geo)
    r_start = float(grid.range[0])
    n_out = _output_length(raw, q_lo, q_hi, r_start)
    df_out = fs / n_out
    k0 = np.ceil(q_lo / df_out).astype(np.int64)  # row r holds output bins k0[r] .. k0[r] + n_valid[r] - 1
    n_valid = np.floor(q_hi / df_out).astype(np.int64) - k0 + 1
    # azimuth: FFT origin at the first pulse, output origin at grid.azimuth[0]
    # (+1/8 cycle: the -pi/4 of the stationary-phase azimuth spectrum, concave range history)
    row_cycles = f_eta * (grid.azimuth[0] - geo.pulse_azimuth[0]) / geo.velocity + 0.125
    return StoltPlan(
        n_r=n_r, n_pad=n_pad, n_out=n_out, f0=raw.fc, bw=raw.bandwidth, df=fs / n_pad, df_out=df_out,
        tau_ref=raw.fast_time[0] + (n_r // 2) / fs, interp=interp, prefilter=prefilter, w_r=w_r,
        alpha2=alpha**2, q_hi=q_hi, k0=k0, k0f=k0.astype(np.float64), n_valid=n_valid,
        range_cycles_per_bin=np.mod(2.0 * r_start * df_out / C, 1.0),  # exp(j 4 pi R_start q / c), q = k df_out
        row_cycles=row_cycles, row_gain=_row_gain(raw, geo, f_eta, alpha, w_a, band_a, pattern),
        amplitude=np.sqrt(geo.reference_range / grid.range).astype(np.float32))


def _stolt_bands(raw: RawData, geo: StripmapGeometry) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """True Doppler ``f_eta`` of each row, ``alpha = c f_eta / 2Vr`` and the Stolt-mapped band
    ``q = sqrt((f0 -+ B/2)^2 - alpha^2)`` of the row (C&W eq. 8.5); checks it is neither
    evanescent nor wider than ``fs``."""
    f0, bw, fs = raw.fc, raw.bandwidth, raw.fs
    f_eta, alpha = doppler_rows(raw, geo)
    q_lo = np.sqrt((f0 - bw / 2) ** 2 - alpha**2)
    q_hi = np.sqrt((f0 + bw / 2) ** 2 - alpha**2)
    if np.max(q_hi - q_lo) >= fs:
        raise ValueError(f"the Stolt-mapped range band (up to {np.max(q_hi - q_lo):.4g} Hz = B / cos(squint)) "
                         f"exceeds fs = {fs:.4g} Hz: the output would alias; sample faster or reduce the squint")
    return f_eta, alpha, q_lo, q_hi


def _row_gain(raw: RawData, geo: StripmapGeometry, f_eta: np.ndarray, alpha: np.ndarray, w_a: Any, band_a: float,
              pattern: float | None) -> np.ndarray:
    """Azimuth window times the point-target normalisation ``D^1.5 sqrt(2 f0 Vr^2 / (c R_ref)) / B_a``
    of each Doppler row, ``D = sqrt(1 - (alpha / f0)^2)`` (float32)."""
    f0, vel = raw.fc, geo.velocity
    d_eta = np.sqrt(1.0 - (alpha / f0) ** 2)
    return (azimuth_weights(w_a, f_eta, geo.doppler_centroid, band_a, pattern, C / f0, vel, geo.squint)
            * d_eta**1.5 * np.sqrt(2.0 * f0 * vel**2 / (C * geo.reference_range)) / band_a).astype(np.float32)


# ============================================================================ steps 1-4 per block of rows
def _range_focus(raw: RawData, plan: StoltPlan, workers: int) -> np.ndarray:
    """Steps 1-4 up to the azimuth IFFT: 2-D spectrum, then per block of Doppler rows the Stolt
    interpolation, factors and range IFFT; complex64 ``[n_pulses, n_samples]``."""
    n_a = raw.data.shape[0]
    spec = np.empty((n_a, plan.n_pad), np.complex64)
    image = np.empty((n_a, plan.n_r), np.complex64)
    scratch = Scratch()
    blocks = [slice(i, min(i + _BLOCK_ROWS, n_a)) for i in range(0, n_a, _BLOCK_ROWS)]
    with ThreadPoolExecutor(workers) if workers > 1 else _Serial() as pool:
        list(pool.map(lambda rows: _range_fft(raw, plan, spec, rows), blocks))
        _store(spec, scipy.fft.fft(spec, axis=0, overwrite_x=True, workers=workers))  # azimuth FFT
        list(pool.map(lambda rows: _stolt_block(plan, spec, rows, scratch, image), blocks))
    return image


def _range_fft(raw: RawData, plan: StoltPlan, spec: np.ndarray, rows: slice) -> None:
    """Step 1 on a block of rows: centred, deconvolved, zero-padded copy and range FFT, in place;
    ``(-1)^n`` puts ``f_tau = (j - n/2) df`` at column ``j``."""
    block = centred_buffer(raw.data[rows], plan.n_pad, plan.prefilter, out=spec[rows])
    _store(block, scipy.fft.fft(block, axis=1, overwrite_x=True, workers=1))


def _stolt_block(plan: StoltPlan, spec: np.ndarray, rows: slice, scratch: Scratch, image: np.ndarray) -> None:
    """Steps 2-4 on a block of Doppler rows: Stolt interpolation, analytic factors, range IFFT
    into ``image[rows]``."""
    shape = (rows.stop - rows.start, int(plan.n_valid[rows].max()))
    kq, f_tau, pos, gain = _stolt_mapping(plan, rows, shape, scratch)
    values = plan.interp(spec[rows], pos, out=scratch.get("values", shape, np.complex64))
    _apply_factors(plan, rows, values, kq, f_tau, gain, scratch)
    out = _scatter_bins(plan, rows, values, scratch.get("out", (shape[0], plan.n_out), np.complex64))
    out = scipy.fft.ifft(out, axis=1, overwrite_x=True, workers=1)  # column m at grid.range[m]
    np.multiply(out[:, :plan.n_r], plan.amplitude, out=image[rows])


def _stolt_mapping(plan: StoltPlan, rows: slice, shape: tuple[int, int],
                   scratch: Scratch) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Step 2, the Stolt change of variable (C&W eq. 8.5): for output bin ``k`` (``q = k df_out``)
    the input frequency ``f_tau = sqrt(q^2 + alpha^2) - f0``. Returns ``(k, f_tau, position in the
    padded spectrum [bins], Jacobian q / (f0 + f_tau))`` (scratch buffers)."""
    kq = np.add(plan.k0f[rows, None], np.arange(shape[1], dtype=np.float64),
                out=scratch.get("kq", shape, np.float64))  # output bin k, float64
    q = np.multiply(kq, plan.df_out, out=scratch.get("q", shape, np.float64))
    np.minimum(q, plan.q_hi[rows, None], out=q)  # beyond a row's band (discarded below): clamp into it
    f_tau = np.multiply(q, q, out=scratch.get("f_tau", shape, np.float64))
    f_tau += plan.alpha2[rows, None]
    np.sqrt(f_tau, out=f_tau)  # f0 + f_tau = sqrt(q^2 + alpha^2)
    gain = scratch.get("gain", shape, np.float32)
    np.divide(q, f_tau, out=gain)  # Stolt Jacobian q / (f0 + f_tau)
    f_tau -= plan.f0
    pos = np.multiply(f_tau, 1.0 / plan.df, out=q)
    pos += plan.n_pad / 2
    return kq, f_tau, pos, gain


def _apply_factors(plan: StoltPlan, rows: slice, values: np.ndarray, kq: np.ndarray, f_tau: np.ndarray,
                   gain: np.ndarray, scratch: Scratch) -> None:
    """Step 3: reference function and output-range origin ``exp(+j 4 pi R_start q / c)`` (C&W
    eq. 8.3), fast-time origin, range window, Jacobian, azimuth factors; ``kq``, ``f_tau`` and
    ``gain`` are overwritten."""
    gain *= plan.row_gain[rows, None]
    if plan.w_r[0] != "rect":  # (rect: every kept bin lies in |f_tau| <= B/2)
        gain *= unit_mean_window(plan.w_r, f_tau, plan.bw).astype(np.float32)
    kq *= plan.range_cycles_per_bin  # phase in cycles, float64: k df_out 2 R_start / c - f_tau tau_ref + row
    f_tau *= plan.tau_ref
    kq -= f_tau
    kq += plan.row_cycles[rows, None]
    _multiply_cis(values, kq, gain, scratch)


def _scatter_bins(plan: StoltPlan, rows: slice, values: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Step 4 (first half): row ``r``'s output bin ``k`` to FFT column ``k mod n_out`` of ``out``."""
    out[...] = 0
    for i, r in enumerate(range(rows.start, rows.stop)):
        first, count = int(plan.k0[r] % plan.n_out), int(plan.n_valid[r])
        stop = min(first + count, plan.n_out)
        out[i, first:stop] = values[i, :stop - first]
        out[i, :count - (stop - first)] = values[i, stop - first:count]
    return out


def _output_length(raw: RawData, q_lo: np.ndarray, q_hi: np.ndarray, r_start: float) -> int:
    """Range FFT length of the Stolt output (its bins are ``fs / n_out`` apart).

    Data at fast time ``tau`` and Doppler row ``alpha`` focus at the closest-approach range
    ``c tau / 2 * q / sqrt(q^2 + alpha^2)`` (``q`` over the row's band), i.e. at output
    sample ``m = fs (tau q / sqrt(q^2 + alpha^2) - 2 R_start / c)``; the extreme corners
    (first and last fast time, band edges) bound that support. The output must hold it
    without wrapping onto ``[0, n_samples)``, plus ``_guard(n_samples)`` samples over which
    the range sidelobes of edge targets decay before they wrap onto the other edge.
    """
    fs, f0, bw, n_r = raw.fs, raw.fc, raw.bandwidth, raw.n_samples
    # q / sqrt(q^2 + alpha^2) increases with q: its extremes are at the band edges, where sqrt(...) = f0 -+ B/2
    d_lo = np.min(q_lo / (f0 - bw / 2))
    d_hi = np.max(q_hi / (f0 + bw / 2))
    m_min = fs * (raw.fast_time[0] * d_lo - 2.0 * r_start / C)
    m_max = fs * (raw.fast_time[-1] * d_hi - 2.0 * r_start / C)
    need = max(m_max + 1.0, n_r) - min(m_min, 0.0)
    return int(scipy.fft.next_fast_len(int(np.ceil(need)) + _guard(n_r)))


def _guard(n_samples: int) -> int:
    """Range samples of the Stolt output beyond the data's focused support (module docstring)."""
    return max(_GUARD_MIN, n_samples // _GUARD_FRACTION)


class _Serial:
    """Stand-in for a thread pool when ``workers == 1``: maps in the calling thread."""

    def __enter__(self) -> "_Serial":
        return self

    def __exit__(self, *exc: Any) -> None:
        return None

    @staticmethod
    def map(fn: Any, items: Any) -> Any:
        return map(fn, items)


def _store(dest: np.ndarray, result: np.ndarray) -> None:
    """Make ``dest`` hold ``result`` (an in-place FFT's output; copied only if it was not in place)."""
    if not np.may_share_memory(dest, result):
        dest[...] = result


def _multiply_cis(values: np.ndarray, cycles: np.ndarray, gain: np.ndarray, scratch: Scratch) -> None:
    """``values *= gain * exp(j 2 pi cycles)`` in place: ``cycles`` float64 (overwritten),
    reduced modulo 1 in float64 before the float32 cos/sin (phases of 1e8 rad stay exact)."""
    cycles -= np.round(cycles, out=scratch.get("round", cycles.shape, np.float64))
    cycles *= 2.0 * np.pi
    ang = scratch.get("angle", cycles.shape, np.float32)
    np.copyto(ang, cycles, casting="same_kind")
    factor = scratch.get("factor", cycles.shape, np.complex64)
    part = np.cos(ang, out=scratch.get("part", cycles.shape, np.float32))
    part *= gain
    factor.real = part
    np.sin(ang, out=part)
    part *= gain
    factor.imag = part
    values *= factor
