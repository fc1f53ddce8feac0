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
from functools import lru_cache
from dataclasses import dataclass
from typing import Any, NamedTuple, Sequence

import numpy as np
import scipy.fft
import scipy.optimize
import scipy.special

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.raw import RawData
from .fft_contract import (azimuth_weights, cis, doppler_rows, focus_setup, range_compressed, slant_image,
                           unit_mean_window, windows_label)
from .stripmap import StripmapGeometry, check_monostatic, slant_output_grid

__all__ = ["range_doppler", "range_doppler_plan", "RangeDopplerPlan", "AzimuthFilter", "Interpolator"]

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
    GeometryNotSupported
        (a ValueError) Bistatic data, as :func:`sarmitsuba.focus.omega_k`.
    """
    t_start = time.perf_counter()
    tolerance = geometry.tolerance if isinstance(geometry, StripmapGeometry) else C / raw.fc / 16.0
    check_monostatic(raw, "range-Doppler", tolerance)          # before the work: bistatic data are refused
    raw = range_compressed(raw)
    geo, w_r, w_a, workers, band_a = focus_setup(raw, geometry, scene_centre, squint, reference_range,
                                                 window_range, window_azimuth, doppler_bandwidth, workers)
    plan = range_doppler_plan(raw, geo, w_r, w_a, band_a, src, taps, upsample, azimuth_pattern)
    src_mode, grid, filt, interp = plan.src_mode, plan.grid, plan.filter, plan.interp
    rd = _range_doppler_domain(raw, plan, workers)                                          # steps 1-3
    image = _rcmc_and_azimuth_compression(rd, raw, grid, filt, interp, upsample, workers)   # steps 4-5
    del rd
    image = scipy.fft.ifft(image, axis=0, workers=workers, overwrite_x=True).astype(np.complex64, copy=False)  # 6.
    seconds = time.perf_counter() - t_start
    window = windows_label(w_r, w_a)
    focus = {"algorithm": "rda", "window": window, "src": src_mode or "none", "src_range": geo.reference_range,
             "taps": int(taps), "kaiser_beta": interp.beta, "upsample": int(upsample),
             "doppler_bandwidth": band_a, "geometry": geo.to_dict(), "workers": workers, "seconds": seconds,
             "interpolation": "RCMC, Kaiser-windowed sinc", "normalisation": "peak = a over the processed band"}
    return slant_image(raw, grid, image, "rda", window, focus)


def _src_mode(src: bool | str) -> str | None:
    """The SRC option as ``None``, ``"2d"`` or ``"range"``; ValueError for anything else."""
    if isinstance(src, str):
        src = src.strip().lower()
    if src not in _SRC_MODES:
        raise ValueError(f"src must be False, True, 'none', '2d' or 'range', got {src!r}")
    return _SRC_MODES[src]


# ============================================================================ the plan
@dataclass(frozen=True, eq=False)
class RangeDopplerPlan:
    """What :func:`range_doppler` computes before touching the data (shared with its float64
    linear map, :mod:`sarmitsuba.focus.linear`)."""

    src_mode: str | None          # None, "2d" or "range"
    grid: Any                     # the slant output grid
    reference_range: float        # R_src [m]
    alpha: np.ndarray             # [n_pulses] c f_eta / 2Vr [Hz]
    n1: int                       # range FFT length (data plus _GUARD, fast length)
    upsample: int
    f_tau: np.ndarray             # [n1] range frequency of each FFT bin [Hz]
    range_filter: np.ndarray      # complex128 [n1]: step 1's window and SRC option 3
    filter: "AzimuthFilter"       # step 5's factors
    interp: "Interpolator"        # step 4's RCMC kernel

    def src_phase(self, rows: slice, f0: float) -> np.ndarray:
        """SRC option 2's phase [cycles] of Doppler ``rows`` over the range frequencies, float64."""
        return _src_cycles(self.reference_range, self.f_tau[None, :], f0, self.alpha[rows, None])


