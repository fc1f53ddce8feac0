"""Convex polygons clipped by half-planes as one Dr.Jit kernel (docs/physics.md (M1), (M2)).

One lane per polygon. Its corners live in Dr.Jit *local memory* (a per-lane scratch buffer that
symbolic loops may read and write at computed indices), in two halves used in turn: a loop over the
polygon's half-planes applies Sutherland and Hodgman's rule (Comm. ACM 17(1), 1974) from one half to
the other, a second loop drops repeated corners, and a last loop scatters the corners to the
output. The arithmetic and the corner order are those of
:func:`sarmitsuba.tracing.mesh.polygons.clip_reference`, the readable NumPy version the tests compare
this kernel with bit for bit; it runs on the ``llvm`` and ``cuda`` variants alike.

A convex polygon gains at most one corner per half-plane. A lane that would gain more (a polygon
that rounding or its input made non-convex), corners that are not finite or a batch that is not
padded are left to :func:`~sarmitsuba.tracing.mesh.polygons.clip_reference`, whose rule for such rows
(the batch's width grows by one slot per half-plane) depends on the whole batch.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..device import device_array, table_array
from ..loops import RECORDING, loop_mode

__all__ = ["clip_kernel", "clip_on_device", "MAX_CORNERS"]

#: The most corners a lane holds (input corners plus one per half-plane that can cut it); a batch
#: that could need more is clipped by the reference.
MAX_CORNERS = 64


def clip_kernel(poly: np.ndarray, count: np.ndarray, lines: np.ndarray, repeat: float):
    """Each polygon clipped to its half-planes, then its corners closer than ``repeat`` [m] to the
    next one dropped, in one kernel.

    Parameters
    ----------
    poly : float64 [n, V, 2]
        Convex polygons, counter-clockwise, padded with their first corner, finite, ``V >= 3``.
    count : int64 [n]
        Corners of each (0 .. V).
    lines : float64 [n, H, 3]
        Half-planes ``a x + b y + c >= 0`` (``(0, 0, c > 0)`` rows hold everything and are skipped).
    repeat : float
        :data:`sarmitsuba.tracing.mesh.polygons.REPEAT_DISTANCE`.

    Returns
    -------
    (float64 [n, W, 2], int64 [n]) or None
        As :func:`sarmitsuba.tracing.mesh.polygons.clip`; None where some lane gained more than one
        corner at some half-plane, or would need more than :data:`MAX_CORNERS` slots (the caller
        then clips the batch with the reference).
    """
    clipped = clip_on_device(poly, count, lines, repeat)
    if clipped is None:
        return None
    out, final, cap = clipped
    out_width = max(int(final.max(initial=0)), 3)
    return np.ascontiguousarray(out.numpy().reshape(len(final), cap, 2)[:, :out_width]), final


def clip_on_device(poly: np.ndarray, count: np.ndarray, lines: np.ndarray, repeat: float,
                   rows: np.ndarray | None = None):
    """:func:`clip_kernel` with its output left on the device, each lane's polygon gathered there
    from ``poly`` (``rows``: lane ``i`` clips polygon ``rows[i]``; None: polygon ``i``).

    Parameters as :func:`clip_kernel`'s, but ``lines`` is [len(rows), H, 3] where ``rows`` is
    given (int64 [m], indices into ``poly``).

    Returns
    -------
    (Float64 [m * cap * 2], int64 [m], int) or None
        The corners of every lane's clipped polygon, ``cap`` slots of ``(x, y)`` a lane, the slots
        from its count on holding its first corner (0 for an empty polygon); the counts (0 below
        3); ``cap``. None as for :func:`clip_kernel`, and for no lanes.
    """
    width = poly.shape[1]
    count = np.asarray(count)
    n = poly.shape[0] if rows is None else len(rows)
    n_lines = lines.shape[1]
    cuts = ~((lines[..., 0] == 0) & (lines[..., 1] == 0) & (lines[..., 2] > 0))
    cap = width + int(cuts.sum(axis=1).max(initial=0))
    if cap > MAX_CORNERS or n == 0:
        return None
    cap = max(8, -(-cap // 8) * 8)                 # a few kernel sizes, not one per batch
    f64, u32 = mi.Float64, mi.UInt32
    # gathered tables, mapped from NumPy's buffers (a gather's code does not depend on alignment)
    corners = _table(f64, np.ascontiguousarray(poly, np.float64).reshape(-1))
    table = _table(f64, np.ascontiguousarray(lines, np.float64).reshape(-1))
    source = None if rows is None else device_array(u32, rows)
    lane_count = count if rows is None else np.take(count, rows)
    with RECORDING:                     # symbolic loops: recorded and run one thread at a time
        out, kept = _kernel(corners, width, device_array(u32, lane_count.astype(np.uint32)), table, n_lines, cap,
                            repeat, source)
        dr.eval(out, kept)
    kept = kept.numpy()
    if np.any(kept == _FAILED):
        return None
    return out, kept.astype(np.int64), cap


#: The count of a lane that gained more than one corner at a half-plane (or ran out of slots).
_FAILED = 0xFFFFFFFF


def _table(cls, values: np.ndarray):
    """A flat gather table: NumPy's buffer mapped as it is, or an aligned copy of a one-entry table
    (read as a scalar load, whose code follows the alignment: :func:`sarmitsuba.tracing.device.gather_table`)."""
    return cls(values) if len(values) > 1 else table_array(cls, values)


def _kernel(corners, width: int, count, table, n_lines: int, cap: int, repeat: float, source=None):
    """The Dr.Jit body of :func:`clip_kernel`: ``corners`` the input ``poly`` flat [n * width * 2],
    ``table`` the half-planes flat [n * n_lines * 3], ``source`` (UInt32 [n] or None) the polygon
    each lane clips. Returns the output corners flat [n * cap * 2] and the kept counts
    (:data:`_FAILED` for a lane that failed)."""
    f64, u32 = mi.Float64, mi.UInt32
    n = dr.width(count)
    row = dr.arange(u32, n)
    polygon = row if source is None else source
    scratch = 2 * cap                          # the slot that masked writes go to
    xs = dr.alloc_local(f64, 2 * cap + 1, dr.zeros(f64, n))
    ys = dr.alloc_local(f64, 2 * cap + 1, dr.zeros(f64, n))
    # the batch's sizes are runtime values, not constants: one kernel per capacity
    width, n_lines = dr.opaque(u32, width), dr.opaque(u32, n_lines)

    def load(k, total):
        x = dr.gather(f64, corners, (polygon * width + k) * 2)
        y = dr.gather(f64, corners, (polygon * width + k) * 2 + 1)
        xs[k], ys[k] = x, y
        return k + 1, total + x + y

    # (the corners' sum is an output of the loop, whose only other effect is on local memory, so
    # that Dr.Jit keeps it; a lane whose corners are not finite fails)
    _, total = dr.while_loop((u32(0), dr.zeros(f64, n)), lambda k, _: k < width, load, mode=loop_mode(),
                             label="corners in")

    def half_plane(h, count, base, failed):
        at = (row * n_lines + h) * 3
        a, b, c = dr.gather(f64, table, at), dr.gather(f64, table, at + 1), dr.gather(f64, table, at + 2)
        act = ~((a == 0.0) & (b == 0.0) & (c > 0.0)) & (count > 0)
        src, dst = base, cap - base

        def corner(i, m):
            j = dr.select(i + 1 < count, i + 1, 0)
            x, y = xs[src + i], ys[src + i]
            xn, yn = xs[src + j], ys[src + j]
            value = a * x + b * y + c
            value_next = a * xn + b * yn + c
            keep = value >= 0.0
            cross = keep != (value_next >= 0.0)
            t = value / dr.select(cross, value - value_next, 1.0)
            at = dr.select(keep & (m < cap), dst + m, scratch)
            xs[at], ys[at] = x, y
            m = dr.select(keep, m + 1, m)
            at = dr.select(cross & (m < cap), dst + m, scratch)
            xs[at], ys[at] = x + t * (xn - x), y + t * (yn - y)
            m = dr.select(cross, m + 1, m)
            return i + 1, m

        stop = dr.select(act, count, 0)
        _, m = dr.while_loop((u32(0), u32(0)), lambda i, *_: i < stop, corner, mode=loop_mode(), label="clip corners")
        failed |= act & ((m > count + 1) | (m > cap))
        return (h + 1, dr.select(act, dr.minimum(m, cap), count), dr.select(act, dst, base), failed)

    _, count, base, failed = dr.while_loop((u32(0), u32(count), dr.zeros(u32, n), ~dr.isfinite(total)),
                                           lambda h, *_: h < n_lines, half_plane, mode=loop_mode(),
                                           label="half-planes")
    out, final = _finish(xs, ys, count, base, cap, repeat)
    return out, dr.select(failed, _FAILED, final)


def _finish(xs, ys, count, base, cap: int, repeat: float):
    """The end of :func:`_kernel`: each lane's corners (``count`` from slot ``base`` of its local
    memory ``xs``, ``ys``) without the repeated ones, then every slot written out (flat [n * cap *
    2]); returns that and the kept counts (0 below 3)."""
    f64, u32 = mi.Float64, mi.UInt32
    n = dr.width(count)
    row = dr.arange(u32, n)
    scratch = 2 * cap
    # the repeated corners dropped (each compared with the next, cyclically), into the other half
    dst = cap - base

    def repeat_body(i, m):
        j = dr.select(i + 1 < count, i + 1, 0)
        x, y = xs[base + i], ys[base + i]
        dx, dy = xs[base + j] - x, ys[base + j] - y
        keep = (dr.sqrt(dx * dx + dy * dy) > repeat) | (count == 1)
        at = dr.select(keep, dst + m, scratch)
        xs[at], ys[at] = x, y
        return i + 1, dr.select(keep, m + 1, m)

    _, kept = dr.while_loop((u32(0), u32(0)), lambda i, *_: i < count, repeat_body, mode=loop_mode(),
                            label="repeated corners")
    final = dr.select(kept >= 3, kept, 0)
    # every slot: its corner, or the first (padding; 0 for a polygon with none left)
    out = dr.zeros(f64, n * cap * 2)

    def write(k):
        real = k < final
        first_x = dr.select(kept > 0, xs[dst], 0.0)
        first_y = dr.select(kept > 0, ys[dst], 0.0)
        at = (row * cap + k) * 2
        dr.scatter(out, dr.select(real, xs[dst + dr.select(real, k, 0)], first_x), at)
        dr.scatter(out, dr.select(real, ys[dst + dr.select(real, k, 0)], first_y), at + 1)
        return (k + 1,)

    dr.while_loop((u32(0),), lambda k: k < cap, write, mode=loop_mode(), label="corners out")
    return out, final
