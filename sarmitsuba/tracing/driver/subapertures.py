"""The sub-apertures of an acquisition: runs of consecutive pulses that share one trace
(docs/physics.md (T3)), where their ray tubes start, and the lattice blocks each launch casts.

:func:`pulses_per_trace` sizes them, :func:`subapertures` splits the pulses and places each
sub-aperture's reference position and ray start, :func:`lattice_blocks` cuts a batch of them into
launches of at most ``max_batch_rays`` tubes; :func:`sarmitsuba.tracing.driver.trace.trace` runs
the launches.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import mitsuba as mi
import numpy as np

from .launches import Blocks
from .moving import moving_pulses
from ...core.radar import RadarParameters
from ...core.geometry import AcquisitionGeometry
from ...scene.trace_inputs import RayFootprint, TraceSettings

__all__ = ["SubApertures", "subapertures", "pulses_per_trace", "lattice_blocks", "SUBAPERTURE_CELLS",
           "RAY_START_MARGIN"]


@dataclass(frozen=True)
class SubApertures:
    """The sub-apertures of an acquisition: runs of consecutive pulses that share one trace
    (docs/physics.md (T3)).

    Attributes
    ----------
    size : int
        Pulses per sub-aperture (the last may have fewer).
    first, count : int64 [n_s]
        First pulse and number of pulses of each.
    reference : float64 [n_s, 3], m
        Reference position: the midpoint of the first and last antenna positions, the source of
        the sub-aperture's ray tubes.
    r_near : float64 [n_s], m
        Distance from the reference position at which rays start (just short of the scene).
    k0 : int64 [n_s]
        First along-track lattice cell of the union of the pulses' cells.
    n_i : int
        Along-track cells per sub-aperture (the pulses' ``n_azimuth`` plus the widest spread of
        their first cells).
    along_limits : float64 [n_s, 2], m
        Union of the pulses' along-track aim limits.
    """

    size: int
    first: np.ndarray
    count: np.ndarray
    reference: np.ndarray
    r_near: np.ndarray
    k0: np.ndarray
    n_i: int
    along_limits: np.ndarray


def pulses_per_trace(params: RadarParameters, settings: TraceSettings, n_pulses: int, moving=None) -> int:
    """Pulses per sub-aperture: the ``pulses_per_trace`` setting, or automatically
    :data:`SUBAPERTURE_CELLS` along-track resolution cells of antenna travel (at least 1, at most
    every pulse), docs/physics.md (T3), and with moving shapes (a ShapeMotion) no more than
    :func:`~sarmitsuba.tracing.driver.moving.moving_pulses` (V2)."""
    if settings.pulses_per_trace > 0:
        return min(settings.pulses_per_trace, max(n_pulses, 1))
    cells = math.floor(SUBAPERTURE_CELLS * params.azimuth_resolution / (params.velocity / params.prf))
    return int(max(1, min(max(n_pulses, 1), cells, moving_pulses(moving, params.prf))))


#: Automatic sub-aperture: the antenna travels this many azimuth resolution cells between traces (``pulses_per_trace
#: = 0``); chosen from ``benchmarks/subaperture.py`` (image NRMSE against per-pulse tracing, urban and Munich).
SUBAPERTURE_CELLS = 16.0


#: Rays start this far [m] short of the scene's bounding sphere (``r_near``), not at the antenna.
#: The origin is placed in float64 and rounded to float32 (``mi.Point3f``); starting next to the
#: scene keeps the float32 ray parameter at scene scale instead of at the antenna's range (the
#: float32 step at 800 km is 0.06 m). The margin only has to keep the rounded origin outside the
#: sphere, so that no geometry lies behind it: 1 m is far above that rounding (about 1e-3 m for
#: coordinates of 10 km) and costs nothing. Path lengths are counted in float64 from the
#: reference position, so the margin does not enter any length.
RAY_START_MARGIN = 1.0


def subapertures(geometry: AcquisitionGeometry, footprint: RayFootprint, scene, size: int) -> SubApertures:
    """Split the acquisition's pulses into sub-apertures of ``size`` consecutive pulses."""
    n_pulses = geometry.positions.shape[0]
    first = np.arange(0, n_pulses, size, dtype=np.int64)
    last = np.minimum(first + size, n_pulses) - 1
    positions = geometry.positions
    reference = 0.5 * (positions[first] + positions[last])     # midpoint of first and last antenna
    radius, center = _bounding_sphere(scene)
    r_near = np.maximum(np.linalg.norm(reference - center, axis=1) - radius - RAY_START_MARGIN, 0.0)
    k0_lo = np.minimum.reduceat(footprint.k0, first)
    k0_hi = np.maximum.reduceat(footprint.k0, first)
    limits = np.stack([np.minimum.reduceat(footprint.along_limits[:, 0], first),
                       np.maximum.reduceat(footprint.along_limits[:, 1], first)], axis=1)
    return SubApertures(size=size, first=first, count=last - first + 1, reference=reference, r_near=r_near,
                        k0=k0_lo, n_i=footprint.n_azimuth + int((k0_hi - k0_lo).max()), along_limits=limits)


def lattice_blocks(subs: SubApertures, batch: slice, footprint: RayFootprint, max_rays: int):
    """The lattice blocks of a batch of sub-apertures (sub-aperture indices relative to the batch),
    in launches of at most ``max_rays`` tubes: each sub-aperture's coarse lattice (in chunks of
    rows when it alone exceeds the ceiling), and the refined cells near its beam, one block each
    (a refined cell's ``m^2`` tubes are never split). Yields :class:`Blocks`."""
    rows_per_block = footprint.n_range if subs.n_i * footprint.n_range <= max_rays else max(1, max_rays // subs.n_i)
    rows = []
    for q, g in enumerate(range(batch.start, batch.stop)):
        k0 = int(subs.k0[g])
        for j0 in range(0, footprint.n_range, rows_per_block):
            rows.append((q, k0, j0, subs.n_i, min(rows_per_block, footprint.n_range - j0), 1))
        for group in footprint.refinements:
            near = group.cells[(group.cells[:, 0] >= k0 - 1) & (group.cells[:, 0] <= k0 + subs.n_i + 1)]
            rows.extend((q, int(ci), int(cj), group.factor, group.factor, group.factor) for ci, cj in near)
    part, lanes = [], 0
    for row in rows:
        size = row[3] * row[4]
        if part and lanes + size > max_rays:
            yield Blocks.of(part)
            part, lanes = [], 0
        part.append(row)
        lanes += size
    if part:
        yield Blocks.of(part)


def _bounding_sphere(scene: mi.Scene) -> tuple[float, np.ndarray]:
    """Radius [m] (half the box diagonal) and centre [3] of the sphere around the scene's box."""
    bbox = scene.bbox()
    lo, hi = np.array(bbox.min, float), np.array(bbox.max, float)
    return 0.5 * float(np.linalg.norm(hi - lo)), 0.5 * (lo + hi)
