"""Lattice geometry for the cell plan (docs/physics.md (T6)): scene points in a block's lattice
lines and back, and int64 keys of pairs. Vectorised NumPy, used by :mod:`sarmitsuba.tracing.cell_plan`."""
from __future__ import annotations

import numpy as np

__all__ = ["lattice_lines", "aim_points", "pair_key"]


def lattice_lines(points, antenna, fp, i0, j0, m) -> np.ndarray:
    """Scene points seen from ``antenna`` on the aim plane, in a block's lattice lines.

    Parameters
    ----------
    points : float64 [..., 3], m
    antenna : float64 [..., 3], m (broadcast against ``points``)
    fp : RayFootprint (``origin``, ``track``, ``look``, ``spacing_azimuth``, ``spacing_range``,
        ``range_min``)
    i0, j0, m : block origin (coarse cells) and tubes per coarse cell edge, broadcast

    Returns float64 [..., 2]: ``(x, y)`` with cell ``(i, j)`` of the block at ``[i, i+1] x [j, j+1]``
    (the central projection of docs/physics.md (T3): lines stay lines).
    """
    origin, track, look = (np.asarray(v, float) for v in (fp.origin, fp.track, fp.look))
    normal = np.cross(track, look)
    w = np.asarray(points, float) - antenna
    t = ((origin - antenna) @ normal)[..., None] / (w @ normal)[..., None]
    x = antenna + w * t - origin
    a = (x @ track) / fp.spacing_azimuth
    r = (x @ look - fp.range_min) / fp.spacing_range
    return np.stack([(a - i0) * m, (r - j0) * m], axis=-1)


def aim_points(x, y, fp, m) -> np.ndarray:
    """The points of the aim plane at lattice lines ``(x, y)`` of tube size ``m`` (block origin
    0): the inverse of :func:`lattice_lines` on that plane (the NumPy twin of the kernel's
    ``CellTerms._aim_point``). float64 [n, 3], m."""
    a = np.asarray(x, float) / m * fp.spacing_azimuth
    r = np.asarray(y, float) / m * fp.spacing_range + fp.range_min
    return (np.asarray(fp.origin, float) + np.multiply.outer(a, np.asarray(fp.track, float))
            + np.multiply.outer(r, np.asarray(fp.look, float)))


def pair_key(a, b):
    """One int64 key per pair of non-negative ``a`` < 2**31 and int32 ``b`` (sorted as the pairs)."""
    return (np.asarray(a, np.int64) << 32) + (np.asarray(b, np.int64) + (1 << 31))