def range_doppler_plan(raw: RawData, geo: StripmapGeometry, w_r: Any, w_a: Any, band_a: float, src: Any, taps: Any,
                       upsample: Any, azimuth_pattern: float | None) -> RangeDopplerPlan:
    """The :class:`RangeDopplerPlan` of range-compressed ``raw`` with the options
    :func:`~sarmitsuba.focus.fft_contract.focus_setup` checked. Raises ValueError for an unknown
    ``src``, ``upsample`` outside 1..8 or ``taps`` not even in 4..32."""
    src_mode = _src_mode(src)
    if isinstance(upsample, bool) or not isinstance(upsample, (int, np.integer)) or not 1 <= upsample <= 8:
        raise ValueError(f"upsample must be an integer in [1, 8], got {upsample!r}")
    grid = slant_output_grid(geo, raw)
    f_eta, alpha = doppler_rows(raw, geo)
    n1 = int(scipy.fft.next_fast_len(raw.data.shape[1] + _GUARD))
    f_tau = np.fft.fftfreq(n1, 1.0 / raw.fs)
    interp = Interpolator(taps, passband=min(0.95, raw.bandwidth / (raw.fs * upsample)))
    filt = _azimuth_filter(raw, geo, grid, f_eta, alpha, w_r, w_a, band_a, src_mode, azimuth_pattern)
    return RangeDopplerPlan(src_mode, grid, geo.reference_range, alpha, n1, int(upsample), f_tau,
                            _range_filter(raw, geo, w_r, src_mode, f_tau), filt, interp)


# ============================================================================ steps 1-3: to the range-Doppler domain
def _range_doppler_domain(raw: RawData, plan: RangeDopplerPlan, workers: int) -> np.ndarray:
    """Steps 1-3: range FFT, range window and SRC option 3; azimuth FFT and SRC option 2;
    range IFFT upsampled by zero-padding the spectrum. complex64 ``[n_pulses, n1 * upsample]``,
    columns ``fast_time[0] + m / (fs upsample)``."""
    n_a = raw.data.shape[0]
    n1, upsample = plan.n1, plan.upsample
    # ---- 1. range FFT, window, SRC option 3
    spec = scipy.fft.fft(raw.data, n=n1, axis=1, workers=workers)
    spec *= plan.range_filter.astype(np.complex64)
    # ---- 2. azimuth FFT, SRC option 2
    spec = scipy.fft.fft(spec, axis=0, workers=workers, overwrite_x=True)
    if plan.src_mode == "2d":
        for rows in _blocks(n_a):
            spec[rows] *= cis(plan.src_phase(rows, raw.fc))
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
    return rd


def _range_filter(raw: RawData, geo: StripmapGeometry, w_r: Any, src_mode: str | None,
                  f_tau: np.ndarray) -> np.ndarray:
    """Step 1's range-frequency filter (complex128 like ``f_tau`` [Hz]): the range window at unit
    mean, times the SRC filter at the Doppler centroid for option 3 (C&W section 6.2.3)."""
    range_filter = unit_mean_window(w_r, f_tau, raw.bandwidth).astype(np.complex128)
    if src_mode == "range":
        a_c = C * geo.doppler_centroid / (2.0 * geo.velocity)
        range_filter *= cis(_src_cycles(geo.reference_range, f_tau, raw.fc, a_c))
    return range_filter


# ============================================================================ steps 4-5: RCMC and azimuth compression
class AzimuthFilter(NamedTuple):
    """Factors of step 5 (float64 per Doppler row or per output range gate unless stated)."""

    q0: np.ndarray          # [n_pulses] Q(0, f_eta) = f0 D(f_eta) [Hz]
    d_eta: np.ndarray       # [n_pulses] D(f_eta), the migration factor
    residual: np.ndarray    # [n_pulses] band-mean coupling left after SRC [Hz]
    row_cycles: np.ndarray  # [n_pulses] reference-range and azimuth-origin phase [cycles]
    row_gain: np.ndarray    # [n_pulses] azimuth window and amplitude normalisation
    d_r: np.ndarray         # [n_samples] R - R_src [m]
    col_cycles: np.ndarray  # [n_samples] 2 f0 (R - R_src) / c [cycles]
    col_gain: np.ndarray    # float32 [n_samples] 1 / sqrt(R)


