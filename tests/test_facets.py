"""Convex planar parts of triangle meshes (sarmitsuba.tracing.mesh.facets): parts checked against areas, normals
and vertex sharing computed here from the input triangles, on hand-made meshes and real scenes."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest
import trimesh

import sarmitsuba  # noqa: F401  (sets the Mitsuba variant)
from sarmitsuba.tracing.mesh.facets import MAX_PART_VERTICES, mesh_parts, scene_parts
from sarmitsuba.scene.loader import load_scene, sionna_scenes


def _triangle_areas(meshes):
    """Area of every input triangle [m^2], global order (shapes in input order)."""
    out = []
    for v, f in meshes:
        v, f = np.asarray(v, np.float64), np.asarray(f, np.int64).reshape(-1, 3)
        out.append(0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1))
    return np.concatenate(out) if out else np.zeros(0)


def _outline(parts, p):
    return parts.vertices[p, :parts.n_vertices[p]]


def _polygon_area(vertices, normal):
    """Signed area of a planar polygon about ``normal`` (positive = counter-clockwise)."""
    return 0.5 * float(np.cross(vertices, np.roll(vertices, -1, axis=0)).sum(axis=0) @ normal)


def _turns(vertices, normal):
    d1, d2 = vertices - np.roll(vertices, 1, axis=0), np.roll(vertices, -1, axis=0) - vertices
    return np.arctan2(np.cross(d1, d2) @ normal, np.einsum("ij,ij->i", d1, d2))


def _check_parts(parts, meshes, angle=1e-9, planar=1e-9):
    """What every decomposition must satisfy: convex counter-clockwise outlines without collinear
    corners, padded with the last corner, planar, each part's area the sum of its triangles'."""
    assert np.all((parts.n_vertices >= 3) & (parts.n_vertices <= MAX_PART_VERTICES))
    assert np.allclose(np.linalg.norm(parts.normal, axis=1), 1.0)
    areas = _triangle_areas(meshes)
    held = parts.triangle_part >= 0
    assert set(parts.triangle_part[held]) == set(range(parts.n_parts))
    expected = np.bincount(parts.triangle_part[held], areas[held], minlength=parts.n_parts)
    for p in range(parts.n_parts):
        v, n = _outline(parts, p), parts.normal[p]
        assert np.all(parts.vertices[p, parts.n_vertices[p]:] == v[-1])
        turns = _turns(v, n)
        assert turns.min() >= -angle and np.abs(turns).min() >= 1e-9, (p, turns)
        assert np.abs(v @ n - parts.offset[p]).max() <= planar
        assert _polygon_area(v, n) == pytest.approx(expected[p], rel=1e-9, abs=1e-12)
    assert np.all(parts.face[:-1] <= parts.face[1:])
    assert np.allclose(parts.normal, parts.face_normal[parts.face])


def _adjacency_truth(parts, meshes, tolerance=1e-5):
    """Parts sharing a vertex position, by brute force over the parts' triangles' vertices."""
    points = [np.asarray(v, np.float64)[np.asarray(f).reshape(-1, 3)] for v, f in meshes]
    corners = np.concatenate(points) if points else np.zeros((0, 3, 3))
    held = parts.triangle_part >= 0
    per_part = [corners[held & (parts.triangle_part == p)].reshape(-1, 3) for p in range(parts.n_parts)]
    return [sorted(q for q in range(parts.n_parts) if q != p and np.any(
        np.linalg.norm(per_part[p][:, None] - per_part[q][None], axis=2) < tolerance))
        for p in range(parts.n_parts)]


def _neighbours(parts, p):
    return parts.adjacency[parts.adjacency_start[p]:parts.adjacency_start[p + 1]].tolist()


def _l_shape():
    """L-shaped polygon of area 3 m^2 in a tilted plane, with a collinear boundary vertex (1, 0),
    triangulated as a fan from its reflex corner (1, 1)."""
    xy = np.array([(1, 1), (0, 0), (1, 0), (2, 0), (2, 1), (1, 2), (0, 2)], np.float64)
    faces = np.array([[0, 5, 6], [0, 6, 1], [0, 1, 2], [0, 2, 3], [0, 3, 4]])
    rotation = trimesh.transformations.rotation_matrix(0.7, [1.0, 2.0, 0.5])[:3, :3]
    return np.c_[xy, np.zeros(len(xy))] @ rotation.T + [3.0, -2.0, 1.0], faces, rotation[:, 2]


def _polygon_fan(n, centre):
    """Regular n-gon of circumradius 1 in z = 0: a fan from its centre or from its vertex 0."""
    ring = np.c_[np.cos(2 * np.pi * np.arange(n) / n), np.sin(2 * np.pi * np.arange(n) / n), np.zeros(n)]
    if centre:
        return np.r_[[[0.0, 0.0, 0.0]], ring], np.array([[0, 1 + i, 1 + (i + 1) % n] for i in range(n)])
    return ring, np.array([[0, i, i + 1] for i in range(1, n - 1)])


def _box(extents=(1.0, 1.0, 1.0), shift=(0.0, 0.0, 0.0)):
    box = trimesh.creation.box(extents=extents)
    return np.asarray(box.vertices) + shift, np.asarray(box.faces)


def test_cube_is_six_outward_unit_squares_touching_their_four_neighbours():
    meshes = [_box()]
    parts = mesh_parts(meshes)
    _check_parts(parts, meshes)
    assert parts.n_parts == parts.n_faces == 6 and np.all(parts.n_vertices == 4)
    areas = [_polygon_area(_outline(parts, p), parts.normal[p]) for p in range(6)]
    assert np.allclose(areas, 1.0)
    # the centre is inside: outward normals are +-axes with the face half a metre out
    assert sorted(map(tuple, np.round(parts.normal).astype(int))) == sorted(
        tuple(s * np.eye(3, dtype=int)[i]) for i in range(3) for s in (1, -1))
    assert np.allclose(parts.offset, 0.5)
    for p in range(6):
        touching = [q for q in range(6) if q != p and parts.normal[q] @ parts.normal[p] > -0.5]
        assert _neighbours(parts, p) == touching          # all but the opposite face
    assert np.all(np.bincount(parts.triangle_part) == 2)
    assert np.array_equal(parts.triangle_base, [0]) and np.all(parts.shape == 0)
    vertices, faces = meshes[0]
    lowest = [faces[parts.triangle_part == p].min() for p in range(6)]
    assert np.array_equal(parts.face_origin[parts.face], vertices[lowest])


def test_l_shape_splits_into_convex_parts_covering_its_area():
    vertices, faces, normal = _l_shape()
    meshes = [(vertices, faces)]
    parts = mesh_parts(meshes)
    _check_parts(parts, meshes)
    assert parts.n_faces == 1 and np.allclose(parts.normal, normal)
    assert parts.n_parts == 2                # an L needs two convex parts; this fan gives two
    areas = sorted(_polygon_area(_outline(parts, p), normal) for p in range(2))
    assert np.allclose(areas, [1.0, 2.0])
    assert np.all(parts.n_vertices == 4)     # the collinear (1, 0) and (1, 1) are dropped
    assert _neighbours(parts, 0) == [1] and _neighbours(parts, 1) == [0]


@pytest.mark.parametrize("centre, counts", [(False, [6, 8]), (True, [7, 7])])
def test_twelve_gon_fan_is_covered_by_parts_of_at_most_eight_corners(centre, counts):
    meshes = [_polygon_fan(12, centre)]
    parts = mesh_parts(meshes)
    _check_parts(parts, meshes)
    total = sum(_polygon_area(_outline(parts, p), parts.normal[p]) for p in range(parts.n_parts))
    assert total == pytest.approx(6 * math.sin(2 * math.pi / 12), rel=1e-12)    # (n/2) sin(2 pi/n)
    assert parts.n_faces == 1 and np.allclose(parts.normal, [0, 0, 1])
    assert sorted(parts.n_vertices.tolist()) == counts
    # every corner is a vertex of the 12-gon: the centre of the central fan sits on a straight
    # edge of both halves and is dropped
    outlines = np.concatenate([_outline(parts, p) for p in range(parts.n_parts)])
    assert np.allclose(np.linalg.norm(outlines, axis=1), 1.0)


@pytest.mark.parametrize("c, n_parts, corners", [
    ((1.0, 1.2, 0.0), 1, [4]),          # convex quad
    ((1.5, -0.2, 0.0), 2, [3, 3]),      # dart: reflex at the shared corner (1, 0)
    ((1.0, 0.0, 0.0), 1, [3]),          # (0, 0)-(1, 0) split at its middle: one triangle
])
def test_two_triangle_faces(c, n_parts, corners):
    """The two-triangle fast path: one part exactly when the union is convex."""
    if c == (1.0, 0.0, 0.0):
        vertices = np.array([(0, 0, 0), (0.5, 0, 0), (0, 1, 0), (1, 0, 0)], np.float64)
        faces = np.array([[0, 1, 2], [1, 3, 2]])
    else:
        vertices = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), c], np.float64)
        faces = np.array([[0, 1, 2], [1, 3, 2]])
    meshes = [(vertices, faces)]
    parts = mesh_parts(meshes)
    _check_parts(parts, meshes)
    assert parts.n_faces == 1 and parts.n_parts == n_parts and sorted(parts.n_vertices) == corners


def test_grid_of_coplanar_squares_is_one_face_with_convex_parts():
    meshes = [_grid(3)]
    parts = mesh_parts(meshes)
    _check_parts(parts, meshes)
    assert parts.n_faces == 1 and np.allclose(parts.normal, [0, 0, 1]) and np.allclose(parts.offset, 0.0)
    assert parts.n_parts <= 9                # no worse than one part per square


def _grid(n):
    """n x n unit squares in z = 0, two triangles each, counter-clockwise about +z."""
    x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0), indexing="ij")
    vertices = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    index = lambda i, j: i * (n + 1) + j       # noqa: E731
    faces = [f for i in range(n) for j in range(n) for f in
             ([index(i, j), index(i + 1, j), index(i + 1, j + 1)], [index(i, j), index(i + 1, j + 1), index(i, j + 1)])]
    return vertices, np.array(faces)


def test_box_on_ground_touches_across_shapes():
    """A unit box standing on a ground quad whose corner is a corner of the box's bottom."""
    ground = (np.array([(-0.5, -0.5, 0), (3, -0.5, 0), (3, 3, 0), (-0.5, 3, 0)], np.float64), np.array([[0, 1, 2], [0, 2, 3]]))
    meshes = [ground, _box(shift=(0.0, 0.0, 0.5))]
    parts = mesh_parts(meshes)
    _check_parts(parts, meshes)
    assert parts.n_parts == 7 and parts.shape.tolist() == [0] + [1] * 6
    assert np.array_equal(parts.triangle_base, [0, 2])
    truth = _adjacency_truth(parts, meshes)
    assert [_neighbours(parts, p) for p in range(parts.n_parts)] == truth
    box_parts = {p: tuple(np.round(parts.normal[p]).astype(int)) for p in range(1, 7)}
    assert sorted(box_parts[q] for q in _neighbours(parts, 0)) == [(-1, 0, 0), (0, -1, 0), (0, 0, -1)]


