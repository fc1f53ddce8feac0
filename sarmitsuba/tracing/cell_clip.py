"""The boundary of a cell piece on the aim plane, in Dr.Jit: convex polygons intersected, less
the exact union of occluders' cut-outs (docs/physics.md (T6)).

A piece is ``B_0 ∩ B_1 ∩ ... less (C_1 ∪ ... ∪ C_n)`` with every ``B`` and ``C_i = O_i ∩ H_i``
convex (lists of ``(x, y)`` float64 corners in lattice lines, either orientation, repeated
corners allowed). Its integral in Gordon's edge form needs only its boundary, as oriented
segments: the edges of ``∩ B`` outside every ``C_j``, and the edges of each ``C_i`` inside
``∩ B`` and outside every other ``C_j``, reversed (a hole's boundary runs the other way). Each
segment meets a convex ``C_j`` in one interval, so trimming it by ``n`` cut-outs leaves at most
``n + 1`` pieces: one starting at its start and one at each interval's end (the boundary of a
union of convex polygons, as in computational geometry's polygon-union algorithms). Unlike
inclusion and exclusion, this is exact for any number of overlapping occluders and costs
``O(n^2)`` edges, not ``2^n`` polygons.

Edges on one line (to :data:`COINCIDENT` cells, the rounding of lines that meet exactly: a
wall's foot on the ground seen through two parts) count once: two such edges with their
polygons on one side are one boundary (the earlier polygon's), with their polygons on opposite
sides no boundary at all (two cut-outs that meet) or the piece's own (a cut-out that only
touches the piece).
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi

__all__ = ["COINCIDENT", "orientation", "segments", "boundary", "inside", "pack", "packed_size"]

#: Two edges on one line to this many lattice cells (and parallel to as many radians) are one
#: line: rounding of lines that meet exactly (a wall's foot on the ground seen through two parts).
COINCIDENT = 1e-8


def _clip(p, q, t0, t1):
    """Narrow ``[t0, t1]`` to where ``p t <= q`` (Liang and Barsky 1984); ``p = 0``: all or nothing."""
    safe = dr.select(p != 0, p, 1.0)
    t0 = dr.select(p < 0, dr.maximum(t0, q / safe), t0)
    t1 = dr.select(p > 0, dr.minimum(t1, q / safe), t1)
    return t0, dr.select((p == 0) & (q < 0), -1.0, t1)


def orientation(corners):
    """+1 where the corners run counter-clockwise in ``(x, y)``, -1 where clockwise."""
    (px0, py0), area = corners[0], mi.Float64(0.0)
    for (ax, ay), (bx, by) in zip(corners, corners[1:] + corners[:1]):
        area += (ax - px0) * (by - py0) - (ay - py0) * (bx - px0)
    return dr.select(area >= 0, 1.0, -1.0)


def _narrow(segment, t0, t1, corners, sign, ref_sign, on_line_inside):
    """Narrow ``[t0, t1]`` of ``segment`` (``(ax, ay, dx, dy, length)``: ``a + t d``) to the inside
    of the convex polygon ``corners`` of orientation ``sign`` (Cyrus and Beck 1978). Where an
    edge lies on the segment's line, ``on_line_inside(same)`` (``same``: the polygon lies on the
    segment's side, ``ref_sign`` the segment's orientation) says whether the segment is inside
    it there; where not, the interval empties (``t1 = -1``)."""
    ax, ay, dx, dy, length = segment
    for (cx, cy), (ex, ey) in zip(corners, corners[1:] + corners[:1]):
        fx, fy = ex - cx, ey - cy
        p = -sign * (fx * dy - fy * dx)
        q = sign * (fx * (ay - cy) - fy * (ax - cx))
        f_length = dr.sqrt(fx * fx + fy * fy)
        on_line = (dr.abs(p) <= COINCIDENT * f_length * length) & (dr.abs(q) <= COINCIDENT * f_length) & (f_length > 0)
        same = sign * ref_sign * (fx * dx + fy * dy) > 0
        t1 = dr.select(on_line & ~on_line_inside(same), -1.0, t1)
        t0, t1 = _clip(dr.select(on_line, 0.0, p), dr.select(on_line, 0.0, q), t0, t1)
    return t0, t1


def segments(polygons, first: int = 0):
    """The boundary of the intersection of convex ``polygons`` as segments ``(x0, y0, x1, y1,
    exists)``, all in the first polygon's orientation: each edge of ``polygons[first:]`` clipped
    to all the others. An edge on the line of a same-side edge of an earlier polygon is left to
    that one; on an opposite-side edge, the polygons only touch (no boundary)."""
    signs = [orientation(c) for c in polygons]
    out = []
    for n in range(first, len(polygons)):
        corners, flip = polygons[n], signs[n] != signs[0]
        for a, b in zip(corners, corners[1:] + corners[:1]):
            ax, ay = dr.select(flip, b[0], a[0]), dr.select(flip, b[1], a[1])
            dx, dy = dr.select(flip, a[0], b[0]) - ax, dr.select(flip, a[1], b[1]) - ay
            segment = (ax, ay, dx, dy, dr.sqrt(dx * dx + dy * dy))
            t0, t1 = mi.Float64(0.0), mi.Float64(1.0)
            for other in range(len(polygons)):
                if other != n:
                    t0, t1 = _narrow(segment, t0, t1, polygons[other], signs[other], signs[0],
                                     lambda same, other=other: same & mi.Bool(other > n))
            out.append((ax + t0 * dx, ay + t0 * dy, ax + t1 * dx, ay + t1 * dy, ((dx != 0) | (dy != 0)) & (t1 > t0)))
    return out


def _trim(segment, intervals):
    """``segment`` less the parameter ``intervals`` ``[(s, e)]`` (empty where ``e <= s``): up to
    ``len(intervals) + 1`` segments, starting at 0 and at each interval's end that lies in no
    other interval (each start once), ending at the next interval's start or at 1."""
    x0, y0, x1, y1, exists = segment
    dx, dy = x1 - x0, y1 - y0
    starts = [(mi.Float64(0.0), mi.Bool(True))] + [(e, e > s) for s, e in intervals]
    out = []
    for k, (a, ok) in enumerate(starts):
        live = exists & ok & (a < 1.0)
        for s, e in intervals:
            live &= ~((e > s) & (s <= a) & (a < e))
        for a_earlier, ok_earlier in starts[1:k]:
            live &= ~(ok_earlier & (a_earlier == a))
        b = mi.Float64(1.0)
        for s, e in intervals:
            b = dr.select((e > s) & (s > a), dr.minimum(b, s), b)
        out.append((x0 + a * dx, y0 + a * dy, x0 + b * dx, y0 + b * dy, live & (b > a)))
    return out


