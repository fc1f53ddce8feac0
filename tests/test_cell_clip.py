"""A cell piece's boundary (``sarmitsuba.tracing.cell_clip``, docs/physics.md (T6)) against shapely.

Truth: shapely's (GEOS) area and centroid of ``∩ base - ∪ cut-outs``, a second, independent
implementation of polygon clipping. The boundary's segments give the area and first moments by
Green's theorem, ``A = 1/2 sum (x0 y1 - x1 y0)``, ``int x dA = 1/6 sum (x0 + x1)(x0 y1 - x1 y0)``,
so a segment missing, doubled, or running the wrong way changes them. Cases: overlapping cut-outs
of either orientation (four, some switched off), cut-outs that share an edge (their common edge is
no boundary), a cut-out sharing an edge with the piece from inside and one touching it from
outside, and four cut-outs that each cover the whole piece (inclusion and exclusion cut at three
terms gives ``A - 4A + 6A - 4A = -A`` there)."""
from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import Polygon
from shapely.ops import unary_union

import sarmitsuba  # noqa: F401  (the LLVM variant)
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from sarmitsuba.tracing.cell_clip import boundary, inside, pack  # noqa: E402

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def _lanes(polygons):
    """float64 [lanes, corners, 2] -> the kernel's corner list."""
    return [(mi.Float64(polygons[:, k, 0].copy()), mi.Float64(polygons[:, k, 1].copy())) for k in range(polygons.shape[1])]


def _moments(base, cuts, live):
    """Area and first moments from :func:`boundary`, per lane (in ``base[0]``'s orientation)."""
    segments = boundary([_lanes(p) for p in base], [([_lanes(c)], mi.Bool(on)) for c, on in zip(cuts, live)])
    dr.eval(segments)                                   # one kernel for all of them
    out = np.zeros((3, base[0].shape[0]))
    for x0, y0, x1, y1, ok in segments:
        x0, y0, x1, y1, ok = (np.asarray(v) for v in (x0, y0, x1, y1, ok))
        cross = np.where(ok, x0 * y1 - x1 * y0, 0.0)
        out += [cross / 2, (x0 + x1) * cross / 6, (y0 + y1) * cross / 6]
    return out


def _truth(base, cuts, live, lane):
    piece = Polygon(base[0][lane])
    for p in base[1:]:
        piece = piece.intersection(Polygon(p[lane]))
    holes = [Polygon(c[lane]) for c, on in zip(cuts, live) if on[lane]]
    region = piece.difference(unary_union(holes)) if holes else piece
    if region.is_empty or region.area == 0:
        return np.zeros(3)
    return np.array([region.area, region.area * region.centroid.x, region.area * region.centroid.y])


def _convex(rng, n_lanes, corners, radius, clockwise):
    centre = rng.uniform(-0.3, 1.3, (n_lanes, 1, 2))
    angle = np.sort(rng.uniform(0.0, 2 * np.pi, (n_lanes, corners)), axis=1)
    polygon = centre + radius * np.stack([np.cos(angle), np.sin(angle)], -1)
    return polygon[:, ::-1].copy() if clockwise else polygon


def _check(base, cuts, live):
    got = _moments(base, cuts, live)
    truth = np.stack([_truth(base, cuts, live, lane) for lane in range(base[0].shape[0])], 1)
    np.testing.assert_allclose(got, truth, atol=1e-9)
    return got


def test_overlapping_cutouts_of_either_orientation():
    rng = np.random.default_rng(7)
    n = 200
    base = [np.repeat(SQUARE[None], n, 0), _convex(rng, n, 5, 0.9, False)]
    cuts = [_convex(rng, n, 4, 0.5, bool(j % 2)) for j in range(4)]
    live = rng.uniform(size=(4, n)) < 0.8
    for lane in range(n):           # cut-out 1 meets cut-out 0 along its first edge (where convex)
        a, b = cuts[0][lane, 0], cuts[0][lane, 1]
        if not Polygon(cuts[0][lane]).exterior.is_ccw:
            continue
        outward = np.array([b[1] - a[1], a[0] - b[0]])
        candidate = np.array([b, a, a + 0.4 * outward, b + 0.3 * outward])
        if Polygon(candidate).is_valid and Polygon(candidate).convex_hull.area == pytest.approx(Polygon(candidate).area):
            cuts[1][lane] = candidate
    got = _check(base, cuts, live)
    assert (got[0] > 1e-3).sum() > 50, "too few lanes with a piece left to test"


def test_cutouts_sharing_the_pieces_edges():
    """A cut-out covering the piece's left half (its edge on the piece's edge, from inside) and one
    touching its right edge from outside: the piece keeps exactly its right half."""
    n = 3
    base = [np.repeat(SQUARE[None], n, 0)]
    left = np.repeat(np.array([[0.0, 0.0], [0.5, 0.0], [0.5, 1.0], [0.0, 1.0]])[None], n, 0)
    right = np.repeat(np.array([[1.0, 0.2], [1.6, 0.2], [1.6, 0.8], [1.0, 0.8]])[None], n, 0)
    got = _check(base, [left, right], np.ones((2, n), bool))
    np.testing.assert_allclose(got[:, 0], [0.5, 0.375, 0.25], atol=1e-12)


