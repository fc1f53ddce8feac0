"""Owned regions: a partition of a facet among the ray tubes that meet it (docs/physics.md (T6)).

The readable NumPy reference of the design chosen for issue 26's lit regions, and the host-side
plan the kernel follows with ``lit_regions = owned`` (:func:`plan`; the per-pulse integrals are
:meth:`sarmitsuba.returns.Returns.owned_po`). A tube whose central ray meets a convex facet (a
*member*, decided once per sub-aperture at its reference position) owns a convex region of the
facet's plane:

* its own cell;
* when it ends its column (no member above, or below, in ground range): the rest of its column's
  strip beyond it;
* when it ends its row (first or last member along track): its row band (its row and the rows
  without members up to the next member row; the first and last bands run to infinity) in every
  run of columns without members on that side.

The cells, strips and quadrants are bounded by the lattice lines as one pulse sees them on the
facet (the projections of the aim-cell edges from that pulse's antenna, (T3)). They partition
the whole plane whenever the members of each column and of each row are contiguous, which holds
for the lattice points inside any convex facet. Clipped to the facet, they therefore tile it
exactly: for any lattice position and for every pulse of the sub-aperture, however far its view
of the lattice has moved from the reference position's. The facet's border returns as the
straight edges it has, not as the tubes' staircase.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .lattice_index import convex_depth, lattice_lines, matches, pair_key, pair_ranges, triple_key, unique_pairs
from .shadow_plan import (band_occluders, find_holes, hidden_run, occluders_near, overlapping_pairs,
                          piece_occluders, touching)

__all__ = ["HalfPlane", "owned_regions", "clip_convex", "region_polygons", "OwnedPlan", "UNBOUNDED", "lattice_lines", "plan"]

#: A half-plane as a directed line ``(a, b)`` (float64 [2] points): the side on its left,
#: ``cross(b - a, x - a) >= 0``.
HalfPlane = tuple


def _flip(line: HalfPlane) -> HalfPlane:
    return line[1], line[0]


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def owned_regions(members, column_line, row_line) -> dict:
    """Each member's owned region, as lists of half-planes (one convex piece per list).

    Parameters
    ----------
    members : iterable of (int, int)
        Lattice cells ``(i, j)`` (along track, ground range) whose central ray meets the facet.
        The members of each column ``i`` and of each row ``j`` must be contiguous.
    column_line : callable, i -> HalfPlane
        The line between columns ``i - 1`` and ``i`` on the facet, directed so that its left is
        the side of column ``i - 1``.
    row_line : callable, j -> HalfPlane
        The line between rows ``j - 1`` and ``j``, directed so that its left is the side of row
        ``j - 1``.

    Returns
    -------
    dict (i, j) -> list of list of HalfPlane
        The convex pieces a member owns: its cell; the rest of its column beyond it when it ends
        its column; its row band in the member-less columns beyond it when it ends its row.
        Their union over all members is the whole plane, and two pieces overlap only on their
        borders: member columns are covered by their members, member-less columns by the bands.

    Raises
    ------
    ValueError
        If ``members`` is empty or a column or row has a gap.
    """
    cols, rows = {}, {}
    for i, j in members:
        cols.setdefault(i, set()).add(j)
        rows.setdefault(j, set()).add(i)
    if not cols:
        raise ValueError("owned_regions: no members (a facet no tube meets owns nothing)")
    for name, lines in (("column", cols), ("row", rows)):
        for key, values in lines.items():
            if len(values) != max(values) - min(values) + 1:
                raise ValueError(f"owned_regions: {name} {key} has a gap in its members {sorted(values)}; "
                                 "the partition needs contiguous members (a convex facet, no occluder)")
    before_col, after_col = (lambda i: column_line(i)), (lambda i: _flip(column_line(i)))   # noqa: E731
    before_row, after_row = (lambda j: row_line(j)), (lambda j: _flip(row_line(j)))         # noqa: E731
    # the rows of each member row's band (it and the member-less rows up to the next member
    # row; the first and last bands run to infinity), and the runs of member-less columns
    member_rows, member_cols = sorted(rows), sorted(cols)
    band = {}
    for n, j in enumerate(member_rows):
        lo = [after_row(j)] if n > 0 else []
        hi = [before_row(member_rows[n + 1])] if n + 1 < len(member_rows) else []
        band[j] = lo + hi
    runs = [(-np.inf, member_cols[0], [before_col(member_cols[0])])]           # (after, before, planes)
    for a, b in zip(member_cols[:-1], member_cols[1:]):
        if b > a + 1:
            runs.append((a, b, [after_col(a + 1), before_col(b)]))
    runs.append((member_cols[-1], np.inf, [after_col(member_cols[-1] + 1)]))
    regions = {}
    for i, j in members:
        column = [after_col(i), before_col(i + 1)]
        pieces = [column + [after_row(j), before_row(j + 1)]]
        if j == max(cols[i]):
            pieces.append(column + [after_row(j + 1)])
        if j == min(cols[i]):
            pieces.append(column + [before_row(j)])
        for left_of, right_of, planes in runs:
            if (i == min(rows[j]) and right_of <= i) or (i == max(rows[j]) and left_of >= i):
                pieces.append(band[j] + planes)
        regions[i, j] = pieces
    return regions


def clip_convex(polygon: np.ndarray, line: HalfPlane) -> np.ndarray:
    """The part of a convex polygon (float64 [n, 2], counter-clockwise) left of ``line``
    (Sutherland and Hodgman 1974). Returns float64 [m, 2], possibly empty."""
    if len(polygon) == 0:
        return polygon
    a, b = (np.asarray(p, float) for p in line)
    side = _cross(b - a, polygon - a)
    out = []
    for n in range(len(polygon)):
        m = (n + 1) % len(polygon)
        if side[n] >= 0:
            out.append(polygon[n])
        if (side[n] >= 0) != (side[m] >= 0):
            out.append(polygon[n] + (polygon[m] - polygon[n]) * (side[n] / (side[n] - side[m])))
    return np.array(out, float).reshape(-1, 2)


def region_polygons(facet: np.ndarray, regions: dict) -> dict:
    """The owned pieces clipped to a convex facet (float64 [n, 2], counter-clockwise).

    Returns dict (i, j) -> list of float64 [m, 2] polygons (empty pieces left out)."""
    facet = np.asarray(facet, float)
    edges = [(facet[n], facet[(n + 1) % len(facet)]) for n in range(len(facet))]
    out = {}
    for cell, pieces in regions.items():
        polys = []
        for planes in pieces:
            poly = facet
            for line in list(planes) + edges:
                poly = clip_convex(poly, line)
            if len(poly) >= 3:
                polys.append(poly)
        out[cell] = polys
    return out


# ============================================================================ the kernel's plan
#: A piece's side that runs to infinity (in lattice lines); the kernel clamps it to
#: the part's projection.
UNBOUNDED = 1e30


@dataclass(frozen=True)
class OwnedPlan:
    """Which first-bounce records of a launch integrate owned regions, and their pieces.

    Attributes
    ----------
    owned : ndarray
        bool [n_records]: the record integrates its owned pieces (polygon terms) instead of its
        whole tile; the others keep their tile terms (PO2)-(PO5).
    record : ndarray
        int64 [n_pieces]: the record of each piece.
    bounds : ndarray
        float64 [n_pieces, 4]: the piece's rectangle ``[ia0, ia1] x [jb0, jb1]`` in the lattice
        lines of the record's tube size ``m`` (:func:`lattice_lines` with ``i0 = j0 = 0``: cell
        ``(i, j)`` is ``[i, i + 1] x [j, j + 1]``), +-:data:`UNBOUNDED` where it runs to infinity.
    cut_piece, cut_part : ndarray
        int64 [n_cuts]: a piece and a part in front of it (an occluder) whose projection from each
        pulse's antenna is cut out of the piece: the kernel subtracts the integral over
        ``piece ∩ part ∩ occluder`` as that pulse sees them (T6).
    pair_piece, pair_parts : ndarray, (ndarray, ndarray)
        int64 [n_pairs]: a piece and two of its occluders whose projections overlap in some view;
        the kernel adds back the integral over ``piece ∩ part ∩ both`` (inclusion and exclusion).
    groups, fallback : int
        Facet-and-sub-aperture groups seen, and those left to whole tiles (a member where the
        part is not, tubes of several sizes).
    """

    owned: np.ndarray
    record: np.ndarray
    bounds: np.ndarray
    cut_piece: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    cut_part: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    pair_piece: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    pair_parts: tuple = (np.zeros(0, np.int64), np.zeros(0, np.int64))
    groups: int = 0
    fallback: int = 0


def plan(sub, part, block, lane, blocks, vertices, views, fp) -> OwnedPlan:
    """The owned pieces of a launch's first-bounce records, eq. (T6) (vectorised NumPy).

    A group is one part (convex planar polygon of :mod:`sarmitsuba.facets`) and one
    sub-aperture. Members are counted on the lattice of their tubes' size (``m`` tubes per coarse
    cell edge, from the scene's lattice origin), whatever block traced them. A group gets owned
    regions when its members have one tube size and every column's and row's members lie among
    the cells whose centres the reference position sees inside the part. A run of member-less
    columns (rows) between member ones where the part holds no cell centre (a sliver between
    centres) belongs to the row bands, as in :func:`owned_regions`; one that holds centres (hidden
    cells) is owned by no band. An end of a column or row is the part's edge when the next cell's centre is
    outside the part; a hole's when that cell is hidden by another part (an occluder); else it is
    cut by the beam's edge and owns nothing beyond its cell. Holes near members are pieces of a
    neighbouring member's record; the pieces near holes are integrated less each occluder's
    projection (``cut_piece``, ``cut_part``). Where a side of the members has an end cut by the
    beam, every row band stops at the members' last lattice line on that side. The owned records
    are the ends at the part's edge, the members near holes and every member whose cell leaves
    the part as the sub-aperture's first, middle or last pulse sees it (parallax); the rest keep
    their whole tiles (inside the part, and lit, for every pulse).

    Parameters
    ----------
    sub, part, block, lane : int arrays [n_records]
        Each record's sub-aperture, part (-1: not on a mesh part), block and launch lane.
    blocks : kernel.Blocks
    vertices : float64 [n_parts, k, 3], m
        Each part's corners in order (repeated corners allowed).
    views : float64 [n_subapertures, 3, 3], m
        Reference, first and last pulse's antenna position of each sub-aperture.
    fp : RayFootprint

    Returns
    -------
    OwnedPlan
    """
    sub, part, block, lane = (np.asarray(a, np.int64) for a in (sub, part, block, lane))
    n = len(sub)
    empty = OwnedPlan(np.zeros(n, bool), np.zeros(0, np.int64), np.zeros((0, 4)))
    idx = np.flatnonzero(part >= 0)
    if idx.size == 0:
        return empty
    b = block[idx]
    # the lattice of the records' own tube size: (i, j) counted from the scene's lattice origin
    m_rec = blocks.m.astype(np.int64)[b]
    _, g = np.unique(pair_key(sub[idx], part[idx]), return_inverse=True)
    g = g.ravel()
    n_g = int(g.max()) + 1
    g_m = np.zeros(n_g, np.int64)
    g_m[g] = m_rec
    ok = np.ones(n_g, bool)
    np.logical_and.at(ok, g, m_rec == g_m[g])
    n_j = blocks.n_j.astype(np.int64)[b]
    rest = lane[idx] - blocks.start.astype(np.int64)[b]
    i = blocks.i0.astype(np.int64)[b] * m_rec + rest // n_j
    j = blocks.j0.astype(np.int64)[b] * m_rec + rest % n_j
    cols, jmin, jmax, _, col_of = pair_ranges(g, i, j)
    rows, imin, imax, _, row_of = pair_ranges(g, j, i)
    (cmin, cmax), (rmin, rmax) = _extent(cols, n_g), _extent(rows, n_g)
    # ---- the part as the reference position and the ends of the sub-aperture see it, in lattice lines ----
    gsub = np.zeros(n_g, np.int64)
    gsub[g] = sub[idx]
    gpart = np.zeros(n_g, np.int64)
    gpart[g] = part[idx]
    polys = [lattice_lines(vertices[gpart], views[gsub, v][:, None], fp, 0.0, 0.0, g_m[:, None].astype(float))
             for v in range(3)]
    ref = polys[0]
    ok &= np.isfinite(ref).all((1, 2))
    # ---- each column's and row's members lie in the cells whose centres the reference sees in the part ----
    column_spans = _centre_spans(np.where(ok[:, None, None], ref, 0.0))
    row_spans = _centre_spans(np.where(ok[:, None, None], ref[..., ::-1], 0.0))
    column_ends = _ends(column_spans, cols, jmin, jmax, n_g)
    row_ends = _ends(row_spans, rows, imin, imax, n_g)
    ok &= column_ends[0] & row_ends[0]
    # the runs of member-less columns (rows) between members where the part holds no cell centre
    # (it is a sliver there) are its row bands'; the others hold hidden cells
    column_gaps, row_gaps = _gaps(cols, column_spans), _gaps(rows, row_spans)
    (_, lo_part, hi_part, span_lo, span_hi), (_, left_part, right_part, row_lo, row_hi) = column_ends, row_ends
    # ---- holes: cells inside the part that a part in front hides; the members and holes near
    #      their border own their cells less the occluders' projections ----
    shift = np.max([np.abs(poly - ref).max((1, 2)) for poly in polys[1:]], axis=0)   # parallax, cells
    reach = np.zeros(int(gsub.max()) + 1)
    np.maximum.at(reach, gsub[ok], shift[ok])
    radius = 1 + np.ceil(reach[gsub]).astype(np.int64)
    holes = find_holes(g, i, j, ok, ((cols, span_lo, span_hi), (rows, imin, imax)), (gsub, gpart, g_m), radius,
                       (sub[idx], part[idx], m_rec))
    # a row whose cells beyond its end are holes up to the part's edge ends at the part's edge
    left_part = left_part | hidden_run(rows, row_lo, imin - 1, holes.occluded)
    right_part = right_part | hidden_run(rows, imax + 1, row_hi, holes.occluded)
    # ---- owned: ends at the part's edge, and cells some view sees leave the part ----
    good = ok[g]
    ends = ((j == jmin[col_of]) & lo_part[col_of], (j == jmax[col_of]) & hi_part[col_of],
            (i == imin[row_of]) & left_part[row_of], (i == imax[row_of]) & right_part[row_of])
    corners = np.stack([np.stack([i + di, j + dj], 1) for di in (0, 1) for dj in (0, 1)], 1).astype(float)
    # a cell farther from the part's edge than the views' largest corner shift + 1 stays inside
    near = good & (convex_depth(ref[g], corners.mean(1)[:, None])[:, 0] <= shift[g] + 1.0)
    leaves = np.zeros(idx.size, bool)
    for poly in polys:
        leaves[near] |= (convex_depth(poly[g[near]], corners[near]) < -1e-9).any(1)
    extended = ends[0] | ends[1] | ends[2] | ends[3]
    holes = occluders_near(holes, (g, i, j), (gsub, gpart, g_m), (sub[idx], part[idx]), (vertices, views, fp))
    holes = touching(holes, (g, i, j), vertices, views, fp, (gsub, gpart, g_m))
    bands = _bands_box(holes.occluded, (cols, jmin, jmax, lo_part, hi_part), (rows, imin, imax, left_part, right_part),
                       (cmin, cmax, rmin, rmax), n_g)
    mine = good & (ends[0] | ends[1] | ends[2] | ends[3] | leaves | holes.border)
    owned = np.zeros(n, bool)
    owned[idx[mine]] = True
    at = np.flatnonzero(mine)
    records, bounds, origin = _pieces(idx[mine], at, g[mine], i[mine], j[mine], [e[mine] for e in ends],
                                      (cmin, cmax, rmin, rmax), bands, (holes, cols, span_lo, span_hi), idx,
                                      (column_gaps, _next_row(rows, row_gaps)[row_of[mine]]))
    piece, occluder = _cuts(holes, (origin, bounds), extended, (g, polys), (gsub, g_m), (vertices, views, fp))
    pairs = overlapping_pairs(piece, occluder, sub[records[piece]], (vertices, views, fp))
    return OwnedPlan(owned, records, bounds, piece, occluder, *pairs, groups=n_g, fallback=int(n_g - ok.sum()))


def _cuts(holes, pieces, extended, records, groups, geometry):
    """Each piece's occluders: its member's or hole's (:func:`piece_occluders`), and for the pieces
    of the ends at the part's edge, which reach beyond their cell, every occluder of the group
    (``holes.named``: found in its holes, or in front where the projections overlap) that meets
    them (:func:`band_occluders`, with the part's box over the sub-aperture's views ``polys``).
    ``records``: each record's group, and the groups' parts in the three views. Returns ``(piece,
    part)`` int64 [n_cuts] twice, sorted."""
    (origin, bounds), (g, polys), (gsub, g_m) = pieces, records, groups
    piece, occluder = piece_occluders(holes, origin, len(g))
    wide = np.flatnonzero(origin < len(g))
    wide = wide[extended[origin[wide]]]
    corners = np.concatenate(polys, axis=1)
    box = np.stack([corners[..., 0].min(1) - 1, corners[..., 0].max(1) + 1, corners[..., 1].min(1) - 1,
                    corners[..., 1].max(1) + 1], 1)
    more = band_occluders((wide, g[origin[wide]], bounds[wide]), holes.named, box, (gsub, g_m), geometry)
    return unique_pairs(np.concatenate([piece, more[0]]), np.concatenate([occluder, more[1]]))


def _bands_box(occluded, columns, rows, extent, n_g):
    """Per group the lines every row band stays within (T6): where a side of the members has a cut
    end, the members' last lattice line on that side (``UNBOUNDED`` where none). An end next to a
    hole is no cut: the hole's pieces and their occluders bound it."""
    cmin, cmax, rmin, rmax = extent

    def edge(part_edge, pairs, step, swap):
        nxt = (pairs[:, 0], step, pairs[:, 1]) if swap else (pairs[:, 0], pairs[:, 1], step)
        return part_edge | np.isin(triple_key(*nxt), occluded)
    (cols, jmin, jmax, lo_part, hi_part), (rows, imin, imax, left_part, right_part) = columns, rows
    return np.stack([np.where(_all_by(rows[:, 0], edge(left_part, rows, imin - 1, True), n_g), -UNBOUNDED, cmin),
                     np.where(_all_by(rows[:, 0], edge(right_part, rows, imax + 1, True), n_g), UNBOUNDED, cmax + 1),
                     np.where(_all_by(cols[:, 0], edge(lo_part, cols, jmin - 1, False), n_g), -UNBOUNDED, rmin),
                     np.where(_all_by(cols[:, 0], edge(hi_part, cols, jmax + 1, False), n_g), UNBOUNDED, rmax + 1)],
                    1).astype(float)