def _cut_intervals(segment, cutouts, signs, ref_sign, skip, on_line_inside):
    """The parameter interval of ``segment`` inside each cut-out but ``skip``: ``[(s, e)]``."""
    x0, y0, x1, y1, _ = segment
    dx, dy = x1 - x0, y1 - y0
    line = (x0, y0, dx, dy, dr.sqrt(dx * dx + dy * dy))
    out = []
    for j, (polygons, live) in enumerate(cutouts):
        if j == skip:
            continue
        s, e = mi.Float64(0.0), mi.Float64(1.0)
        for poly, sign in zip(polygons, signs[j]):
            s, e = _narrow(line, s, e, poly, sign, ref_sign, lambda same, j=j: on_line_inside(same, j))
        out.append((s, dr.select(live, e, -1.0)))
    return out


def boundary(base, cutouts):
    """The oriented boundary of ``∩ base`` less the union of the cut-outs ``cutouts``
    (``[(polygons, live)]``: each the intersection of its convex ``polygons``, none where not
    ``live``), in ``base[0]``'s orientation: ``[(x0, y0, x1, y1, exists)]``, ``(m_b + 1)(n + 1)
    + n^2 m_c`` of them for ``m_b`` base edges, ``n`` cut-outs of ``m_c`` edges each."""
    ref = orientation(base[0])
    signs = [[orientation(p) for p in polygons] for polygons, _ in cutouts]
    out = []
    for segment in segments(base):                 # the piece's own edges, outside every cut-out
        out += _trim(segment, _cut_intervals(segment, cutouts, signs, ref, None, lambda same, j: same))
    for i, (polygons, live) in enumerate(cutouts):  # each cut-out's edges in the piece, outside the others
        for x0, y0, x1, y1, exists in segments(base + list(polygons), first=len(base)):
            segment = (x0, y0, x1, y1, exists & live)
            rule = (lambda same, j, i=i: ~same | mi.Bool(j < i))    # meeting cut-outs: no boundary between them
            out += [(b0, b1, a0, a1, ok) for a0, a1, b0, b1, ok in
                    _trim(segment, _cut_intervals(segment, cutouts, signs, ref, i, rule))]
    return out


def inside(x, y, base, cutouts):
    """Whether the point ``(x, y)`` lies in every ``base`` polygon and in no live cut-out (closed
    polygons): mi.Bool."""
    def held(polygons):
        ok = mi.Bool(True)
        for corners in polygons:
            sign = orientation(corners)
            for (ax, ay), (bx, by) in zip(corners, corners[1:] + corners[:1]):
                ok &= sign * ((bx - ax) * (y - ay) - (by - ay) * (x - ax)) >= 0
        return ok
    out = held(base)
    for polygons, live in cutouts:
        out &= ~(live & held(polygons))
    return out


def packed_size(n_base: int, n_cut: int, corners: int) -> int:
    """The most segments :func:`pack` can give: ``n_base`` polygons and ``n_cut`` cut-outs of two
    polygons each, every polygon padded to ``corners`` corners, each edge in ``n_cut + 1`` pieces."""
    return (n_base + 2 * n_cut) * corners * (n_cut + 1)


