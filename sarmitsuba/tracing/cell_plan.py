"""Cell pieces: each lattice cell integrates exactly what its tubes' chains see in it
(docs/physics.md (T6)). The plan, in NumPy.

The tracer records, per bounce order ``d`` and per lattice cell (lane) of a launch, the convex
part its central ray met (:mod:`sarmitsuba.tracing.facets`), the hash of the facets met so far (the
chain's key), and whether the hit sees the antenna (and if not, the part that hides it). A
cell whose 3 x 3 neighbourhood of traced central rays (on the lattice of its tube size, in any
block of its sub-aperture) all reached the same chain, all visible, keeps its whole tile (PO5).
Every other cell with a visible hit in its 3 x 3 is *mixed* (a missing neighbour counts as a
change: the beam's edge, or a block of another tube size, whose lanes about the cell
(:func:`across_sizes`) join its candidates and occluders): for each chain
``C = (X_0, ..., X_d)`` that a visible hit of its neighbourhood followed (a *candidate*), the
cell integrates

    cell ∩ X_0' ∩ X_1'' ∩ ... ∩ X_d^(d)  less the parts in front at each level, less the parts
    that hide the last hit from the antenna,

where ``X_i^(i)`` is part ``X_i`` mirrored in the planes of ``X_0 .. X_{i-1}`` and projected from
the pulse's antenna onto the aim plane. The parts in front at level ``i`` are those that the
neighbourhood's rays with the same chain up to ``i - 1`` met instead of ``X_i``; the receive
side's are the parts that hid the neighbourhood's hits of the same chain. A piece takes out the
exact union of all its occluders (the kernel trims every boundary edge by the others'
projections); pieces are launched in groups of equal occluder counts (:data:`OCCLUDER_GROUPS`),
a piece with more than the most split into quarters of its cell (:func:`split_crowded`).

The candidates also include the chains of the 5 x 5 neighbourhood whose last part reaches into
the cell from some view (a part's acute corner, a small occluder, between the central rays; cells
with no visible hit in their 3 x 3 are examined for these too), and the chains ending on a part
adjacent to a candidate's last part (sharing a corner) that reaches into the cell: a wall seen
nearly edge-on, narrower than a cell, that no central ray met.

Everything here is host-side bookkeeping; the per-pulse integrals are
:class:`sarmitsuba.tracing.cell_terms.CellTerms`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cell_lanes import across_sizes, lane_grid, neighbourhoods
from .cell_split import MOST_OCCLUDERS, NONE, ON_PLANE, RECEIVE, meets, split_crowded
from .lattice_index import pair_key

__all__ = ["CellPlan", "LaneTable", "plan_cells", "split_crowded", "occluder_groups", "OCCLUDER_GROUPS", "MOST_OCCLUDERS", "RECEIVE", "NONE"]

#: Occluder counts of the launches: a piece with ``k`` occluders goes to the first group of at
#: least ``k`` (the rest padded with :data:`NONE`), so that few kernels serve all counts; a piece
#: with more than the last is split (:data:`MOST_OCCLUDERS`). No occluder is ever left out: Munich has
#: pieces behind up to 18, and keeping only the first eight let a shadowed roof light up where the
#: others fell (a spot that moved with the lattice: -25.8 dB against -43.5 dB with all of them).
OCCLUDER_GROUPS = (1, 2, 3, 4, 6, 8, 12, 16)
_MISS = -1
#: A prime below 2**31 for the face chain's running hash (:func:`face_keys`).
_PRIME = 2_147_483_647


@dataclass(frozen=True)
class LaneTable:
    """What each lane's central ray met at one bounce order: int64 [n_lanes] each.

    ``part`` the convex part (-1: nothing, or no part), ``key`` the chain's key (-1: nothing),
    ``visible`` whether the hit sees the antenna, ``blocker`` the part that hides it (-1)."""

    part: np.ndarray
    key: np.ndarray
    visible: np.ndarray
    blocker: np.ndarray


@dataclass(frozen=True)
class CellPlan:
    """The pieces of one bounce order's mixed cells.

    Attributes
    ----------
    replaced : bool [n_records]
        The record's tile is replaced by its cell's pieces.
    record : int64 [n_pieces]
        A record of the cell's neighbourhood (its sub-aperture, block and chain's reflections).
    chain : int64 [n_pieces, depth + 1]
        The piece's parts, level by level.
    bounds : float64 [n_pieces, 4]
        The cell: x0, x1, y0, y1 in lattice lines of its tube size.
    cuts : list of (int64 [n], int64 [n, k], int64 [n, k])
        The pieces with occluders, grouped by :data:`OCCLUDER_GROUPS`: for group ``k``, the
        pieces, their occluders' parts and levels (``RECEIVE`` for the receive side, ``NONE``
        for padding). Each piece is integrated less the union of its occluders' projections;
        the pieces in no group have none.
    """

    replaced: np.ndarray
    record: np.ndarray
    chain: np.ndarray
    bounds: np.ndarray
    cuts: list


def plan_cells(depth, tables, records, traced, blocks, n_lanes, parts, views, fp) -> CellPlan:
    """The pieces of bounce order ``depth``'s mixed cells.

    Parameters
    ----------
    depth : int
        Bounce order (0: first bounce).
    tables : list of LaneTable
        Bounce orders ``0 .. depth``.
    records : int64 [n_records]
        The lane of each record (visible hit) of this order.
    traced : bool [n_lanes]
        The lanes the launch traced.
    blocks : launches.Blocks
    parts : (vertices [n_parts, V, 3], face [n_parts], normal [n_parts, 3], offset [n_parts],
        adjacency_start, adjacency, closed)
    views : float64 [n_subapertures, 3, 3]
        Each sub-aperture's reference position, first and last antenna position.
    fp : RayFootprint
    """
    tables = face_keys(tables, parts[1])
    table = tables[depth]
    n_rec = len(records)
    rec_of = np.full(n_lanes, -1, np.int64)
    rec_of[records] = np.arange(n_rec)
    grid = lane_grid(blocks, n_lanes)
    block, gi, gj, m = grid[0], grid[5], grid[6], grid[7]
    lanes = np.flatnonzero(traced)
    state = np.where(rec_of >= 0, table.key, _MISS)                    # a visible chain, or a miss
    sub = blocks.sub.astype(np.int64)[block]
    nb = neighbourhoods(lanes, traced, grid, sub)
    safe = np.maximum(nb, 0)
    r = np.where(nb >= 0, rec_of[safe], -1)
    has = r >= 0
    s3 = state[safe]
    # a neighbour of another chain, hidden, or missing (beyond the beam, or tubes of another size)
    mixed = ((s3 != s3[:, :1]) | (nb < 0)).any(1) & has.any(1)
    # cells whose own chain runs on, but near a change (5 x 5): a corner of an adjacent part may
    # reach into them between the central rays
    wide = neighbourhoods(lanes, traced, grid, sub, reach=2)
    near = ~mixed & has[:, 0] & ((state[np.maximum(wide, 0)] != state[lanes][:, None]) & (wide >= 0)).any(1)
    bad = (has & (table.part[safe] < 0)).any(1)                         # shapes with no parts keep tiles
    mixed &= ~bad
    near &= ~bad
    # where blocks of two tube sizes meet, the other size's lanes about the cell (its visible
    # hits of parts only)
    edge = np.flatnonzero((wide < 0).any(1))
    x_row, x_lane = across_sizes(lanes[edge], traced, grid, sub, reach=2, signature=_signature(tables, rec_of))
    x_row = edge[x_row]
    changed = np.bincount(x_row[state[x_lane] != state[lanes[x_row]]], minlength=lanes.size) > 0
    near |= ~mixed & has[:, 0] & changed & ~bad
    x_vis = (rec_of[x_lane] >= 0) & (table.part[x_lane] >= 0)
    x_row, x_lane = x_row[x_vis], x_lane[x_vis]
    # cells with no visible hit in their 3 x 3 but some in their 5 x 5 (or of the other size): a
    # part's acute corner can reach into them past the central rays
    wide_safe = np.maximum(wide, 0)
    has5 = (wide >= 0) & (rec_of[wide_safe] >= 0)
    fringe = ~has.any(1) & (has5.any(1) | (np.bincount(x_row, minlength=lanes.size) > 0)) \
        & ~(has5 & (table.part[wide_safe] < 0)).any(1)
    look = mixed | near | fringe
    row_of = np.cumsum(look) - 1
    x_row, x_lane = row_of[x_row[look[x_row]]], x_lane[look[x_row]]
    cell, nb, wide, has5, has = lanes[look], nb[look], wide[look], has5[look], has[look]
    mixed = (mixed | fringe)[look]
    # candidates: the distinct visible chains of the 3 x 3 (first record in :data:`cell_lanes.OFFSETS` order; a cell
    # near a change only its own), then those of the 5 x 5 whose last part reaches into the cell
    key3 = np.where(has, table.key[np.maximum(nb, 0)], _MISS)
    first = has.copy()
    first[~mixed, 1:] = False
    for k in range(1, 9):
        for q in range(k):
            first[:, k] &= key3[:, k] != key3[:, q]
    c_of, col = np.nonzero(first)
    donor_lane = nb[c_of, col]
    rows, cols = np.nonzero(has5)
    rows, w_lanes = np.concatenate([rows, x_row]), np.concatenate([wide[rows, cols], x_lane])
    keys5 = rows * (1 << 33) + table.key[w_lanes]
    keys5, first5 = np.unique(keys5, return_index=True)
    new = ~np.isin(keys5, c_of * (1 << 33) + table.key[donor_lane])
    w_row, w_donor = rows[first5][new], w_lanes[first5][new]
    w_chain = np.stack([tables[i].part[w_donor] for i in range(depth + 1)], 1)
    reach = np.all(w_chain >= 0, 1)
    reach[reach] = _reaches(cell[w_row[reach]], w_chain[reach], w_chain[reach, -1], grid, blocks, parts, views, fp)
    chain = np.stack([tables[i].part[donor_lane] for i in range(depth + 1)], 1)
    c_of, chain, donor_lane = (np.concatenate([c_of, w_row[reach]]), np.concatenate([chain, w_chain[reach]]),
                               np.concatenate([donor_lane, w_donor[reach]]))
    c_of, chain, donor_lane = _adjacent(c_of, chain, donor_lane, cell, grid, blocks, parts, views, fp)
    pieced = mixed | (np.bincount(c_of, minlength=len(cell)) > 1)
    keep = pieced[c_of]
    c_of, chain, donor_lane = c_of[keep], chain[keep], donor_lane[keep]
    occluders = _near_occluders(depth, tables, c_of, chain, donor_lane, _neighbours(c_of, nb, x_row, x_lane),
                                cell, grid, blocks, parts, views, fp)
    replaced = np.zeros(n_rec, bool)
    own = rec_of[cell[pieced]]
    replaced[own[own >= 0]] = True
    return _pieces(depth, replaced, cell[c_of], chain, donor_lane, rec_of, occluders, grid, blocks, parts, views, fp)


def _pieces(depth, replaced, c_lane, chain, donor_lane, rec_of, occluders, grid, blocks, parts, views, fp):
    """The plan of pieces on cells ``c_lane`` with their donors and occluders, crowded pieces
    split (:func:`split_crowded`)."""
    gi, gj, m = grid[5], grid[6], grid[7]
    # the cell in lattice lines of the donor's tube size (the kernel reads the donor's block)
    scale = m[donor_lane].astype(float)
    bounds = np.stack([gi[c_lane], gi[c_lane] + 1, gj[c_lane], gj[c_lane] + 1], 1) * (scale / m[c_lane])[:, None]
    sub = blocks.sub.astype(np.int64)[grid[0][c_lane]]
    index, bounds, occluders = split_crowded(depth, chain, sub, scale, bounds, occluders, parts, views, fp)
    cuts = occluder_groups(*occluders, len(index))
    return CellPlan(replaced=replaced, record=rec_of[donor_lane][index], chain=chain[index], bounds=bounds, cuts=cuts)


def _signature(tables, rec_of):
    """One int64 per lane for what the plan reads of it (its chain's keys and parts, whether it
    is a record, its visibility and blocker): lanes of one signature are interchangeable."""
    columns = [rec_of >= 0] + [value for t in tables for value in (t.key, t.part, t.visible, t.blocker)]
    return np.unique(np.stack(columns, 1).astype(np.int64), axis=0, return_inverse=True)[1].ravel()


def face_keys(tables, face):
    """The lane tables with each chain's key made that of its faces too: the tracer's key hashes
    the shapes and planes met, so two faces of one shape in one plane (a shape's roofs at one
    height, the squares of a grating) would be one chain, and a cell between them would integrate
    only the donor's. Faces are the coplanar, edge-connected triangles of one shape
    (:mod:`sarmitsuba.tracing.facets`); the convex parts of one face stay one chain, as their shared edges
    bound nothing. Keys stay in [0, 2**32), -1 where nothing was met."""
    out, chain = [], None
    for table in tables:
        f = np.where(table.part >= 0, face[np.maximum(table.part, 0)], -1).astype(np.int64)
        chain = f + 1 if chain is None else (chain * 1_000_003 + f + 1) % _PRIME
        key = np.where(table.key >= 0, (table.key * 2_654_435_761 + chain) % (1 << 32), -1)
        out.append(LaneTable(part=table.part, key=key, visible=table.visible, blocker=table.blocker))
    return out


def _adjacent(c_of, chain, donor_lane, cell, grid, blocks, parts, views, fp):
    """Add, to the candidates, each chain whose last part is adjacent to a candidate's (sharing a
    corner) where that part, unfolded as the candidate's, meets the cell from some view and faces
    the antenna (or belongs to an open surface)."""
    adj_start, adjacency = parts[4], parts[5]
    last = chain[:, -1]
    count = adj_start[last + 1] - adj_start[last]
    at = np.repeat(np.arange(len(last)), count)
    neighbour = adjacency[np.repeat(adj_start[last], count) + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))]
    known = np.unique(pair_key(c_of, last))
    fresh_key, first = np.unique(pair_key(c_of[at], neighbour), return_index=True)
    new = ~np.isin(fresh_key, known)
    at, neighbour = at[first][new], neighbour[first][new]
    if at.size:
        near = _reaches(cell[c_of[at]], chain[at], neighbour, grid, blocks, parts, views, fp)
        at, neighbour = at[near], neighbour[near]
    extra = chain[at].copy()
    extra[:, -1] = neighbour
    order = np.argsort(np.concatenate([c_of, c_of[at]]), kind="stable")
    return (np.concatenate([c_of, c_of[at]])[order], np.concatenate([chain, extra])[order],
            np.concatenate([donor_lane, donor_lane[at]])[order])


def _reaches(lane, chain, last, grid, blocks, parts, views, fp, facing: bool = True):
    """Whether part ``last`` [n], unfolded as the chains ``chain`` [n, depth + 1] take it (the
    mirrors of their parts before the last level), meets the cells ``lane`` [n] from some view
    of their sub-aperture (by :data:`cell_split.MARGIN`) and, at the first bounce, faces the antenna (or
    belongs to an open surface; with ``facing``): bool [n]."""
    normal, offset, closed = parts[2], parts[3], parts[6]
    block, gi, gj, m = grid[0], grid[5], grid[6], grid[7]
    sub = blocks.sub.astype(np.int64)[block[lane]]
    box = np.stack([gi[lane], gi[lane] + 1, gj[lane], gj[lane] + 1], 1).astype(float)
    near = meets(sub, box, m[lane].astype(float), chain, last, parts, views, fp)
    if facing and chain.shape[1] == 1:
        near &= (np.einsum("ij,ij->i", normal[last], views[sub, 0]) - offset[last] > 0) | ~closed[last]
    return near


def _neighbours(c_of, nb, x_row, x_lane):
    """Each piece's neighbourhood lanes as ``(piece, lane)`` int64 pairs: its cell's 3 x 3 ``nb``
    (-1 kept) and the other tube size's lanes ``x_lane`` about cell ``x_row``."""
    n = len(c_of)
    order = np.argsort(x_row, kind="stable")
    x_row, x_lane = x_row[order], x_lane[order]
    start = np.searchsorted(x_row, c_of)
    count = np.searchsorted(x_row, c_of, side="right") - start
    piece = np.repeat(np.arange(n), count)
    within = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    return (np.concatenate([np.repeat(np.arange(n), nb.shape[1]), piece]),
            np.concatenate([nb[c_of].ravel(), x_lane[np.repeat(start, count) + within]]))


