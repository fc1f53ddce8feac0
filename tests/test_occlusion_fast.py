"""The fast kernels of :mod:`sarmitsuba.tracing.visibility.occlusion` against readable references written out
here (issue 56): :func:`shadow_lines` (per live corner, per distinct chain and occluder),
:func:`lit_boundary` (line-major Cyrus-Beck intervals, only the parallel pairs tested one by
one), :func:`segment_moments` (boxes by sorted ``reduceat``) and the areas of :func:`clip_mixed`'s
dark test. The references share no helper with the code they check: the geometry they need
(the unfolded windows' planes, the crossings' order, a 3-D half-space restricted to a face,
the half-planes of a polygon's edges, Cyrus-Beck clipping, the union of an edge's intervals,
the shoelace area) is written out below from docs/physics.md (M3), (M4), so a bug in a helper
of :mod:`sarmitsuba.tracing.visibility.occlusion`, :mod:`~sarmitsuba.tracing.discovery.chains` or
:mod:`~sarmitsuba.tracing.mesh.polygons` that the fast kernel uses shows as a difference. The
comparisons are to the bit where the arithmetic is the same and to 1e-12 where only the order
of a sum changed. Inputs include the degenerate cases: no cut-outs, empty bases, zero-length
edges, cut-outs along the base's edges and along each other's (both sides), a cut-out that is
the whole base, occluders with the most corners a part has, and segments on, parallel to and
outside a polygon's lines.

Deliberate bugs these tests fail (each planted in a copy of the package; those marked * passed
the former references, which called the same helper): ``_crossing_before``'s difference of the
two planes' terms reversed*; ``_window_planes``' unfolded offset without the shift*, or its
normal negated*; ``BOX_SLACK`` negative (-1e-3)*; ``chains.to_face_lines`` with a face-parallel
plane's everywhere and nowhere swapped*; ``chains.unfolded_frame``'s origin carried with
``- shift``*; ``polygons.edge_lines`` with the edges' normals turned outward*; ``_interval`` or
``_interval_rows`` with a parallel segment outside when above its line; :func:`lit_boundary`'s
box test with the boxes' low and high ends swapped.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from sarmitsuba.tracing.visibility.cut_outs import polygon_areas
from sarmitsuba.tracing.visibility.occlusion import _interval, _interval_rows, lit_boundary, segment_moments, \
    shadow_lines, shared_shadow_lines
from sarmitsuba.tracing.mesh.polygons import clip, moments
from test_patch_geometry import all_chains, antennas, batch, convex, quad, surfaces

#: The half-plane ``0 x + 0 y + 1 >= 0``, which holds everywhere: the padding slots of a table of
#: half-planes (``polygons.EVERYTHING``).
EVERYWHERE = (0.0, 0.0, 1.0)
#: Two edges on one line to this fraction of a segment's length (and parallel to as many
#: radians) are one line (``occlusion.COINCIDENT``, the contract of docs/physics.md (M4)).
COINCIDENT = 1e-9


# --------------------------------------------------------------------------- geometry, written out
def _frame(s, part):
    """The face frame of parts ``part``: the frame's origin projected on the plane, ``u``, ``v``."""
    origin, normal = s.origin[part], s.normal[part]
    return origin + normal * (s.offset[part] - np.sum(origin * normal, axis=-1))[..., None], s.axis_u[part], s.axis_v[part]


def _corners(s, part):
    """The world corners [k, V, 3] of parts ``part`` [k] (padding slots included)."""
    o, u, v = _frame(s, part)
    poly = s.polygon[part]
    return o[:, None] + poly[..., :1] * u[:, None] + poly[..., 1:] * v[:, None]


def _on_face(g, h, origin, u, v):
    """The half-space ``g . y + h >= 0`` of points ``y = origin + x u + y v`` of a plane, as the face
    half-plane ``a x + b y + c >= 0`` with ``(a, b)`` unit; a plane parallel to the face (``(a, b)``
    below 1e-12 of ``|g|``) holds everywhere or nowhere: ``(0, 0, +-1)``."""
    a, b = np.sum(g * u, axis=1), np.sum(g * v, axis=1)
    c = np.sum(g * origin, axis=1) + h
    norm = np.hypot(a, b)
    flat = norm <= 1e-12 * np.linalg.norm(g, axis=1)
    safe = np.where(flat, 1.0, norm)
    return np.stack([np.where(flat, 0.0, a / safe), np.where(flat, 0.0, b / safe),
                     np.where(flat, np.where(c >= 0, 1.0, -1.0), c / safe)], axis=1)