def pack(base, cutouts):
    """:func:`boundary`'s live segments packed into local memory by a symbolic loop over the
    polygons' edges (one edge, clipped and trimmed into its up to ``n + 1`` pieces, per
    iteration), so that the code's size grows with the number of edges, not with its square
    times the cut-outs. At most :func:`packed_size` segments. Returns ``(ends,
    count)``: four ``dr.Local`` float64 buffers (x0, y0, x1, y1) holding ``count`` segments
    (mi.UInt32), in :func:`boundary`'s orientation; the same set of segments (tested)."""
    polygons = list(base) + [p for polys, _ in cutouts for p in polys]
    widths = {len(polys) for polys, _ in cutouts}
    assert widths <= {2} or not cutouts, "each cut-out is a projection and a half-plane"
    cap = max(len(p) for p in polygons)
    polygons = [p + [p[-1]] * (cap - len(p)) for p in polygons]     # repeated corners: empty edges
    signs = [orientation(p) for p in polygons]
    n_base, n_cut = len(base), len(cutouts)
    n_edges = len(polygons) * cap
    size = packed_size(n_base, n_cut, cap)
    corner_x, corner_y = dr.alloc_local(mi.Float64, n_edges), dr.alloc_local(mi.Float64, n_edges)
    sign_of = dr.alloc_local(mi.Float64, len(polygons))
    for k, corners in enumerate(polygons):
        sign_of[k] = signs[k]
        for c, (x, y) in enumerate(corners):
            corner_x[k * cap + c], corner_y[k * cap + c] = x, y
    ends = [dr.alloc_local(mi.Float64, size) for _ in range(4)]

    def edge_step(t, count, *ends):      # buffers written in a loop are its state
        k, c = t // cap, t % cap
        nxt = k * cap + (c + 1) % cap
        flip = sign_of[k] != signs[0]
        a = (corner_x[t], corner_y[t])
        b = (corner_x[nxt], corner_y[nxt])
        ax, ay = dr.select(flip, b[0], a[0]), dr.select(flip, b[1], a[1])
        dx, dy = dr.select(flip, a[0], b[0]) - ax, dr.select(flip, a[1], b[1]) - ay
        segment = (ax, ay, dx, dy, dr.sqrt(dx * dx + dy * dy))
        own_cut = dr.select(k >= n_base, mi.Int32(k - n_base) // 2, -1)
        t0, t1 = mi.Float64(0.0), mi.Float64(1.0)
        for other, corners in enumerate(polygons):      # the region the edge bounds: base ∩ its cut-out
            if other >= n_base:
                applies = (own_cut == (other - n_base) // 2) & (k != other)
            else:
                applies = k != other
            n0, n1 = _narrow(segment, t0, t1, corners, signs[other], signs[0],
                             lambda same, other=other: same & (k < other))
            t0, t1 = dr.select(applies, n0, t0), dr.select(applies, n1, t1)
        live = (dx != 0) | (dy != 0)
        for j, (_, on) in enumerate(cutouts):
            live &= (own_cut != j) | on
        clipped = (ax + t0 * dx, ay + t0 * dy, ax + t1 * dx, ay + t1 * dy, live & (t1 > t0))
        x0, y0, x1, y1, exists = clipped
        ex, ey = x1 - x0, y1 - y0
        line = (x0, y0, ex, ey, dr.sqrt(ex * ex + ey * ey))
        intervals = []
        for j, (polys, on) in enumerate(cutouts):       # the parts inside the other cut-outs
            s, e = mi.Float64(0.0), mi.Float64(1.0)
            for p in range(2):
                other = n_base + 2 * j + p
                s, e = _narrow(line, s, e, polygons[other], signs[other], signs[0],
                               lambda same, j=j: dr.select(own_cut < 0, same, ~same | (j < own_cut)))
            intervals.append((s, dr.select(on & (own_cut != j), e, -1.0)))
        reverse = own_cut >= 0
        for piece in _trim(clipped, intervals):
            px0, py0, px1, py1, ok = piece
            for buffer, value in zip(ends, (dr.select(reverse, px1, px0), dr.select(reverse, py1, py0),
                                            dr.select(reverse, px0, px1), dr.select(reverse, py0, py1))):
                buffer[count] = value
            count = count + dr.select(ok & exists, mi.UInt32(1), mi.UInt32(0))
        return (t + 1, count, *ends)

    # a varying count must start at full width: a literal start indexes every lane's buffer with
    # the first lane's count (Dr.Jit 1.5, LLVM)
    start = dr.zeros(mi.UInt32, dr.width(polygons[0][0][0]))
    _, count, *ends = dr.while_loop((mi.UInt32(0), start, *ends), lambda t, count, *_: t < n_edges, edge_step,
                                    label="cell_boundary")
    return ends, count
