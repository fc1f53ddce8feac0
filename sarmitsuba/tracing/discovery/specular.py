"""The next bounce order's chains, found by specular rays from the lit pieces of the last one
(docs/physics.md (M6)).

From points of a fixed grid in each face's frame (:func:`grid_points`) on every transmit-lit or
mixed piece, the wave arriving from the sub-aperture's reference position through the piece's
chain is reflected specularly and cast to the first part it meets (:func:`discover`). Each
distinct (chain, part met) extends its chain by one mirror, and so does every other convex part
of the face met: a face met is met whole, and the next order's regions (the image method, (M3))
decide what each part receives. Rays find *which* parts a path runs through; the chains' exact
regions, not the rays, decide where.
"""
from __future__ import annotations

import numpy as np

from ...core.arrays import row_norm, unique_pairs
from ..mesh.patches import Surfaces
from ..mesh.polygons import edge_lines, inside
from ..visibility.rays import lift
from .chains import Chains, unfold

__all__ = ["DISCOVERY_POINTS", "MAX_DISCOVERY_SUBDIVISION", "arriving", "arriving_views", "discover", "rays_beyond",
           "discovery_subdivision", "grid_points"]

#: Discovery rays start on a grid fixed in each face's frame, at least this many points across
#: the shape's bounding box (and at least one per patch): a corner reflector a patch wide still
#: sends rays from every face into every other (docs/physics.md (M6)).
DISCOVERY_POINTS = 16
#: At most this many discovery points per patch edge.
MAX_DISCOVERY_SUBDIVISION = 32


def discover(surfaces: Surfaces, lit, reference: np.ndarray, rays, subdivision: np.ndarray, patch: float,
             depth: int) -> Chains:
    """The next bounce order's chains of a bounce order's lit pieces, eq. (M6).

    Parameters
    ----------
    surfaces : Surfaces
    lit : sarmitsuba.tracing.visibility.lit_pieces.LitPieces
        The order's chains and pieces, with which are transmit-lit or mixed.
    reference : float64 [n_sub, 3]
        Each sub-aperture's reference position [m].
    rays : sarmitsuba.tracing.visibility.rays.Rays
        Casts the reflected rays (``first_hit``) and knows each face's parts (``face_partners``).
    subdivision : int64 [n_parts]
        Discovery points per patch edge (:func:`discovery_subdivision`).
    patch : float
        Patch size [m].
    depth : int
        The chains' capacity (``max_depth``).

    Returns
    -------
    Chains
        One chain per distinct (chain, part met) and per other part of that part's face, one order
        higher than its parent, in the parent's sub-aperture; none when no ray meets another part.
    """
    chains = lit.chains
    chain, hit, found = _reflected(surfaces, lit, reference, rays, subdivision, patch)
    pairs = unique_pairs(chain[found], hit[found])
    # a face met is met whole: its other convex parts join (their regions decide what they get)
    start, partners = rays.face_partners
    size = start[pairs[:, 1] + 1] - start[pairs[:, 1]]
    local = np.arange(int(size.sum())) - np.repeat(np.cumsum(size) - size, size)
    extra = np.stack([np.repeat(pairs[:, 0], size), partners[np.repeat(start[pairs[:, 1]], size) + local]], axis=1)
    pairs = np.concatenate([pairs, extra])
    pairs = unique_pairs(pairs[:, 0], pairs[:, 1])
    pairs = pairs[pairs[:, 1] != chains.last[pairs[:, 0]]]
    if len(pairs) == 0:
        return unfold(surfaces, np.zeros((0, depth), np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64))
    parent, new = pairs[:, 0], pairs[:, 1]
    parts = chains.parts[parent].copy()
    order = chains.order[parent] + 1
    parts[np.arange(len(parent)), order] = new
    return unfold(surfaces, parts, order, chains.sub[parent])


def _reflected(surfaces: Surfaces, lit, reference: np.ndarray, rays, subdivision: np.ndarray, patch: float):
    """The specular rays of ``lit``'s transmit-lit and mixed pieces (their discovery points): each
    ray's chain (int64 [m]), the part it first meets (int64 [m], -1 for none), and whether that is
    another part (bool [m])."""
    chains, pieces = lit.chains, lit.pieces
    keep = np.flatnonzero(lit.transmit | lit.mixed)
    owner, points2 = grid_points(pieces.select(keep), subdivision[chains.last[pieces.region[keep]]], patch)
    chain = np.take(pieces.region[keep], owner)
    part = np.take(chains.last, chain)
    points = surfaces.to_world(part, points2)
    antenna = np.take(reference, np.take(chains.sub, chain), axis=0)
    d = arriving(chains, chain, points, antenna)
    normal = np.take(surfaces.normal, part, axis=0)
    reflected = d - 2.0 * np.einsum("mi,mi->m", d, normal)[:, None] * normal
    origin = lift(points, normal, points - d)
    hit, _ = rays.first_hit(origin, direction=reflected)
    return chain, hit, (hit >= 0) & (hit != part)


