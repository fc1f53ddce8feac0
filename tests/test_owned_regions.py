"""The owned partition (docs/physics.md (T6)) tiles a convex facet exactly, for any lattice and view.

Truth: Gordon's closed form over the whole facet (``physical_optics.polygon_integral``, itself
tested against numerical quadrature) and the shoelace area."""
import dataclasses
import math

import numpy as np
import pytest

from sarmitsuba.owned_regions import owned_regions, region_polygons
from sarmitsuba.physical_optics import polygon_integral


def _rotated(points, deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.asarray(points, float) @ np.array([[c, s], [-s, c]])


def _lattice(origin, e1, e2):
    """Cell point ``(i + fa, j + fg)`` of an affine lattice (``e1 x e2 > 0``)."""
    origin, e1, e2 = (np.asarray(v, float) for v in (origin, e1, e2))
    return lambda i, j, fa=0.5, fg=0.5: origin + (i + fa) * e1 + (j + fg) * e2


def _members(facet, cell, n=80):
    """Cells whose centre lies inside the counter-clockwise convex ``facet``."""
    out = set()
    for i in range(-n, n):
        for j in range(-n, n):
            x = cell(i, j)
            if all((b - a)[0] * (x - a)[1] - (b - a)[1] * (x - a)[0] > 0
                   for a, b in zip(facet, np.roll(facet, -1, axis=0))):
                out.add((i, j))
    return out


def _integral(poly, q):
    """Gordon's closed form over a polygon in the plane z = 0."""
    return polygon_integral(np.c_[poly, np.zeros(len(poly))], np.array([0.0, 0.0, 1.0]), np.r_[q, 0.0])


def _lines(origin, e1, e2):
    """The view's lattice lines, directed as :func:`owned_regions` asks."""
    origin, e1, e2 = (np.asarray(v, float) for v in (origin, e1, e2))
    column = lambda i: (origin + i * e1, origin + i * e1 + e2)     # noqa: E731  (left: column i - 1)
    row = lambda j: (origin + j * e2, origin + j * e2 - e1)        # noqa: E731  (left: row j - 1)
    return column, row


FACETS = {
    "triangle 30 deg": _rotated([[-2.0, -1.5], [2.5, -1.0], [0.3, 2.2]], 30.0),
    "triangle 60 deg": _rotated([[-2.0, -1.5], [2.5, -1.0], [0.3, 2.2]], 60.0),
    "square 30 deg": _rotated([[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]], 30.0),
    "sliver 10 deg": _rotated([[-3.0, -0.2], [3.0, -0.1], [2.8, 0.3]], 10.0),
}
# (lattice at the reference position, lattice as the pulse sees it): moved, scaled, skewed
VIEWS = {
    "same view": (((0.05, 0.11), (0.2, 0.0), (0.0, 0.283)), ((0.05, 0.11), (0.2, 0.0), (0.0, 0.283))),
    "parallax of 3.4 cells": (((0.05, 0.11), (0.2, 0.0), (0.0, 0.283)), ((0.73, -0.41), (0.207, 0.0), (0.0, 0.29))),
    "skewed view": (((0.05, 0.11), (0.2, 0.0), (0.0, 0.283)), ((-0.31, 0.2), (0.19, 0.03), (-0.04, 0.27))),
}


@pytest.mark.parametrize("facet_name", FACETS)
@pytest.mark.parametrize("view", VIEWS)
def test_owned_regions_tile_the_facet_exactly(facet_name, view):
    facet = FACETS[facet_name]
    at_reference, at_pulse = VIEWS[view]
    members = _members(facet, _lattice(*at_reference))
    pieces = region_polygons(facet, owned_regions(members, *_lines(*at_pulse)))
    polys = [p for ps in pieces.values() for p in ps]
    area = sum(0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]) for p in polys)
    exact_area = 0.5 * np.sum(facet[:, 0] * np.roll(facet[:, 1], -1) - np.roll(facet[:, 0], -1) * facet[:, 1])
    assert abs(area - exact_area) < 1e-12 * exact_area
    # the two-way phase gradient of X band at 45 deg: 280 rad/m, tens of radians across a cell
    for q in ((0.1, -284.5), (180.0, -220.0), (-95.0, 40.0)):
        facet3 = np.concatenate([facet, np.zeros((len(facet), 1))], axis=1)
        truth = polygon_integral(facet3, np.array([0.0, 0.0, 1.0]), np.array([*q, 0.0]))
        total = sum(_integral(p, np.array(q)) for p in polys)
        assert abs(total - truth) < 1e-9 * exact_area, (q, total, truth)
        # the staircase the kernel sums today (whole cells as the pulse sees them) is far off
        cell = _lattice(*at_pulse)
        stair = sum(_integral(np.array([cell(i, j, a, g) for a, g in ((0, 0), (1, 0), (1, 1), (0, 1))]),
                                        np.array(q)) for i, j in members)
        assert abs(stair - truth) > 10 * abs(total - truth) + 1e-6 * exact_area


