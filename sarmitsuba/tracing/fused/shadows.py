"""The occluders' shadow half-planes on the Dr.Jit device (docs/physics.md (M3), (M4), (B2);
docs/design.md section 10.1).

:func:`sarmitsuba.tracing.visibility.occlusion.shared_shadow_lines` is the readable NumPy
reference: for each distinct (chain, occluder, leg) row, the half-planes (face coordinates of the
chain's last part) of the points whose path the occluder hides on that leg. Here the same rows
come from one kernel, one lane per distinct row and antenna, which does what the reference's
``_shadow_rows``, ``_window_planes``, ``_crossing_before``, ``_crossing_after``,
:func:`~sarmitsuba.tracing.discovery.chains.unfolded_frame` and
:func:`~sarmitsuba.tracing.discovery.chains.to_face_lines` do:

* the leg's frame (``lin``, ``shift`` of the chain at that leg; the identity on the return leg and,
  monostatic, on the first bounce's only leg), the occluder's plane and corners carried into it,
  the corners' centre (their sum in order, as ``np.bincount``);
* the antenna (on the return leg, bistatic, the receiver) and the rows: the occluder's plane
  crossed beyond it; crossed before the next window (or the point, on the last leg); after the
  previous window (legs after the first, not the return leg: else :data:`EVERYTHING`); then one
  plane through the antenna and each edge, facing the centre (:data:`EVERYTHING` past the
  occluder's corners);
* each as a face half-plane in the chain's unfolded frame (the real frame on the return leg),
  ``np.hypot`` written as glibc's (2.35 and later, without FMA) computes it.

Why a lane per row, not per half-plane: a row's frame, plane, windows and centre are shared by its
``H`` half-planes, and its edge loop carries each corner to the next edge.

The host finds the distinct rows (``np.unique`` of the reference's key), gathers the per-row
antennas, and expands the rows back with one ``np.take`` per antenna, into memory from Dr.Jit's
allocator (which keeps freed blocks: fresh NumPy memory of megabytes costs its page faults on
every call, and the reference pays them); the surfaces' and chains' tables go to the device once
per object (they are immutable). Every float64 operation is the
reference's, in its order: ``np.einsum`` over 3 terms sums ``(x0 y0 + x2 y2) + x1 y1`` and adds
the result to a zero (a -0 becomes +0), written here with an opaque zero that Dr.Jit cannot fold;
Dr.Jit's LLVM backend does not contract products and sums into FMAs. The results agree bit for
bit with the reference on the ``llvm`` variants (tests/test_fused_shadows.py); the ``cuda``
variants have not been compared (nor other libm versions' ``hypot``).
"""
from __future__ import annotations

import weakref

import drjit as dr
import mitsuba as mi
import numpy as np

from ..device import device_array, releasing, table_array
from ..loops import RECORDING, loop_mode
from ..mesh.polygons import EVERYTHING
from ..visibility import occlusion

__all__ = ["shared_shadow_lines", "DEVICE_ROWS"]

#: Fewer rows, or distinct rows, than this go to the reference: the kernel's tracing and launch
#: (about 0.5 ms, warm) cost more than the reference's NumPy below about 60 distinct rows (urban
#: and Munich's calls, 2-core VM, 2026-11-28; from 75 on the kernel was as fast or faster).
DEVICE_ROWS = 64

#: Columns of the surfaces' table: normal (3), offset, plane point (3), axis_u (3), axis_v (3),
#: then the world corners (3 per slot).
_S_CORNERS = 13
#: Columns of the chains' table per level: lin (9, row-major), shift (3).
_C_LEVEL = 12

_CACHE: dict = {}


def _cached(obj, build):
    """``build(obj)``, computed once per live object (keyed by identity, dropped with it)."""
    key = id(obj)
    hit = _CACHE.get(key)
    if hit is not None and hit[0]() is obj:
        return hit[1]
    value = build(obj)
    _CACHE[key] = (weakref.ref(obj, lambda _, key=key: _CACHE.pop(key, None)), value)
    return value


