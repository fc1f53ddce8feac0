"""The fast kernels of :mod:`sarmitsuba.tracing.mesh.patches` and :mod:`sarmitsuba.tracing.visibility.motion`
against the readable versions they replaced (kept here, or beside them as ``_reference``
functions), on random batches with their degenerate cases: empty batches, pieces with no candidate
line, parallel lines, lines through a segment's end that do not move, regions on patch lines.
The fast versions give the references' results bit for bit (the same float operations in the same
order; only the loops and gathers are arranged differently).
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.tracing.visibility import motion
from sarmitsuba.tracing.mesh import patches
from sarmitsuba.tracing.visibility.motion_reference import endpoint_rates_reference
from sarmitsuba.tracing.mesh import piece_cuts
from sarmitsuba.tracing.mesh.patches import Surfaces, _to_world_reference
from sarmitsuba.tracing.mesh.piece_cuts import pieces_of
from sarmitsuba.tracing.mesh.polygons import pad


# ---------------------------------------------------------------- references (the former kernels)

def _endpoint_rates_reference(start, end, owner, line_owner, lines, rates):
    """:func:`sarmitsuba.tracing.visibility.motion.endpoint_rates` as it was: every (segment, candidate line)
    pair by fancy indexing, the best line per segment by a lexsort."""
    n = len(start)
    out_s, out_e = np.zeros((n, 2)), np.zeros((n, 2))
    if n == 0 or len(lines) == 0:
        return out_s, out_e
    order = np.argsort(line_owner, kind="stable")
    owners = line_owner[order]
    for lo in range(0, n, 32768):
        hi = min(n, lo + 32768)
        first = np.searchsorted(owners, owner[lo:hi], side="left")
        count = np.searchsorted(owners, owner[lo:hi], side="right") - first
        seg = np.repeat(np.arange(lo, hi), count)
        line = order[np.repeat(first, count) + np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)]
        out_s[lo:hi], out_e[lo:hi] = _solve_reference(start, end, seg, line, lines, rates, lo, hi)
    return out_s, out_e


def _first_reference(seg, score, n, offset):
    best = np.full(n, -1, np.int64)
    if len(seg):
        order = np.lexsort((-score, seg))
        first = np.ones(len(order), bool)
        first[1:] = seg[order][1:] != seg[order][:-1]
        best[seg[order][first] - offset] = order[first]
    return best


def _solve_reference(start, end, seg, line, lines, rates, lo, hi):
    n = hi - lo
    g, h = lines[line, :2], lines[line, 2]
    ds = np.abs(np.einsum("mi,mi->m", g, start[seg]) + h) < motion.ON_LINE
    de = np.abs(np.einsum("mi,mi->m", g, end[seg]) + h) < motion.ON_LINE
    keep = ds | de
    seg, line, g, ds, de = seg[keep], line[keep], g[keep], ds[keep], de[keep]
    moving = np.any(rates[line] != 0.0, axis=1)
    own_rows = np.flatnonzero(ds & de)
    own = _first_reference(seg[own_rows], moving[own_rows].astype(float), n, lo)
    has_own = own >= 0
    own_row = own_rows[np.maximum(own, 0)] if len(own_rows) else np.zeros(n, np.int64)
    own_line = line[own_row] if len(line) else np.zeros(n, np.int64)
    g_own = np.where(has_own[:, None], lines[own_line, :2], 0.0)
    r_own = np.where(has_own[:, None], rates[own_line], 0.0)
    moving_own = has_own & np.any(r_own != 0.0, axis=1)
    local = seg - lo
    cross = np.abs(g[:, 0] * g_own[local, 1] - g[:, 1] * g_own[local, 0])
    results = []
    for point, on in ((start[lo:hi], ds), (end[lo:hi], de)):
        rows = np.flatnonzero(on & (cross > motion._PARALLEL))
        other = _first_reference(seg[rows], moving[rows].astype(float), n, lo)
        has = other >= 0
        other_line = line[rows[np.maximum(other, 0)]] if len(rows) else np.zeros(n, np.int64)
        g_other = lines[other_line, :2]
        r_other = np.where(has[:, None], rates[other_line], 0.0)
        ok = has_own & has & (moving_own | np.any(r_other != 0.0, axis=1))
        rhs0 = -(np.einsum("si,si->s", r_own[:, :2], point) + r_own[:, 2])
        rhs1 = -(np.einsum("si,si->s", r_other[:, :2], point) + r_other[:, 2])
        det = g_own[:, 0] * g_other[:, 1] - g_own[:, 1] * g_other[:, 0]
        safe = np.where(ok & (det != 0), det, 1.0)
        x = (rhs0 * g_other[:, 1] - rhs1 * g_own[:, 1]) / safe
        y = (g_own[:, 0] * rhs1 - g_other[:, 0] * rhs0) / safe
        results.append(np.where(ok[:, None], np.stack([x, y], axis=1), 0.0))
    return results[0], results[1]


def _assert_same(a, b):
    """Equal arrays; the einsum of the references may fuse a multiply-add where the plain
    expression does not (an ulp), so values agree to 1e-12 of their scale."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype
    scale = max(float(np.abs(b).max(initial=0.0)), 1.0)
    np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-12 * scale)