def test_cutouts_ending_on_one_line():
    """Two cut-outs across the piece with one common side (x = 0.6): every edge of the piece that
    crosses them leaves both intervals at one point, and the piece's part beyond it counts once."""
    n, off = 2, np.array([0.3, 0.7])            # off the origin: no edge on a line through it
    base = [np.repeat(SQUARE[None] + off, n, 0)]
    wide = np.repeat(np.array([[0.2, -1.0], [0.6, -1.0], [0.6, 2.0], [0.2, 2.0]])[None] + off, n, 0)
    narrow = np.repeat(np.array([[0.4, -1.0], [0.6, -1.0], [0.6, 2.0], [0.4, 2.0]])[None] + off, n, 0)
    got = _check(base, [wide, narrow], np.ones((2, n), bool))
    np.testing.assert_allclose(got[0], 0.6, atol=1e-12)


def test_four_cutouts_that_each_cover_the_piece_leave_nothing():
    n = 2
    base = [np.repeat(SQUARE[None], n, 0)]
    cuts = [np.repeat((SQUARE * (1.5 + 0.1 * j) - 0.2 - 0.05 * j)[None], n, 0) for j in range(4)]
    got = _check(base, cuts, np.ones((4, n), bool))
    assert np.abs(got).max() < 1e-12


def test_inside_agrees_with_the_boundary():
    """The scatterers' membership test (:func:`inside`) on a grid, some cut-outs switched off: its
    area estimate matches the boundary's area (to the grid's resolution)."""
    rng = np.random.default_rng(3)
    n = 4
    base = [np.repeat(SQUARE[None], n, 0), _convex(rng, n, 6, 0.8, True)]
    cuts = [_convex(rng, n, 4, 0.4, False) for _ in range(3)]
    live = np.array([[True, False, True, True], [True, True, False, True], [False, True, True, True]])
    area = _check(base, cuts, live)[0]
    g = (np.arange(200) + 0.5) / 200
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    lanes = np.repeat(np.arange(n), x.size)
    pick = lambda p: [(mi.Float64(p[lanes, k, 0]), mi.Float64(p[lanes, k, 1])) for k in range(p.shape[1])]  # noqa: E731
    held = np.asarray(inside(mi.Float64(np.tile(x, n)), mi.Float64(np.tile(y, n)), [pick(p) for p in base],
                             [([pick(c)], mi.Bool(on[lanes])) for c, on in zip(cuts, live)]))
    estimate = held.reshape(n, -1).mean(1)
    np.testing.assert_allclose(estimate, np.abs(area), atol=0.01)


def test_the_packed_kernel_gives_the_reference_segments():
    """:func:`pack` (symbolic loops over edges, local memory) against :func:`boundary` (the
    unrolled reference): the same area and first moments on every lane, and as many segments as
    the reference has live ones."""
    rng = np.random.default_rng(11)
    n = 150
    base = [np.repeat(SQUARE[None], n, 0), _convex(rng, n, 4, 0.9, False)]
    cuts = [(_convex(rng, n, 4, 0.6, bool(j % 2)), _convex(rng, n, 3, 1.5, False)) for j in range(2)]
    live = rng.uniform(size=(2, n)) < 0.85
    base_dr = [_lanes(p) for p in base]
    cut_dr = [([_lanes(a), _lanes(b)], mi.Bool(on)) for (a, b), on in zip(cuts, live)]
    reference = np.zeros((4, n))
    segments = boundary(base_dr, cut_dr)
    dr.eval(segments)
    for x0, y0, x1, y1, ok in segments:
        x0, y0, x1, y1, ok = (np.asarray(v) for v in (x0, y0, x1, y1, ok))
        cross = np.where(ok, x0 * y1 - x1 * y0, 0.0)
        reference += [cross / 2, (x0 + x1) * cross / 6, (y0 + y1) * cross / 6, ok]
    ends, count = pack(base_dr, cut_dr)

    def step(i, area, mx, my):
        x0, y0, x1, y1 = (e[i] for e in ends)
        cross = x0 * y1 - x1 * y0
        return i + 1, area + cross / 2, mx + (x0 + x1) * cross / 6, my + (y0 + y1) * cross / 6
    _, *moments = dr.while_loop((mi.UInt32(0), mi.Float64(0.0), mi.Float64(0.0), mi.Float64(0.0)),
                                lambda i, *_: i < count, step)
    dr.eval(moments, count)
    np.testing.assert_allclose(np.asarray(moments), reference[:3], atol=1e-9)
    np.testing.assert_array_equal(np.asarray(count), reference[3])
    assert (reference[0] > 1e-3).sum() > 30
