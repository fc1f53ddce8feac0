"""The lone pairs of rows that agree within a tolerance, on the Dr.Jit device (docs/design.md
section 10.1, "How shared segments find each other").

Two boundary segments of stable pieces cancel where their midpoints and edges agree within a
tolerance and no third segment's do (eq. (M5)); so do two split lanes at one junction. The
reference finds such pairs with a k-d tree over the features and a column that keeps groups apart
(:func:`sarmitsuba.tracing.integration.term_lanes.cancel_shared`). Here the rows are sorted by
group and, within a group, by a projection of their first two features,
``key = f_0 + PHI f_1``; rows within ``tolerance`` of each other (Euclidean, every feature) have
keys at most ``tolerance sqrt(1 + PHI^2)`` apart, so each lane scans forward from its own row
while the key stays in that window, counting the rows that match in every feature. The
irrational slope ``PHI`` keeps the rows of a patch line (one ``f_0`` or one ``f_1``) from sharing
a key. A lane whose window holds more than :data:`SCAN_LIMIT` rows is an overflow row: the rows
of its group go to the reference instead.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np
from scipy.spatial import cKDTree

from ..device import device_array, releasing
from ..loops import RECORDING, loop_mode

__all__ = ["PHI", "SCAN_LIMIT", "RowMatcher", "lone_pairs", "lone_pairs_reference"]

#: Slope of the sort key's projection (the golden ratio's conjugate): no patch line, horizontal
#: or vertical, and no edge at a simple angle runs along it.
PHI = 0.6180339887498949
#: Rows a lane compares at most before its group is left to the reference (an overflow row).
SCAN_LIMIT = 64


@releasing
def lone_pairs(features: np.ndarray, group: np.ndarray, tolerance: float) -> tuple[np.ndarray, int]:
    """The pairs of rows of one group within ``tolerance`` of each other and of no third row.

    Parameters
    ----------
    features : float64 [n, f], f >= 2
        Each row's features (face coordinates [m] and products of them); the distance is the
        Euclidean distance over all ``f``.
    group : int64 [n]
        Each row's group (0 <= group < 2^63); rows of two groups are never a pair.
    tolerance : float
        The largest distance of a pair (> 0).

    Returns
    -------
    pairs : int64 [p, 2]
        Row indices ``(i, j)``, ``i < j``, sorted by ``i``: as :func:`lone_pairs_reference`
        gives them, but for pairs whose distance lies within rounding of ``tolerance``.
    overflow : int
        Rows whose group went to the reference (a scan window over :data:`SCAN_LIMIT` rows).
    """
    features = np.ascontiguousarray(features, np.float64)
    n, f = features.shape
    if n < 2:
        return np.zeros((0, 2), np.int64), 0
    # sorted by group, then key (stably), on the host, where the rows already are
    key = features[:, 0] + PHI * features[:, 1]
    group = np.asarray(group, np.int64)
    order = np.lexsort((key, group))
    sorted_group = np.take(group, order)
    f64 = mi.Float64
    table = [device_array(f64, np.ascontiguousarray(features[order, k])) for k in range(f)]
    device_key, device_group = device_array(f64, key[order]), device_array(mi.Int64, sorted_group)
    dr.eval(table, device_key, device_group)
    with RECORDING:                     # a symbolic loop: recorded one thread at a time
        count, partner, overflow = _scan(table, device_key, device_group, tolerance)
        dr.eval(count, partner, overflow)
    count, partner, overflow = count.numpy(), partner.numpy().astype(np.int64), overflow.numpy()
    lone = np.flatnonzero(count == 1)
    lone = lone[count[partner[lone]] == 1]
    lone = lone[lone < partner[lone]]
    rows = np.stack([order[lone], order[partner[lone]]], axis=1)
    spilled = 0
    if np.any(overflow):
        bad = np.isin(sorted_group, np.unique(sorted_group[overflow]))
        rows = rows[~bad[lone]]
        members = order[bad]
        spilled = len(members)
        extra = lone_pairs_reference(features[members], group[members], tolerance)
        rows = np.concatenate([rows, members[extra]])
    rows = np.sort(rows, axis=1)
    return rows[np.lexsort((rows[:, 1], rows[:, 0]))], spilled


def _scan(table, key, group, tolerance: float):
    """The Dr.Jit body of :func:`lone_pairs`: per sorted row, the rows within ``tolerance`` among
    those after it in its key window (loop) and, through atomic integer adds, those before it.
    Returns ``(matches UInt32, partner UInt32, overflow Bool)`` per sorted row; ``partner`` is the
    match's sorted index where ``matches`` is 1."""
    f64, u32 = mi.Float64, mi.UInt32
    n = dr.width(key)
    lane = dr.arange(u32, n)
    size = dr.opaque(u32, n)
    window = dr.opaque(f64, tolerance * math.sqrt(1.0 + PHI * PHI) * (1.0 + 1e-9))
    limit = dr.opaque(f64, tolerance * tolerance)
    back_count = dr.zeros(u32, n)
    back_partner = dr.zeros(u32, n)

    def inside(j, steps, *_):
        live = j < size
        same = dr.gather(mi.Int64, group, j, live) == group
        near = dr.gather(f64, key, j, live) - key <= window
        return live & same & near & (steps < SCAN_LIMIT)

    def step(j, steps, count, partner):
        d2 = dr.zeros(f64, n)
        for column in table:
            d = dr.gather(f64, column, j) - column
            d2 += d * d
        match = d2 <= limit
        # atomic adds: Expand (the default for small arrays) writes per-worker copies indexed with
        # the array's length in the kernel's code (one kernel per length), and two host threads
        # running one kernel's blocks as worker 0 would share a copy
        dr.scatter_add(back_count, u32(1), j, match, mode=dr.ReduceMode.Direct)
        dr.scatter(back_partner, lane, j, match)
        return (j + 1, steps + 1, count + dr.select(match, 1, 0), dr.select(match, j, partner))

    j, steps, count, partner = dr.while_loop((lane + 1, dr.zeros(u32, n), dr.zeros(u32, n), dr.zeros(u32, n)),
                                             inside, step, mode=loop_mode(), label="lone pairs")
    overflow = (steps >= SCAN_LIMIT) & inside(j, u32(0))
    total = count + back_count
    return total, dr.select(count == 1, partner, back_partner), overflow