def _edges(poly, count):
    """Each slot's edge to the next corner of its polygon (cyclic within ``count``): start [n, V, 2],
    vector [n, V, 2], and whether the slot holds an edge of nonzero length."""
    width = poly.shape[1]
    slot = np.arange(width)[None, :]
    following = np.where(slot + 1 < count[:, None], slot + 1, 0)
    vector = np.take_along_axis(poly, following[..., None], axis=1) - poly
    live = (slot < count[:, None]) & (np.hypot(vector[..., 0], vector[..., 1]) > 0)
    return poly, vector, live


def _polygon_lines(poly, count):
    """The half-planes of convex counter-clockwise polygons, one per edge, ``(a, b)`` the unit
    inward normal (the edge turned left), :data:`EVERYWHERE` for slots with no edge."""
    start, vector, live = _edges(poly, count)
    length = np.where(live, np.sqrt(vector[..., 0] * vector[..., 0] + vector[..., 1] * vector[..., 1]), 1.0)
    a, b = -vector[..., 1] / length, vector[..., 0] / length
    c = -(a * start[..., 0] + b * start[..., 1])
    return np.where(live[..., None], np.stack([a, b, c], axis=-1), EVERYWHERE)


def _clip_interval(start, delta, lines, on_line_inside):
    """Cyrus and Beck (1978): the parameters ``[s, e]`` of the part of each segment ``start + t delta``
    (``t`` in [0, 1]; [m, 2]) inside its convex polygon, given by half-planes ``lines`` [m, H, 3];
    ``e <= s``: none. A segment on one of the lines (parallel to it within :data:`COINCIDENT`
    radians, on it within COINCIDENT of the segment's length, or of a metre) counts as inside it
    where ``on_line_inside(left)`` [m, H] holds, ``left`` whether the polygon lies on the
    segment's left; a segment parallel to a line and below it is outside."""
    a, b, c = lines[..., 0], lines[..., 1], lines[..., 2]
    x, y, dx, dy = start[:, None, 0], start[:, None, 1], delta[:, None, 0], delta[:, None, 1]
    value = a * x + b * y + c                    # the start's height over each line
    rate = a * dx + b * dy                       # its change along the segment
    length = np.sqrt(dx * dx + dy * dy)
    unit = np.hypot(a, b)
    parallel = np.abs(rate) <= COINCIDENT * length * np.maximum(unit, 1e-300)
    on = parallel & (np.abs(value) <= COINCIDENT * np.maximum(length, 1.0)) & (unit > 0)
    left = (a * -dy + b * dx) > 0
    outside = parallel & np.where(on, ~on_line_inside(left), value < 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -value / rate
    enter = np.where(~parallel & (rate > 0), t, -np.inf).max(axis=1)
    leave = np.where(~parallel & (rate < 0), t, np.inf).min(axis=1)
    return np.maximum(enter, 0.0), np.where(outside.any(axis=1), -1.0, np.minimum(leave, 1.0))


# --------------------------------------------------------------------------- references
def shadow_lines_reference(surfaces, chains, chain, occluder, leg, antenna):
    """docs/physics.md (M4): the half-planes of the points ``x`` of chain ``chain``'s last part whose
    path the part ``occluder`` hides on leg ``leg``, seen from ``antenna``; on the way out in the
    unfolded frame (``y = U_d(x)``, the occluder carried by ``U_leg``), on the return leg in the
    scene. Slots: 0 the occluder's plane crossed beyond the antenna, 1 before the next window (or
    before the point, on the last leg), 2 after the previous window (legs after the first), 3 on
    the planes through the antenna and each of the occluder's edges."""
    depth = chains.parts.shape[1]
    k, width = len(chain), surfaces.polygon.shape[1]
    rows = np.arange(k)
    order = chains.order[chain]
    last = chains.parts[chain, order]
    back = (leg == depth) | ((order == 0) & (leg == 0))          # the return leg (or the first bounce)
    level = np.where(back, 0, leg)
    lin = np.where(back[:, None, None], np.eye(3), chains.lin[chain, level])
    shift = np.where(back[:, None], 0.0, chains.shift[chain, level])

    def carried(i, vector):                                       # the linear part of U_i, row by row
        return np.einsum("kij,kj->ki", chains.lin[chain, i], vector)

    # the occluder in the leg's frame: its plane n . y = c and its corners
    normal = np.einsum("kij,kj->ki", lin, surfaces.normal[occluder])
    offset = surfaces.offset[occluder] + np.sum(normal * shift, axis=1)
    corners = np.einsum("kij,kvj->kvi", lin, _corners(surfaces, occluder)) + shift[:, None]
    a = offset - np.sum(normal * antenna, axis=1)                 # a_O = c_O - n_O . A
    sign = np.where(a >= 0, 1.0, -1.0)[:, None]
    # the frame the half-planes act on: the last part's, carried by U_d on the way out
    o, u, v = _frame(surfaces, last)
    unfolded = np.einsum("kij,kj->ki", chains.lin[chain, order], o) + chains.shift[chain, order]
    origin = np.where(back[:, None], o, unfolded)
    u = np.where(back[:, None], u, carried(order, u))
    v = np.where(back[:, None], v, carried(order, v))

    def window(i):                                                # window i unfolded: n_i, a_i = c_i - n_i . A
        part = np.maximum(chains.parts[chain, i], 0)
        n_i = carried(i, surfaces.normal[part])
        return n_i, surfaces.offset[part] + np.sum(n_i * chains.shift[chain, i], axis=1) - np.sum(n_i * antenna, axis=1)

    def earlier(n_1, a_1, n_2, a_2):                              # t_1 < t_2: (n_1 / a_1 - n_2 / a_2) . (y - A) > 0
        g = n_1 / np.where(a_1 != 0, a_1, 1.0)[:, None] - n_2 / np.where(a_2 != 0, a_2, 1.0)[:, None]
        return g, -np.sum(g * antenna, axis=1)

    lines = np.tile(np.asarray(EVERYWHERE), (k, width + 3, 1))
    lines[:, 0] = _on_face(sign * normal, -np.sum(sign * normal * antenna, axis=1), origin, u, v)
    n_next, a_next = window(np.minimum(leg, depth - 1))
    g_next, h_next = earlier(normal, a, n_next, a_next)
    last_leg = back | (leg == order)                              # crossed before the point: sign (n . y - c) > 0
    lines[:, 1] = _on_face(np.where(last_leg[:, None], sign * normal, g_next),
                           np.where(last_leg, -sign[:, 0] * offset, h_next), origin, u, v)
    n_prev, a_prev = window(np.maximum(leg - 1, 0))
    g_prev, h_prev = earlier(n_prev, a_prev, normal, a)
    lines[:, 2] = np.where((~back & (leg > 0))[:, None], _on_face(g_prev, h_prev, origin, u, v), EVERYWHERE)
    count = surfaces.n_corners[occluder]
    live = np.arange(width)[None, :] < count[:, None]
    centre = np.where(live[..., None], corners, 0.0).sum(axis=1) / count[:, None]
    for e in range(width):
        p = corners[:, e] - antenna
        q = corners[rows, np.where(e + 1 < count, e + 1, 0)] - antenna
        g = np.cross(p, q)
        g *= np.where(np.sum(g * (centre - antenna), axis=1) >= 0, 1.0, -1.0)[:, None]     # facing the occluder
        lines[:, 3 + e] = np.where(live[:, e, None], _on_face(g, -np.sum(g * antenna, axis=1), origin, u, v), EVERYWHERE)
    return lines


def lit_boundary_reference(base, base_count, cut, cut_count, cut_owner):
    """docs/physics.md (M4): the lit part ``B - (C_1 u ... u C_n)`` of each base as its boundary: the
    base's edges outside every cut-out, and, reversed, each cut-out's edges inside its base and
    outside the others. Every edge is clipped against every other cut-out of its base (no box
    test), and the parts left are the gaps in the union of its intervals. On one line, the
    base's edge gives way to a cut-out on its side; a cut-out's edge to the base's edge
    (its inside on the same side) and to a cut-out on the other side, or an earlier one on the
    same side."""
    g = len(base)
    base_lines, cut_lines = _polygon_lines(base, base_count), _polygon_lines(cut, cut_count)
    p_b, d_b, live_b = _edges(base, base_count)
    p_c, d_c, live_c = _edges(cut, cut_count)
    rb, kb = np.nonzero(live_b)
    rc, kc = np.nonzero(live_c)
    s0, e0 = _clip_interval(p_c[rc, kc], d_c[rc, kc], base_lines[cut_owner[rc]], lambda left: ~left)
    inner = e0 > s0
    rc, kc, s0, e0 = rc[inner], kc[inner], s0[inner], e0[inner]
    start = np.concatenate([p_b[rb, kb], p_c[rc, kc] + s0[:, None] * d_c[rc, kc]])
    delta = np.concatenate([d_b[rb, kb], d_c[rc, kc] * (e0 - s0)[:, None]])
    owner = np.concatenate([rb, cut_owner[rc]])
    own = np.concatenate([np.full(len(rb), -1), rc])              # -1: the base's edge
    # every edge against every other cut-out of its base
    of_base = {b: np.flatnonzero(cut_owner == b) for b in range(g)}
    pairs = [(i, j) for i in range(len(owner)) for j in of_base[owner[i]] if j != own[i]]
    edge, other = (np.array([x[c] for x in pairs], np.int64).reshape(-1) for c in (0, 1))
    is_base, before = (own[edge] < 0)[:, None], (other < own[edge])[:, None]
    s, e = _clip_interval(start[edge], delta[edge], cut_lines[other],
                          lambda left: np.where(is_base, left, ~left | before))
    real = e > s
    edge, s, e = edge[real], s[real], e[real]
    # the gaps in the union of each edge's intervals: sorted by start, after the running end
    rank = np.lexsort((s, edge))
    edge, s, e = edge[rank], s[rank], e[rank]
    reach = np.maximum.accumulate(e + 2.0 * edge) - 2.0 * edge
    head = np.ones(len(edge), bool)
    head[1:] = edge[1:] != edge[:-1]
    after = np.where(head, 0.0, np.roll(reach, 1))
    tail = np.ones(len(edge), bool)
    tail[:-1] = edge[1:] != edge[:-1]
    untouched = np.setdiff1d(np.arange(len(owner)), edge)
    row = np.concatenate([edge, edge[tail], untouched])
    a = np.concatenate([after, reach[tail], np.zeros(len(untouched))])
    b = np.concatenate([s, np.ones(int(tail.sum())), np.ones(len(untouched))])
    keep = (b > a) & ((b - a) * np.linalg.norm(delta[row], axis=1) > 1e-12)
    row, a, b = row[keep], a[keep], b[keep]
    p = start[row] + a[:, None] * delta[row]
    q = start[row] + b[:, None] * delta[row]
    flip = own[row] >= 0
    p, q = np.where(flip[:, None], q, p), np.where(flip[:, None], p, q)
    return owner[row], p, q


def areas_reference(poly, count):
    """The shoelace area of each polygon's ``count`` corners, about its first corner."""
    out = np.zeros(len(poly))
    for r in range(len(poly)):
        if count[r] >= 3:
            x, y = poly[r, :count[r], 0] - poly[r, 0, 0], poly[r, :count[r], 1] - poly[r, 0, 1]
            out[r] = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    return out


def segment_moments_reference(owner, start, end, n):
    x0, y0, x1, y1 = start[:, 0], start[:, 1], end[:, 0], end[:, 1]
    cross = x0 * y1 - x1 * y0
    area = 0.5 * np.bincount(owner, weights=cross, minlength=n)
    safe = np.where(area != 0, area, 1.0)
    cx = np.bincount(owner, weights=(x0 + x1) * cross, minlength=n) / (6 * safe)
    cy = np.bincount(owner, weights=(y0 + y1) * cross, minlength=n) / (6 * safe)
    ixx = np.bincount(owner, weights=(x0 * x0 + x0 * x1 + x1 * x1) * cross, minlength=n) / 12 - area * cx * cx
    iyy = np.bincount(owner, weights=(y0 * y0 + y0 * y1 + y1 * y1) * cross, minlength=n) / 12 - area * cy * cy
    ixy = np.bincount(owner, weights=(x0 * y1 + 2 * x0 * y0 + 2 * x1 * y1 + x1 * y0) * cross, minlength=n) / 24 \
        - area * cx * cy
    lo = np.full((n, 2), np.inf)
    hi = np.full((n, 2), -np.inf)
    for point in (start, end):
        np.minimum.at(lo, owner, point)
        np.maximum.at(hi, owner, point)
    diagonal = np.where(np.isfinite(lo[:, 0]), np.linalg.norm(hi - lo, axis=1), 0.0)
    return area, np.stack([cx, cy], axis=1), np.stack([ixx, ixy, iyy], axis=1), diagonal


# --------------------------------------------------------------------------- inputs
def octagon(centre, e1, e2):
    """A flat regular octagon (a fan of six triangles: one part with eight corners)."""
    angle = np.arange(8) * np.pi / 4
    c, e1, e2 = (np.asarray(x, float) for x in (centre, e1, e2))
    return c + np.cos(angle)[:, None] * e1 + np.sin(angle)[:, None] * e2, np.array([[0, i, i + 1] for i in range(1, 7)])


def scene_with_octagon(rng):
    """Ground, a wall, a tilted plate, a tilted octagon (the widest part: its slots are full) and a
    level plate turned off the axes (parallel to the ground: its plane's half-space holds on the
    ground everywhere or nowhere)."""
    return surfaces([quad((0, 0, 0), (10, 0, 0), (0, 10, 0)),
                     quad((0, -2, 3), (6, 0, 0), (0, 0, 3)),
                     quad(np.array([1, 3, 4.0]) + rng.normal(size=3) * 0.5, (1.5, 0.5, 0.3), (0.0, 1.0, 1.0)),
                     octagon(np.array([-2, 1, 2.0]) + rng.normal(size=3) * 0.5, (1.0, 0.2, 0.3), (0.3, 0.8, 0.9)),
                     quad((3.1, -4.2, 5.3), (1.2, 0.4, 0.0), (-0.3, 0.9, 0.0))])


def all_triples(s, seqs, depth):
    chain, occluder, leg = [], [], []
    for i, seq in enumerate(seqs):
        d = len(seq) - 1
        for o in range(s.n_parts):
            if o in seq:
                continue
            for lg in list(range(d + 1)) + ([depth] if d > 0 else []):
                chain.append(i)
                occluder.append(o)
                leg.append(lg)
    return np.array(chain), np.array(occluder), np.array(leg)


def close(new, ref, rel=1e-12):
    assert new.shape == ref.shape and new.dtype == ref.dtype
    assert np.array_equal(np.isfinite(new), np.isfinite(ref))
    fin = np.isfinite(ref)
    assert np.abs(new[fin] - ref[fin]).max(initial=0.0) <= rel * max(1.0, np.abs(ref[fin]).max(initial=0.0))


# --------------------------------------------------------------------------- shadow lines
def test_shadow_lines_are_the_reference():
    """Every (chain, occluder, leg) of a scene with an eight-corner occluder, from two antennas."""
    rng = np.random.default_rng(3)
    s = scene_with_octagon(rng)
    assert s.n_corners.max() == s.polygon.shape[1] == 8
    seqs, chains = all_chains(s)
    chain, occluder, leg = all_triples(s, seqs, chains.parts.shape[1])
    for antenna in antennas(rng):
        a = np.repeat(antenna[None], len(chain), 0)
        close(shadow_lines(s, chains, chain, occluder, leg, a), shadow_lines_reference(s, chains, chain, occluder, leg, a))
    # no rows
    none = np.zeros(0, np.int64)
    assert shadow_lines(s, chains, none, none, none, np.zeros((0, 3))).shape == (0, s.polygon.shape[1] + 3, 3)


def test_shared_shadow_lines_are_the_reference_per_pair():
    """Repeated (chain, occluder, leg) rows in shuffled order, two antennas per chain."""
    rng = np.random.default_rng(4)
    s = scene_with_octagon(rng)
    seqs, chains = all_chains(s)
    chain, occluder, leg = all_triples(s, seqs, chains.parts.shape[1])
    pick = rng.integers(0, len(chain), 3 * len(chain))
    ants = [np.array([antenna + rng.normal(size=3) for _ in range(len(chains))]) for antenna in antennas(rng)]
    got = shared_shadow_lines(s, chains, chain[pick], occluder[pick], leg[pick], *ants)
    assert len(got) == 2
    for lines, antenna in zip(got, ants):
        c = chain[pick]
        close(lines, shadow_lines_reference(s, chains, c, occluder[pick], leg[pick], antenna[c]))


# --------------------------------------------------------------------------- Cyrus-Beck intervals
def test_interval_rows_is_cyrus_beck():
    """Segments crossing, inside, outside, on and parallel to convex polygons' lines (the polygon
    on either side), zero-length, against padded and nowhere rows: :func:`_interval_rows` (and
    :func:`_interval`, which :func:`boundary` uses) give the same bits as Cyrus and Beck's
    clipping written out here."""
    rng = np.random.default_rng(5)
    polys = [convex(rng, k=rng.integers(3, 9)) for _ in range(40)] + [np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])]
    poly, count = batch(polys)
    table = _polygon_lines(poly, count)
    table[3, :count[3]] = np.array([0.0, 0.0, -1.0])          # a nowhere polygon (an empty cut-out)
    starts, deltas, rows = [], [], []
    for r in range(len(polys)):
        for _ in range(30):
            starts.append(rng.normal(size=2))
            deltas.append(rng.normal(size=2) * rng.choice([0.0, 0.1, 1.0, 3.0]))
            rows.append(r)
        n = count[r]
        for k in range(n):                                    # along each edge, both ways, and offset
            p, q = poly[r, k], poly[r, (k + 1) % n]
            for a, b in ((p, q), (q, p), (p + 0.25 * (q - p), p + 0.5 * (q - p)), (p - (q - p), q + (q - p))):
                for shift in (0.0, 1e-13, 1e-3, -1e-3):
                    normal = np.array([-(q - p)[1], (q - p)[0]])
                    starts.append(a + shift * normal)
                    deltas.append(b - a)
                    rows.append(r)
    start, delta, row = np.array(starts), np.array(deltas), np.array(rows)
    flags = rng.random((2, len(row))) < 0.5
    for inside_same, inside_other in ((False, True), (True, False), (flags[0], flags[1])):
        rule = (lambda left: np.where(left, np.broadcast_to(inside_same, row.shape)[:, None],   # noqa: E731
                                      np.broadcast_to(inside_other, row.shape)[:, None]))
        ref = _clip_interval(start, delta, table[row], rule)
        assert np.any(ref[1] > ref[0]) and np.any(ref[1] <= ref[0])
        for new in [_interval(start, delta, table[row], rule)] + \
                [_interval_rows(start, delta, table, row, inside_same, inside_other, used) for used in (None, count)]:
            for x, y in zip(new, ref):                        # all slots, or only each polygon's lines
                assert np.array_equal(x, y)
    assert all(len(x) == 0 for x in _interval_rows(start[:0], delta[:0], table, row[:0], False, True))


