"""The mixed pieces' occluders held sparse (:class:`sarmitsuba.tracing.visibility.lit_pieces.Blockers`: sorted
``(piece, key)`` pairs) against the dense ``(n_pieces, max per piece)`` tables they replaced: the
same keys for the same pieces in the same order, the same pieces usable for cutting, and
:func:`sarmitsuba.tracing.visibility.lit_pieces.spread_occluders` the same as its dense form (kept here as
the reference)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sarmitsuba.core.arrays import unique_pairs
from sarmitsuba.tracing.visibility.lit_pieces import Blockers, LitPieces, spread_occluders
from sarmitsuba.tracing.mesh.piece_cuts import cell_key


def _random_blockers(rng, n, m, non_mesh=0.05):
    piece = rng.integers(0, n, m)
    key = rng.integers(0, 40, m)
    key[rng.random(m) < non_mesh] = -2
    return piece, key


def _dense_reference(piece, key, n):
    """The dense table as ``_blockers`` built it: row ``p`` piece ``p``'s distinct keys ascending,
    -1 beyond."""
    pairs = unique_pairs(piece, key)
    per = np.bincount(pairs[:, 0], minlength=n)
    table = np.full((n, int(per.max(initial=0))), -1, np.int64)
    slot = np.arange(len(pairs)) - np.repeat(np.cumsum(per) - per, per)
    table[pairs[:, 0], slot] = pairs[:, 1]
    return table


@pytest.mark.parametrize("n, m", [(0, 0), (5, 0), (1, 1), (30, 200), (500, 40)])
def test_blockers_are_the_dense_table(n, m):
    """``rows``, ``mesh_only`` and ``dense`` read the same as the dense table, for pieces asked in
    any order, repeated, and without occluders; the empty case included."""
    rng = np.random.default_rng(n * 1000 + m)
    piece, key = _random_blockers(rng, max(n, 1), m)
    blockers = Blockers.of(piece, key)
    table = _dense_reference(piece, key, n)
    np.testing.assert_array_equal(blockers.dense(n), table)
    assert np.all(np.diff(blockers.piece) >= 0)
    # clip_mixed's test: every occluder a mesh part, at least one
    np.testing.assert_array_equal(blockers.mesh_only(n), np.all(table != -2, axis=1) & np.any(table >= 0, axis=1))
    for ids in (np.arange(n), rng.permutation(n), rng.integers(0, max(n, 1), 2 * n) if n else np.zeros(0, np.int64),
                np.zeros(0, np.int64)):
        at, got = blockers.rows(ids, mesh=True)
        want_at, slot = np.nonzero(table[ids] >= 0)
        np.testing.assert_array_equal(at, want_at)
        np.testing.assert_array_equal(got, table[ids][want_at, slot])
        at, got = blockers.rows(ids)
        want_at, slot = np.nonzero(table[ids] != -1)
        np.testing.assert_array_equal(at, want_at)
        np.testing.assert_array_equal(got, table[ids][want_at, slot])
    other = Blockers.of(*_random_blockers(rng, max(n, 1), m // 2))
    union = blockers.union(other)
    np.testing.assert_array_equal(np.stack([union.piece, union.key], 1),
                                  unique_pairs(np.concatenate([piece, other.piece]), np.concatenate([key, other.key])))


def _spread_dense(lit, blockers, clipped):
    """The dense form of :func:`spread_occluders` (``blockers`` int64 [n, c], -1 padded): returns
    the new table and the rows made mixed."""
    pieces = lit.pieces
    row = clipped.piece[clipped.owner]
    low = pieces.cell[row] * pieces.patch
    tol = 1e-9 * pieces.patch

    def sides(point):
        return [np.where(np.abs(point[:, axis] - low[:, axis]) < tol, -1,
                         np.where(np.abs(point[:, axis] - low[:, axis] - pieces.patch) < tol, 1, 0)) for axis in (0, 1)]

    start_side, end_side = sides(clipped.start), sides(clipped.end)
    inner = ~np.any([(a != 0) & (a == b) for a, b in zip(start_side, end_side)], axis=0)
    sources, steps = [], []
    for side in (start_side, end_side):
        side = [np.where(inner, v, 0) for v in side]
        for dx, dy in ((1, 0), (0, 1), (1, 1)):
            step = np.stack([side[0] * dx, side[1] * dy], axis=1)
            live = np.any(step != 0, axis=1) & ((dx == 0) | (side[0] != 0)) & ((dy == 0) | (side[1] != 0))
            sources.append(row[live])
            steps.append(step[live])
    source, step = np.concatenate(sources), np.concatenate(steps)
    keys = cell_key(pieces.region, pieces.cell)
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    wanted = cell_key(pieces.region[source], pieces.cell[source] + step)
    at = np.minimum(np.searchsorted(sorted_keys, wanted), len(keys) - 1)
    found = sorted_keys[at] == wanted
    source, target = source[found], order[at[found]]
    keep = ~lit.mixed[target]
    source, target = source[keep], target[keep]
    width = blockers.shape[1]
    pairs = np.stack([np.repeat(target, width), blockers[source].reshape(-1)], axis=1)
    pairs = pairs[pairs[:, 1] >= 0]
    pairs = unique_pairs(pairs[:, 0], pairs[:, 1])
    rows, start, count = np.unique(pairs[:, 0], return_index=True, return_counts=True)
    out = np.full((len(lit.lit), max(width, int(count.max(initial=0)))), -1, np.int64)
    out[:, :width] = blockers
    slot = np.arange(len(pairs)) - np.repeat(start, count)
    out[rows] = -1
    out[pairs[:, 0], slot] = pairs[:, 1]
    return out, rows


@pytest.mark.parametrize("seed", range(4))
def test_spread_occluders_is_its_dense_form(seed):
    """Two regions of 7 x 7 patches (1 m), a third of them mixed with random occluders (some not
    mesh parts), and cut boundaries of the mixed ones from side to side, corner to corner and inside:
    the pieces made mixed and their occluders are the dense form's."""
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(7), np.arange(7), indexing="ij")
    cell = np.tile(np.stack([i.ravel(), j.ravel()], 1), (2, 1))
    region = np.repeat([0, 1], 49)
    n = len(cell)
    mixed = rng.random(n) < 0.3
    lit = ~mixed & (rng.random(n) < 0.5)
    piece, key = _random_blockers(rng, n, 300, non_mesh=0.1)
    keep = mixed[piece]
    blockers = Blockers.of(piece[keep], key[keep])
    cut = np.flatnonzero(mixed)
    owner = np.repeat(np.arange(len(cut)), 3)
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0], [1, 0.5], [0.5, 1], [0, 0.5], [0.3, 0.6]])
    start = cell[cut[owner]] + corners[rng.integers(0, len(corners), len(owner))]
    end = cell[cut[owner]] + corners[rng.integers(0, len(corners), len(owner))]
    lit_pieces = LitPieces(chains=None, pieces=SimpleNamespace(cell=cell, region=region, patch=1.0), lit=lit,
                           transmit=lit.copy(), mixed=mixed, blockers=blockers)

    class Clipped(SimpleNamespace):
        def __len__(self):
            return len(self.piece)

    clipped = Clipped(piece=cut, owner=owner, start=start.astype(float), end=end.astype(float))
    new, rows = spread_occluders(lit_pieces, clipped)
    table, want_rows = _spread_dense(lit_pieces, blockers.dense(n), clipped)
    assert len(rows) > 0
    np.testing.assert_array_equal(rows, want_rows)
    np.testing.assert_array_equal(new.blockers.dense(n), table[:, :new.blockers.dense(n).shape[1]])
    assert np.all(table[:, new.blockers.dense(n).shape[1]:] == -1)
    np.testing.assert_array_equal(new.mixed, mixed | np.isin(np.arange(n), rows))
    np.testing.assert_array_equal(new.lit, lit & ~np.isin(np.arange(n), rows))


