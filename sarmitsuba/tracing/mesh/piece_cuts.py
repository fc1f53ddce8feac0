"""Cutting regions into pieces on the patch grid (docs/physics.md (M2)): :func:`pieces_of` cuts a
batch of convex regions (each on one part, in its face's frame) into one piece per patch they
meet, *whole* where the patch lies inside the region, else the patch clipped to it;
:func:`cell_key` names a (region, patch) pair. The pieces are :class:`sarmitsuba.tracing.mesh.patches.Pieces`.
"""
from __future__ import annotations

import numpy as np

from .facets import MAX_PART_VERTICES
from .patches import Pieces
from .polygons import clip, moments, pad

__all__ = ["pieces_of", "sweep", "with_small", "cell_lines", "cell_key", "SLIVER", "PIECE_CORNERS", "MAX_CELLS_PER_SIDE"]

#: Cells of one region at most per dimension (a guard against a patch size far below the region).
MAX_CELLS_PER_SIDE = 1 << 20


def cell_key(region: np.ndarray, cell: np.ndarray) -> np.ndarray:
    """An int64 key of ``(region, i, j)``, unique for ``|i|, |j| < 2^20`` and regions < 2^22."""
    return ((region.astype(np.int64) << 42) + ((cell[..., 0].astype(np.int64) + (1 << 20)) << 21)
            + (cell[..., 1].astype(np.int64) + (1 << 20)))