def test_owned_regions_refuses_gaps_and_empty_sets():
    column, row = _lines((0, 0), (1, 0), (0, 1))
    with pytest.raises(ValueError, match="no members"):
        owned_regions(set(), column, row)
    with pytest.raises(ValueError, match="column 0 has a gap"):
        owned_regions({(0, 0), (0, 2)}, column, row)


# ============================================================================ the kernel's plan
from types import SimpleNamespace  # noqa: E402

from sarmitsuba.kernel import Blocks  # noqa: E402
from sarmitsuba.lattice_index import convex_depth  # noqa: E402
from sarmitsuba.owned_regions import UNBOUNDED, clip_convex, lattice_lines, plan  # noqa: E402

_FP = SimpleNamespace(origin=np.zeros(3), track=np.array([1.0, 0.0, 0.0]), look=np.array([0.0, 1.0, 0.0]),
                      spacing_azimuth=0.5, spacing_range=0.7, range_min=-20.0)


def _shoelace(poly):
    return 0.5 * float(np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - poly[:, 1] * np.roll(poly[:, 0], -1)))


def _ccw(poly):
    return poly if _shoelace(poly) > 0 else poly[::-1]


#: The plan's triangle, and a sliver 9 m long and at most 0.2 m wide: between cell centres in
#: many of its columns and rows.
TRIANGLE = [[-3.0, -2.0], [4.0, -1.0], [0.5, 3.5]]
SLIVER = [[-4.5, -0.1], [4.5, 0.0], [-4.5, 0.1]]


