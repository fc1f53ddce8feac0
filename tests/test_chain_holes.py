"""The mesh tracer's chains of mirrors and their visibility against independent geometry written
here (docs/physics.md (M3), (M4)): paths built backwards from their reflection points, the image
method traced point by point, and segment-parallelogram crossings. Nothing in the references calls
the code they check; the scenes are turned 25 deg off the axes, their mirrors sit tens of metres
off the origin and meet at 70 or 110 deg (never 0 or 90), and the antennas' headings are not 0.

A mutation audit found three holes in the earlier tests; each test here was seen to fail with its
deliberate bug and to pass without it:
  * ``lit_pieces.classify`` (and ``recheck``) reading the return leg's bit as ``(bits >> order) & 1``
    (the last transmit leg's) instead of ``(bits >> (order + 1)) & 1``: double and triple bounces
    hidden on their way back still lit;
  * ``occlusion._window_planes`` with the shift term's sign flipped: the shadows of third-order
    chains whose first mirror is off the origin and not at right angles to the second are cut at
    the wrong unfolded window;
  * ``chains.path_points`` (and ``image_source``, ``_source_of``, and the device's copy in
    ``PathVisibility.legs_clear``) applying ``U_i`` where ``U_i^{-1}`` is meant: the reflection
    points of chains of four or more bounces through mirrors that neither are parallel nor meet
    at right angles (where a product of reflections is not its own inverse).
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from sarmitsuba.tracing.discovery.chains import image_source, path_points, region_lines, unfold
from sarmitsuba.tracing.mesh.facets import mesh_parts, scene_parts
from sarmitsuba.tracing.visibility.lit_pieces import lit_pieces, recheck
from sarmitsuba.tracing.visibility.occlusion import clip_mixed, shadow_lines
from sarmitsuba.tracing.mesh.patches import surfaces_from
from sarmitsuba.tracing.visibility.rays import PathVisibility, Rays

import drjit as dr                                  # after sarmitsuba, which picks the variant
import mitsuba as mi


# --------------------------------------------------------------------------- independent geometry
def rot_z(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def parallelogram(centre, e1, e2) -> np.ndarray:
    """Corners [4, 3] (counter-clockwise about ``e1 x e2``) of the parallelogram ``centre +- e1 +- e2``,
    rounded to float32 (as a Mitsuba mesh holds them): the references use these very corners."""
    c, e1, e2 = (np.asarray(x, float) for x in (centre, e1, e2))
    return np.array([c - e1 - e2, c + e1 - e2, c + e1 + e2, c - e1 + e2]).astype(np.float32).astype(np.float64)


def plane(corners: np.ndarray) -> tuple[np.ndarray, float]:
    """Unit normal and offset ``n . x = c`` of a parallelogram's plane."""
    n = unit(np.cross(corners[1] - corners[0], corners[3] - corners[0]))
    return n, float(n @ corners[0])


def mirror(points: np.ndarray, n: np.ndarray, c: float) -> np.ndarray:
    """``points`` [..., 3] reflected in the plane ``n . x = c``."""
    return points - 2.0 * (points @ n - c)[..., None] * n


