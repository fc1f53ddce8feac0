"""Lit-region boundaries that move with the antenna across a sub-aperture (docs/physics.md (M8)).

A sub-aperture's lit pieces are cut once, from its reference position ``A``. Their edges on the
face's own lines (patch lines, the face's border, the beam's reach) stay where they are for every
pulse; their edges on the lines the antenna defines (a chain's mirrored windows, eq. (M3), an
occluder's shadow, eq. (M4)) move as the antenna moves along its track. Every such line is a
smooth function of the antenna position, so each boundary point moves, to first order, at a rate
the lines through it fix: a point ``p`` on the lines ``l_1`` and ``l_2`` (rows ``(g_i, h_i)``, the
line ``g_i . p + h_i = 0``) with rates ``(g_i', h_i')`` per metre of travel moves at

    ``[g_1; g_2] p' = -[g_1' . p + h_1'; g_2' . p + h_2']``.

The rates come from the lines cut again at a second antenna position ``A_2`` (the sub-aperture's
last pulse): ``l' = (l(A_2) - l(A)) / |A_2 - A|``. A point on a line that does not move and on
one that does slides along the fixed one. Each pulse then evaluates its terms at
``p + t p'``, ``t`` its travel from ``A`` along ``(A_2 - A) / |A_2 - A|`` (float64 on the host,
applied in :mod:`sarmitsuba.tracing.integration`).

:func:`endpoint_rates` finds, for every boundary segment, the line it lies on and, at each end,
the line that ends it among the candidate lines of its piece, and solves the 2 x 2 system above.
A segment none of whose candidate lines holds both its ends, or an end where no second line is
found, does not move (rate 0): the frozen boundary of the sub-aperture, as before this module.
"""
from __future__ import annotations

import numpy as np

__all__ = ["ON_LINE", "line_rates", "endpoint_rates"]

#: A point lies on a line within this distance [m] (the clipped polygons' own rounding is about
#: 1e-12 of their coordinates).
ON_LINE = 1e-7
#: Two lines closer to parallel than this sine meet nowhere useful.
_PARALLEL = 1e-6
#: Segments handled per block (memory: ``block x lines x 3`` float64 arrays).
_BLOCK = 32768


