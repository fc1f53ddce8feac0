"""Phase gradient autofocus from the distributed clutter (docs/physics.md (PGA8)).

A sway's phase error is common to every scatterer at one range: the clutter carries it as the
point targets do. :func:`across_range` reads it from the clutter alone: every range bin of the
pulses is a range line whose window is the whole beam, and the step from one pulse to the next is
``arg sum_b d_p(b) d*_(p-1)(b) / mean_p |d(b)|^2`` over the bins ``b`` (the kernel of (PGA) with no
window, D. E. Wahl et al. 1994; the correlation Doppler estimator of S. N. Madsen 1989, read at
every pulse). For clutter filling the beam the echo's Doppler spectrum is the two-way antenna
pattern's, symmetric about the beam's centroid, so the sum's phase is the error's step plus a
constant: no scatterer needs to be found, however far the sway smears it, and no single target's
clutter is fitted (the estimate's noise falls as one over the square root of the bins).

The error of a horizontal sway along the line of sight is ``e sin(theta)``: across a swath it
scales with the sine of the look angle, and :func:`common_bins` keeps the ranges where that sine
lies within :data:`COMMON_SCALE` of the image centre's.

References
----------
.. [1] D. E. Wahl, P. H. Eichel, D. C. Ghiglia and C. V. Jakowatz, "Phase gradient autofocus: a
   robust tool for high resolution SAR phase correction", IEEE Trans. Aerosp. Electron. Syst.
   30(3), 827-835, 1994.
.. [2] S. N. Madsen, "Estimating the Doppler centroid of SAR data", IEEE Trans. Aerosp.
   Electron. Syst. 25(2), 134-140, 1989.
"""
from __future__ import annotations

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.raw import RawData

__all__ = ["COMMON_SCALE", "EDGE_DB", "LIT_DB", "look_sine", "common_bins", "across_range"]

#: The ranges whose line-of-sight share of a horizontal sway, ``sin(theta)``, lies within this
#: fraction of the reference range's (docs/physics.md (PGA8)): 80 m either side of 1000 m ground
#: range at 45 deg (``d ln sin(theta) / dy = cos^2(theta) / y``). The estimate is the error at the
#: bins' mean range; a 20 rad error differs by 0.8 rad at the span's ends. 2 % (the 68 bins of the
#: 120 m plate of benchmarks/pga_sweep.py within 40 m) left 0.36 rad rms over the trihedral's
#: aperture where 4 % (its 100 lit bins) left 0.30.
COMMON_SCALE = 0.04


def look_sine(ground: np.ndarray, height: float) -> np.ndarray:
    """``sin(theta) = y / sqrt(y^2 + h^2)`` of the ground ranges ``ground`` [m] (horizontal
    distances from the track) seen from ``height`` [m] above them: the line-of-sight share of a
    horizontal sway normal to the track (docs/physics.md (J4))."""
    ground = np.abs(np.asarray(ground, float))
    return ground / np.hypot(ground, height)


def _track_frame(image: SarImage) -> tuple[np.ndarray, float]:
    """``(ground [n_rg] m, height m)``: each range column's horizontal distance from the mid-aperture
    track and the track's height above the image's origin (``metadata["focus"]["track"]``)."""
    track = image.metadata["focus"]["track"]
    position, direction = np.asarray(track["position"], float), np.asarray(track["direction"], float)
    columns = image.origin + image.range[:, None] * image.range_direction - position
    across = columns - np.outer(columns @ direction, direction)
    return np.hypot(across[:, 0], across[:, 1]), float(position[2] - image.origin[2])


def common_bins(raw: RawData, image: SarImage, scale: float = COMMON_SCALE) -> np.ndarray:
    """bool [n_samples]: the fast-time samples of ``raw`` whose slant range (half the two-way path
    ``c t``) sees the image's plane at a look-angle sine within ``scale`` of the image's middle
    column's (eq. (PGA8)); samples nearer than the track's height are left out. None on a
    slant-range image (``image.plane != "ground"``): its look angles need the ground."""
    if image.plane != "ground":
        return np.zeros(np.size(raw.fast_time), bool)
    ground, height = _track_frame(image)
    reference = look_sine(ground[ground.size // 2], height)
    slant = SPEED_OF_LIGHT * np.asarray(raw.fast_time, float) / 2.0
    with np.errstate(invalid="ignore"):
        sine = np.sqrt(np.maximum(slant ** 2 - height ** 2, 0.0)) / slant
    return (slant > abs(height)) & (np.abs(sine / reference - 1.0) <= scale)


#: :func:`across_range` takes steps only from the first to the last pulse whose echo power lies within
#: this many dB of the 90th percentile of the pulses' powers: the pulses whose beam lies whole on the scene.
#: Where it leaves the scene the beam sees clutter on one side only and the sum's phase is that
#: side's Doppler (measured on a 120 m plate: 1.3 rad per pulse beyond 1 dB down, 0.01 within).
EDGE_DB = 1.0
#: :func:`across_range` uses the bins whose mean power lies within this many dB of the 90th
#: percentile of the bins' mean powers (and is not zero).
LIT_DB = 10.0


def across_range(data: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The phase error of every pulse from the lag-one products of the range-compressed ``data``
    (complex [n_pulses, n_bins], the bins to use), eq. (PGA8): the steps
    ``arg sum_b d_p(b) d*_(p-1)(b) / mean_p |d(b)|^2`` (each bin weighs alike: a bright point's bin,
    whose Doppler sweeps the band, counts once) over the bins within :data:`LIT_DB` of the 90th
    percentile bin's mean power, summed over the pulses, less the linear fit over the pulses that
    see the scene whole (their echo power within :data:`EDGE_DB` of the 90th percentile's).

    Returns
    -------
    phase : float64 [n_pulses], rad
        Constant beyond the pulses that see the scene whole (no step is taken there) but for the
        linear fit removed; zero without echo.
    inside : bool [n_pulses]
        Those pulses (the first to the last such pulse).
    """
    level = np.mean(np.abs(np.asarray(data)).astype(np.float64) ** 2, axis=0)
    lit = (level >= np.percentile(level, 90.0) * 10.0 ** (-LIT_DB / 10.0)) & (level > 0)
    data = np.asarray(data)[:, lit] / np.sqrt(level[lit])           # each bin's clutter weighs alike
    power = np.sum(np.abs(data) ** 2, axis=1)
    inside = np.zeros(power.size, bool)
    whole = np.flatnonzero(power >= np.percentile(power, 90.0) * 10.0 ** (-EDGE_DB / 10.0)) if power.any() else []
    if len(whole):
        inside[whole[0]:whole[-1] + 1] = True          # from the first to the last: speckle dips inside stay in
    steps = np.angle(np.sum(data[1:] * np.conj(data[:-1]), axis=1))
    phase = np.concatenate([[0.0], np.cumsum(np.where(inside[1:] & inside[:-1], steps, 0.0))])
    k = np.arange(phase.size, dtype=float)
    if np.count_nonzero(inside) >= 2:
        slope, offset = np.polyfit(k[inside], phase[inside], 1)
        phase = phase - (slope * k + offset)
    return phase, inside