def test_degenerate_triangles_belong_to_no_part():
    vertices, faces = _box()
    near = vertices[0] + [0.0, 3e-6, 0.0]                  # one vertex with vertex 0 (1e-5 m tolerance)
    vertices = np.r_[vertices, [[0.2, 0.2, 0.5], [0.3, 0.3, 0.5], [np.nan, 0.0, 0.0], near]]
    # repeated vertex, collinear, NaN, two vertices merged (area 2.6e-6 m^2 before merging)
    bad = np.array([[0, 0, 1], [8, 9, 7], [10, 1, 2], [0, 11, 7]])
    faces = np.r_[faces[:5], bad, faces[5:]]
    meshes = [(vertices, faces)]
    parts = mesh_parts(meshes)
    assert np.array_equal(np.nonzero(parts.triangle_part < 0)[0], [5, 6, 7, 8])
    good = [(vertices, np.r_[faces[:5], faces[9:]])]
    reference = mesh_parts(good)
    assert parts.n_parts == 6 and np.array_equal(parts.vertices, reference.vertices)
    assert np.array_equal(np.delete(parts.triangle_part, [5, 6, 7, 8]), reference.triangle_part)
    assert np.array_equal(parts.adjacency, reference.adjacency)


def _assorted():
    """Meshes with multi-triangle faces, collinear and reflex corners, float32 vertex values."""
    cylinder = trimesh.creation.cylinder(radius=1.5, height=2.0, sections=20)
    l_vertices, l_faces, _ = _l_shape()
    meshes = [(cylinder.vertices, cylinder.faces), (l_vertices, l_faces), _polygon_fan(12, True), _grid(4)]
    return [(np.asarray(v, np.float32).astype(np.float64), np.asarray(f)) for v, f in meshes]