# --------------------------------------------------------------------------- lit boundaries
def pieces_and_cut_outs(rng, groups=200, n_cut=5):
    """Bases (random convex, squares, some empty or with a repeated corner) and their cut-outs: half
    planes through them (sharing their edges), cut-outs adjacent along a shared edge, the same
    cut-out twice, the whole base, and random convex ones; flat, in owner order."""
    bases, cuts, owners = [], [], []
    for g in range(groups):
        base = np.array([[0, 0], [1.7, 0], [1.7, 1.7], [0, 1.7]]) if g % 3 == 0 else convex(rng, k=7)
        if g % 17 == 5:
            base = np.insert(base, 1, base[1], axis=0)[:8]    # a zero-length edge
        bases.append(base)
        b_all, bc_all = batch([base])
        mine = []
        for _ in range(int(rng.integers(0, n_cut + 1))):
            kind = rng.integers(0, 6)
            if kind == 0:
                angle = rng.uniform(0, 2 * np.pi)
                poly_c, count_c = clip(b_all, bc_all, np.array([[[math.cos(angle), math.sin(angle), rng.normal() * 0.3]]]))
            elif kind == 1 and mine:
                p0, p1 = mine[-1][0], mine[-1][1]
                out = np.array([p1[1] - p0[1], -(p1[0] - p0[0])])
                poly_c, count_c = batch([np.array([p1, p0, p0 + out * 0.5, p1 + out * 0.5])], 16)
                poly_c, count_c = clip(poly_c, count_c, _polygon_lines(b_all, bc_all))
            elif kind == 2 and mine:
                poly_c, count_c = batch([mine[-1]], 16)
            elif kind == 3:
                poly_c, count_c = clip(b_all, bc_all, np.array([[EVERYWHERE]]))
            else:
                poly_c, count_c = batch([convex(rng, centre=rng.normal(size=2) * 0.6, scale=0.4)], 16)
                poly_c, count_c = clip(poly_c, count_c, _polygon_lines(b_all, bc_all))
            if count_c[0] >= 3:
                mine.append(poly_c[0][:count_c[0]])
        cuts += mine
        owners += [g] * len(mine)
    base_poly, base_count = batch(bases)
    base_count[::23] = 0                                       # bases that return nothing
    cut_poly, cut_count = batch(cuts, 16)
    return base_poly, base_count, cut_poly, cut_count, np.array(owners, np.int64)


