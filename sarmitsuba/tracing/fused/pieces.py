"""Regions cut into pieces of the patch grid on the Dr.Jit device (docs/physics.md (M2),
docs/design.md section 10.1).

:func:`sarmitsuba.tracing.mesh.piece_cuts.pieces_of` is the readable NumPy reference: every convex
region is swept row by row of the grid; in a row, the patches between its extents on both of the
row's lines are whole, the other patches the row's slab meets are clipped to the region. Here the
same pieces, in the same order and to the bit, come from two kernels, one lane per (region, grid
row), the rows of each region in increasing order, the regions in theirs:

1. *rows*: a loop over the region's corners gives its x-extents on the row's two grid lines
   (``t = (y - p_y) / dy``, ``x = p_x + t (q_x - p_x)`` for the edges that cross a line, and the
   corners on it; ``+inf`` / ``-inf`` where the line misses), the same for the reach (the region
   clipped to ``span``) with the reach's corners inside the slab; from them the row's first cell
   (the reach's outer span), its whole cells (the region's inner span), its number of cells and
   of border cells;
2. *pieces*: once the host has clipped the border cells and found the slivers among them, the
   prefix sum of the rows' pieces (whole cells and kept border cells) gives each row its block of
   the output (CSR: count, prefix sum, write; no atomics, no order from thread timing), and each
   lane writes its pieces there: region, cell ``(i, row)``, whole, border row.

The host keeps the rest of the reference as it is: the reach (``polygons.clip``), the regions no
wider than a patch (their own pieces, the reference's ``with_small``), the border cells (two
ranges of ``i`` per row, either side of the whole ones, made with ``np.repeat``) clipped to their
patches (``polygons.clip``, which has its own kernel for large batches) and the slivers dropped by
their moments (``moments=``, by default :func:`sarmitsuba.tracing.mesh.polygons.moments`). The
outputs are the kernels' own buffers, viewed by NumPy (no copy).

Every float64 operation of the kernels is the reference's, in its order (Dr.Jit's LLVM backend
does not contract products and sums into FMAs); divisions by the patch size divide by an opaque
value (Dr.Jit turns a division by a literal into a product with its reciprocal); minima and maxima
are written as NumPy computes them (``np.maximum(x, y)`` is ``x > y ? x : y``). The results agree
bit for bit with the reference on the ``llvm`` variants (tests/test_fused_pieces.py); the ``cuda``
variants have not been compared.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..device import device_array, releasing, table_array
from ..loops import RECORDING, loop_mode
from ..mesh import piece_cuts
from ..mesh.patches import Pieces
from ..mesh.polygons import clip
from ..mesh.polygons import moments as reference_moments

__all__ = ["KERNEL_REGIONS", "pieces_of"]

#: Batches of fewer regions than this are cut by the reference. Measured on slices of Munich's
#: batches (2 shared cores, medians of 15): the kernels gain 0-30 % from 256 regions on, nothing
#: measurable below; a batch of ``simulate("urban")`` (79 regions, 3 ms) took 8 ms with them, the
#: launches waiting for Dr.Jit's worker threads on a loaded machine.
KERNEL_REGIONS = 512


@releasing
def pieces_of(polygon: np.ndarray, count: np.ndarray, patch: float, span: np.ndarray | None = None, *,
              moments=reference_moments) -> Pieces:
    """:func:`sarmitsuba.tracing.mesh.piece_cuts.pieces_of` with its row sweep on the device: the
    same pieces, every field bit for bit, eq. (M2) of docs/physics.md.

    Parameters and result are the reference's (``polygon`` float64 [r, V, 2], ``count`` int64 [r],
    ``patch`` [m], ``span`` float64 [r, H, 3] or None, ``moments`` a function with the signature of
    :func:`sarmitsuba.tracing.mesh.polygons.moments`); batches of fewer than
    :data:`KERNEL_REGIONS` regions are the reference's own.
    """
    polygon = np.asarray(polygon)
    if polygon.dtype != np.float64 or polygon.ndim != 3 or len(polygon) < KERNEL_REGIONS or polygon.shape[1] == 0:
        return _reference(polygon, count, patch, span, moments)
    count = np.asarray(count, np.int64)
    reach, reach_count = (polygon, count) if span is None else clip(polygon, count, span)
    low, high = polygon[:, 0].copy(), polygon[:, 0].copy()     # the box over every slot, a slot at a
    for k in range(1, polygon.shape[1]):                            # time (as ``max(axis=1)``, faster)
        np.minimum(low, polygon[:, k], out=low)
        np.maximum(high, polygon[:, k], out=high)
    small = np.all(high - low <= patch, axis=1) & (reach_count >= 3) & (count >= 3)
    live = np.flatnonzero((reach_count >= 3) & ~small)
    cut = _sweep(polygon, count, np.asarray(reach, np.float64), reach_count, live, patch, moments)
    return piece_cuts.with_small(cut, polygon, count, np.flatnonzero(small), patch, moments)


def _reference(polygon, count, patch, span, moments):
    """The reference itself, its moments ``moments``."""
    return piece_cuts.pieces_of(polygon, count, patch, span, moments=moments)


def _sweep(polygon, count, reach, reach_count, live, patch: float, moments) -> Pieces:
    """The pieces of regions ``live`` (int64 [l]), swept row by row on the device; the reference's
    ``sweep``."""
    y_lo = np.floor(reach[live, :, 1].min(axis=1) / patch).astype(np.int64)
    y_hi = np.floor(reach[live, :, 1].max(axis=1) / patch).astype(np.int64)
    rows = y_hi - y_lo + 1
    if np.any(rows > piece_cuts.MAX_CELLS_PER_SIDE):
        raise ValueError(f"a region spans more than {piece_cuts.MAX_CELLS_PER_SIDE} patches of {patch:g} m")
    n_rows = int(rows.sum())
    if n_rows == 0:                     # nothing to sweep: the reference's empty pieces
        return piece_cuts.sweep(polygon, count, reach, reach_count, live, patch, moments)
    region = np.repeat(live, rows)
    row = np.repeat(y_lo - (np.cumsum(rows) - rows), rows) + np.arange(n_rows)
    i64 = mi.Int64
    tables = _corner_table(polygon, count)
    reach_tables = tables if reach is polygon else _corner_table(reach, reach_count)
    with RECORDING:                     # symbolic loops: recorded and run one thread at a time
        p = dr.opaque(mi.Float64, patch)
        lanes = (device_array(i64, region), device_array(i64, row))
        spans = _rows_kernel(lanes, tables, reach_tables, (polygon.shape[1], reach.shape[1]), p)
        dr.eval(spans)
    first, whole_first, whole_last, n_cells, n_border = (x.numpy() for x in spans)
    b_at = np.cumsum(n_border) - n_border
    region_b, cell_b = _border_cells(region, row, first, whole_first, whole_last, n_cells, n_border)
    cut, cut_count = clip(np.take(polygon, region_b, axis=0), count[region_b], piece_cuts.cell_lines(cell_b, patch))
    area, _, _, diagonal = moments(cut, cut_count)
    kept = (cut_count >= 3) & (area > piece_cuts.SLIVER * patch * diagonal)
    ranks = np.zeros(len(kept) + 1, np.int64)
    np.cumsum(kept, out=ranks[1:])
    n_out = n_cells - n_border + ranks[b_at + n_border] - ranks[b_at]
    total = int(n_out.sum())
    with RECORDING:
        index = table_array(i64, np.where(kept, ranks[:-1], -1) if len(kept) else np.full(1, -1))
        room = max(total, 1)
        pieces = (dr.zeros(i64, room), dr.zeros(i64, room * 2), dr.zeros(mi.Bool, room), dr.zeros(i64, room))
        _pieces_kernel(lanes + spans[:4] + (device_array(i64, b_at), device_array(i64, np.cumsum(n_out) - n_out)),
                       index, pieces)
        dr.eval(pieces)
    region, cell, whole, border = (x.numpy() for x in pieces)
    return Pieces(region[:total], cell[:2 * total].reshape(total, 2), whole[:total], border[:total],
                  cut if kept.all() else cut[kept], cut_count[kept], patch)


def _border_cells(region, row, first, whole_first, whole_last, n_cells, n_border):
    """The border cells of rows ``row`` of regions ``region`` (int64 [k]), row by row, by ``i``:
    those left of the row's whole cells, then those right of them (all of them in a row without
    whole cells). Returns ``(region int64 [b], cell int64 [b, 2])``."""
    n_b = int(n_border.sum())
    left = np.where(n_border < n_cells, whole_first - first, n_cells)
    size = np.stack([left, n_border - left], axis=1).reshape(-1)
    start = np.stack([first, np.maximum(whole_last + 1, first)], axis=1).reshape(-1)
    cell = np.empty((n_b, 2), np.int64)
    cell[:, 0] = np.repeat(start - (np.cumsum(size) - size), size) + np.arange(n_b)
    cell[:, 1] = np.repeat(row, n_border)
    return np.repeat(region, n_border), cell


def _corner_table(poly: np.ndarray, count: np.ndarray):
    """A batch [r, V, 2] and its counts [r] as flat device tables ``(x, y, count)``."""
    return (table_array(mi.Float64, np.ascontiguousarray(poly[..., 0]).reshape(-1)),
            table_array(mi.Float64, np.ascontiguousarray(poly[..., 1]).reshape(-1)),
            table_array(mi.Int64, count))


def _np_max(x, y):
    """``np.maximum(x, y)`` (``x > y ? x : y``: the second of two equal zeros)."""
    return dr.select(x > y, x, y)


def _np_min(x, y):
    """``np.minimum(x, y)`` (``x < y ? x : y``)."""
    return dr.select(x < y, x, y)


def _crossing(p, q, valid, y, acc):
    """One edge ``p -> q`` (corners ``(x, y)``) of a region on the line ``y``, the reference's
    ``_row_extents``: ``acc`` = (least and greatest crossing, least and greatest corner on the
    line) updated."""
    lo_x, hi_x, lo_on, hi_on = acc
    dy = q[1] - p[1]
    moving = dy != 0
    t = (y - p[1]) / dr.select(moving, dy, 1.0)
    meets = valid & moving & (t >= 0) & (t <= 1)
    x = p[0] + t * (q[0] - p[0])
    on = valid & (p[1] == y)
    return (dr.select(meets, _np_min(lo_x, x), lo_x), dr.select(meets, _np_max(hi_x, x), hi_x),
            dr.select(on, _np_min(lo_on, p[0]), lo_on), dr.select(on, _np_max(hi_on, p[0]), hi_on))


def _extents(tables, g, width, y0, y1, held: bool):
    """A region's x-extents ``(lo0, hi0, lo1, hi1)`` on the lines ``y0``, ``y1`` (the reference's
    ``_row_extents``; ``lo > hi`` where a line misses) and, if ``held``, the least and greatest x
    of its corners in the slab ``[y0, y1]`` (``+inf``, ``-inf`` if none)."""
    f64, u32 = mi.Float64, mi.UInt32
    xs, ys, counts = tables
    n = dr.width(g)
    used = dr.gather(mi.Int64, counts, g)
    start = g * width
    inf = dr.full(f64, np.inf, n)
    state = (dr.zeros(u32, n),) + tuple(dr.copy(v) for _ in range(5) for v in (inf, -inf))

    def step(k, *acc):
        nxt = dr.select(k + 1 == width, 0, k + 1)
        p = (dr.gather(f64, xs, start + k), dr.gather(f64, ys, start + k))
        q = (dr.gather(f64, xs, start + nxt), dr.gather(f64, ys, start + nxt))
        valid = mi.Int64(k) < used
        a = _crossing(p, q, valid, y0, acc[0:4]) + _crossing(p, q, valid, y1, acc[4:8])
        if not held:
            return (k + 1,) + a + acc[8:]
        inside = valid & (p[1] >= y0) & (p[1] <= y1)
        return (k + 1,) + a + (dr.select(inside, _np_min(acc[8], p[0]), acc[8]),
                               dr.select(inside, _np_max(acc[9], p[0]), acc[9]))

    out = dr.while_loop(state, lambda k, *_: k < width, step, mode=loop_mode(),
                        label="reach corners" if held else "region corners")
    a = out[1:]
    lo0, hi0 = _np_min(a[0], a[2]), _np_max(a[1], a[3])
    lo1, hi1 = _np_min(a[4], a[6]), _np_max(a[5], a[7])
    return lo0, hi0, lo1, hi1, a[8], a[9]


def _rows_kernel(lanes, tables, reach_tables, widths, patch):
    """The first kernel of :func:`pieces_of`: per row (``lanes``: region, grid row ``j``, Int64),
    its first cell, its first and last whole cells, its number of cells and of border cells
    (Int64: ``(first, whole_first, whole_last, n_cells, n_border)``), the reference's ``sweep``
    arithmetic in its order; ``patch`` [m] an opaque Float64."""
    region, row = lanes[0], lanes[1]
    f64, i64 = mi.Float64, mi.Int64
    region = mi.UInt32(region)
    y0, y1 = f64(row) * patch, f64(row + 1) * patch
    width, reach_width = (dr.opaque(mi.UInt32, w) for w in widths)
    lo0, hi0, lo1, hi1, _, _ = _extents(tables, region, width, y0, y1, False)
    r_lo0, r_hi0, r_lo1, r_hi1, h_lo, h_hi = _extents(reach_tables, region, reach_width, y0, y1, True)
    o_lo = _np_min(_np_min(r_lo0, r_lo1), h_lo)
    o_hi = _np_max(_np_max(r_hi0, r_hi1), h_hi)
    i_lo, i_hi = _np_max(lo0, lo1), _np_min(hi0, hi1)
    meets, full = o_hi >= o_lo, i_hi >= i_lo
    first = i64(dr.floor(dr.select(meets, o_lo, 0.0) / patch))
    last = dr.select(meets, _np_max(i64(dr.ceil(dr.select(meets, o_hi, 0.0) / patch)) - 1, first), first - 1)
    whole_first = _np_max(i64(dr.ceil(dr.select(full, i_lo, 0.0) / patch)), first)
    whole_last = dr.select(full, _np_min(i64(dr.floor(dr.select(full, i_hi, 0.0) / patch)) - 1, last),
                           whole_first - 1)
    n_cells = _np_max(last - first + 1, 0)
    n_border = n_cells - _np_max(_np_min(whole_last, last) - whole_first + 1, 0)
    return first, whole_first, whole_last, n_cells, n_border


def _pieces_kernel(lanes, index, out):
    """The second kernel of :func:`pieces_of`: each row writes its pieces (its whole cells and its
    border cells whose clipped piece is kept, ``index`` >= 0 at their border row) from row
    ``at`` of ``out`` on: region, cell ``(i, row)`` (flat [n * 2]), whole, border row (-1: whole)."""
    region, row, first, whole_first, whole_last, n_cells, b_at, at = lanes
    region_out, cell_out, whole_out, border_out = out
    i64, u32 = mi.Int64, mi.UInt32
    n = dr.width(first)

    def write(k, i, m, w):
        whole = (i >= whole_first) & (i <= whole_last)
        border = dr.select(whole, -1, dr.gather(i64, index, u32(b_at + m), ~whole))
        real = whole | (border >= 0)
        slot = u32(at + w)
        dr.scatter(region_out, region, slot, real)
        dr.scatter(cell_out, i, 2 * slot, real)
        dr.scatter(cell_out, row, 2 * slot + 1, real)
        dr.scatter(whole_out, whole, slot, real)
        dr.scatter(border_out, border, slot, real)
        return k + 1, i + 1, dr.select(whole, m, m + 1), dr.select(real, w + 1, w)

    dr.while_loop((dr.zeros(i64, n), dr.copy(first), dr.zeros(i64, n), dr.zeros(i64, n)),
                  lambda k, *_: k < n_cells, write, mode=loop_mode(), label="pieces")