def _all_by(keys, values, n):
    """Per group (``keys`` in ``[0, n)``): whether every one of its ``values`` is true."""
    return np.bincount(keys, weights=~values, minlength=n) == 0


def _centre_spans(poly):
    """The cells whose centres lie inside each convex polygon (float64 [n_g, v, 2], lattice lines;
    repeated corners allowed), per column: int64 [n, 4] rows ``(group, column, row_lo, row_hi)``."""
    n_g = len(poly)
    c_lo = np.ceil(poly[..., 0].min(1) - 0.5).astype(np.int64)
    c_hi = np.floor(poly[..., 0].max(1) - 0.5).astype(np.int64)
    count = np.maximum(c_hi - c_lo + 1, 0)
    cg = np.repeat(np.arange(n_g), count)
    cc = c_lo[cg] + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))
    x = cc + 0.5
    pa, pb = poly[cg], np.roll(poly[cg], -1, axis=1)
    xa, xb, ya, yb = pa[..., 0], pb[..., 0], pa[..., 1], pb[..., 1]
    spans = (np.minimum(xa, xb) <= x[:, None]) & (np.maximum(xa, xb) >= x[:, None]) & (xa != xb)
    t = np.where(spans, (x[:, None] - xa) / np.where(xa != xb, xb - xa, 1.0), 0.0)
    y = ya + t * (yb - ya)
    j_lo = np.ceil(np.where(spans, y, np.inf).min(1) - 0.5)
    j_hi = np.floor(np.where(spans, y, -np.inf).max(1) - 0.5)
    has = np.isfinite(j_lo) & np.isfinite(j_hi) & (j_lo <= j_hi)
    return np.stack([cg[has], cc[has], j_lo[has].astype(np.int64), j_hi[has].astype(np.int64)], 1)


