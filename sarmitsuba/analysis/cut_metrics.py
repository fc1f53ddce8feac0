"""Measurements on a band-limited point-target chip: the peak and 1-D cuts through it.

Steps 4 and 5 of the point-target procedure of :mod:`sarmitsuba.analysis.point_target` (ISCE3
``point_target_info``): refine the peak of the chip's band-limited interpolant
(:class:`sarmitsuba.signal.bandlimited.Interpolant2D`), then sample a cut through the peak along each
image axis every ``1 / oversample`` pixel and read its -3 dB width (IRW), first nulls (null
search), PSLR and null-bounded ISLR. The definitions are those of :mod:`sarmitsuba.analysis.point_target`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.optimize

from ..signal.bandlimited import Interpolant2D

__all__ = ["refine_peak", "CutMetrics", "first_null", "cut_metrics", "measure_cut"]


def refine_peak(interp: Interpolant2D, u: float, v: float, step: float) -> tuple[float, float]:
    """Peak of ``|interp|^2`` [fractional pixels, chip-local] refined from a grid maximum ``(u, v)``.

    Alternating parabolic vertex fits of the log-power along each axis, at steps ``step``,
    ``step / 8``, ``step / 64``, ``step / 512`` (pixels; two sweeps each); each vertex move is
    limited to one step, and a non-concave fit does not move. Returns ``(u, v)`` as floats.
    """
    for h in (step, step / 8.0, step / 64.0, step / 512.0):
        for _ in range(2):
            for axis in (0, 1):
                offsets = np.array([-h, 0.0, h])
                if axis == 0:
                    values = np.abs(interp(u + offsets, v)[:, 0]) ** 2
                else:
                    values = np.abs(interp(u, v + offsets)[0, :]) ** 2
                y0, y1, y2 = np.log(np.maximum(values, 1e-300))
                curvature = y0 - 2.0 * y1 + y2
                shift = 0.5 * (y0 - y2) / curvature * h if curvature < 0 else 0.0
                shift = float(np.clip(shift, -h, h))
                if axis == 0:
                    u += shift
                else:
                    v += shift
    return float(u), float(v)


@dataclass(frozen=True)
class CutMetrics:
    """Impulse-response metrics of one cut through the peak (:func:`cut_metrics`).

    Attributes
    ----------
    irw : float, pixels
        -3 dB width of ``|I|^2``.
    null : float, pixels
        Mean distance from the peak to the first nulls either side.
    pslr_db, islr_db : float, dB
        Peak and integrated (null-bounded) sidelobe ratios; ``-inf`` without sidelobe energy.
    extent : float
        Sidelobe extent actually integrated, in first-null distances (smaller than the
        requested ``sidelobes`` when the chip edge came first).
    """

    irw: float
    null: float
    pslr_db: float
    islr_db: float
    extent: float


def first_null(power: np.ndarray, k0: int, step: int) -> int:
    """Index of the first local minimum of ``power`` (float [n]) walking from ``k0`` by ``step`` (+-1).

    Raises ValueError when the walk reaches the end of the cut before a minimum.
    """
    k = k0
    n = power.size
    while 0 <= k + step < n and power[k + step] <= power[k]:
        k += step
    if k + step < 0 or k + step >= n:
        raise ValueError("no null found in a cut through the peak before the chip edge: the target is not "
                         "resolved in this chip (increase chip or check the focus)")
    return k


def _half_power_width(power: np.ndarray, k0: int, left: int, right: int, ov: int,
                      half_power_root: Callable[[int, int], float]) -> float:
    """IRW [pixels]: the -3 dB points bracketed between samples, refined by ``half_power_root``."""
    half = power[k0] / 2.0
    lo = k0
    while power[lo - 1] > half:
        lo -= 1
        if lo <= left:
            raise ValueError("the -3 dB point lies beyond the first null: not a point-target response")
    hi = k0
    while power[hi + 1] > half:
        hi += 1
        if hi >= right:
            raise ValueError("the -3 dB point lies beyond the first null: not a point-target response")
    x_lo = half_power_root(lo - 1, lo)
    x_hi = half_power_root(hi, hi + 1)
    return (x_hi - x_lo) / ov


def _sidelobe_ratios(power: np.ndarray, k0: int, left: int, right: int,
                     sidelobes: float) -> tuple[float, float, float]:
    """(PSLR [dB], ISLR [dB], extent): sidelobes from the first nulls out to ``sidelobes`` null
    distances beyond them, or to the cut's end; mainlobe between the nulls."""
    span_l = (k0 - left) * sidelobes
    span_r = (right - k0) * sidelobes
    side_lo = max(0, int(round(left - span_l)))
    side_hi = min(power.size - 1, int(round(right + span_r)))
    extent = min((left - side_lo) / max(k0 - left, 1), (side_hi - right) / max(right - k0, 1))
    main = power[left:right + 1].sum()
    side = power[side_lo:left].sum() + power[right + 1:side_hi + 1].sum()
    side_max = max(power[side_lo:left].max(initial=0.0), power[right + 1:side_hi + 1].max(initial=0.0))
    with np.errstate(divide="ignore"):
        pslr = 10.0 * np.log10(side_max / power[k0]) if side_max > 0 else -np.inf
        islr = 10.0 * np.log10(side / main) if side > 0 else -np.inf
    return float(pslr), float(islr), float(extent)


