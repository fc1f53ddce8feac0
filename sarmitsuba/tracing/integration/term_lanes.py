"""A bounce order's lit pieces as lanes for the per-pulse kernels: boundary segments to point and
area terms (:mod:`sarmitsuba.tracing.integration.patch_terms`), rough pieces to scatterers
(:mod:`sarmitsuba.tracing.integration.surface_clutter`), docs/physics.md (M5), (M7).

* :func:`segments` -- the segments that need terms: two stable pieces of one region leave out the
  patch line they share (their terms there are equal and opposite), and :func:`cancel_shared` the
  edges two convex parts of one face share;
* :func:`build_lanes` -- one lane per point term (a split segment's two ends, a sinc segment's
  midpoint, the three candidates of an open one), one area lane per piece that may be near the
  specular direction; consecutive segments of one straight boundary drop the split ends they
  share (:func:`cancel_junctions`);
* :func:`scatterer_lanes` -- every scatterer of a rough part's lattice inside its lit pieces.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial import cKDTree

from ..discovery.chains import Chains, facing_sign, image_source
from ..loops import lane_float
from .patch_terms import AREA, OPEN_START, OPEN_END, SINC, SPLIT_END, SPLIT_START, PieceTable, TermLanes
from ..mesh.patches import Surfaces
from ..mesh.piece_cuts import cell_key
from ..mesh.polygons import edge_lines, inside
from .surface_clutter import ScattererLanes, cell_hash, points_inside_boundary, scatterer_offsets, scatterer_phases, surface_keys

__all__ = ["segments", "cancel_shared", "cancel_junctions", "kd_tree_pairs", "build_lanes", "windows", "piece_table", "scatterer_lanes"]


def segments(pieces, stable: np.ndarray, cancel: bool = True):
    """The boundary segments of lit pieces that need terms: ``(piece, start, end)``, face
    coordinates. A stable piece leaves out each segment it shares with a stable neighbour of its
    region across a patch line (their terms there are equal and opposite, docs/physics.md (M5));
    ``cancel`` false keeps them all (the ``sbr`` ``cancel_interior = false`` reference)."""
    piece, start, end, side = pieces.edges()
    keep = np.ones(len(piece), bool)
    if cancel and np.any(stable):
        keys = np.sort(cell_key(pieces.region[stable], pieces.cell[stable]))
        # patch lines bottom, right, top, left: the neighbour across is (0,-1), (1,0), (0,1), (-1,0)
        step = np.array([[0, -1], [1, 0], [0, 1], [-1, 0]])
        rows = np.flatnonzero((side >= 0) & np.take(stable, piece))
        row_piece = np.take(piece, rows)
        other = cell_key(np.take(pieces.region, row_piece),
                         np.take(pieces.cell, row_piece, axis=0) + np.take(step, np.take(side, rows), axis=0))
        at = np.minimum(np.searchsorted(keys, other), len(keys) - 1)
        keep[rows[np.take(keys, at) == other]] = False
    keep = np.flatnonzero(keep)                       # (np.take: row gathers of [s, 2] are slow by mask)
    return np.take(piece, keep), np.take(start, keep, axis=0), np.take(end, keep, axis=0)


def _equal_rows(columns) -> tuple[np.ndarray, np.ndarray]:
    """Rows grouped by equal values in every one of ``columns`` (int64 arrays of one length):
    ``(order, group)``, the rows in an order that puts equal rows next to each other and each
    ordered row's group number (0, 1, ...). One sort of a 64-bit hash of the rows; where two
    different rows share a hash, :func:`_equal_rows_reference` (a lexicographic sort)."""
    n = len(columns[0])
    if n < 2:
        return _equal_rows_reference(columns)
    h = _row_hash(columns)
    order = np.argsort(h)
    same = np.ones(n, bool)                               # an ordered row equals the one before it
    same[0] = False
    for column in columns:
        ordered = column[order]
        same[1:] &= ordered[1:] == ordered[:-1]
    hashed = h[order]
    if np.any((hashed[1:] == hashed[:-1]) & ~same[1:]):   # a collision: different rows, one hash
        return _equal_rows_reference(columns)
    return order, np.cumsum(~same) - 1


def _row_hash(columns) -> np.ndarray:
    """uint64 [n]: a hash of each row of ``columns`` (multiply-xor, wrapping)."""
    h = np.zeros(len(columns[0]), np.uint64)
    for column in columns:
        h = (h ^ np.asarray(column, np.int64).view(np.uint64)) * np.uint64(0x9E3779B97F4A7C15)
        h ^= h >> np.uint64(29)
    return h


def _equal_rows_reference(columns) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_equal_rows` by a lexicographic sort (the rows sorted)."""
    order = np.lexsort(columns)
    same = np.ones(len(order), bool)                      # a sorted row equals the one before it
    same[0] = False
    for column in columns:
        ordered = column[order]
        same[1:] &= ordered[1:] == ordered[:-1]
    return order, np.cumsum(~same) - 1


