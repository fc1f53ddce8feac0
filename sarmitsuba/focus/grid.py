"""Image grids: where the focusing stage evaluates the image (docs/design.md sections 3 and 8).

An :class:`ImageGrid` is a regular or irregular lattice spanned by two unit vectors.
Pixel ``(i, j)`` sits at the world position

.. math::

    \\mathbf{x}_{ij} = \\mathbf{o} + a_i \\, \\hat{\\mathbf{e}}_a + r_j \\, \\hat{\\mathbf{e}}_r

(metres, right-handed world frame, z up), the same convention as
:class:`sarmitsuba.core.image.SarImage`, so a focused image carries its grid unchanged.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..core.arrays import readonly, vector3

__all__ = ["ImageGrid"]

_PLANES = ("ground", "slant")
_UNIT_TOL = 1e-9  # tolerance on |e| - 1 for the direction vectors
_MAX_AXIS = 1 << 20  # guard against a typo in extent/spacing allocating terabytes


@dataclass(frozen=True, eq=False)
class ImageGrid:
    """Pixel lattice on which an image is focused.

    Attributes
    ----------
    origin : float64 [3], m
        World position of ``azimuth == 0, range == 0`` (the scene centre for ground grids).
    azimuth_direction : float64 [3]
        Unit vector of the azimuth (row) axis in the world frame.
    range_direction : float64 [3]
        Unit vector of the range (column) axis; points away from the sensor.
    azimuth : float64 [n_az], m
        Strictly increasing coordinate of each row along ``azimuth_direction``.
    range : float64 [n_rg], m
        Strictly increasing coordinate of each column along ``range_direction``.
    plane : str
        ``"ground"`` (range axis is ground range) or ``"slant"`` (slant range).

    Raises
    ------
    ValueError
        When a vector is not 3 finite numbers, a direction is not a unit vector, an axis is
        empty, non-finite or not strictly increasing, or ``plane`` is unknown.

    Notes
    -----
    Arrays are copied to float64 and made read-only, so a grid is immutable (equality
    is identity: ``eq=False`` avoids element-wise array comparisons). The two
    directions need not be orthogonal for focusing, but :meth:`ground` always builds an
    orthonormal pair and :meth:`sarmitsuba.core.image.SarImage.pixel_of` assumes one.
    """

    origin: np.ndarray
    azimuth_direction: np.ndarray
    range_direction: np.ndarray
    azimuth: np.ndarray
    range: np.ndarray
    plane: str = "ground"

    def __post_init__(self) -> None:
        for name in ("origin", "azimuth_direction", "range_direction"):
            object.__setattr__(self, name, readonly(vector3(name, getattr(self, name))))
        for name in ("azimuth_direction", "range_direction"):
            norm = float(np.linalg.norm(getattr(self, name)))
            if abs(norm - 1.0) > _UNIT_TOL:
                raise ValueError(f"{name} must be a unit vector (|e| = 1 within {_UNIT_TOL}), got |e| = {norm!r}")
        for name in ("azimuth", "range"):
            axis = np.array(getattr(self, name), dtype=np.float64)
            if axis.ndim != 1 or axis.size == 0 or not np.all(np.isfinite(axis)):
                raise ValueError(f"{name} must be a non-empty 1-D array of finite metres, got shape {axis.shape}")
            if axis.size > 1 and not np.all(np.diff(axis) > 0):
                raise ValueError(f"{name} must be strictly increasing (metres along its direction)")
            object.__setattr__(self, name, readonly(axis))
        if self.plane not in _PLANES:
            raise ValueError(f"plane must be one of {_PLANES}, got {self.plane!r}")

    # ------------------------------------------------------------------ constructors
    @classmethod
    def ground(cls, origin: Sequence[float], track_direction: Sequence[float],
               look_direction: Sequence[float], azimuth_extent: float, range_extent: float,
               spacing: float | tuple[float, float]) -> "ImageGrid":
        """Horizontal grid centred on ``origin``, rows along track, columns in ground range.

        Parameters
        ----------
        origin : sequence of 3 floats, m
            Grid centre in the world frame (pixel ``azimuth == 0, range == 0``).
        track_direction : sequence of 3 floats
            Platform flight direction; only its horizontal part is used.
        look_direction : sequence of 3 floats
            Line of sight from the sensor toward the scene (for the default geometry,
            flying along +x and looking right, e.g. ``(0, -1, -1)``).
        azimuth_extent, range_extent : float, m
            Full width of the grid along each axis (>= 0).
        spacing : float or (float, float), m
            Pixel spacing, one value for both axes or ``(azimuth, range)``; > 0.

        Returns
        -------
        ImageGrid
            ``plane == "ground"``. ``azimuth_direction`` is the horizontal unit track
            direction. ``range_direction`` is the horizontal part of ``look_direction``
            made orthogonal to the track (so it points away from the sensor and the pair
            is orthonormal; a squinted look loses its along-track part). Each axis is
            ``(k - n // 2) * spacing`` for ``k = 0 .. n - 1`` with the odd
            ``n = 2 * floor(extent / (2 * spacing)) + 1``: symmetric around 0, with a
            pixel exactly at ``origin``, spanning at most ``extent``.

        Raises
        ------
        ValueError
            When a vector is not 3 finite numbers, the track is vertical, the look
            direction has no horizontal part across the track (nadir or along-track
            looking), an extent is negative or non-finite, or a spacing is not positive.

        Examples
        --------
        >>> g = ImageGrid.ground((0, 0, 0), (1, 0, 0), (0, -1, -1), 10.0, 6.0, 0.5)
        >>> g.shape, g.range_direction.tolist()
        ((21, 13), [0.0, -1.0, 0.0])
        """
        origin_v = vector3("origin", origin)
        track = vector3("track_direction", track_direction)
        look = vector3("look_direction", look_direction)
        track[2] = 0.0
        norm = np.linalg.norm(track)
        if not norm > 1e-12:
            raise ValueError("track_direction must have a horizontal component (it is vertical or zero)")
        e_az = track / norm
        look[2] = 0.0
        look -= (look @ e_az) * e_az
        norm = np.linalg.norm(look)
        if not norm > 1e-12:
            raise ValueError("look_direction must have a horizontal component across the track "
                             "(it is vertical, zero or parallel to the track)")
        e_rg = look / norm
        spacings = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (2,))
        axes = []
        for label, extent, step in (("azimuth", azimuth_extent, spacings[0]), ("range", range_extent, spacings[1])):
            extent = float(extent)
            if not (np.isfinite(extent) and extent >= 0):
                raise ValueError(f"{label}_extent must be a finite number >= 0 (metres), got {extent!r}")
            if not (np.isfinite(step) and step > 0):
                raise ValueError(f"spacing must be finite and > 0 (metres) for the {label} axis, got {step!r}")
            half = int(np.floor(extent / (2.0 * step) + 1e-9))
            if 2 * half + 1 > _MAX_AXIS:
                raise ValueError(f"{label}_extent / spacing gives {2 * half + 1} pixels, more than {_MAX_AXIS}; "
                                 f"check the units (metres)")
            axes.append(np.arange(-half, half + 1, dtype=np.float64) * step)
        return cls(origin=origin_v, azimuth_direction=e_az, range_direction=e_rg,
                   azimuth=axes[0], range=axes[1], plane="ground")

    # ------------------------------------------------------------------ derived
    @property
    def shape(self) -> tuple[int, int]:
        """``(n_az, n_rg)``: the shape of an image on this grid."""
        return (self.azimuth.size, self.range.size)

    def positions(self) -> np.ndarray:
        """World positions of all pixels.

        Returns
        -------
        float64 [n_az, n_rg, 3], m
            ``origin + azimuth[i] * azimuth_direction + range[j] * range_direction``.
        """
        return (self.origin
                + self.azimuth[:, None, None] * self.azimuth_direction
                + self.range[None, :, None] * self.range_direction)