# ---------------------------------------------------------------- motion.endpoint_rates

def _boundary_case(rng, n_pieces: int, extra: int):
    """Pieces (random convex quads) with their edges as segments; candidate lines: each piece's
    edges (some moving), lines through random corners (some parallel to an edge, some fixed) and
    random lines; a few pieces without any line, a few lines of pieces without segments."""
    start, end, owner, line_owner, lines = [], [], [], [], []
    for k in range(n_pieces):
        angle = np.sort(rng.uniform(0.0, 2.0 * np.pi, 4))
        corner = rng.uniform(-5.0, 5.0, 2) + rng.uniform(0.5, 2.0) * np.stack([np.cos(angle), np.sin(angle)], 1)
        nxt = np.roll(corner, -1, axis=0)
        start.append(corner)
        end.append(nxt)
        owner += [k] * 4
        if k % 7 == 3:
            continue                                    # a piece with no candidate line
        edge = nxt - corner
        normal = np.stack([-edge[:, 1], edge[:, 0]], 1) / np.linalg.norm(edge, axis=1)[:, None]
        own = np.column_stack([normal, -np.einsum("ij,ij->i", normal, corner)])
        cand = [own, own[:1]]                           # an edge's line twice (ties)
        for _ in range(extra):
            p = corner[rng.integers(4)]
            theta = rng.uniform(0.0, 2.0 * np.pi) if rng.random() > 0.2 else np.arctan2(normal[0, 1], normal[0, 0])
            g = np.array([np.cos(theta), np.sin(theta)])
            cand.append(np.array([[g[0], g[1], -g @ p]]))
        cand.append(np.column_stack([rng.normal(size=(2, 2)), rng.normal(size=2)]))
        cand = np.concatenate(cand)
        lines.append(cand)
        line_owner += [k] * len(cand)
    lines.append(np.array([[1.0, 0.0, 3.0]]))            # a piece with lines and no segments
    line_owner.append(n_pieces + 5)
    lines = np.concatenate(lines)
    rates = rng.normal(size=lines.shape) * (rng.random(len(lines)) > 0.4)[:, None]
    perm = rng.permutation(len(lines))                  # lines in no particular order
    seg_perm = rng.permutation(4 * n_pieces)
    return (np.concatenate(start)[seg_perm], np.concatenate(end)[seg_perm], np.array(owner, np.int64)[seg_perm],
            np.array(line_owner, np.int64)[perm], lines[perm], rates[perm])