#: Two boundary segments (or two split ends) are one where their coordinates agree to this [m]:
#: far above float64's rounding of face coordinates kilometres from the origin (1e-13 m), far below
#: any segment a piece keeps (:data:`~sarmitsuba.tracing.mesh.polygons.REPEAT_DISTANCE` joins
#: closer corners). A tolerance, not a rounding to a grid: the two copies of one point, computed
#: from two pieces, may fall on two sides of a grid line, and a geometric derivative's moved
#: geometry would then cancel a pair its own geometry keeps (docs/physics.md (AD4)).
MATCH_TOLERANCE = 1e-8


def _lone_pairs(features: np.ndarray, tolerance: float) -> np.ndarray:
    """int64 [p, 2]: the pairs of rows of ``features`` (float64 [n, f]) within ``tolerance`` of
    each other and of no third row (scipy's k-d tree)."""
    if len(features) < 2:
        return np.zeros((0, 2), np.int64)
    pairs = cKDTree(features).query_pairs(tolerance, output_type="ndarray")
    near = np.bincount(pairs.ravel(), minlength=len(features))
    return pairs[(near[pairs[:, 0]] == 1) & (near[pairs[:, 1]] == 1)]


def _labels(keys) -> np.ndarray:
    """int64 [n]: each row's group number (0, 1, ...), rows equal in every one of ``keys`` (int64
    columns) sharing one."""
    order, group = _equal_rows(keys)
    label = np.empty(len(group), np.int64)
    label[order] = group
    return label


def _grouped(features: np.ndarray, label: np.ndarray) -> np.ndarray:
    """``features`` with one more column that puts rows of different groups ``label`` far apart:
    their group number times a gap beyond every feature's range."""
    gap = 10.0 * (float(np.ptp(features, axis=0).max(initial=0.0)) + 1.0)
    return np.column_stack([features, label.astype(np.float64) * gap])


def kd_tree_pairs(features: np.ndarray, label: np.ndarray, tolerance: float) -> np.ndarray:
    """The pairs of rows of one group (``label`` int64 [n]) within ``tolerance`` of each other in
    ``features`` (float64 [n, f]) and of no third row: int64 [p, 2], by scipy's k-d tree (the
    reference of :func:`sarmitsuba.tracing.fused.matching.lone_pairs`)."""
    return _lone_pairs(_grouped(features, label), tolerance)


def cancel_shared(s: Surfaces, chains: Chains, chain: np.ndarray, start: np.ndarray, end: np.ndarray,
                  stable: np.ndarray, match=kd_tree_pairs) -> np.ndarray:
    """bool: the segments of stable pieces that another stable piece's segment runs along the other
    way, both reached through mirrors on the same planes (the faces of the earlier windows) and
    lying on the same face: an edge two convex parts of one face share, whose terms are equal and
    opposite (eq. (M5)). Both of a pair are dropped; a segment is one with another where their
    midpoints and their edges (up to sign: ``e e^T``) agree to :data:`MATCH_TOLERANCE` and no
    third segment's do. ``chain`` [s] each segment's chain, ``start``, ``end`` [s, 2] face
    coordinates (one frame per face), ``stable`` [s]; ``match``: how the pairs are found
    (:func:`kd_tree_pairs`, or a device kernel with its signature)."""
    drop = np.zeros(len(chain), bool)
    rows = np.flatnonzero(stable)
    if len(rows) < 2:
        return drop
    c = np.take(chain, rows)
    parts = np.take(chains.parts, c, axis=0)            # (np.take: row gathers ~10x faster than x[idx])
    faces = np.where(parts >= 0, np.take(s.face, np.maximum(parts, 0)), -1)
    p = np.take(start, rows, axis=0).astype(np.float64)
    e = np.take(end, rows, axis=0).astype(np.float64) - p
    features = np.column_stack([p + 0.5 * e, e[:, 0] ** 2, e[:, 1] ** 2, e[:, 0] * e[:, 1]])
    pairs = match(features, _labels((chains.sub[c], *faces.T)), MATCH_TOLERANCE)
    pairs = pairs[np.einsum("mi,mi->m", e[pairs[:, 0]], e[pairs[:, 1]]) < 0]      # the other way
    drop[rows[pairs.ravel()]] = True
    return drop


