"""The cell plan's bookkeeping (docs/physics.md (T6)): its fast lookups against their readable
references."""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.tracing.cell_lanes import across_sizes, across_sizes_reference, lane_grid
from sarmitsuba.tracing.kernel import Blocks


@pytest.mark.parametrize("reach", [1, 2])
def test_bucketed_lookup_across_tube_sizes_finds_what_the_cell_by_cell_one_finds(reach):
    """Two sub-apertures of coarse tubes with blocks 7, 3 and 5 times finer (sizes that do and do
    not divide each other), a tenth of the lanes untraced. Truth: the reference, which looks up
    every cell of each lane's neighbourhood on the other lattice. The bucketed lookup gives the
    same pairs, and with a signature the same (lane, signature) pairs, one lane per signature and
    cell. A finer cell bucketed only by the coarse cell of its first corner, or a neighbourhood one
    cell short, loses pairs."""
    rng = np.random.default_rng(3)
    blocks = Blocks.of([(0, 0, 0, 40, 40, 1), (0, 10, 20, 28, 21, 7), (0, 30, 5, 6, 9, 3),
                        (0, 31, 7, 10, 5, 5), (1, 0, 0, 40, 40, 1), (1, 12, 21, 10, 10, 5)])
    grid = lane_grid(blocks, blocks.n_lanes)
    traced = rng.random(blocks.n_lanes) > 0.1
    sub = blocks.sub.astype(np.int64)[grid[0]]
    lanes = np.flatnonzero(traced)
    rows, found = across_sizes_reference(lanes, traced, grid, sub, reach=reach)
    assert rows.size > 1000
    fast = across_sizes(lanes, traced, grid, sub, reach=reach)
    assert set(zip(*fast)) == set(zip(rows.tolist(), found.tolist()))
    signature = rng.integers(0, 3, blocks.n_lanes)
    rows_s, found_s = across_sizes(lanes, traced, grid, sub, reach=reach, signature=signature)
    assert rows_s.size < rows.size / 2
    assert set(zip(rows_s.tolist(), signature[found_s].tolist())) == set(zip(rows.tolist(), signature[found].tolist()))


def _square(centre, half, z):
    x, y = centre
    return [[x - half, y - half, z], [x + half, y - half, z], [x + half, y + half, z], [x - half, y + half, z]]


def _shadow_box(corners, antenna, mirror_x=None):
    """An occluder's shadow on the ground z = 0 cast from ``antenna``, mirrored in the wall
    x = ``mirror_x`` where given, as a shapely polygon in metres (lattice lines of a 1 m lattice
    whose aim plane is the ground): similar triangles, independent of the plan's projection."""
    import shapely
    a = np.asarray(antenna, float)
    pts = []
    for b in np.asarray(corners, float):
        s = a + (b - a) * a[2] / (a[2] - b[2])
        pts.append((2 * mirror_x - s[0] if mirror_x is not None else s[0], s[1]))
    return shapely.Polygon(pts).convex_hull


ANTENNA = np.array([0.3, -700.0, 900.0])
WALL_X = 10.0


def _above(x, y, height, depth):
    """The point ``height`` up on the ray from the antenna to ground point (x, y) (the ground
    mirrored in the wall x = WALL_X at depth 1)."""
    ground = np.array([2 * WALL_X - x if depth else x, y, 0.0])
    return ground + (ANTENNA - ground) * (height / ANTENNA[2])


def _split(depth, blockers):
    """split_crowded on a piece on the ground's cell [2, 3] x [5, 6] (after the wall x = WALL_X at
    depth 1) behind ``blockers`` (the transmit side's at depth 0, the receive side's at 1) and a
    second piece elsewhere behind three of them."""
    from types import SimpleNamespace
    from sarmitsuba.tracing.cell_plan import RECEIVE, split_crowded
    wall_x, antenna = WALL_X, ANTENNA
    ground = _square((0.0, 0.0), 50.0, 0.0)
    wall = [[wall_x, -50, 0], [wall_x, 50, 0], [wall_x, 50, 30], [wall_x, -50, 30]]
    vertices = np.array([ground, wall] + blockers, float)
    normal = np.cross(vertices[:, 1] - vertices[:, 0], vertices[:, 2] - vertices[:, 0])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    offset = np.einsum("ij,ij->i", normal, vertices[:, 0])
    parts = (vertices, np.arange(len(vertices)), normal, offset, None, None, np.zeros(len(vertices), bool))
    fp = SimpleNamespace(origin=np.zeros(3), track=np.array([1.0, 0, 0]), look=np.array([0, 1.0, 0]),
                         spacing_azimuth=1.0, spacing_range=1.0, range_min=0.0)
    views = np.repeat(antenna[None, None], 3, axis=1)
    chain = np.array([[1, 0]] * 2 if depth else [[0]] * 2)
    n = len(blockers)
    level = RECEIVE if depth else 0
    piece = np.array([0] * n + [1] * 3)
    part = np.concatenate([np.arange(n) + 2, [2, 3, 4]])
    bounds = np.array([[2.0, 3.0, 5.0, 6.0], [5.0, 6.0, 5.0, 6.0]])
    out = split_crowded(depth, chain, np.zeros(2, np.int64), np.ones(2), bounds, (piece, part, np.full(piece.size, level)),
                        parts, views, fp)
    return out, level


