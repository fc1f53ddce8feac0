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

from .raw import _atomic_savez, _json_default

__all__ = ["SarImage", "SarImageError"]

_PLANES = ("ground", "slant")


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
            raise SarImageError(
                f"data must be complex64 [n_azimuth, n_range], got {self.data.dtype} {self.data.shape}")
        n_az, n_rg = self.data.shape
        for name, shape in (("azimuth", (n_az,)), ("range", (n_rg,)), ("origin", (3,)),
                            ("azimuth_direction", (3,)), ("range_direction", (3,))):
            value = getattr(self, name)
            if value.shape != shape or value.dtype != np.float64:
                raise SarImageError(f"{name} must be float64 {list(shape)}, got {value.dtype} {list(value.shape)}")
        if self.plane not in _PLANES:
            raise SarImageError(f"plane must be one of {_PLANES}, got {self.plane!r}")

    def positions(self) -> np.ndarray:
        """World positions of all pixels, float64 [n_azimuth, n_range, 3] in metres."""
        return (self.origin
                + self.azimuth[:, None, None] * self.azimuth_direction
                + self.range[None, :, None] * self.range_direction)

    def pixel_of(self, point: np.ndarray) -> tuple[float, float]:
        """Fractional (row, column) of a world point projected onto the grid axes."""
        rel = np.asarray(point, float) - self.origin
        az = rel @ self.azimuth_direction
        rg = rel @ self.range_direction
        return (float(np.interp(az, self.azimuth, np.arange(self.azimuth.size))),
                float(np.interp(rg, self.range, np.arange(self.range.size))))

    def save(self, path: str | os.PathLike) -> Path:
        """Write the image as ``.npz`` atomically (temporary name, then rename)."""
        return _atomic_savez(
            Path(path), data=self.data, azimuth=self.azimuth, range=self.range, origin=self.origin,
            azimuth_direction=self.azimuth_direction, range_direction=self.range_direction,
            plane=np.str_(self.plane), algorithm=np.str_(self.algorithm), window=np.str_(self.window),
            metadata=np.str_(json.dumps(self.metadata, default=_json_default)))

    @classmethod
    def load(cls, path: str | os.PathLike) -> "SarImage":
        """Read a file written by :meth:`save`; raises :class:`SarImageError` on a bad file."""
        try:
            with np.load(path, allow_pickle=False) as f:
                kwargs: dict[str, Any] = {k: f[k] for k in (
                    "data", "azimuth", "range", "origin", "azimuth_direction", "range_direction")}
                kwargs.update({k: str(f[k]) for k in ("plane", "algorithm", "window")})
                kwargs["metadata"] = json.loads(str(f["metadata"]))
        except (OSError, KeyError, ValueError, EOFError) as exc:
            raise SarImageError(f"{path}: cannot read SarImage ({exc})") from exc
        return cls(**kwargs)
