"""Convex planar parts of a scene's triangle meshes, for integrating physical optics over each
mesh face exactly.

A *face* is a maximal group of coplanar, edge-connected triangles of one shape; a *part* is a
convex polygon of at most :data:`MAX_PART_VERTICES` vertices, a union of edge-adjacent triangles
of one face. :func:`mesh_parts` decomposes meshes given as arrays, :func:`scene_parts` those of
a loaded Mitsuba scene.

The decomposition uses differences of vertex positions only, so it does not depend on where the
meshes sit: translated meshes give the same parts (same vertices in the same order), translated.
All of it is NumPy, SciPy and Python, float64; Munich (Sionna RT, 38,936 triangles in 2,367
shapes) takes 0.15 s and gives 25,123 parts on 23,479 faces.

* one triangle is one part; two triangles whose union is a convex quad are one part (94 % of
  Munich's faces: 51 % single triangles, 43 % quads), done for all such faces at once;
* larger faces grow parts greedily from their lowest-index unassigned triangle, breadth first,
  adding each edge-adjacent triangle that keeps the part convex and within
  :data:`MAX_PART_VERTICES` corners.

Parts keep the mesh's own vertices (so parts of neighbouring faces share their corners exactly);
with float32 meshes they are therefore planar only to the rounding and to ``angle_tolerance``
times the face's size (0.15 mm at most in Munich), and an intended straight edge may bend
inwards at a vertex by the rounding (such a vertex stays a corner; Munich has none).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Sequence

import mitsuba as mi
import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ...core.arrays import unique_rows

__all__ = ["MAX_PART_VERTICES", "Parts", "mesh_parts", "scene_parts", "scene_meshes", "set_vertices", "triangle_table"]

#: Most corners a part may have (vertex slots of :attr:`Parts.vertices`).
MAX_PART_VERTICES = 8
#: Triangles with area below this [m^2] (or non-finite) are degenerate: they belong to no part.
DEGENERATE_AREA = 1e-12
#: An outline vertex whose turn angle [rad] is below this is collinear with its neighbours and
#: is dropped from the part's corners.
COLLINEAR_ANGLE = 1e-9


@dataclass(frozen=True)
class Parts:
    """Convex planar parts of a scene's meshes.

    Attributes
    ----------
    normal : ndarray
        float64 [n_parts, 3], unit normal of the part's face, oriented as the mesh (right-hand
        rule of its triangles' vertex order).
    offset : ndarray
        float64 [n_parts], m: ``normal . x`` for the points ``x`` of the part's plane (taken at
        the face's :attr:`face_origin`).
    vertices : ndarray
        float64 [n_parts, MAX_PART_VERTICES, 3], m: the part's corners, counter-clockwise seen
        from the tip of ``normal``; slots from ``n_vertices`` on repeat the last corner.
    n_vertices : ndarray
        int32 [n_parts], 3 to :data:`MAX_PART_VERTICES`.
    face : ndarray
        int32 [n_parts], the part's face (numbered over the scene in order of their first
        triangle); parts are sorted by face.
    shape : ndarray
        int32 [n_parts], index of the part's shape in the input list.
    face_origin : ndarray
        float64 [n_faces, 3], m: the face's lowest-index vertex (it moves with the mesh).
    face_normal : ndarray
        float64 [n_faces, 3], unit normal of each face.
    triangle_part : ndarray
        int32 [n_triangles], the part holding each input triangle (shapes in input order, each
        shape's triangles in buffer order); -1 for degenerate triangles.
    triangle_base : ndarray
        int64 [n_shapes], first row of each shape in ``triangle_part``.
    adjacency_start, adjacency : ndarray
        int64 [n_parts + 1] and int32 [n_pairs], CSR: ``adjacency[adjacency_start[p]:
        adjacency_start[p + 1]]`` are the other parts (sorted) that share a vertex position with
        part ``p`` (within the position tolerance, across shapes too). A part's vertex positions
        are those of its triangles: its corners and any collinear vertex dropped from them.
    closed : ndarray
        bool [n_parts]: the part's shape is a closed surface (every edge of its non-degenerate
        triangles, after merging vertices, belongs to exactly two of them, wound in opposite
        directions), so one side of every part faces the shape's inside.
    """

    normal: np.ndarray
    offset: np.ndarray
    vertices: np.ndarray
    n_vertices: np.ndarray
    face: np.ndarray
    shape: np.ndarray
    face_origin: np.ndarray
    face_normal: np.ndarray
    triangle_part: np.ndarray
    triangle_base: np.ndarray
    adjacency_start: np.ndarray
    adjacency: np.ndarray
    closed: np.ndarray = None

    @property
    def n_parts(self) -> int:
        """Number of parts."""
        return len(self.n_vertices)

    @property
    def n_faces(self) -> int:
        """Number of faces (coplanar edge-connected triangle groups)."""
        return len(self.face_normal)


def scene_parts(scene) -> Parts:
    """The :class:`Parts` of a loaded Mitsuba scene.

    Every shape of ``scene.shapes()`` is one input shape (in that order); those that are not
    meshes (``shape.is_mesh()`` false: spheres, disks, cylinders; ``rectangle`` and ``cube`` are
    meshes in Mitsuba 3.9) contribute no triangles, and their ``triangle_base`` is where the next
    shape's rows start. Vertex positions are the float32 buffers widened to float64.
    """
    return mesh_parts(scene_meshes(scene))


def scene_meshes(scene) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per shape of ``scene.shapes()``: its vertex positions float64 [n_v, 3] (m, the float32
    buffer widened) and triangles int64 [n_f, 3]; empty arrays for a shape that is not a mesh."""
    meshes = []
    for shape in scene.shapes():
        if shape.is_mesh():
            vertices = np.array(shape.vertex_positions_buffer(), np.float32).astype(np.float64).reshape(-1, 3)
            faces = np.array(shape.faces_buffer(), np.int64).reshape(-1, 3)
        else:
            vertices, faces = np.zeros((0, 3)), np.zeros((0, 3), np.int64)
        meshes.append((vertices, faces))
    return meshes