def in_parallelogram(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Signed clearance [m] (m) of points on a parallelogram's plane from its edges (> 0 inside)."""
    e1, e2 = corners[1] - corners[0], corners[3] - corners[0]
    gram = np.array([[e1 @ e1, e1 @ e2], [e1 @ e2, e2 @ e2]])
    rel = points - corners[0]
    u, v = np.linalg.solve(gram, np.stack([rel @ e1, rel @ e2]))
    l1, l2 = np.linalg.norm(e1), np.linalg.norm(e2)
    return np.min(np.stack([u * l1, (1 - u) * l1, v * l2, (1 - v) * l2]), axis=0)


def crossing(a: np.ndarray, b: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Segments ``a -> b`` [m, 3] against a parallelogram: a signed clearance [m] (m), > 0 where the
    open segment crosses it; its size is the distance (in the parallelogram, or along the segment)
    to the nearest place where that answer changes."""
    c0, e1, e2 = corners[0], corners[1] - corners[0], corners[3] - corners[0]
    d = b - a
    system = np.stack([np.broadcast_to(e1, d.shape), np.broadcast_to(e2, d.shape), -d], axis=2)
    ok = np.abs(np.linalg.det(system)) > 1e-9 * np.linalg.norm(d, axis=1)
    solved = np.full((len(a), 3), -np.inf)                # parallel to the plane: never crosses
    if ok.any():
        solved[ok] = np.linalg.solve(system[ok], (a - c0)[ok][..., None])[..., 0]
    u, v, t = solved.T
    l1, l2, length = np.linalg.norm(e1), np.linalg.norm(e2), np.linalg.norm(d, axis=1)
    return np.min(np.stack([u * l1, (1 - u) * l1, v * l2, (1 - v) * l2, t * length, (1 - t) * length]), axis=0)


def image_path(quads: list, seq, antenna: np.ndarray, x: np.ndarray):
    """The paths ``antenna -> seq[0] -> ... -> x`` [m, 3] by the image method: the antenna's images
    in each mirror's plane, then back from ``x`` toward each image to the mirror before it. Returns
    the points ``[antenna, q_0, .., q_{d-1}, x]`` (each [m, 3]), the least clearance [m] of the
    reflection points inside their windows (and along their back-traced legs), > 0 where the path
    exists, and whether the antenna sees ``x``'s side the wave arrives on."""
    planes = [plane(quads[p]) for p in seq]
    images = [np.broadcast_to(antenna, x.shape)]
    for n, c in planes[:-1]:
        images.append(mirror(images[-1], n, c))
    points, cur = [x], x
    clearance = np.full(len(x), np.inf)
    for j in range(len(seq) - 2, -1, -1):
        n, c = planes[j]
        towards = images[j + 1] - cur
        t = (c - cur @ n) / (towards @ n)
        cur = cur + t[:, None] * towards
        length = np.linalg.norm(towards, axis=1)
        clearance = np.minimum(clearance, np.minimum(t * length, (1 - t) * length))
        clearance = np.minimum(clearance, in_parallelogram(cur, quads[seq[j]]))
        points.insert(0, cur)
    n, c = planes[-1]
    returns = np.sign(images[0] @ n - c) == np.sign(images[-1] @ n - c)
    return [images[0]] + points, clearance, returns


def face_to_world(s, part: int, coords: np.ndarray) -> np.ndarray:
    """World points of face coordinates on ``part``, from the frame's fields (origin, axes, plane)."""
    o, n = s.origin[part], s.normal[part]
    o = o + n * (s.offset[part] - o @ n)
    return o + coords[:, :1] * s.axis_u[part] + coords[:, 1:] * s.axis_v[part]


def world_to_face(s, part: int, points: np.ndarray) -> np.ndarray:
    rel = points - s.origin[part]
    return np.stack([rel @ s.axis_u[part], rel @ s.axis_v[part]], axis=1)


# --------------------------------------------------------------------------- scenes
def numpy_surfaces(quads: list):
    """Surfaces of parallelograms (one part each, part ``i`` the ``i``-th), frames anchored at a corner."""
    parts = mesh_parts([(q, np.array([[0, 1, 2], [0, 2, 3]])) for q in quads])
    n = len(quads)
    s = surfaces_from(parts, np.arange(n), np.ones(n, bool), np.array([q[0] for q in quads]),
                      np.tile(np.eye(3), (n, 1, 1)), np.zeros(n, np.int64))
    assert s.n_parts == n and np.array_equal(parts.shape, np.arange(n))
    return s


def _mesh(name: str, corners: np.ndarray):
    mesh = mi.Mesh(name, 4, 2, props=mi.Properties(), has_vertex_normals=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(np.asarray(corners, np.float32).ravel())
    params["faces"] = mi.UInt32(np.array([0, 1, 2, 0, 2, 3], np.uint32))
    params.update()
    return mesh


def mitsuba_scene(quads: list):
    """A Mitsuba scene of parallelograms (one mesh each), its Surfaces, and the part of each
    parallelogram; with the ray casters the tracer uses."""
    scene = mi.load_dict({"type": "scene", **{f"q{i}": _mesh(f"q{i}", q) for i, q in enumerate(quads)}})
    parts = scene_parts(scene)
    shapes = list(scene.shapes())
    ids = np.array([int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(sh))[0]) for sh in shapes], np.int64)
    size = int(ids.max()) + 1
    s = surfaces_from(parts, ids, np.ones(len(ids), bool), np.zeros((size, 3)), np.tile(np.eye(3), (size, 1, 1)),
                      np.zeros(size, np.int64))
    names = [sh.id() for sh in shapes]
    part_of = np.array([np.flatnonzero(parts.shape == names.index(f"q{i}"))[0] for i in range(len(quads))])
    assert s.n_parts == len(quads)
    return scene, s, part_of, Rays(scene, s), PathVisibility(scene, s)


#: The scenes' frame: turned 25 deg about the vertical, and moved off the origin.
TURN, SHIFT = rot_z(25.0), np.array([31.0, -47.0, 5.0])


def world(p) -> np.ndarray:
    return TURN @ np.asarray(p, float) + SHIFT


def along(v) -> np.ndarray:
    return TURN @ np.asarray(v, float)


def corner_block(wall_turn: float = 30.0, angle: float = 110.0, height: float = 3.0, extra=()) -> list:
    """Ground (half-size 25 m), a wall (10 m wide) turned ``wall_turn`` deg off the track, and a second
    wall meeting its end at ``angle`` deg (8 m wide): a concave corner open toward the antennas;
    ``extra`` parallelograms ``(centre, e1, e2)`` in the scene's frame after them."""
    wt = rot_z(wall_turn)
    foot = np.array([0.0, 6.0, height])
    e1 = wt @ np.array([5.0, 0.0, 0.0])
    d2 = wt @ (rot_z(angle) @ np.array([-1.0, 0.0, 0.0]))
    quads = [parallelogram(world([0, 0, 0]), along([25, 0, 0]), along([0, 25, 0])),
             parallelogram(world(foot), along(e1), along([0, 0, height])),
             parallelogram(world(foot + e1 + 4 * d2), along(4 * d2), along([0, 0, height]))]
    return quads + [parallelogram(world(c), along(a), along(b)) for c, a, b in extra]


def antenna_at(look: float, heading: float, distance: float) -> np.ndarray:
    """An antenna ``distance`` m from the scene's frame origin at ``look`` deg off the vertical, seen
    along ``heading`` deg off the scene frame's -y axis."""
    h, lk = math.radians(heading), math.radians(look)
    return world([0, 0, 0]) + distance * along([math.sin(lk) * math.sin(h), -math.sin(lk) * math.cos(h), math.cos(lk)])


# --------------------------------------------------------------------------- hole 4: reflection points
def constructed_paths(rng, orders, centre, antenna):
    """Paths built from their reflection points: random points ``q_0 .. q_{d-1}, x`` near
    ``centre``, and at each ``q_i`` a mirror whose normal bisects the directions to its neighbours
    (so the path obeys the mirror law there by construction). Turns between 25 and 155 deg, legs at
    least 4 m, and every two mirrors of a path neither parallel nor perpendicular (|cos| in
    [0.1, 0.95]). The last part is a plate through ``x`` turned off the arriving leg. Returns the
    parallelograms (2 x 1.5 m half sizes) and, per path, its parts and points ``[A, q_0, .., x]``."""
    quads, paths = [], []
    for d in orders:
        while True:
            route = np.concatenate([antenna[None], centre + rng.uniform(-12, 12, size=(d + 1, 3))])
            back, ahead = unit(route[:-2] - route[1:-1]), unit(route[2:] - route[1:-1])
            turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", back, ahead), -1, 1)))
            normals = unit(back + ahead)
            cos = np.abs(normals @ normals.T)[np.triu_indices(d, 1)]
            if (np.all((turn > 25) & (turn < 155)) and np.linalg.norm(np.diff(route, axis=0), axis=1).min() > 4
                    and np.all((cos > 0.1) & (cos < 0.95))):
                break
        normals = np.concatenate([normals, unit(unit(route[-2] - route[-1]) + rng.normal(size=3) * 0.3)[None]])
        first = len(quads)
        for p, n in zip(route[1:], normals):
            e1 = unit(np.cross(n, rng.normal(size=3)))
            quads.append(np.array([p - 2 * e1 - 1.5 * np.cross(n, e1), p + 2 * e1 - 1.5 * np.cross(n, e1),
                                   p + 2 * e1 + 1.5 * np.cross(n, e1), p - 2 * e1 + 1.5 * np.cross(n, e1)]))
        paths.append((list(range(first, first + d + 1)), route))
    return quads, paths


def slab_surfaces(quads: list):
    """Surfaces of closed slabs 0.3 m thick (triangles wound outward), each with the parallelogram
    ``quads[i]`` as its outer face (normal ``(c_1 - c_0) x (c_3 - c_0)``), and the part of each of
    those faces."""
    meshes = []
    for q in quads:
        n, _ = plane(q)
        corners = np.concatenate([q, q - 0.3 * n])
        quads_of_box = [(0, 1, 2, 3), (7, 6, 5, 4), (0, 4, 5, 1), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 4, 0)]
        triangles = []
        middle = corners.mean(axis=0)
        for a, b, c, d in quads_of_box:
            for tri in ((a, b, c), (a, c, d)):
                t = corners[list(tri)]
                out = np.cross(t[1] - t[0], t[2] - t[0]) @ (t.mean(axis=0) - middle) > 0
                triangles.append(tri if out else tri[::-1])
        meshes.append((corners, np.array(triangles)))
    parts = mesh_parts(meshes)
    n_shapes = len(quads)
    s = surfaces_from(parts, np.arange(n_shapes), np.ones(n_shapes, bool), np.array([q[0] for q in quads]),
                      np.tile(np.eye(3), (n_shapes, 1, 1)), np.zeros(n_shapes, np.int64))
    face_part = np.array([np.flatnonzero((parts.shape == i) & (parts.normal @ plane(q)[0] > 1 - 1e-9))[0]
                          for i, q in enumerate(quads)])
    assert np.all(np.bincount(parts.shape, minlength=n_shapes) == 6) and np.all(parts.closed)
    return s, face_part