def cancel_junctions(lane_kind, lane_piece, point2, edge2, region, stable, match=kd_tree_pairs) -> np.ndarray:
    """bool: the split lanes that meet another of the opposite sign at the same point, along the
    same direction, in the same region, both of stable pieces: consecutive segments of one
    straight boundary, whose terms there are equal and opposite (eq. (M5)); both are dropped. The
    same: points and unit directions within :data:`MATCH_TOLERANCE`, no third lane's (``match``:
    as in :func:`cancel_shared`)."""
    candidate = np.flatnonzero(((lane_kind == SPLIT_START) | (lane_kind == SPLIT_END)) & stable[lane_piece])
    drop = np.zeros(len(lane_kind), bool)
    if len(candidate) < 2:
        return drop
    edge_c = np.take(edge2, candidate, axis=0).astype(np.float64)
    direction = edge_c / np.linalg.norm(edge_c, axis=1, keepdims=True)
    features = np.column_stack([np.take(point2, candidate, axis=0).astype(np.float64), direction])
    pairs = match(features, _labels((region[lane_piece[candidate]].astype(np.int64),)), MATCH_TOLERANCE)
    kinds = lane_kind[candidate]
    pairs = pairs[kinds[pairs[:, 0]] != kinds[pairs[:, 1]]]
    drop[candidate[pairs.ravel()]] = True
    return drop