def _ends(spans, lines, lo, hi, n_g):
    """Per group, whether each member line (``lines`` [n, 2]: group, column or row) has its members
    ``[lo, hi]`` inside the cells whose centres lie in the part (``spans`` of
    :func:`_centre_spans`); per line whether its low and high end is the part's edge, and the
    first and last cell of the part on it (its members' where they are not inside)."""
    if len(spans) == 0:
        none = np.zeros(len(lines), bool)
        return _all_by(lines[:, 0], none, n_g), none, none, lo, hi
    keys = pair_key(spans[:, 0], spans[:, 1])
    order = np.argsort(keys)
    query = pair_key(lines[:, 0], lines[:, 1])
    at = np.minimum(np.searchsorted(keys[order], query), len(keys) - 1)
    found = keys[order][at] == query
    s_lo, s_hi = spans[order, 2][at], spans[order, 3][at]
    inside = found & (lo >= s_lo) & (hi <= s_hi)
    return (_all_by(lines[:, 0], inside, n_g), inside & (lo == s_lo), inside & (hi == s_hi),
            np.where(inside, s_lo, lo), np.where(inside, s_hi, hi))


def _extent(lines, n_g):
    """Per group the first and last of its member lines (``lines`` int64 [n, 2]: group, column
    or row): int64 [n_g] twice."""
    lo = np.full(n_g, np.iinfo(np.int64).max)
    hi = np.full(n_g, np.iinfo(np.int64).min)
    np.minimum.at(lo, lines[:, 0], lines[:, 1])
    np.maximum.at(hi, lines[:, 0], lines[:, 1])
    return lo, hi