def test_reflection_points_of_long_chains_through_oblique_mirrors():
    """Chains of 4, 5 and 6 bounces (3 to 5 mirrors) whose mirrors are neither parallel nor
    perpendicular, 300 m off the origin, seen from an antenna at 41 deg look on a -28 deg heading;
    each mirror the outer face of a closed slab (so the side a window is seen from matters).

    Independent truth: (1) the paths were built from their reflection points (each mirror's normal
    bisects the legs it joins), so :func:`path_points` at the built point ``x`` must return those
    points, and the image source (:func:`image_source`) lies on the last leg produced backwards,
    at the path's whole length from ``x`` (and ``U_d(x)`` as far from ``A`` along the first leg);
    (2) for other points of the last part (up to 0.4 m off the built one), every reflection point
    lies on its mirror's plane and each leg leaves it as the mirror image of the one arriving
    (the law of reflection, checked with reflection matrices written here), and the points are
    those of the image method traced back from ``x``; (3) the built points lie inside the chains'
    regions (:func:`region_lines`: the path crosses every window's centre, each from its slab's
    outer side), and the chains are valid.

    Seen to catch: ``path_points`` with ``U_i`` for ``U_i^{-1}`` (``einsum("mij,...")`` on
    ``crossing - shift``, and ``lin @ crossing + shift``), ``image_source`` with ``lin_d``
    untransposed, and ``chains._source_of`` (the image source a window is seen from) untransposed
    (every chain then invalid): a reflection matrix is its own inverse, a product of two in
    mirrors that are not at right angles is not."""
    rng = np.random.default_rng(7)
    centre = np.array([140.0, -260.0, 35.0])
    antenna = centre + 800 * np.array([math.sin(math.radians(41)) * math.sin(math.radians(-28)),
                                       -math.sin(math.radians(41)) * math.cos(math.radians(-28)),
                                       math.cos(math.radians(41))])
    orders = [3, 4, 5, 3, 4, 5, 4, 3]
    quads, paths = constructed_paths(rng, orders, centre, antenna)
    s, face_part = slab_surfaces(quads)
    depth = max(orders) + 1
    parts = np.full((len(paths), depth), -1)
    for k, (seq, _) in enumerate(paths):
        parts[k, :len(seq)] = face_part[seq]
    chains = unfold(s, parts, np.array(orders), np.zeros(len(paths), np.int64))
    rows = np.arange(len(paths))
    a = np.repeat(antenna[None], len(paths), 0)

    # (1) the built paths, their image sources and unfolded points
    x = np.array([route[-1] for _, route in paths])
    got = path_points(s, chains, rows, x, a)
    length = np.array([np.linalg.norm(np.diff(route, axis=0), axis=1).sum() for _, route in paths])
    for k, (seq, route) in enumerate(paths):
        d = orders[k]
        np.testing.assert_allclose(got[k, :d + 1], route[1:], rtol=0, atol=1e-7,
                                   err_msg=f"path {k}, order {d}")
        np.testing.assert_allclose(got[k, d + 1:], np.repeat(route[-1:], depth - d - 1, 0), rtol=0, atol=1e-9)
    source = x + length[:, None] * unit(np.array([route[-2] - route[-1] for _, route in paths]))
    np.testing.assert_allclose(image_source(chains, a), source, rtol=0, atol=1e-7)
    first = antenna + length[:, None] * unit(np.array([route[1] - antenna for _, route in paths]))
    np.testing.assert_allclose(chains.unfolded(x, rows), first, rtol=0, atol=1e-7)

    # (2) other points of the last parts: the mirror law at every reflection point
    m = 12
    chain = np.repeat(rows, m)
    offsets = rng.uniform(-0.4, 0.4, size=(len(chain), 2))
    points = np.empty((len(chain), 3))
    for k, (seq, route) in enumerate(paths):
        q = quads[seq[-1]]
        e1, e2 = unit(q[1] - q[0]), unit(q[3] - q[0])
        sel = slice(k * m, (k + 1) * m)
        points[sel] = route[-1] + offsets[sel, :1] * e1 + offsets[sel, 1:] * e2
    got = path_points(s, chains, chain, points, np.repeat(antenna[None], len(chain), 0))
    checked = 0
    for k, (seq, route) in enumerate(paths):
        d = orders[k]
        sel = slice(k * m, (k + 1) * m)
        walk = [np.broadcast_to(antenna, points[sel].shape)] + [got[sel, i] for i in range(d)] + [points[sel]]
        by_images, _, _ = image_path(quads, seq, antenna, points[sel])
        for i in range(d):
            n, c = plane(quads[seq[i]])
            assert np.abs(walk[i + 1] @ n - c).max() < 1e-8, (k, i)            # on the mirror's plane
            reflect = np.eye(3) - 2.0 * np.outer(n, n)
            arriving, leaving = unit(walk[i + 1] - walk[i]), unit(walk[i + 2] - walk[i + 1])
            np.testing.assert_allclose(leaving, arriving @ reflect.T, rtol=0, atol=1e-9,
                                       err_msg=f"path {k}, mirror {i}")
            np.testing.assert_allclose(walk[i + 1], by_images[i + 1], rtol=0, atol=1e-7)
            checked += len(arriving)
    assert checked == m * sum(orders)

    # (3) the built points are reached through their chains
    lines, valid, _ = region_lines(s, chains, a)
    assert valid.all()
    assert np.all(s.seen_side[parts[parts >= 0]] == 1)            # the mirrors: outer faces of closed slabs
    face = np.array([world_to_face(s, face_part[seq[-1]], route[-1:])[0] for seq, route in paths])
    margin = (lines[:, :, 0] * face[:, :1] + lines[:, :, 1] * face[:, 1:] + lines[:, :, 2]).min(axis=1)
    assert np.all(margin > 1e-3), margin


