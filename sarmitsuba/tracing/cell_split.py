"""Crowded cell pieces split, and the geometric tests of the cell plan (docs/physics.md (T6)).

A piece's boundary is packed into local memory (:func:`sarmitsuba.tracing.cell_clip.pack`) that grows
with the square of its occluder count, and the stack holds it: a piece behind more than
:data:`MOST_OCCLUDERS` is split into the quarters of its cell, each with the occluders whose
projection meets it (:func:`split_crowded`). Where many parts meet at one point (the apex of a
spire: sixteen faces) no split separates them; below :data:`MOST_SPLITS` halvings (1/16 of a
tube, under a wavelength at the default tube size) such a sub-piece is a tile of its own, lit
or hidden as its central ray is (:func:`centre_hidden`).

Projections are central, from a view of the sub-aperture onto the aim plane, in lattice lines
(:func:`sarmitsuba.tracing.lattice_index.lattice_lines`); parts of later bounce orders are unfolded,
mirrored in the planes of the chain's earlier parts (:func:`unfold`).
"""
from __future__ import annotations

import numpy as np

from .lattice_index import aim_points, lattice_lines

__all__ = ["ON_PLANE", "MARGIN", "MOST_OCCLUDERS", "MOST_SPLITS", "RECEIVE", "NONE", "meets_box", "covers_box",
           "unfold", "fold", "meets", "in_front", "centre_hidden", "split_crowded"]

#: Corners of an occluder closer than this to the part's plane [m] lie on it.
ON_PLANE = 1e-4
#: A candidate's projection is kept where it comes this close to the cell [cells].
MARGIN = 0.05

#: The most occluders of one piece: the packed boundary (:func:`sarmitsuba.tracing.cell_clip.pack`) lives
#: in local (stack) memory, which grows with the square of the count (32 overflow an 8 MiB
#: stack). A piece with more is split into quarters of its cell (:func:`split_crowded`).
MOST_OCCLUDERS = 16
#: The halvings of a crowded piece's cell; beyond them, a still crowded sub-piece is decided by
#: its central ray (:func:`centre_hidden`).
MOST_SPLITS = 4

#: The level of an occluder that hides the last hit from the antenna (receive side).
RECEIVE = 255
#: The level of a padding slot of an occluder group (no occluder).
NONE = 254


def _box_sides(poly, box, margin):
    """For convex polygons ``poly`` [n, v, 2] (either orientation, repeated corners allowed) and
    the boxes ``box`` [n, 4] (x0, x1, y0, y1) grown by ``margin``: the box's corners [4 x (cx, cy)],
    and per corner the side of each polygon edge it lies on (float [n, v], > 0 inside), with the
    polygon's coordinates, edges ``(px, py, ex, ey)``."""
    x0, x1, y0, y1 = (box[:, k] for k in range(4))
    x0, y0, x1, y1 = x0 - margin, y0 - margin, x1 + margin, y1 + margin
    px, py = poly[..., 0], poly[..., 1]
    ex, ey = np.roll(px, -1, 1) - px, np.roll(py, -1, 1) - py
    sign = np.where((px * np.roll(py, -1, 1) - np.roll(px, -1, 1) * py).sum(1) >= 0, 1.0, -1.0)[:, None]
    corners = ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
    sides = [sign * (ex * (cy[:, None] - py) - ey * (cx[:, None] - px)) for cx, cy in corners]
    return corners, sides, (px, py, ex, ey)


def meets_box(poly, box, margin):
    """Whether convex polygons ``poly`` [n, v, 2] (either orientation, repeated corners allowed)
    meet the boxes ``box`` [n, 4] (x0, x1, y0, y1) grown by ``margin`` (separating axes)."""
    ((x0, y0), _, (x1, y1), _), sides, (px, py, ex, ey) = _box_sides(poly, box, margin)
    ok = (px.max(1) >= x0) & (px.min(1) <= x1) & (py.max(1) >= y0) & (py.min(1) <= y1)
    outside = np.logical_and.reduce([side < 0 for side in sides])
    return ok & ~(outside & ((ex != 0) | (ey != 0))).any(1)