def set_vertices(scene, vertices: dict) -> None:
    """Move the Mitsuba scene's meshes: shape ``k`` (its index in ``scene.shapes()``) to the
    vertices ``vertices[k]`` (float [n_v, 3], m), the buffer rewritten in float32 and the scene's
    acceleration structure rebuilt (the rays then meet the moved shapes).

    A mesh that Mitsuba builds from its ``to_world`` (``rectangle``, ``cube``: no vertex buffer
    to write) takes instead, into its ``to_world``, the rigid motion that carries its present
    vertices onto ``vertices[k]`` (the shapes' motions are rigid, docs/physics.md (V1)): its
    vertices are then those within float32 rounding. Raises ValueError for a shape with neither
    (a sphere: not a mesh)."""
    if not vertices:
        return
    params = mi.traverse(scene)
    shapes = list(scene.shapes())
    for k, v in vertices.items():
        keys = [key for key in params.keys() if params.properties[key][2] == shapes[k]]
        buffer = [key for key in keys if key.endswith(".vertex_positions")]
        transform = [key for key in keys if key.endswith(".to_world")]
        if buffer:
            params[buffer[0]] = mi.Float(np.asarray(v, np.float32).ravel())
        elif transform and shapes[k].is_mesh():
            present = np.array(shapes[k].vertex_positions_buffer(), np.float64).reshape(-1, 3)
            params[transform[0]] = _moved_transform(params[transform[0]], present, np.asarray(v, np.float64))
        else:
            raise ValueError(f"shape {shapes[k].id()!r} has no vertices to move (it is not a triangle mesh)")
    params.update()


def _moved_transform(to_world, present: np.ndarray, target: np.ndarray):
    """``to_world`` (mi.AffineTransform4f) followed by the rigid motion that takes the points
    ``present`` [n, 3] onto ``target`` [n, 3] (m) in the least-squares sense: the rotation about
    their centroids by scipy's ``Rotation.align_vectors`` (the Kabsch algorithm; unique for
    points not all on one line), then the centroids' translation."""
    from scipy.spatial.transform import Rotation
    to, at = target.mean(axis=0), present.mean(axis=0)
    rotation, _ = Rotation.align_vectors(target - to, present - at)
    motion = np.eye(4)
    motion[:3, :3] = rotation.as_matrix()
    motion[:3, 3] = to - rotation.apply(at)
    matrix = np.array(to_world.matrix, np.float64).reshape(4, 4)
    return mi.AffineTransform4f((motion @ matrix).astype(np.float32))


