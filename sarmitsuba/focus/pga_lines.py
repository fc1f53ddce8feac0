"""Which range lines phase gradient autofocus may learn from (docs/physics.md (PGA3), (PGA4)), and
what bounds the linear part of the phase error it leaves (docs/physics.md (PGA5)).

PGA assumes that each range line it uses holds one point-like scatterer that outshines its
clutter (Wahl et al. 1994, section II). :func:`signal_pixels` finds the pixels that hold signal
(the clutter background of (PGA3)); :func:`line_levels` measures how far each line's brightest
sample stands above that background, and :func:`band_occupancy` how much of the beam's Doppler band
the response about it fills. A point fills the band however far a phase error smears it (the
error moves its energy about and leaves its spectrum's magnitude alone); the double bounce of a
wall or the rim of a plate is extended along the line, and its spectrum is as narrow as it is long.
:func:`point_lines` keeps the lines that are point-like by both measures.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage, image_coordinates
from ..core.valid_ranges import ParameterError

__all__ = ["signal_pixels", "dominance_db", "line_levels", "point_likeness", "doppler_band", "band_occupancy", "point_lines",
           "linear_shift_bound",
           "upsample", "reference_azimuth", "reference_shift", "shift_phase", "REFERENCE_SEARCH", "REFERENCE_UPSAMPLE",
           "SIGNAL_BOX", "SIGNAL_DB", "SIGNAL_PERCENTILE", "POINT_DB", "POINT_BAND", "RESPONSE_DB", "BAND_DB",
           "POINT_SHARE", "POINT_EXTENT", "smeared_lines", "SMEAR_WINDOWS", "SMEAR_SIGMAS"]

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
#: above the median intensity of the image's signal pixels and the response about it fills at least
#: :data:`POINT_BAND` of the beam's Doppler band (:func:`band_occupancy`: the response is the
#: contiguous run of samples within :data:`RESPONSE_DB` of that sample; a spectral sample counts
#: when it lies within :data:`BAND_DB` of the spectrum's peak). Measured on nominal-track images
#: (docs/physics.md (PGA4)): trihedrals, focused or smeared by sways of 0.5 to 5 cm, 0.49 to 1; the
#: double bounce of PEC walls 20 m long 0.28 and 0.35, of the urban scene's buildings 0.16 to 0.30.
POINT_DB = 20.0
POINT_BAND = 0.45
RESPONSE_DB = 20.0
BAND_DB = 20.0


#: Without the beam's band (an image whose metadata do not give it), (PGA4) judges a line by how
#: its energy gathers instead: at least :data:`POINT_SHARE` of its energy over its lit samples lies
#: within :data:`POINT_EXTENT` of its lit extent about its brightest sample (:func:`point_likeness`).
#: Measured on the nominal-track images of docs/physics.md (PGA4)'s table: the lines of a defocused
#: trihedral that reach 20 dB hold 0.65 to 0.91; those of walls on ground 0.29 to 0.46. It refuses a
#: point smeared over most of the image, which the band does not.
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


def dominance_db(intensity: np.ndarray, signal: np.ndarray | None = None) -> float:
    """[dB] The brightest pixel's intensity over the median intensity of the pixels that hold signal
    (``signal``, :func:`signal_pixels` of ``intensity`` float64 [n_az, n_rg] by default), eq.
    (PGA3)'s ``D``; -inf for an image without signal. Empty parts of the image (beyond the scene,
    in shadow, outside every beam), which only sidelobes reach, are not clutter and do not pull the
    median down."""
    intensity = np.asarray(intensity, dtype=np.float64)
    if signal is None:
        signal = signal_pixels(intensity)
    if not signal.any():
        return float("-inf")
    return float(10.0 * np.log10(intensity.max() / np.median(intensity[signal])))


def line_levels(intensity: np.ndarray, signal: np.ndarray | None = None) -> np.ndarray:
    """float64 [n_rg], dB: every range line's brightest sample over the median intensity of the
    image's signal pixels (eq. (PGA3)'s background; :func:`signal_pixels` of ``intensity`` [n_az,
    n_rg], azimuth along axis 0, by default); -inf where the image holds no signal."""
    intensity = np.asarray(intensity, dtype=np.float64)
    if signal is None:
        signal = signal_pixels(intensity)
    background = np.median(intensity[signal]) if signal.any() else 0.0
    if not background > 0:
        return np.full(intensity.shape[1], -np.inf)
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(intensity.max(axis=0) / background)


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


def doppler_band(image: SarImage) -> np.ndarray | None:
    """bool [n_az]: the samples of the azimuth spectrum (``numpy.fft.fftfreq`` order) within the
    beam's one-way 3 dB Doppler band, ``|f - f_c| <= 2 sin(theta / 2) / lambda`` cycles per metre
    (``theta`` = ``metadata["radar"]["azimuth_beamwidth"]``, ``lambda`` from ``fc``; ``f_c`` the
    power-weighted circular mean frequency of the image, the Doppler centroid); None where the
    metadata do not give the beamwidth and carrier."""
    meta = image.metadata if isinstance(image.metadata, dict) else {}
    radar, focus = meta.get("radar") or {}, meta.get("focus") or {}
    fc, theta = focus.get("fc") or radar.get("frequency"), radar.get("azimuth_beamwidth")
    if not (fc and theta) or image.azimuth.size < 2:
        return None
    n = image.data.shape[0]
    f = np.fft.fftfreq(n, d=float(np.median(np.abs(np.diff(image.azimuth)))))
    power = np.sum(np.abs(np.fft.fft(np.asarray(image.data), axis=0)) ** 2, axis=1)
    turn = np.sum(power * np.exp(2j * np.pi * np.arange(n) / n))
    centre = f[int(np.round(np.angle(turn) * n / (2.0 * np.pi))) % n]
    half = 2.0 * np.sin(np.radians(float(theta)) / 2.0) * float(fc) / SPEED_OF_LIGHT
    offset = (f - centre + 0.5 * n * abs(f[1])) % (n * abs(f[1])) - 0.5 * n * abs(f[1])   # circular
    return np.abs(offset) <= half


def band_occupancy(data: np.ndarray, band: np.ndarray | None) -> np.ndarray:
    """float64 [n_rg]: per range line of ``data`` (complex [n_az, n_rg], the image as focused, not
    deramped), the share of the ``band`` (:func:`doppler_band`) in which the spectrum of its
    response lies within :data:`BAND_DB` of that spectrum's peak (eq. (PGA4)). The response is the
    contiguous run of samples within :data:`RESPONSE_DB` of the line's brightest sample (the image
    does not wrap). A point, focused or defocused, gives 0.5 to 1; a scatterer extended along the
    line over ``l`` metres a few times ``1 / l`` over the band's width. NaN everywhere without a band."""
    data = np.asarray(data)
    n, m = data.shape
    if band is None or not band.any():
        return np.full(m, np.nan)
    intensity = np.abs(data).astype(np.float64) ** 2
    rows = np.arange(n)[:, None]
    peak = np.argmax(intensity, axis=0)
    below = intensity < intensity[peak, np.arange(m)] * 10.0 ** (-RESPONSE_DB / 10.0)
    first = np.array([np.max(np.flatnonzero(below[:p, j]), initial=-1) for j, p in enumerate(peak)]) + 1
    last = np.array([p + np.min(np.flatnonzero(below[p:, j]), initial=n - p) for j, p in enumerate(peak)])
    response = np.where((rows >= first) & (rows < last), data, 0.0)
    spectrum = np.abs(np.fft.fft(response, axis=0)[band]) ** 2
    return np.mean(spectrum >= spectrum.max(axis=0) * 10.0 ** (-BAND_DB / 10.0), axis=0)