def rays_beyond(surfaces: Surfaces, lit, reference: np.ndarray, rays, subdivision: np.ndarray, patch: float) -> int:
    """How many of the deepest traced order's specular rays (those :func:`discover` would cast
    from ``lit`` for the next order) meet another part: 0 when nothing lies beyond that order, so
    that a deep order holding most of the energy (a trihedral's third) is its corner's own, not a
    sign of orders left out (docs/physics.md (M6))."""
    if len(lit.chains) == 0:
        return 0
    return int(np.count_nonzero(_reflected(surfaces, lit, reference, rays, subdivision, patch)[2]))


def discovery_subdivision(surfaces: Surfaces, patch: float) -> np.ndarray:
    """int64 [n_parts]: discovery points per patch edge on each part, ``ceil(P / (D /
    DISCOVERY_POINTS))`` for the bounding-box diagonal ``D`` of its object (its connected body in
    its shape), 1 to :data:`MAX_DISCOVERY_SUBDIVISION`."""
    corners = surfaces.to_world(np.arange(surfaces.n_parts), surfaces.polygon)
    groups = surfaces.body if surfaces.body is not None else surfaces.shape_id
    shape = np.unique(groups, return_inverse=True)[1]
    n = int(shape.max(initial=-1)) + 1
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    np.minimum.at(lo, shape, corners.min(axis=1))
    np.maximum.at(hi, shape, corners.max(axis=1))
    size = np.linalg.norm(hi - lo, axis=1)[shape]
    return np.clip(np.ceil(patch * DISCOVERY_POINTS / np.maximum(size, 1e-9)), 1, MAX_DISCOVERY_SUBDIVISION).astype(np.int64)


def grid_points(pieces, subdivision: np.ndarray, patch: float):
    """Points of the faces' discovery grids inside each piece: the centres of the ``m x m``
    sub-cells of its patch (``m = subdivision``, per piece) that the piece holds; a piece that
    holds none gives its centroid. Returns (piece index int64 [p], face coordinates [p, 2])."""
    count = subdivision ** 2
    owner = np.repeat(np.arange(len(pieces)), count)
    local = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    m = subdivision[owner]
    offset = np.stack([(local // m + 0.5) / m, (local % m + 0.5) / m], axis=1)
    points = (np.take(pieces.cell, owner, axis=0) + offset) * patch       # row gathers by np.take
    held = np.take(pieces.whole, owner)
    test = np.flatnonzero(~held)
    if len(test):
        lines = edge_lines(pieces.polygon, pieces.count)
        border = np.take(pieces.border, np.take(owner, test))
        held[test] = inside(np.take(points, test, axis=0)[:, None, :], np.take(lines, border, axis=0))[:, 0]
    kept = np.flatnonzero(held)
    owner, points = np.take(owner, kept), np.take(points, kept, axis=0)
    empty = np.flatnonzero(np.bincount(owner, minlength=len(pieces)) == 0)
    if len(empty):
        _, centroid, _, _ = pieces.select(empty).geometry()
        owner, points = np.concatenate([owner, empty]), np.concatenate([points, centroid])
    return owner, points


def arriving(chains: Chains, chain: np.ndarray, points: np.ndarray, antenna: np.ndarray) -> np.ndarray:
    """The direction the wave from ``antenna`` arrives in at ``points`` on the chains' last parts:
    the unfolded path's direction folded back, ``lin_d^T (U_d(x) - A) / |U_d(x) - A|``."""
    return arriving_views(chains, chain, points, antenna[:, None, :])[0]


def arriving_views(chains: Chains, chain: np.ndarray, points: np.ndarray, views: np.ndarray) -> list:
    """:func:`arriving` from each of the antenna positions ``views`` [m, v, 3] (one list entry per
    view): the unfolded points and the maps gathered once for all views."""
    lin = np.take(chains.lin_last, chain, axis=0)
    y = np.einsum("mij,mj->mi", lin, points) + np.take(chains.shift_last, chain, axis=0)
    out = []
    for v in range(views.shape[1]):
        first = y - views[:, v]
        first /= row_norm(first)[:, None]
        out.append(np.einsum("mji,mj->mi", lin, first))
    return out
