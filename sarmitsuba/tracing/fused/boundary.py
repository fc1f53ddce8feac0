"""The lit boundary of mixed pieces on the Dr.Jit device (docs/physics.md (M4), docs/design.md
section 10.1).

:func:`sarmitsuba.tracing.visibility.occlusion.lit_boundary` is the readable NumPy reference: a
piece less the union of its convex cut-outs, as the piece's edges outside every cut-out and the
cut-outs' edges, reversed, inside the piece and outside every other cut-out. Here the same
segments, in the same order and to the bit, come from two kernels, one lane per edge (the pieces'
live edges, then the cut-outs' live edges, as the reference lists them):

1. *intervals*: a cut-out's edge is first cut to its piece (Cyrus and Beck, 1978, against the
   piece's lines); then every edge loops over the cut-outs of its piece (a CSR range, in the
   cut-outs' order), tests their bounding boxes (:data:`~sarmitsuba.tracing.visibility.occlusion.BOX_SLACK`)
   and cuts itself to each that meets it, writing the non-empty intervals ``(s, e)`` in that
   order into its own block of rows (as many rows as its piece has cut-outs);
2. *gaps*: each edge walks its rows in the order of ``(s, row)`` (a selection over the block:
   ``np.lexsort((s, edge))`` within the edge, ``k^2`` steps for ``k`` intervals, a few on real
   scenes), keeps the running end of the intervals seen and writes the gaps before each
   interval's start into the same block; its tail gap (after the last interval) and, for an
   edge no interval touches, the whole edge are flags.

The host prepares the tables (the half-planes of
:func:`~sarmitsuba.tracing.mesh.polygons.edge_lines`, their normals' lengths by ``np.hypot``, the
cut-outs' boxes, the live edges) and assembles the result from the gaps in the reference's order
(every edge's gaps before its intervals, then the tail gaps, then the untouched edges), with the
reference's arithmetic ``start + a delta`` and its flip of the cut-outs' edges. Every float64
operation of the kernels is the reference's, in its order (Dr.Jit's LLVM backend does not
contract products and sums into FMAs); minima and maxima are written as NumPy computes them
(``np.maximum(x, y)`` is ``x > y ? x : y``), so that even signed zeros agree. The results agree
bit for bit with the reference on the ``llvm`` variants (tests/test_fused_boundary.py); the
``cuda`` variants have not been compared.

Nothing here depends on thread timing: each lane writes its own rows, no atomics.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..device import device_array, releasing, table_array
from ..loops import RECORDING, loop_mode
from ..mesh.polygons import corner_slots, edge_lines
from ..visibility.occlusion import BOX_SLACK, COINCIDENT

__all__ = ["lit_boundary"]

#: The reference's shortest kept segment [m] (``(b - a) |delta| > 1e-12``).
SHORTEST = 1e-12


def _lengths(vectors: np.ndarray) -> np.ndarray:
    """Euclidean lengths of 2-vectors [..., 2] as the reference computes them (``sqrt(x x + y y)``)."""
    x, y = vectors[..., 0], vectors[..., 1]
    return np.sqrt(x * x + y * y)


def _following(poly: np.ndarray) -> np.ndarray:
    """Each slot's edge vector to the next slot, cyclically (``np.roll(poly, -1, axis=1) - poly``)."""
    out = np.empty_like(poly)
    np.subtract(poly[:, 1:], poly[:, :-1], out=out[:, :-1])
    np.subtract(poly[:, :1], poly[:, -1:], out=out[:, -1:])
    return out


def _line_table(lines: np.ndarray):
    """Half-planes [T, H, 3] as flat device tables ``(a, b, c, max(|n|, 1e-300), |n| > 0)``, ``|n|``
    by ``np.hypot`` as the reference computes it (not ``sqrt(a a + b b)``, which differs in the last
    bit for about one line in twenty)."""
    a, b, c = (np.ascontiguousarray(lines[..., i]).reshape(-1) for i in range(3))
    normal_len = np.hypot(a, b)
    f64 = mi.Float64
    return (table_array(f64, a), table_array(f64, b), table_array(f64, c),
            table_array(f64, np.maximum(normal_len, 1e-300)), table_array(mi.UInt32, normal_len > 0))