def lone_pairs_reference(features: np.ndarray, group: np.ndarray, tolerance: float) -> np.ndarray:
    """:func:`lone_pairs` by scipy's k-d tree, group by group (the readable reference; shares
    nothing with the kernel): int64 [p, 2], ``i < j``."""
    features, group = np.asarray(features, np.float64), np.asarray(group, np.int64)
    out = []
    for g in np.unique(group):
        rows = np.flatnonzero(group == g)
        if len(rows) < 2:
            continue
        pairs = cKDTree(features[rows]).query_pairs(tolerance, output_type="ndarray")
        near = np.bincount(pairs.ravel(), minlength=len(rows))
        lone = pairs[(near[pairs[:, 0]] == 1) & (near[pairs[:, 1]] == 1)]
        out.append(rows[lone])
    return np.concatenate(out).astype(np.int64) if out else np.zeros((0, 2), np.int64)


class RowMatcher:
    """:func:`lone_pairs` with the signature of
    :func:`sarmitsuba.tracing.integration.term_lanes.kd_tree_pairs` (``(features, label,
    tolerance) -> pairs``), counting the rows it left to the reference in :attr:`overflow` (one
    matcher per launch: not shared between threads)."""

    def __init__(self) -> None:
        self.overflow = 0

    def __call__(self, features: np.ndarray, label: np.ndarray, tolerance: float) -> np.ndarray:
        pairs, spilled = lone_pairs(features, label, tolerance)
        self.overflow += spilled
        return pairs