@pytest.mark.parametrize("order", [3, 4])
def test_leg_casts_of_long_chains_follow_the_reflection_points(order):
    """The Dr.Jit leg casts (:meth:`PathVisibility.legs_clear`) of chains of ``order + 1`` bounces
    built as above (mirrors neither parallel nor perpendicular), with a small plate across one
    chosen leg of each path (a different leg from path to path, the return included).

    Independent truth: each leg of the path (by the image method written here, on the mirrors
    as the scene holds them: within 1 mm of the built points) tested against every parallelogram
    of the scene but the two it joins (segment-parallelogram crossings written here): a leg's bit
    is set exactly where it is free. Legs that pass within 1 mm of an edge are skipped; every
    path's chosen leg is hidden.

    Seen to catch: the kernel's reflection points unfolded with ``lin`` for its inverse (the
    transpose) in ``legs_clear``: the same bug as in ``path_points``, in the device's copy."""
    rng = np.random.default_rng(20 + order)
    centre = np.array([-9.0, 21.0, 14.0])
    antenna = centre + 700 * np.array([math.sin(math.radians(33)) * math.sin(math.radians(62)),
                                       -math.sin(math.radians(33)) * math.cos(math.radians(62)),
                                       math.cos(math.radians(33))])
    count = 6
    quads, paths = constructed_paths(rng, [order] * count, centre, antenna)
    hidden_leg = [k % (order + 2) for k in range(count)]              # leg order + 1: the return
    for k, (seq, route) in enumerate(paths):
        leg = hidden_leg[k]
        a, b = (route[-1], antenna) if leg == order + 1 else (route[1], antenna) if leg == 0 else route[leg:leg + 2]
        axis = unit(b - a)
        e1 = unit(np.cross(axis, [0.2, -0.4, 1.0]))
        middle = a + 3.0 * axis if leg in (0, order + 1) else 0.5 * (a + b)        # the antenna's legs: 3 m out
        quads.append(parallelogram(middle, 0.25 * e1, 0.25 * np.cross(axis, e1)))
    # corners exact in float32 (centre and half sides on a 2^-17 m grid, |x| < 128 m): planar parts
    grid = 2.0 ** 17
    exact = []
    for q in quads:
        c, e1, e2 = (np.round(v * grid) / grid for v in (0.5 * (q[0] + q[2]), 0.5 * (q[1] - q[0]), 0.5 * (q[3] - q[0])))
        exact.append(np.array([c - e1 - e2, c + e1 - e2, c + e1 + e2, c - e1 + e2]))
    quads = exact
    assert all(np.array_equal(q.astype(np.float32).astype(np.float64), q) for q in quads)
    scene, s, part_of, rays, visibility = mitsuba_scene(quads)
    parts = part_of[np.array([seq for seq, _ in paths])]
    chains = unfold(s, parts, np.full(count, order), np.zeros(count, np.int64))
    chain = np.arange(count)
    coords = np.array([world_to_face(s, part_of[seq[-1]], route[-1:])[0] for seq, route in paths])
    bits = visibility.legs_clear(chains, chain, coords, np.repeat(antenna[None], count, 0), order)
    checked = 0
    for k, (seq, route) in enumerate(paths):
        # the path on the rounded mirrors, by the image method, to the point the kernel was given
        x = face_to_world(s, part_of[seq[-1]], coords[k:k + 1])
        walk, clearance, _ = image_path(quads, seq, antenna, x)
        assert clearance[0] > 0.05 and np.abs(np.array(walk)[:, 0] - route).max() < 1e-3
        walk = [w[0] for w in walk]
        legs = [(walk[i], walk[i + 1], {seq[i - 1] if i else None, seq[i]}) for i in range(order + 1)]
        legs.append((walk[-1], antenna, {seq[-1]}))
        for leg, (a, b, ends) in enumerate(legs):
            worst = max(float(crossing(a[None], b[None], q)[0]) for i, q in enumerate(quads) if i not in ends)
            if abs(worst) < 1e-3:
                continue
            assert bool((int(bits[k]) >> leg) & 1) == (worst < 0), (k, leg, worst)
            if leg == hidden_leg[k]:
                assert worst > 0
            checked += 1
    assert checked >= count * (order + 2) - 3