def _surface_tables(surfaces):
    """The surfaces' device tables: float64 ``[n_parts, 13 + 3 V]`` (flat) and the corner counts."""
    n = surfaces.n_parts
    parts = np.arange(n)
    table = np.concatenate([surfaces.normal, surfaces.offset[:, None], surfaces.plane_point(parts),
                            surfaces.axis_u, surfaces.axis_v, surfaces.world_polygon.reshape(n, -1)], axis=1)
    return table_array(mi.Float64, table.reshape(-1)), table_array(mi.UInt32, surfaces.n_corners)


def _chain_tables(chains):
    """The chains' device tables: float64 ``[n, D, 12]`` (lin, shift; flat) and uint32 ``[n, 1 + D]``
    (order, then the parts, -1 as 0)."""
    n, depth = chains.parts.shape
    table = np.concatenate([chains.lin.reshape(n, depth, 9), chains.shift], axis=2)
    ints = np.concatenate([chains.order[:, None], np.maximum(chains.parts, 0)], axis=1)
    return table_array(mi.Float64, table.reshape(-1)), table_array(mi.UInt32, ints.reshape(-1))


@releasing
def shared_shadow_lines(surfaces, chains, chain: np.ndarray, occluder: np.ndarray, leg: np.ndarray,
                        *antennas: np.ndarray, receivers: tuple | None = None) -> list[np.ndarray]:
    """:func:`sarmitsuba.tracing.visibility.occlusion.shared_shadow_lines` on the device: the same
    half-planes, bit for bit (docs/physics.md (M4); bistatic (B2)).

    Parameters
    ----------
    surfaces : Surfaces
    chains : Chains
    chain, occluder, leg : int64 [k]
        Each row's chain, occluding part and leg (``0 .. d`` on the way out, ``D`` the return).
    *antennas : float64 [n_chains, 3]
        Antenna positions [m], one array per antenna, indexed by chain.
    receivers : tuple of float64 [n_chains, 3], optional
        Bistatic: the return legs' ends [m], one per antenna.

    Returns
    -------
    list of float64 [k, H, 3]
        One per antenna: rows ``(a, b, c)``, ``a x + b y + c >= 0`` (``(a, b)`` unit or zero,
        face coordinates [m] of each chain's last part), ``H = V + 3``; padding rows
        :data:`~sarmitsuba.tracing.mesh.polygons.EVERYTHING`. From the kernel they are writable
        views of one buffer that Dr.Jit allocated.

    Batches of fewer than :data:`DEVICE_ROWS` rows, or distinct rows, take the reference's NumPy
    (which is faster there).
    """
    if len(chain) < max(DEVICE_ROWS, 1):
        return occlusion.shared_shadow_lines(surfaces, chains, chain, occluder, leg, *antennas, receivers=receivers)
    key = (chain * (int(occluder.max(initial=0)) + 1) + occluder) * (int(leg.max(initial=0)) + 1) + leg
    _, first, back = np.unique(key, return_index=True, return_inverse=True)
    k, n_ant = len(first), len(antennas)
    c = chain[first]
    if k < DEVICE_ROWS:                             # few distinct rows: the reference
        return occlusion.shared_shadow_lines(surfaces, chains, chain, occluder, leg, *antennas, receivers=receivers)
    n_slot = surfaces.polygon.shape[1]
    H = n_slot + 3
    ends = antennas if receivers is None else receivers
    per_lane = np.empty((n_ant, k, 6))
    for i in range(n_ant):
        np.take(antennas[i], c, axis=0, out=per_lane[i, :, :3])
        np.take(ends[i], c, axis=0, out=per_lane[i, :, 3:])
    ints = np.empty((n_ant, k, 3), np.int64)
    ints[:, :, 0], ints[:, :, 1], ints[:, :, 2] = c, occluder[first], leg[first]
    s_table = _cached(surfaces, _surface_tables)
    c_table = _cached(chains, _chain_tables)
    lanes = (device_array(mi.Float64, per_lane.reshape(-1)), device_array(mi.UInt32, ints.reshape(-1)))
    sizes = (chains.parts.shape[1], n_slot, int(receivers is not None))
    with RECORDING:
        out = _kernel(lanes, s_table, c_table, sizes)
        dr.eval(out)
    block = np.stack([x.numpy() for x in out], axis=1).reshape(n_ant, k, H * 3)
    # the rows expanded into memory from Dr.Jit's allocator, which keeps freed blocks for the next
    # call (fresh NumPy memory of megabytes costs its page faults again on every call)
    result = dr.empty(mi.Float64, n_ant * len(chain) * H * 3)
    dr.eval(result)
    result = result.numpy().reshape(n_ant, len(chain), H * 3)
    back = back.reshape(-1)
    for i in range(n_ant):
        np.take(block[i], back, axis=0, out=result[i], mode="clip")     # (in range: "clip" is unbuffered)
    return [result[i].reshape(len(chain), H, 3) for i in range(n_ant)]