def test_assorted_meshes_keep_areas_and_adjacency():
    meshes = _assorted()
    parts = mesh_parts(meshes)
    _check_parts(parts, meshes, angle=1e-5, planar=1e-6)
    cylinder = parts.shape == 0
    sides = cylinder & (np.abs(parts.normal[:, 2]) < 1e-6)
    assert np.count_nonzero(sides) == 20 and np.all(parts.n_vertices[sides] == 4)     # one quad each
    assert len(np.unique(parts.face[cylinder & ~sides])) == 2         # each cap one face
    assert [_neighbours(parts, p) for p in range(parts.n_parts)] == _adjacency_truth(parts, meshes)


def test_translation_gives_the_same_parts_translated():
    meshes = _assorted()
    shift = np.array([1000.0, -37.5, 12.25])          # exact on these float32 values
    moved = [(v + shift, f) for v, f in meshes]
    a, b = mesh_parts(meshes), mesh_parts(moved)
    for name in ("n_vertices", "face", "shape", "triangle_part", "adjacency_start", "adjacency"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(a.vertices + shift, b.vertices)
    assert np.array_equal(a.face_origin + shift, b.face_origin)
    assert np.allclose(a.normal, b.normal, atol=1e-12)
    assert np.allclose(a.offset + a.normal @ shift, b.offset, atol=1e-9)


def test_flipped_winding_flips_normals_and_reverses_outlines():
    meshes = _assorted()
    flipped = [(v, f[:, ::-1]) for v, f in meshes]
    a, b = mesh_parts(meshes), mesh_parts(flipped)
    _check_parts(b, flipped, angle=1e-5, planar=1e-6)
    assert np.array_equal(a.triangle_part, b.triangle_part) and np.array_equal(a.n_vertices, b.n_vertices)
    assert np.allclose(a.normal, -b.normal, atol=1e-12) and np.allclose(a.offset, -b.offset, atol=1e-9)
    for p in range(a.n_parts):
        forward, backward = _outline(a, p), _outline(b, p)[::-1]
        start = np.nonzero(np.all(backward == forward[0], axis=1))[0]
        assert len(start) == 1 and np.array_equal(np.roll(backward, -start[0], axis=0), forward), p


def test_empty_and_non_mesh_shapes():
    parts = mesh_parts([(np.zeros((0, 3)), np.zeros((0, 3), int)), _box(), (np.zeros((0, 3)), np.zeros((0, 3), int))])
    assert parts.n_parts == 6 and np.array_equal(parts.triangle_base, [0, 0, 12]) and np.all(parts.shape == 1)
    none = mesh_parts([])
    assert none.n_parts == 0 and none.n_faces == 0 and np.array_equal(none.adjacency_start, [0])


def test_scene_parts_skips_shapes_that_are_not_meshes():
    import mitsuba as mi
    scene = mi.load_dict({"type": "scene", "a": {"type": "sphere"}, "b": {"type": "rectangle"},
                          "c": {"type": "disk"}})
    mesh = [s.is_mesh() for s in scene.shapes()]
    parts = scene_parts(scene)
    assert sum(mesh) == 1 and parts.n_parts == 1 and parts.shape[0] == mesh.index(True)
    assert np.array_equal(parts.triangle_base, np.cumsum([0] + [2 * m for m in mesh])[:-1])
    assert _polygon_area(_outline(parts, 0), parts.normal[0]) == pytest.approx(4.0)


def _scene_meshes(scene):
    out = []
    for shape in scene.shapes():
        if shape.is_mesh():
            out.append((np.array(shape.vertex_positions_buffer(), np.float32).astype(np.float64).reshape(-1, 3),
                        np.array(shape.faces_buffer()).reshape(-1, 3)))
        else:
            out.append((np.zeros((0, 3)), np.zeros((0, 3), np.int64)))
    return out


def test_scene_parts_of_builtin_scenes():
    dihedral = scene_parts(load_scene("dihedral").scene)    # rectangles are two-triangle meshes
    assert dihedral.n_parts == 2 and np.array_equal(dihedral.triangle_base, [0, 2])
    assert np.allclose([_polygon_area(_outline(dihedral, p), dihedral.normal[p]) for p in range(2)], [200.0, 100.0])
    assert np.allclose(dihedral.normal, [[0, 0, 1], [0, 1, 0]])      # ground up, wall facing +y
    assert np.array_equal(dihedral.adjacency, [1, 0])                 # along the fold line
    scene = load_scene("urban").scene
    parts, meshes = scene_parts(scene), _scene_meshes(scene)
    _check_parts(parts, meshes, planar=1e-4)
    kinds = [s.id() for s in scene.shapes()]
    counts = np.bincount(parts.shape, minlength=len(kinds))
    for i, name in enumerate(kinds):          # a cube: six rectangles; the trihedral: three triangles
        expected = 1 if name == "ground" else 3 if name == "tower_reflector" else 6
        assert counts[i] == expected, name
    assert np.all(parts.n_vertices[parts.shape != kinds.index("tower_reflector")] == 4)
    areas = _triangle_areas(meshes)
    for i in range(len(kinds)):
        rows = slice(parts.triangle_base[i], parts.triangle_base[i] + len(meshes[i][1]))
        got = sum(_polygon_area(_outline(parts, p), parts.normal[p]) for p in np.nonzero(parts.shape == i)[0])
        assert got == pytest.approx(areas[rows].sum(), rel=1e-9)
    trihedral = np.nonzero(parts.shape == kinds.index("tower_reflector"))[0]
    assert np.allclose([_polygon_area(_outline(parts, p), parts.normal[p]) for p in trihedral], 0.5 * 1.5 ** 2, rtol=1e-6)


@pytest.mark.skipif("munich" not in sionna_scenes(), reason="sionna-rt extra not installed")
@pytest.mark.filterwarnings("ignore::sarmitsuba.scene.meshcheck.MeshDefectWarning")      # 5 known defective meshes
def test_munich_decomposes_quickly_into_convex_planar_parts():
    scene = load_scene("sionna:munich").scene
    start = time.perf_counter()
    parts = scene_parts(scene)
    elapsed = time.perf_counter() - start
    assert elapsed < 3.0
    meshes = _scene_meshes(scene)
    assert len(parts.triangle_part) == 38936 and parts.n_parts > 20000
    # float32 vertices of faces up to ~100 m, coplanar to angle_tolerance 1e-5: the parts lie within
    # 1e-5 rad x the face's size of their plane (0.15 mm at most)
    size = np.zeros(parts.n_faces)
    for p in range(parts.n_parts):
        v = _outline(parts, p)
        size[parts.face[p]] = max(size[parts.face[p]], np.linalg.norm(v - parts.face_origin[parts.face[p]], axis=1).max())
    for p in range(parts.n_parts):
        v, n = _outline(parts, p), parts.normal[p]
        assert np.abs(v @ n - parts.offset[p]).max() <= 1e-6 + 1e-5 * size[parts.face[p]]
    _check_parts(parts, meshes, angle=1e-5, planar=np.inf)
    # adjacency: parts whose triangles have equal corners touch; so do a few more, where shapes'
    # float32 corners differ by an ulp (4 to 8 um)
    corners = np.concatenate([v[f] for v, f in meshes]).reshape(-1, 3)
    _, position = np.unique(corners, axis=0, return_inverse=True)
    owner = np.repeat(parts.triangle_part, 3)
    by_position: dict[int, set] = {}
    for pos, part in zip(position.ravel().tolist(), owner.tolist()):
        by_position.setdefault(pos, set()).add(part)
    truth = [set() for _ in range(parts.n_parts)]
    for group in by_position.values():
        for p in group:
            truth[p] |= group - {p}
    by_part = [corners.reshape(-1, 3, 3)[parts.triangle_part == p].reshape(-1, 3) for p in range(parts.n_parts)]
    for p in range(parts.n_parts):
        found = set(_neighbours(parts, p))
        assert truth[p] <= found, p
        for q in found - truth[p]:
            assert np.linalg.norm(by_part[p][:, None] - by_part[q][None], axis=2).min() < 1e-5