@pytest.mark.parametrize("seed", [7, 8])
def test_lit_boundary_is_the_reference(seed):
    rng = np.random.default_rng(seed)
    base, base_count, cut, cut_count, owner = pieces_and_cut_outs(rng)
    cases = [(cut, cut_count, owner), (cut[:0], cut_count[:0], owner[:0])]
    shuffled = rng.permutation(len(owner))                    # owners not in order
    cases.append((cut[shuffled], cut_count[shuffled], owner[shuffled]))
    for c, cc, o in cases:
        new, ref = lit_boundary(base, base_count, c, cc, o), lit_boundary_reference(base, base_count, c, cc, o)
        assert np.array_equal(new[0], ref[0])
        close(new[1], ref[1])
        close(new[2], ref[2])


# --------------------------------------------------------------------------- moments
def test_segment_moments_are_the_reference():
    """Closed boundaries of random polygons in shuffled order, regions with no segments, none at all,
    and loose segments (each end counts in the box)."""
    rng = np.random.default_rng(9)
    polys = [convex(rng, centre=rng.normal(size=2) * 50, k=rng.integers(3, 9)) for _ in range(60)]
    owner = np.concatenate([np.full(len(p), i) for i, p in enumerate(polys)]) * 2    # odd regions empty
    start = np.concatenate(polys)
    end = np.concatenate([np.roll(p, -1, axis=0) for p in polys])
    order = rng.permutation(len(owner))
    loose = (rng.integers(0, 30, 200), rng.normal(size=(200, 2)), rng.normal(size=(200, 2)), 31)   # not closed: the box
    for args in ((owner[order], start[order], end[order], 2 * len(polys) + 3), (owner[:0], start[:0], end[:0], 4), loose):
        for x, y in zip(segment_moments(*args), segment_moments_reference(*args)):
            close(x, y)


def test_areas_are_the_moments_areas():
    """The dark test's areas: the shoelace areas written out here (to 1e-12; far from the origin),
    and :func:`moments`' areas to the bit (the dark test compares them with each other)."""
    rng = np.random.default_rng(10)
    polys = [convex(rng, centre=rng.normal(size=2) * 1e3, k=rng.integers(3, 12)) for _ in range(50)] + [np.zeros((0, 2))]
    poly, count = batch([p[:8] for p in polys])
    count[::7] = 2                                             # fewer than three corners: empty
    got = polygon_areas(poly, count)
    close(got, areas_reference(poly, np.minimum(count, 8)))
    assert np.all(got[count >= 3] > 0) and np.all(got[count < 3] == 0)
    assert np.array_equal(got, moments(poly, count)[0])