@pytest.mark.parametrize("seed", range(4))
def test_endpoint_rates_are_the_reference(seed):
    """The Dr.Jit kernel against the former NumPy kernel (above) and the readable per-segment
    reference (:mod:`sarmitsuba.tracing.visibility.motion_reference`), which share none of its code.
    Deliberate bugs in the kernel it caught: ``moving_own | moving_other`` as ``&``; the own line
    without its preference for a moving one; the other line without it; the parallel test dropped;
    the sign of ``h'`` in the other line's right-hand side; a sign in Cramer's rule."""
    rng = np.random.default_rng(seed)
    case = _boundary_case(rng, n_pieces=60, extra=4)
    got = motion.endpoint_rates(*case)
    want = _endpoint_rates_reference(*case)
    readable = endpoint_rates_reference(*case)
    assert np.count_nonzero(want[0].any(axis=1)) > 20  # the case moves ends
    for g, w, r in zip(got, want, readable):
        _assert_same(g, w)
        np.testing.assert_allclose(g, r, rtol=1e-9, atol=1e-9 * max(float(np.abs(r).max(initial=0.0)), 1.0))


def test_endpoint_rates_degenerate():
    rng = np.random.default_rng(9)
    start, end, owner, line_owner, lines, rates = _boundary_case(rng, n_pieces=5, extra=2)
    for case in [(start[:0], end[:0], owner[:0], line_owner, lines, rates),
                 (start, end, owner, line_owner[:0], lines[:0], rates[:0]),
                 (start, end, owner + 1000, line_owner, lines, rates),        # no segment has a line
                 (start, end, owner, line_owner, lines, np.zeros_like(rates))]:  # nothing moves
        got, want = motion.endpoint_rates(*case), _endpoint_rates_reference(*case)
        for g, w in zip(got, want):
            _assert_same(g, w)
    assert not motion.endpoint_rates(start, end, owner, line_owner, lines, np.zeros_like(rates))[0].any()


# ---------------------------------------------------------------- Surfaces.to_world

def _surfaces(rng, n: int) -> Surfaces:
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    u = np.cross(normal, rng.normal(size=(n, 3)))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    polygon = rng.normal(size=(n, 8, 2))
    z = np.zeros(n, np.int64)
    return Surfaces(normal=normal, offset=rng.normal(size=n) * 50.0, origin=rng.normal(size=(n, 3)) * 100.0,
                    axis_u=u, axis_v=np.cross(normal, u), polygon=polygon, n_corners=np.full(n, 8), shape_id=z.astype(np.uint32),
                    row=z, seen_side=z.astype(np.int8), face=np.arange(n), triangle_part=z, triangle_base=z[:1])


def test_to_world_is_the_reference():
    rng = np.random.default_rng(4)
    s = _surfaces(rng, 50)
    part = rng.integers(0, 50, 900)
    cases = [(part, rng.normal(size=(900, 2)) * 30.0),                 # [n, 2]
             (part, rng.normal(size=(900, 8, 2)) * 30.0),              # [n, V, 2] (the per-axis path)
             (part[:7], rng.normal(size=(7, 8, 2))),                   # small
             (np.array(3), rng.normal(size=(5, 2))),                   # one part, several points
             (part[:40].reshape(5, 8), rng.normal(size=(5, 8, 3, 2))),
             (part, rng.normal(size=(900, 8, 2)).astype(np.float32)),
             (part[:0], np.zeros((0, 8, 2))), (part[:0], np.zeros((0, 2)))]
    for p, coords in cases:
        got, want = s.to_world(p, coords), _to_world_reference(s, p, coords)
        assert got.shape == want.shape and got.dtype == want.dtype
        np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(s.plane_point(part), patches._plane_point_reference(s, part))
    # the plane point lies on the plane
    np.testing.assert_allclose(np.einsum("ij,ij->i", s.plane_point(part), s.normal[part]), s.offset[part], atol=1e-9)


# ---------------------------------------------------------------- pieces_of's row spans