def build_lanes(s: Surfaces, chains: Chains, geometry, stable, segments, kind, table_segments, reference, depth: int,
                cancel: bool = True, motion=None, edges=None, match=None):
    """:class:`TermLanes` and :class:`PieceTable` of lit pieces (``geometry``: region, part,
    centroid (world and face), area, second moments, diagonal per piece): per segment 2 (split),
    1 (sinc) or 3 (open) point lanes; per unstable piece an area lane. ``cancel`` false keeps the
    split ends that consecutive segments share. ``motion``: ``(p_rate, q_rate, moved_to)``, the
    segments' ends' rates (face coordinates, per metre of travel, float64 [s, 2]) and each
    chain's second antenna position [n_chains, 3] (:mod:`sarmitsuba.tracing.visibility.motion`, eq. (M8)).
    ``match``: how :func:`cancel_junctions` finds its pairs (default :func:`kd_tree_pairs`)."""
    region, part, centroid, centroid2, area, second, diagonal = geometry
    seg_piece, p2, q2 = segments
    copies = np.where(kind == SPLIT_START, 2, np.where(kind == SINC, 1, 3))
    lane_seg = np.repeat(np.arange(len(seg_piece)), copies)
    role = np.arange(len(lane_seg)) - np.repeat(np.cumsum(copies) - copies, copies)
    base_kind = kind[lane_seg]
    lane_kind = np.where(base_kind == SPLIT_START, SPLIT_START + role,
                         np.where(base_kind == SINC, SINC, OPEN_START + role))
    at_start = (lane_kind == SPLIT_START) | (lane_kind == OPEN_START)
    at_end = (lane_kind == SPLIT_END) | (lane_kind == OPEN_END)
    p, q = np.take(p2, lane_seg, axis=0), np.take(q2, lane_seg, axis=0)
    point2 = np.where(at_start[:, None], p, np.where(at_end[:, None], q, 0.5 * (p + q)))
    lane_piece = seg_piece[lane_seg]
    unstable = np.flatnonzero(~stable)
    lane_piece = np.concatenate([lane_piece, unstable])
    lane_kind = np.concatenate([lane_kind, np.full(len(unstable), AREA)])
    point2 = np.concatenate([point2, centroid2[unstable]])
    mid2 = np.concatenate([0.5 * (p + q), centroid2[unstable]])
    edge2 = np.concatenate([q - p, np.zeros((len(unstable), 2))])
    if motion is not None:
        p_rate, q_rate = np.take(motion[0], lane_seg, axis=0), np.take(motion[1], lane_seg, axis=0)
        zero = np.zeros((len(unstable), 2))
        point_rate2 = np.concatenate([np.where(at_start[:, None], p_rate, np.where(at_end[:, None], q_rate,
                                                                                  0.5 * (p_rate + q_rate))), zero])
        mid_rate2 = np.concatenate([0.5 * (p_rate + q_rate), zero])
        edge_rate2 = np.concatenate([q_rate - p_rate, zero])
    else:
        point_rate2 = mid_rate2 = edge_rate2 = np.zeros((len(lane_kind), 2))
    lane_seg = np.concatenate([lane_seg, np.full(len(unstable), -1)])
    drop = cancel_junctions(lane_kind, lane_piece, point2, edge2, region, stable, match or kd_tree_pairs) if cancel \
        else np.zeros(len(lane_kind), bool)
    kept = np.flatnonzero(~drop)
    lane_piece, lane_kind, point2, mid2, edge2, point_rate2, mid_rate2, edge_rate2, lane_seg = (
        np.take(a, kept, axis=0) for a in (lane_piece, lane_kind, point2, mid2, edge2, point_rate2, mid_rate2,
                                           edge_rate2, lane_seg))
    chain = region[lane_piece]
    lane_part = part[lane_piece]
    point = s.to_world(lane_part, point2)
    middle = s.to_world(lane_part, mid2)
    edge = s.vector_to_world(lane_part, edge2)
    lin = np.take(np.ascontiguousarray(chains.lin).reshape((-1,) + chains.lin.shape[2:]),
                  chain * chains.lin.shape[1] + np.take(chains.order, chain), axis=0)
    window_data = windows(s, chains, chain, point, reference[chains.sub[chain]], depth)
    moving = np.any(point_rate2 != 0, axis=1) | np.any(edge_rate2 != 0, axis=1)
    if motion is not None and np.any(moving):
        point_rate, mid_rate = s.vector_to_world(lane_part, point_rate2), s.vector_to_world(lane_part, mid_rate2)
        # U_d is affine: a rate is carried by its linear part
        rates = [point_rate, np.einsum("mij,mj->mi", lin, point_rate), mid_rate,
                 np.einsum("mij,mj->mi", lin, mid_rate), s.vector_to_world(lane_part, edge_rate2)]
        origin = reference[chains.sub[chain]]
        travel = motion[2][chain] - origin
        step = np.linalg.norm(travel, axis=1, keepdims=True)
        window_data.update(origin=origin, axis=(travel / np.where(step > 0, step, 1.0)).astype(lane_float()),
                           motion=np.stack(rates, axis=1).astype(lane_float()))
    if edges is not None and np.any(edges["on"]):
        seg = np.maximum(lane_seg, 0)
        on = (lane_seg >= 0) & edges["on"][seg]
        other = np.where(on, edges["other"][seg], -1)
        window_data.update(diffracting=on, wedge_x0=edges["x0"][seg].astype(lane_float()),
                           wedge_xn=edges["xn"][seg].astype(lane_float()),
                           wedge_row=s.row[np.where(other >= 0, other, lane_part)].astype(np.uint32),
                           wedge_defer=(other >= 0) & (other < lane_part), double=np.zeros(len(on), bool),
                           across=edges["across"][seg].astype(lane_float()),
                           across_xn=edges["xn_across"][seg].astype(lane_float()))
    lanes = TermLanes(kind=lane_kind.astype(np.uint32), point=point, unfolded=chains.unfolded(point, chain),
                      middle=middle, middle_unfolded=chains.unfolded(middle, chain), edge=edge.astype(lane_float()),
                      normal=np.take(s.normal, lane_part, axis=0).astype(lane_float()), fold=np.transpose(lin, (0, 2, 1)).astype(lane_float()),
                      sub=chains.sub[chain].astype(np.uint32), row=s.row[lane_part].astype(np.uint32),
                      piece=lane_piece.astype(np.uint32), stable=stable[lane_piece], **window_data)
    if lanes.diffracting is not None:
        lanes = with_double(lanes, chains, chain)
    table = piece_table(s, chains, geometry, table_segments)
    return lanes, table


