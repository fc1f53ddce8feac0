"""The readable NumPy reference of :func:`sarmitsuba.tracing.visibility.motion.endpoint_rates`, the Dr.Jit
kernel of the boundary rates of eq. (M8) (docs/physics.md): one segment at a time, one candidate
line at a time, in plain Python. It shares no code with the kernel; tests compare the two.
"""
from __future__ import annotations

import numpy as np

__all__ = ["endpoint_rates_reference"]

#: A point lies on a line within this distance [m] (the kernel's contract).
ON_LINE = 1e-7
#: Two lines closer to parallel than this sine do not end a segment.
PARALLEL = 1e-6


def endpoint_rates_reference(start, end, owner, line_owner, lines, rates):
    """The rates float64 [s, 2] of ``start`` and of ``end`` [s, 2] (segments of pieces ``owner``
    [s]) from the candidate ``lines`` [L, 3] of pieces ``line_owner`` [L] and their ``rates``
    [L, 3], eq. (M8): see :func:`sarmitsuba.tracing.visibility.motion.endpoint_rates` for the arguments.
    Slow (a Python loop over segments and lines): for tests."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    lines, rates = np.asarray(lines, float), np.asarray(rates, float)
    out = np.zeros((2, len(start), 2))
    for s in range(len(start)):
        candidates = [j for j in range(len(lines)) if line_owner[j] == owner[s]]   # in their given order
        through = {0: [], 1: []}
        for j in candidates:
            for e, point in enumerate((start[s], end[s])):
                if abs(lines[j, 0] * point[0] + lines[j, 1] * point[1] + lines[j, 2]) < ON_LINE:
                    through[e].append(j)
        own = _preferred([j for j in through[0] if j in through[1]], rates)
        if own is None:
            continue
        for e, point in enumerate((start[s], end[s])):
            crossing = [j for j in through[e]
                        if abs(lines[j, 0] * lines[own, 1] - lines[j, 1] * lines[own, 0]) > PARALLEL]
            other = _preferred(crossing, rates)
            if other is None or not (np.any(rates[own] != 0) or np.any(rates[other] != 0)):
                continue
            # [g_own; g_other] p' = -[g_own' . p + h_own'; g_other' . p + h_other']
            matrix = np.array([lines[own, :2], lines[other, :2]])
            rhs = -np.array([rates[own, :2] @ point + rates[own, 2], rates[other, :2] @ point + rates[other, 2]])
            out[e, s] = np.linalg.solve(matrix, rhs)
    return out[0], out[1]


def _preferred(rows: list, rates: np.ndarray):
    """The first of ``rows`` whose line moves (a nonzero rate), else the first; None if empty."""
    for j in rows:
        if np.any(rates[j] != 0):
            return j
    return rows[0] if rows else None