def cut_metrics(profile: np.ndarray, k0: int, ov: int, sidelobes: float,
                half_power_root: Callable[[int, int], float]) -> CutMetrics:
    """IRW, first nulls, PSLR and ISLR of a cut sampled every ``1 / ov`` pixel.

    Parameters
    ----------
    profile : complex or float [n]
        The cut, with the peak at sample ``k0``.
    k0 : int
        Index of the peak sample.
    ov : int
        Samples per pixel.
    sidelobes : float
        Sidelobe extent beyond each first null, in first-null distances.
    half_power_root : callable (k1, k2) -> float
        The fractional sample index in ``[k1, k2]`` where the exact power crosses half the peak.

    Raises
    ------
    ValueError
        When a first null or a -3 dB point is not found inside the cut.
    """
    power = np.abs(profile) ** 2
    left = first_null(power, k0, -1)
    right = first_null(power, k0, +1)
    null = 0.5 * (right - left) / ov
    irw = _half_power_width(power, k0, left, right, ov, half_power_root)
    pslr, islr, extent = _sidelobe_ratios(power, k0, left, right, sidelobes)
    return CutMetrics(irw=irw, null=null, pslr_db=pslr, islr_db=islr, extent=extent)


def measure_cut(interp: Interpolant2D, axis: int, centre: float, other: float, peak: complex,
                chip: int, ov: int, sidelobes: float) -> CutMetrics:
    """:func:`cut_metrics` of the cut through the peak along ``axis`` (0 azimuth, 1 range).

    The cut samples the chip interpolant at ``centre + k / ov`` pixels (the peak exactly a
    sample) across the whole ``chip``-pixel chip, at ``other`` on the other axis; the -3 dB
    points are refined on the interpolant itself (Brent's method, ``xtol`` 1e-9 samples).
    ``peak`` is the complex value at the peak. Lengths in the result are in pixels.
    """
    k_lo = -int(np.floor(centre * ov))
    k_hi = int(np.floor((chip - 1 - centre) * ov))
    pos = centre + np.arange(k_lo, k_hi + 1) / ov
    prof = interp(pos, other)[:, 0] if axis == 0 else interp(other, pos)[0, :]

    def along(x: float) -> float:
        """Power minus half the peak power at fractional cut sample ``x``."""
        t = centre + (x + k_lo) / ov
        val = interp(t, other)[0, 0] if axis == 0 else interp(other, t)[0, 0]
        return abs(val) ** 2 - abs(peak) ** 2 / 2.0

    def root(k1: int, k2: int) -> float:
        """The half-power crossing between samples ``k1`` and ``k2``."""
        return scipy.optimize.brentq(along, k1, k2, xtol=1e-9)

    return cut_metrics(prof, -k_lo, ov, sidelobes, root)