def _plan_case(deg, height, occluded=False, m=1, cut=None, shape=TRIANGLE):
    """A triangle (``shape``) turned ``deg`` at ``height`` over the aim plane, seen from 1 km up
    and 1 km across; its members are the cells whose centre the reference position sees inside it
    (and inside the lattice-line rectangle ``cut``, ``(x0, x1, y0, y1)``, when given: the beam's
    edge or the range window)."""
    tri = np.c_[_rotated(shape, deg), np.full(3, height)]
    tri[:, 1] += 2.0
    views = np.array([[[0.0, -1000.0, 1000.0], [-9.0, -1000.0, 1000.0], [9.0, -1000.0, 1000.0]]])
    blocks = Blocks.of([(0, -20, 10, 40 * m, 100 * m, m)])
    poly = _ccw(lattice_lines(tri, views[0, 0], _FP, 0.0, 0.0, float(m)))
    ii, jj = np.meshgrid(np.arange(40 * m), np.arange(100 * m), indexing="ij")
    gi, gj = ii - 20 * m, jj + 10 * m
    centres = np.stack([gi + 0.5, gj + 0.5], -1).reshape(-1, 2)
    inside = np.ones(len(centres), bool)
    for a, b in zip(poly, np.roll(poly, -1, axis=0)):
        inside &= (b - a)[0] * (centres - a)[:, 1] - (b - a)[1] * (centres - a)[:, 0] > 0
    if cut is not None:
        inside &= np.any([(gi.ravel() >= x0) & (gi.ravel() + 1 <= x1) & (gj.ravel() >= y0) & (gj.ravel() + 1 <= y1)
                          for x0, x1, y0, y1 in cut], axis=0)
    lane = np.flatnonzero(inside)
    if occluded == "interior":         # an occluder hides one interior member
        lane = np.delete(lane, len(lane) // 2)
    elif occluded == "stray":          # ... or a tube meets the part outside it (no member may)
        lane = np.append(lane, lane.max() + 1)
    elif occluded == "column":         # ... or a whole column of members
        lane = lane[gi.ravel()[lane] != np.median(gi.ravel()[lane]).round()]
    n = len(lane)
    result = plan(np.zeros(n), np.zeros(n), np.zeros(n), lane, blocks, np.concatenate([tri, tri[-1:]])[None], views, _FP)
    return tri, views, result, np.stack([gi.ravel()[lane], gj.ravel()[lane]], 1)


def _assert_tiles(tri, views, result, cells, cut=None, hole=None, occluder=None, owned=None, scale=1.0, cell=1.0):
    """The plan's owned pieces (cut to the part, less the projections of their occluders) and the
    tiles of the members it leaves whole tile the part (within ``cut``, less the cell ``hole``,
    less the projection of the convex ``occluder`` [k, 3]) as each pulse sees it: areas and
    Gordon's integral, for the sub-aperture's reference, first and last pulse and one between.
    ``owned``: whether each member in ``cells`` is owned (``result.owned`` when the part's
    records are all there are). ``scale``: each piece's tubes per coarse cell edge (its bounds are
    in those lines); ``cells`` are in coarse lines, each ``cell`` wide."""
    owned = result.owned if owned is None else owned
    scale = np.broadcast_to(scale, (len(result.bounds),))
    cell = np.broadcast_to(cell, (len(cells),))
    for antenna in (*views[0], 0.3 * views[0, 1] + 0.7 * views[0, 0]):
        part = _ccw(lattice_lines(tri, antenna, _FP, 0.0, 0.0, 1.0))
        edges = [(part[n], part[(n + 1) % 3]) for n in range(3)]
        shadow = []
        if occluder is not None:          # the occluder's projection: its edges, left side inside
            occ = _ccw(lattice_lines(occluder, antenna, _FP, 0.0, 0.0, 1.0))
            shadow = [(occ[n], occ[(n + 1) % len(occ)]) for n in range(len(occ))]
        targets = [part]
        if cut is not None:      # the part within each rectangle, as half-planes (left side kept)
            targets = []
            for x0, x1, y0, y1 in cut:
                target = part
                for line in (((x0, 1), (x0, 0)), ((x1, 0), (x1, 1)), ((0, y0), (1, y0)), ((1, y1), (0, y1))):
                    target = clip_convex(target, line)
                targets.append(target)
        pieces, cuts = [], []
        for q, (x0, x1, y0, y1) in enumerate(result.bounds):
            x0, x1, y0, y1 = (float(np.clip(v, -1e4, 1e4)) / scale[q] for v in (x0, x1, y0, y1))
            poly = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
            for line in edges:
                poly = clip_convex(poly, line)
            if len(poly) >= 3:
                pieces.append(poly)
            for _ in range(int(np.sum(result.cut_piece == q))):
                for line in shadow:
                    poly = clip_convex(poly, line)
                if len(poly) >= 3:
                    cuts.append(poly)
        for (i, j), w in zip(cells[~owned], cell[~owned]):
            tile = np.array([[i, j], [i + w, j], [i + w, j + w], [i, j + w]], float)
            assert len(clip_convex(clip_convex(clip_convex(tile, edges[0]), edges[1]), edges[2])) == 4
            pieces.append(tile)
        holes = [] if hole is None else [hole]
        if shadow:
            in_shadow = part
            for line in shadow:
                in_shadow = clip_convex(in_shadow, line)
            holes.append(in_shadow)
        area = sum(_shoelace(t) for t in targets) - sum(_shoelace(h) for h in holes)
        assert sum(_shoelace(p) for p in pieces) - sum(_shoelace(c) for c in cuts) == pytest.approx(area, rel=1e-10)
        for q in ([2.1, -1.3], [0.4, 3.7]):
            total = sum(_integral(p, np.array(q)) for p in pieces) - sum(_integral(c, np.array(q)) for c in cuts)
            expected = sum(_integral(t, np.array(q)) for t in targets if len(t) >= 3) \
                - sum(_integral(h, np.array(q)) for h in holes)
            assert abs(total - expected) < 1e-10 * area


@pytest.mark.parametrize("deg", [30.0, 60.0])
@pytest.mark.parametrize("height", [0.0, 35.0])
def test_plan_pieces_and_whole_tiles_tile_the_part_for_every_view(deg, height):
    """The part alone (35 m up: 0.7 cells of parallax between the sub-aperture's ends)."""
    tri, views, result, cells = _plan_case(deg, height)
    assert result.fallback == 0 and result.owned.any() and not result.owned.all()
    _assert_tiles(tri, views, result, cells)


@pytest.mark.parametrize("deg", [30.0, 60.0])
@pytest.mark.parametrize("height", [0.0, 35.0])
def test_plan_pieces_stop_where_the_beam_cuts_the_members(deg, height):
    """Members cut short of the part's edge by the beam's edges along track (lattice lines on both
    sides): the pieces and tiles cover the part within the cut exactly, so the part's own edges
    return as edges and nothing beyond the beam is integrated. (The lattice covers every part in
    range, planning.ray_footprint, so nothing cuts a column but the beam's curved edge, tested
    next, and shadows, tested with the occluders.)"""
    cut = [(-1.0, 3.0, -1e4, 1e4)]
    tri, views, result, cells = _plan_case(deg, height, cut=cut)
    assert result.fallback == 0 and result.owned.any() and not result.owned.all()
    _assert_tiles(tri, views, result, cells, cut)


@pytest.mark.parametrize("deg", [30.0, 60.0])
def test_plan_pieces_stop_at_a_staircase_cut(deg):
    """A cut that is no straight line (the beam's edge across range is a conic on the aim plane,
    cut at each row's own column): ends short of the part's edge own nothing beyond their cell, so
    the pieces cover the part within the staircase exactly. (Where a side of the members has a cut
    end, every piece stops at the members' last line on that side, exact for a straight cut: so
    here each side a step cuts is cut along its whole length, physics.md (T6).)"""
    steps = {30.0: ((1.0, 30.0), (4.0, 32.0), (6.0, 33.0)), 60.0: ((-4.0, 35.0), (0.0, 33.0), (3.0, 31.0), (1e4, 34.0))}
    edges = [-1e4] + [x for x, _ in steps[deg]]
    cut = [(x0, x1, y0, 1e4) for x0, (x1, y0) in zip(edges, steps[deg])]
    tri, views, result, cells = _plan_case(deg, 0.0, cut=cut)
    assert result.fallback == 0 and result.owned.any()
    _assert_tiles(tri, views, result, cells, cut)


def _square(centre, height, side=1.6):
    """A level square ``side`` wide, ``height`` above the aim plane, placed so that the reference
    position (1 km up, 1 km across) sees it at ``centre`` on the aim plane."""
    square = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]) * side / 2 + centre
    scale = (1000.0 - height) / 1000.0
    return np.c_[square[:, 0] * scale, (square[:, 1] + 1000.0) * scale - 1000.0, np.full(4, height)]