def mesh_parts(meshes: Sequence[tuple[np.ndarray, np.ndarray]], position_tolerance: float = 1e-5,
               angle_tolerance: float = 1e-5, separate: Sequence[int] = ()) -> Parts:
    """Decompose triangle meshes into convex planar parts.

    Parameters
    ----------
    meshes : sequence of (ndarray, ndarray)
        Per shape: vertex positions float [n_v, 3] in m, and triangles int [n_f, 3] (vertex
        indices; the vertex order gives the orientation by the right-hand rule).
    position_tolerance : float
        Vertices closer than this [m] are one vertex: within a shape for finding shared edges,
        across shapes for :attr:`Parts.adjacency`.
    angle_tolerance : float
        Edge-adjacent triangles whose normals differ by less than this [rad] are coplanar (one
        face); a part's outline may turn inwards by up to this much at a corner (convex within
        the tolerance of the mesh's own rounding).
    separate : sequence of int
        Shapes whose triangles are faces of their own, coplanar or not (a mesh whose vertices
        move off their faces' planes, docs/physics.md (AD4)).

    Returns
    -------
    Parts
        Parts sorted by face; faces in order of their first triangle. Degenerate triangles
        (area below :data:`DEGENERATE_AREA` m^2, non-finite, or with two vertices merged into
        one) belong to no face and no part.
    """
    points, faces, vertex_shape, triangle_shape, triangle_base = _stack(meshes)
    merged, cluster = _merge_vertices(points, vertex_shape, position_tolerance)
    tri = merged[faces]
    cross = np.cross(points[tri[:, 1]] - points[tri[:, 0]], points[tri[:, 2]] - points[tri[:, 0]])
    norm = np.linalg.norm(cross, axis=1)
    valid = (np.isfinite(norm) & (0.5 * norm >= DEGENERATE_AREA) & (tri[:, 0] != tri[:, 1])
             & (tri[:, 1] != tri[:, 2]) & (tri[:, 2] != tri[:, 0]))
    unit = np.where(valid[:, None], cross / np.where(valid, norm, 1.0)[:, None], 0.0)
    face, pairs = _faces(tri, unit, valid, math.cos(angle_tolerance), np.isin(triangle_shape, list(separate)))
    n_faces = int(face.max(initial=-1)) + 1
    inside = face >= 0
    face_normal = np.zeros((n_faces, 3))
    np.add.at(face_normal, face[inside], cross[inside])
    face_normal /= np.linalg.norm(face_normal, axis=1, keepdims=True)
    origin = np.full(n_faces, len(points), np.int64)
    np.minimum.at(origin, np.repeat(face[inside], 3), tri[inside].ravel())
    face_origin = points[origin] if n_faces else np.zeros((0, 3))
    slots, n_vertices, part_face, triangle_part = _split(tri, face, pairs, points, face_normal, face_origin,
                                                         angle_tolerance)
    normal = face_normal[part_face]
    start, adjacency = _adjacency(triangle_part, tri, cluster, len(slots))
    first_triangle = np.full(n_faces, len(tri), np.int64)
    np.minimum.at(first_triangle, face[inside], np.nonzero(inside)[0])
    part_shape = triangle_shape[first_triangle[part_face]].astype(np.int32)
    closed = _closed_shapes(tri[valid], triangle_shape[valid], len(meshes))
    return Parts(normal=normal, offset=np.einsum("ij,ij->i", normal, face_origin[part_face]),
                 vertices=points[slots], n_vertices=n_vertices.astype(np.int32), face=part_face.astype(np.int32),
                 shape=part_shape, face_origin=face_origin, face_normal=face_normal, triangle_part=triangle_part,
                 triangle_base=triangle_base, adjacency_start=start, adjacency=adjacency,
                 closed=closed[part_shape] if len(part_shape) else np.zeros(0, bool))


