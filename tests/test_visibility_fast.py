"""The visibility casts' host work against readable references (issue 56): first_hit's distance
masked in the cast's kernel, lift's norm, the legs of the paths and the occluders of mixed pieces
gathered by np.take, the discovery grid's points. Each pair must agree exactly, on the calls a
render of a small city block makes (rays that hit, miss and graze) and on degenerate inputs.

The references share no helper with the code they check: the geometry they need is written out
here from docs/physics.md (M3), (M4), (M6): the reflection points on the unfolded path (not
``chains.path_points``), the lift off a surface, the rays cast (float32, stopping a millionth
short of their end) and their hits mapped to parts through the surfaces' triangle tables (not
``Rays._ray``), the parts' bounding spheres, the distinct (piece, occluder) pairs (not
``Blockers.of``), the occluders lying in a leg's own planes (not ``lit_pieces.in_leg_planes``), a
piece's half-planes and centroid (not ``polygons.edge_lines``, ``inside``, ``moments``). The
partner table of an occluder (``Rays.occluder_partners``) is an input here, as the render gives it.

Deliberate bugs these tests fail, and the former references (which called the same helpers)
passed, each planted in a copy of the package: ``chains.path_points``' reflection point mapped
back with ``+ shift``, or its crossing parameter with ``+ n . A``; ``Blockers.of`` without its
sort; ``in_leg_planes`` with the end plane of the last outbound leg dropped; ``IN_PLANE``
negative (no occluder ever in a leg's plane); rays reaching a hundred-thousandth past their
end (``visibility._direction_and_reach``); ``polygons.edge_lines`` with the edges' normals
turned outward.
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.tracing.visibility import lit_pieces as lp
from sarmitsuba.tracing.discovery import specular
from sarmitsuba.tracing.visibility.rays import Rays, lift

import drjit as dr                                  # after sarmitsuba, which picks the variant
import mitsuba as mi

import sarmitsuba
from sarmitsuba.pipeline import simulate
from test_patches import block, render
from test_patches import sensor as patches_sensor

#: ``visibility.NO_HIT`` and ``NOT_A_MESH``: a ray that met nothing, a shape that is not a mesh.
NO_HIT, NOT_A_MESH = -1, -2
#: A point is lifted ``1e-4 m + 1e-6 |p|`` off its surface (``visibility.SURFACE_LIFT``,
#: ``SURFACE_LIFT_RELATIVE``; docs/physics.md (M4)).
LIFT, LIFT_RELATIVE = 1e-4, 1e-6
#: An occluder within this distance [m] of a leg's own plane hides nothing on it (``lit_pieces.IN_PLANE``).
IN_PLANE = 1e-4
#: A bounded ray stops this fraction of its length short of its end (docs/physics.md (M4)).
SHORT = 1e-6


def _dot(x, y):
    return np.einsum("mi,mi->m", x, y)


def _to_world(surfaces, part, coords):
    """``o + x u + y v``: the face frame's origin projected on the part's plane, its axes."""
    origin, normal = surfaces.origin[part], surfaces.normal[part]
    o = origin + normal * (surfaces.offset[part] - _dot(origin, normal))[:, None]
    return o + coords[:, 0, None] * surfaces.axis_u[part] + coords[:, 1, None] * surfaces.axis_v[part]


def _lift_reference(points, normal, toward):
    side = np.sign(np.einsum("mi,mi->m", normal, toward - points))
    size = LIFT + LIFT_RELATIVE * np.linalg.norm(points, axis=1)
    return points + normal * (side * size)[:, None]


def _reflection_points(surfaces, chains, chain, points, antenna):
    """docs/physics.md (M3): the path from ``antenna`` through chain ``chain`` to ``points`` is the
    straight segment ``A -> y``, ``y = U_d(x)``; it crosses window ``i``'s unfolded plane
    ``n_i . w = c_i`` (``n_i = lin_i n``, ``c_i = c + n_i . shift_i``) at ``w = A + t (y - A)``, and
    ``q_i = U_i^{-1}(w) = lin_i^T (w - shift_i)`` (``lin_i`` orthogonal). Rows ``i >= d`` repeat
    the point."""
    depth = chains.parts.shape[1]
    order = chains.order[chain]
    y = np.einsum("mij,mj->mi", chains.lin[chain, order], points) + chains.shift[chain, order]
    out = np.repeat(points[:, None, :], depth, axis=1)
    for i in range(depth - 1):
        rows = np.flatnonzero(order > i)
        c = chain[rows]
        lin, shift, part = chains.lin[c, i], chains.shift[c, i], chains.parts[c, i]
        n_i = np.einsum("mij,mj->mi", lin, surfaces.normal[part])
        c_i = surfaces.offset[part] + _dot(n_i, shift)
        a, ray = antenna[rows], y[rows] - antenna[rows]
        w = a + ((c_i - _dot(n_i, a)) / _dot(n_i, ray))[:, None] * ray
        out[rows, i] = np.einsum("mji,mj->mi", lin, w - shift)
    return out


def _first_hit_reference(rays, start, end=None, direction=None):
    """The part each ray meets first and its distance (float64; inf where none): float32 rays from
    ``start`` toward ``end``, stopping :data:`SHORT` of its length short, or along ``direction``;
    a hit's shape and triangle mapped to its part by ``triangle_part[triangle_base[shape] +
    primitive]`` (shapes that are not meshes, or degenerate triangles: :data:`NOT_A_MESH`)."""
    if len(start) == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    s = rays.surfaces
    assert s.split_count is None or not np.any(s.split_count)       # no covered parts (tests/test_covers_locate.py)
    if end is not None:
        span = end - start
        length = np.linalg.norm(span, axis=1)
        direction, reach = span / np.where(length > 0, length, 1.0)[:, None], length * (1.0 - SHORT)
    else:
        reach = np.full(len(start), np.inf)
    f32 = np.float32
    ray = mi.Ray3f(mi.Point3f(*start.T.astype(f32)), mi.Vector3f(*direction.T.astype(f32)))
    ray.maxt = mi.Float(reach.astype(f32))
    pi = rays.scene.ray_intersect_preliminary(ray, coherent=False)
    dr.eval(pi.t, pi.prim_index, pi.shape)
    found = pi.is_valid().numpy().astype(bool)
    shape = dr.reinterpret_array(mi.UInt32, pi.shape).numpy().astype(np.int64)
    prim = pi.prim_index.numpy().astype(np.int64)
    base = np.full(len(start), -1)
    base[found] = s.triangle_base[shape[found]]
    mesh = found & (base >= 0)
    triangle = np.where(mesh, base + prim, 0)
    met = np.where(mesh, s.triangle_part[triangle], NOT_A_MESH)
    part = np.where(found, np.where(met >= 0, met, NOT_A_MESH), NO_HIT)
    t = np.where(found, pi.t.numpy().astype(np.float64), np.inf)
    return part.astype(np.int64), t


def _legs_reference(surfaces, chains, chain, points, antenna, receiver=None):
    """docs/physics.md (M4): the legs ``A -> q_0 -> ... -> q_{d-1} -> x`` (each ray starting on the
    mesh: the first from ``q_0`` toward the antenna) and ``x -> A``, their ends on surfaces
    lifted off them toward the other end; the return leg exists beyond the first bounce.
    Bistatic (B2): the return is ``x -> R``, the receiver, and exists at every bounce."""
    depth = chains.parts.shape[1]
    order = chains.order[chain]
    q = _reflection_points(surfaces, chains, chain, points, antenna)
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
    back = antenna if receiver is None else receiver
    start[:, depth] = _lift_reference(points, surfaces.normal[chains.parts[chain, order]], back)
    end[:, depth] = back
    exists[:, depth] = (order != 0) | (receiver is not None)
    return start, end, exists


def _spheres(surfaces):
    """Each part's bounding sphere: its corners' box centre and the farthest corner's distance."""
    n, width = surfaces.n_parts, surfaces.polygon.shape[1]
    part = np.repeat(np.arange(n), width)
    corners = _to_world(surfaces, part, surfaces.polygon.reshape(-1, 2)).reshape(n, width, 3)
    live = np.arange(width)[None, :] < surfaces.n_corners[:, None]
    lo = np.where(live[..., None], corners, np.inf).min(axis=1)
    hi = np.where(live[..., None], corners, -np.inf).max(axis=1)
    centre = 0.5 * (lo + hi)
    return centre, np.where(live, np.linalg.norm(corners - centre[:, None], axis=2), 0.0).max(axis=1)