def _gaps(lines, spans):
    """The runs of member-less lines between member lines of each group (``lines`` int64 [n, 2]:
    group, column or row, sorted) that hold no cell centre inside the part (``spans`` of
    :func:`_centre_spans`): int64 [n_gaps, 3] rows ``(group, first, last + 1)``."""
    step = (lines[1:, 0] == lines[:-1, 0]) & (lines[1:, 1] > lines[:-1, 1] + 1)
    gaps = np.stack([lines[:-1, 0][step], lines[:-1, 1][step] + 1, lines[1:, 1][step]], 1).reshape(-1, 3)
    return gaps[_empty(gaps, spans)]


def _empty(gaps, spans):
    """Whether each run of member-less lines (``gaps`` of :func:`_gaps`) holds no cell centre
    inside the part (``spans`` of :func:`_centre_spans`): bool [n_gaps]."""
    if len(gaps) == 0 or len(spans) == 0:
        return np.ones(len(gaps), bool)
    keys = pair_key(gaps[:, 0], gaps[:, 1])
    at = np.searchsorted(keys, pair_key(spans[:, 0], spans[:, 1]), "right") - 1
    run = gaps[np.maximum(at, 0)]
    inside = (at >= 0) & (run[:, 0] == spans[:, 0]) & (spans[:, 1] < run[:, 2])
    return np.bincount(np.maximum(at, 0)[inside], minlength=len(gaps)) == 0


