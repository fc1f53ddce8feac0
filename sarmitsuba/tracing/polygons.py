"""Convex polygons in a face's plane, many at once: clipping by half-planes, their edges as
half-planes, area moments and membership, in float64 NumPy (docs/physics.md (M1), (M2)).

A batch of polygons is ``poly`` float64 [n, V, 2] with ``count`` int64 [n] corners each,
counter-clockwise, the slots from ``count`` on repeating the *first* corner: the next corner of
every corner is then the next slot, cyclically (``np.roll(poly, -1, axis=1)``). A half-plane is a
row ``(a, b, c)``: the points with ``a x + b y + c >= 0``; a row ``(0, 0, 1)`` holds everything.

:func:`clip` is Sutherland and Hodgman's polygon clipping (Comm. ACM 17(1), 1974), one
half-plane at a time over the whole batch; :func:`moments` are the polygon's area, centroid and
second moments by Green's theorem (the shoelace formula and its moments). Shapely does the same
for one polygon at a time; the tests check these against it.
"""
from __future__ import annotations

import numpy as np

__all__ = ["EVERYTHING", "clip", "edge_lines", "moments", "inside", "pad", "corner_slots", "drop_repeats",
           "following"]

#: The half-plane that holds every point: the padding row of a half-plane list.
EVERYTHING = (0.0, 0.0, 1.0)
#: Corners closer than this [m] to the next corner are one corner (clipping a polygon at a corner
#: that lies on the clipping line repeats it).
REPEAT_DISTANCE = 1e-9


def corner_slots(count: np.ndarray, width: int) -> np.ndarray:
    """bool [n, width]: which slots of a padded batch hold corners."""
    return np.arange(width)[None, :] < np.asarray(count)[:, None]