@releasing
def lit_boundary(base: np.ndarray, base_count: np.ndarray, cut: np.ndarray, cut_count: np.ndarray,
                 cut_owner: np.ndarray):
    """:func:`sarmitsuba.tracing.visibility.occlusion.lit_boundary` on the device: the same
    segments in the same order, bit for bit.

    Parameters and returns as the reference's (float64 polygons [g, V, 2] and cut-outs [c, W, 2],
    int64 counts and owners; ``(owner int64 [s], start float64 [s, 2], end float64 [s, 2])``); a
    base with count 0 still returns its cut-outs' edges, as there.
    """
    base = np.asarray(base, np.float64)
    cut = np.asarray(cut, np.float64)
    base_count = np.asarray(base_count, np.int64)
    cut_count = np.asarray(cut_count, np.int64)
    cut_owner = np.asarray(cut_owner, np.int64)
    g, n_corner = base.shape[0], base.shape[1]
    n_cut, width = cut.shape[0], cut.shape[1]
    empty = (np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros((0, 2)))
    # the edges: the bases' live ones, then the cut-outs' (the reference's order)
    delta_b = _following(base)
    at_b = np.flatnonzero(corner_slots(base_count, n_corner) & (_lengths(delta_b) > 0))
    delta_c = _following(cut)
    at_c = np.flatnonzero(corner_slots(cut_count, width) & (_lengths(delta_c) > 0))
    rb, rc = at_b // max(n_corner, 1), at_c // max(width, 1)
    n_b, n = len(at_b), len(at_b) + len(at_c)
    if n == 0:
        return empty
    corner = np.concatenate([base.reshape(-1, 2)[at_b], cut.reshape(-1, 2)[at_c]])
    delta = np.concatenate([delta_b.reshape(-1, 2)[at_b], delta_c.reshape(-1, 2)[at_c]])
    owner = np.concatenate([rb, cut_owner[rc]])
    own = np.concatenate([np.zeros(n_b, np.int64), rc])
    is_cut = np.arange(n) >= n_b
    # each base's cut-outs, in their order (CSR); an edge's rows: one per cut-out of its base
    order = np.argsort(cut_owner, kind="stable")
    per_base = np.bincount(cut_owner, minlength=g) if n_cut else np.zeros(g, np.int64)
    first_base = np.cumsum(per_base) - per_base
    per = per_base[owner]
    row_at = np.cumsum(per) - per
    capacity = max(int(per.sum()), 1)
    # the tables: the bases' and the cut-outs' half-planes, the cut-outs' boxes
    if n_cut == 0:                                  # a dummy cut-out (no edge's range holds it)
        cut, cut_count, order = np.zeros((1, max(width, 1), 2)), np.zeros(1, np.int64), np.zeros(1, np.int64)
        width = cut.shape[1]
    lo, hi = cut[:, 0].copy(), cut[:, 0].copy()     # padded with the first corner: the corners' box
    for k in range(1, width):
        np.minimum(lo, cut[:, k], out=lo)
        np.maximum(hi, cut[:, k], out=hi)
    hi_s, lo_s = hi + BOX_SLACK, lo - BOX_SLACK
    f64, u32 = mi.Float64, mi.UInt32
    base_table = _line_table(edge_lines(base, base_count)) + (table_array(u32, np.minimum(base_count, n_corner)),)
    cut_table = _line_table(edge_lines(cut, cut_count)) + (
        table_array(u32, np.minimum(cut_count, width)), table_array(f64, lo_s[:, 0]), table_array(f64, lo_s[:, 1]),
        table_array(f64, hi_s[:, 0]), table_array(f64, hi_s[:, 1]), table_array(u32, order))
    lanes = (device_array(f64, corner[:, 0]), device_array(f64, corner[:, 1]), device_array(f64, delta[:, 0]),
             device_array(f64, delta[:, 1]), device_array(u32, owner), device_array(u32, own),
             device_array(mi.Bool, is_cut), device_array(u32, first_base[owner]), device_array(u32, per),
             device_array(u32, row_at))
    with RECORDING:                     # symbolic loops: recorded and run one thread at a time
        s_row, e_row = dr.zeros(f64, capacity), dr.zeros(f64, capacity)
        edge, rows = _intervals_kernel(lanes, base_table, cut_table, (n_corner, width), (s_row, e_row))
        dr.eval(edge, rows, s_row, e_row)
        a_gap, b_gap = dr.zeros(f64, capacity), dr.zeros(f64, capacity)
        gaps, tail, reach, whole = _gaps_kernel(edge[4], edge[5], rows, lanes[9], (s_row, e_row), (a_gap, b_gap))
        dr.eval(gaps, tail, reach, whole, a_gap, b_gap)
    sx, sy, dx, dy = (x.numpy() for x in edge[:4])
    gaps, tail, reach, whole = gaps.numpy().astype(np.int64), tail.numpy(), reach.numpy(), whole.numpy()
    a_gap, b_gap = a_gap.numpy(), b_gap.numpy()
    # the reference's order: every edge's gaps before its intervals (by edge, then start), the
    # tail gaps (by edge), the edges no interval touches
    with_gaps = np.flatnonzero(gaps)
    slot = np.repeat(row_at[with_gaps] - (np.cumsum(gaps[with_gaps]) - gaps[with_gaps]), gaps[with_gaps]) \
        + np.arange(int(gaps.sum()))
    tails, wholes = np.flatnonzero(tail), np.flatnonzero(whole)
    row = np.concatenate([np.repeat(with_gaps, gaps[with_gaps]), tails, wholes])
    a = np.concatenate([a_gap[slot], reach[tails], np.zeros(len(wholes))])
    b = np.concatenate([b_gap[slot], np.ones(len(tails)), np.ones(len(wholes))])
    o = np.stack([sx, sy], axis=1)[row]
    d = np.stack([dx, dy], axis=1)[row]
    p = o + a[:, None] * d
    q = o + b[:, None] * d
    flip = is_cut[row][:, None]
    return owner[row], np.where(flip, q, p), np.where(flip, p, q)