# --------------------------------------------------------------------------- hole 3: shadows of third-order chains
def _oblique_corner_with_occluders():
    """The 110 deg corner (walls 6 m high, their planes 47 and 28 m off the origin, their normals at
    70 deg) with an occluder standing 1.5 m behind each wall (outside the corner: the legs that
    leave a wall's window produced beyond it cross them) and one tilted plate inside the corner."""
    wt = rot_z(30.0)
    foot = np.array([0.0, 6.0, 3.0])
    e1 = wt @ np.array([5.0, 0.0, 0.0])
    d2 = wt @ (rot_z(110.0) @ np.array([-1.0, 0.0, 0.0]))
    inside = foot + e1 + 2 * d2 - 0.4 * e1
    n1 = unit(np.cross(e1, [0.0, 0.0, 1.0]))
    n1 = -n1 if n1 @ (inside - foot) > 0 else n1                  # pointing out of the corner
    c2 = foot + e1 + 4 * d2
    n2 = unit(np.cross(d2, [0.0, 0.0, 1.0]))
    n2 = -n2 if n2 @ (inside - c2) > 0 else n2
    extra = [(foot + 1.5 * n1 + [0, 0, 0.5], rot_z(8) @ e1 * 0.9, [0.3, -0.2, 2.5]),
             (c2 + 1.5 * n2 + [0, 0, 0.5], rot_z(-8) @ d2 * 3.6, [0.2, 0.3, 2.5]),
             ([2.0, 2.0, 4.5], rot_z(30) @ [1.5, 0.4, 0.3], [0.2, 0.6, 1.1])]
    quads = corner_block(extra=extra)
    quads[0] = parallelogram(world([0, 0, 0]), along([12, 0, 0]), along([0, 12, 0]))      # a smaller ground
    return quads