def covers_box(poly, box, margin):
    """Whether convex polygons ``poly`` [n, v, 2] (either orientation, repeated corners allowed)
    hold the whole boxes ``box`` [n, 4] (x0, x1, y0, y1) grown by ``margin``."""
    _, sides, _ = _box_sides(poly, box, margin)
    return np.logical_and.reduce([(side >= 0).all(1) for side in sides])


def unfold(points, mirrors):
    """Scene ``points`` [n, ..., 3] in the unfolded frame of a chain whose earlier parts' planes are
    ``mirrors`` (list of (normal [n, 3], offset [n]), the first part's first)."""
    for normal, offset in reversed(mirrors):
        d = np.einsum("n...k,nk->n...", points, normal) - offset.reshape((-1,) + (1,) * (points.ndim - 2))
        points = points - 2.0 * d[..., None] * normal.reshape((-1,) + (1,) * (points.ndim - 2) + (3,))
    return points


def fold(points, mirrors):
    """The inverse of :func:`unfold`: unfolded ``points`` [n, ..., 3] back in the scene frame (the
    same reflections in the opposite order)."""
    return unfold(points, mirrors[::-1])


def meets(sub, box, scale, chain, last, parts, views, fp, shadow=None, covers: bool = False):
    """Whether part ``last`` [n], unfolded as the chains ``chain`` [n, k + 1] take it (the mirrors
    of their parts before the last), meets the rectangles ``box`` [n, 4] (x0, x1, y0, y1 in
    lattice lines of ``scale`` [n] tubes per cell) from some view of sub-aperture ``sub`` [n]
    (by :data:`MARGIN`): bool [n]. With ``shadow`` (int64 [n], a part), ``last`` is first cast
    from the view onto that part's plane (a receive-side occluder's shadow, as the kernel casts
    it); where a cast is not in front of the view the answer is True (kept). With ``covers``,
    also whether the projection holds the whole box from every view (:func:`covers_box`)."""
    vertices, normal, offset = parts[0], parts[2], parts[3]
    mirrors = [(normal[chain[:, i]], offset[chain[:, i]]) for i in range(chain.shape[1] - 1)]
    near, whole = np.zeros(len(sub), bool), np.ones(len(sub), bool)
    for v in range(views.shape[1]):
        view = views[sub, v][:, None]
        corners = vertices[last]
        if shadow is not None:
            n_d, o_d = normal[shadow], offset[shadow]
            den = np.einsum("nvk,nk->nv", corners - view, n_d)
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (o_d - np.einsum("nvk,nk->n", view, n_d))[:, None] / den
            cast = np.isfinite(t).all(1) & (t > 0).all(1)
            near |= ~cast
            whole &= cast
            corners = np.where(cast[:, None, None], view + (corners - view) * np.where(cast[:, None], t, 1.0)[..., None],
                               corners)
        poly = lattice_lines(unfold(corners, mirrors), view, fp, 0.0, 0.0, scale[:, None])
        near |= meets_box(poly, box, MARGIN)
        if covers:
            whole &= covers_box(poly, box, MARGIN)
    return (near, whole) if covers else near


def in_front(part, x, sub, parts, views):
    """Whether every corner of part ``part`` [n] lies on the antenna's side of part ``x``'s plane
    (by :data:`ON_PLANE`) from every view of sub-aperture ``sub``: bool [n]."""
    vertices, normal, offset = parts[0], parts[2], parts[3]
    d = np.einsum("nvk,nk->nv", vertices[part], normal[x]) - offset[x][:, None]
    out = np.ones(len(part), bool)
    for v in range(views.shape[1]):
        side = np.sign(np.einsum("nk,nk->n", views[sub, v], normal[x]) - offset[x])
        out &= (side[:, None] * d > ON_PLANE).all(1)
    return out