def _np_max(x, y):
    """``np.maximum(x, y)`` (``x > y ? x : y``: the second of two equal zeros)."""
    return dr.select(x > y, x, y)


def _np_min(x, y):
    """``np.minimum(x, y)`` (``x < y ? x : y``)."""
    return dr.select(x < y, x, y)


def _clip_step(table, k, sx, sy, dx, dy, scaled, on_tol, same_in, other_in, lower, upper, outside):
    """One half-plane ``table[k]`` of the Cyrus-Beck interval of ``s + t d`` (the reference's
    ``_interval_rows``, its arithmetic in its order): the new ``(lower, upper, outside)``."""
    f64 = mi.Float64
    a, b, c, floor_len = (dr.gather(f64, t, k) for t in table[:4])
    has_normal = dr.gather(mi.UInt32, table[4], k) > 0
    num = a * sx + b * sy + c
    den = a * dx + b * dy
    tol = scaled * floor_len
    bound = -num / den
    lower = dr.select(den > tol, _np_max(lower, bound), lower)            # not parallel, entering
    upper = dr.select(den < -tol, _np_min(upper, bound), upper)           # leaving
    # parallel: outside below the line, or on it with the segment not counted inside there
    near = (dr.abs(den) <= tol) & (num <= on_tol)
    on = (dr.abs(num) <= on_tol) & has_normal
    same = (a * -dy + b * dx) > 0
    inside = dr.select(same, same_in, other_in)
    outside |= near & ((~on & (num < 0)) | (on & ~inside))
    return lower, upper, outside


def _interval_ends(lower, upper, outside):
    """``(s, e)`` of an interval's bounds (``e <= s``: empty)."""
    return _np_max(lower, 0.0), _np_min(dr.select(outside, -1.0, upper), 1.0)