def _closed_shapes(tri: np.ndarray, shape: np.ndarray, n_shapes: int) -> np.ndarray:
    """bool [n_shapes]: every edge of the shape's triangles ``tri`` (merged vertex indices) is shared
    by exactly two of them, which run along it in opposite directions (a closed, manifold,
    consistently wound surface)."""
    closed = np.zeros(n_shapes, bool)
    if not len(tri):
        return closed
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    owner = np.tile(shape, 3)
    keys, counts = unique_rows(np.column_stack([owner, edges]), return_counts=True)
    bad = np.zeros(n_shapes, bool)
    bad[keys[counts != 2, 0]] = True
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    keys, counts = unique_rows(np.column_stack([owner, directed]), return_counts=True)
    bad[keys[counts != 1, 0]] = True                  # an edge run twice one way: inconsistent winding
    closed[np.unique(shape)] = True
    return closed & ~bad


def _stack(meshes):
    """All shapes' vertices float64 [N, 3] and triangles int64 [T, 3] (global vertex indices), the
    shape of each vertex int64 [N] and triangle int64 [T], and each shape's first triangle row
    int64 [n_shapes]."""
    vertices = [np.asarray(v, np.float64).reshape(-1, 3) for v, _ in meshes]
    faces = [np.asarray(f, np.int64).reshape(-1, 3) for _, f in meshes]
    n_v = np.array([len(v) for v in vertices], np.int64)
    n_f = np.array([len(f) for f in faces], np.int64)
    vertex_base = np.concatenate([[0], np.cumsum(n_v)[:-1]]).astype(np.int64)
    triangle_base = np.concatenate([[0], np.cumsum(n_f)[:-1]]).astype(np.int64)
    if len(meshes) == 0:
        vertex_base = triangle_base = np.zeros(0, np.int64)
    for f, v in zip(faces, vertices):
        if len(f) and (f.min() < 0 or f.max() >= len(v)):
            raise ValueError(f"triangle vertex index out of range [0, {len(v)})")
    points = np.concatenate(vertices) if vertices else np.zeros((0, 3))
    tri = (np.concatenate([f + b for f, b in zip(faces, vertex_base)]) if faces else np.zeros((0, 3), np.int64))
    return points, tri, np.repeat(np.arange(len(meshes)), n_v), np.repeat(np.arange(len(meshes)), n_f), triangle_base


def _merge_vertices(points, shape_of, tolerance):
    """Vertices within ``tolerance`` of one another, chained: ``merged`` [N] the lowest index of
    the vertex's group within its shape, ``cluster`` [N] its group's label over all shapes.
    Non-finite vertices stay alone."""
    n = len(points)
    finite = np.nonzero(np.all(np.isfinite(points), axis=1))[0]
    pairs = np.zeros((0, 2), np.int64)
    if len(finite) > 1:
        pairs = finite[cKDTree(points[finite]).query_pairs(tolerance, output_type="ndarray")]
    _, cluster = connected_components(sparse.coo_matrix(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)), directed=False)
    same = pairs[shape_of[pairs[:, 0]] == shape_of[pairs[:, 1]]]
    _, label = connected_components(sparse.coo_matrix(
        (np.ones(len(same)), (same[:, 0], same[:, 1])), shape=(n, n)), directed=False)
    lowest = np.full(label.max(initial=-1) + 1, n, np.int64)
    np.minimum.at(lowest, label, np.arange(n))
    return lowest[label], cluster


def _faces(tri, unit, valid, cos_tolerance, alone):
    """Face of each triangle int64 [T] (-1 when degenerate), numbered in order of their lowest
    triangle, and the coplanar edge-adjacent triangle pairs int64 [P, 2] that join them (none
    with a triangle where ``alone`` [T])."""
    t = len(tri)
    ids = np.nonzero(valid)[0]
    edges = np.sort(tri[ids][:, [[0, 1], [1, 2], [2, 0]]], axis=2).reshape(-1, 2)
    owner = np.repeat(ids, 3)
    key = edges[:, 0] * (int(tri.max(initial=0)) + 1) + edges[:, 1]
    order = np.argsort(key, kind="stable")
    key, owner = key[order], owner[order]
    found = []
    for d in range(1, len(key)):          # all pairs within a group of equal edges
        same = np.nonzero(key[:-d] == key[d:])[0]
        if len(same) == 0:
            break
        found.append(np.stack([owner[same], owner[same + d]], axis=1))
    pairs = np.concatenate(found) if found else np.zeros((0, 2), np.int64)
    pairs = pairs[(pairs[:, 0] != pairs[:, 1]) & ~alone[pairs[:, 0]] & ~alone[pairs[:, 1]]
                  & (np.einsum("ij,ij->i", unit[pairs[:, 0]], unit[pairs[:, 1]]) > cos_tolerance)]
    pairs = unique_rows(np.sort(pairs, axis=1))
    _, label = connected_components(sparse.coo_matrix(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(t, t)), directed=False)
    face = np.full(t, -1, np.int64)
    _, first = np.unique(label[ids], return_index=True)     # ids ascending: first = lowest triangle
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    face[ids] = rank[np.unique(label[ids], return_inverse=True)[1]]
    return face, pairs


