"""Where a border edge lies on another part: the junction test of the wedges (docs/physics.md
(E1), :func:`sarmitsuba.tracing.integration.edges.find_wedges`).

An edge whose midpoint lies within :data:`JUNCTION` of another part's plane and inside its
polygon (a wall's foot on the ground) is not a free edge; a shared edge that lies strictly
inside a third part is a junction and does not diffract. The candidates are the parts whose
bounding sphere holds the point, found from k-d trees (``scipy.spatial.cKDTree``) as arrays.

=========================  ===============================================================
:func:`part_spheres`       each part's bounding sphere (centre, radius), once per surfaces
:func:`points_in_spheres`  the sphere-point pairs, block by block
:func:`on_other_part`      the test itself
=========================  ===============================================================
"""
from __future__ import annotations

import numpy as np

from ..mesh.patches import Surfaces

__all__ = ["JUNCTION", "SPHERE_BLOCK", "on_other_part", "part_spheres", "points_in_spheres"]

#: An edge that lies within this [m] of another part's plane and inside its polygon is a junction
#: (a wall's foot on the ground): it does not diffract, (E1).
JUNCTION = 1e-3


def part_spheres(s: Surfaces):
    """The parts with corners (int64 [r]), and a sphere about each holding its polygon and
    :data:`JUNCTION` more: centres float64 [r, 3] (the mean corner) and radii float64 [r]."""
    real = np.flatnonzero(s.n_corners > 0)
    corners = np.take(s.world_polygon, real, axis=0)
    slots = np.arange(corners.shape[1])[None, :] < s.n_corners[real][:, None]
    centre = np.sum(corners * slots[..., None], axis=1) / s.n_corners[real][:, None]
    radius = np.max(np.where(slots, np.linalg.norm(corners - centre[:, None], axis=2), 0.0), axis=1) + JUNCTION
    return real, centre, radius


#: Spheres per k-d tree query of :func:`points_in_spheres` (bounds the pairs held at once: a city's
#: ground triangles meet about 16 edge midpoints each).
SPHERE_BLOCK = 1 << 17


def points_in_spheres(centre: np.ndarray, radius: np.ndarray, point: np.ndarray):
    """Pairs ``(sphere, point)`` int64 [k] each, of the spheres ``centre`` [r, 3], ``radius`` [r]
    and the points [q, 3] inside them (distance <= radius), block by block (a generator). The
    spheres go in classes of radius within a factor 2, each class in blocks of
    :data:`SPHERE_BLOCK`, each block one ``sparse_distance_matrix`` of two k-d trees at its largest
    radius (the pairs come back as arrays, not as a Python list per sphere)."""
    from scipy.spatial import cKDTree
    points = cKDTree(point)
    size = np.ceil(np.log2(np.maximum(radius, 1e-6))).astype(np.int64)
    for k in np.unique(size):
        members = np.flatnonzero(size == k)
        for rows in np.array_split(members, -(-len(members) // SPHERE_BLOCK)):
            near = cKDTree(centre[rows]).sparse_distance_matrix(points, float(np.max(radius[rows])),
                                                                output_type="ndarray")
            within = near["v"] <= radius[rows[near["i"]]]
            yield rows[near["i"][within]], near["j"][within].astype(np.int64)


def on_other_part(s: Surfaces, part: np.ndarray, point: np.ndarray, strict: bool = False,
                   spheres=None) -> np.ndarray:
    """bool [q]: ``point`` [q, 3] lies within :data:`JUNCTION` of another part's plane and inside
    its polygon or on its border (a wall's foot on the ground, eq. (E1)); ``strict``: inside, at
    least :data:`JUNCTION` from its border (which leaves out the faces an edge runs along). The
    candidates are the parts whose bounding sphere holds the point (``spheres``:
    :func:`part_spheres` of ``s``, computed here if not given)."""
    out = np.zeros(len(part), bool)
    real, centre, radius = part_spheres(s) if spheres is None else spheres
    if len(point) == 0 or len(real) == 0:
        return out
    found = [(np.zeros(0, np.int64), np.zeros(0, np.int64))]
    for sphere, qi in points_in_spheres(centre, radius, point):     # the pairs near the part's plane
        cand = np.take(real, sphere)
        keep = (cand != part[qi]) & (np.abs(np.einsum("ei,ei->e", s.normal[cand], point[qi]) - s.offset[cand])
                                     < JUNCTION)
        found.append((qi[keep], cand[keep]))
    qi, cand = (np.concatenate(column) for column in zip(*found))
    if len(qi) == 0:
        return out
    # in blocks of candidates of similar corner counts, each padded to its own widest: a few
    # parts of many corners (a city's ground) would otherwise widen every row
    order = np.argsort(s.n_corners[cand], kind="stable")
    for block in np.array_split(order, -(-len(order) // _INSIDE_BLOCK)):
        hit = _inside(s, cand[block], point[qi[block]], strict)
        out[qi[block][hit]] = True
    return out


#: Candidate (point, part) pairs tested at once by :func:`on_other_part` (memory: about
#: 100 B per pair and polygon corner).
_INSIDE_BLOCK = 1 << 16


def _inside(s: Surfaces, cand: np.ndarray, point: np.ndarray, strict: bool) -> np.ndarray:
    """bool [k]: each ``point`` [k, 3] (on part ``cand``'s plane) lies inside the part's polygon
    or on its border (``strict``: at least :data:`JUNCTION` inside)."""
    xy = s.to_face(cand, point)
    corners = s.n_corners[cand]
    poly = s.polygon[cand, :int(corners.max())]          # the slots some candidate uses
    valid = np.arange(poly.shape[1])[None, :] < corners[:, None]
    nxt = np.where((np.arange(poly.shape[1])[None, :] + 1 < corners[:, None])[..., None],
                   np.roll(poly, -1, axis=1), poly[:, :1])          # corner i + 1, the first after the last
    cross = (nxt[..., 0] - poly[..., 0]) * (xy[:, None, 1] - poly[..., 1]) \
        - (nxt[..., 1] - poly[..., 1]) * (xy[:, None, 0] - poly[..., 0])
    length = np.linalg.norm(nxt - poly, axis=2)
    # inside, or on the polygon's border (a wall on the ground's rim) unless strict
    margin = (JUNCTION if strict else -JUNCTION) * np.maximum(length, 1e-30)
    return np.all(~valid | (cross >= margin), axis=1)