def _regions(rng, n: int, patch: float):
    """Convex regions, some with corners and edges on patch lines, some thin, one triangle with a
    repeated corner."""
    poly, count = np.zeros((n, 9, 2)), np.zeros(n, np.int64)
    for k in range(n):
        m = int(rng.integers(3, 10))
        angle = np.sort(rng.uniform(0.0, 2.0 * np.pi, m))
        r = rng.uniform(0.3, 6.0) * patch
        pts = rng.uniform(-10, 10, 2) * patch + r * np.stack([np.cos(angle), np.sin(angle) * rng.uniform(0.05, 1.0)], 1)
        if k % 3 == 0:
            pts = np.round(pts / patch) * patch          # corners on the grid
            keep = np.concatenate([[True], np.any(pts[1:] != pts[:-1], axis=1)])
            pts = pts[keep]
            if len(pts) < 3:
                pts = np.array([[0.0, 0.0], [patch, 0.0], [patch, 2 * patch]])
        if k % 3 == 0 and k % 2 == 0:
            pts = np.array([[0.0, 0.0], [3 * patch, 0.0], [3 * patch, 2 * patch], [0.0, 2 * patch]])  # on lines
        poly[k, :len(pts)], count[k] = pts, len(pts)
    poly[-1, :4], count[-1] = [[0.0, 0.0], [2 * patch, 0.0], [2 * patch, 0.0], [0.0, 3 * patch]], 4
    return pad(poly, count), count


@pytest.mark.parametrize("seed", range(3))
def test_row_spans_from_shared_lines(seed):
    """The extents on each grid line computed once (:func:`piece_cuts._line_extents`) give each row
    what :func:`piece_cuts._row_spans` computes on its own two lines."""
    rng = np.random.default_rng(seed)
    patch = 1.7439
    poly, count = _regions(rng, 40, patch)
    live = np.arange(40)
    y_lo = np.floor(poly[live, :, 1].min(axis=1) / patch).astype(np.int64)
    rows = np.floor(poly[live, :, 1].max(axis=1) / patch).astype(np.int64) - y_lo + 1
    region = np.repeat(live, rows)
    row = np.repeat(y_lo, rows) + np.arange(int(rows.sum())) - np.repeat(np.cumsum(rows) - rows, rows)
    lines = rows + 1
    line_region = np.repeat(live, lines)
    line_y = np.repeat(y_lo, lines) + np.arange(int(lines.sum())) - np.repeat(np.cumsum(lines) - lines, lines)
    bottom = np.arange(len(row)) + np.repeat(np.arange(len(live)), rows)
    on_lines = piece_cuts._line_extents(poly, count, patch, line_region, line_y, bottom)
    got = piece_cuts._row_spans(poly, count, patch, region, row, on_lines)
    want = piece_cuts._row_spans(poly, count, patch, region, row)
    for g, w in zip(got, want):
        for a, b in zip(g, w):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("seed", range(2))
def test_pieces_tile_the_regions(seed):
    """The pieces of each region cover it: their areas sum to its area, whole pieces lie inside
    it, every piece's cell is where its polygon lies (with and without a span)."""
    rng = np.random.default_rng(seed)
    patch = 1.7439
    poly, count = _regions(rng, 30, patch)
    from sarmitsuba.tracing.mesh.polygons import moments
    area = moments(poly, count)[0]
    for span in (None, np.tile(np.array([[[0.0, 0.0, 1.0]]]), (30, 1, 1))):
        p = pieces_of(poly, count, patch, span)
        a, centroid, _, _ = p.geometry()
        np.testing.assert_allclose(np.bincount(p.region, weights=a, minlength=30), area, rtol=1e-9, atol=1e-9)
        border = ~p.whole
        inside = np.floor(centroid[border] / patch).astype(np.int64) == p.cell[border]
        small = np.isin(p.region[border], np.flatnonzero(np.ptp(poly, axis=1).max(axis=1) <= patch))
        assert np.all(inside.all(axis=1) | small)


# ---------------------------------------------------------------- motion.line_rates