@pytest.mark.parametrize("depth", [0, 1])
def test_a_crowded_piece_is_split_into_quarters_each_with_the_occluders_that_reach_it(depth):
    """A piece on a 1 m cell of the ground behind 24 small plates 2 m up (at the first bounce the
    transmit side's, after a wall the receive side's) and one larger plate whose shadow covers the
    cell's first quarter is split into quarters with at most 16 each. Truth: which plates'
    shadows, cast from the antenna by similar triangles (and mirrored in the wall), meet each
    quarter (shapely; within the plan's margin they may be kept); at the first bounce the covered
    quarter is empty and left out (on the receive side it is kept: only first-level occluders
    are checked for cover), while a quarter covered by a triangle that dips under the ground (not
    wholly in front) is kept. The other piece keeps its three occluders."""
    import shapely
    from sarmitsuba.tracing.cell_split import MARGIN, MOST_OCCLUDERS
    antenna, wall_x = ANTENNA, WALL_X
    rng = np.random.default_rng(3)
    # the piece's cell [2, 3] x [5, 6] where the unfolded ground lies (mirrored in the wall at depth 1)
    spots = rng.uniform(0.08, 0.92, size=(24, 2)) + (2.0, 5.0)
    blockers = []
    for sx, sy in spots:                 # a plate 2 m up whose shadow falls about (sx, sy)
        x = 2 * wall_x - sx if depth else sx
        ground = np.array([x, sy, 0.0])
        top = ground + (antenna - ground) * (2.0 / antenna[2])
        blockers.append(_square(top[:2], 0.04, 2.0))
    x = 2 * wall_x - 2.25 if depth else 2.25          # the cover: its shadow holds [2, 2.5] x [5, 5.5] and more
    top = np.array([x, 5.25, 0.0]) + (antenna - np.array([x, 5.25, 0.0])) * (2.0 / antenna[2])
    blockers.append(_square(top[:2], 0.35, 2.0))
    if not depth:         # a triangle whose shadow holds [2.5, 3] x [5.5, 6] but that dips under the ground
        ground_points = np.array([[2.4, 5.4, 0.0], [3.8, 5.4, 0.0], [2.4, 6.8, 0.0]])
        heights = np.array([2.0, 2.0, -0.5])
        tri = ground_points + (antenna - ground_points) * (heights / antenna[2])[:, None]
        blockers.append(np.concatenate([tri, tri[-1:]]).tolist())
    (index, out, (o_piece, o_part, o_level)), level = _split(depth, blockers)
    assert sorted(index.tolist()) == [0] * (4 if depth else 3) + [1]
    assert np.all(np.diff(o_piece) >= 0) and set(o_level.tolist()) == {level}
    quarters = np.flatnonzero(index == 0)
    covered = [] if depth else [shapely.box(2, 5, 2.5, 5.5)]
    boxes = [shapely.box(*out[q][[0, 2, 1, 3]]) for q in quarters]
    assert shapely.union_all(boxes + covered).equals(shapely.box(2, 5, 3, 6))
    assert np.isclose(sum(b.area for b in boxes + covered), 1.0)
    shadows = [_shadow_box(b, antenna, wall_x if depth else None) for b in blockers]
    for q in quarters:
        held = set(o_part[o_piece == q].tolist())
        assert 0 < len(held) <= MOST_OCCLUDERS
        box = shapely.box(*out[q][[0, 2, 1, 3]])
        must = {k + 2 for k, s in enumerate(shadows) if s.intersects(box)}
        may = {k + 2 for k, s in enumerate(shadows) if s.distance(box) <= MARGIN + 1e-9}
        assert must <= held <= may, (q, must - held, held - may)
        assert len(must) > 2
    other = np.flatnonzero(index == 1)[0]
    assert out[other].tolist() == [5.0, 6.0, 5.0, 6.0] and sorted(o_part[o_piece == other].tolist()) == [2, 3, 4]