def _row_extents(polygon: np.ndarray, count: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The x-extent ``[lo, hi]`` of convex polygons (rows of ``polygon``) on the horizontal lines
    ``y`` [n] (``lo > hi`` where the line misses the polygon)."""
    width = polygon.shape[1]
    p, q = polygon, np.roll(polygon, -1, axis=1)
    valid = np.arange(width)[None, :] < count[:, None]
    dy = q[..., 1] - p[..., 1]
    t = (y[:, None] - p[..., 1]) / np.where(dy != 0, dy, 1.0)
    meets = valid & (dy != 0) & (t >= 0) & (t <= 1)
    x = p[..., 0] + t * (q[..., 0] - p[..., 0])
    on = valid & (p[..., 1] == y[:, None])            # a corner on the line (horizontal edges too)
    lo = np.minimum(np.where(meets, x, np.inf).min(axis=1), np.where(on, p[..., 0], np.inf).min(axis=1))
    hi = np.maximum(np.where(meets, x, -np.inf).max(axis=1), np.where(on, p[..., 0], -np.inf).max(axis=1))
    return lo, hi


def _line_extents(polygon, count, patch, line_region, line_y, bottom):
    """The extents (:func:`_row_extents`) of regions ``line_region`` [l] on the grid lines
    ``line_y P`` [l], at the rows' bottom lines ``bottom`` [k] and the top lines that follow them:
    ``(lo0, hi0, lo1, hi1)`` [k]."""
    lo, hi = _row_extents(polygon[line_region], count[line_region], line_y * patch)
    return lo[bottom], hi[bottom], lo[bottom + 1], hi[bottom + 1]


def _inner_spans(lo0, hi0, lo1, hi1):
    """The inner span of :func:`_row_spans`: where both of a row's lines lie inside."""
    return np.maximum(lo0, lo1), np.minimum(hi0, hi1)


def _row_spans(polygon: np.ndarray, count: np.ndarray, patch: float, region: np.ndarray, row: np.ndarray,
               on_lines=None):
    """For rows ``row`` [k] of regions ``region`` [k]: the x-extent of the polygon within the
    row's slab ``[row P, (row + 1) P]`` (outer: its corners in the slab and its extents on both
    lines) and on both of its lines (inner: where every point of the slab's height lies inside).
    ``on_lines``: the extents on the rows' lines if known (:func:`_line_extents`)."""
    y0, y1 = row * patch, (row + 1) * patch
    poly, cnt = polygon[region], count[region]
    lo0, hi0, lo1, hi1 = on_lines if on_lines is not None else (*_row_extents(poly, cnt, y0), *_row_extents(poly, cnt, y1))
    slots = np.arange(poly.shape[1])[None, :] < cnt[:, None]
    held = slots & (poly[..., 1] >= y0[:, None]) & (poly[..., 1] <= y1[:, None])
    outer_lo = np.minimum(np.minimum(lo0, lo1), np.where(held, poly[..., 0], np.inf).min(axis=1))
    outer_hi = np.maximum(np.maximum(hi0, hi1), np.where(held, poly[..., 0], -np.inf).max(axis=1))
    return (outer_lo, outer_hi), _inner_spans(lo0, hi0, lo1, hi1)


def pieces_of(polygon: np.ndarray, count: np.ndarray, patch: float, span: np.ndarray | None = None,
              moments=moments) -> Pieces:
    """Cut convex regions into pieces of the patch grid, eq. (M2).

    Each region is swept row by row of the grid: in a row, the patches between the region's
    extents on both of the row's lines lie wholly inside it (a convex region's extent over the
    row is widest at one of its lines and narrowest at one of them), the rest of the patches
    that meet it are clipped to it.

    Parameters
    ----------
    polygon : float64 [r, V, 2]
        The regions (convex, counter-clockwise, face coordinates, m).
    count : int64 [r]
        Their corners (regions with fewer than 3 are skipped).
    patch : float
        Patch size ``P`` [m].
    span : float64 [r, H, 3], optional
        Half-planes that bound where pieces are wanted (the beam's reach): patches wholly outside
        them are left out, but the pieces are the region's own (a span does not cut a patch).
    moments : callable, optional
        The border pieces' moments (:func:`~sarmitsuba.tracing.mesh.polygons.moments`, the
        default, or a function with its signature and results).

    Returns
    -------
    Pieces
    """
    count = np.asarray(count, np.int64)
    reach, reach_count = (polygon, count) if span is None else clip(polygon, count, span)
    extent = polygon.max(axis=1) - polygon.min(axis=1)
    small = np.all(extent <= patch, axis=1) & (reach_count >= 3) & (count >= 3)
    live = np.flatnonzero((reach_count >= 3) & ~small)
    cut = sweep(polygon, count, reach, reach_count, live, patch, moments)
    return with_small(cut, polygon, count, np.flatnonzero(small), patch, moments)


def with_small(cut: Pieces, polygon: np.ndarray, count: np.ndarray, small: np.ndarray, patch: float,
                moments=moments) -> Pieces:
    """``cut`` and one border piece per region of ``small`` (a region no wider than a patch is its
    own piece, whatever patches it straddles: its cell is its centroid's)."""
    if len(small) == 0:
        return cut
    _, centroid, _, _ = moments(polygon[small], count[small])
    width = max(cut.polygon.shape[1], polygon.shape[1])
    poly = np.zeros((len(cut.count) + len(small), width, 2))
    poly[:len(cut.count), :cut.polygon.shape[1]] = cut.polygon
    poly[len(cut.count):, :polygon.shape[1]] = polygon[small]
    counts = np.concatenate([cut.count, count[small]])
    pad(poly, counts)
    border = np.concatenate([cut.border, len(cut.count) + np.arange(len(small))])
    return Pieces(np.concatenate([cut.region, small]), np.concatenate([cut.cell, np.floor(centroid / patch).astype(np.int64)]),
                  np.concatenate([cut.whole, np.zeros(len(small), bool)]), border, poly, counts, patch)


def sweep(polygon, count, reach, reach_count, live, patch: float, moments=moments) -> Pieces:
    """The pieces of regions ``live``, swept row by row (:func:`pieces_of`)."""
    y_lo = np.floor(reach[live, :, 1].min(axis=1) / patch).astype(np.int64)
    y_hi = np.floor(reach[live, :, 1].max(axis=1) / patch).astype(np.int64)
    rows = y_hi - y_lo + 1
    if np.any(rows > MAX_CELLS_PER_SIDE):
        raise ValueError(f"a region spans more than {MAX_CELLS_PER_SIDE} patches of {patch:g} m")
    region = np.repeat(live, rows)
    row = np.repeat(y_lo, rows) + np.arange(int(rows.sum())) - np.repeat(np.cumsum(rows) - rows, rows)
    # the extents on every grid line once (a row's top line is the next row's bottom line)
    lines = rows + 1
    line_region = np.repeat(live, lines)
    line_y = np.repeat(y_lo, lines) + np.arange(int(lines.sum())) - np.repeat(np.cumsum(lines) - lines, lines)
    bottom = np.arange(len(row)) + np.repeat(np.arange(len(live)), rows)      # each row's bottom line
    on_lines = _line_extents(polygon, count, patch, line_region, line_y, bottom)
    reach_on_lines = on_lines if reach is polygon and reach_count is count else \
        _line_extents(reach, reach_count, patch, line_region, line_y, bottom)
    (o_lo, o_hi), _ = _row_spans(reach, reach_count, patch, region, row, reach_on_lines)
    i_lo, i_hi = _inner_spans(*on_lines)
    meets, full = o_hi >= o_lo, i_hi >= i_lo             # (infinite extents where a line misses)
    first = np.floor(np.where(meets, o_lo, 0.0) / patch).astype(np.int64)
    last = np.where(meets, np.maximum(np.ceil(np.where(meets, o_hi, 0.0) / patch).astype(np.int64) - 1, first),
                    first - 1)
    whole_first = np.maximum(np.ceil(np.where(full, i_lo, 0.0) / patch).astype(np.int64), first)
    whole_last = np.where(full, np.minimum(np.floor(np.where(full, i_hi, 0.0) / patch).astype(np.int64) - 1, last),
                          whole_first - 1)
    n_cells = np.maximum(last - first + 1, 0)
    cell_row = np.repeat(np.arange(len(row)), n_cells)
    i = np.repeat(first, n_cells) + np.arange(int(n_cells.sum())) - np.repeat(np.cumsum(n_cells) - n_cells, n_cells)
    whole = (i >= whole_first[cell_row]) & (i <= whole_last[cell_row])
    cell = np.stack([i, row[cell_row]], axis=1)
    region = region[cell_row]
    b = np.flatnonzero(~whole)
    cut, cut_count = clip(np.take(polygon, region[b], axis=0), count[region[b]], cell_lines(cell[b], patch))
    area, _, _, diagonal = moments(cut, cut_count)
    # a sliver a patch line cuts off a corner that the face's float32 vertices put a rounding
    # error across it is no piece: it would make the real piece's border look like a shared
    # patch line (eq. (M5)), and a diffracting edge lose its term (E4)
    kept = (cut_count >= 3) & (area > SLIVER * patch * diagonal)
    keep = np.ones(len(region), bool)
    keep[b[~kept]] = False
    border = np.full(len(region), -1, np.int64)
    border[b[kept]] = np.arange(int(kept.sum()))
    poly = cut[kept]
    rows_kept = np.flatnonzero(keep)
    border = border[rows_kept]
    return Pieces(region[rows_kept], cell[rows_kept], whole[rows_kept], border, poly, cut_count[kept], patch)


#: A cut piece narrower than this share of a patch (its area over the patch and its diagonal) is
#: a rounding sliver and is left out.
SLIVER = 1e-6


def cell_lines(cell: np.ndarray, patch: float) -> np.ndarray:
    """The four half-planes of each patch ``cell`` [n, 2]: float64 [n, 4, 3]."""
    x0, y0 = cell[:, 0] * patch, cell[:, 1] * patch
    lines = np.zeros((len(cell), 4, 3))
    lines[:, 0, 0], lines[:, 1, 0], lines[:, 2, 1], lines[:, 3, 1] = 1.0, -1.0, 1.0, -1.0
    np.negative(x0, out=lines[:, 0, 2])
    np.add(x0, patch, out=lines[:, 1, 2])
    np.negative(y0, out=lines[:, 2, 2])
    np.add(y0, patch, out=lines[:, 3, 2])
    return lines


#: Most corners a piece carries: a part's, plus one per clipping line of a chain and of its patch.
PIECE_CORNERS = MAX_PART_VERTICES + 4