def _dot(x, y, zero):
    """``np.einsum("ki,ki->k", x, y)`` of 3-vectors (tuples of Float64), to the bit."""
    return ((x[0] * y[0] + x[2] * y[2]) + x[1] * y[1]) + zero


def _mat_vec(m, x, zero):
    """``np.einsum("kij,kj->ki", m, x)`` (``m`` nine Float64, row-major), to the bit."""
    return tuple(_dot(m[3 * i:3 * i + 3], x, zero) for i in range(3))


def _hypot(x, y):
    """``np.hypot`` as glibc (2.35 and later, the generic code without FMA) computes it."""
    f64 = mi.Float64
    x, y = dr.abs(x), dr.abs(y)
    ax, ay = dr.select(x < y, y, x), dr.select(x < y, x, y)
    scale, large, tiny, eps = 2.0 ** -600, 2.0 ** 511, 2.0 ** -511, 2.0 ** -54
    ax_k = dr.select(ax > large, ax * scale, dr.select(ay < tiny, ax / scale, ax))
    ay_k = dr.select(ax > large, ay * scale, dr.select(ay < tiny, ay / scale, ay))
    h = dr.sqrt(ax_k * ax_k + ay_k * ay_k)
    near = h <= 2.0 * ay_k
    d_near, d_far = h - ay_k, h - ax_k
    t1 = dr.select(near, ax_k * (2.0 * d_near - ax_k), 2.0 * d_far * (ax_k - 2.0 * ay_k))
    t2 = dr.select(near, (d_near - 2.0 * (ax_k - ay_k)) * d_near, (4.0 * d_far - ay_k) * ay_k + d_far * d_far)
    h = h - (t1 + t2) / (2.0 * h)
    h = dr.select(ax > large, h / scale, dr.select(ay < tiny, h * scale, h))
    wide = dr.select(ax > large, ay <= ax * eps, dr.select(ay < tiny, ax >= ay / eps, ay <= ax * eps))
    h = dr.select(wide, ax + ay, h)
    finite = dr.isfinite(x) & dr.isfinite(y)
    return dr.select(finite, h, dr.select(dr.isinf(x) | dr.isinf(y), f64(np.inf), x + y))


def _face_line(g, h, frame, zero):
    """:func:`~sarmitsuba.tracing.discovery.chains.to_face_lines` of ``g . y + h >= 0``: ``(a, b, c)``."""
    origin, u, v = frame
    a, b = _dot(g, u, zero), _dot(g, v, zero)
    c = _dot(g, origin, zero) + h
    norm = _hypot(a, b)
    scale = dr.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]) * 1e-12
    flat = norm <= scale
    safe = dr.select(flat, 1.0, norm)
    return (dr.select(flat, 0.0, a / safe), dr.select(flat, 0.0, b / safe),
            dr.select(flat, dr.select(c >= 0, 1.0, -1.0), c / safe))


