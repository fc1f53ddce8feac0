"""Which range lines phase gradient autofocus may learn from (docs/physics.md (PGA3), (PGA4)), and
what bounds the linear part of the phase error it leaves (docs/physics.md (PGA5)).

PGA assumes that each range line it uses holds one point-like scatterer that outshines its
clutter (Wahl et al. 1994, section II). :func:`signal_pixels` finds the pixels that hold signal
(the clutter background of (PGA3)); :func:`point_likeness` measures, per range line, how far its
brightest sample stands above that background and how much of the line's energy lies close to it;
:func:`point_lines` keeps the lines that are point-like by both measures: clutter, the rims of a
plate and the double bounce of a wall spread their energy along the line and are rejected.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..core.image import SarImage, image_coordinates
from ..core.valid_ranges import ParameterError

__all__ = ["signal_pixels", "point_likeness", "point_lines", "linear_shift_bound", "upsample", "reference_azimuth",
           "reference_shift", "shift_phase", "REFERENCE_SEARCH", "REFERENCE_UPSAMPLE",
           "SIGNAL_BOX", "SIGNAL_DB", "SIGNAL_PERCENTILE", "POINT_DB", "POINT_SHARE", "POINT_EXTENT"]

#: (PGA3)'s background: pixels whose local mean intensity over this many pixels square lies within
#: :data:`SIGNAL_DB` of the :data:`SIGNAL_PERCENTILE` th percentile of the local means. 9 x 9
#: pixels average 81 speckle samples (the local mean of clutter within about 0.5 dB); empty parts
#: of a rendered image lie 20 to 40 dB below its clutter (their sidelobes). 10 dB refused a
#: defocused group of trihedrals without clutter (18.7 dB, tests/test_pga_phase.py), 25 dB kept
#: too much of the empty part (23.3 dB on the clutter of tests/test_pga_guard.py).
SIGNAL_BOX = 9
SIGNAL_DB = 20.0
SIGNAL_PERCENTILE = 90.0
#: (PGA4): a range line is point-like when its brightest sample stands at least :data:`POINT_DB`
#: above the median intensity of the image's signal pixels and at least :data:`POINT_SHARE` of its
#: energy over its lit samples lies within :data:`POINT_EXTENT` of its lit extent about that
#: sample. Measured on the nominal-track images of docs/physics.md (PGA4)'s table: the lines of a
#: defocused trihedral that reach 20 dB hold 0.65 to 0.91; those of walls on ground 0.29 to 0.46;
#: lines below 20 dB reach 0.78 (speckle, rims), which is why both tests are needed.
POINT_DB = 20.0
POINT_SHARE = 0.5
POINT_EXTENT = 0.25
#: Lines with fewer lit samples than this carry no point-likeness (too short to judge).
MIN_LIT = 10


def signal_pixels(intensity: np.ndarray) -> np.ndarray:
    """bool, the shape of ``intensity`` (float64 [n_az, n_rg], ``|I|^2``): the pixels that hold signal
    (eq. (PGA3)): local mean intensity (a :data:`SIGNAL_BOX` boxcar, scipy.ndimage.uniform_filter)
    within :data:`SIGNAL_DB` of the :data:`SIGNAL_PERCENTILE` th percentile of the local means,
    and non-zero. An image of clutter everywhere keeps every pixel."""
    from scipy.ndimage import uniform_filter
    local = uniform_filter(intensity, size=SIGNAL_BOX, mode="nearest")
    level = np.percentile(local, SIGNAL_PERCENTILE)
    return (local >= level * 10.0 ** (-SIGNAL_DB / 10.0)) & (intensity > 0)


def point_likeness(intensity: np.ndarray, signal: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per range line, eq. (PGA4): the share of its energy near its brightest sample and how far
    that sample stands above the image's clutter.

    Parameters
    ----------
    intensity : float64 [n_az, n_rg]
        ``|I|^2`` of the image PGA works on (deramped, eq. (PGA2)); azimuth along axis 0.
    signal : bool [n_az, n_rg], optional
        The pixels that hold signal; default :func:`signal_pixels` of ``intensity``.

    Returns
    -------
    share : float64 [n_rg]
        Energy of the line within ``POINT_EXTENT * lit / 2`` samples (circularly) of its brightest
        sample over its energy on its lit samples (``lit`` of them, those of ``signal``); NaN for
        lines with fewer than :data:`MIN_LIT` lit samples. Clutter filling the lit extent gives
        about :data:`POINT_EXTENT` plus the speckle of the window's contents.
    level_db : float64 [n_rg], dB
        The line's brightest sample over the median intensity of all signal pixels (eq. (PGA3)'s
        background); -inf where the image holds no signal.
    """
    intensity = np.asarray(intensity, dtype=np.float64)
    if signal is None:
        signal = signal_pixels(intensity)
    n, m = intensity.shape
    peak_row = np.argmax(intensity, axis=0)
    lit = signal.sum(axis=0)
    distance = np.abs(np.arange(n)[:, None] - peak_row[None, :])
    distance = np.minimum(distance, n - distance)
    near = distance <= np.maximum(1, (POINT_EXTENT * lit / 2.0).astype(int))[None, :]
    lit_energy = np.sum(np.where(signal, intensity, 0.0), axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(lit >= MIN_LIT, np.sum(np.where(near, intensity, 0.0), axis=0) / lit_energy, np.nan)
        background = np.median(intensity[signal]) if signal.any() else 0.0
        level_db = 10.0 * np.log10(intensity[peak_row, np.arange(m)] / background) if background > 0 \
            else np.full(m, -np.inf)
    return share, level_db


def point_lines(intensity: np.ndarray, signal: np.ndarray | None = None) -> np.ndarray:
    """int [k]: indices of the range lines that are point-like (eq. (PGA4)): ``level_db >=``
    :data:`POINT_DB` and ``share >=`` :data:`POINT_SHARE` (:func:`point_likeness`), ascending."""
    share, level_db = point_likeness(intensity, signal)
    return np.flatnonzero((level_db >= POINT_DB) & (np.nan_to_num(share, nan=0.0) >= POINT_SHARE))


def linear_shift_bound(ground_range: float, max_slope: float) -> float:
    """The largest along-track shift [m] that the linear part of a motion error leaves in a PGA
    image (eq. (PGA5)): ``ground_range * max_slope``.

    ``ground_range`` [m] is the horizontal distance from the track to the scene (``R0 sin theta``),
    ``max_slope`` the largest slope ``|de/ds|`` of the horizontal cross-track deviation along the
    track (``2 pi A / P`` for a sinusoid of amplitude ``A`` and period ``P``). Raises ValueError for
    a negative or non-finite argument."""
    if not (np.isfinite(ground_range) and np.isfinite(max_slope) and ground_range >= 0 and max_slope >= 0):
        raise ValueError(f"ground_range and max_slope must be finite and >= 0, got {ground_range!r}, {max_slope!r}")
    return float(ground_range * max_slope)


def upsample(data: np.ndarray, factor: int) -> np.ndarray:
    """``data`` [n, m] FFT-interpolated ``factor`` times along axis 0 (rows ``i * factor`` keep their
    values): the spectrum is cut at its weakest bin, so a band about any centre stays whole."""
    if factor == 1:
        return data.astype(np.complex128)
    n = data.shape[0]
    spectrum = np.fft.fft(data.astype(np.complex128), axis=0)
    cut = int(np.argmin(np.sum(np.abs(spectrum) ** 2, axis=1)))
    bins = (cut + 1 + np.arange(n)) % n                          # the band, contiguous, after the cut
    signed = cut + 1 + np.arange(n)
    signed -= n * int(np.round((signed[0] + signed[-1]) / (2.0 * n)))
    out = np.zeros((n * factor, data.shape[1]), complex)
    out[signed % (n * factor)] = spectrum[bins] * factor
    return np.fft.ifft(out, axis=0)


#: The reference point is looked for within this fraction of the image's azimuth extent of where
#: it should appear (the linear part's shift, eq. (PGA5), is a few metres on airborne tracks).
REFERENCE_SEARCH = 0.25
#: Upsampling of the column through the reference point that locates its peak (then a parabola).
REFERENCE_UPSAMPLE = 16


def reference_azimuth(image: SarImage, reference: Any) -> tuple[float, tuple[float, ...], float] | None:
    """``(azimuth, world point, range)`` [m] where the ``reference`` point should appear
    (:func:`~sarmitsuba.core.image.image_coordinates`), or None without one; checked first."""
    if reference is None:
        return None
    point = np.asarray(reference, dtype=np.float64).reshape(-1) if np.ndim(reference) else np.zeros(0)
    if point.size != 3 or not np.all(np.isfinite(point)):
        raise ParameterError(f"reference must be the world position (x, y, z) in metres of a known point-like "
                             f"scatterer in the image, 3 finite numbers; got {reference!r}")
    azimuth, ground = image_coordinates(image, point)
    a_lo, a_hi = float(np.min(image.azimuth)), float(np.max(image.azimuth))
    r_lo, r_hi = float(np.min(image.range)), float(np.max(image.range))
    if not (a_lo <= azimuth <= a_hi and r_lo <= ground <= r_hi):
        raise ParameterError(f"reference ({', '.join(f'{v:g}' for v in point)}) appears at azimuth {azimuth:.2f} m, range {ground:.2f} m, "
                             f"outside the image (azimuth {a_lo:.2f} .. {a_hi:.2f} m, range {r_lo:.2f} .. "
                             f"{r_hi:.2f} m): give a point inside the image, or leave reference out")
    return azimuth, tuple(float(v) for v in point), ground


def reference_shift(data: np.ndarray, image: SarImage, step: float, target: tuple) -> float:
    """Along-track distance [m] from where the reference point should appear to its peak in the
    corrected image ``data`` [n_rows, n_rg] (rows ``step`` apart from ``image.azimuth[0]``): the
    brightest pixel within :data:`REFERENCE_SEARCH` of the image's extent and one column of the
    point, refined on the column upsampled :data:`REFERENCE_UPSAMPLE` times and a parabola
    through the log intensity of the three samples about its peak (eq. (PGA5))."""
    azimuth, _, ground = target
    rows = image.azimuth[0] + step * np.arange(data.shape[0])
    col = int(np.argmin(np.abs(image.range - ground)))
    cols = np.arange(max(col - 1, 0), min(col + 2, data.shape[1]))
    near = np.abs(rows - azimuth) <= REFERENCE_SEARCH * abs(step) * data.shape[0]
    patch = np.where(near[:, None], np.abs(data[:, cols]), -1.0)
    row, c = np.unravel_index(int(np.argmax(patch)), patch.shape)
    fine = np.abs(upsample(data[:, cols[c]:cols[c] + 1], REFERENCE_UPSAMPLE)[:, 0]) ** 2
    n = fine.size
    around = (REFERENCE_UPSAMPLE * row + np.arange(-REFERENCE_UPSAMPLE, REFERENCE_UPSAMPLE + 1)) % n
    peak = int(around[np.argmax(fine[around])])
    left, mid, right = np.log(np.maximum(fine[[(peak - 1) % n, peak, (peak + 1) % n]], 1e-300))
    curvature = left - 2.0 * mid + right
    offset = 0.5 * (left - right) / curvature if curvature < 0 else 0.0
    found = image.azimuth[0] + step / REFERENCE_UPSAMPLE * (peak + offset)
    return float(found - azimuth)


def shift_phase(n: int, step: float, shift: float) -> np.ndarray:
    """The linear phase [rad, centred order] whose removal (:func:`_apply`) moves the image by
    ``-shift`` metres along its rows (``step`` [m] apart): ``-2 pi f shift``, ``f`` in cycles per metre."""
    return -2.0 * np.pi * np.fft.fftshift(np.fft.fftfreq(n, d=step)) * shift
