"""Pairing the lanes of a geometry moved by ``+-h`` with the lanes of the geometry itself, and
their central differences (docs/physics.md (AD4)).

The host's sorts and hashes may order the rows of a moved geometry's lanes differently, so each
moved lane is paired with the lane of equal discrete attributes (kind, pulse group, material,
chain) nearest to it: a lane moves by about ``h`` times the vertices' displacement, far less
than lanes lie apart. Where the lanes cannot be paired one to one (a piece, a segment or a lane
more or fewer) the move changes the lit regions' topology: :class:`GeometryChange`.
:func:`tangent_lanes` then forms ``(lanes(p + h) - lanes(p)) / h`` field by field, in float64.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial import cKDTree

from ...core.arrays import unique_rows
from ...core.radar import ParameterError
from ..integration.patch_terms import AREA

__all__ = ["GeometryChange", "GeometryChangeWarning", "topology_change", "align_terms", "align_scatterers", "tangent_lanes", "ARRIVAL_FIELDS",
           "match_rows", "row_groups", "nearest_distinct"]

#: The lane fields only the earlier bounces' factors are formed from (``gamma`` and the Jones
#: matrices, :meth:`sarmitsuba.tracing.integration.patch_terms.PatchTerms.arrival`): their tangents are taken
#: of those factors on the device instead.
ARRIVAL_FIELDS = ("first", "window_cos", "window_direction", "window_normal")


class GeometryChange(ParameterError):
    """The parameter moves a boundary of visibility (a lit region's topology changes within
    its step): its derivative is not defined there (docs/physics.md (AD4))."""


class GeometryChangeWarning(UserWarning):
    """A geometric parameter's step changed the lit regions' topology on one side: its gradient
    is the one-sided derivative from the other side, or NaN where both sides change it
    (docs/physics.md (AD4))."""


def topology_change(what: str) -> GeometryChange:
    """The :class:`GeometryChange` that says what changed (``what``: lanes, pieces, ...)."""
    return GeometryChange(f"the geometric parameter changes the lit regions' {what} within its step: it "
                          "moves a boundary of visibility, where the derivative is not defined (docs/physics.md "
                          "(AD4)); evaluate it at another value of the parameter")


def match_rows(keys: np.ndarray, features: np.ndarray, other_keys: np.ndarray, other_features: np.ndarray,
               tolerance: float) -> np.ndarray:
    """For each row of ``features`` (float64 [n, f]) the row of ``other_features`` with equal
    ``keys`` (int64 [n, k]) nearest to it: int64 [n], one to one, each within ``tolerance``;
    GeometryChange otherwise (the moved geometry's lanes are not the same lanes)."""
    if len(keys) != len(other_keys):
        raise topology_change("lanes")
    if len(keys) == 0:
        return np.zeros(0, np.int64)
    # the host's sorts mostly keep the order: a row whose namesake is within the tolerance with
    # its key is paired with it (a nearer row would be an identical lane), the rest by the tree
    same = np.all(keys == other_keys, axis=1) & (np.linalg.norm(features - other_features, axis=1) <= tolerance)
    if np.all(same):
        return np.arange(len(keys))
    if np.any(same):
        rest = np.flatnonzero(~same)
        chosen = np.arange(len(keys))
        chosen[rest] = rest[match_rows(keys[rest], features[rest], other_keys[rest], other_features[rest], tolerance)]
        return chosen
    group = row_groups(np.concatenate([keys, other_keys])).astype(float)
    spread = float(np.ptp(np.concatenate([features, other_features]), axis=0).max()) + 1.0
    # the key as a coordinate far beyond every feature's range: a nearest row has the same key
    a = np.column_stack([features, group[:len(keys)] * 10.0 * spread])
    b = np.column_stack([other_features, group[len(keys):] * 10.0 * spread])
    chosen = nearest_distinct(a, b, tolerance)
    if np.any(chosen < 0):
        raise topology_change("lanes")
    return chosen


def row_groups(keys: np.ndarray) -> np.ndarray:
    """int64 [n]: equal for equal rows of ``keys`` (int64 [n, k]), distinct otherwise; the inverse
    of ``np.unique(keys, axis=0, return_inverse=True)`` (:func:`sarmitsuba.core.arrays.unique_rows`)."""
    return unique_rows(np.asarray(keys, np.int64).reshape(len(keys), -1), return_inverse=True)[1]


def _owners(table, label: np.ndarray) -> np.ndarray:
    """int64 [s]: ``label`` of the piece each boundary segment of a piece table belongs to (-1:
    none)."""
    owner = np.full(len(table.segment_mid), -1, np.int64)
    count = np.asarray(table.segment_count, np.int64)
    piece = np.repeat(np.arange(len(count)), count)
    rows = np.repeat(np.asarray(table.segment_start, np.int64), count) + np.arange(len(piece)) \
        - np.repeat(np.cumsum(count) - count, count)
    owner[rows] = label[piece]
    return owner


def _short(edge, tolerance: float) -> np.ndarray:
    """bool: segments (float [s, 3]) no longer than ``tolerance``."""
    return np.linalg.norm(np.asarray(edge, float).reshape(-1, 3), axis=1) <= tolerance


def _pair_rows(key, feature, tiny, other_key, other_feature, other_tiny, tolerance: float) -> np.ndarray:
    """Rows of the other set paired with each row (int64, -1: none): the rows that are not
    ``tiny`` one to one (:func:`match_rows`), the tiny ones where a tiny one lies near."""
    order = np.full(len(key), -1, np.int64)
    big, big_other = np.flatnonzero(~tiny), np.flatnonzero(~other_tiny)
    order[big] = big_other[match_rows(key[big], feature[big], other_key[big_other], other_feature[big_other],
                                      tolerance)]
    small, small_other = np.flatnonzero(tiny), np.flatnonzero(other_tiny)
    if len(small) and len(small_other):
        found = nearest_distinct(np.column_stack([feature[small], key[small]]),
                                 np.column_stack([other_feature[small_other], other_key[small_other]]), tolerance)
        order[small[found >= 0]] = small_other[found[found >= 0]]
    return order


def nearest_distinct(a: np.ndarray, b: np.ndarray, tolerance: float) -> np.ndarray:
    """For each row of ``a`` a distinct row of ``b`` within ``tolerance``: its nearest, or where
    another row took that first (identical lanes: two split ends at one corner) the nearest one
    left among its eight nearest; -1 where none is left. In passes over the neighbours' ranks
    (the first row of ``a`` wins a row of ``b`` two propose at once), not row by row."""
    if len(a) == 0 or len(b) == 0:
        return np.full(len(a), -1, np.int64)
    k = min(8, len(b))
    distance, index = cKDTree(b).query(a, k=k)
    distance, index = distance.reshape(len(a), k), index.reshape(len(a), k)
    out = np.full(len(a), -1, np.int64)
    taken = np.zeros(len(b), bool)
    for j in range(k):                   # pass j: each row still unpaired proposes its j-th nearest
        rows = np.flatnonzero(out < 0)
        rows = rows[(distance[rows, j] <= tolerance) & ~taken[index[rows, j].clip(0, len(b) - 1)]]
        if len(rows) == 0:
            continue
        proposed = index[rows, j]
        first = np.unique(proposed, return_index=True)[1]   # one row per proposed row of b: the first
        out[rows[first]] = proposed[first]
        taken[proposed[first]] = True
    return out


def _take_or_keep(lanes, main, order: np.ndarray):
    """``lanes`` reordered by ``order``, each row where ``order`` is -1 taken from ``main``."""
    n = len(main)
    if len(lanes) == n and np.array_equal(order, np.arange(n)):
        return lanes                                    # (the host's order kept: most uploads)
    whole = bool(np.all(order >= 0))
    rows = order if whole else np.where(order >= 0, order, len(lanes) + np.arange(n))
    out = {}
    for field in dataclasses.fields(lanes):
        a, b = getattr(lanes, field.name), getattr(main, field.name)
        if isinstance(a, np.ndarray) and a.ndim and len(a) == len(lanes) and isinstance(b, np.ndarray):
            out[field.name] = np.take(a if whole else np.concatenate([a, b.astype(a.dtype)]), rows, axis=0)
    return dataclasses.replace(lanes, **out)


def _key(lanes, names) -> np.ndarray:
    return np.column_stack([np.asarray(getattr(lanes, n)).reshape(len(lanes), -1).astype(np.int64)
                            for n in names if getattr(lanes, n, None) is not None])


def _features(lanes, names) -> np.ndarray:
    return np.column_stack([np.asarray(getattr(lanes, n), np.float64).reshape(len(lanes), -1)
                            for n in names if getattr(lanes, n, None) is not None])


def align_terms(main, main_pieces, lanes, pieces, tolerance: float):
    """The moved tracer's term lanes and piece table (``lanes``, ``pieces``) in the order of the
    tracer's own (``main``, ``main_pieces``): each lane paired with the lane of equal kind,
    pulse group, material and chain nearest to it, each piece with the piece nearest to it, and
    each piece's boundary segments with its nearest ones (the host's sorts may order the moved
    geometry's rows differently)."""
    names = ("point", "unfolded", "middle", "middle_unfolded", "edge", "normal")
    keys = ("kind", "sub", "row", "stable", "window_row")
    # a segment no longer than the pairing tolerance (a sliver's end where two lines meet at a
    # corner) may be there on one side of the parameter and not on the other: its terms are
    # O(h), so it is paired where it can be and otherwise keeps its own value (tangent 0)
    tiny, tiny_moved = (_short(x.edge, tolerance) & (x.kind != AREA) for x in (main, lanes))
    order = _pair_rows(_key(main, keys), _features(main, names), tiny, _key(lanes, keys), _features(lanes, names),
                       tiny_moved, tolerance)
    paired = order >= 0
    moved_piece = lanes.piece[order[paired]]
    lanes = _take_or_keep(lanes, main, order)
    n = len(main_pieces.area)
    # each piece is the piece its lanes were paired with; a piece no lane names (a sliver, or a
    # whole piece whose segments its neighbours cancel): the moved piece of its own row where that
    # lies within the tolerance (the host's order of whole pieces is the same at the moved
    # geometry; one face's piece is there once per sub-aperture, at one centroid), else the
    # nearest; a sliver of the moved geometry that no lane of the geometry itself names is left out
    piece_order = np.full(n, -1, np.int64)
    piece_order[main.piece[paired]] = moved_piece
    if not np.array_equal(piece_order[main.piece[paired]], moved_piece):
        raise topology_change("pieces")
    where = lambda t, rows: np.column_stack([np.take(t.centroid, rows, axis=0), np.take(t.centroid_unfolded, rows, axis=0)])
    rest = np.flatnonzero(piece_order < 0)
    own = rest[rest < len(pieces.area)]
    own = own[np.linalg.norm(where(main_pieces, own) - where(pieces, own), axis=1) <= tolerance]
    own = own[~np.isin(own, piece_order)]
    piece_order[own] = own
    rest = np.flatnonzero(piece_order < 0)
    if len(rest):
        free = np.setdiff1d(np.arange(len(pieces.area)), piece_order)
        near = nearest_distinct(where(main_pieces, rest), where(pieces, free), tolerance)
        if np.any(near < 0):
            raise topology_change("pieces")
        piece_order[rest] = free[near]
    if len(np.unique(piece_order)) != n:
        raise topology_change("pieces")
    lanes = dataclasses.replace(lanes, piece=main.piece.copy())
    # the area terms' boundary segments, piece by piece, as the lanes
    owner = _owners(main_pieces, np.arange(n))
    inverse = np.full(len(pieces.area), -1, np.int64)
    inverse[piece_order] = np.arange(n)
    moved_owner = _owners(pieces, inverse)
    feature = lambda t: np.column_stack([t.segment_mid, t.segment_edge]).astype(np.float64)
    rows = _pair_rows(owner[:, None], feature(main_pieces), _short(main_pieces.segment_edge, tolerance),
                      moved_owner[:, None], feature(pieces), _short(pieces.segment_edge, tolerance) | (moved_owner < 0),
                      tolerance)
    per_piece = {f.name: np.take(getattr(pieces, f.name), piece_order, axis=0) for f in dataclasses.fields(pieces)
                 if getattr(pieces, f.name) is not None and len(getattr(pieces, f.name)) == n
                 and not f.name.startswith("segment_")}      # (a table with as many segments as pieces)
    kept = np.where(rows >= 0, rows, len(pieces.segment_mid) + np.arange(len(rows)))
    per_segment = {name: np.take(np.concatenate([getattr(pieces, name), getattr(main_pieces, name)]), kept, axis=0)
                   for name in ("segment_mid", "segment_edge", "segment_mid_rate", "segment_edge_rate")
                   if getattr(pieces, name) is not None}
    return lanes, dataclasses.replace(pieces, segment_start=main_pieces.segment_start,
                                      segment_count=main_pieces.segment_count, **per_piece, **per_segment)


def align_scatterers(main, lanes, tolerance: float):
    """The moved tracer's scatterer lanes in the order of the tracer's own (nearest of equal pulse
    group and material)."""
    keys = ("sub", "row", "window_row")
    names = ("point", "unfolded")
    order = match_rows(_key(main, keys), _features(main, names), _key(lanes, keys), _features(lanes, names), tolerance)
    return _take_or_keep(lanes, main, order)


def tangent_lanes(main, plus, step: float):
    """``(plus - main) / step`` of every floating-point field of a lanes dataclass (term lanes,
    piece table or scatterer lanes, float64), the fields of :data:`ARRIVAL_FIELDS` and every
    discrete field left as ``main``'s; GeometryChange where a discrete field of ``plus`` differs
    from ``main``'s."""
    out = {}
    for field in dataclasses.fields(main):
        a, p = (getattr(x, field.name) for x in (main, plus))
        if not isinstance(a, np.ndarray):
            continue
        if p is None or p.shape != a.shape:
            raise topology_change(field.name)
        if a.dtype.kind == "f" and field.name not in ARRIVAL_FIELDS:
            out[field.name] = (p.astype(np.float64) - a.astype(np.float64)) / step
        elif a.dtype.kind != "f" and not np.array_equal(a, p):
            raise topology_change(field.name)
    return dataclasses.replace(main, **out)