def point_lines(intensity: np.ndarray, signal: np.ndarray | None = None,
                occupancy: np.ndarray | None = None) -> np.ndarray:
    """int [k]: indices of the range lines that are point-like (eq. (PGA4)), ascending: ``line_levels
    >=`` :data:`POINT_DB` and ``occupancy >=`` :data:`POINT_BAND` (:func:`band_occupancy`); where
    ``occupancy`` is None or NaN everywhere (no band known), ``share >=`` :data:`POINT_SHARE`
    (:func:`point_likeness`) instead."""
    level = line_levels(intensity, signal)
    if occupancy is None or np.all(np.isnan(occupancy)):
        share = point_likeness(intensity, signal)[0]
        return np.flatnonzero((level >= POINT_DB) & (np.nan_to_num(share, nan=0.0) >= POINT_SHARE))
    return np.flatnonzero((level >= POINT_DB) & (np.nan_to_num(occupancy, nan=0.0) >= POINT_BAND))


#: :func:`smeared_lines`: the azimuth windows [samples] the intensity is averaged over, and how many
#: nominal standard deviations of such an average of speckle (``sqrt(2 / W)``, two samples a
#: resolution cell) a line's best window must stand above the background. Speckle is correlated
#: over more samples than that: measured on the rough ground of tests/test_pga_guard.py (256 lines
#: of 265 samples), its best window reached 11.4; a trihedral 20 dB over its clutter smeared over
#: 12 m by a 2 cm, 30 m sway reached 18.2 (benchmarks/pga_sweep.py).
SMEAR_WINDOWS = (8, 16, 32, 64, 128)
SMEAR_SIGMAS = 14.0