def _split(tri, face, pairs, points, face_normal, face_origin, angle_tolerance):
    """Parts of all faces: corner vertex indices int64 [n_parts, MAX_PART_VERTICES] (counter-
    clockwise, padded with the last corner), each part's face int64 [n_parts] and each triangle's
    part int32 [T]; parts sorted by face, then by their seed triangle."""
    n_faces = len(face_normal)
    size = np.bincount(face[face >= 0], minlength=n_faces)
    by_face = np.argsort(np.where(face >= 0, face, n_faces), kind="stable")[: int((face >= 0).sum())]
    start = np.concatenate([[0], np.cumsum(size)]).astype(np.int64)
    first = by_face[start[:-1]]
    one, two = np.nonzero(size == 1)[0], np.nonzero(size == 2)[0]
    second = by_face[start[two] + 1]
    quads, ok = _quads(tri[first[two]], tri[second], points, face_normal[two], angle_tolerance)
    outlines = [np.pad(tri[first[one]], ((0, 0), (0, MAX_PART_VERTICES - 3)), constant_values=-1),
                np.pad(quads[ok], ((0, 0), (0, MAX_PART_VERTICES - 4)), constant_values=-1)]
    part_face, part_rank = [one, two[ok]], [np.zeros(len(one), np.int64), np.zeros(int(ok.sum()), np.int64)]
    members = [first[one], first[two[ok]], second[ok]]
    member_record = [np.arange(len(one)), len(one) + np.arange(int(ok.sum())), len(one) + np.arange(int(ok.sum()))]
    general = np.setdiff1d(np.nonzero(size >= 2)[0], two[ok])
    neighbour_start, neighbour = _neighbours(pairs, len(tri))
    record = len(one) + int(ok.sum())
    for f in general.tolist():
        found = _split_face(by_face[start[f]:start[f + 1]].tolist(), tri, neighbour_start, neighbour, points,
                            face_normal[f], face_origin[f], angle_tolerance)
        for rank, (cycle, chosen) in enumerate(found):
            outlines.append(np.array([cycle + [-1] * (MAX_PART_VERTICES - len(cycle))], np.int64))
            part_face.append(np.array([f]))
            part_rank.append(np.array([rank]))
            members.append(np.array(chosen, np.int64))
            member_record.append(np.full(len(chosen), record))
            record += 1
    outline, part_face, part_rank = (np.concatenate(x) for x in (outlines, part_face, part_rank))
    order = np.lexsort((part_rank, part_face))
    part_of_record = np.empty(len(order), np.int64)
    part_of_record[order] = np.arange(len(order))
    triangle_part = np.full(len(tri), -1, np.int32)
    triangle_part[np.concatenate(members)] = part_of_record[np.concatenate(member_record)]
    outline = outline[order]
    outline = np.take_along_axis(outline, np.argsort(outline < 0, axis=1, kind="stable"), axis=1)
    count = (outline >= 0).sum(axis=1)
    last = outline[np.arange(len(outline)), count - 1] if len(outline) else np.zeros(0, np.int64)
    outline = np.where(np.arange(MAX_PART_VERTICES) < count[:, None], outline, last[:, None])
    return outline, count, part_face[order], triangle_part


