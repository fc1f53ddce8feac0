"""Coplanar faces of two shapes that overlap on the same side: the smaller covers the larger
(docs/physics.md (M1)).

An object placed on a surface with a face in the surface's plane (a corner reflector on a roof, a
slab laid on the ground) leaves two faces in one place. A ray tracer meets one of them at
random; physical optics over both would count that area twice. Here the smaller part (the
object, by area; the later shape where they are equal) covers the other: the covered part is
replaced by convex pieces of itself less the covers (triangles of shapely's difference,
triangulated by mapbox-earcut through trimesh), and a ray that meets the covered part's triangles
is given the part that lies at its hit point (:func:`locate`). Faces that overlap back to back
(a box's bottom on the ground) need nothing: the box hides them.
"""
from __future__ import annotations

import numpy as np

from ...core.arrays import unique_rows

__all__ = ["covered_parts", "split_covered", "locate", "COPLANAR_ANGLE", "COPLANAR_DISTANCE"]

#: Two parts lie in one plane where their normals are within this [rad] and their planes this far
#: [m] apart.
COPLANAR_ANGLE = 1e-4
COPLANAR_DISTANCE = 1e-4


def covered_parts(normal: np.ndarray, offset: np.ndarray, corners: list, shape: np.ndarray, area: np.ndarray):
    """Pairs ``(covered, cover)`` int64 [k, 2] of same-facing coplanar parts of different shapes
    whose polygons overlap (``corners``: each part's world corners [v, 3])."""
    import shapely
    key = np.round(np.column_stack([normal / COPLANAR_ANGLE, offset / COPLANAR_DISTANCE])).astype(np.int64)
    _, group = unique_rows(key, return_inverse=True)
    pairs = []
    group = np.asarray(group).ravel()
    order = np.argsort(group, kind="stable")             # each group's members, ascending, in one pass
    bounds = np.flatnonzero(np.diff(group[order])) + 1
    for members in np.split(order, bounds):
        if len(members) < 2 or len(np.unique(shape[members])) < 2:
            continue
        u = corners[members[0]][1] - corners[members[0]][0]
        u /= np.linalg.norm(u)
        v = np.cross(normal[members[0]], u)
        flat = [shapely.Polygon(np.c_[corners[m] @ u, corners[m] @ v]) for m in members]
        # only the pairs whose boxes meet (an STRtree): a plane of many parts (a facade's row of
        # window panes) would otherwise cost every pair
        # pairs (in the order of a loop over i < j, as before)
        left, right = shapely.STRtree(flat).query(flat, predicate="intersects")
        for i, j in sorted((i, j) for i, j in zip(left.tolist(), right.tolist()) if j > i):
            a, b = members[i], members[j]
            if shape[a] == shape[b] or flat[i].intersection(flat[j]).area <= 1e-9:
                continue
            small, large = (a, b) if (area[a], a) < (area[b], b) else (b, a)
            pairs.append((large, small))
    return np.array(pairs, np.int64).reshape(-1, 2)


def split_covered(polygon2: np.ndarray, count: int, covers2: list) -> list:
    """The convex pieces (triangles, face coordinates) of a covered part's polygon ``polygon2`` less
    its covers' polygons ``covers2`` (each [v, 2], in the same coordinates)."""
    import shapely
    import trimesh
    rest = shapely.Polygon(polygon2[:count]).difference(shapely.unary_union([shapely.Polygon(c) for c in covers2]))
    triangles = []
    for poly in getattr(rest, "geoms", [rest]):
        if poly.is_empty or poly.area <= 1e-12 or poly.geom_type != "Polygon":
            continue
        vertices, faces = trimesh.creation.triangulate_polygon(poly, engine="earcut")
        for f in faces:
            tri = vertices[f]
            (ax, ay), (bx, by) = tri[1] - tri[0], tri[2] - tri[0]
            twice_area = ax * by - ay * bx
            if twice_area < 0:
                tri = tri[::-1]
            if abs(twice_area) > 1e-12:
                triangles.append(tri)
    return triangles


def locate(points2: np.ndarray, candidates: list, polygons: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """For each point [m, 2] (face coordinates), the first of its ``candidates`` (a list of part
    index arrays, none empty) whose polygon (``polygons``/``counts``, face coordinates of the same
    face) holds it; the nearest candidate where none does (a point on an edge, within rounding).
    Returns int64 [m].

    A point's distance outside a polygon is ``max_e -side_e / max_e |e|`` over its edges ``e``
    (``side_e`` the cross product of the edge and the point from its start); a part with fewer
    than 3 corners (wholly covered) is never chosen, but stands where it is its point's first
    candidate and nothing else is near (no finite distance)."""
    m = len(points2)
    out = np.zeros(m, np.int64)
    if m == 0:
        return out
    size = np.fromiter((len(c) for c in candidates), np.int64, count=m)
    part = np.concatenate(candidates).astype(np.int64)
    which = np.repeat(np.arange(m), size)
    count = np.asarray(counts)[part]
    corner = polygons[part]                                             # [k, w, 2]
    width = corner.shape[1]
    slots = np.arange(width)[None, :] < count[:, None]
    following = np.take_along_axis(corner, ((np.arange(width)[None, :] + 1) % np.maximum(count, 1)[:, None])[..., None],
                                   axis=1)
    edge = following - corner
    point = points2[which][:, None, :]
    side = edge[..., 0] * (point[..., 1] - corner[..., 1]) - edge[..., 1] * (point[..., 0] - corner[..., 0])
    length = np.sqrt(edge[..., 0] * edge[..., 0] + edge[..., 1] * edge[..., 1])
    worst = -np.where(slots, side, np.inf).min(axis=1, initial=np.inf) \
        / np.maximum(np.where(slots, length, 0.0).max(axis=1, initial=0.0), 1e-300)
    usable = count >= 3
    first = np.cumsum(size) - size
    k = np.arange(len(part))
    # the first candidate that holds the point
    holds = np.full(m, len(part))
    np.minimum.at(holds, which[usable & (worst <= 0)], k[usable & (worst <= 0)])
    # else the nearest (the first of equals); else the first candidate
    distance = np.where(usable & ~np.isnan(worst), worst, np.inf)
    order = np.lexsort((k, distance, which))
    nearest = order[first]
    nearest = np.where(np.isfinite(distance[nearest]), nearest, first)
    return part[np.where(holds < len(part), holds, nearest)]


def locate_reference(points2: np.ndarray, candidates: list, polygons: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """:func:`locate`, point by point (the readable reference its test compares against)."""
    out = np.zeros(len(points2), np.int64)
    for k, (point, options) in enumerate(zip(points2, candidates)):
        best, best_distance = options[0], np.inf
        for part in options:
            if counts[part] < 3:                # a part wholly covered: no polygon of its own
                continue
            corner = polygons[part, :counts[part]]
            edge = np.roll(corner, -1, axis=0) - corner
            side = edge[:, 0] * (point[1] - corner[:, 1]) - edge[:, 1] * (point[0] - corner[:, 0])
            worst = float(-side.min() / max(np.linalg.norm(edge, axis=1).max(), 1e-300))
            if worst <= 0:
                best = part
                break
            if worst < best_distance:
                best, best_distance = part, worst
        out[k] = best
    return out