def _occluded_case(deg, offset, *others):
    """The 30 or 60 deg triangle on the aim plane with a square 1.6 m wide, 30 m above it, in front
    (0.5 cells of parallax between the sub-aperture's ends): its projection is ``offset`` [m] from
    the triangle's centroid (``others``: more squares, ``(offset, height)``). Cells whose centre
    the reference position sees in a square's projection are that square's records (parts 1, 2,
    ..., the highest where they overlap); the triangle's members are the rest of its cells."""
    tri = np.c_[_rotated([[-3.0, -2.0], [4.0, -1.0], [0.5, 3.5]], deg), np.zeros(3)]
    tri[:, 1] += 2.0
    views = np.array([[[0.0, -1000.0, 1000.0], [-9.0, -1000.0, 1000.0], [9.0, -1000.0, 1000.0]]])
    squares = [_square(tri.mean(0)[:2] + np.asarray(o), h) for o, h in ((offset, 30.0), *others)]
    blocks = Blocks.of([(0, -20, 10, 40, 100, 1)])
    ii, jj = np.meshgrid(np.arange(40), np.arange(100), indexing="ij")
    gi, gj = ii.ravel() - 20, jj.ravel() + 10
    centres = np.stack([gi + 0.5, gj + 0.5], -1)

    def inside(poly):
        poly = _ccw(lattice_lines(poly, views[0, 0], _FP, 0.0, 0.0, 1.0))
        keep = np.ones(len(centres), bool)
        for a, b in zip(poly, np.roll(poly, -1, axis=0)):
            keep &= (b - a)[0] * (centres - a)[:, 1] - (b - a)[1] * (centres - a)[:, 0] > 0
        return keep
    hit = np.where(inside(tri), 0, -1)
    for k in sorted(range(len(squares)), key=lambda k: squares[k][0, 2]):      # the highest last
        hit = np.where(inside(squares[k]), k + 1, hit)
    lane = np.flatnonzero(hit >= 0)
    part = hit[lane]
    vertices = np.stack([np.concatenate([tri, tri[-1:]]), *squares])
    result = plan(np.zeros(len(lane)), part, np.zeros(len(lane)), lane, blocks, vertices, views, _FP)
    mine = part == 0
    hidden = int(np.sum(inside(tri) & (hit > 0)))
    return (tri, squares[0] if not others else squares, views, _part_only(result, mine),
            np.stack([gi[lane], gj[lane]], 1)[mine], result.owned[mine], hidden)