def _next_row(rows, gaps):
    """The top of each member row's band (``rows`` int64 [n, 2], sorted), float64 [n]: the next
    member row of its group across a run of ``gaps`` (centre-free member-less rows), else the row
    above it (the next is a member row, or the rows between hold hidden cells);
    :data:`UNBOUNDED` for the group's last member row."""
    last = np.r_[rows[1:, 0] != rows[:-1, 0], True]
    above = np.isin(pair_key(rows[:, 0], rows[:, 1] + 1), pair_key(gaps[:, 0], gaps[:, 1]))
    return np.where(last, UNBOUNDED, np.where(above, np.r_[rows[1:, 1], 0], rows[:, 1] + 1)).astype(float)


def _run_pieces(gi, ii, gaps, right):
    """For row ends at ``(gi, ii)``: every member-less column run of their group on their right
    (left) side. Returns the ends' and the runs' indices, int64 [n] each."""
    end, run = matches(gaps[:, 0], gi)
    keep = gaps[run, 1] > ii[end] if right else gaps[run, 2] <= ii[end]
    return end[keep], run[keep]


def _pieces(records, origin, gi, ii, jj, ends, extent, box, hole_pieces, idx, gaps):
    """The owned records' pieces (T6), sorted by record: the column piece (beyond the record's
    cell where it ends its column at the part's edge), and the row band in the member-less columns
    left and right when it ends its row at the part's edge; then each hole's cell, integrated by
    its owner's record (to the part's edge where it is its column's first or last cell of the
    part: ``hole_pieces`` is the :class:`Holes`, the member columns and their first and last
    cells of the part). ``origin``: each record's
    place among the members; ``ends``: the record
    ends its column low, high, its row left, right at the part's edge; ``extent``: per group
    ``cmin, cmax, rmin, rmax``; ``box``: per group the lines every row band stays within
    (``UNBOUNDED`` where no cut); ``gaps``: the group's centre-free runs of member-less columns
    (:func:`_gaps`) and each record's band top (:func:`_next_row`). A row end's band covers every
    such run on its side, and the columns beyond its group's last member column. A column's own
    extension runs to the part's edge: the lattice
    covers every part in range (:func:`sarmitsuba.planning.ray_footprint`), so only the beam's
    edge (where the pattern is at its null) and shadows cut a column, and a shadow is a hole.
    Returns the records, bounds and origins (the member's place, or ``len(idx)`` plus the hole's)
    of the pieces."""
    low, high, left, right = ends
    cmin, cmax, rmin, rmax = extent
    column_gaps, next_row = gaps
    inf = UNBOUNDED
    column = np.stack([ii, ii + 1, np.where(low, -inf, jj), np.where(high, inf, jj + 1)], 1)
    band_lo = np.where(jj > rmin[gi], jj, -inf)
    band_hi = next_row
    pieces = [column,
              np.stack([np.full(ii.size, -inf), cmin[gi], band_lo, band_hi], 1)[left],
              np.stack([cmax[gi] + 1.0, np.full(ii.size, inf), band_lo, band_hi], 1)[right]]
    ends_of = [np.flatnonzero(left), np.flatnonzero(right)]
    for n, side in enumerate((left, right)):         # the member-less column runs between members
        end, run = _run_pieces(gi[side], ii[side], column_gaps, right=n == 1)
        at = np.flatnonzero(side)[end]
        pieces.append(np.stack([column_gaps[run, 1], column_gaps[run, 2], band_lo[at], band_hi[at]], 1))
        ends_of.append(at)
    more = np.concatenate(ends_of)
    out = np.concatenate([records, records[more]])
    src = np.concatenate([origin, origin[more]])
    groups = np.concatenate([gi, gi[more]])
    bounds = np.concatenate(pieces).astype(float)
    lo, hi = box[groups][:, 0::2], box[groups][:, 1::2]
    band = np.arange(len(out)) >= len(records)
    bounds[band] = np.clip(bounds[band], np.repeat(lo, 2, axis=1)[band], np.repeat(hi, 2, axis=1)[band])
    holes, cols, span_lo, span_hi = hole_pieces
    hg, hi_, hj = holes.cells
    col = np.searchsorted(pair_key(cols[:, 0], cols[:, 1]), pair_key(hg, hi_))
    first, last = (hj == span_lo[col], hj == span_hi[col]) if len(cols) else (hj < 0, hj < 0)
    out = np.concatenate([out, idx[holes.owner]])
    src = np.concatenate([src, len(idx) + np.arange(len(hi_))])
    cells = np.stack([hi_, hi_ + 1, np.where(first, -inf, hj), np.where(last, inf, hj + 1)], 1).astype(float)
    bounds = np.concatenate([bounds, cells.reshape(-1, 4)])
    keep = (bounds[:, 1] > bounds[:, 0]) & (bounds[:, 3] > bounds[:, 2])
    out, bounds, src = out[keep], bounds[keep], src[keep]
    order = np.argsort(out, kind="stable")
    return out[order], bounds[order], src[order]