def _quads(a, b, points, normal, angle_tolerance):
    """Two-triangle faces at once: the union of triangles ``a`` and ``b`` (vertex indices, each
    int64 [n, 3], ``a`` the lower-index one) as an outline int64 [n, 4] starting at ``a``'s first
    vertex (-1 marks a dropped collinear corner), and whether it is one convex part (``b`` shares
    exactly one edge with ``a``, reversed, and both shared corners turn by at least
    ``-angle_tolerance``)."""
    n = len(a)
    matches = np.zeros(n, np.int64)
    r_of, c_of = np.zeros(n, np.int64), np.zeros(n, np.int64)
    for r in range(3):            # a's edge p -> q = a[r+1] -> a[r+2], b holds q -> p
        p, q = a[:, (r + 1) % 3], a[:, (r + 2) % 3]
        for s in range(3):
            hit = (b[:, s] == q) & (b[:, (s + 1) % 3] == p)
            matches += hit
            r_of = np.where(hit, r, r_of)
            c_of = np.where(hit, b[:, (s + 2) % 3], c_of)
    rows = np.arange(n)
    x, p, q = a[rows, r_of], a[rows, (r_of + 1) % 3], a[rows, (r_of + 2) % 3]
    c = c_of
    turn_p = _turn(points[x], points[p], points[c], normal)
    turn_q = _turn(points[c], points[q], points[x], normal)
    ok = ((matches == 1) & (c != a[:, 0]) & (c != a[:, 1]) & (c != a[:, 2])
          & (turn_p >= -angle_tolerance) & (turn_q >= -angle_tolerance))
    outline = np.stack([x, np.where(np.abs(turn_p) < COLLINEAR_ANGLE, -1, p), c,
                        np.where(np.abs(turn_q) < COLLINEAR_ANGLE, -1, q)], axis=1)
    shift = np.array([0, 3, 1])[r_of]                  # position of a[0] in (x, p, c, q)
    quad = np.take_along_axis(outline, (shift[:, None] + np.arange(4)) % 4, axis=1)
    return quad, ok


def _turn(a, b, c, normal):
    """Signed turn angle [rad] at ``b`` of the path ``a -> b -> c`` about ``normal`` (positive =
    counter-clockwise); arrays [n, 3]."""
    d1, d2 = b - a, c - b
    return np.arctan2(np.einsum("ij,ij->i", np.cross(d1, d2), normal), np.einsum("ij,ij->i", d1, d2))


def _neighbours(pairs, n_triangles):
    """Coplanar edge-neighbours of every triangle, CSR: start int64 [T + 1] and neighbours int64
    (sorted per triangle)."""
    both = np.concatenate([pairs, pairs[:, ::-1]])
    both = both[np.lexsort((both[:, 1], both[:, 0]))]
    return np.searchsorted(both[:, 0], np.arange(n_triangles + 1)), both[:, 1]


def _split_face(members, tri, neighbour_start, neighbour, points, normal, origin, angle_tolerance):
    """Greedy convex decomposition of one face: from each lowest-index unassigned triangle, add
    edge-neighbours breadth first while the outline stays convex (every turn at least
    ``-angle_tolerance``) with at most :data:`MAX_PART_VERTICES` non-collinear corners.
    Returns [(corner vertex indices counter-clockwise, triangles)] in order of their seeds."""
    axis = np.eye(3)[np.argmin(np.abs(normal))]
    u = _cross(normal, axis) / np.linalg.norm(_cross(normal, axis))
    basis = np.stack([u, _cross(normal, u)], axis=1)
    vertex_ids = np.unique(tri[members])
    xy = dict(zip(vertex_ids.tolist(), ((points[vertex_ids] - origin) @ basis).tolist()))
    assigned: set[int] = set()
    parts = []
    for seed in members:
        if seed in assigned:
            continue
        cycle = tri[seed].tolist()
        turns = {v: _turn2(xy[cycle[i - 1]], xy[v], xy[cycle[(i + 1) % 3]]) for i, v in enumerate(cycle)}
        assigned.add(seed)
        chosen, tried = [seed], {seed}
        queue = deque(neighbour[neighbour_start[seed]:neighbour_start[seed + 1]].tolist())
        while queue:
            t = queue.popleft()
            if t in assigned or t in tried:
                continue
            tried.add(t)
            if _grow(cycle, turns, tri[t].tolist(), xy, angle_tolerance):
                assigned.add(t)
                chosen.append(t)
                queue.extend(neighbour[neighbour_start[t]:neighbour_start[t + 1]].tolist())
        parts.append(([v for v in cycle if abs(turns[v]) >= COLLINEAR_ANGLE], chosen))
    return parts


