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
applied in :mod:`sarmitsuba.tracing.integration.patch_terms`).

:func:`endpoint_rates` finds, for every boundary segment, the line it lies on and, at each end,
the line that ends it among the candidate lines of its piece, and solves the 2 x 2 system above.
A segment none of whose candidate lines holds both its ends, or an end where no second line is
found, does not move (rate 0): the frozen boundary of the sub-aperture, as before this module.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..device import device_array, table_array
from ..loops import RECORDING, loop_mode

__all__ = ["ON_LINE", "line_rates", "endpoint_rates"]

#: A point lies on a line within this distance [m] (the clipped polygons' own rounding is about
#: 1e-12 of their coordinates).
ON_LINE = 1e-7
#: Two lines closer to parallel than this sine meet nowhere useful.
_PARALLEL = 1e-6


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
    """The rates [m per m of antenna travel] of the ends of boundary segments, eq. (M8): one Dr.Jit
    kernel, one lane per segment, looping over its piece's candidate lines (float64; the same code
    on the ``cuda`` variants). :func:`sarmitsuba.tracing.visibility.motion_reference.endpoint_rates_reference`
    is its readable NumPy reference.

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

    Notes
    -----
    A segment's *own* line is the first of its candidates (in their order within the piece) that
    holds both ends, a moving one preferred; at each end the *other* line is the first candidate
    through that end and at least :data:`_PARALLEL` (sine) off the own line, a moving one
    preferred. The rate solves ``[g_own; g_other] p' = -[g_own' . p + h_own'; g_other' . p +
    h_other']`` by Cramer's rule.
    """
    n = len(start)
    if n == 0 or len(lines) == 0:
        return np.zeros((n, 2)), np.zeros((n, 2))
    # the candidate lines sorted by piece (stably: a piece's lines keep their order, which breaks
    # ties); a segment's candidates are then one run of rows
    order = np.argsort(line_owner, kind="stable")
    owners = np.take(line_owner, order)
    first = np.searchsorted(owners, owner, side="left")
    count = np.searchsorted(owners, owner, side="right") - first
    lines, rates = np.take(np.asarray(lines, float), order, axis=0), np.take(np.asarray(rates, float), order, axis=0)
    moving = (rates[:, 0] != 0.0) | (rates[:, 1] != 0.0) | (rates[:, 2] != 0.0)
    start, end = np.asarray(start, float), np.asarray(end, float)
    f64, u32 = mi.Float64, mi.UInt32
    table = tuple(table_array(f64, column) for column in (*lines.T, *rates.T)) + (table_array(u32, moving),)
    lanes = tuple(device_array(f64, column) for column in (*start.T, *end.T))
    with RECORDING:                     # symbolic loops: recorded and run one thread at a time
        s_rate, e_rate = _rates_kernel(lanes, device_array(u32, first), device_array(u32, first + count), table)
        dr.eval(s_rate, e_rate)
    return np.stack([r.numpy() for r in s_rate], axis=1), np.stack([r.numpy() for r in e_rate], axis=1)


#: No candidate line found (a lane's index sentinel).
_NONE = 0xFFFFFFFF


def _rates_kernel(lanes, first, stop, table):
    """The Dr.Jit body of :func:`endpoint_rates`: ``lanes`` the segments' ``(sx, sy, ex, ey)``,
    candidates ``first .. stop - 1`` of the sorted ``table`` ``(a, b, c, a', b', c', moving)``."""
    sx, sy, ex, ey = lanes
    a_t, b_t, c_t, ra_t, rb_t, rc_t, moving_t = table
    f64, u32 = mi.Float64, mi.UInt32
    width = dr.width(first)
    none = dr.full(u32, _NONE, width)

    def line(k, active=True):
        return (dr.gather(f64, a_t, k, active), dr.gather(f64, b_t, k, active), dr.gather(f64, c_t, k, active),
                dr.gather(u32, moving_t, k, active) > 0)

    def on(a, b, c, x, y):
        return dr.abs(x * a + y * b + c) < ON_LINE

    def first_own(k, any_, moving_):
        a, b, c, m = line(k)
        both = on(a, b, c, sx, sy) & on(a, b, c, ex, ey)
        return (k + 1, dr.select(both & (any_ == _NONE), k, any_),
                dr.select(both & m & (moving_ == _NONE), k, moving_))

    _, own_any, own_moving = dr.while_loop((u32(first), u32(none), u32(none)), lambda k, *_: k < stop, first_own,
                                           mode=loop_mode(), label="own lines")
    own = dr.select(own_moving != _NONE, own_moving, own_any)
    has_own = own != _NONE
    ga, gb, _, moving_own = line(own, has_own)
    r_own = (dr.gather(f64, ra_t, own, has_own), dr.gather(f64, rb_t, own, has_own), dr.gather(f64, rc_t, own, has_own))

    def first_other(k, s_any, s_moving, e_any, e_moving):
        a, b, c, m = line(k)
        across = dr.abs(a * gb - b * ga) > _PARALLEL
        at_s, at_e = on(a, b, c, sx, sy) & across, on(a, b, c, ex, ey) & across
        return (k + 1, dr.select(at_s & (s_any == _NONE), k, s_any), dr.select(at_s & m & (s_moving == _NONE), k, s_moving),
                dr.select(at_e & (e_any == _NONE), k, e_any), dr.select(at_e & m & (e_moving == _NONE), k, e_moving))

    _, s_any, s_moving, e_any, e_moving = dr.while_loop(
        (u32(first), u32(none), u32(none), u32(none), u32(none)), lambda k, *_: k < stop, first_other,
        mode=loop_mode(), label="crossing lines")
    out = []
    for x, y, any_, moving_ in ((sx, sy, s_any, s_moving), (ex, ey, e_any, e_moving)):
        other = dr.select(moving_ != _NONE, moving_, any_)
        has = other != _NONE
        oa, ob, _, moving_other = line(other, has)
        r_other = (dr.gather(f64, ra_t, other, has), dr.gather(f64, rb_t, other, has), dr.gather(f64, rc_t, other, has))
        ok = has_own & has & (moving_own | moving_other)
        rhs0 = -(r_own[0] * x + r_own[1] * y + r_own[2])
        rhs1 = -(r_other[0] * x + r_other[1] * y + r_other[2])
        det = ga * ob - gb * oa
        safe = dr.select(ok & (det != 0.0), det, 1.0)
        out.append((dr.select(ok, (rhs0 * ob - rhs1 * gb) / safe, 0.0), dr.select(ok, (ga * rhs1 - oa * rhs0) / safe, 0.0)))
    return out[0], out[1]