def _near_occluders(depth, tables, c_of, chain, donor_lane, nb, cell, grid, blocks, parts, views, fp):
    """:func:`_occluders` of the pieces, less the transmit-side ones whose projection (mirrored as
    the chain's part of their level) meets the piece's cell from no view of the sub-aperture."""
    block = grid[0]
    piece, part, level = _occluders(depth, tables, c_of, chain, donor_lane, nb, parts, views,
                                    blocks.sub.astype(np.int64)[block[cell[c_of]]])
    near = np.ones(len(piece), bool)
    for lv in range(depth + 1):
        at = np.flatnonzero(level == lv)
        if at.size:
            prefix = np.concatenate([chain[piece[at], :lv], part[at, None]], 1)
            near[at] = _reaches(cell[c_of[piece[at]]], prefix, part[at], grid, blocks, parts, views, fp, facing=False)
    return piece[near], part[near], level[near]


def _occluders(depth, tables, c_of, chain, donor_lane, nb, parts, views, sub):
    # nb: (piece, lane) pairs of the pieces' neighbourhoods (:func:`_neighbours`)
    """Every piece's occluders: ``(piece, part, level)`` int64 arrays, sorted by piece.

    At level ``i``, the parts that the neighbourhood's rays with the piece's chain up to ``i - 1``
    met instead of ``X_i`` (and, at the first bounce, the cell's other candidates), on another
    face and with a corner on the antenna's side of ``X_i``'s plane; on the receive side (after
    the first bounce), the parts that hid the neighbourhood's hits of the piece's chain."""
    vertices, face, normal, offset = parts[:4]
    n = len(c_of)
    pieces, occ, levels = [], [], []
    at, lane = nb                                                      # (piece, lane) pairs
    safe = np.maximum(lane, 0)
    for level in range(depth + 1):
        same = lane >= 0
        if level > 0:
            same &= tables[level - 1].key[safe] == tables[level - 1].key[donor_lane[at]]
        pieces.append(at)
        occ.append(np.where(same, tables[level].part[safe], -1))
        levels.append(np.full(at.size, level))
    # the cell's other candidates with the same chain up to the last level (adjacent parts no
    # central ray met included)
    start = np.concatenate([[0], np.cumsum(np.bincount(c_of))])
    count = np.diff(start)[c_of]
    rep = np.repeat(np.arange(n), count)
    others = start[c_of][rep] + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))
    same = np.all(chain[others, :depth] == chain[rep, :depth], axis=1)
    pieces.append(rep[same])
    occ.append(chain[others[same], depth])
    levels.append(np.full(same.sum(), depth))
    if depth > 0:             # receive side: the neighbours with the same chain that were hidden
        same = (lane >= 0) & (tables[depth].key[safe] == tables[depth].key[donor_lane[at]]) \
            & (tables[depth].visible[safe] == 0)
        pieces.append(at)
        occ.append(np.where(same, tables[depth].blocker[safe], -1))
        levels.append(np.full(at.size, RECEIVE))
    piece, part, level = (np.concatenate(a) for a in (pieces, occ, levels))
    keep = part >= 0
    piece, part, level = piece[keep], part[keep], level[keep]
    key = (piece * (1 << 20) + part) * 256 + level
    key, first = np.unique(key, return_index=True)
    piece, part, level = piece[first], part[first], level[first]
    lv = np.minimum(level, depth)
    x = chain[piece, lv]
    keep = (part != x) & (face[part] != face[x])
    # transmit side: a corner on the antenna's side of X_i's (unfolded) plane. Checked at level 0
    # only (deeper levels' mirrors are the kernel's); receive side: kept. A part in X_i's own
    # plane (coincident faces: two shapes' walls back to back, a duplicated plate) covers the same
    # surface: the lower part index keeps it, so the two are counted once, not twice
    ref = views[sub[piece], 0]
    side = np.sign(np.einsum("ij,ij->i", normal[x], ref) - offset[x])
    d = np.einsum("ijk,ik->ij", vertices[part], normal[x]) - offset[x][:, None]
    front = (side[:, None] * d > ON_PLANE).any(1)
    coplanar = (np.abs(d) <= ON_PLANE).all(1) & (level <= depth)
    keep &= np.where(coplanar, part < x, front | (level > 0))
    return piece[keep], part[keep], level[keep]


def occluder_groups(piece, part, level, n_pieces):
    """The pieces with occluders, in groups of :data:`OCCLUDER_GROUPS` occluders (padded with
    ``NONE`` levels): ``[(pieces, parts [n, k], levels [n, k])]``. ``piece`` must be sorted."""
    counts = np.bincount(piece, minlength=n_pieces)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    cuts, low = [], 1
    assert OCCLUDER_GROUPS[-1] == MOST_OCCLUDERS and counts.max(initial=0) <= MOST_OCCLUDERS, \
        "crowded pieces are split first (split_crowded)"
    for size in OCCLUDER_GROUPS:
        have = np.flatnonzero((counts >= low) & (counts <= size))
        low = size + 1
        if have.size == 0:
            continue
        slot = np.arange(size)[None]
        index = starts[have][:, None] + np.minimum(slot, counts[have][:, None] - 1)
        pad = slot >= counts[have][:, None]
        cuts.append((have, part[index], np.where(pad, NONE, level[index])))
    return cuts
