"""The image grid a render focuses onto: a ground grid around the scene (docs/design.md section 8).

:func:`image_grid` covers a loaded scene and its layover (:func:`ground_grid` from the radar
parameters and a bounding box); :func:`sized_grid` is a grid of a given size around the scene
centre. All grids are :class:`~sarmitsuba.focus.grid.ImageGrid` s on the ground plane through
the scene centre (float64, metres, world or local frame as the geometry given).
"""
from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

from ..scene.planning import box_corners
from ..core.radar import ParameterError
from ..core.geometry import AcquisitionGeometry, ground_layover
from .grid import ImageGrid

if TYPE_CHECKING:                      # only for annotations
    from ..scene.loader import LoadedScene

__all__ = ["image_grid", "ground_grid", "sized_grid"]


def image_grid(loaded: "LoadedScene", geometry: AcquisitionGeometry) -> ImageGrid:
    """Ground grid around the scene centre covering the scene and its layover (see :func:`ground_grid`).

    The grid depends on the scene and the track's direction, never on the sensor's
    ``track_offset``: the layover is taken from the nominal track (``geometry`` less the offset),
    so the two passes of an interferometric pair focus on one grid.
    Raises ValueError (from :meth:`ImageGrid.ground`) when the grid would be too large."""
    offset = np.asarray(loaded.params.track_offset, dtype=np.float64)
    if np.any(offset):
        geometry = dataclasses.replace(geometry, positions=geometry.positions - offset)     # (only positions are read)
    return ground_grid(loaded.params, loaded.bbox_lo, loaded.bbox_hi, geometry)


def ground_grid(p, bbox_lo: np.ndarray, bbox_hi: np.ndarray, geometry: AcquisitionGeometry) -> ImageGrid:
    """Ground grid around the scene centre covering a bounding box and its layover.

    Ground-range extent: the bounding box's corners and the points where the focuser lays them
    over (:func:`radar.ground_layover`, exact for a straight track: toward the sensor by about
    ``h / tan(theta)``), plus 16 resolution cells on every side. Pixel spacing: half the finer
    of the ground-range and azimuth resolutions. A curved track gets a square grid (see
    :func:`_curved_grid`).
    """
    corners = box_corners(bbox_lo, bbox_hi)
    relative = corners - geometry.scene_center
    if geometry.curved:
        return _curved_grid(p, relative, geometry)
    along = relative @ geometry.track_direction
    across = relative @ geometry.look_direction
    laid = ground_layover(geometry, corners)
    laid = laid[np.all(np.isfinite(laid), axis=1)]
    along, across = np.concatenate([along, laid[:, 0]]), np.concatenate([across, laid[:, 1]])
    spacing = 0.5 * min(p.ground_range_resolution, p.azimuth_resolution)
    half_range = np.abs(across).max() + 16 * p.ground_range_resolution
    half_az = np.abs(along).max() + 16 * p.azimuth_resolution
    return ImageGrid.ground(geometry.scene_center, geometry.track_direction, geometry.look_direction,
                            azimuth_extent=2 * half_az, range_extent=2 * half_range, spacing=spacing)


def _curved_grid(p, relative: np.ndarray, geometry: AcquisitionGeometry) -> ImageGrid:
    """A curved track's ground grid (a circle sees the scene from every side): a square about the
    scene centre, along the mid-aperture track, holding the box's corners and their layover toward
    any side, ``h / tan(theta)`` for a corner ``h`` above the scene centre, plus 16 of the finer
    resolution cells and 2 of the coarser (the axes turn with the look, so both margins go all round;
    16 coarse cells at the fine spacing would multiply the pixels for nothing)."""
    radius = float(np.max(np.hypot(relative[:, 0], relative[:, 1])))
    height = float(np.max(np.abs(relative[:, 2])))
    fine, coarse = sorted((p.ground_range_resolution, p.azimuth_resolution))
    half = radius + height / math.tan(math.radians(p.incidence_angle)) + 16 * fine + 2 * coarse
    spacing = 0.5 * min(p.ground_range_resolution, p.azimuth_resolution)
    return ImageGrid.ground(geometry.scene_center, geometry.track_direction, geometry.look_direction,
                            azimuth_extent=2 * half, range_extent=2 * half, spacing=spacing)


def sized_grid(p, geometry: AcquisitionGeometry, size: tuple[int, int], spacing: float | None = None) -> ImageGrid:
    """Ground grid of exactly ``size = (n_azimuth, n_range)`` pixels centred on the scene centre.

    ``spacing`` [m] defaults to half the finer of the ground-range and azimuth resolutions of
    the radar parameters ``p`` (as :func:`ground_grid`; ``p`` is unused when ``spacing`` is
    given). Raises ParameterError for sizes below 2 or a non-positive spacing.
    """
    n_az, n_rg = (int(v) for v in size)
    if min(n_az, n_rg) < 2 or (n_az, n_rg) != tuple(size):
        raise ParameterError(f"image_size = {size}: two whole numbers >= 2 (azimuth, range pixels)")
    if spacing is None:
        spacing = 0.5 * min(p.ground_range_resolution, p.azimuth_resolution)
    spacing = float(spacing)
    if not (math.isfinite(spacing) and spacing > 0):
        raise ParameterError(f"image_spacing = {spacing} m must be > 0")
    return ImageGrid(origin=np.asarray(geometry.scene_center, float), azimuth_direction=geometry.track_direction,
                     range_direction=geometry.look_direction, azimuth=(np.arange(n_az) - n_az // 2) * spacing,
                     range=(np.arange(n_rg) - n_rg // 2) * spacing, plane="ground")