@pytest.mark.parametrize("deg", [30.0, 60.0])
@pytest.mark.parametrize("offset", [(0.0, 0.0), (0.7, 0.8), (-1.8, 0.0), (-2.7, 0.0)],
                         ids=["inside", "off-centre", "across the edge", "beside the edge"])
def test_plan_cuts_the_shadow_of_a_part_in_front_out_of_the_pieces(deg, offset):
    """A part in front hides some of the triangle's cells (a hole; or, across the triangle's edge,
    the ends of some columns and rows; or, beside the edge, no cell centre from the reference
    position but up to 1.8 cells of the triangle from the sub-aperture's first pulse): the pieces
    around the shadow, less the occluder's projection as each pulse sees it, and the whole tiles
    tile the triangle less the shadow exactly. Truth: the shoelace area and Gordon's closed form
    of the triangle less those of (triangle ∩ shadow), both convex."""
    tri, occluder, views, result, cells, owned, hidden = _occluded_case(deg, np.array(offset))
    assert (hidden == 0 if offset == (-2.7, 0.0) else hidden >= 2)
    assert len(result.cut_piece) > 0 and result.fallback == 0
    _assert_tiles(tri, views, result, cells, occluder=occluder, owned=owned)


def _part_only(result, mine):
    """The plan's pieces of the records ``mine`` (the occluders' own groups are not under test)."""
    keep = mine[result.record]
    cut, pair = keep[result.cut_piece], keep[result.pair_piece]
    renumber = np.cumsum(keep) - 1
    return dataclasses.replace(result, record=result.record[keep], bounds=result.bounds[keep],
                               cut_piece=renumber[result.cut_piece[cut]], cut_part=result.cut_part[cut],
                               pair_piece=renumber[result.pair_piece[pair]],
                               pair_parts=tuple(p[pair] for p in result.pair_parts))


def test_plan_adds_back_where_two_shadows_overlap():
    """Two squares in front, 30 and 20 m up, whose shadows overlap on the triangle: each piece is
    cut by both, and where both meet it their overlap is added back once. The pieces less their
    cuts plus their pairs, and the whole tiles, give the area of the triangle less the union of
    the shadows (shapely) and Gordon's closed form of the triangle less that of each shadow on it
    plus that of both, for the reference, first and last pulse."""
    shapely = pytest.importorskip("shapely")
    tri, squares, views, result, cells, owned, hidden = _occluded_case(30.0, (0.0, 0.0), ((0.9, 0.6), 20.0))
    assert hidden >= 4 and len(result.pair_piece) > 0
    for antenna in views[0]:
        part = _ccw(lattice_lines(tri, antenna, _FP, 0.0, 0.0, 1.0))
        shadows = [_ccw(lattice_lines(sq, antenna, _FP, 0.0, 0.0, 1.0)) for sq in squares]

        def clip(poly, *polygons):
            for other in polygons:
                for n in range(len(other)):
                    poly = clip_convex(poly, (other[n], other[(n + 1) % len(other)]))
            return poly
        signed = [(1.0, np.array([[i, j], [i + 1, j], [i + 1, j + 1], [i, j + 1]], float)) for i, j in cells[~owned]]
        for q, (x0, x1, y0, y1) in enumerate(np.clip(result.bounds, -1e4, 1e4)):
            piece = clip(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]), part)
            signed.append((1.0, piece))
            signed += [(-1.0, clip(piece, shadows[k - 1])) for k in result.cut_part[result.cut_piece == q]]
            signed += [(1.0, clip(piece, shadows[a - 1], shadows[b - 1]))
                       for a, b in zip(*(p[result.pair_piece == q] for p in result.pair_parts))]
        signed = [(w, p) for w, p in signed if len(p) >= 3]
        truth = shapely.Polygon(part).difference(shapely.unary_union([shapely.Polygon(s_) for s_ in shadows])).area
        assert sum(w * _shoelace(p) for w, p in signed) == pytest.approx(truth, rel=1e-10)
        for g in ([2.1, -1.3], [0.4, 3.7]):
            exact = _integral(part, g) - sum(_integral(clip(part, s_), g) for s_ in shadows) \
                + _integral(clip(part, *shadows), g)
            assert abs(sum(w * _integral(p, np.array(g)) for w, p in signed) - exact) < 1e-10 * truth


