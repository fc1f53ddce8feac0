"""Focused SAR image: the contract between the focusing stage and the products (docs/design.md section 3).

A ground-plane image lives on a local grid around the scene centre. Pixel ``(i, j)`` sits
at the world position ``origin + azimuth[i] * azimuth_direction + range[j] * range_direction``
(metres, z up). For ``plane == "ground"`` the range axis is ground range, increasing away
from the sensor; for ``plane == "slant"`` it is slant range.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .outputs import atomic_savez, json_default
from .raw import read_npz, refuse_non_finite

__all__ = ["SarImage", "SarImageError"]

_PLANES = ("ground", "slant")
_ARRAYS = ("data", "azimuth", "range", "origin", "azimuth_direction", "range_direction")
_STRINGS = ("plane", "algorithm", "window")


def _fractional_index(axis: np.ndarray, value: float) -> float:
    """Fractional index of ``value`` on a monotonic axis: linear between samples, extrapolated
    with the end steps beyond them (0.0 for a one-sample axis)."""
    n = axis.size
    if n < 2:
        return 0.0
    sign = 1.0 if axis[-1] >= axis[0] else -1.0
    a, v = sign * axis, sign * float(value)
    if v < a[0]:
        return float((v - a[0]) / (a[1] - a[0]))
    if v > a[-1]:
        return float(n - 1 + (v - a[-1]) / (a[-1] - a[-2]))
    return float(np.interp(v, a, np.arange(n)))


class SarImageError(ValueError):
    """A SarImage file or array set does not honour the contract of docs/design.md section 3."""


@dataclass(frozen=True)
class SarImage:
    """Complex focused image on an azimuth x range grid.

    Attributes
    ----------
    data : complex64 [n_azimuth, n_range]
        Focused complex image (sqrt(m^2) in normalised radiometry).
    azimuth : float64 [n_azimuth], m
        Along-track coordinate of each row, relative to ``origin``.
    range : float64 [n_range], m
        Ground range (``plane == "ground"``) or slant range (``"slant"``) of each column,
        relative to ``origin``; increases away from the sensor.
    origin : float64 [3], m
        World position of ``azimuth == 0, range == 0`` (the scene centre for ground grids).
    azimuth_direction, range_direction : float64 [3]
        Unit vectors in the world frame spanning the grid.
    plane : str
        ``"ground"`` or ``"slant"``.
    algorithm : str
        Focusing algorithm that made the image (``"backprojection"``, ...).
    window : str
        Window applied in focusing (``"rect"`` when none).
    metadata : dict
        The RawData metadata plus the focusing parameters and timing.

    Raises
    ------
    SarImageError
        On a wrong dtype or shape (an axis length that disagrees with ``data``), a non-finite
        axis, origin or direction, or an unknown plane. Non-finite pixels are refused only by
        :meth:`load`.
    """

    data: np.ndarray
    azimuth: np.ndarray
    range: np.ndarray
    origin: np.ndarray
    azimuth_direction: np.ndarray
    range_direction: np.ndarray
    plane: str = "ground"
    algorithm: str = "backprojection"
    window: str = "rect"
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.data.ndim != 2 or self.data.dtype != np.complex64:
            raise SarImageError(f"data must be complex64 [n_azimuth, n_range], got {self.data.dtype} "
                                f"{list(self.data.shape)}")
        n_az, n_rg = self.data.shape
        for name, shape in (("azimuth", (n_az,)), ("range", (n_rg,)), ("origin", (3,)),
                            ("azimuth_direction", (3,)), ("range_direction", (3,))):
            value = getattr(self, name)
            if name in ("azimuth", "range") and value.ndim == 1 and value.size != shape[0]:
                rows = f"{n_az} azimuth rows" if name == "azimuth" else f"{n_rg} range columns"
                raise SarImageError(f"data has {rows} but {name} has {value.size} entries: the arrays are not "
                                    "of one image; focus the raw data again (sarmitsuba focus)")
            if value.shape != shape or value.dtype != np.float64:
                raise SarImageError(f"{name} must be float64 {list(shape)}, got {value.dtype} {list(value.shape)}")
            refuse_non_finite(value, name, "value", {"azimuth": ("row",), "range": ("column",)}.get(name, ("axis",)),
                               SarImageError,
                               "the image geometry is corrupt: focus the raw data again (sarmitsuba focus)")
        if self.plane not in _PLANES:
            raise SarImageError(f"plane must be one of {_PLANES}, got {self.plane!r}")

    def positions(self) -> np.ndarray:
        """World positions of all pixels, float64 [n_azimuth, n_range, 3] in metres."""
        return (self.origin
                + self.azimuth[:, None, None] * self.azimuth_direction
                + self.range[None, :, None] * self.range_direction)

    def pixel_of(self, point: np.ndarray) -> tuple[float, float]:
        """Fractional (row, column) at which the image shows the world point ``point`` (3 floats, m).

        The point is placed where a focuser matched to its range history puts it,
        :func:`sarmitsuba.analysis.image_coordinates`: when the metadata record the straight
        track, at the intersection of the point's closest-approach circle about the track with
        the image plane (zero-Doppler azimuth; ground images: its layover position; slant
        images of the FFT focusers: its closest-approach range); otherwise projected
        orthogonally on the axes. A point on the image plane maps to its own pixel, so
        ``pixel_of(positions()[i, j]) == (i, j)``. Linear in the axes and extrapolated beyond
        them: a point outside the grid gives an index outside ``[0, n - 1]`` (never clamped).
        Raises ValueError when the point is not 3 finite numbers or cannot appear in the image.
        """
        from .analysis import image_coordinates  # analysis imports this module
        point = np.asarray(point, dtype=np.float64).reshape(-1)
        if point.shape != (3,):
            raise ValueError(f"point must be 3 finite numbers (world x, y, z in m), got {point.tolist()!r}")
        az, rg = image_coordinates(self, point)
        return _fractional_index(self.azimuth, az), _fractional_index(self.range, rg)

    def save(self, path: str | os.PathLike) -> Path:
        """Write the image as ``.npz`` atomically (temporary name, then rename)."""
        return atomic_savez(
            Path(path), data=self.data, azimuth=self.azimuth, range=self.range, origin=self.origin,
            azimuth_direction=self.azimuth_direction, range_direction=self.range_direction,
            plane=np.str_(self.plane), algorithm=np.str_(self.algorithm), window=np.str_(self.window),
            metadata=np.str_(json.dumps(self.metadata, default=json_default)))

    @classmethod
    def load(cls, path: str | os.PathLike) -> "SarImage":
        """Read a file written by :meth:`save`.

        Unlike an image built in memory (whose NaN pixels the quick-look tolerates), a loaded
        image must be finite: it is read for analysis and figures.

        Raises
        ------
        SarImageError
            Naming ``path`` and the problem: missing or unreadable file, not an ``.npz``
            archive, damaged archive (truncated, bad CRC), missing field, axis lengths that
            disagree with the data shape, non-finite geometry or pixels (count and first
            (azimuth, range) pixel).
        """
        kwargs = read_npz(path, "SarImage", SarImageError, _read_image_fields)
        try:
            image = cls(**kwargs)
            refuse_non_finite(image.data, "data", "pixel", ("azimuth", "range"), SarImageError,
                               "the image is damaged or was focused from non-finite raw data; focus a finite "
                               "raw.npz again (sarmitsuba focus)")
        except SarImageError as exc:
            raise SarImageError(f"{path}: {exc}") from None
        return image


def _read_image_fields(f: Any) -> dict[str, Any]:
    """The keyword arguments of :class:`SarImage` from an open ``NpzFile``."""
    missing = [k for k in (*_ARRAYS, *_STRINGS, "metadata") if k not in f.files]
    if missing:
        raise KeyError(f"not a SarImage file, missing {missing}: give an image.npz written by SarImage.save "
                       "(sarmitsuba render or focus)")
    kwargs: dict[str, Any] = {k: np.asarray(f[k]) for k in _ARRAYS}
    kwargs.update({k: str(f[k]) for k in _STRINGS})
    kwargs["metadata"] = json.loads(str(f["metadata"]))
    return kwargs
