"""Convex polygons in a face's plane, many at once: clipping by half-planes, their edges as
half-planes, area moments and membership, in float64 NumPy (docs/physics.md (M1), (M2)).

A batch of polygons is ``poly`` float64 [n, V, 2] with ``count`` int64 [n] corners each,
counter-clockwise, the slots from ``count`` on repeating the *first* corner: the next corner of
every corner is then the next slot, cyclically (``np.roll(poly, -1, axis=1)``). A half-plane is a
row ``(a, b, c)``: the points with ``a x + b y + c >= 0``; a row ``(0, 0, 1)`` holds everything.

:func:`clip` is Sutherland and Hodgman's polygon clipping (Comm. ACM 17(1), 1974), one
half-plane at a time over the whole batch; :func:`moments` are the polygon's area, centroid and
second moments by Green's theorem (the shoelace formula and its moments). Shapely does the same
for one polygon at a time; the tests check these against it. :func:`clip` works on flat corner
arrays for speed, and hands large batches to a Dr.Jit kernel
(:func:`sarmitsuba.tracing.mesh.polygon_kernels.clip_kernel`); :func:`clip_reference` is the same
clipping on the padded batch, small and readable, that both are tested against bit for bit
(tests/test_polygons_fast.py, which also keeps the plain NumPy versions of :func:`moments`,
:func:`pad`, :func:`drop_repeats` and :func:`edge_lines` that those are tested against).
"""
from __future__ import annotations

import numpy as np

from .polygon_kernels import clip_kernel

__all__ = ["EVERYTHING", "clip", "clip_reference", "edge_lines", "moments", "inside", "pad", "corner_slots",
           "drop_repeats", "drop_collinear", "following", "padded", "REPEAT_DISTANCE"]

#: The half-plane that holds every point: the padding row of a half-plane list.
EVERYTHING = (0.0, 0.0, 1.0)
#: Corners closer than this [m] to the next corner are one corner (clipping a polygon at a corner
#: that lies on the clipping line repeats it).
REPEAT_DISTANCE = 1e-9
#: Batches of at least this many polygons are clipped by the Dr.Jit kernel
#: (:func:`sarmitsuba.tracing.mesh.polygon_kernels.clip_kernel`); smaller ones by the flat NumPy path,
#: which is as fast there (Munich's batches, 2 cores: 50 k polygons by 11 half-planes 30 ms against
#: 53 ms, 355 k by 4 in 0.10 s against 1.05 s; under 10 k rows both take a few ms).
KERNEL_ROWS = 16384
#: Rows of a batch that :func:`moments` takes at a time (its temporaries then fit in the cache).
MOMENT_ROWS = 16384


def corner_slots(count: np.ndarray, width: int) -> np.ndarray:
    """bool [n, width]: which slots of a padded batch hold corners."""
    return np.arange(width)[None, :] < np.asarray(count)[:, None]