def _line_rates_reference(at_a, at_b, step):
    at_a, at_b = np.asarray(at_a, float), np.asarray(at_b, float)
    step = np.asarray(step, float).reshape((-1,) + (1,) * (at_a.ndim - 1))
    real = (np.abs(np.linalg.norm(at_a[..., :2], axis=-1) - 1.0) < 1e-6) \
        & (np.abs(np.linalg.norm(at_b[..., :2], axis=-1) - 1.0) < 1e-6)
    rate = np.where(step > 0, (at_b - at_a) / np.where(step > 0, step, 1.0), 0.0)
    return np.where(real[..., None], rate, 0.0)


def test_line_rates_are_the_reference():
    rng = np.random.default_rng(5)
    theta = rng.uniform(0, 2 * np.pi, (40, 6))
    at_a = np.stack([np.cos(theta), np.sin(theta), rng.normal(size=(40, 6))], -1)
    at_b = np.stack([np.cos(theta + 1e-3), np.sin(theta + 1e-3), at_a[..., 2] + 1e-3], -1)
    at_a[:, 5], at_b[3:9, 4] = (0.0, 0.0, 1.0), (0.0, 0.0, 1.0)     # padding rows
    at_b[10:12, 2, :2] *= 0.5                                        # not unit at the second position
    step = rng.uniform(0.0, 2.0, 40)
    step[[1, 7]] = 0.0
    for a, b, st in [(at_a, at_b, step), (at_a[:0], at_b[:0], step[:0]), (at_a[:, 0], at_b[:, 0], step)]:
        got, want = motion.line_rates(a, b, st), _line_rates_reference(a, b, st)
        assert got.shape == want.shape
        np.testing.assert_array_equal(got, want)


# ---------------------------------------------------------------- Pieces.select / geometry / edges

def _select_reference(p, keep):
    keep = np.flatnonzero(keep) if np.asarray(keep).dtype == bool else np.asarray(keep, np.int64)
    border = p.border[keep]
    rows = border[border >= 0]
    new = np.full(len(keep), -1, np.int64)
    new[border >= 0] = np.arange(len(rows))
    return patches.Pieces(p.region[keep], p.cell[keep], p.whole[keep], new, p.polygon[rows], p.count[rows], p.patch)


def _geometry_reference(p):
    import math
    from sarmitsuba.tracing.mesh.polygons import moments
    n, size = len(p), p.patch
    area = np.full(n, size * size)
    centroid = (p.cell + 0.5) * size
    second = np.tile([size ** 4 / 12.0, 0.0, size ** 4 / 12.0], (n, 1))
    diagonal = np.full(n, size * math.sqrt(2.0))
    b = np.flatnonzero(~p.whole)
    if len(b):
        rows = p.border[b]
        area[b], centroid[b], second[b], diagonal[b] = moments(p.polygon[rows], p.count[rows])
    return area, centroid, second, diagonal


def _edges_reference(p, rows=None):
    rows = np.arange(len(p)) if rows is None else np.asarray(rows, np.int64)
    whole = rows[p.whole[rows]]
    square = (p.cell[whole][:, None, :] + patches.UNIT_SQUARE[None]) * p.patch
    border = rows[~p.whole[rows]]
    poly, count = p.polygon[p.border[border]], p.count[p.border[border]]
    slots = np.arange(poly.shape[1])[None, :] < count[:, None]
    end = np.roll(poly, -1, axis=1)
    keep = slots & (np.linalg.norm(end - poly, axis=2) > 0)
    b_rows, b_cols = np.nonzero(keep)
    b_start, b_end = poly[b_rows, b_cols], end[b_rows, b_cols]
    b_side = patches._grid_side(p.cell[border[b_rows]], b_start, b_end, p.patch)
    return (np.concatenate([np.repeat(whole, 4), border[b_rows]]), np.concatenate([square.reshape(-1, 2), b_start]),
            np.concatenate([np.roll(square, -1, axis=1).reshape(-1, 2), b_end]),
            np.concatenate([np.tile(np.arange(4), len(whole)), b_side]))