def _grow(cycle, turns, triangle, xy, angle_tolerance) -> bool:
    """Add ``triangle`` to the outline ``cycle`` (in place, with its ``turns``) if it shares an
    edge with it, brings a new vertex, and keeps it convex within :data:`MAX_PART_VERTICES`
    corners; whether it was added."""
    n = len(cycle)
    position = {v: i for i, v in enumerate(cycle)}
    for s in range(3):
        q, p, c = triangle[s], triangle[(s + 1) % 3], triangle[(s + 2) % 3]
        i = position.get(p)
        if i is None or cycle[(i + 1) % n] != q:
            continue
        if c in position:
            return False
        before, after = cycle[i - 1], cycle[(i + 2) % n]
        new = {p: _turn2(xy[before], xy[p], xy[c]), c: _turn2(xy[p], xy[c], xy[q]),
               q: _turn2(xy[c], xy[q], xy[after])}
        if min(new.values()) < -angle_tolerance:
            return False
        corners = sum(abs(turns[v]) >= COLLINEAR_ANGLE for v in cycle if v not in new)
        if corners + sum(abs(t) >= COLLINEAR_ANGLE for t in new.values()) > MAX_PART_VERTICES:
            return False
        cycle.insert(i + 1, c)
        turns.update(new)
        return True
    return False


def _cross(a, b):
    """Cross product of two 3-vectors (cheaper than ``np.cross`` for one pair)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _turn2(a, b, c) -> float:
    """Signed turn angle [rad] at ``b`` of the planar path ``a -> b -> c`` (points (x, y))."""
    d1x, d1y, d2x, d2y = b[0] - a[0], b[1] - a[1], c[0] - b[0], c[1] - b[1]
    return math.atan2(d1x * d2y - d1y * d2x, d1x * d2x + d1y * d2y)


def _adjacency(triangle_part, tri, cluster, n_parts):
    """CSR of the parts sharing a vertex position: start int64 [n_parts + 1], neighbours int32."""
    rows = np.nonzero(triangle_part >= 0)[0]
    part = np.repeat(triangle_part[rows].astype(np.int64), 3)
    position = cluster[tri[rows].ravel()]
    n_clusters = int(cluster.max(initial=-1)) + 1
    incidence = sparse.csr_matrix((np.ones(len(part), np.int32), (part, position)), shape=(n_parts, n_clusters))
    incidence.data[:] = 1
    touch = (incidence @ incidence.T).tocsr()
    touch.setdiag(0)
    touch.eliminate_zeros()
    touch.sort_indices()
    return touch.indptr.astype(np.int64), touch.indices.astype(np.int32)


def triangle_table(scene, size: int):
    """Per shape id: mesh flag and first row of the float64 triangle table; per triangle: its unit
    normal (float64 cross product of the float32 edges; zero for a degenerate triangle) and its
    plane's offset ``n . v0``. Returns ``(is_mesh, base, normal [n, 3], offset [n], other)``,
    ``other`` whether the scene has shapes that are not meshes (a Mitsuba scene; ``size`` exceeds
    every shape id)."""
    import drjit as dr
    import mitsuba as mi
    is_mesh = np.zeros(size, np.uint32)
    base = np.zeros(size, np.uint32)
    normals, offsets, other, count = [], [], False, 0
    for shape in scene.shapes():
        sid = int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])
        if not shape.is_mesh():
            other = True
            continue
        v = np.array(shape.vertex_positions_buffer(), np.float32).astype(np.float64).reshape(-1, 3)
        f = np.array(shape.faces_buffer(), np.int64).reshape(-1, 3)
        v0, v1, v2 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        normal = np.cross(v1 - v0, v2 - v0)
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        normal = np.where(length > 0, normal / np.where(length > 0, length, 1.0), 0.0)
        is_mesh[sid], base[sid] = 1, count
        normals.append(normal)
        offsets.append(np.einsum("ij,ij->i", normal, v0))
        count += f.shape[0]
    normal = np.concatenate(normals) if normals else np.zeros((1, 3))
    offset = np.concatenate(offsets) if offsets else np.zeros(1)
    return is_mesh, base, normal, offset, other
