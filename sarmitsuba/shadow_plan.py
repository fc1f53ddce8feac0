"""Shadows in the owned-region plan (docs/physics.md (T6)): the cells of a part that a part in
front hides (holes), which members and holes near them own pieces, and which occluders each
piece is cut by. Vectorised NumPy, called by :func:`sarmitsuba.owned_regions.plan`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .lattice_index import convex_depth, lattice_lines, matches, pair_key, split_triple_key, triple_key, unique_pairs

#: m: an occluder's corner this close to a part's plane lies in it (:func:`crosses`); walls
#: standing on a roof or the ground touch its plane, they do not cross it.
CROSSING_TOLERANCE = 1e-4

__all__ = ["CROSSING_TOLERANCE", "crosses", "Holes", "find_holes", "touching", "meets", "band_occluders", "hidden_run", "piece_occluders",
           "overlapping_occluders", "occluders_near", "overlapping_pairs", "in_front"]


def _views(part, sub, m, vertices, views, fp):
    """The ``part``s (int64 [n]) as sub-aperture ``sub``'s reference, first and last position see
    them, in lattice lines of tube size ``m`` (scalar or [n]): three float64 [n, k, 2]."""
    m = np.broadcast_to(np.asarray(m, float), (len(part),))[:, None]
    return [lattice_lines(vertices[part], views[sub, v][:, None], fp, 0.0, 0.0, m) for v in range(3)]


def _apart(points_a, points_b, axes):
    """Whether two point sets (float64 [n, k, 2], [n, l, 2]) are separated along one of ``axes``
    [n, a, 2] (separating axes: then their convex hulls do not meet). Returns bool [n]."""
    pa, pb = np.einsum("nkd,nad->nak", points_a, axes), np.einsum("nkd,nad->nak", points_b, axes)
    return ((pa.max(-1) < pb.min(-1)) | (pa.min(-1) > pb.max(-1))).any(1)


def _normals(poly):
    """The edge normals of polygons [n, k, 2] (unnormalised): float64 [n, k, 2]."""
    e = np.roll(poly, -1, axis=1) - poly
    return np.stack([-e[..., 1], e[..., 0]], -1)


def _around(keys, radius):
    """The cells within ``radius[g]`` (Chebyshev, in cells) of each cell ``keys`` (:func:`triple_key`,
    group ``g``): ``(row, offset, key)``, int64 each, the key's index, the offset's index (offsets
    ``(di, dj)`` in row-major order from ``(-r, -r)``) and the neighbour's key."""
    reach = int(radius.max()) if len(radius) else 0
    d = np.arange(-reach, reach + 1)
    di, dj = np.repeat(d, d.size), np.tile(d, d.size)
    g, i, j = split_triple_key(keys)
    row, offset = np.nonzero(np.maximum(np.abs(di), np.abs(dj))[None, :] <= radius[g][:, None])
    return row, offset, triple_key(g[row], i[row] + di[offset], j[row] + dj[offset])


def piece_occluders(holes, origin, n_members):
    """Each piece's occluders (``origin``: its member's place, or ``n_members`` plus its hole's):
    ``(piece, part)`` pairs, int64 [n_cuts] each."""
    key = np.concatenate([holes.member_cuts[0], n_members + holes.hole_cuts[0]])
    parts = np.concatenate([holes.member_cuts[1], holes.hole_cuts[1]])
    order = np.argsort(key, kind="stable")
    piece, pos = matches(key[order], origin)
    return piece, parts[order][pos]


@dataclass(frozen=True)
class Holes:
    """The cells a part in front hides between a group's members, near the members (T6).

    ``border``: bool [n_members], the members with a hole within ``radius``; ``cells``: int64
    [3, n_holes] ``(g, i, j)`` of the holes with a member within ``radius``, ``owner`` int64
    [n_holes] that member (its record integrates the hole's piece); ``member_cuts``,
    ``hole_cuts``: ``(member or hole, occluding part)`` pairs, the parts of the records in the holes
    within ``radius`` of each; ``occluded``: int64, the sorted keys (:func:`triple_key`) of every hole;
    ``named``: ``(group, part)``, every occluder found in a group, sorted."""

    border: np.ndarray
    cells: np.ndarray
    owner: np.ndarray
    member_cuts: tuple
    hole_cuts: tuple
    occluded: np.ndarray
    named: tuple