def pad(poly: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The batch with every slot from ``count`` on set to the first corner (in place; returned)."""
    poly[:] = np.where(corner_slots(count, poly.shape[1])[..., None], poly, poly[:, :1])
    return poly


def following(poly: np.ndarray) -> np.ndarray:
    """The next corner of every slot of a padded batch (cyclically)."""
    return np.roll(poly, -1, axis=1)


def clip(poly: np.ndarray, count: np.ndarray, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each polygon clipped to its half-planes (Sutherland-Hodgman), float64.

    Parameters
    ----------
    poly : float64 [n, V, 2]
        Convex polygons, counter-clockwise, padded with their first corner.
    count : int64 [n]
        Corners of each (0 for an empty polygon).
    lines : float64 [n, H, 3]
        Half-planes ``a x + b y + c >= 0`` of each polygon (:data:`EVERYTHING` rows pad).

    Returns
    -------
    poly : float64 [n, W, 2]
        The clipped polygons (convex, counter-clockwise, repeated corners dropped, padded), ``W``
        their largest corner count (at least 3); a polygon with fewer than 3 corners is empty
        (count 0).
    count : int64 [n]
    """
    poly = np.array(poly, np.float64)              # a copy: the corners are rewritten in place
    count = np.asarray(count, np.int64).copy()
    n = poly.shape[0]
    if n == 0:
        return np.zeros((0, 3, 2)), count
    for h in range(lines.shape[1]):
        line = lines[:, h]
        # only the polygons this half-plane can cut: not the padding rows, not empty polygons
        act = np.flatnonzero(~((line[:, 0] == 0) & (line[:, 1] == 0) & (line[:, 2] > 0)) & (count > 0))
        if len(act) == 0:
            continue
        width = poly.shape[1]
        sub, line, c = poly[act], line[act], count[act]
        value = line[:, 0, None] * sub[..., 0] + line[:, 1, None] * sub[..., 1] + line[:, 2, None]
        nxt = np.concatenate([sub[:, 1:], sub[:, :1]], axis=1)
        value_next = np.concatenate([value[:, 1:], value[:, :1]], axis=1)
        valid = corner_slots(c, width)
        keep = valid & (value >= 0)
        cross = valid & ((value >= 0) != (value_next >= 0))
        t = value / np.where(cross, value - value_next, 1.0)
        point = sub + t[..., None] * (nxt - sub)
        emitted = keep.astype(np.int64) + cross
        start = np.cumsum(emitted, axis=1) - emitted
        new_count = np.minimum(emitted[:, -1] + start[:, -1], width + 1)
        # a convex polygon gains at most one corner; rounding that makes it slightly non-convex
        # could ask for more, which are dropped (the last slot is overwritten)
        grown = int(new_count.max(initial=0)) > width
        out_width = width + 1 if grown else width
        out = np.zeros((len(act), out_width, 2))
        rows = np.broadcast_to(np.arange(len(act))[:, None], (len(act), width))
        out[rows[keep], np.minimum(start, out_width - 1)[keep]] = sub[keep]
        out[rows[cross], np.minimum(start + keep, out_width - 1)[cross]] = point[cross]
        new_count = np.minimum(new_count, out_width)
        # the slot after the last corner holds the first one: every corner's next is then the next slot
        room = np.flatnonzero(new_count < out_width)
        if out_width > width:
            poly = np.concatenate([poly, np.repeat(poly[:, :1], out_width - width, axis=1)], axis=1)
        out[room, new_count[room]] = out[room, 0]
        poly[act] = out
        count[act] = new_count
    poly, count = drop_repeats(poly, count)
    count = np.where(count >= 3, count, 0)
    width = max(int(count.max(initial=0)), 3)
    return pad(poly[:, :width].copy(), count), count


def drop_repeats(poly: np.ndarray, count: np.ndarray, distance: float = REPEAT_DISTANCE):
    """The batch without corners equal to their next corner (cyclically): ``(poly, count)``,
    padded."""
    poly = pad(poly, count)
    width = poly.shape[1]
    gap = np.linalg.norm(np.roll(poly, -1, axis=1) - poly, axis=2)
    keep = corner_slots(count, width) & ((gap > distance) | (count[:, None] == 1))
    start = np.cumsum(keep, axis=1) - keep
    out = np.zeros_like(poly)
    rows = np.broadcast_to(np.arange(poly.shape[0])[:, None], keep.shape)
    out[rows[keep], start[keep]] = poly[keep]
    count = keep.sum(axis=1).astype(np.int64)
    return pad(out, count), count


def edge_lines(poly: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The half-planes of convex counter-clockwise polygons: float64 [n, V, 3], one per edge
    (``a x + b y + c >= 0`` inside, ``(a, b)`` the unit inward normal), :data:`EVERYTHING` for
    slots beyond ``count``."""
    edge = np.roll(poly, -1, axis=1) - poly
    length = np.linalg.norm(edge, axis=2)
    valid = corner_slots(count, poly.shape[1]) & (length > 0)
    safe = np.where(valid, length, 1.0)
    a = np.where(valid, -edge[..., 1] / safe, 0.0)
    b = np.where(valid, edge[..., 0] / safe, 0.0)
    c = np.where(valid, -(a * poly[..., 0] + b * poly[..., 1]), 1.0)
    return np.stack([a, b, c], axis=2)


def inside(points: np.ndarray, lines: np.ndarray, tolerance: float = 0.0) -> np.ndarray:
    """bool [n, m]: whether each of ``points`` [n, m, 2] satisfies every half-plane of its row of
    ``lines`` [n, H, 3] (to ``tolerance`` m)."""
    value = (lines[:, None, :, 0] * points[..., 0, None] + lines[:, None, :, 1] * points[..., 1, None]
             + lines[:, None, :, 2])
    return np.all(value >= -tolerance, axis=2)


def moments(poly: np.ndarray, count: np.ndarray):
    """Area [m^2], centroid [m] float64 [n, 2], second moments about the centroid float64 [n, 3]
    (``Ixx = int x^2``, ``Ixy = int x y``, ``Iyy = int y^2``, m^4) and bounding-box diagonal [m]
    of each polygon (Green's theorem; empty polygons: zeros). Padding slots add nothing (their
    edges have no length)."""
    x0, y0 = poly[:, :1, 0], poly[:, :1, 1]            # about the first corner, for conditioning
    x, y = poly[..., 0] - x0, poly[..., 1] - y0
    x1, y1 = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    cross = x * y1 - x1 * y
    area = 0.5 * cross.sum(axis=1)
    safe = np.where(area != 0, area, 1.0)
    cx = ((x + x1) * cross).sum(axis=1) / (6 * safe)
    cy = ((y + y1) * cross).sum(axis=1) / (6 * safe)
    ixx = ((x * x + x * x1 + x1 * x1) * cross).sum(axis=1) / 12 - area * cx * cx
    iyy = ((y * y + y * y1 + y1 * y1) * cross).sum(axis=1) / 12 - area * cy * cy
    ixy = ((x * y1 + 2 * x * y + 2 * x1 * y1 + x1 * y) * cross).sum(axis=1) / 24 - area * cx * cy
    # padded slots repeat the first corner, so they do not widen the box
    diagonal = np.linalg.norm(poly.max(axis=1) - poly.min(axis=1), axis=1) if poly.shape[0] else np.zeros(0)
    centroid = np.stack([cx + x0[:, 0], cy + y0[:, 0]], axis=1)
    empty = count < 3
    return (np.where(empty, 0.0, area), np.where(empty[:, None], 0.0, centroid),
            np.where(empty[:, None], 0.0, np.stack([ixx, ixy, iyy], axis=1)), np.where(empty, 0.0, diagonal))
