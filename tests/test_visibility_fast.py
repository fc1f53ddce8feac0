"""The visibility casts' host work against its readable references (issue 56): first_hit's distance
masked in the cast's kernel, lift's norm, the legs of the paths and the occluders of mixed pieces
gathered by np.take, the discovery grid's points. Each pair must agree exactly, on the calls a
render of a small city block makes (rays that hit, miss and graze) and on degenerate inputs."""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.tracing import lit_pieces as lp
from sarmitsuba.tracing import mesh_trace
from sarmitsuba.tracing.visibility import NO_HIT, NOT_A_MESH, Rays, lift

import drjit as dr                                  # after sarmitsuba, which picks the variant
import mitsuba as mi

from test_patches import block, render


def _lift_reference(points, normal, toward):
    side = np.sign(np.einsum("mi,mi->m", normal, toward - points))
    size = 1e-4 + 1e-6 * np.linalg.norm(points, axis=1)
    return points + normal * (side * size)[:, None]


def _first_hit_reference(rays, start, end=None, direction=None):
    """:meth:`Rays.first_hit` as it was: ``found`` read back after the cast, the distance masked by
    np.where."""
    if len(start) == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    pi = rays.scene.ray_intersect_preliminary(rays._ray(start, end, direction), coherent=False)
    found = pi.is_valid()
    shape = dr.reinterpret_array(mi.UInt32, pi.shape)
    mesh = found & (dr.gather(mi.UInt32, rays.is_mesh, shape, found) > 0)
    triangle = dr.gather(mi.UInt32, rays.base, shape, mesh) + pi.prim_index
    part = dr.select(mesh, dr.gather(mi.Int32, rays.part, triangle, mesh), NOT_A_MESH)
    part = dr.select(found, part, NO_HIT)
    dr.eval(part, pi.t)
    part, t = part.numpy().astype(np.int64), np.where(found.numpy(), pi.t.numpy().astype(np.float64), np.inf)
    return rays._resolve(part, t, start, end, direction), t


def _legs_reference(surfaces, chains, chain, points, antenna):
    """:func:`sarmitsuba.tracing.lit_pieces.legs` with fancy-index gathers."""
    depth = chains.parts.shape[1]
    order = chains.order[chain]
    q = lp.path_points(surfaces, chains, chain, points, antenna)
    start = np.zeros((len(chain), depth + 1, 3))
    end = np.zeros_like(start)
    exists = np.zeros((len(chain), depth + 1), bool)
    for leg in range(depth):
        rows = np.flatnonzero(order >= leg)
        a = antenna[rows] if leg == 0 else q[rows, leg - 1]
        b = q[rows, leg]
        b = _lift_reference(b, surfaces.normal[chains.parts[chain[rows], leg]], a)
        if leg > 0:
            a = _lift_reference(a, surfaces.normal[chains.parts[chain[rows], leg - 1]], b)
        start[rows, leg], end[rows, leg], exists[rows, leg] = b if leg == 0 else a, a if leg == 0 else b, True
    start[:, depth] = _lift_reference(points, surfaces.normal[chains.last[chain]], antenna)
    end[:, depth] = antenna
    exists[:, depth] = order != 0
    return start, end, exists


