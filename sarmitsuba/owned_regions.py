"""Owned regions: a partition of a facet among the ray tubes that meet it (docs/physics.md (T6)).

The readable NumPy reference of the design chosen for issue 26's lit regions; the kernel does
not use it yet. A tube whose central ray meets a convex facet (a *member*, decided once per
sub-aperture at its reference position) owns a convex region of the facet's plane:

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

import numpy as np

__all__ = ["HalfPlane", "owned_regions", "clip_convex", "region_polygons"]

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