def _azimuth_filter(raw: RawData, geo: StripmapGeometry, grid: Any, f_eta: np.ndarray, alpha: np.ndarray, w_r: Any,
                    w_a: Any, band_a: float, src_mode: str | None, pattern: float | None) -> AzimuthFilter:
    """Step 5's azimuth matched filter ``exp(+j 4 pi R f0 D(f_eta) / c)`` (C&W eq. 6.26), split into
    row and column factors, with the azimuth window, normalisation and SRC residual."""
    f0, bw, vel, r_src = raw.fc, raw.bandwidth, geo.velocity, geo.reference_range
    q0 = np.sqrt(f0**2 - alpha**2)  # Q(0, f_eta) = f0 D(f_eta)
    d_r = grid.range - r_src
    col_cycles = 2.0 * f0 * d_r / C  # float64 [n_r]: 2 R f0 D / c = 2 (R_src + d) (f0 + (Q0 - f0)) / c
    row_cycles = (2.0 * r_src * q0 / C + f_eta * (grid.azimuth[0] - geo.pulse_azimuth[0]) / vel + 0.125)
    d_eta = q0 / f0
    residual, applied = _src_residual(w_r, bw, f0, alpha, src_mode, C * geo.doppler_centroid / (2.0 * vel))
    row_cycles += 2.0 * r_src * (residual - applied) / C
    row_gain = (azimuth_weights(w_a, f_eta, geo.doppler_centroid, band_a, pattern, C / f0, vel, geo.squint)
                * d_eta**1.5 * np.sqrt(2.0 * f0 * vel**2 / C) / band_a)
    col_gain = (1.0 / np.sqrt(grid.range)).astype(np.float32)
    return AzimuthFilter(q0, d_eta, residual, row_cycles, row_gain, d_r, col_cycles, col_gain)


def _src_residual(w_r: Any, bw: float, f0: float, alpha: np.ndarray, src_mode: str | None,
                  alpha_centroid: float) -> tuple[np.ndarray, np.ndarray]:
    """Band-mean coupling per Doppler row [Hz] a target at ``R`` keeps as ``(R - R_src) x coupling``
    (SRC is exact at ``R_src`` only), and the part of it SRC applied (the centroid's for option 3).
    Removing the mean per range gate keeps it from biasing the peak phase; the zero-mean rest
    only broadens, by far less (module docstring). Zeros without SRC."""
    n_a = alpha.shape[0]
    residual = _mean_coupling(w_r, bw, f0, alpha) if src_mode is not None else np.zeros(n_a)
    if src_mode == "range":
        return residual, np.full(n_a, _mean_coupling(w_r, bw, f0, np.array([alpha_centroid]))[0])
    return residual, residual


def _rcmc_and_azimuth_compression(rd: np.ndarray, raw: RawData, grid: Any, filt: AzimuthFilter,
                                  interp: "Interpolator", upsample: int, workers: int) -> np.ndarray:
    """Steps 4-5 per block of Doppler rows: RCMC (output gate ``R`` reads ``R / D(f_eta)``, C&W
    eq. 6.23) and the azimuth matched filter; complex64 ``[n_pulses, n_samples]`` (range-Doppler)."""
    n_a, n_r = raw.data.shape
    f0, fine_rate, t0 = raw.fc, raw.fs * upsample, float(raw.fast_time[0])
    image = np.empty((n_a, n_r), np.complex64)

    def run_block(rows: slice) -> None:
        pos = (2.0 * grid.range[None, :] / (C * filt.d_eta[rows, None]) - t0) * fine_rate
        values = interp(rd[rows], pos)
        cycles = (filt.row_cycles[rows, None] + filt.col_cycles[None, :]
                  + 2.0 * filt.d_r[None, :] * (filt.q0[rows, None] - f0 + filt.residual[rows, None]) / C)
        values *= cis(cycles)
        values *= (filt.row_gain[rows, None] * filt.col_gain[None, :]).astype(np.float32)
        image[rows] = values

    blocks = _blocks(n_a)
    if workers > 1:
        with ThreadPoolExecutor(workers) as pool:
            list(pool.map(run_block, blocks))
    else:
        for block in blocks:
            run_block(block)
    return image


def _blocks(n: int) -> list[slice]:
    return [slice(i, min(i + _BLOCK_ROWS, n)) for i in range(0, n, _BLOCK_ROWS)]


def _mean_coupling(w_r: tuple[str, dict[str, float]], bw: float, f0: float, alpha: np.ndarray) -> np.ndarray:
    """Band mean [Hz] of the coupling ``Q - Q(0) - f f0 / Q(0)`` per Doppler row, weighted by the range window."""
    f = (np.arange(513) / 512 - 0.5) * bw
    w = unit_mean_window(w_r, f, bw)
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


# ============================================================================ interpolation kernel
#: Fractional positions tabulated per tap (nearest entry; weight error <= pi / (2 * 4096)).
_TABLE_BINS = 4096


