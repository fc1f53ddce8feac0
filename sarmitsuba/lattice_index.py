"""Lattice cells and keys for the owned-region plan (docs/physics.md (T6)): scene points in a
block's lattice lines, int64 keys of cell pairs and triples, key matching, and a convex polygon's
depth test. Vectorised NumPy, shared by :mod:`sarmitsuba.owned_regions` and
:mod:`sarmitsuba.shadow_plan`."""
from __future__ import annotations

import numpy as np

__all__ = ["lattice_lines", "pair_key", "pair_ranges", "convex_depth", "triple_key", "split_triple_key", "matches",
           "unique_pairs"]


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


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


def pair_key(a, b):
    """One int64 key per pair of non-negative ``a`` < 2**31 and int32 ``b`` (sorted as the pairs)."""
    return (np.asarray(a, np.int64) << 32) + (np.asarray(b, np.int64) + (1 << 31))


def pair_ranges(g, x, y):
    """For the distinct pairs ``(g, x)``: their keys, ``min y``, ``max y``, count, and each input's pair."""
    keys, inverse = np.unique(pair_key(g, x), return_inverse=True)
    inverse = inverse.ravel()
    pairs = np.stack([keys >> 32, (keys & 0xFFFFFFFF) - (1 << 31)], 1)
    lo = np.full(len(pairs), np.iinfo(np.int64).max)
    hi = np.full(len(pairs), np.iinfo(np.int64).min)
    np.minimum.at(lo, inverse, y)
    np.maximum.at(hi, inverse, y)
    return pairs, lo, hi, np.bincount(inverse, minlength=len(pairs)), inverse


def convex_depth(polygon, points):
    """How far ``points`` [n, k, 2] lie inside the convex ``polygon`` [n, v, 2] (either
    orientation; repeated corners allowed): float64 [n, k], the smallest distance to an edge's
    line, negative outside."""
    e = np.roll(polygon, -1, axis=1) - polygon
    p0 = polygon[:, :1]
    area = _cross(polygon - p0, np.roll(polygon, -1, axis=1) - p0).sum(1)
    length = np.linalg.norm(e, axis=-1)[:, None]
    side = np.sign(area)[:, None, None] * _cross(e[:, None], points[:, :, None] - polygon[:, None])
    return np.where(length > 0, side / np.where(length > 0, length, 1.0), np.inf).min(-1)


_SPAN = 1 << 20


def triple_key(g, i, j):
    """One int64 key per triple (``0 <= g < 2**22``, ``|i|, |j| < 2**20``), sorted as the triples."""
    return (np.asarray(g, np.int64) << 42) + ((np.asarray(i, np.int64) + _SPAN) << 21) + (np.asarray(j, np.int64) + _SPAN)


def split_triple_key(key):
    """The ``(g, i, j)`` of :func:`triple_key`'s keys: int64 arrays."""
    return key >> 42, ((key >> 21) & (2 * _SPAN - 1)) - _SPAN, (key & (2 * _SPAN - 1)) - _SPAN


def matches(sorted_keys, query):
    """Every ``(query index, position in sorted_keys)`` pair with equal keys: int64 [n] each."""
    lo = np.searchsorted(sorted_keys, query, "left")
    count = np.searchsorted(sorted_keys, query, "right") - lo
    q = np.repeat(np.arange(len(query)), count)
    return q, np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) + np.repeat(lo, count)


def unique_pairs(a, b):
    """The distinct pairs ``(a, b)`` (as :func:`pair_key` takes them), sorted: int64 arrays."""
    pair = np.unique(pair_key(a, b))
    return pair >> 32, (pair & 0xFFFFFFFF) - (1 << 31)