def pad(poly: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The batch with every slot from ``count`` on set to the first corner (in place; returned)."""
    if poly.shape[0] and poly.shape[1] > 1:
        padding = ~corner_slots(count, poly.shape[1])
        if poly.dtype == np.float64 and poly.shape[2:] == (2,) and poly.flags.c_contiguous:
            corner = poly.view(np.complex128)[..., 0]          # a corner as one element: faster
            np.copyto(corner, corner[:, :1].copy(), where=padding)
        else:
            np.copyto(poly, poly[:, :1].copy(), where=padding[..., None])
    return poly


def following(poly: np.ndarray) -> np.ndarray:
    """The next corner of every slot of a padded batch (cyclically)."""
    return np.roll(poly, -1, axis=1)


def _next_slot(a: np.ndarray) -> np.ndarray:
    """``np.roll(a, -1, axis=1)`` (the next slot's value, cyclically), without the generic roll."""
    if a.shape[1] == 0:
        return a.copy()
    out = np.empty_like(a)
    out[:, :-1] = a[:, 1:]
    out[:, -1] = a[:, 0]
    return out


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

    The corners live in one flat array (each row's after the previous row's, a corner ``x + i y``
    complex128 so that it moves as one element) while the half-planes are applied, and only the
    polygons that still have a half-plane to come are carried from one half-plane to the next; the
    arithmetic and the corner order are :func:`clip_reference`'s (the tests compare the two bit for
    bit).
    """
    poly = np.ascontiguousarray(poly, np.float64)
    count = np.asarray(count, np.int64)
    lines = np.asarray(lines, np.float64)
    n, width = poly.shape[0], poly.shape[1]
    if n == 0:
        return np.zeros((0, 3, 2)), count.copy()
    if width == 0 or not padded(poly, count):
        return clip_reference(poly, count, lines)
    # the last half-plane of each polygon that can cut it; rows in decreasing order of it, so that
    # the polygons still to clip at half-plane h are a leading block
    cuts = ~((lines[..., 0] == 0) & (lines[..., 1] == 0) & (lines[..., 2] > 0)) & (count > 0)[:, None]
    n_lines = lines.shape[1]
    last = np.where(cuts.any(axis=1), n_lines - np.argmax(cuts[:, ::-1], axis=1), 0) if n_lines else \
        np.zeros(n, np.int64)
    corners = poly.view(np.complex128)[..., 0]    # a corner x + i y as one element
    if np.all(last[1:] <= last[:-1]):
        order, last_sorted, cnt = np.arange(n), last, count
        z = corners[corner_slots(count, width)]
    else:
        order = np.argsort(-last, kind="stable")
        last_sorted = last[order]
        cnt = count[order]
        z = corners.reshape(-1)[np.repeat(order * width, cnt) + _ranks(cnt)]
    if not np.isfinite(z).all():
        return clip_reference(poly, count, lines)
    if n >= KERNEL_ROWS and width >= 3:
        clipped = clip_kernel(poly, count, lines, REPEAT_DISTANCE)
        if clipped is not None:
            return clipped
    off = np.zeros(n + 1, np.int64)
    np.cumsum(cnt, out=off[1:])
    live = n                                   # rows [0, live) of the sorted order still clip
    done = []                                  # finished tails: (corners, counts), last first
    for h in range(n_lines):
        m = int(np.count_nonzero(last_sorted > h))
        if m < live:
            done.append((z[off[m]:], cnt[m:]))
            z, cnt, off, live = z[:off[m]], cnt[:m], off[:m + 1], m
        if m == 0:
            break
        z, cnt, off, width = _clip_half_plane(z, cnt, off, order[:m], lines[:, h], width)
    done.append((z, cnt))
    # back to the original rows: the finished blocks were split off the end of the sorted order
    z = np.concatenate([d[0] for d in done[::-1]] + [np.zeros(1, np.complex128)])   # a zero last:
    cnt = np.concatenate([d[1] for d in done[::-1]])                                # for the empty
    z, cnt, off = _drop_repeats_flat(z, cnt, REPEAT_DISTANCE)
    start = np.empty(n, np.int64)
    start[order] = off[:-1]
    kept = np.empty(n, np.int64)
    kept[order] = cnt
    start[kept == 0] = len(z) - 1
    final = np.where(kept >= 3, kept, 0)
    out_width = min(max(int(final.max(initial=0)), 3), width)
    slot = np.arange(out_width)[None, :]
    out = z[start[:, None] + np.where(slot < final[:, None], slot, 0)]
    return out.view(np.float64).reshape(n, out_width, 2), final


def _clip_half_plane(z, cnt, off, order, line, width):
    """One half-plane of :func:`clip` on its flat corners: ``z`` complex128 (the live polygons'
    corners, one row after another), ``cnt`` int64 [m] and ``off`` int64 [m + 1] (each row's
    count and start), ``order`` int64 [m] (each live row's polygon), ``line`` float64 [n, 3]
    (this half-plane of every polygon), ``width`` the batch's corner slots. Returns the new
    ``(z, cnt, off, width)``."""
    rows = np.repeat(order, cnt)          # each corner's polygon
    a, b, c = (line[:, k].take(rows) for k in range(3))
    value = np.multiply(a, z.real, out=a)  # a x + b y + c, in place
    value += np.multiply(b, z.imag, out=b)
    value += c
    keep = value >= 0
    keep_next = np.empty_like(keep)
    keep_next[:-1] = keep[1:]
    some = cnt > 0
    first, final = off[:-1][some], off[1:][some] - 1
    keep_next[final] = keep[first]
    cross = keep != keep_next
    if not cross.any() and keep.all():
        return z, cnt, off, width              # nothing cut by this half-plane
    emitted = keep.astype(np.int64) + cross
    end = np.empty(len(emitted) + 1, np.int64)
    end[0] = 0
    np.cumsum(emitted, out=end[1:])
    new_off = end[off]
    new_cnt = np.diff(new_off)
    # where an edge leaves (or enters) the half-plane: the crossing point, after the corner
    ci = np.flatnonzero(cross)
    jump = np.zeros(len(z) + 1, np.int64)  # from a row's last corner back to its first
    jump[final] = first - final - 1
    nxt = ci + 1 + jump[ci]
    t = value[ci] / (value[ci] - value[nxt])
    here, there = z[ci], z[nxt]
    point = np.empty_like(here)
    point.real = here.real + t * (there.real - here.real)
    point.imag = here.imag + t * (there.imag - here.imag)
    z = np.repeat(z, emitted)
    z[end[ci + 1] - 1] = point
    # a convex polygon gains at most one corner, the batch's width with it; rounding that
    # makes one slightly non-convex could ask for more (as clip_reference: the last slot keeps
    # the last crossing point, else the last corner, that fell on or past it)
    if new_cnt.max(initial=0) > width:
        width += 1
        over = np.flatnonzero(new_cnt > width)
        if len(over):
            is_cross = np.zeros(len(z), bool)
            is_cross[end[ci + 1] - 1] = True
            z, new_cnt, new_off = _truncate(z, is_cross, new_cnt, new_off, over, width)
    return z, new_cnt, new_off, width


def _ranks(count: np.ndarray) -> np.ndarray:
    """int64 [sum(count)]: 0, 1, ..., count - 1 for each row in turn (the slots of flat corners)."""
    total = int(count.sum())
    start = np.zeros(len(count), np.int64)
    np.cumsum(count[:-1], out=start[1:])
    return np.arange(total) - np.repeat(start, count)


def padded(poly: np.ndarray, count: np.ndarray) -> bool:
    """Whether every row of the batch is padded (the slot after its last corner holds its first,
    the next corner :func:`clip_reference` reads) and its count fits its slots: then :func:`clip`'s
    flat path and its kernel give :func:`clip_reference`'s result (with finite corners, checked
    in :func:`clip`: a padding half-plane then keeps every corner)."""
    width = poly.shape[1]
    if np.any(count < 0) or np.any(count > width):
        return False
    part = np.flatnonzero((count > 0) & (count < width))
    return bool(np.all(poly[part, count[part]] == poly[part, 0]))


def _truncate(z, is_cross, cnt, off, over, width):
    """The rows ``over`` cut to ``width`` corners as :func:`clip_reference` does when a row asks
    for more slots than it has: every corner meant for slot ``width - 1`` or beyond lands there, the
    corners first, then the crossing points, the last one written staying."""
    drop = np.zeros(len(z), bool)
    for r in over:
        s, e = off[r], off[r + 1]
        tail = np.arange(s + width - 1, e)
        crossing = tail[is_cross[tail]]
        z[s + width - 1] = z[crossing[-1] if len(crossing) else tail[-1]]
        drop[s + width:e] = True
    cnt = cnt.copy()
    cnt[over] = width
    off = np.zeros(len(cnt) + 1, np.int64)
    np.cumsum(cnt, out=off[1:])
    return z[~drop], cnt, off


def _drop_repeats_flat(z, cnt, distance):
    """:func:`drop_repeats` on flat corners ``x + i y`` complex128 [N] (each row's after the
    previous row's; whatever follows the last row is kept as it is): ``(z, count, offsets)``."""
    off = np.zeros(len(cnt) + 1, np.int64)
    np.cumsum(cnt, out=off[1:])
    some = cnt > 0
    first, final = off[:-1][some], off[1:][some] - 1
    step = np.empty_like(z)                    # to the next corner
    np.subtract(z[1:], z[:-1], out=step[:-1])
    step[final] = z[first] - z[final]
    step[off[-1]:] = 0.0                       # (kept below whatever it is)
    dx, dy = step.real, step.imag
    gap = np.sqrt(dx * dx + dy * dy)           # not abs(): hypot rounds differently
    keep = gap > distance
    keep[off[:-1][cnt == 1]] = True
    keep[off[-1]:] = True
    end = np.zeros(len(keep) + 1, np.int64)
    np.cumsum(keep, out=end[1:])
    off = end[off]
    return z[keep], np.diff(off), off


def clip_reference(poly: np.ndarray, count: np.ndarray, lines: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`clip` one half-plane at a time over the padded batch: the small readable version
    that :func:`clip` is tested against (and falls back on for corners that are not finite or
    batches that are not padded)."""
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
    count = np.asarray(count)
    diff = _next_slot(poly) - poly
    gap = np.sqrt(diff[..., 0] * diff[..., 0] + diff[..., 1] * diff[..., 1])
    keep = corner_slots(count, width) & ((gap > distance) | (count[:, None] == 1))
    new_count = keep.sum(axis=1).astype(np.int64)
    out = np.zeros_like(poly)
    out[corner_slots(new_count, width)] = poly[keep]
    return pad(out, new_count), new_count


def drop_collinear(poly: np.ndarray, count: np.ndarray, distance: float = REPEAT_DISTANCE):
    """The batch of convex polygons without the corners that lie within ``distance`` [m] of the
    line through their neighbours (a straight edge split in two) or of their previous corner:
    ``(poly, count)``, padded, each polygon its simplest outline (at least 3 corners). A corner
    where a clipping line touched the outline is such a corner; whether the clipper makes one
    hangs on rounding, so the geometric derivatives (docs/physics.md (AD4)) compare outlines
    without them."""
    poly, count = drop_repeats(np.asarray(poly, float), np.asarray(count, np.int64), distance)
    n, width = poly.shape[:2]
    slot = np.arange(width)[None, :]
    rows = np.arange(n)[:, None]
    safe = np.maximum(count, 1)[:, None]
    a, c = poly[rows, (slot - 1) % safe], poly[rows, (slot + 1) % safe]
    ab, ac = poly - a, c - a
    chord = np.sqrt(ac[..., 0] ** 2 + ac[..., 1] ** 2)
    off = np.abs(ab[..., 0] * ac[..., 1] - ab[..., 1] * ac[..., 0]) / np.maximum(chord, 1e-300)
    along = ab[..., 0] * ac[..., 0] + ab[..., 1] * ac[..., 1]
    drop = corner_slots(count, width) & (off <= distance) & (along >= 0) & (along <= chord * chord)
    drop &= (count[:, None] > 3)
    keep = corner_slots(count, width) & ~drop
    new_count = keep.sum(axis=1).astype(np.int64)
    short = new_count < 3                                # (never fewer than a triangle's corners)
    keep[short] = corner_slots(count[short], width)
    new_count[short] = count[short]
    out = np.zeros_like(poly)
    out[corner_slots(new_count, width)] = poly[keep]
    return pad(out, new_count), new_count


def edge_lines(poly: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The half-planes of convex counter-clockwise polygons: float64 [n, V, 3], one per edge
    (``a x + b y + c >= 0`` inside, ``(a, b)`` the unit inward normal), :data:`EVERYTHING` for
    slots beyond ``count``."""
    edge = _next_slot(poly) - poly
    length = np.sqrt(edge[..., 0] * edge[..., 0] + edge[..., 1] * edge[..., 1])
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
    edges have no length).

    Computed a block of rows at a time (:data:`MOMENT_ROWS`): the dozens of temporaries of a large
    batch then stay in the processor's cache; every row's arithmetic is the same."""
    poly = np.asarray(poly)
    count = np.asarray(count)
    if poly.shape[0] <= MOMENT_ROWS:
        return _moments(poly, count)
    parts = [_moments(poly[s:s + MOMENT_ROWS], count[s:s + MOMENT_ROWS])
             for s in range(0, poly.shape[0], MOMENT_ROWS)]
    return tuple(np.concatenate([part[k] for part in parts]) for k in range(4))


def _moments(poly: np.ndarray, count: np.ndarray):
    """:func:`moments` of one block of rows."""
    x0, y0 = poly[:, :1, 0], poly[:, :1, 1]            # about the first corner, for conditioning
    x, y = poly[..., 0] - x0, poly[..., 1] - y0
    x1, y1 = _next_slot(x), _next_slot(y)
    cross = x * y1 - x1 * y
    area = 0.5 * cross.sum(axis=1)
    safe = np.where(area != 0, area, 1.0)
    cx = ((x + x1) * cross).sum(axis=1) / (6 * safe)
    cy = ((y + y1) * cross).sum(axis=1) / (6 * safe)
    ixx = ((x * x + x * x1 + x1 * x1) * cross).sum(axis=1) / 12 - area * cx * cx
    iyy = ((y * y + y * y1 + y1 * y1) * cross).sum(axis=1) / 12 - area * cy * cy
    ixy = ((x * y1 + 2 * x * y + 2 * x1 * y1 + x1 * y) * cross).sum(axis=1) / 24 - area * cx * cy
    # padded slots repeat the first corner, so they do not widen the box
    diagonal = _diagonal(poly)
    centroid = np.stack([cx + x0[:, 0], cy + y0[:, 0]], axis=1)
    empty = count < 3
    return (np.where(empty, 0.0, area), np.where(empty[:, None], 0.0, centroid),
            np.where(empty[:, None], 0.0, np.stack([ixx, ixy, iyy], axis=1)), np.where(empty, 0.0, diagonal))


def _diagonal(poly: np.ndarray) -> np.ndarray:
    """float64 [n]: the length of each row's bounding-box diagonal over all its slots (a min and
    max over the slots one slot at a time: a reduction over the middle axis of [n, V, 2] is slow)."""
    if poly.shape[0] == 0:
        return np.zeros(0)
    low, high = poly[:, 0].copy(), poly[:, 0].copy()
    for j in range(1, poly.shape[1]):
        np.minimum(low, poly[:, j], out=low)
        np.maximum(high, poly[:, j], out=high)
    size = high - low
    return np.sqrt(size[:, 0] * size[:, 0] + size[:, 1] * size[:, 1])