def test_blockers_out_of_range_are_refused():
    """A pair code holds a piece below 2^32 and a key in [-2, 2^31 - 2): anything else is an error,
    not a wrong pair."""
    Blockers.of(np.array([(1 << 32) - 1]), np.array([(1 << 31) - 3]))
    for piece, key in (([-1], [0]), ([1 << 32], [0]), ([0], [-3]), ([0], [(1 << 31) - 2])):
        with pytest.raises(ValueError):
            Blockers.of(np.array(piece), np.array(key))


def _corner_samples_reference(pieces):
    """:func:`corner_samples` as it was: whole and border pieces' samples apart, then sorted by piece."""
    from sarmitsuba.tracing.visibility.lit_pieces import SAMPLE_INSET
    from sarmitsuba.tracing.mesh.patches import UNIT_SQUARE
    from sarmitsuba.tracing.mesh.polygons import corner_slots
    p = pieces.patch
    whole = np.flatnonzero(pieces.whole)
    w_points = ((pieces.cell[whole][:, None, :] + 0.5 + (UNIT_SQUARE[None] - 0.5) * (1.0 - 2.0 * SAMPLE_INSET)) * p)
    border = np.flatnonzero(~pieces.whole)
    poly, count = pieces.polygon[pieces.border[border]], pieces.count[pieces.border[border]]
    slots = corner_slots(count, poly.shape[1])
    centroid = (poly * slots[..., None]).sum(axis=1) / np.maximum(count, 1)[:, None]
    toward = centroid[:, None, :] - poly
    distance = np.linalg.norm(toward, axis=2)
    step = np.minimum(SAMPLE_INSET * p, 0.5 * distance) / np.where(distance > 0, distance, 1.0)
    b_points = (poly + toward * step[..., None])[slots]
    b_owner = np.broadcast_to(border[:, None], slots.shape)[slots]
    owner = np.concatenate([np.repeat(whole, 4), b_owner])
    order = np.argsort(owner, kind="stable")
    return np.concatenate([w_points.reshape(-1, 2), b_points])[order], owner[order]


@pytest.mark.parametrize("patch", [0.7, 2.0])
def test_corner_samples_are_the_reference(patch):
    """Regions cut into whole and border pieces (a triangle, a thin sliver, a polygon of the most
    corners, an empty region, a region inside one patch): the same samples, bit for bit, in the
    same order."""
    from sarmitsuba.tracing.visibility.lit_pieces import corner_samples
    from sarmitsuba.tracing.mesh.piece_cuts import pieces_of
    width = 8
    angle = np.linspace(0, 2 * np.pi, width, endpoint=False)
    regions = [np.stack([5 + 4 * np.cos(angle), -3 + 3 * np.sin(angle)], 1),
               np.array([[0.0, 0.0], [6.0, 0.0], [1.0, 5.0]]),
               np.array([[0.0, 0.0], [9.0, 0.0], [9.0, 1e-3]]),
               np.array([[0.1, 0.1], [0.3, 0.1], [0.2, 0.3]]),
               np.zeros((0, 2))]
    polygon = np.zeros((len(regions), width, 2))
    count = np.array([len(r) for r in regions])
    for k, r in enumerate(regions):
        polygon[k, :len(r)] = r
        polygon[k, len(r):] = r[-1] if len(r) else 0.0
    pieces = pieces_of(polygon, count, patch)
    assert pieces.whole.any() and (~pieces.whole).any()
    got, want = corner_samples(pieces), _corner_samples_reference(pieces)
    np.testing.assert_array_equal(got[1], want[1])
    assert np.array_equal(got[0], want[0])