def _gather3(table, at):
    """Three consecutive float64 entries of ``table`` from ``at`` on."""
    return tuple(dr.gather(mi.Float64, table, at + j) for j in range(3))


def _crossing_before(normal, a, window, antenna, zero):
    """The reference's ``_crossing_before``: ``(g, h)`` of ``t_O < t_i`` for window ``(n_i, o_i)``."""
    n_i, o_i = window
    a_i = o_i - _dot(n_i, antenna, zero)
    a_s, a_is = dr.select(a != 0, a, 1.0), dr.select(a_i != 0, a_i, 1.0)
    g = tuple(normal[j] / a_s - n_i[j] / a_is for j in range(3))
    return g, -_dot(g, antenna, zero)


def _row_geometry(lanes, s_table, c_table, sizes):
    """Per lane: its row's indices, antenna, leg frame, occluder plane, corner function, face
    frame and windows (the reference's ``_shadow_rows`` before its antenna loop)."""
    f64, u32 = mi.Float64, mi.UInt32
    lane_f, lane_i = lanes
    s_tab, s_count = s_table
    c_tab, c_int = c_table
    depth, n_slot, bistatic = sizes
    n = dr.width(lane_i) // 3
    lane = dr.arange(u32, n)
    zero = dr.opaque(f64, 0.0, n)
    D, width, bistatic = dr.opaque(u32, depth), dr.opaque(u32, _S_CORNERS + 3 * n_slot), dr.opaque(u32, bistatic)
    c, o, leg = (dr.gather(u32, lane_i, 3 * lane + j) for j in range(3))
    antenna, end = _gather3(lane_f, 6 * lane), _gather3(lane_f, 6 * lane + 3)
    ints = c * (D + 1)
    order = dr.gather(u32, c_int, ints)
    back = (leg == D) | ((order == 0) & (leg == 0) & (bistatic == 0))
    antenna = tuple(dr.select(back, e, a) for e, a in zip(end, antenna))    # the return leg: the receiver (B2)

    def level(i):
        at = (c * D + i) * _C_LEVEL
        return tuple(dr.gather(f64, c_tab, at + j) for j in range(9)), _gather3(c_tab, at + 9)

    lin, shift = level(dr.select(back, 0, leg))
    lin = tuple(dr.select(back, float(j % 4 == 0), x) for j, x in enumerate(lin))    # the real frame
    shift = tuple(dr.select(back, 0.0, x) for x in shift)
    s0 = o * width
    normal = _mat_vec(lin, _gather3(s_tab, s0), zero)
    offset = dr.gather(f64, s_tab, s0 + 3) + _dot(normal, shift, zero)

    def corner(e):
        w = _gather3(s_tab, s0 + _S_CORNERS + 3 * e)
        return tuple(x + s for x, s in zip(_mat_vec(lin, w, zero), shift))

    last = dr.gather(u32, c_int, ints + 1 + order) * width
    lin_d, shift_d = level(order)
    real = tuple(_gather3(s_tab, last + 4 + 3 * j) for j in range(3))
    unfolded = (tuple(x + s for x, s in zip(_mat_vec(lin_d, real[0], zero), shift_d)),
                _mat_vec(lin_d, real[1], zero), _mat_vec(lin_d, real[2], zero))
    frame = tuple(tuple(dr.select(back, r, u) for r, u in zip(rv, uv)) for rv, uv in zip(real, unfolded))

    def window(i):
        part = dr.gather(u32, c_int, ints + 1 + i) * width
        lin_i, shift_i = level(i)
        n_u = _mat_vec(lin_i, _gather3(s_tab, part), zero)
        return n_u, dr.gather(f64, s_tab, part + 3) + _dot(n_u, shift_i, zero)

    windows = (window(dr.minimum(leg, D - 1)), window(dr.select(leg > 0, leg - 1, 0)))
    count = dr.gather(u32, s_count, o)
    return (lane, zero, leg, order, back, antenna), (normal, offset, corner, count), frame, windows


