"""The fast kernels of :mod:`sarmitsuba.tracing.occlusion` against the readable implementations
they replaced (kept here as references, issue 56): :func:`shadow_lines` (per live corner, per
distinct chain and occluder), :func:`lit_boundary` (line-major Cyrus-Beck intervals, only the
parallel pairs tested one by one), :func:`segment_moments` (boxes by sorted ``reduceat``) and
the areas of :func:`clip_mixed`'s dark test. The references are the code as it was; the
comparisons are to the bit where the arithmetic is the same and to 1e-12 where only the order
of a sum changed. Inputs include the degenerate cases: no cut-outs, empty bases, zero-length
edges, cut-outs along the base's edges and along each other's (both sides), a cut-out that is
the whole base, occluders with the most corners a part has, and segments on, parallel to and
outside a polygon's lines.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from sarmitsuba.tracing.chains import to_face_lines, unfolded_frame
from sarmitsuba.tracing.occlusion import (BOX_SLACK, COINCIDENT, _areas, _crossing_after, _crossing_before,
                                          _interval, _interval_rows, _window_planes, lit_boundary, segment_moments,
                                          shadow_lines, shared_shadow_lines)
from sarmitsuba.tracing.polygons import EVERYTHING, clip, corner_slots, edge_lines, moments, pad
from test_patch_geometry import all_chains, antennas, batch, convex, quad, surfaces


# --------------------------------------------------------------------------- references (the code as it was)
def shadow_lines_reference(surfaces, chains, chain, occluder, leg, antenna):
    depth = chains.parts.shape[1]
    k = len(chain)
    width = surfaces.polygon.shape[1] + 3
    lines = np.tile(np.asarray(EVERYTHING), (k, width, 1))
    order = chains.order[chain]
    back = (leg == depth) | ((order == 0) & (leg == 0))
    level = np.where(back, 0, leg)
    lin, shift = chains.lin[chain, level], chains.shift[chain, level]
    lin = np.where(back[:, None, None], np.eye(3), lin)
    shift = np.where(back[:, None], 0.0, shift)
    corners = surfaces.to_world(occluder, surfaces.polygon[occluder])
    corners = np.einsum("kij,kvj->kvi", lin, corners) + shift[:, None, :]
    normal = np.einsum("kij,kj->ki", lin, surfaces.normal[occluder])
    offset = surfaces.offset[occluder] + np.einsum("ki,ki->k", normal, shift)
    a = offset - np.einsum("ki,ki->k", normal, antenna)
    sign = np.where(a >= 0, 1.0, -1.0)[:, None]
    origin, u, v = unfolded_frame(surfaces, chains.select(chain))
    real_origin = surfaces.plane_point(chains.last[chain])
    real_u, real_v = surfaces.axis_u[chains.last[chain]], surfaces.axis_v[chains.last[chain]]
    origin = np.where(back[:, None], real_origin, origin)
    u = np.where(back[:, None], real_u, u)
    v = np.where(back[:, None], real_v, v)

    def put(slot, g, h):
        lines[:, slot] = to_face_lines(g, h, origin, u, v)

    put(0, sign * normal, -np.einsum("ki,ki->k", sign * normal, antenna))
    windows = _window_planes(surfaces, chains, chain)
    last_leg = back | (leg == order)
    g_far = np.where(last_leg[:, None], sign * normal, 0.0)
    h_far = np.where(last_leg, -(sign[:, 0] * offset), 0.0)
    g_next, h_next = _crossing_before(normal, a, windows, np.minimum(leg, depth - 1), antenna)
    g_far = np.where(last_leg[:, None], g_far, g_next)
    h_far = np.where(last_leg, h_far, h_next)
    put(1, g_far, h_far)
    g_prev, h_prev = _crossing_after(normal, a, windows, leg - 1, antenna)
    after = ~back & (leg > 0)
    lines[:, 2] = np.where(after[:, None], to_face_lines(g_prev, h_prev, origin, u, v), EVERYTHING)
    count = surfaces.n_corners[occluder]
    slots = corner_slots(count, corners.shape[1])
    centre = (corners * slots[..., None]).sum(axis=1) / count[:, None]
    for e in range(corners.shape[1]):
        p = corners[:, e] - antenna
        q = np.roll(corners, -1, axis=1)[:, e] - antenna
        g = np.cross(p, q)
        g *= np.where(np.einsum("ki,ki->k", g, centre - antenna) >= 0, 1.0, -1.0)[:, None]
        line = to_face_lines(g, -np.einsum("ki,ki->k", g, antenna), origin, u, v)
        lines[:, 3 + e] = np.where(slots[:, e, None], line, EVERYTHING)
    return lines


def lit_boundary_reference(base, base_count, cut, cut_count, cut_owner):
    g, width = len(base), cut.shape[1]
    cut_lines = edge_lines(cut, cut_count)
    base_lines = edge_lines(base, base_count)
    lo = np.where(corner_slots(cut_count, width)[..., None], cut, np.inf).min(axis=1)
    hi = np.where(corner_slots(cut_count, width)[..., None], cut, -np.inf).max(axis=1)
    delta_b = np.roll(base, -1, axis=1) - base
    live_b = corner_slots(base_count, base.shape[1]) & (np.linalg.norm(delta_b, axis=2) > 0)
    rb, kb = np.nonzero(live_b)
    delta_c = np.roll(cut, -1, axis=1) - cut
    live_c = corner_slots(cut_count, width) & (np.linalg.norm(delta_c, axis=2) > 0)
    rc, kc = np.nonzero(live_c)
    s0, e0 = _interval(cut[rc, kc], delta_c[rc, kc], base_lines[cut_owner[rc]], lambda same: ~same)
    inner = e0 > s0
    rc, kc, s0, e0 = rc[inner], kc[inner], s0[inner], e0[inner]
    start = np.concatenate([base[rb, kb], cut[rc, kc] + s0[:, None] * delta_c[rc, kc]])
    delta = np.concatenate([delta_b[rb, kb], delta_c[rc, kc] * (e0 - s0)[:, None]])
    owner = np.concatenate([rb, cut_owner[rc]])
    own = np.concatenate([np.full(len(rb), -1), rc])
    order = np.argsort(cut_owner, kind="stable")
    first = np.searchsorted(cut_owner[order], np.arange(g))
    per = np.bincount(cut_owner, minlength=g)[owner]
    edge = np.repeat(np.arange(len(owner)), per)
    other = order[np.repeat(first[owner], per) + np.arange(int(per.sum())) - np.repeat(np.cumsum(per) - per, per)]
    e_lo = np.minimum(start, start + delta)[edge]
    e_hi = np.maximum(start, start + delta)[edge]
    meet = (other != own[edge]) & np.all((e_lo <= hi[other] + BOX_SLACK) & (e_hi >= lo[other] - BOX_SLACK), axis=1)
    edge, other = edge[meet], other[meet]
    earlier = (other < own[edge])[:, None]
    is_base = (own[edge] < 0)[:, None]
    s, e = _interval(start[edge], delta[edge], cut_lines[other], lambda same: np.where(is_base, same, ~same | earlier))
    real = e > s
    edge, s, e = edge[real], s[real], e[real]
    rank = np.lexsort((s, edge))
    edge, s, e = edge[rank], s[rank], e[rank]
    reach = np.maximum.accumulate(e + 2.0 * edge) - 2.0 * edge
    head = np.ones(len(edge), bool)
    head[1:] = edge[1:] != edge[:-1]
    before = np.where(head, 0.0, np.roll(reach, 1))
    tail = np.ones(len(edge), bool)
    tail[:-1] = edge[1:] != edge[:-1]
    untouched = np.setdiff1d(np.arange(len(owner)), edge)
    row = np.concatenate([edge, edge[tail], untouched])
    a = np.concatenate([before, reach[tail], np.zeros(len(untouched))])
    b = np.concatenate([s, np.ones(int(tail.sum())), np.ones(len(untouched))])
    keep = (b > a) & ((b - a) * np.linalg.norm(delta[row], axis=1) > 1e-12)
    row, a, b = row[keep], a[keep], b[keep]
    p = start[row] + a[:, None] * delta[row]
    q = start[row] + b[:, None] * delta[row]
    flip = own[row] >= 0
    p, q = np.where(flip[:, None], q, p), np.where(flip[:, None], p, q)
    return owner[row], p, q


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
    """Ground, a wall, a tilted plate and a tilted octagon (the widest part: its slots are full)."""
    return surfaces([quad((0, 0, 0), (10, 0, 0), (0, 10, 0)),
                     quad((0, -2, 3), (6, 0, 0), (0, 0, 3)),
                     quad(np.array([1, 3, 4.0]) + rng.normal(size=3) * 0.5, (1.5, 0.5, 0.3), (0.0, 1.0, 1.0)),
                     octagon(np.array([-2, 1, 2.0]) + rng.normal(size=3) * 0.5, (1.0, 0.2, 0.3), (0.3, 0.8, 0.9))])


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
def test_interval_rows_is_interval():
    """Segments crossing, inside, outside, on and parallel to convex polygons' lines (the polygon
    on either side), zero-length, against padded and nowhere rows: the same bits as
    :func:`_interval`."""
    rng = np.random.default_rng(5)
    polys = [convex(rng, k=rng.integers(3, 9)) for _ in range(40)] + [np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])]
    poly, count = batch(polys)
    table = edge_lines(poly, count)
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
        ref = _interval(start, delta, table[row],
                        lambda same: np.where(same, np.broadcast_to(inside_same, row.shape)[:, None],
                                              np.broadcast_to(inside_other, row.shape)[:, None]))
        for used in (None, count):                            # all slots, or only each polygon's lines
            new = _interval_rows(start, delta, table, row, inside_same, inside_other, used)
            for x, y in zip(new, ref):
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
                poly_c, count_c = clip(poly_c, count_c, edge_lines(b_all, bc_all))
            elif kind == 2 and mine:
                poly_c, count_c = batch([mine[-1]], 16)
            elif kind == 3:
                poly_c, count_c = clip(b_all, bc_all, np.array([[EVERYTHING]]))
            else:
                poly_c, count_c = batch([convex(rng, centre=rng.normal(size=2) * 0.6, scale=0.4)], 16)
                poly_c, count_c = clip(poly_c, count_c, edge_lines(b_all, bc_all))
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
    rng = np.random.default_rng(10)
    polys = [convex(rng, centre=rng.normal(size=2) * 1e3, k=rng.integers(3, 12)) for _ in range(50)] + [np.zeros((0, 2))]
    poly, count = batch([p[:8] for p in polys])
    count[::7] = 2                                             # fewer than three corners: empty
    assert np.array_equal(_areas(poly, count), moments(poly, count)[0])
