"""Integration elements fixed on the mesh: every planar face covered by square patches in its own
frame, and the pieces of a lit region they cut (docs/physics.md (M1), (M2)).

:func:`surfaces_of` turns a loaded scene's meshes into :class:`Surfaces`: the convex planar parts
of :mod:`sarmitsuba.tracing.mesh.facets`, each with its face's frame. The frame is the shape's own
(:func:`sarmitsuba.scene.loader.shape_frame`: the shape's anchor vertex and axes, projected into
the face's plane), the frame of the clutter scatterers' lattice (docs/physics.md (C)); it moves
and turns with the shape and does not depend on the ray lattice, the pulse or the track.

A patch is the square ``[i P, (i + 1) P) x [j P, (j + 1) P)`` of a face's frame, ``P`` the patch
size (:func:`sarmitsuba.scene.planning.patch_size`, a whole number of scatterer cells). A *region*
is a convex polygon on one part: the part itself at the first bounce, or the part of it that a
chain of mirrors lets the antenna reach (:mod:`sarmitsuba.tracing.discovery.chains`). :func:`sarmitsuba.tracing.mesh.piece_cuts.pieces_of` cuts
a batch of regions into *pieces*, one per patch they meet: *whole* where the patch lies inside
the region, else the patch clipped to it.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from ...core.arrays import unique_pairs, unique_rows
from .covers import covered_parts, split_covered
from ...scene.loader import shape_frame
from .facets import Parts, mesh_parts, scene_meshes, scene_parts
from .polygons import REPEAT_DISTANCE, drop_collinear, moments, pad

__all__ = ["Surfaces", "moved_surfaces", "shape_indices", "surfaces_of", "surfaces_from", "face_axes", "face_partners", "occluder_partners", "Pieces", "ALONG_FIRST_AXIS",
           "UNIT_SQUARE"]

#: A face whose normal lies within 0.81 deg of its shape's first axis takes its frame's ``u`` from
#: the shape's second axis (as the clutter lattice does, docs/physics.md (C)).
ALONG_FIRST_AXIS = 0.9999


@dataclass(frozen=True)
class Surfaces:
    """The scene's convex planar parts with their faces' frames (float64, m).

    Attributes
    ----------
    normal : float64 [n, 3]
        Unit normal of the part (the mesh's orientation).
    offset : float64 [n]
        ``normal . x`` on the part's plane.
    origin : float64 [n, 3]
        The frame's origin: the shape's anchor vertex (not in general on the plane).
    axis_u, axis_v : float64 [n, 3]
        The frame's axes in the plane, ``axis_v = normal x axis_u``.
    polygon : float64 [n, V, 2]
        The part's corners in face coordinates ``((x - origin) . axis_u, (x - origin) . axis_v)``,
        counter-clockwise (about ``normal``), padded with the first corner
        (:mod:`sarmitsuba.tracing.mesh.polygons`).
    n_corners : int64 [n]
    shape_id : uint32 [n]
        Mitsuba id of the part's shape (the material table's index).
    row : int64 [n]
        The part's material row.
    seen_side : int8 [n]
        The side of the part that faces out of its body where the body is closed and consistently
        wound (:attr:`sarmitsuba.tracing.mesh.facets.Parts.closed`): +1 its front (the body's
        divergence-theorem volume ``sum area offset / 3`` is positive), -1 its back; 0 where the
        body is open or its winding inconsistent (either side may be seen).
    face : int64 [n]
        The part's face (coplanar edge-connected triangles of one shape).
    triangle_part : int64 [n_triangles]
        The part of every triangle (-1: degenerate), at ``triangle_base[shape id] + primitive``.
    triangle_base : int64 [max shape id + 1]
        Each mesh's first row of ``triangle_part``; -1 for shapes that are not meshes.
    split_start, split_count : int64 [n]
        A part covered by another shape's coplanar face (:mod:`sarmitsuba.tracing.mesh.covers`) has no
        corners of its own: a ray that meets its triangles meets the part among
        ``split_parts[split_start : split_start + split_count]`` (its uncovered pieces and its
        covers) that holds the hit point. 0 for every other part.
    split_parts : int64 [k]
    body : int64 [n] or None
        The connected object each part belongs to: parts of one shape that share a vertex
        (a mesh that holds several objects, three corner reflectors say, holds several bodies).
    """

    normal: np.ndarray
    offset: np.ndarray
    origin: np.ndarray
    axis_u: np.ndarray
    axis_v: np.ndarray
    polygon: np.ndarray
    n_corners: np.ndarray
    shape_id: np.ndarray
    row: np.ndarray
    seen_side: np.ndarray
    face: np.ndarray
    triangle_part: np.ndarray
    triangle_base: np.ndarray
    split_start: np.ndarray | None = None
    split_count: np.ndarray | None = None
    split_parts: np.ndarray | None = None
    body: np.ndarray | None = None

    @property
    def n_parts(self) -> int:
        """Parts (convex planar polygons of the mesh, docs/physics.md (M1))."""
        return len(self.offset)

    def to_world(self, part: np.ndarray, coords: np.ndarray) -> np.ndarray:
        """World points float64 [..., 3] of face coordinates ``coords`` [..., 2] on ``part``
        (whose shape is a leading part of ``coords``' own)."""
        # ``o + x u + y v`` in that order (bit for bit :func:`_to_world_reference`), from the
        # cached frames (one gather); big batches one world axis at a time (NumPy's broadcast
        # loops over a last axis of 3 are slow)
        frame = np.take(self._frames, part, axis=0)                   # [..., 3 (o, u, v), 3]
        frame = frame.reshape(frame.shape[:-2] + (1,) * (coords.ndim + 1 - frame.ndim) + (3, 3))
        x, y = coords[..., 0], coords[..., 1]
        if coords.size < 4096:
            return frame[..., 0, :] + x[..., None] * frame[..., 1, :] + y[..., None] * frame[..., 2, :]
        out = np.empty(np.broadcast_shapes(x.shape, frame.shape[:-2]) + (3,), np.result_type(coords, frame))
        term = np.empty(out.shape[:-1], out.dtype)
        for k in range(3):
            axis = out[..., k]
            np.multiply(x, frame[..., 1, k], out=axis)
            axis += frame[..., 0, k]
            axis += np.multiply(y, frame[..., 2, k], out=term)
        return out

    def vector_to_world(self, part: np.ndarray, vectors: np.ndarray) -> np.ndarray:
        """World vectors float64 [m, 3] of face-coordinate vectors ``vectors`` [m, 2] on ``part`` [m]
        (edges, offsets, rates: no origin)."""
        return vectors[:, :1] * np.take(self.axis_u, part, axis=0) + vectors[:, 1:] * np.take(self.axis_v, part, axis=0)

    def to_face(self, part: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Face coordinates float64 [..., 2] of world points [..., 3] on (or projected onto) ``part``."""
        o, u, v = (_expand(a[part], points.ndim) for a in (self.origin, self.axis_u, self.axis_v))
        rel = points - o
        return np.stack([np.sum(rel * u, axis=-1), np.sum(rel * v, axis=-1)], axis=-1)

    def plane_point(self, part: np.ndarray) -> np.ndarray:
        """A point of each part's plane, float64 [..., 3]: the frame's origin projected on it."""
        return self._frames[part, 0]

    @functools.cached_property
    def world_polygon(self) -> np.ndarray:
        """float64 [n, V, 3]: every part's :attr:`polygon` in world coordinates (computed once):
        ``world_polygon[part]`` is ``to_world(part, polygon[part])`` bit for bit, without the
        arithmetic. Read only (shared by every caller)."""
        corners = self.to_world(np.arange(self.n_parts), self.polygon)
        corners.flags.writeable = False
        return corners

    @functools.cached_property
    def _frames(self) -> np.ndarray:
        """float64 [n, 3, 3]: every part's plane point (:meth:`plane_point`), ``axis_u`` and
        ``axis_v`` as rows (computed once; the surfaces are immutable)."""
        return np.stack([_plane_point_reference(self, np.arange(self.n_parts)), self.axis_u, self.axis_v], axis=1)


def _plane_point_reference(s: Surfaces, part: np.ndarray) -> np.ndarray:
    """:meth:`Surfaces.plane_point` computed directly (its cache's source, and the tests' reference)."""
    origin, normal = s.origin[part], s.normal[part]
    return origin + normal * (s.offset[part] - np.einsum("...i,...i->...", origin, normal))[..., None]


def _to_world_reference(s: Surfaces, part: np.ndarray, coords: np.ndarray) -> np.ndarray:
    """:meth:`Surfaces.to_world` without the cache (the tests' reference)."""
    o, u, v = (_expand(a, coords.ndim) for a in (_plane_point_reference(s, part), s.axis_u[part], s.axis_v[part]))
    return o + coords[..., 0, None] * u + coords[..., 1, None] * v


def _expand(values: np.ndarray, ndim: int) -> np.ndarray:
    """``values`` [..., 3] with axes inserted before the last until it has ``ndim`` dimensions."""
    while values.ndim < ndim:
        values = values[..., None, :]
    return values


def face_axes(normal: np.ndarray, shape_axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The face frame's axes ``(u, v)`` float64 [n, 3] in planes of unit ``normal`` [n, 3]: the
    shape's first axis projected on the plane and normalised (its second axis' where the normal
    lies along the first), ``v = normal x u`` (docs/physics.md (C), (M1)); ``shape_axes`` [n, 3, 3]
    holds each shape's axes as rows."""
    first, second = shape_axes[:, 0], shape_axes[:, 1]
    along = np.abs(np.einsum("ij,ij->i", normal, first)) > ALONG_FIRST_AXIS
    axis = np.where(along[:, None], second, first)
    u = axis - normal * np.einsum("ij,ij->i", normal, axis)[:, None]
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, np.cross(normal, u)


def shape_indices(shapes) -> np.ndarray:
    """int64 [len(shapes)]: each Mitsuba shape's registry index, the value rays report as their
    shape and :attr:`Surfaces.shape_id` holds."""
    return np.array([int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]) for s in shapes], np.int64)


def surfaces_of(scene, table, parts: Parts | None = None) -> Surfaces:
    """The :class:`Surfaces` of a loaded Mitsuba scene whose material table is ``table``
    (:class:`sarmitsuba.scene.trace_inputs.MaterialTable`: rows, shape frames)."""
    parts = scene_parts(scene) if parts is None else parts
    shapes = list(scene.shapes())
    ids = shape_indices(shapes)
    mesh = np.array([s.is_mesh() for s in shapes], bool)
    return surfaces_from(parts, ids, mesh, table.shape_origin, table.shape_axes, table.row_of_shape)


def surfaces_from(parts: Parts, shape_ids: np.ndarray, is_mesh: np.ndarray, shape_origin: np.ndarray,
                  shape_axes: np.ndarray, row_of_shape: np.ndarray) -> Surfaces:
    """The :class:`Surfaces` of ``parts``, whose input shape ``k`` has the Mitsuba id
    ``shape_ids[k]`` and is a mesh where ``is_mesh[k]``; ``shape_origin`` [ids, 3], ``shape_axes``
    [ids, 3, 3] and ``row_of_shape`` [ids] are indexed by id (as the material table's)."""
    shape_ids = np.asarray(shape_ids, np.int64)
    shape_id = shape_ids[parts.shape] if len(shape_ids) else np.zeros(0, np.int64)
    origin = shape_origin[shape_id]
    u, v = face_axes(parts.normal, shape_axes[shape_id])
    rel = parts.vertices - origin[:, None, :]
    polygon = np.stack([np.einsum("pvi,pi->pv", rel, u), np.einsum("pvi,pi->pv", rel, v)], axis=2)
    base = np.full(int(shape_ids.max(initial=-1)) + 1, -1, np.int64)
    base[shape_ids[is_mesh]] = parts.triangle_base[np.flatnonzero(is_mesh)]
    surfaces = Surfaces(normal=parts.normal, offset=parts.offset, origin=origin, axis_u=u, axis_v=v,
                        polygon=pad(polygon, parts.n_vertices.astype(np.int64)),
                        n_corners=parts.n_vertices.astype(np.int64), shape_id=shape_id.astype(np.uint32),
                        row=np.asarray(row_of_shape)[shape_id].astype(np.int64),
                        seen_side=np.zeros(parts.n_parts, np.int8),
                        face=parts.face.astype(np.int64), triangle_part=parts.triangle_part.astype(np.int64),
                        triangle_base=base, body=_bodies(parts))
    surfaces = dataclasses.replace(surfaces, seen_side=_seen_side(surfaces, parts.closed))
    return _uncover(surfaces)


def face_partners(surfaces: Surfaces) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``(start int64 [n_parts + 1], parts int64 [k])``: for each part, the other parts of its
    face (:attr:`Surfaces.face`) that have corners of their own."""
    n = surfaces.n_parts
    real = np.flatnonzero(surfaces.n_corners > 0)
    order = real[np.argsort(surfaces.face[real], kind="stable")]
    faces, first, count = np.unique(surfaces.face[order], return_index=True, return_counts=True)
    group = np.minimum(np.searchsorted(faces, surfaces.face), max(len(faces) - 1, 0))
    has = (len(faces) > 0) & (faces[group] == surfaces.face) if len(faces) else np.zeros(n, bool)
    size = np.where(has, count[group] if len(faces) else 0, 0)
    rows = np.repeat(np.arange(n), size)
    local = np.arange(int(size.sum())) - np.repeat(np.cumsum(size) - size, size)
    parts = order[np.repeat(first[group] if len(faces) else np.zeros(n, np.int64), size) + local]
    keep = parts != rows
    size = np.bincount(rows[keep], minlength=n)
    return np.concatenate([[0], np.cumsum(size)]).astype(np.int64), parts[keep].astype(np.int64)


def occluder_partners(surfaces: Surfaces) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``(start int64 [n_parts + 1], parts int64 [k])``: for each part, the other parts of its
    face and the parts of its shape that share a corner with it (to ``1e-6`` m). Where a ray met a
    part, these cast the rest of the shadow there: the silhouette of a body runs along edges two
    such parts share (a box's roof and wall meet at the tip of its shadow)."""
    n = surfaces.n_parts
    start, partners = face_partners(surfaces)
    rows = [np.repeat(np.arange(n), np.diff(start)), partners]
    slots = np.arange(surfaces.polygon.shape[1])[None, :] < surfaces.n_corners[:, None]
    part, slot = np.nonzero(slots)
    if len(part):
        corners = surfaces.to_world(part, surfaces.polygon[part, slot])
        key = np.round(corners * 1e6).astype(np.int64)
        shape = np.asarray(surfaces.shape_id, np.int64)[part]
        _, group = unique_rows(np.column_stack([shape, key]), return_inverse=True)
        order = np.argsort(group, kind="stable")
        g, p = group[order], part[order]
        first = np.searchsorted(g, g, side="left")
        last = np.searchsorted(g, g, side="right")
        size = last - first
        a = np.repeat(p, size)
        b = p[np.repeat(first, size) + np.arange(int(size.sum())) - np.repeat(np.cumsum(size) - size, size)]
        rows.append(np.stack([a, b]))
    pairs = np.concatenate([np.stack(rows[:2])] + rows[2:], axis=1).T
    pairs = unique_pairs(*pairs[pairs[:, 0] != pairs[:, 1]].T)
    size = np.bincount(pairs[:, 0], minlength=n)
    return np.concatenate([[0], np.cumsum(size)]).astype(np.int64), pairs[:, 1].astype(np.int64)


def _seen_side(s: Surfaces, closed: np.ndarray | None) -> np.ndarray:
    """int8 [n]: :attr:`Surfaces.seen_side` from the closed, consistently wound shapes ``closed``
    [n] (per part): the sign of each body's volume ``sum area offset / 3`` (divergence theorem)."""
    side = np.zeros(s.n_parts, np.int8)
    if closed is None or not np.any(closed):
        return side
    area = moments(s.polygon, s.n_corners)[0]
    body = np.unique(s.body, return_inverse=True)[1]
    volume = np.bincount(body, weights=area * s.offset, minlength=int(body.max(initial=-1)) + 1) / 3.0
    shut = np.ones(len(volume), bool)
    np.logical_and.at(shut, body, np.asarray(closed, bool))
    sign = np.where(shut, np.sign(volume), 0.0)[body]
    return sign.astype(np.int8)


def _bodies(parts: Parts) -> np.ndarray:
    """The connected objects of the parts: components of the graph of parts of one shape that
    share a vertex position."""
    from scipy import sparse
    from scipy.sparse.csgraph import connected_components
    n = parts.n_parts
    owner = np.repeat(np.arange(n), np.diff(parts.adjacency_start))
    other = parts.adjacency.astype(np.int64)
    same = parts.shape[owner] == parts.shape[other]
    graph = sparse.coo_matrix((np.ones(int(same.sum())), (owner[same], other[same])), shape=(n, n))
    return connected_components(graph, directed=False)[1].astype(np.int64)


def _part_areas(world: np.ndarray, count: np.ndarray) -> np.ndarray:
    """float64 [n]: the areas of polygons ``world`` [n, V, 3] (``count`` [n] corners; 0 below 3):
    half the norm of the sum of their fans' cross products, summed in fan order and normed by a dot
    product per part as :func:`_part_areas_reference` (bit for bit: the areas order covers,
    :func:`sarmitsuba.tracing.mesh.covers.covered_parts`)."""
    first = world[:, :1]
    cross = np.cross(world[:, 1:-1] - first, world[:, 2:] - first)
    cross[np.arange(cross.shape[1])[None, :] >= (count - 2)[:, None]] = 0.0
    total = cross.sum(axis=1)
    return np.array([0.5 * math.sqrt(t.dot(t)) if k >= 3 else 0.0 for t, k in zip(total, count.tolist())])


def _part_areas_reference(world: np.ndarray, count: np.ndarray) -> np.ndarray:
    """:func:`_part_areas` one part at a time."""
    corners = [world[k, :count[k]] for k in range(len(count))]
    return np.array([0.5 * np.linalg.norm(np.cross(c[1:-1] - c[0], c[2:] - c[0]).sum(axis=0)) if len(c) >= 3 else 0.0
                     for c in corners])


def _uncover(s: Surfaces) -> Surfaces:
    """``s`` with every part that another shape's coplanar, same-facing face covers replaced by the
    triangles of what the covers leave of it (:mod:`sarmitsuba.tracing.mesh.covers`)."""
    n = s.n_parts
    world = s.to_world(np.arange(n), s.polygon)
    corners = [c[:k] for c, k in zip(world, s.n_corners.tolist())]
    area = _part_areas(world, s.n_corners)
    pairs = covered_parts(s.normal, s.offset, corners, s.shape_id, area)
    if len(pairs) == 0:
        return s
    rows, polygons, candidates = [], [], {}
    for covered in np.unique(pairs[:, 0]):
        covers = pairs[pairs[:, 0] == covered, 1]
        covers2 = [s.to_face(np.array(covered), corners[c]) for c in covers]
        pieces = split_covered(s.polygon[covered], s.n_corners[covered], covers2)
        first = n + len(rows)
        rows.extend([covered] * len(pieces))
        polygons.extend(pieces)
        candidates[int(covered)] = np.concatenate([np.arange(first, first + len(pieces)), covers])
    extra = np.array(rows, np.int64)
    grow = lambda a: np.concatenate([a, a[extra]])          # noqa: E731  (the pieces keep their part's plane and frame)
    polygon = np.zeros((n + len(extra), s.polygon.shape[1], 2))
    polygon[:n] = s.polygon
    if len(extra):
        polygon[n:, :3] = np.array(polygons).reshape(-1, 3, 2)
    n_corners = np.concatenate([s.n_corners, np.full(len(extra), 3)])
    n_corners[list(candidates)] = 0
    pad(polygon, n_corners)
    start = np.zeros(n + len(extra), np.int64)
    count = np.zeros(n + len(extra), np.int64)
    flat = []
    for covered, options in candidates.items():
        start[covered], count[covered] = len(flat), len(options)
        flat.extend(options.tolist())
    return Surfaces(normal=grow(s.normal), offset=grow(s.offset), origin=grow(s.origin), axis_u=grow(s.axis_u),
                    axis_v=grow(s.axis_v), polygon=polygon, n_corners=n_corners, shape_id=grow(s.shape_id),
                    row=grow(s.row), seen_side=grow(s.seen_side), face=grow(s.face), triangle_part=s.triangle_part,
                    triangle_base=s.triangle_base, split_start=start, split_count=count,
                    split_parts=np.array(flat, np.int64), body=None if s.body is None else grow(s.body))


@dataclass(frozen=True)
class Pieces:
    """The pieces a batch of regions cuts from the patches (float64, face coordinates).

    A *whole* piece is its patch (no polygon stored); a *border* piece is the patch clipped to
    its region, stored in ``polygon`` / ``count`` at row ``border[k]``.

    Attributes
    ----------
    region : int64 [n]
        The region each piece belongs to (its row in the batch of regions).
    cell : int64 [n, 2]
        The patch ``(i, j)``.
    whole : bool [n]
        The patch lies wholly inside the region (the piece is the patch).
    border : int64 [n]
        Row of a border piece's polygon, -1 for whole pieces.
    polygon : float64 [b, V, 2]
        The border pieces, counter-clockwise, padded with their last corner.
    count : int64 [b]
        Their corners.
    patch : float
        The patch size [m].
    """

    region: np.ndarray
    cell: np.ndarray
    whole: np.ndarray
    border: np.ndarray
    polygon: np.ndarray
    count: np.ndarray
    patch: float

    def __len__(self) -> int:
        return len(self.region)

    def select(self, keep) -> "Pieces":
        """The pieces ``keep`` (an index array or a boolean mask), their border polygons compacted."""
        keep = np.flatnonzero(keep) if np.asarray(keep).dtype == bool else np.asarray(keep, np.int64)
        border = self.border[keep]
        is_border = border >= 0
        rows = border[is_border]
        new = np.cumsum(is_border) - 1
        new[~is_border] = -1
        return Pieces(self.region[keep], np.take(self.cell, keep, axis=0), self.whole[keep], new,
                      np.take(self.polygon, rows, axis=0), self.count[rows], self.patch)

    def simplified(self) -> "Pieces":
        """The same pieces, each border polygon without its collinear and repeated corners
        (:func:`~sarmitsuba.tracing.mesh.polygons.drop_collinear`)."""
        if len(self.count) == 0:
            return self
        poly, count = drop_collinear(self.polygon, self.count, REPEAT_DISTANCE * max(self.patch, 1.0))
        return dataclasses.replace(self, polygon=poly, count=count)

    def polygons(self, width: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Every piece's polygon: float64 [n, V, 2] and corner counts int64 [n] (whole pieces:
        their patch, corners bottom-left, bottom-right, top-right, top-left)."""
        width = max(self.polygon.shape[1] if len(self.count) else 4, 4) if width is None else width
        poly = np.zeros((len(self), width, 2))
        count = np.full(len(self), 4, np.int64)
        poly[:, :4] = (self.cell[:, None, :] + UNIT_SQUARE[None]) * self.patch
        b = np.flatnonzero(~self.whole)
        if len(b):
            take = min(width, self.polygon.shape[1])
            poly[b, :take] = self.polygon[self.border[b], :take]
            count[b] = self.count[self.border[b]]
        return pad(poly, count), count

    def geometry(self, moments=moments):
        """Area [m^2], centroid (face coordinates, m) float64 [n, 2], second moments about the
        centroid float64 [n, 3] (``Ixx, Ixy, Iyy``, m^4) and bounding-box diagonal [m] of every
        piece (whole pieces in closed form; the border pieces by ``moments``, with the signature of
        :func:`~sarmitsuba.tracing.mesh.polygons.moments`, its default)."""
        n, p = len(self), self.patch
        area = np.full(n, p * p)
        centroid = (self.cell + 0.5) * p
        second = np.tile([p ** 4 / 12.0, 0.0, p ** 4 / 12.0], (n, 1))
        diagonal = np.full(n, p * math.sqrt(2.0))
        b = np.flatnonzero(~self.whole)
        if len(b):
            rows = self.border[b]
            if len(rows) == len(self.count) and np.array_equal(rows, np.arange(len(rows))):
                poly, count = self.polygon, self.count       # (as :meth:`select` and pieces_of leave them)
            else:
                poly, count = np.take(self.polygon, rows, axis=0), self.count[rows]
            area[b], centroid[b], second[b], diagonal[b] = moments(poly, count)
        return area, centroid, second, diagonal

    def geometry_of(self, keep, moments=moments):
        """:meth:`geometry` of the pieces ``keep`` (an index array or a boolean mask): the values
        of ``self.select(keep).geometry()``, each piece's computed once per :class:`Pieces` object
        (callers ask for overlapping sets of the same pieces: the carried power, the lanes);
        ``moments`` as in :meth:`geometry`."""
        keep = np.flatnonzero(keep) if np.asarray(keep).dtype == bool else np.asarray(keep, np.int64)
        cache = self.__dict__.get("_geometry_cache")
        if cache is None:
            n = len(self)
            cache = (np.zeros(n, bool), np.zeros(n), np.zeros((n, 2)), np.zeros((n, 3)), np.zeros(n))
            object.__setattr__(self, "_geometry_cache", cache)
        done, values = cache[0], cache[1:]
        missing = keep[~done[keep]]
        if len(missing):
            missing = np.flatnonzero(np.bincount(missing, minlength=len(self)))     # distinct, ascending
            for table, value in zip(values, self.select(missing).geometry(moments)):
                table[missing] = value
            done[missing] = True
        return tuple(np.take(table, keep, axis=0) for table in values)

    def edges(self, rows: np.ndarray | None = None):
        """The boundary segments of pieces ``rows`` (all by default), counter-clockwise:
        ``(piece int64 [s], start float64 [s, 2], end float64 [s, 2], side int64 [s])`` with
        ``side`` 0..3 where the segment runs along its patch's bottom, right, top or left line
        (shared with the neighbouring patch's piece of the same region) and -1 elsewhere."""
        rows = np.arange(len(self)) if rows is None else np.asarray(rows, np.int64)
        is_whole = np.take(self.whole, rows)
        whole = rows[is_whole]
        square = (np.take(self.cell, whole, axis=0)[:, None, :] + UNIT_SQUARE[None]) * self.patch
        w_piece = np.repeat(whole, 4)
        w_start = square.reshape(-1, 2)
        w_end = np.take(square, [1, 2, 3, 0], axis=1).reshape(-1, 2)
        w_side = np.tile(np.arange(4), len(whole))
        border = rows[~is_whole]
        at = np.take(self.border, border)
        poly, count = np.take(self.polygon, at, axis=0), np.take(self.count, at)
        width = poly.shape[1]
        # each corner's step to the next (cyclically over the padded slots, as np.roll), by row-wise
        # flat gathers with np.take (fancy [rows, cols] gathers are several times slower)
        step = np.empty_like(poly)
        if width:
            np.subtract(poly[:, 1:], poly[:, :-1], out=step[:, :-1])
            np.subtract(poly[:, 0], poly[:, -1], out=step[:, -1])
        keep = np.arange(width)[None, :] < count[:, None]
        keep &= step[..., 0] * step[..., 0] + step[..., 1] * step[..., 1] > 0      # (a length > 0)
        flat = np.flatnonzero(keep)
        b_rows, b_cols = np.divmod(flat, max(width, 1))
        corners = poly.reshape(-1, 2)
        b_start = np.take(corners, flat, axis=0)
        b_end = np.take(corners, flat - b_cols + (b_cols + 1) % max(width, 1), axis=0)
        b_border = np.take(border, b_rows)
        b_side = _grid_side(np.take(self.cell, b_border, axis=0), b_start, b_end, self.patch)
        return (np.concatenate([w_piece, b_border]), np.concatenate([w_start, b_start]),
                np.concatenate([w_end, b_end]), np.concatenate([w_side, b_side]))


#: A segment's ends within this fraction of the patch size of one of its patch's lines lie on it.
ON_GRID_LINE = 1e-9


def _grid_side(cell: np.ndarray, start: np.ndarray, end: np.ndarray, patch: float) -> np.ndarray:
    """Which line of its patch (0 bottom, 1 right, 2 top, 3 left) each segment runs along, -1 none."""
    lo, hi = cell * patch, (cell + 1) * patch
    tol = ON_GRID_LINE * patch
    on = [(np.abs(start[:, 1] - lo[:, 1]) <= tol) & (np.abs(end[:, 1] - lo[:, 1]) <= tol),
          (np.abs(start[:, 0] - hi[:, 0]) <= tol) & (np.abs(end[:, 0] - hi[:, 0]) <= tol),
          (np.abs(start[:, 1] - hi[:, 1]) <= tol) & (np.abs(end[:, 1] - hi[:, 1]) <= tol),
          (np.abs(start[:, 0] - lo[:, 0]) <= tol) & (np.abs(end[:, 0] - lo[:, 0]) <= tol)]
    side = np.full(len(cell), -1, np.int64)
    for k in (3, 2, 1, 0):
        side = np.where(on[k], k, side)
    return side


#: The unit square's corners in the order of a whole piece's polygon.
UNIT_SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def moved_surfaces(scene, table, vertices: dict, separate=(), grid_offset=None):
    """The :class:`~sarmitsuba.tracing.mesh.patches.Surfaces` of ``scene`` with shape ``k``'s vertices
    replaced by ``vertices[k]`` (float64 [n_v, 3], m), its frame (C), (M1) moved with them, and the
    material table with that frame: ``(surfaces, table)``. The triangles of the shapes
    ``separate`` are faces of their own (:func:`~sarmitsuba.tracing.mesh.facets.mesh_parts`); the
    patch grid of every smooth shape is shifted by ``grid_offset`` [3] (m, in the shape's frame),
    its rough shapes' grid staying on their scatterer lattice."""
    meshes = scene_meshes(scene)
    origin, axes = table.shape_origin.copy(), table.shape_axes.copy()
    shapes = list(scene.shapes())
    for k, v in vertices.items():
        meshes[k] = (np.asarray(v, np.float64), meshes[k][1])
        shape_id = int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shapes[k]))[0])
        origin[shape_id], axes[shape_id] = shape_frame(v)
    table = dataclasses.replace(table, shape_origin=origin, shape_axes=axes)
    grid = origin
    if grid_offset is not None:
        smooth = table.clutter[table.row_of_shape, 0] == 0 if table.clutter is not None else \
            np.ones(len(origin), bool)
        grid = origin + np.where(smooth[:, None], np.einsum("sij,i->sj", axes, np.asarray(grid_offset, float)), 0.0)
    parts = mesh_parts(meshes, separate=separate)
    return surfaces_of(scene, dataclasses.replace(table, shape_origin=grid), parts), table