@lru_cache(maxsize=16)
def _kaiser_beta(taps: int, passband: float) -> float:
    """Kaiser beta minimising the worst-case interpolation error over ``|omega| <= passband pi``."""
    def err(beta: float) -> float:
        h, d = _sinc_table(taps, beta, 64)
        om = np.linspace(0.0, passband * np.pi, 96)
        r = np.einsum("mt,wmt->wm", h, np.exp(-1j * om[:, None, None] * d[None]))
        return float(np.abs(r - 1.0).max())
    res = scipy.optimize.minimize_scalar(err, bounds=(0.0, 2.0 * taps), method="bounded", options={"xatol": 1e-3})
    return float(res.x)


def _sinc_table(taps: int, beta: float, bins: int) -> tuple[np.ndarray, np.ndarray]:
    """Kaiser-windowed sinc weights [bins + 1, taps] at fractions ``b / bins``, each row
    normalised to unit sum (exact DC gain), and the tap distances ``d = mu + taps/2 - 1 - t``."""
    half = taps // 2
    mu = np.arange(bins + 1, dtype=np.float64) / bins
    d = mu[:, None] + (half - 1) - np.arange(taps)[None, :]
    w = scipy.special.i0(beta * np.sqrt(np.clip(1.0 - (d / half) ** 2, 0.0, None))) / scipy.special.i0(beta)
    h = np.sinc(d) * w
    return h / h.sum(axis=1, keepdims=True), d


class Interpolator:
    """Windowed-sinc interpolation of complex rows at fractional positions, vectorised.

    ``taps`` (even, 4..32) Kaiser-windowed sinc weights, Kaiser beta chosen for the
    worst-case error over the band ``|omega| <= passband * pi`` (fraction of Nyquist
    occupied by the signal), tabulated at 4096 fractions. Samples outside the row are
    zero. Cost per output sample: ``taps`` gathers and multiply-adds on float32 pairs,
    run as ``taps`` vectorised passes over a block of rows (never a Python loop over
    samples).
    """

    def __init__(self, taps: int, passband: float):
        if isinstance(taps, bool) or not isinstance(taps, (int, np.integer)) or taps % 2 or not 4 <= taps <= 32:
            raise ValueError(f"interpolation taps must be an even integer in [4, 32], got {taps!r}")
        self.taps = int(taps)
        self.passband = float(passband)
        self.beta = _kaiser_beta(self.taps, round(self.passband, 3))
        h, _ = _sinc_table(self.taps, self.beta, _TABLE_BINS)
        self.table = np.ascontiguousarray(h.T.astype(np.float32))  # [taps, bins + 1]

    def weights(self, frac: np.ndarray) -> np.ndarray:
        """The kernel's exact weights (untabulated) at fractional positions ``frac`` float64
        [...] in [0, 1): float64 [taps, ...], tap ``t`` at sample ``floor(pos) - (taps/2 - 1) + t``,
        each position's weights summing to 1 (as the table's rows)."""
        half = self.taps // 2
        d = frac[None] + (half - 1) - np.arange(self.taps).reshape((-1,) + (1,) * np.ndim(frac))
        w = np.sinc(d) * scipy.special.i0(self.beta * np.sqrt(np.clip(1.0 - (d / half) ** 2, 0.0, None)))
        return w / w.sum(axis=0, keepdims=True)

    def __call__(self, rows: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """Interpolate ``rows`` (complex64 [R, N]) at ``pos`` (float [R, M], sample units)."""
        n_rows, n = rows.shape
        taps, half = self.taps, self.taps // 2
        width = n + 2 * taps
        padded = np.zeros((n_rows, width), np.complex64)
        padded[:, taps:taps + n] = rows
        flat = padded.reshape(-1)
        whole = np.floor(pos)
        frac = pos - whole
        first = whole.astype(np.int64) - (half - 1) + taps  # padded index of tap 0
        outside = (first < 0) | (first > width - taps)
        np.clip(first, 0, width - taps, out=first)
        first += (np.arange(n_rows, dtype=np.int64) * width)[:, None]
        if flat.size < 2**31:
            first = first.astype(np.int32)
        bins = np.rint(frac * _TABLE_BINS).astype(np.int32)
        out = np.zeros(pos.shape + (2,), np.float32)
        value = np.empty(pos.shape, np.complex64)
        weight = np.empty(pos.shape, np.float32)
        for t in range(taps):
            np.take(flat[t:], first, out=value, mode="clip")
            np.take(self.table[t], bins, out=weight)
            pair = value.view(np.float32).reshape(pos.shape + (2,))
            pair *= weight[..., None]
            out += pair
        result = out.view(np.complex64).reshape(pos.shape)
        result[outside] = 0
        return result