def with_double(lanes: TermLanes, chains: Chains, chain: np.ndarray) -> TermLanes:
    """``lanes`` followed by a copy of every diffracting point lane that has a diffracting edge
    across its face (eq. (E6)): the copy's incident leg ends at the point across
    (``point + across``, unfolded through the lane's chain), its return leg leaves from its own
    point, and it carries only the doubly diffracted term."""
    rows = np.flatnonzero(lanes.diffracting & np.any(lanes.across != 0, axis=1) & (lanes.kind != AREA))
    if len(rows) == 0:
        return lanes
    offset = lanes.across[rows].astype(float)
    copy = {f.name: (None if getattr(lanes, f.name) is None else getattr(lanes, f.name)[rows])
            for f in dataclasses.fields(lanes)}
    copy.update(unfolded=chains.unfolded(lanes.point[rows] + offset, chain[rows]),
                middle_unfolded=chains.unfolded(lanes.middle[rows] + offset, chain[rows]),
                double=np.ones(len(rows), bool))
    if lanes.motion is not None:
        copy["origin"], copy["axis"] = lanes.origin[rows], lanes.axis[rows]
    merged = {}
    for f in dataclasses.fields(lanes):
        a, b = getattr(lanes, f.name), copy[f.name]
        merged[f.name] = None if a is None else np.concatenate([a, b])
    return TermLanes(**merged)


def windows(s: Surfaces, chains: Chains, chain, point, antenna, depth: int) -> dict:
    """The earlier bounces of each lane's path seen from its reference position: the unfolded
    direction, and per bounce the part's row, the incidence cosine, the arriving direction and
    the normal facing it (:class:`TermLanes`)."""
    if depth == 0:
        return {}
    y = chains.unfolded(point, chain)
    first = y - antenna
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    rows, cos, direction, normal = [], [], [], []
    for i in range(depth):
        window = np.take(chains.parts[:, i], chain)
        d = np.einsum("mji,mj->mi", np.take(chains.lin[:, i], chain, axis=0), first)
        n = np.take(s.normal, window, axis=0)
        dot = np.einsum("mi,mi->m", n, d)
        rows.append(s.row[window])
        cos.append(np.abs(dot))
        direction.append(d)
        normal.append(n * np.where(dot > 0, -1.0, 1.0)[:, None])
    return dict(first=first.astype(lane_float()), window_row=np.stack(rows, 1).astype(np.uint32),
                window_cos=np.stack(cos, 1).astype(lane_float()), window_direction=np.stack(direction, 1).astype(lane_float()),
                window_normal=np.stack(normal, 1).astype(lane_float()))


def piece_table(s: Surfaces, chains: Chains, geometry, table_segments) -> PieceTable:
    """The :class:`PieceTable` of lit pieces; the boundary segments (``table_segments``: piece,
    start, end) only of those that may be near the specular direction (their area terms
    integrate them)."""
    region, part, centroid, centroid2, area, second, diagonal = geometry
    piece, start2, end2 = table_segments[:3]
    order = np.argsort(piece, kind="stable")            # each piece's segments in one run
    piece, start2, end2 = np.take(piece, order), np.take(start2, order, axis=0), np.take(end2, order, axis=0)
    owner = part[piece]
    rates = {}
    if len(table_segments) > 3:                         # the segments' ends' rates, eq. (M8)
        p_rate, q_rate = np.take(table_segments[3], order, axis=0), np.take(table_segments[4], order, axis=0)
        rates = dict(segment_mid_rate=s.vector_to_world(owner, 0.5 * (p_rate + q_rate)).astype(lane_float()),
                     segment_edge_rate=s.vector_to_world(owner, q_rate - p_rate).astype(lane_float()))
    mid = s.vector_to_world(owner, 0.5 * (start2 + end2) - np.take(centroid2, piece, axis=0))
    edge = s.vector_to_world(owner, end2 - start2)
    count = np.bincount(piece, minlength=len(region))
    return PieceTable(centroid=centroid, centroid_unfolded=chains.unfolded(centroid, region),
                      diagonal=diagonal.astype(lane_float()), area=area.astype(lane_float()),
                      moments=second.astype(lane_float()), axis_u=s.axis_u[part].astype(lane_float()),
                      axis_v=s.axis_v[part].astype(lane_float()),
                      segment_start=(np.cumsum(count) - count).astype(np.uint32), segment_count=count.astype(np.uint32),
                      segment_mid=mid.astype(lane_float()), segment_edge=edge.astype(lane_float()), **rates)