def test_plan_leaves_a_stray_member_to_whole_tiles():
    """A tube that meets the part where the reference position sees no part (a cell beyond a
    row's end): the ends are not where the part says, so the group keeps its tiles."""
    _, _, result, _ = _plan_case(30.0, 0.0, occluded="stray")
    assert result.fallback == result.groups == 1 and not result.owned.any()


def test_plan_leaves_a_hole_to_the_tiles_around_it():
    """An interior cell that is no member (an occluder's shadow): the rest of the part is still
    tiled exactly, and the hole is not covered (the tiles around it bound it)."""
    tri, views, result, cells = _plan_case(30.0, 0.0, occluded="interior")
    assert result.fallback == 0 and result.owned.any()
    hole = sorted(set(map(tuple, _plan_case(30.0, 0.0)[3])) - set(map(tuple, cells)))
    assert len(hole) == 1
    i, j = hole[0]
    _assert_tiles(tri, views, result, cells, hole=np.array([[i, j], [i + 1, j], [i + 1, j + 1], [i, j + 1]], float))


def test_plan_leaves_a_missing_column_to_whoever_traced_it():
    """A whole column of cell centres inside the part with no member (cells a refined block
    traced, or an occluder's shadow): no row band covers it, the rest is tiled exactly."""
    tri, views, result, cells = _plan_case(30.0, 0.0, occluded="column")
    assert result.fallback == 0 and result.owned.any()
    full = _plan_case(30.0, 0.0)[3]
    gone = sorted(set(map(tuple, full)) - set(map(tuple, cells)))
    column = {i for i, _ in gone}
    assert len(column) == 1 and len(gone) > 3
    i = column.pop()
    part = _ccw(lattice_lines(tri, views[0, 0], _FP, 0.0, 0.0, 1.0))
    strip = clip_convex(clip_convex(part, ((i, 1.0), (i, 0.0))), ((i + 1, 0.0), (i + 1, 1.0)))
    _assert_tiles(tri, views, result, cells, hole=strip)


@pytest.mark.parametrize("deg", [8.0, 30.0, 60.0])
@pytest.mark.parametrize("height", [0.0, 35.0])
def test_plan_tiles_a_sliver_between_cell_centres(deg, height):
    """A sliver whose centre-free columns and rows lie between member ones: the row bands cover
    those runs, and the pieces tile the part exactly for every view (a Munich roof's acute corner
    fell back to whole tiles before, and moved its image by +4 dB with the lattice)."""
    tri, views, result, cells = _plan_case(deg, height, shape=SLIVER)
    columns, rows = np.unique(cells[:, 0]), np.unique(cells[:, 1])
    assert np.ptp(columns) + 1 > len(columns) or np.ptp(rows) + 1 > len(rows)      # the premise: gaps
    assert result.fallback == 0 and result.owned.any()
    _assert_tiles(tri, views, result, cells)


def test_plan_counts_cells_on_the_refined_lattice():
    """Tubes 3 to a coarse cell: members counted on the fine lattice, pieces in its lines, and
    they tile the part exactly."""
    tri, views, result, cells = _plan_case(60.0, 0.0, m=3)
    assert result.fallback == 0 and result.owned.any()
    part = _ccw(lattice_lines(tri, views[0, 0], _FP, 0.0, 0.0, 3.0))
    assert np.all(np.abs(result.bounds[(np.abs(result.bounds) < UNBOUNDED)]) < 200)
    assert abs(_shoelace(part)) > 100       # the part spans many fine cells
    _assert_tiles(tri, views, result, cells / 3.0, scale=3.0, cell=1 / 3)


def test_plan_leaves_a_part_across_refined_cells_to_whole_tiles():
    """A part traced on the coarse lattice and, in one of its cells, by tubes 3 to a coarse cell:
    neither lattice's partition may reach into the other's cells, so the group keeps its tiles
    (physics.md (T6): Munich's ground and large roofs next to small objects)."""
    tri, views, result, cells = _plan_case(30.0, 0.0)
    blocks = Blocks.of([(0, -20, 10, 40, 100, 1), (0, int(cells[0, 0]), int(cells[0, 1]), 3, 3, 3)])
    n = len(cells)
    lane = (cells[:, 0] + 20) * 100 + cells[:, 1] - 10
    block = np.zeros(n, int)
    lane[0], block[0] = 4000 + 4, 1                   # the centre tube of the refined cell
    tri4 = np.concatenate([tri, tri[-1:]])[None]
    mixed = plan(np.zeros(n), np.zeros(n), block, lane, blocks, tri4, views, _FP)
    assert mixed.fallback == mixed.groups == 1 and not mixed.owned.any()