def _kernel(lanes, s_table, c_table, sizes):
    """The shadow rows of every lane (a distinct row and antenna): ``(a, b, c)``, float64 ``[n H]``
    each (row ``j`` of lane ``i`` at ``i H + j``)."""
    f64, u32 = mi.Float64, mi.UInt32
    (lane, zero, leg, order, back, antenna), (normal, offset, corner, count), frame, windows = \
        _row_geometry(lanes, s_table, c_table, sizes)
    n, n_slot = dr.width(lane), sizes[1]
    # O's plane crossed beyond A (row 0), before the next window or the point (1), after the
    # previous window (2)
    a = offset - _dot(normal, antenna, zero)
    sign = dr.select(a >= 0, 1.0, -1.0)
    g0 = tuple(sign * x for x in normal)
    h0 = -_dot(g0, antenna, zero)
    g_next, h_next = _crossing_before(normal, a, windows[0], antenna, zero)
    last_leg = back | (leg == order)
    g1 = tuple(dr.select(last_leg, x, y) for x, y in zip(g0, g_next))
    h1 = dr.select(last_leg, -(sign * offset), h_next)
    g_prev, h_prev = _crossing_before(normal, a, windows[1], antenna, zero)
    after = ~back & (leg > 0)

    # the corners' centre: their sum in order (np.bincount), over their count
    def add(e, sx, sy, sz):
        p = corner(e)
        return e + 1, sx + p[0], sy + p[1], sz + p[2]

    _, sx, sy, sz = dr.while_loop((dr.zeros(u32, n), dr.zeros(f64, n), dr.zeros(f64, n), dr.zeros(f64, n)),
                                  lambda e, *_: e < count, add, mode=loop_mode(), label="shadow centre")
    to_centre = tuple(s / f64(count) - x for s, x in zip((sx, sy, sz), antenna))
    height = dr.opaque(u32, n_slot + 3)
    # every row EVERYTHING (0, 0, 1) until written: the rows past the corners stay so
    out = (dr.zeros(f64, n * (n_slot + 3)), dr.zeros(f64, n * (n_slot + 3)), dr.full(f64, 1.0, n * (n_slot + 3)))

    # row j: the three above, then the plane through A and edge j - 3 (corner p to the next),
    # facing the centre; row 2 EVERYTHING where there is no previous window
    def row(j, px, py, pz):
        e = dr.select(j >= 3, j - 3, 0)
        q = corner(dr.select(e + 1 < count, e + 1, 0))
        p = (px - antenna[0], py - antenna[1], pz - antenna[2])
        r = tuple(x - y for x, y in zip(q, antenna))
        g = (p[1] * r[2] - p[2] * r[1], p[2] * r[0] - p[0] * r[2], p[0] * r[1] - p[1] * r[0])
        s = dr.select(_dot(g, to_centre, zero) >= 0, 1.0, -1.0)
        g = tuple(x * s for x in g)
        h = -_dot(g, antenna, zero)
        for k, (g_k, h_k) in enumerate(((g0, h0), (g1, h1), (tuple(-x for x in g_prev), -h_prev))):
            g = tuple(dr.select(j == k, x, y) for x, y in zip(g_k, g))
            h = dr.select(j == k, h_k, h)
        keep = (j != 2) | after
        for target, value, pad in zip(out, _face_line(g, h, frame, zero), EVERYTHING):
            dr.scatter(target, dr.select(keep, value, pad), lane * height + j)
        return (j + 1,) + tuple(dr.select(j >= 3, b, a) for a, b in zip((px, py, pz), q))

    dr.while_loop((dr.zeros(u32, n),) + corner(dr.zeros(u32, n)), lambda j, *_: j < count + 3, row,
                  mode=loop_mode(), label="shadow rows")
    return out