def test_shadows_of_every_chain_through_oblique_mirrors_off_the_origin():
    """Every chain of one to three parts (186) of a concave corner whose walls meet at 110 deg, 47 m
    off the origin and turned 25 + 30 deg off the axes, on a ground 5 m up, with occluders behind
    and in front of the walls (tilted off the vertical), from two antennas (35 deg look on a
    20 deg heading, 55 deg look on -35 deg): on up to 80 random points of each chain's last part
    that the chain reaches (of 800 drawn), for every occluder not in the chain and every leg,
    :func:`shadow_lines` holds the point exactly when the path (by the image method, written here)
    exists and crosses the occluder on that leg (segment-parallelogram crossing, written here).
    Points within 1e-6 m of a shadow's or the occluder's edge are skipped.

    Seen to catch: ``_window_planes`` with ``- n_u . shift`` for ``+ n_u . shift`` (some 400
    points wrong on 15 (chain, occluder, leg) triples, all of third-order chains whose first
    mirror is off the origin and not at right angles to the second: the ground 5 m up and the
    tilted plates, and the wall-wall-ground chain; an occluder's crossing was ordered against the
    second window's plane moved by ``4 c_0 (n_0 . n_1)``)."""
    quads = _oblique_corner_with_occluders()
    s = numpy_surfaces(quads)
    n1, c1 = plane(quads[1])
    n2, _ = plane(quads[2])
    assert abs(c1) > 10 and 0.2 < abs(n1 @ n2) < 0.9                # off the origin, not at right angles
    n = len(quads)
    seqs = [q for d in range(3) for q in itertools.product(range(n), repeat=d + 1)
            if all(a != b for a, b in zip(q, q[1:]))]
    depth = 3
    parts = np.full((len(seqs), depth), -1)
    for i, q in enumerate(seqs):
        parts[i, :len(q)] = q
    chains = unfold(s, parts, np.array([len(q) - 1 for q in seqs]), np.zeros(len(seqs), np.int64))
    rng = np.random.default_rng(12)
    triples = [(i, o, leg) for i, q in enumerate(seqs) for o in range(n) if o not in q
               for leg in list(range(len(q))) + ([depth] if len(q) > 1 else [])]
    chain, occluder, leg = (np.array(v) for v in zip(*triples))
    tested = np.zeros(3, np.int64)
    hidden = np.zeros(3, np.int64)
    wrong = []
    for antenna in (antenna_at(35.0, 20.0, 900.0), antenna_at(55.0, -35.0, 1200.0)):
        lines = shadow_lines(s, chains, chain, occluder, leg, np.repeat(antenna[None], len(chain), 0))
        for i, q in enumerate(seqs):
            d = len(q) - 1
            last = quads[q[-1]]
            uv = rng.uniform(0, 1, size=(800, 2))
            x = last[0] + uv[:, :1] * (last[1] - last[0]) + uv[:, 1:] * (last[3] - last[0])
            path, clearance, _ = image_path(quads, q, antenna, x)
            keep = np.flatnonzero(clearance > 1e-9)[:80]                 # up to 80 points the chain reaches
            x, clearance, path = x[keep], clearance[keep], [p[keep] for p in path]
            face = world_to_face(s, q[-1], x)
            for r in np.flatnonzero(chain == i):
                row = lines[r]
                held = (row[None, :, 0] * face[:, :1] + row[None, :, 1] * face[:, 1:] + row[None, :, 2]).min(axis=1)
                lg = leg[r]
                a, b = (x, path[0]) if lg == depth or d == 0 else (path[lg], path[lg + 1])
                crosses = crossing(a, b, quads[occluder[r]])
                use = (clearance > 1e-9) & (np.abs(crosses) > 1e-6) & (np.abs(held) > 1e-6)
                truth, got = crosses[use] > 0, held[use] >= 0
                tested[d] += use.sum()
                hidden[d] += truth.sum()
                if np.any(truth != got):
                    wrong.append((q, int(occluder[r]), int(lg), int(np.sum(truth != got))))
    assert not wrong, f"{len(wrong)} (chain, occluder, leg) wrong, e.g. {wrong[:5]}"
    assert tested[2] > 15000 and hidden[2] > 500 and tested[1] > 10000 and hidden[1] > 400, (tested, hidden)