def find_holes(g, i, j, ok, lines, groups, radius, records) -> Holes:
    """Find the holes and their occluders (:class:`Holes`). ``g, i, j``: each record's group and
    cell (its own tube size); ``lines``: the ``(pairs, lo, hi)`` of the member columns (the
    part's first and last cell on each: a shadow may cut a column's end) and rows (the first and
    last member); ``groups``: each group's sub-aperture, part and tube size; ``radius``: per group, in cells
    (1 plus the parallax of the sub-aperture); ``records``: each record's sub-aperture, part and
    tube size (any record in a hole's cell, on another part, is an occluder)."""
    gsub, gpart, g_m = groups
    member = triple_key(g, i, j)
    order = np.argsort(member)
    members = member[order]
    gaps = [triple_key(*_gaps(pairs, lo, hi, ok, swap)) for (pairs, lo, hi), swap in zip(lines, (False, True))]
    cand = np.unique(np.concatenate(gaps))
    if members.size:
        cand = cand[members[np.minimum(np.searchsorted(members, cand), members.size - 1)] != cand]
    hg, hi, hj = split_triple_key(cand)
    sub_r, part_r, m_r = records
    pair_h, pair_p = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for m in np.unique(g_m[hg]):
        sel = np.flatnonzero(g_m[hg] == m)
        rkey = triple_key(sub_r, (i * m) // m_r, (j * m) // m_r)
        o = np.argsort(rkey)
        q, pos = matches(rkey[o], triple_key(gsub[hg[sel]], hi[sel], hj[sel]))
        p = part_r[o][pos]
        keep = p != gpart[hg[sel][q]]
        pair_h.append(sel[q][keep])
        pair_p.append(p[keep])
    pair_h, pair_p = unique_pairs(np.concatenate(pair_h), np.concatenate(pair_p))
    hole_keys = cand[pair_h]                     # sorted: the pairs are
    cand = np.unique(hole_keys)                  # a gap no part in front explains is no hole
    hg, hi, hj = split_triple_key(cand)
    n_holes = len(cand)
    # members within radius of a hole: their pieces are cut by the hole's occluders
    row, _, around = _around(hole_keys, radius)
    o = np.argsort(around, kind="stable")
    near = np.flatnonzero(ok[g])
    q, pos = matches(around[o], member[near])
    border = np.zeros(len(g), bool)
    border[near[q]] = True
    member_cuts = unique_pairs(near[q], pair_p[row[o][pos]])
    # each hole's owner: a member within radius, the first in the order of :func:`_around`'s offsets
    row, offset, around = _around(cand, radius)
    q, pos = matches(members, around)
    first = np.lexsort((pos, offset[q], row[q]))
    first = first[np.r_[True, row[q][first][1:] != row[q][first][:-1]]] if first.size else first
    owner = np.full(n_holes, -1)
    owner[row[q][first]] = order[pos[first]]
    # holes within radius of a hole: their pieces are cut by that hole's occluders
    q, pos = matches(hole_keys, around)
    h, p = unique_pairs(row[q], pair_p[pos])
    keep = owner >= 0
    renumber = np.cumsum(keep) - 1
    named = unique_pairs(np.concatenate([g[member_cuts[0]], hg[h]]), np.concatenate([member_cuts[1], p]))
    return Holes(border, np.stack([hg, hi, hj])[:, keep], owner[keep], member_cuts,
                 (renumber[h][keep[h]], p[keep[h]]), cand, named)


def crosses(part, other, vertices, tolerance: float = CROSSING_TOLERANCE):
    """Whether ``other``'s corners lie on both sides of ``part``'s plane, each farther than
    ``tolerance`` [m] (int64 [n] parts each; their corners ``vertices``): then only its side in
    front hides the part (T6). Returns bool [n]."""
    normal, point = _plane(part, vertices)
    normal = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    side = np.einsum("nd,nkd->nk", normal, vertices[other] - point[:, None])
    return (side.max(1) > tolerance) & (side.min(1) < -tolerance)


def _plane(part, vertices):
    """The planes of ``part`` (int64 [n]): Newell's normal (unnormalised) and a corner, float64
    [n, 3] each."""
    v = vertices[part]
    return np.cross(v, np.roll(v, -1, axis=1)).sum(1), v[:, 0]


def touching(holes: Holes, members, vertices, views, fp, groups) -> Holes:
    """Keep the occluders whose projection meets the member's or hole's cell in some view of the
    sub-aperture (:func:`meets`; the pieces beyond a cell get theirs from :func:`band_occluders`),
    and the holes no one occluder covers in every view; the border members are those with an
    occluder left. The projections are tested as the convex hull of the occluder's corners
    in the reference, first and last view (conservative where the corners move along lines
    between them), by separating axes: the lattice's two and the occluder's edge normals. An
    occluder that crosses the hole's part (:func:`crosses`) hides it only with its side in front:
    it covers no hole. ``groups``: each group's sub-aperture, part and tube size."""
    gsub, gpart, g_m = groups
    g, i, j = members
    hg, hi, hj = holes.cells
    kept = []
    for (who, part), (cg, ci, cj) in ((holes.member_cuts, (g, i, j)), (holes.hole_cuts, (hg, hi, hj))):
        cg, ci, cj = cg[who], ci[who].astype(float), cj[who].astype(float)
        meet, covered = meets(np.stack([ci, ci + 1, cj, cj + 1], 1), part, gsub[cg], g_m[cg], vertices, views, fp)
        kept.append((who, part, meet, covered & ~crosses(gpart[cg], part, vertices)))
    (mw, mp, m_meets, _), (hw, hp, h_meets, h_covered) = kept
    live = np.ones(hg.size, bool)
    live[hw[h_covered]] = False
    h_keep = h_meets & live[hw]
    renumber = np.cumsum(live) - 1
    border = np.zeros(len(g), bool)
    border[mw[m_meets]] = True
    return Holes(border, holes.cells[:, live], holes.owner[live], (mw[m_meets], mp[m_meets]),
                 (renumber[hw[h_keep]], hp[h_keep]), holes.occluded, holes.named)


def meets(rect, part, sub, m, vertices, views, fp):
    """Whether the projection of ``part`` (int64 [n]) from sub-aperture ``sub``'s reference, first
    and last position meets the rectangle ``rect`` (float64 [n, 4], ``x0, x1, y0, y1`` in lattice
    lines of tube size ``m``) in some view, and whether it covers it in every one. Tested on the
    convex hull of the corners in the three views (conservative where the corners move along
    lines between them) by separating axes: the lattice's two and the part's edge normals.
    Returns bool [n] twice."""
    polys = _views(part, sub, m, vertices, views, fp)
    x0, x1, y0, y1 = rect.T
    corners = np.stack([np.stack([x0, y0], 1), np.stack([x1, y0], 1), np.stack([x1, y1], 1), np.stack([x0, y1], 1)], 1)
    axes = np.concatenate([np.broadcast_to(np.eye(2), (len(part), 2, 2)), _normals(polys[0])], 1)
    covered = np.all([(convex_depth(poly, corners) > 1e-9).all(1) for poly in polys], axis=0)
    return ~_apart(np.concatenate(polys, axis=1), corners, axes), covered


def band_occluders(pieces, group_pairs, box, groups, geometry):
    """Occluders of the pieces that reach beyond their member's cell (the column extensions and row
    bands of the ends at the part's edge): every part named as an occluder anywhere in the
    piece's group whose projection meets the piece (:func:`meets`, the piece clamped to the part's
    box in the sub-aperture's views). ``pieces``: ``(index, group, bounds)`` of those pieces;
    ``group_pairs``: ``(group, part)``, sorted; ``box``: float64 [n_groups, 4]. Returns ``(piece,
    part)`` int64 [n] twice."""
    index, group, bounds = pieces
    gsub, g_m = groups
    q, pos = matches(group_pairs[0], group)
    lo, hi = (np.repeat(box[group[q]][:, side::2], 2, axis=1) for side in (0, 1))
    rect = np.clip(bounds[q], lo, hi)
    part = group_pairs[1][pos]
    meet, _ = meets(rect, part, gsub[group[q]], g_m[group[q]], *geometry)
    return index[q][meet], part[meet]


def _gaps(pairs, lo, hi, ok, swap):
    """The cells ``lo`` to ``hi`` of each member column (or row, ``swap``) of the groups ``ok``,
    members included: ``(g, i, j)``."""
    count = np.where(ok[pairs[:, 0]], hi - lo + 1, 0)
    at = np.repeat(np.arange(len(pairs)), count)
    other = lo[at] + np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    return (pairs[at, 0], other, pairs[at, 1]) if swap else (pairs[at, 0], pairs[at, 1], other)


def hidden_run(pairs, lo, hi, occluded):
    """Per row ``pairs`` [n, 2] (group, row): whether its cells ``lo..hi`` (columns) are all holes
    (``occluded``, sorted :func:`triple_key` keys); False where the run is empty."""
    count = np.maximum(hi - lo + 1, 0)
    at = np.repeat(np.arange(len(pairs)), count)
    x = lo[at] + np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    hidden = np.isin(triple_key(pairs[at, 0], x, pairs[at, 1]), occluded)
    return (count > 0) & (np.bincount(at, weights=hidden, minlength=len(pairs)) == count)


def in_front(part, other, sub, vertices, views, fp):
    """Whether ``other`` lies in front of ``part`` (int64 [n] each) where their projections from
    the sub-aperture's reference, first and last position overlap: at some corner of one inside
    the other, the ray from the antenna meets ``other``'s plane first. Planar convex parts that do
    not cross keep one order over their overlap; an overlap with no corner of either inside the
    other is not seen. Returns bool [n]."""
    out = np.zeros(len(part), bool)
    if len(part) == 0:
        return out
    origin, track, look = (np.asarray(v, float) for v in (fp.origin, fp.track, fp.look))
    (n_a, o_a), (n_b, o_b) = _plane(part, vertices), _plane(other, vertices)
    for view in range(3):
        antenna = views[sub, view]
        a = lattice_lines(vertices[part], antenna[:, None], fp, 0.0, 0.0, 1.0)
        b = lattice_lines(vertices[other], antenna[:, None], fp, 0.0, 0.0, 1.0)
        points = np.concatenate([a, b], axis=1)
        inside = (convex_depth(a, points) >= -1e-9) & (convex_depth(b, points) >= -1e-9)
        aim = origin + points[..., :1] * fp.spacing_azimuth * track + (points[..., 1:] * fp.spacing_range
                                                                       + fp.range_min) * look
        ray = aim - antenna[:, None]

        def distance(normal, point):
            return np.einsum("nd,nd->n", normal, point - antenna)[:, None] / np.einsum("nd,nkd->nk", normal, ray)
        out |= (inside & (distance(n_b, o_b) < distance(n_a, o_a) * (1.0 - 1e-9))).any(1)
    return out


def overlapping_occluders(groups, records, geometry):
    """Every part in front of a group's part where their projections overlap in some view of the
    sub-aperture, among the parts its records meet (bounding boxes of the three views, then
    :func:`in_front`). ``groups``: each group's sub-aperture and part; ``records``: each record's
    sub-aperture and part; ``geometry``: ``(vertices, views, fp)``. Returns ``(group, part)`` int64
    [n] twice."""
    gsub, gpart = groups
    vertices, views, fp = geometry
    sub, part = unique_pairs(*records)                       # the parts each sub-aperture meets
    if len(sub) == 0 or len(gsub) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    points = np.concatenate(_views(part, sub, 1.0, *geometry), axis=1)
    lo, hi = points.min(1), points.max(1)
    at = np.searchsorted(pair_key(sub, part), pair_key(gsub, gpart))     # each group's own box
    q, pos = matches(sub, gsub)                                           # (group, part of its sub-aperture)
    keep = (part[pos] != gpart[q]) & np.all(lo[pos] <= hi[at[q]], 1) & np.all(hi[pos] >= lo[at[q]], 1)
    q, pos = q[keep], pos[keep]
    front = in_front(gpart[q], part[pos], gsub[q], vertices, views, fp)
    return q[front], part[pos][front]


def overlapping_pairs(piece, part, sub, geometry):
    """The pairs of one piece's occluders (``piece``, ``part`` int64 [n], sorted by piece) whose
    projections from the piece's sub-aperture (``sub``, per cut) overlap in some view: the hulls of
    their corners in the three views are not separated by an edge normal of either (separating
    axes, conservative). Their overlap was cut out twice; the kernel adds it back once.
    Returns ``(piece, (part_a, part_b))``, int64 [n_pairs]."""
    vertices, views, fp = geometry
    start = np.flatnonzero(np.r_[True, piece[1:] != piece[:-1]]) if len(piece) else np.zeros(0, np.int64)
    size = np.diff(np.r_[start, len(piece)])
    rank = np.arange(len(piece)) - np.repeat(start, size)
    later = np.repeat(size, size) - rank - 1                  # the cuts after each one in its piece
    a = np.repeat(np.arange(len(piece)), later)
    b = a + 1 + np.arange(later.sum()) - np.repeat(np.cumsum(later) - later, later)
    pa, pb = (_views(part[c], sub[c], 1.0, vertices, views, fp) for c in (a, b))
    apart = _apart(np.concatenate(pa, axis=1), np.concatenate(pb, axis=1),
                   np.concatenate([_normals(pa[0]), _normals(pb[0])], 1))
    return piece[a][~apart], (part[a][~apart], part[b][~apart])


def occluders_near(holes: Holes, members, groups, records, geometry) -> Holes:
    """Add to the holes' occluders every part in front of a group's part where their projections
    overlap (:func:`overlapping_occluders`), and name it for every member whose cell lies in the
    box of its projection over the sub-aperture's three views (:func:`touching` then keeps those
    it meets). ``members``: each record's group and cell; ``groups``: each group's sub-aperture,
    part and tube size; ``records``: each record's sub-aperture and part."""
    g, i, j = members
    gsub, gpart, g_m = groups
    more = overlapping_occluders((gsub, gpart), records, geometry)
    named = unique_pairs(*(np.concatenate(c) for c in zip(holes.named, more)))
    grp, part = more
    points = np.concatenate(_views(part, gsub[grp], g_m[grp], *geometry), axis=1)
    lo, hi = np.floor(points.min(1)).astype(np.int64), np.floor(points.max(1)).astype(np.int64)
    width, height = hi[:, 0] - lo[:, 0] + 1, hi[:, 1] - lo[:, 1] + 1
    count = width * height
    at = np.repeat(np.arange(len(grp)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    cells = triple_key(grp[at], lo[at, 0] + k // height[at], lo[at, 1] + k % height[at])
    order = np.argsort(triple_key(g, i, j))
    q, pos = matches(triple_key(g, i, j)[order], cells)
    cuts = unique_pairs(np.concatenate([holes.member_cuts[0], order[pos]]),
                        np.concatenate([holes.member_cuts[1], part[at[q]]]))
    return Holes(holes.border, holes.cells, holes.owner, cuts, holes.hole_cuts, holes.occluded, named)
