"""The lanes of a launch on the ray-tube lattice, and their neighbourhoods (docs/physics.md (T6)).

A launch's lanes are the tubes of its blocks (:class:`sarmitsuba.tracing.launches.Blocks`): each block a
rectangle of one sub-aperture and one tube size ``m`` (tubes per coarse cell edge). A lane's
cell is ``(i, j)`` on the lattice of its tube size. The cell plan (:mod:`sarmitsuba.tracing.cell_plan`)
reads each traced cell's 3 x 3 or 5 x 5 neighbourhood of the same size
(:func:`neighbourhoods`), and where blocks of two sizes meet, the other size's lanes about it
(:func:`across_sizes`, bucketed; :func:`across_sizes_reference` the cell-by-cell reference it is
tested against).
"""
from __future__ import annotations

import numpy as np

__all__ = ["OFFSETS", "lane_grid", "neighbourhoods", "across_sizes", "across_sizes_reference"]

#: The centre first, then the four edge neighbours, then the corners (the donor's preference).
OFFSETS = ((0, 0), (-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1))


def lane_grid(blocks, n_lanes):
    """Per lane: block, ``(ii, jj)`` within it, ``n_a``, ``n_j``, its cell ``(i, j)`` on the lattice
    of its tube size, and the tube size ``m`` (all int64 [n_lanes])."""
    sizes = blocks.n_a.astype(np.int64) * blocks.n_j.astype(np.int64)
    block = np.repeat(np.arange(sizes.size), sizes)[:n_lanes]
    rest = np.arange(n_lanes) - blocks.start.astype(np.int64)[block]
    n_j = blocks.n_j.astype(np.int64)[block]
    n_a = blocks.n_a.astype(np.int64)[block]
    ii, jj = rest // n_j, rest % n_j
    m = blocks.m.astype(np.int64)[block]
    return block, ii, jj, n_a, n_j, blocks.i0.astype(np.int64)[block] * m + ii, blocks.j0.astype(np.int64)[block] * m + jj, m


def _cell_key(sub, m, gi, gj):
    """One int64 key per cell of one tube size ``m`` (below 1024: tubes are never finer than a
    quarter wavelength, (T2)) of one sub-aperture (below 8192 in a launch; ``gi``, ``gj``: the cell
    on the lattice of its tube size, within +-2**19)."""
    offset = 1 << 19
    return ((sub * 1024 + m) << 40) + ((gi + offset) << 20) + (gj + offset)


def _traced_cells(traced, grid, sub):
    """A lookup of the traced lanes by cell: ``find(sub, m, gi, gj)`` gives the lane of each cell
    (int64), -1 where no traced lane has it."""
    gi, gj, m = grid[5], grid[6], grid[7]
    have = np.flatnonzero(traced)
    keys = _cell_key(sub[have], m[have], gi[have], gj[have])
    order = np.argsort(keys)
    keys, have = keys[order], have[order]

    def find(sub_, m_, gi_, gj_):
        want = _cell_key(sub_, m_, gi_, gj_)
        if len(keys) == 0:
            return np.full(want.shape, -1, np.int64)
        at = np.minimum(np.searchsorted(keys, want), len(keys) - 1)
        return np.where(keys[at] == want, have[at], -1)
    return find


def neighbourhoods(lanes, traced, grid, sub, reach: int = 1):
    """The traced neighbours of ``lanes`` on the lattice of their tube size, in any block of their
    sub-aperture, ``reach`` cells around (1: the 3 x 3 in :data:`OFFSETS` order): int64
    [n, (2 reach + 1)^2], -1 where there is none (no traced cell of that size there: the beam's
    edge, or a block of another tube size)."""
    gi, gj, m = grid[5], grid[6], grid[7]
    offsets = OFFSETS if reach == 1 else [(di, dj) for di in range(-reach, reach + 1) for dj in range(-reach, reach + 1)]
    find = _traced_cells(traced, grid, sub)
    out = np.full((lanes.size, len(offsets)), -1, np.int64)
    for k, (di, dj) in enumerate(offsets):
        out[:, k] = find(sub[lanes], m[lanes], gi[lanes] + di, gj[lanes] + dj)
    return out


