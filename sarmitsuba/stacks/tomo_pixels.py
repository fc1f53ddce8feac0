"""Which pixels of a stack a tomographic inversion uses (docs/physics.md (TS7)).

* :func:`check_region`: the window of azimuth rows and range columns, inside the image (never
  clipped);
* :func:`clutter_level`: the window's clutter power, the mode of its pixels' power in dB (for
  fully developed speckle the mean intensity, (TS7));
* :func:`select_pixels`: the pixels to invert, those at most :data:`CLUTTER_MARGIN_DB` below the
  clutter level (the default), or within ``min_power_db`` of the window's brightest; a window
  with no such pixel is refused, naming its brightest pixel's level.

Whether a reference point stands over its surroundings is
:func:`sarmitsuba.stacks.tomography.reference_clutter` (TS6).

Errors are :class:`~sarmitsuba.stacks.tomography.TomographyError` and name the Python
parameters as ``name = value``; the ``tomography`` command shows them with its flags
(``--rows``, ``--min-power-db``).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..core.image import SarImage
from .tomography import TomographyError

__all__ = ["CLUTTER_MARGIN_DB", "check_region", "mean_power", "clutter_level", "select_pixels"]

#: Default selection: pixels at most this many dB below the window's clutter level (TS7); a
#: pixel of fully developed speckle falls below it with probability 1 - exp(-10^-1.5) = 3.1 %.
CLUTTER_MARGIN_DB = 15.0
#: Width [dB] of the histogram's bins, and of the moving average that smooths it, of
#: :func:`clutter_level` (the log of speckle spreads over 5.6 dB, one standard deviation).
_BIN_DB, _SMOOTH_DB = 1.0, 5.0


def check_region(shape: tuple[int, int], region: tuple[slice, slice]) -> tuple[slice, slice]:
    """The window ``region = (rows, cols)`` of an image of ``shape = (n_az, n_rg)`` pixels,
    checked: each a slice with step 1 (or None) whose bounds lie in ``[0, n]``, not empty.

    Returns the two slices with their bounds filled in. Raises TomographyError naming the
    image's size (``region rows`` or ``region cols``); nothing is clipped.
    """
    out = []
    for axis, (part, n, what) in enumerate(zip(region, shape, ("rows", "cols"))):
        if not isinstance(part, slice) or part.step not in (None, 1):
            raise TomographyError(f"region {what} = {part!r}: give a slice A:B of whole numbers")
        start = 0 if part.start is None else part.start
        stop = n if part.stop is None else part.stop
        if not (0 <= start < stop <= n):
            kind = "azimuth rows" if axis == 0 else "range columns"
            raise TomographyError(f"region {what} = {start}:{stop} is empty or lies outside the image: it has {n} "
                                  f"{kind} (0:{n}) of {shape[0]} x {shape[1]} pixels [azimuth, range]; give region "
                                  f"{what} A:B with 0 <= A < B <= {n}")
        out.append(slice(int(start), int(stop)))
    return out[0], out[1]


def mean_power(images: Sequence[SarImage], region: tuple[slice, slice]) -> np.ndarray:
    """The passes' mean power ``|y_n|^2`` over ``region``, float64 [rows, cols] (m^2 in normalised
    radiometry)."""
    return np.mean([np.abs(np.asarray(im.data)[region]).astype(np.float64) ** 2 for im in images], axis=0)


def clutter_level(power: np.ndarray) -> float:
    """The clutter power of a window (TS7): the mode of ``10 log10(power)`` over its pixels of
    non-zero power, from a histogram of 1 dB bins smoothed over 5 dB; for fully developed speckle
    (exponential intensity) the mode of the log lies at the mean intensity. Returns the power
    (same unit as ``power``); 0 when no pixel has any."""
    p = np.asarray(power, np.float64)
    db = 10.0 * np.log10(p[p > 0])
    if db.size == 0:
        return 0.0
    lo = math.floor(float(db.min())) - _SMOOTH_DB
    edges = np.arange(lo, float(db.max()) + _SMOOTH_DB + _BIN_DB, _BIN_DB)
    counts, _ = np.histogram(db, bins=edges)
    width = int(round(_SMOOTH_DB / _BIN_DB))
    smooth = np.convolve(counts, np.ones(width) / width, mode="same")
    return float(10.0 ** ((edges[int(np.argmax(smooth))] + 0.5 * _BIN_DB) / 10.0))


def select_pixels(images: Sequence[SarImage], region: tuple[slice, slice] = (slice(None), slice(None)),
                  min_power_db: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The pixels of ``region`` to invert: (rows, cols) int64 [P].

    ``min_power_db`` None (the default): those whose mean power over the passes is at most
    :data:`CLUTTER_MARGIN_DB` below the window's :func:`clutter_level` (TS7), so that the ground,
    facades and roofs are inverted however bright the double-bounce lines are; a number (< 0,
    dB): those within it of the window's brightest pixel.

    Raises
    ------
    TomographyError
        ``region`` outside the image (:func:`check_region`), ``min_power_db`` not a finite number
        (a number > 0 selects nothing), or no pixel selected: naming the brightest pixel's level
        [dBsm, normalised radiometry] and the ``min_power_db`` that would include pixels.
    """
    n_az, n_rg = images[0].data.shape
    region = check_region((n_az, n_rg), region)
    if min_power_db is not None and not math.isfinite(min_power_db):
        raise TomographyError(f"min_power_db = {min_power_db!r}: give a finite number of dB < 0 (pixels within it of "
                              "the window's brightest), or leave it out for the clutter level's default")
    power = mean_power(images, region)
    brightest = float(power.max())
    if min_power_db is None:
        floor = clutter_level(power) * 10.0 ** (-CLUTTER_MARGIN_DB / 10.0)
    else:
        floor = brightest * 10.0 ** (min_power_db / 10.0)
    keep = (power >= floor) & (power > 0)
    if not keep.any():
        _refuse_empty(region, brightest, min_power_db)
    r, c = np.nonzero(keep)
    return np.arange(n_az)[region[0]][r], np.arange(n_rg)[region[1]][c]


def _refuse_empty(region: tuple[slice, slice], brightest: float, min_power_db: float | None) -> None:
    """No pixel of the window selected: its brightest pixel's level, and what would select some."""
    where = f"rows {region[0].start}:{region[0].stop}, cols {region[1].start}:{region[1].stop}"
    if brightest <= 0:
        raise TomographyError(f"the window ({where}) has no echo: its brightest pixel is 0 (-inf dBsm) in every "
                              "pass, so no min_power_db includes a pixel; choose region rows and region cols where "
                              "the passes image the scene")
    raise TomographyError(f"no pixel of the window ({where}) is within min_power_db = {min_power_db:g} dB of its "
                          f"brightest, at {10.0 * math.log10(brightest):.1f} dBsm: min_power_db = 0 includes that "
                          "pixel, -30 the pixels within 30 dB of it")