def smeared_lines(intensity: np.ndarray, signal: np.ndarray | None = None,
                  occupancy: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The range lines that hold a scatterer however far a phase error smears it (eq. (PGA4)): the
    intensity (float64 [n_az, n_rg]) averaged along azimuth over ``W`` samples (each of
    :data:`SMEAR_WINDOWS` shorter than the image; scipy.ndimage.uniform_filter1d, the image wrapped),
    its best window over the median of the averages over the signal pixels (:func:`signal_pixels`)
    at least ``1 + SMEAR_SIGMAS sqrt(2 / W)`` for some ``W``, and ``occupancy >=`` :data:`POINT_BAND`
    where given (a wall's energy gathers too); of those, the run of adjacent lines about the one
    that stands out most (one scatterer's range extent: speckle passes in scattered lines). A point
    smeared over ``X`` samples with a peak ``SCR`` times the clutter's mean stands about ``SCR / X``
    over it in a window of ``X``.

    Returns
    -------
    lines : int [k]
        Ascending, adjacent.
    excess_db : float64 [n_rg], dB
        Each line's best window over the background, the largest over the windows relative to its
        threshold (``10 log10(excess / threshold)``; >= 0 for the lines kept).
    """
    from scipy.ndimage import uniform_filter1d
    intensity = np.asarray(intensity, dtype=np.float64)
    if signal is None:
        signal = signal_pixels(intensity)
    best = np.full(intensity.shape[1], -np.inf)
    for width in (w for w in SMEAR_WINDOWS if w < intensity.shape[0]):
        smooth = uniform_filter1d(intensity, width, axis=0, mode="wrap")
        background = np.median(smooth[signal]) if signal.any() else 0.0
        if not background > 0:
            continue
        threshold = 1.0 + SMEAR_SIGMAS * np.sqrt(2.0 / width)
        best = np.maximum(best, 10.0 * np.log10(smooth.max(axis=0) / background / threshold))
    broad = np.ones(best.size, bool) if occupancy is None else np.nan_to_num(occupancy, nan=1.0) >= POINT_BAND
    keep = (best >= 0.0) & broad
    if not keep.any():
        return np.zeros(0, int), best
    top = int(np.argmax(np.where(keep, best, -np.inf)))         # the run of lines about the one that stands out most
    low = top - int(np.argmin(keep[top::-1])) + 1 if not keep[:top + 1].all() else 0
    high = top + int(np.argmin(keep[top:])) if not keep[top:].all() else keep.size
    return np.arange(low, high), best


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