def scatterer_lanes(s: Surfaces, chains: Chains, pieces, clipped, lit_pieces, rough_row: np.ndarray, table,
                    cell: float, seed: int, reference: np.ndarray, depth: int) -> ScattererLanes:
    """Every scatterer of the rough parts' lattices inside a bounce order's lit pieces, eq. (C),
    (M7): a whole piece's patch holds ``m x m`` cells whole, a border piece the cells whose
    scatterer lies in its polygon, a mixed piece those in its lit region (``clipped``, cut from
    ``lit_pieces.pieces``). ``rough_row`` bool [rows]: which material rows have a clutter model;
    ``table`` the material table (shape keys and axes)."""
    m = max(1, int(round(pieces.patch / cell)))
    part_of = chains.last
    rough = rough_row[s.row[part_of[pieces.region]]]
    rows = np.flatnonzero(rough)
    owner, iu, iv = _candidate_cells(pieces, rows, m, cell)
    region = pieces.region[owner]
    held = pieces.whole[owner].copy()
    border = np.flatnonzero(~held)
    cut = lit_pieces.select(clipped.piece)
    c_rows = np.flatnonzero(rough_row[s.row[part_of[cut.region]]])
    c_owner, c_iu, c_iv = _candidate_cells(cut, c_rows, m, cell)
    region = np.concatenate([region, cut.region[c_owner]])
    iu, iv = np.concatenate([iu, c_iu]), np.concatenate([iv, c_iv])
    key = _chain_keys(s, chains, table, cell, seed, reference)[region]
    h0 = cell_hash(iu, iv, key)
    point2 = (np.stack([iu, iv], axis=1) + scatterer_offsets(h0)) * cell
    n_regular = len(owner)
    if len(border):
        poly_rows = pieces.border[owner[border]]
        lines = edge_lines(pieces.polygon, pieces.count)[poly_rows]
        held[border] = inside(point2[border][:, None, :], lines)[:, 0]
    if len(c_owner):
        keep_cut = points_inside_boundary(point2[n_regular:], c_owner, clipped.owner, clipped.start, clipped.end,
                                          len(clipped.piece))
    else:
        keep_cut = np.zeros(0, bool)
    keep = np.concatenate([held, keep_cut])
    region, point2, h0 = region[keep], point2[keep], h0[keep]
    part = part_of[region]
    point = s.to_world(part, point2)
    phase, cross = scatterer_phases(h0)
    lin = chains.lin[region, chains.order[region]]
    return ScattererLanes(point=point, unfolded=chains.unfolded(point, region), normal=s.normal[part].astype(lane_float()),
                          fold=np.transpose(lin, (0, 2, 1)).astype(lane_float()), sub=chains.sub[region].astype(np.uint32),
                          row=s.row[part].astype(np.uint32), phase=phase.astype(lane_float()),
                          phase_cross=cross.astype(lane_float()),
                          **windows(s, chains, region, point, reference[chains.sub[region]], depth))


def _candidate_cells(pieces, rows: np.ndarray, m: int, cell: float):
    """The lattice cells that may hold scatterers of pieces ``rows``: a whole piece's ``m x m``, a
    border piece's those its bounding box meets. Returns (piece, iu, iv) int64 arrays."""
    poly, count = pieces.polygons()
    lo = np.floor(poly[rows].min(axis=1) / cell).astype(np.int64)
    hi = np.floor(poly[rows].max(axis=1) / cell).astype(np.int64)
    whole = pieces.whole[rows]
    lo = np.where(whole[:, None], pieces.cell[rows] * m, lo)
    hi = np.where(whole[:, None], pieces.cell[rows] * m + m - 1, hi)
    nu, nv = hi[:, 0] - lo[:, 0] + 1, hi[:, 1] - lo[:, 1] + 1
    size = nu * nv
    owner = np.repeat(rows, size)
    local = np.arange(int(size.sum())) - np.repeat(np.cumsum(size) - size, size)
    k = np.repeat(np.arange(len(rows)), size)
    return owner, lo[k, 0] + local % nu[k], lo[k, 1] + local // nu[k]


def _chain_keys(s: Surfaces, chains: Chains, table, cell: float, seed: int, reference: np.ndarray) -> np.ndarray:
    """The clutter lattice key of each chain's last part on the side its wave arrives on."""
    last = chains.last
    back = facing_sign(s, last, image_source(chains, reference[chains.sub])) < 0
    shape = s.shape_id
    plane_offset = s.offset[last] - np.einsum("ni,ni->n", s.normal[last], s.origin[last])
    return surface_keys(table.shape_key[shape[last]], back, s.normal[last], plane_offset,
                        table.shape_axes[shape[last]], cell, seed)