def _distinct_pairs(piece, key):
    """The distinct ``(piece, key)`` pairs, sorted by piece, then key."""
    rank = np.lexsort((key, piece))
    piece, key = piece[rank], key[rank]
    new = np.ones(len(piece), bool)
    new[1:] = (piece[1:] != piece[:-1]) | (key[1:] != key[:-1])
    return piece[new], key[new]


def _in_leg_planes(surfaces, chains, chain, key):
    """docs/physics.md (M4): whether occluder ``key`` (``leg * n_parts + part``) of a path through
    ``chain`` lies, every corner within :data:`IN_PLANE`, in the plane of a part its leg starts or
    ends on: outbound leg ``l`` runs from window ``l - 1`` (the antenna for ``l = 0``) to window
    ``l`` (the last part for ``l = d``), the return leg from the last part to the antenna."""
    depth, n = chains.parts.shape[1], surfaces.n_parts
    out = np.zeros(len(key), bool)
    for r, (c, k) in enumerate(zip(chain, key)):
        if k < 0:
            continue
        leg, part, d = k // n, k % n, chains.order[c]
        if leg == depth:
            planes = [chains.parts[c, d]]
        else:
            planes = ([chains.parts[c, leg - 1]] if leg >= 1 else []) + ([chains.parts[c, leg]] if leg <= d else [])
        count = surfaces.n_corners[part]
        corners = _to_world(surfaces, np.full(count, part), surfaces.polygon[part, :count])
        out[r] = any(np.all(np.abs(corners @ surfaces.normal[p] - surfaces.offset[p]) <= IN_PLANE) for p in planes)
    return out