def across_sizes(lanes, traced, grid, sub, reach: int = 1, signature=None):
    """:func:`across_sizes_reference`'s pairs, with the other size's lanes of one signature
    (``signature``, int64 [n_lanes]: what the plan reads of a lane, equal for interchangeable
    lanes; None: every lane its own) in one cell of ``lanes``' lattice given once.

    Finer lanes are put in buckets by the cell of the coarser lattice they lie in (a finer cell
    lies in one coarser cell where the sizes divide, in up to two per axis otherwise), so each of
    ``lanes`` looks up its ``(2 reach + 1)^2`` cells' buckets; coarser lanes are looked up cell by
    cell, as in the reference (a few per axis). Returns ``(row, lane)`` int64 pairs."""
    gi, gj, m = grid[5], grid[6], grid[7]
    signature = np.arange(m.size, dtype=np.int64) if signature is None else signature
    out_row, out_lane = [], []
    sizes = np.unique(m[traced]).tolist()
    for m2 in sizes:
        targets = np.flatnonzero(traced & (m == m2))
        for m1 in np.unique(m[lanes]).tolist():
            at = np.flatnonzero(m[lanes] == m1)
            if m1 == m2 or at.size == 0:
                continue
            lane = lanes[at]
            if m2 < m1:                  # coarser neighbours: at most a few cells per axis
                row, found = _cells_about(lane, targets, grid, sub, reach, m1, m2)
                out_row.append(at[row])
                out_lane.append(found)
                continue
            # finer neighbours: bucketed by the cell of the lattice m1 they lie in
            ci = [(gi[targets] * m1) // m2, ((gi[targets] + 1) * m1 - 1) // m2]
            cj = [(gj[targets] * m1) // m2, ((gj[targets] + 1) * m1 - 1) // m2]
            keys = np.concatenate([_cell_key(sub[targets], m1, a, b) for a in ci for b in cj])
            owner = np.tile(targets, 4)
            pair = np.unique(np.stack([keys, signature[owner]], 1), axis=0, return_index=True)[1]
            keys, owner = keys[pair], owner[pair]
            order = np.argsort(keys, kind="stable")
            keys, owner = keys[order], owner[order]
            for di in range(-reach, reach + 1):
                for dj in range(-reach, reach + 1):
                    want = _cell_key(sub[lane], m1, gi[lane] + di, gj[lane] + dj)
                    first = np.searchsorted(keys, want)
                    count = np.searchsorted(keys, want, side="right") - first
                    rows = np.repeat(np.arange(lane.size), count)
                    within = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
                    out_row.append(at[rows])
                    out_lane.append(owner[np.repeat(first, count) + within])
    if not out_row:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(out_row), np.concatenate(out_lane)


def _cells_about(lane, targets, grid, sub, reach, m1, m2):
    """The lanes ``targets`` (tube size ``m2``, coarser than ``lane``'s ``m1``) whose cells meet the
    ``(2 reach + 1)^2`` cells about each of ``lane``: ``(row, target)`` pairs, cell by cell."""
    gi, gj = grid[5], grid[6]
    keys = _cell_key(sub[targets], m2, gi[targets], gj[targets])
    order = np.argsort(keys)
    keys, targets = keys[order], targets[order]
    rows, found = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    if keys.size == 0:
        return rows[0], found[0]
    lo_i, hi_i = (gi[lane] - reach) * m2 // m1, -((-(gi[lane] + reach + 1) * m2) // m1)
    lo_j, hi_j = (gj[lane] - reach) * m2 // m1, -((-(gj[lane] + reach + 1) * m2) // m1)
    for di in range(int((hi_i - lo_i).max(initial=0))):
        for dj in range(int((hi_j - lo_j).max(initial=0))):
            want = _cell_key(sub[lane], m2, lo_i + di, lo_j + dj)
            at = np.minimum(np.searchsorted(keys, want), keys.size - 1)
            ok = (lo_i + di < hi_i) & (lo_j + dj < hi_j) & (keys[at] == want)
            rows.append(np.flatnonzero(ok))
            found.append(targets[at[ok]])
    return np.concatenate(rows), np.concatenate(found)


def across_sizes_reference(lanes, traced, grid, sub, reach: int = 1):
    """The traced lanes of *other* tube sizes, in the same sub-aperture, whose cells meet the
    ``(2 reach + 1)^2`` cells about each of ``lanes`` (on the lattice of its own size): where
    blocks of two tube sizes meet (the refinement of (T2)), the neighbours that
    :func:`neighbourhoods` cannot name. Blocks start on coarse cells, so a cell ``(i, j)`` of
    size ``m`` covers ``[i / m, (i + 1) / m)`` coarse cells. Returns ``(row, lane)`` int64 pairs,
    ``row`` indexing ``lanes``: every such lane, each cell of the region looked up in turn (the
    readable reference of :func:`across_sizes`, which is quadratic in the size ratio: a coarse
    cell next to tubes 69 times finer looks up 345^2 cells)."""
    gi, gj, m = grid[5], grid[6], grid[7]
    find = _traced_cells(traced, grid, sub)
    out_row, out_lane = [], []
    for m2 in np.unique(m[traced]).tolist():
        at = np.flatnonzero(m[lanes] != m2)
        if at.size == 0:
            continue
        lane, m1 = lanes[at], m[lanes[at]]
        lo_i, hi_i = (gi[lane] - reach) * m2 // m1, -((-(gi[lane] + reach + 1) * m2) // m1)
        lo_j, hi_j = (gj[lane] - reach) * m2 // m1, -((-(gj[lane] + reach + 1) * m2) // m1)
        for di in range(int((hi_i - lo_i).max())):
            for dj in range(int((hi_j - lo_j).max())):
                found = find(sub[lane], np.full(lane.size, m2), lo_i + di, lo_j + dj)
                ok = (lo_i + di < hi_i) & (lo_j + dj < hi_j) & (found >= 0)
                out_row.append(at[ok])
                out_lane.append(found[ok])
    if not out_row:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(out_row), np.concatenate(out_lane)