def _crosses(start, end, corners, normal, offset):
    """Whether the segments ``start`` -> ``end`` [n, 3] cross the convex planar polygons
    ``corners`` [n, v, 3] (plane ``normal`` [n, 3], ``offset`` [n]; repeated corners allowed)
    strictly between their ends: bool [n]."""
    d0 = np.einsum("nk,nk->n", start, normal) - offset
    d1 = np.einsum("nk,nk->n", end, normal) - offset
    with np.errstate(divide="ignore", invalid="ignore"):
        t = d0 / (d0 - d1)
    hit = start + (end - start) * np.where(np.isfinite(t), t, 0.0)[:, None]
    edge = np.roll(corners, -1, 1) - corners
    turn = np.einsum("nvk,nk->nv", np.cross(edge, hit[:, None] - corners), normal)
    real = np.linalg.norm(edge, axis=2) > 0
    inside = np.all((turn >= 0) | ~real, 1) | np.all((turn <= 0) | ~real, 1)
    return np.isfinite(t) & (t > 1e-9) & (t < 1 - 1e-9) & inside


def _unfolded(part, mirrors, parts):
    """Parts ``part`` [n] unfolded by ``mirrors``: corners [n, v, 3], normal [n, 3], offset [n]."""
    vertices, normal = parts[0], parts[2]
    corners = unfold(vertices[part], mirrors)
    tip = unfold(vertices[part, :1] + normal[part][:, None], mirrors)[:, 0]
    n = tip - corners[:, 0]                              # a reflected direction: difference of points
    return corners, n, np.einsum("nk,nk->n", n, corners[:, 0])


def centre_hidden(depth, chain, sub, scale, bounds, occluders, parts, views, fp):
    """Whether the central ray of each piece (its rectangle's centre, from the sub-aperture's
    reference position) is hidden by one of its occluders: bool [n].

    The ray is the chain's unfolded straight line: it meets the unfolded part of level ``i`` at
    ``P_i``; an occluder of level ``i`` (unfolded as that level's part) hides it where it
    crosses the segment ``P_{i-1} -> P_i`` (the antenna for ``i = 0``), a receive-side one
    where it crosses the segment from the last hit, folded back into the scene, to the antenna.
    Arguments as :func:`split_crowded`."""
    normal, offset = parts[2], parts[3]
    view = views[sub, 0]
    aim = aim_points(0.5 * (bounds[:, 0] + bounds[:, 1]), 0.5 * (bounds[:, 2] + bounds[:, 3]), fp, scale)
    mirrors = [(normal[chain[:, i]], offset[chain[:, i]]) for i in range(depth)]
    points = []
    for i in range(depth + 1):         # where the ray meets level i's unfolded plane
        _, n_i, o_i = _unfolded(chain[:, i], mirrors[:i], parts)
        w = aim - view
        points.append(view + w * ((o_i - np.einsum("nk,nk->n", view, n_i)) / np.einsum("nk,nk->n", w, n_i))[:, None])
    piece, part, level = occluders
    hidden = np.zeros(len(chain), bool)
    for lv in np.unique(level):
        at = np.flatnonzero(level == lv)
        p, q = piece[at], part[at]
        mine = [(a[p], b[p]) for a, b in mirrors]
        if lv == RECEIVE:
            start, end = fold(points[depth][p], mine), view[p]
            corners, n_q, o_q = _unfolded(q, [], parts)
        else:
            start, end = (view[p] if lv == 0 else points[lv - 1][p]), points[lv][p]
            corners, n_q, o_q = _unfolded(q, mine[:lv], parts)
        crossed = _crosses(start, end, corners, n_q, o_q)
        hidden |= np.bincount(p[crossed], minlength=len(chain)) > 0
    return hidden