def _blockers_reference(rays, surfaces, chains, coords, owner, chain, antenna, mixed, reach, receiver=None):
    """docs/physics.md (M4): each mixed piece's samples traced along every leg of their paths; the
    part a leg meets first is an occluder of that leg (``leg * n_parts + part``; ``-2`` not a
    mesh), and with it its partners whose bounding spheres come within ``reach`` of that leg;
    distinct pairs, less the occluders in the leg's own planes: ``(piece, key)``."""
    rows = np.flatnonzero(mixed[owner])
    if len(rows) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    points = _to_world(surfaces, chains.parts[chain[rows], chains.order[chain[rows]]], coords[rows])
    start, end, exists = _legs_reference(surfaces, chains, chain[rows], points, antenna[chain[rows]],
                                         None if receiver is None else receiver[chain[rows]])
    sample, leg = np.nonzero(exists)
    part, _ = _first_hit_reference(rays, start[sample, leg], end[sample, leg])
    found = np.flatnonzero(part != NO_HIT)
    key = np.where(part >= 0, leg * surfaces.n_parts + part, -2)[found]
    piece = owner[rows][sample[found]]
    partner_start, partner_parts = rays.occluder_partners
    centre, radius = _spheres(surfaces)
    more_piece, more_key = [], []
    for j in np.flatnonzero(key >= 0):
        a, b = start[sample[found[j]], leg[found[j]]], end[sample[found[j]], leg[found[j]]]
        hit = key[j] % surfaces.n_parts
        for other in partner_parts[partner_start[hit]:partner_start[hit + 1]]:
            t = np.clip((centre[other] - a) @ (b - a) / max((b - a) @ (b - a), 1e-300), 0.0, 1.0)
            if np.linalg.norm(a + t * (b - a) - centre[other]) <= radius[other] + reach:
                more_piece.append(piece[j])
                more_key.append((key[j] // surfaces.n_parts) * surfaces.n_parts + other)
    piece, key = _distinct_pairs(np.concatenate([piece, np.array(more_piece, np.int64)]),
                                 np.concatenate([key, np.array(more_key, np.int64)]))
    piece_chain = np.zeros(len(mixed), np.int64)
    piece_chain[owner] = chain
    keep = ~_in_leg_planes(surfaces, chains, piece_chain[piece], key)
    return piece[keep], key[keep]


def _grid_points_reference(pieces, subdivision, patch):
    """docs/physics.md (M6): the centres of the ``m x m`` sub-cells of each piece's patch that the
    piece holds (a border piece: inside every half-plane of its polygon's edges, the edge's
    inward normal ``(-dy, dx) / |d|``); a piece that holds none gives its centroid."""
    owner, points = [], []
    for i in range(len(pieces)):
        m = int(subdivision[i])
        k = np.arange(m * m)
        grid = (pieces.cell[i] + np.stack([(k // m + 0.5) / m, (k % m + 0.5) / m], axis=1)) * patch
        if not pieces.whole[i]:
            b = pieces.border[i]
            poly = pieces.polygon[b, :pieces.count[b]]
            edge = np.roll(poly, -1, axis=0) - poly
            length = np.sqrt(edge[:, 0] * edge[:, 0] + edge[:, 1] * edge[:, 1])
            a, bb = -edge[:, 1] / length, edge[:, 0] / length
            c = -(a * poly[:, 0] + bb * poly[:, 1])
            live = length > 0
            grid = grid[np.all((a * grid[:, :1] + bb * grid[:, 1:] + c >= 0) | ~live, axis=1)]
        owner.append(np.full(len(grid), i))
        points.append(grid)
    owner = np.concatenate(owner + [np.zeros(0, np.int64)]).astype(np.int64)
    points = np.concatenate(points + [np.zeros((0, 2))])
    empty = np.flatnonzero(np.bincount(owner, minlength=len(pieces)) == 0)
    centroids = []
    for i in empty:                                   # the centroid: the patch's, or Green's theorem
        if pieces.whole[i]:
            centroids.append((pieces.cell[i] + 0.5) * patch)
            continue
        b = pieces.border[i]
        first = pieces.polygon[b, 0]
        p = pieces.polygon[b, :pieces.count[b]] - first          # about the first corner (conditioning)
        q = np.roll(p, -1, axis=0)
        cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
        centroids.append(first + np.array([np.sum((p[:, 0] + q[:, 0]) * cross), np.sum((p[:, 1] + q[:, 1]) * cross)])
                         / (3.0 * np.sum(cross)))
    return np.concatenate([owner, empty]), np.concatenate([points, np.reshape(centroids, (-1, 2))]), len(empty)


@pytest.fixture(scope="module")
def recorded():
    """The calls of a depth-3 render of the subdivided block: first_hit's, _blockers' and
    grid_points' arguments and results."""
    calls = {"first_hit": [], "blockers": [], "grid": []}
    first_hit, blockers, grid = Rays.first_hit, lp._blockers, specular.grid_points

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
    mp.setattr(specular, "grid_points", grid_rec)
    try:
        render(block(subdivide=True), depth=3)
        # and bistatic, the return legs ending at a receiver across the track (docs/physics.md (B2))
        sensor = {**patches_sensor(20.0, prf=200.0, velocity=100.0, n_pulses=24, antenna_length=2.0),
                  "receiver_altitude": 400.0, "receiver_heading": 110.0, "receiver_velocity": 20.0}
        simulate(sarmitsuba.Scene(block(subdivide=True), sensor=sensor, integrator={"max_depth": 2}),
                 image_size=(32, 32))
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
        piece, key = _blockers_reference(*args)
        assert _same(out.piece, piece) and _same(out.key, key)


def test_legs_are_the_reference(recorded):
    """The legs of the samples of the recorded mixed pieces (every bounce order of the render)."""
    for (rays, surfaces, chains, coords, owner, chain, antenna, mixed, reach, *receiver), _ in recorded["blockers"]:
        rows = np.flatnonzero(mixed[owner])
        points = surfaces.to_world(chains.last[chain[rows]], coords[rows])
        receiver = receiver[0][chain[rows]] if receiver and receiver[0] is not None else None
        got = lp.legs(surfaces, chains, chain[rows], points, antenna[chain[rows]], receiver)
        want = _legs_reference(surfaces, chains, chain[rows], points, antenna[chain[rows]], receiver)
        assert all(_same(g, w) for g, w in zip(got, want))


def test_grid_points_are_the_reference(recorded):
    """The discovery grid's points of every call of the render (whole and border pieces, pieces
    that hold no grid point), and of no pieces."""
    centroids = 0
    for args, (owner, points) in recorded["grid"]:
        want_owner, want_points, empty = _grid_points_reference(*args)
        grid = len(want_owner) - empty
        assert _same(owner, want_owner) and _same(points[:grid], want_points[:grid])
        # the centroids of pieces that hold no grid point: Green's theorem, summed in another order
        assert np.abs(points[grid:] - want_points[grid:]).max(initial=0.0) <= 1e-12 * max(1.0, np.abs(points).max())
        centroids += empty
    pieces, subdivision, patch = recorded["grid"][0][0]
    none = pieces.select(np.zeros(0, np.int64))
    got, want = specular.grid_points(none, subdivision[:0], patch), _grid_points_reference(none, subdivision[:0], patch)
    assert _same(got[0], want[0]) and _same(got[1], want[1])