def _assert_pieces_equal(a, b):
    for field in a.__dataclass_fields__:
        x, y = getattr(a, field), getattr(b, field)
        if isinstance(y, np.ndarray):
            assert x.shape == y.shape and x.dtype == y.dtype, field
        np.testing.assert_array_equal(x, y, err_msg=field)


def test_pieces_methods_are_the_references():
    rng = np.random.default_rng(6)
    patch = 1.7439
    poly, count = _regions(rng, 30, patch)
    p = pieces_of(poly, count, patch)
    assert p.whole.any() and (~p.whole).any()
    for keep in [rng.random(len(p)) > 0.5, np.zeros(len(p), bool), np.ones(len(p), bool),
                 rng.permutation(len(p))[:40], np.array([], np.int64)]:
        q, want = p.select(keep), _select_reference(p, keep)
        _assert_pieces_equal(q, want)
        for g, w in zip(q.geometry(), _geometry_reference(want)):
            np.testing.assert_array_equal(g, w)
        for g, w in zip(q.edges(), _edges_reference(want)):
            np.testing.assert_array_equal(g, w)
    # border rows not in order (the gathered path of geometry); a repeated corner (edges drops it)
    shuffled = patches.Pieces(p.region, p.cell, p.whole, np.where(p.border >= 0, len(p.count) - 1 - p.border, -1),
                              p.polygon[::-1].copy(), p.count[::-1].copy(), p.patch)
    shuffled.polygon[0, 1] = shuffled.polygon[0, 0]
    for g, w in zip(shuffled.geometry(), _geometry_reference(shuffled)):
        np.testing.assert_array_equal(g, w)
    rows = rng.permutation(len(p))[:25]
    for g, w in zip(shuffled.edges(rows), _edges_reference(shuffled, rows)):
        np.testing.assert_array_equal(g, w)


def test_world_polygon_is_to_world_of_each_part():
    rng = np.random.default_rng(8)
    s = _surfaces(rng, 700)
    part = rng.integers(0, 700, 5000)
    np.testing.assert_array_equal(s.world_polygon[part], s.to_world(part, s.polygon[part]))
    np.testing.assert_array_equal(s.world_polygon[part], _to_world_reference(s, part, s.polygon[part]))
    assert not s.world_polygon.flags.writeable


def test_part_areas_are_the_reference():
    """The parts' areas that order covers: the fan's cross products summed in order and normed by
    a dot product per part, bit for bit (a norm by reduction differs in the last bit)."""
    rng = np.random.default_rng(10)
    count = rng.integers(3, 10, 300)
    count[:4] = [0, 3, 9, 9]
    world = rng.normal(size=(300, 9, 3)) * rng.uniform(1.0, 300.0, (300, 1, 1))
    world[2] = np.linspace(0.0, 1.0, 9)[:, None] * [1.0, 2.0, 3.0]           # collinear: area 0
    want = patches._part_areas_reference(world, count)
    np.testing.assert_array_equal(patches._part_areas(world, count), want)
    assert want[0] == 0.0 and want[2] < 1e-12
    assert patches._part_areas(world[:0], count[:0]).shape == (0,)


def test_cell_lines_are_the_reference():
    cell = np.array([[0, 0], [-3, 7], [12, -1], [-1, 0]], np.int64)
    patch = 1.7439
    x0, y0 = cell[:, 0] * patch, cell[:, 1] * patch
    one, zero = np.ones_like(x0), np.zeros_like(x0)
    want = np.stack([np.stack([one, zero, -x0], 1), np.stack([-one, zero, x0 + patch], 1),
                     np.stack([zero, one, -y0], 1), np.stack([zero, -one, y0 + patch], 1)], axis=1)
    got = piece_cuts.cell_lines(cell, patch)
    np.testing.assert_array_equal(got, want)
    assert np.array_equal(np.signbit(got), np.signbit(want))
    assert piece_cuts.cell_lines(cell[:0], patch).shape == (0, 4, 3)