def _blockers_reference(rays, surfaces, chains, coords, owner, chain, antenna, mixed, reach):
    """:func:`sarmitsuba.tracing.lit_pieces._blockers` with fancy-index gathers over [s, D + 1, 3]."""
    n = len(mixed)
    rows = np.flatnonzero(mixed[owner])
    if len(rows) == 0:
        return lp.Blockers.empty()
    points = surfaces.to_world(chains.last[chain[rows]], coords[rows])
    start, end, exists = _legs_reference(surfaces, chains, chain[rows], points, antenna[chain[rows]])
    sample, leg = np.nonzero(exists)
    part, _ = _first_hit_reference(rays, start[sample, leg], end[sample, leg])
    found = np.flatnonzero(part != NO_HIT)
    key = np.where(part >= 0, leg * surfaces.n_parts + part, -2)[found]
    piece = owner[rows][sample[found]]
    via = np.flatnonzero(key >= 0)
    hit_part = key[via] % surfaces.n_parts
    partner_start, partner_parts = rays.occluder_partners
    size = partner_start[hit_part + 1] - partner_start[hit_part]
    rep = np.repeat(via, size)
    local = np.arange(int(size.sum())) - np.repeat(np.cumsum(size) - size, size)
    extra = partner_parts[np.repeat(partner_start[hit_part], size) + local]
    a = start[sample[found[rep]], leg[found[rep]]]
    b = end[sample[found[rep]], leg[found[rep]]]
    centre, radius = rays.part_sphere
    ab = b - a
    t = np.clip(np.einsum("mi,mi->m", centre[extra] - a, ab) / np.maximum(np.einsum("mi,mi->m", ab, ab), 1e-300), 0, 1)
    near = np.linalg.norm(a + t[:, None] * ab - centre[extra], axis=1) <= radius[extra] + reach
    piece = np.concatenate([piece, piece[rep[near]]])
    key = np.concatenate([key, (key[rep[near]] // surfaces.n_parts) * surfaces.n_parts + extra[near]])
    piece_chain = np.zeros(n, np.int64)
    piece_chain[owner] = chain
    pairs = lp.Blockers.of(piece, key)
    keep = ~lp.in_leg_planes(surfaces, chains, piece_chain[pairs.piece], pairs.key)
    return lp.Blockers(pairs.piece[keep], pairs.key[keep])


def _grid_points_reference(pieces, subdivision, patch):
    """:func:`sarmitsuba.tracing.mesh_trace._grid_points` with fancy-index and mask gathers."""
    from sarmitsuba.tracing.polygons import edge_lines, inside
    count = subdivision ** 2
    owner = np.repeat(np.arange(len(pieces)), count)
    local = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    m = subdivision[owner]
    offset = np.stack([(local // m + 0.5) / m, (local % m + 0.5) / m], axis=1)
    points = (pieces.cell[owner] + offset) * patch
    held = pieces.whole[owner].copy()
    test = np.flatnonzero(~held)
    if len(test):
        lines = edge_lines(pieces.polygon, pieces.count)
        held[test] = inside(points[test][:, None, :], lines[pieces.border[owner[test]]])[:, 0]
    owner, points = owner[held], points[held]
    empty = np.flatnonzero(np.bincount(owner, minlength=len(pieces)) == 0)
    if len(empty):
        _, centroid, _, _ = pieces.select(empty).geometry()
        owner, points = np.concatenate([owner, empty]), np.concatenate([points, centroid])
    return owner, points


@pytest.fixture(scope="module")
def recorded():
    """The calls of a depth-3 render of the subdivided block: first_hit's, _blockers' and
    _grid_points' arguments and results."""
    calls = {"first_hit": [], "blockers": [], "grid": []}
    first_hit, blockers, grid = Rays.first_hit, lp._blockers, mesh_trace._grid_points

    def first_hit_rec(self, start, end=None, direction=None):
        out = first_hit(self, start, end, direction)
        calls["first_hit"].append((self, start, end, direction, out))
        return out

    def blockers_rec(*args):
        out = blockers(*args)
        calls["blockers"].append((args, out))
        return out

    def grid_rec(*args):
        out = grid(*args)
        calls["grid"].append((args, out))
        return out

    mp = pytest.MonkeyPatch()
    mp.setattr(Rays, "first_hit", first_hit_rec)
    mp.setattr(lp, "_blockers", blockers_rec)
    mp.setattr(mesh_trace, "_grid_points", grid_rec)
    try:
        render(block(subdivide=True), depth=3)
    finally:
        mp.undo()
    assert all(calls[k] for k in calls)
    return calls


def _same(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))


def test_lift_is_the_reference():
    """Random points, a zero normal, a point on its plane (side 0), the origin, no rows."""
    rng = np.random.default_rng(3)
    points = rng.normal(size=(501, 3)) * 1e3
    normal = rng.normal(size=(501, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    toward = points + rng.normal(size=(501, 3))
    normal[0] = 0.0
    toward[1] = points[1]
    points[2] = 0.0
    assert _same(lift(points, normal, toward), _lift_reference(points, normal, toward))
    empty = np.zeros((0, 3))
    assert _same(lift(empty, empty, empty), _lift_reference(empty, empty, empty))


def test_first_hit_is_the_reference(recorded):
    """Every call of the render, and rays that miss (upward), hit from above, start inside
    buildings, bounded and unbounded; no rays."""
    rays = recorded["first_hit"][0][0]
    for _, start, end, direction, (part, t) in recorded["first_hit"]:
        want = _first_hit_reference(rays, start, end, direction)
        assert _same(part, want[0]) and _same(t, want[1])
    rng = np.random.default_rng(5)
    start = rng.uniform(-30, 30, size=(2000, 3)) * [1, 1, 0] + [0, 0, 40]
    start[:200, 2] = 5.0                                   # inside or beside the buildings
    direction = rng.normal(size=(2000, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    for args in ((start, None, direction), (start, start + 60 * direction, None), (start, start, None)):
        got, want = rays.first_hit(*args), _first_hit_reference(rays, *args)
        assert _same(got[0], want[0]) and _same(got[1], want[1])
    part, t = rays.first_hit(start, None, direction)
    assert (part == NO_HIT).any() and (part >= 0).any() and np.isinf(t[part == NO_HIT]).all()
    empty = rays.first_hit(np.zeros((0, 3)), np.zeros((0, 3)))
    assert empty[0].shape == (0,) and empty[1].shape == (0,)


def test_blockers_are_the_reference(recorded):
    """The mixed pieces' occluders of every call of the render, pair for pair."""
    assert any(len(out.piece) for _, out in recorded["blockers"])
    for args, out in recorded["blockers"]:
        want = _blockers_reference(*args)
        assert _same(out.piece, want.piece) and _same(out.key, want.key)


def test_legs_are_the_reference(recorded):
    """The legs of the samples of the recorded mixed pieces (every bounce order of the render)."""
    for (rays, surfaces, chains, coords, owner, chain, antenna, mixed, reach), _ in recorded["blockers"]:
        rows = np.flatnonzero(mixed[owner])
        points = surfaces.to_world(chains.last[chain[rows]], coords[rows])
        got = lp.legs(surfaces, chains, chain[rows], points, antenna[chain[rows]])
        want = _legs_reference(surfaces, chains, chain[rows], points, antenna[chain[rows]])
        assert all(_same(g, w) for g, w in zip(got, want))


def test_grid_points_are_the_reference(recorded):
    """The discovery grid's points of every call of the render (whole and border pieces, pieces
    that hold no grid point), and of no pieces."""
    for args, (owner, points) in recorded["grid"]:
        want = _grid_points_reference(*args)
        assert _same(owner, want[0]) and _same(points, want[1])
    pieces, subdivision, patch = recorded["grid"][0][0]
    none = pieces.select(np.zeros(0, np.int64))
    got, want = mesh_trace._grid_points(none, subdivision[:0], patch), _grid_points_reference(none, subdivision[:0], patch)
    assert _same(got[0], want[0]) and _same(got[1], want[1])