def line_rates(at_a: np.ndarray, at_b: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Rates of half-plane rows ``(a, b, c)`` [..., H, 3] cut at two antenna positions ``step``
    [...] metres apart (the first axis): ``(at_b - at_a) / step``, 0 where ``step`` is 0 or a row
    is a padding or degenerate condition (``(a, b)`` not unit) at either position."""
    at_a, at_b = np.asarray(at_a, float), np.asarray(at_b, float)
    step = np.asarray(step, float).reshape((-1,) + (1,) * (at_a.ndim - 1))
    def unit(rows):                                  # |(a, b)| as np.linalg.norm sums it
        return np.abs(np.sqrt(rows[..., 0] * rows[..., 0] + rows[..., 1] * rows[..., 1]) - 1.0) < 1e-6
    ahead = step > 0
    rate = np.subtract(at_b, at_a)
    rate /= np.where(ahead, step, 1.0)
    return np.where((unit(at_a) & unit(at_b))[..., None] & ahead, rate, 0.0)


def endpoint_rates(start: np.ndarray, end: np.ndarray, owner: np.ndarray, line_owner: np.ndarray, lines: np.ndarray,
                   rates: np.ndarray):
    """The rates [m per m of antenna travel] of the ends of boundary segments.

    Parameters
    ----------
    start, end : float64 [s, 2]
        The segments (face coordinates, m).
    owner : int64 [s]
        Each segment's piece (any index shared with ``line_owner``).
    line_owner : int64 [L]
        The piece of each candidate line: the piece's own edges and the lines of its chain and
        occluders.
    lines : float64 [L, 3]
        Rows ``(a, b, c)``, ``a x + b y + c = 0``, ``(a, b)`` unit.
    rates : float64 [L, 3]
        Their rates (:func:`line_rates`; 0 for the face's own lines).

    Returns
    -------
    (float64 [s, 2], float64 [s, 2])
        The rates of ``start`` and ``end``; 0 for a segment on no candidate line, or whose ends no
        second line crosses, or on no moving line and at no moving line's end.
    """
    n = len(start)
    out_s, out_e = np.zeros((n, 2)), np.zeros((n, 2))
    if n == 0 or len(lines) == 0:
        return out_s, out_e
    # the candidate lines sorted by piece (stably: a piece's lines keep their order, which breaks
    # ties below); a segment's candidates are then one run of rows
    order = np.argsort(line_owner, kind="stable")
    owners = np.take(line_owner, order)
    lines, rates = np.take(np.asarray(lines, float), order, axis=0), np.take(np.asarray(rates, float), order, axis=0)
    moving = (rates[:, 0] != 0.0) | (rates[:, 1] != 0.0) | (rates[:, 2] != 0.0)
    columns = tuple(np.ascontiguousarray(lines[:, i]) for i in range(3))     # (1-D takes are the cheapest)
    start, end = np.asarray(start, float), np.asarray(end, float)
    for lo in range(0, n, _BLOCK):
        hi = min(n, lo + _BLOCK)
        first = np.searchsorted(owners, owner[lo:hi], side="left")
        count = np.searchsorted(owners, owner[lo:hi], side="right") - first
        out_s[lo:hi], out_e[lo:hi] = _solve(start[lo:hi], end[lo:hi], first, count, lines, rates, moving, columns)
    return out_s, out_e


def _first(seg: np.ndarray, score: np.ndarray, n: int) -> np.ndarray:
    """Per segment ``0 .. n``, the row of the first ``score`` True among its rows, else its first
    row (-1 where it has none); ``seg`` [k] non-decreasing."""
    best = np.full(n, -1, np.int64)
    if len(seg):
        head = np.flatnonzero(np.concatenate([[True], seg[1:] != seg[:-1]]))
        best[seg[head]] = head
        hit = np.flatnonzero(score)
        if len(hit):
            head = hit[np.concatenate([[True], seg[hit[1:]] != seg[hit[:-1]]])]
            best[seg[head]] = head
    return best


def _on_line(a, b, c, point, seg):
    """bool [m]: whether each segment's ``point`` [n, 2] (at the pairs' segments ``seg`` [m])
    lies on its candidate line ``(a, b, c)`` [m]: ``|a x + b y + c| < ON_LINE``, summed in that
    order (the einsum ``g . p`` and then ``+ h`` of the former kernel), in place."""
    value = np.take(np.ascontiguousarray(point[:, 0]), seg)
    value *= a
    term = np.take(np.ascontiguousarray(point[:, 1]), seg)
    term *= b
    value += term
    value += c
    return np.abs(value, out=value) < ON_LINE


def _solve(start, end, first, count, lines, rates, moving, columns):
    """:func:`endpoint_rates` of segments ``start``, ``end`` [n, 2] whose candidates are the
    rows ``first[k] .. first[k] + count[k]`` of ``lines`` (``columns`` its three columns,
    contiguous), ``rates`` and ``moving``."""
    n = len(start)
    seg = np.repeat(np.arange(n), count)
    line = np.arange(len(seg))
    line += np.take(first - (np.cumsum(count) - count), seg)
    a, b, c = (np.take(column, line) for column in columns)   # (1-D np.take: the cheapest gathers)
    ds, de = _on_line(a, b, c, start, seg), _on_line(a, b, c, end, seg)
    keep = np.flatnonzero(ds | de)
    seg, line, ds, de = seg[keep], line[keep], ds[keep], de[keep]
    g = np.take(lines, line, axis=0)[:, :2]
    line_moving = moving[line]
    own_rows = np.flatnonzero(ds & de)
    own = _first(seg[own_rows], line_moving[own_rows], n)
    has_own = own >= 0
    own_line = line[own_rows[np.maximum(own, 0)]] if len(own_rows) else np.zeros(n, np.int64)
    g_own = np.where(has_own[:, None], np.take(lines, own_line, axis=0)[:, :2], 0.0)
    r_own = np.where(has_own[:, None], np.take(rates, own_line, axis=0), 0.0)
    moving_own = has_own & moving[own_line]
    cross = np.abs(g[:, 0] * g_own[seg, 1] - g[:, 1] * g_own[seg, 0])
    rhs_own = (-(r_own[:, 0] * start[:, 0] + r_own[:, 1] * start[:, 1] + r_own[:, 2]),
               -(r_own[:, 0] * end[:, 0] + r_own[:, 1] * end[:, 1] + r_own[:, 2]))
    results = []
    for point, on, rhs0 in ((start, ds, rhs_own[0]), (end, de, rhs_own[1])):
        rows = np.flatnonzero(on & (cross > _PARALLEL))
        other = _first(seg[rows], line_moving[rows], n)
        has = other >= 0
        other_line = line[rows[np.maximum(other, 0)]] if len(rows) else np.zeros(n, np.int64)
        g_other = np.take(lines, other_line, axis=0)[:, :2]
        r_other = np.where(has[:, None], np.take(rates, other_line, axis=0), 0.0)
        ok = has_own & has & (moving_own | moving[other_line])
        rhs1 = -(r_other[:, 0] * point[:, 0] + r_other[:, 1] * point[:, 1] + r_other[:, 2])
        det = g_own[:, 0] * g_other[:, 1] - g_own[:, 1] * g_other[:, 0]
        safe = np.where(ok & (det != 0), det, 1.0)
        x = (rhs0 * g_other[:, 1] - rhs1 * g_own[:, 1]) / safe
        y = (g_own[:, 0] * rhs1 - g_other[:, 0] * rhs0) / safe
        results.append(np.where(ok[:, None], np.stack([x, y], axis=1), 0.0))
    return results[0], results[1]