# --------------------------------------------------------------------------- hole 2: return legs hidden
def _legs_clear(quads, parts_in_scene, seq, antenna, x):
    """Which legs of the image-method paths to ``x`` are free of every parallelogram but those they
    start or end on: transmit (all legs out) and back (the return leg) bool [m], the paths'
    clearance in their windows, whether they return, and the least clearance of any crossing."""
    path, clearance, returns = image_path(quads, seq, antenna, x)
    d = len(seq) - 1
    legs = [(path[i], path[i + 1], {seq[i - 1] if i else None, seq[i]}) for i in range(d + 1)]
    legs.append((x, path[0], {seq[-1]}))
    free, margin = [], np.full(len(x), np.inf)
    for a, b, ends in legs:
        worst = np.full(len(x), -np.inf)
        for o in parts_in_scene:
            if o in ends:
                continue
            f = crossing(a, b, quads[o])
            margin = np.minimum(margin, np.abs(f))
            worst = np.maximum(worst, f)
        free.append(worst <= 0)
    return np.all(free[:-1], axis=0), free[-1], clearance, returns, margin


@pytest.mark.parametrize("order", [1, 2], ids=["double", "triple"])
def test_return_leg_occluder_hides_second_and_third_order_paths(order):
    """A concave corner (walls at 110 deg, turned 30 deg off the track) under a tilted plate that
    floats 7 m in front of it, above every transmit leg of the ground-wall and ground-wall-wall
    paths but across their return legs, seen at 38 deg look on a 25 deg heading. Every chain of
    ``order + 1`` parts among ground and walls, cut into 0.7 m pieces by :func:`lit_pieces`.

    Independent truth per piece: its corners (pulled a thousandth of a patch toward its centroid)
    traced by the image method and each leg tested against every parallelogram written here: lit
    where every corner's path is free both ways (and the chain returns), transmit-lit where the
    legs out are, mixed where the corners disagree; pieces with a corner's leg within 5 mm of an
    edge are skipped. Dozens of pieces are transmit-lit but not lit.

    Seen to catch: ``classify`` reading the return bit as ``(bits >> order) & 1`` (every
    transmit-lit piece then lit)."""
    look = 38.0
    e = math.radians(90.0 - look)
    wt = rot_z(30.0)
    front = np.array([0.0, 6.0, 0.0]) + wt @ np.array([0.0, -7.0, 0.0])
    blocker = (front + [0, 0, 7.0 * math.tan(e) + 3.5 + 5.0], wt @ np.array([14.0, 0.0, 0.0]), [0.0, -0.8, 5.0])
    quads = corner_block(extra=[blocker])
    antenna = antenna_at(look, 0.0, 600.0)                          # on a 25 deg heading: the scene's frame
    scene, s, part_of, rays, visibility = mitsuba_scene(quads)
    seqs = [q for q in itertools.product(range(3), repeat=order + 1) if all(a != b for a, b in zip(q, q[1:]))]
    chains = unfold(s, part_of[np.array(seqs)], np.full(len(seqs), order), np.zeros(len(seqs), np.int64))
    patch = 0.7
    lit = lit_pieces(s, chains, np.repeat(antenna[None], len(seqs), 0), rays, visibility, patch)
    poly, count = lit.pieces.polygons()
    counts = dict(checked=0, transmit_only=0, lit=0, mixed=0)
    wrong = []
    for k in range(len(lit.pieces)):
        seq = seqs[lit.pieces.region[k]]
        corners = poly[k, :count[k]]
        toward = corners.mean(axis=0) - corners
        dist = np.linalg.norm(toward, axis=1)
        samples = corners + toward * (np.minimum(1e-3 * patch, 0.5 * dist) / np.maximum(dist, 1e-300))[:, None]
        x = face_to_world(s, part_of[seq[-1]], samples)
        out, back, clearance, returns, margin = _legs_clear(quads, range(len(quads)), seq, antenna, x)
        assert np.all(clearance > -1e-6), (seq, k)                 # a piece of the region: its path exists
        if margin.min() < 5e-3:
            continue
        both = out & back & returns
        mixed = (both.any() and not both.all()) or (out.any() and not out.all())
        want = (bool(both.all()), bool(out.all()), bool(mixed))
        have = (bool(lit.lit[k]), bool(lit.transmit[k]), bool(lit.mixed[k]))
        counts["checked"] += 1
        counts["transmit_only"] += want[1] and not want[0]
        counts["lit"] += want[0]
        counts["mixed"] += want[2]
        if want != have:
            wrong.append((seq, k, want, have))
    assert not wrong, f"{len(wrong)} pieces (seq, piece, (lit, transmit, mixed) wanted, got): {wrong[:5]}"
    assert counts["checked"] >= 100 and counts["transmit_only"] >= 30 and counts["lit"] >= 20, counts