def _intervals_kernel(lanes, base_table, cut_table, widths, out):
    """The first kernel of :func:`lit_boundary`: per edge, its start and delta (a cut-out's edge cut
    to its base), whether it lives, and its intervals in the other cut-outs of its base, written
    to ``out`` (``s``, ``e``) from row ``row_at`` on. Returns ``((sx, sy, dx, dy, alive, length),
    rows)``."""
    px, py, dcx, dcy, owner, own, is_cut, first, per, row_at = lanes
    s_row, e_row = out
    f64, u32, b_ = mi.Float64, mi.UInt32, mi.Bool
    n = dr.width(px)
    n_corner, width = (dr.opaque(u32, w) for w in widths)
    inf = dr.full(f64, np.inf, n)
    # the cut-out's edge inside its base (the base's edges are the base's: on one, outside)
    length_c = dr.sqrt(dcx * dcx + dcy * dcy)
    scaled_c, on_tol_c = COINCIDENT * length_c, COINCIDENT * _np_max(length_c, 1.0)
    used_b = dr.select(is_cut, dr.gather(u32, base_table[5], owner), 0)
    line0 = owner * n_corner
    no, yes = dr.zeros(b_, n), dr.full(b_, True, n)

    def base_line(h, lower, upper, outside):
        return (h + 1,) + _clip_step(base_table, line0 + h, px, py, dcx, dcy, scaled_c, on_tol_c, no, yes,
                                     lower, upper, outside)

    _, lower, upper, outside = dr.while_loop((dr.zeros(u32, n), -inf, dr.copy(inf), dr.zeros(b_, n)),
                                             lambda h, *_: h < used_b, base_line, mode=loop_mode(),
                                             label="edge in its base")
    s0, e0 = _interval_ends(lower, upper, outside)
    alive = ~is_cut | (e0 > s0)
    sx = dr.select(is_cut, px + s0 * dcx, px)
    sy = dr.select(is_cut, py + s0 * dcy, py)
    dx = dr.select(is_cut, dcx * (e0 - s0), dcx)
    dy = dr.select(is_cut, dcy * (e0 - s0), dcy)
    length = dr.sqrt(dx * dx + dy * dy)
    scaled, on_tol = COINCIDENT * length, COINCIDENT * _np_max(length, 1.0)
    ex, ey = sx + dx, sy + dy
    lo_x, lo_y, hi_x, hi_y = _np_min(sx, ex), _np_min(sy, ey), _np_max(sx, ex), _np_max(sy, ey)
    stop = dr.select(alive, first + per, first)
    other_in = is_cut

    def candidate(i, rows):
        j = dr.gather(u32, cut_table[10], i)
        meet = ~(is_cut & (j == own))
        meet &= (lo_x <= dr.gather(f64, cut_table[8], j)) & (hi_x >= dr.gather(f64, cut_table[6], j))
        meet &= (lo_y <= dr.gather(f64, cut_table[9], j)) & (hi_y >= dr.gather(f64, cut_table[7], j))
        used = dr.select(meet, dr.gather(u32, cut_table[5], j), 0)
        same_in = ~is_cut | (j < own)
        line0_j = j * width

        def cut_line(h, lower, upper, outside):
            return (h + 1,) + _clip_step(cut_table, line0_j + h, sx, sy, dx, dy, scaled, on_tol, same_in, other_in,
                                         lower, upper, outside)

        _, lower, upper, outside = dr.while_loop((dr.zeros(u32, n), -inf, dr.copy(inf), dr.zeros(b_, n)),
                                                 lambda h, *_: h < used, cut_line, mode=loop_mode(),
                                                 label="edge in a cut-out")
        s, e = _interval_ends(lower, upper, outside)
        real = meet & (e > s)
        dr.scatter(s_row, s, row_at + rows, real)
        dr.scatter(e_row, e, row_at + rows, real)
        return i + 1, rows + dr.select(real, 1, 0)

    _, rows = dr.while_loop((u32(first), dr.zeros(u32, n)), lambda i, _: i < stop, candidate, mode=loop_mode(),
                            label="edge in the other cut-outs")
    return (sx, sy, dx, dy, alive, length), rows


def _gaps_kernel(alive, length, rows, row_at, intervals, out):
    """The second kernel of :func:`lit_boundary`: per edge, the gaps in the union of its
    ``rows`` intervals (from row ``row_at`` of ``intervals``), walked in the order of their
    starts (ties by row), the running end of those before as each gap's start; the kept ones
    (longer than :data:`SHORTEST`) written to ``out`` (``a``, ``b``) from row ``row_at`` on.
    Returns ``(gaps, tail, reach, whole)``: the gaps written, whether the tail gap ``[reach, 1]``
    is kept, the intervals' reach, and whether the edge has no interval and is kept whole."""
    s_row, e_row = intervals
    a_out, b_out = out
    f64, u32 = mi.Float64, mi.UInt32
    n = dr.width(rows)
    inf = dr.full(f64, np.inf, n)
    stop = row_at + rows

    def next_row(t, cur_s, cur_r, reach, gaps):
        # the row after (cur_s, cur_r) in the order of (s, row)
        def scan(r, best_s, best_r):
            s = dr.gather(f64, s_row, r)
            later = (s > cur_s) | ((s == cur_s) & (r > cur_r))
            better = later & (s < best_s)
            return r + 1, dr.select(better, s, best_s), dr.select(better, r, best_r)

        _, s, r = dr.while_loop((u32(row_at), dr.copy(inf), u32(row_at)), lambda r, *_: r < stop, scan,
                                mode=loop_mode(), label="next interval")
        e = dr.gather(f64, e_row, r)
        head = t == 0
        a = dr.select(head, 0.0, reach)
        keep = (s > a) & ((s - a) * length > SHORTEST)
        dr.scatter(a_out, a, row_at + gaps, keep)
        dr.scatter(b_out, s, row_at + gaps, keep)
        reach = dr.select(head, e, _np_max(reach, e))
        return t + 1, s, r, reach, gaps + dr.select(keep, 1, 0)

    _, _, _, reach, gaps = dr.while_loop((dr.zeros(u32, n), -inf, dr.zeros(u32, n), dr.zeros(f64, n),
                                          dr.zeros(u32, n)), lambda t, *_: t < rows, next_row,
                                         mode=loop_mode(), label="gaps")
    touched = rows > 0
    tail = touched & (1.0 > reach) & ((1.0 - reach) * length > SHORTEST)
    whole = alive & ~touched & (length > SHORTEST)
    return gaps, tail, reach, whole