@pytest.mark.parametrize("depth", [0, 1])
def test_a_spire_apex_too_crowded_to_split_is_decided_by_the_central_ray(depth):
    """Twenty faces of an open cone 2 to 3 m up meet at its apex, whose shadow falls in the
    piece's cell: no split separates them there. The sub-pieces are split down to 1/16 of the
    cell; those still crowded are tiles of their own, left out where the central ray is hidden.
    Truth: the union of the faces' shadows cast by similar triangles (shapely). Every output
    has at most 16 occluders, every output whose centre is in shadow has some, and what is left
    out lies in shadow (within half a finest sub-piece)."""
    import shapely
    from sarmitsuba.tracing.cell_plan import MOST_OCCLUDERS
    from sarmitsuba.tracing.cell_split import MOST_SPLITS
    apex = _above(2.43, 5.61, 3.0, depth)
    blockers = []
    for k in range(20):
        a, b = 2 * np.pi * k / 20, 2 * np.pi * (k + 1) / 20
        base = [apex + (0.3 * np.cos(t), 0.3 * np.sin(t), -1.0) for t in (a, b)]
        blockers.append([apex.tolist(), base[0].tolist(), base[1].tolist(), base[1].tolist()])
    (index, out, (o_piece, o_part, o_level)), _ = _split(depth, blockers)
    shadows = shapely.union_all([_shadow_box(b, ANTENNA, WALL_X if depth else None) for b in blockers])
    mine = np.flatnonzero(index == 0)
    counts = np.bincount(o_piece, minlength=len(index))
    assert counts.max() <= MOST_OCCLUDERS
    finest = 1.0 / 2 ** MOST_SPLITS
    assert np.isclose((out[mine, 1] - out[mine, 0]).min(), finest)          # split down to the last halving
    centres = shapely.points(0.5 * (out[mine, 0] + out[mine, 1]), 0.5 * (out[mine, 2] + out[mine, 3]))
    in_shadow = shapely.contains(shadows, centres)
    assert in_shadow.any() and np.all(counts[mine][in_shadow] > 0)
    left = shapely.box(2, 5, 3, 6).difference(shapely.union_all([shapely.box(*b[[0, 2, 1, 3]]) for b in out[mine]]))
    assert left.area > 0 and left.difference(shadows.buffer(finest * 0.75)).area < 1e-12


def test_aim_points_invert_lattice_lines_on_an_oblique_lattice():
    """``aim_points`` is the inverse of ``lattice_lines`` on the aim plane: scene points on the
    plane of a lattice whose track is turned 30 deg and whose look axis dips 40 deg, seen from an
    antenna off the plane, come back to themselves (tube size 3, spacings 0.4 m and 0.7 m).
    Spacings or axes swapped, or the tube size applied once, fail it."""
    from types import SimpleNamespace
    from sarmitsuba.tracing.lattice_index import aim_points, lattice_lines
    a, d = np.radians(30.0), np.radians(40.0)
    track = np.array([np.cos(a), np.sin(a), 0.0])
    look = np.cos(d) * np.array([-np.sin(a), np.cos(a), 0.0]) + np.sin(d) * np.array([0.0, 0.0, -1.0])
    fp = SimpleNamespace(origin=np.array([5.0, -3.0, 2.0]), track=track, look=look, spacing_azimuth=0.4,
                         spacing_range=0.7, range_min=-12.0)
    rng = np.random.default_rng(0)
    u, v = rng.uniform(-30, 30, size=(2, 50))
    points = fp.origin + np.outer(u, track) + np.outer(v, look)             # on the aim plane
    xy = lattice_lines(points, np.array([100.0, -800.0, 700.0]), fp, 0.0, 0.0, 3.0)
    assert np.allclose(aim_points(xy[:, 0], xy[:, 1], fp, 3.0), points, atol=1e-9)


def test_fold_undoes_unfold_through_two_mirrors_that_do_not_commute():
    """A third-order chain's points unfolded in two walls 60 deg apart (reflections that do not
    commute) and folded back are the points again; folding in the unfolding's order instead
    moves them by metres. Truth: the points themselves."""
    from sarmitsuba.tracing.cell_split import fold, unfold
    rng = np.random.default_rng(2)
    points = rng.uniform(-20, 20, size=(8, 3))
    mirrors = []
    for angle, offset in ((0.0, 3.0), (60.0, -2.0)):
        n = np.array([np.cos(np.radians(angle)), np.sin(np.radians(angle)), 0.0])
        mirrors.append((np.repeat(n[None], 8, 0), np.full(8, offset)))
    unfolded = unfold(points, mirrors)
    assert np.abs(unfolded - points).max() > 1.0
    assert np.allclose(fold(unfolded, mirrors), points, atol=1e-12)