def test_recheck_finds_a_return_leg_occluder_inside_a_mixed_piece():
    """A 2 m piece of a wall (turned 30 deg off the track) reached by the ground-wall double bounce:
    a small plate on the return leg of one of its corners makes it mixed; a second small plate on
    the return leg of its centre hides none of its corners. Checked here (the image method and
    segment-parallelogram crossings written here) before the assertions: the corners' legs out are
    free, one corner's return crosses the first plate only, the centre's return the second only.
    The second plate's shadow then lies inside the piece's lit region, so its exact cut must name
    it: :func:`recheck` (sampling the cut lit region) must add it, on the return leg, to the
    piece's occluders, and name the piece among those that gained one.

    Seen to catch: ``recheck`` reading the return bit as ``(bits >> order) & 1`` (the centre's
    ray never cast again), and the same bug in ``classify`` (the piece is not mixed)."""
    look, patch = 38.0, 2.0
    antenna = antenna_at(look, 0.0, 600.0)
    base = corner_block(height=4.0)
    _, s0, part0, _, _ = mitsuba_scene(base)
    wall = part0[1]
    # the cell of the wall's frame that holds the wall's centre (whole inside the wall)
    centre_face = world_to_face(s0, wall, base[1].mean(axis=0)[None])[0]
    cell = np.floor(centre_face / patch)
    cell_corners = (cell + np.array([[0, 0], [1, 0], [1, 1], [0, 1]])) * patch
    assert np.all(in_parallelogram(face_to_world(s0, wall, cell_corners), base[1]) > 0.1)
    cell_centre = face_to_world(s0, wall, ((cell + 0.5) * patch)[None])[0]
    corner = face_to_world(s0, wall, cell_corners[2:3])[0]

    def plate_on_return(point, distance, half):
        """A square plate across the return leg from ``point``, ``distance`` m toward the antenna."""
        axis = unit(antenna - point)
        e1 = unit(np.cross(axis, [0.3, 0.2, 1.0]))
        e2 = np.cross(axis, e1)
        return parallelogram(point + distance * axis, half * e1, half * e2)

    quads = base + [plate_on_return(corner, 2.5, 0.35), plate_on_return(cell_centre, 2.5, 0.3)]
    scene, s, part_of, rays, visibility = mitsuba_scene(quads)
    ground, wall, first, second = part_of[0], part_of[1], part_of[3], part_of[4]
    seq = (0, 1)

    # the independent check of the design: which legs the plates cross
    inset = cell_corners + (np.sign((cell + 0.5) * patch - cell_corners) * 1e-3 * patch)
    x = face_to_world(s, wall, np.concatenate([inset, ((cell + 0.5) * patch)[None]]))
    out, back, clearance, returns, margin = _legs_clear(quads, range(len(quads)), seq, antenna, x)
    assert np.all(clearance > 0.1) and returns.all() and margin.min() > 0.02
    assert out.all() and np.array_equal(back, [True, True, False, True, False])
    only_first = _legs_clear(quads, [0, 1, 2, 3], seq, antenna, x)[1]
    only_second = _legs_clear(quads, [0, 1, 2, 4], seq, antenna, x)[1]
    assert np.array_equal(only_first, [True, True, False, True, True])
    assert np.array_equal(only_second, [True, True, True, True, False])

    chains = unfold(s, np.array([[ground, wall]]), np.array([1]), np.zeros(1, np.int64))
    a = antenna[None]
    lit = lit_pieces(s, chains, a, rays, visibility, patch)
    piece = np.flatnonzero((lit.pieces.region == 0) & np.all(lit.pieces.cell == cell, axis=1))
    assert len(piece) == 1
    piece = int(piece[0])
    assert lit.transmit[piece] and lit.mixed[piece] and not lit.lit[piece]
    depth = chains.parts.shape[1]
    back_first, back_second = depth * s.n_parts + first, depth * s.n_parts + second
    keys = lit.blockers.key[lit.blockers.piece == piece]
    assert back_first in keys and back_second not in keys           # the corners missed the second plate
    clipped = clip_mixed(s, lit, a)
    assert piece in clipped.piece
    blockers, gained = recheck(s, lit, clipped, a, rays, visibility)
    assert piece in gained
    assert back_second in blockers.key[blockers.piece == piece]