def split_crowded(depth, chain, sub, scale, bounds, occluders, parts, views, fp, most: int = MOST_OCCLUDERS):
    """Pieces with more than ``most`` occluders split into the quarters of their rectangle, each
    with those of the piece's occluders whose projection meets it from some view (:func:`meets`;
    receive-side ones as the shadows the kernel casts), again until none has more. A quarter
    that one first-level occluder hides whole (wholly in front of the chain's first part, its
    projection holding the quarter from every view) is empty and left out: a tower's many
    walls all cross a roof's cell, but the front ones hide it.

    Parameters
    ----------
    depth : int
    chain : int64 [n, depth + 1]
        The pieces' parts, level by level.
    sub, scale : int64 [n], float64 [n]
        The pieces' sub-apertures, and the tubes per cell edge of their lattice lines.
    bounds : float64 [n, 4]
        x0, x1, y0, y1 in lattice lines.
    occluders : (piece, part, level) int64 arrays, sorted by piece.
    most : int

    Returns ``(index, bounds, occluders)``: the piece each output piece comes from (int64
    [n_out]), the output rectangles (float64 [n_out, 4]) and their occluders, sorted by piece.

    After :data:`MOST_SPLITS` halvings a sub-piece that still has more is a tile of its own,
    without occluders: whole where its central ray is lit, left out where it is hidden
    (:func:`centre_hidden`).
    """
    piece, part, level = occluders
    index = np.arange(len(chain))
    for split in range(MOST_SPLITS + 1):
        counts = np.bincount(piece, minlength=len(index))
        crowded = counts > most
        if not crowded.any():
            return index, bounds, (piece, part, level)
        if split == MOST_SPLITS:     # a tile of its own: whole, or left out where its centre is hidden
            hidden = centre_hidden(depth, chain[index], sub[index], scale[index], bounds, (piece, part, level),
                                   parts, views, fp)
            keep = ~(crowded & hidden)
            stay = ~crowded[piece]
            renumber = np.cumsum(keep) - 1
            return index[keep], bounds[keep], tuple(a[stay] if k else renumber[a[stay]]
                                                    for k, a in enumerate((piece, part, level)))
        # new numbering: the pieces that stay, then four quarters of each crowded one
        n_stay = int((~crowded).sum())
        new_id = np.where(crowded, -1, np.cumsum(~crowded) - 1)
        quarter0 = n_stay + 4 * (np.cumsum(crowded) - 1)
        x0, x1, y0, y1 = bounds[crowded].T
        xm, ym = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        quarters = np.stack([np.stack(q, 1) for q in ((x0, xm, y0, ym), (xm, x1, y0, ym), (x0, xm, ym, y1),
                                                      (xm, x1, ym, y1))], 1).reshape(-1, 4)
        stay = ~crowded[piece]
        c_piece, c_part, c_level = (np.repeat(a[~stay], 4) for a in (piece, part, level))
        q = np.tile(np.arange(4), int((~stay).sum()))
        c_new = quarter0[c_piece] + q
        source = index[c_piece]
        near, hides = np.ones(len(c_new), bool), np.zeros(len(c_new), bool)
        for lv in np.unique(c_level):
            at = np.flatnonzero(c_level == lv)
            upto = depth if lv == RECEIVE else lv
            prefix = np.concatenate([chain[source[at], :upto], c_part[at, None]], 1)
            near[at], hides[at] = meets(sub[source[at]], quarters[c_new[at] - n_stay], scale[source[at]], prefix,
                                         c_part[at], parts, views, fp, covers=True,
                                         shadow=chain[source[at], depth] if lv == RECEIVE else None)
        # a quarter that one first-level occluder hides whole (wholly in front of the chain's
        # first part, its projection over the quarter from every view) is empty: left out
        hides &= (c_level == 0) & in_front(c_part, chain[source, 0], sub[source], parts, views)
        alive = np.bincount(c_new[hides] - n_stay, minlength=len(quarters)) == 0
        renumber = np.concatenate([np.arange(n_stay), n_stay + np.cumsum(alive) - 1])
        near &= alive[c_new - n_stay]
        piece = renumber[np.concatenate([new_id[piece[stay]], c_new[near]])]
        part, level = np.concatenate([part[stay], c_part[near]]), np.concatenate([level[stay], c_level[near]])
        order = np.argsort(piece, kind="stable")
        piece, part, level = piece[order], part[order], level[order]
        index = np.concatenate([index[~crowded], np.repeat(index[crowded], 4)[alive]])
        bounds = np.concatenate([bounds[~crowded], quarters[alive]])
