"""Mixed pieces cut exactly: a piece less the union of its occluders' shadows, as the oriented
boundary that Gordon's edge form integrates (docs/physics.md (M4)).

A piece whose corners disagree on some leg of its path is *mixed*. The rays that were hidden
name their occluders (:func:`sarmitsuba.tracing.visibility.lit_pieces.classify`). Each occluder ``O`` on leg
``l`` of a chain hides the points whose path crosses it on that leg: on the unfolded path (eq.
(M3)) the segment from the antenna ``A`` to ``y = U_d(x)`` meets the unfolded ``U_l(O)`` between
the chain's windows ``l - 1`` and ``l``; on the return leg the segment from ``x`` to ``A`` meets
``O`` itself. Both are intersections of half-spaces linear in ``y`` (or ``x``): the planes through
``A`` and ``O``'s edges, ``O``'s plane crossed beyond ``A``, and the order of the crossings
(:func:`shadow_lines`). Cut to the piece they are convex *cut-outs* ``C_i``.

The lit part ``B - (C_1 u ... u C_n)`` of a piece ``B`` has for boundary (:func:`boundary`) the
edges of ``B`` outside every ``C_j``, and, reversed, the edges of each ``C_i`` inside ``B`` and
outside every other ``C_j``. A segment meets a convex polygon in one interval (Cyrus and Beck,
1978), so trimming it by ``n`` cut-outs leaves at most ``n + 1`` segments: ``O(n^2)`` edges for any
number of overlapping occluders, exact (inclusion and exclusion would need ``2^n`` polygons).
Edges on one line count once: two with their polygons on the same side are one boundary (the
piece's, or the earlier cut-out's), two with their polygons on opposite sides none (two shadows
that meet). shapely computes the same differences polygon by polygon; the tests check against
it.
"""
from __future__ import annotations

import dataclasses

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..discovery.chains import Chains, to_face_lines, unfolded_frame
from ..mesh.patches import Surfaces
from ..mesh.polygons import EVERYTHING, corner_slots, edge_lines, moments
from .cut_outs import cut_outs

__all__ = ["shadow_lines", "shared_shadow_lines", "boundary", "lit_boundary", "COINCIDENT", "ClippedPieces", "clip_mixed", "replace_pieces",
           "segment_moments"]

#: Two edges on one line to this fraction of the segment's length (and parallel to as many
#: radians) are one line (a wall's foot seen through two parts).
COINCIDENT = 1e-9


def shadow_lines(surfaces: Surfaces, chains: Chains, chain: np.ndarray, occluder: np.ndarray, leg: np.ndarray,
                 antenna: np.ndarray) -> np.ndarray:
    """The half-planes (face coordinates of each chain's last part) of the points whose path
    through chain ``chain`` [k] the part ``occluder`` [k] hides on leg ``leg`` [k] (``0 .. d`` on
    the way out from ``antenna`` [k, 3], ``D`` the return), eq. (M4): float64 [k, H, 3]."""
    (found, ), slot = _shadow_rows(surfaces, chains, chain, occluder, leg, [antenna])
    return np.take(found, slot, axis=0)


def _shadow_rows(surfaces: Surfaces, chains: Chains, chain: np.ndarray, occluder: np.ndarray, leg: np.ndarray,
                 antennas: list[np.ndarray], receivers: list[np.ndarray] | None = None):
    """:func:`shadow_lines` from each of ``antennas`` (each [k, 3]) as the distinct half-planes
    (one float64 [r + 1, 3] per antenna, the last :data:`EVERYTHING`) and the rows that fill
    each slot, int64 [k, H] (the same for every antenna): the geometry that does not depend on
    the antenna (corners, frames, windows) is found once. Bistatic (``receivers``, one [k, 3] per
    antenna, docs/physics.md (B2)) the return leg's shadows are cast from the receiver, and at the
    first bounce leg 0 is the way out only."""
    depth = chains.parts.shape[1]
    k = len(chain)
    n_slot = surfaces.polygon.shape[1]
    order = chains.order[chain]
    back = (leg == depth) | ((order == 0) & (leg == 0) & (receivers is None))      # the return leg: the real frame
    level = np.where(back, 0, leg)
    map_at = chain * depth + level                            # row gathers by np.take: ~10x faster on [n, 3]
    lin = np.take(chains.lin.reshape(-1, 3, 3), map_at, axis=0)
    shift = np.take(chains.shift.reshape(-1, 3), map_at, axis=0)
    lin = np.where(back[:, None, None], np.eye(3), lin)
    shift = np.where(back[:, None], 0.0, shift)
    # each occluder's corners (the live slots only, row by row), carried into the leg's frame
    count = np.take(surfaces.n_corners, occluder)
    slots = corner_slots(count, n_slot)
    kk, ee = np.nonzero(slots)
    parts, of_part = np.unique(occluder, return_inverse=True)
    world = np.take(np.take(surfaces.world_polygon, parts, axis=0).reshape(-1, 3),
                    np.take(of_part.reshape(-1), kk) * n_slot + ee, axis=0)
    corners = np.einsum("nij,nj->ni", np.take(lin, kk, axis=0), world) + np.take(shift, kk, axis=0)
    normal = np.einsum("kij,kj->ki", lin, np.take(surfaces.normal, occluder, axis=0))
    offset = np.take(surfaces.offset, occluder) + np.einsum("ki,ki->k", normal, shift)
    first = np.cumsum(count) - count
    with np.errstate(divide="ignore", invalid="ignore"):
        centre = np.stack([np.bincount(kk, weights=corners[:, i], minlength=k) for i in range(3)], axis=1) \
            / count[:, None]
    following = np.take(first, kk) + (ee + 1) % np.take(count, kk)
    # the frame the half-spaces act on: the unfolded point y (way out), the point x (return),
    # per distinct chain once
    chain_set, of_chain = np.unique(chain, return_inverse=True)
    of_chain = of_chain.reshape(-1)
    frames = unfolded_frame(surfaces, chains.select(chain_set))
    last = chains.last[chain_set]
    reals = (surfaces.plane_point(last), surfaces.axis_u[last], surfaces.axis_v[last])
    origin, u, v = (np.where(back[:, None], np.take(r, of_chain, axis=0), np.take(f, of_chain, axis=0))
                    for f, r in zip(frames, reals))
    at = np.concatenate([np.tile(np.arange(k), 3), kk])
    frame = [np.take(x, at, axis=0) for x in (origin, u, v)]
    windows = tuple(np.take(w, of_chain, axis=0) for w in _window_planes(surfaces, chains, chain_set))
    last_leg = back | (leg == order)
    # the rows of each slot: 0, 1, 2 (the third only after a window), then one per live corner
    nowhere = 3 * k + len(kk)
    slot = np.full((k, n_slot + 3), nowhere)
    slot[:, 0], slot[:, 1] = np.arange(k), np.arange(k, 2 * k)
    slot[:, 2] = np.where(~back & (leg > 0), np.arange(2 * k, 3 * k), nowhere)
    slot.reshape(-1)[kk * (n_slot + 3) + 3 + ee] = np.arange(3 * k, nowhere)
    out = []
    for i, antenna in enumerate(antennas):
        if receivers is not None:                 # the return leg seen from the receiver (B2)
            antenna = np.where(back[:, None], receivers[i], antenna)
        a = offset - np.einsum("ki,ki->k", normal, antenna)
        sign = np.where(a >= 0, 1.0, -1.0)[:, None]
        # the half-spaces g . y + h >= 0
        g_all = np.empty((nowhere, 3))
        h_all = np.empty(nowhere)
        # O's plane crossed beyond A (t_O > 0), and before the point (t_O < 1) or the next window
        g_all[:k] = sign * normal
        h_all[:k] = -np.einsum("ki,ki->k", g_all[:k], antenna)
        g_next, h_next = _crossing_before(normal, a, windows, np.minimum(leg, depth - 1), antenna)
        g_all[k:2 * k] = np.where(last_leg[:, None], sign * normal, g_next)
        h_all[k:2 * k] = np.where(last_leg, -(sign[:, 0] * offset), h_next)
        g_all[2 * k:3 * k], h_all[2 * k:3 * k] = _crossing_after(normal, a, windows, leg - 1, antenna)
        # the planes through A and each edge, facing the occluder's centre
        seen = np.take(antenna, kk, axis=0)
        p = corners - seen
        q = np.take(p, following, axis=0)
        g = np.stack([p[:, 1] * q[:, 2] - p[:, 2] * q[:, 1], p[:, 2] * q[:, 0] - p[:, 0] * q[:, 2],
                      p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]], axis=1)
        g *= np.where(np.einsum("ni,ni->n", g, np.take(centre - antenna, kk, axis=0)) >= 0, 1.0, -1.0)[:, None]
        g_all[3 * k:] = g
        h_all[3 * k:] = -np.einsum("ni,ni->n", g, seen)
        out.append(np.concatenate([to_face_lines(g_all, h_all, *frame), [EVERYTHING]]))
    return out, slot


def shared_shadow_lines(surfaces: Surfaces, chains: Chains, chain: np.ndarray, occluder: np.ndarray, leg: np.ndarray,
                        *antennas: np.ndarray, receivers: tuple | None = None) -> list[np.ndarray]:
    """:func:`shadow_lines` of each distinct (chain, occluder, leg) once (the pieces of one chain
    share their occluders' shadows), from each of ``antennas`` (each [n_chains, 3]; bistatic with
    the return legs' ends ``receivers``, one [n_chains, 3] per antenna): one float64 [k, H, 3] per
    antenna."""
    key = (chain * (int(occluder.max(initial=0)) + 1) + occluder) * (int(leg.max(initial=0)) + 1) + leg
    _, first, back = np.unique(key, return_index=True, return_inverse=True)
    c = chain[first]
    found, slot = _shadow_rows(surfaces, chains, c, occluder[first], leg[first], [antenna[c] for antenna in antennas],
                               None if receivers is None else [r[c] for r in receivers])
    slot = np.take(slot, back.reshape(-1), axis=0)
    return [np.take(f, slot, axis=0) for f in found]


def _window_planes(surfaces: Surfaces, chains: Chains, chain: np.ndarray):
    """Each chain's unfolded window planes: normals [k, D, 3] and offsets [k, D] (zero beyond)."""
    depth = chains.parts.shape[1]
    normal = np.zeros((len(chain), depth, 3))
    offset = np.zeros((len(chain), depth))
    for i in range(depth):
        part = np.maximum(chains.parts[chain, i], 0)
        n_u = np.einsum("kij,kj->ki", chains.lin[chain, i], surfaces.normal[part])
        normal[:, i] = n_u
        offset[:, i] = surfaces.offset[part] + np.einsum("ki,ki->k", n_u, chains.shift[chain, i])
    return normal, offset


def _crossing_before(normal, a, windows, i, antenna):
    """``t_O < t_i`` (the occluder's plane crossed before window ``i``'s): ``(n_O / a_O - n_i / a_i)
    . (y - A) > 0`` as ``g . y + h >= 0``."""
    n_i = windows[0][np.arange(len(i)), i]
    a_i = windows[1][np.arange(len(i)), i] - np.einsum("ki,ki->k", n_i, antenna)
    g = normal / np.where(a != 0, a, 1.0)[:, None] - n_i / np.where(a_i != 0, a_i, 1.0)[:, None]
    return g, -np.einsum("ki,ki->k", g, antenna)


def _crossing_after(normal, a, windows, i, antenna):
    """``t_O > t_i`` (crossed after window ``i``'s): ``(n_i / a_i - n_O / a_O) . (y - A) > 0``."""
    g, h = _crossing_before(normal, a, windows, np.maximum(i, 0), antenna)
    return -g, -h


def _interval(start, delta, lines, on_line_inside):
    """The parameter interval ``[s, e]`` of segments ``start + t delta``, ``t`` in [0, 1], inside
    convex polygons given by their half-planes ``lines`` [..., H, 3] (Cyrus-Beck). Where a segment
    lies on one of the lines, ``on_line_inside(same)`` (``same``: the polygon lies on the segment's
    left, its own inside) says whether it counts as inside there. ``e <= s``: empty."""
    num = lines[..., 0] * start[..., None, 0] + lines[..., 1] * start[..., None, 1] + lines[..., 2]
    den = lines[..., 0] * delta[..., None, 0] + lines[..., 1] * delta[..., None, 1]
    length = np.linalg.norm(delta, axis=-1)[..., None]
    normal_len = np.hypot(lines[..., 0], lines[..., 1])
    parallel = np.abs(den) <= COINCIDENT * length * np.maximum(normal_len, 1e-300)
    on = parallel & (np.abs(num) <= COINCIDENT * np.maximum(length, 1.0)) & (normal_len > 0)
    # the polygon lies on the segment's left where its inward normal points left: (-dy, dx)
    same = (lines[..., 0] * -delta[..., None, 1] + lines[..., 1] * delta[..., None, 0]) > 0
    outside = (parallel & ~on & (num < 0)) | (on & ~on_line_inside(same))
    bound = -num / np.where(parallel, 1.0, den)
    lower = np.where(~parallel & (den > 0), bound, -np.inf).max(axis=-1)
    upper = np.where(~parallel & (den < 0), bound, np.inf).min(axis=-1)
    s, e = np.maximum(lower, 0.0), np.minimum(upper, 1.0)
    return s, np.where(np.any(outside, axis=-1), -1.0, e)


def _length(vectors: np.ndarray) -> np.ndarray:
    """Euclidean lengths of 2-vectors [..., 2] (``np.linalg.norm(vectors, axis=-1)``, to the bit)."""
    x, y = vectors[..., 0], vectors[..., 1]
    return np.sqrt(x * x + y * y)


def _interval_rows(start, delta, table, line_row, inside_same, inside_other, used=None):
    """:func:`_interval` (to the bit) of segments ``start + t delta`` [m, 2] in the convex
    polygons ``table[line_row]`` (half-planes [T, H, 3], ``line_row`` int64 [m]); on a polygon's
    line a segment counts as inside where ``inside_same`` [m] (the polygon on its left) or
    ``inside_other`` [m] (on its right) holds (bool arrays or scalars). ``used`` int64 [T]: the
    leading slots of each table row that may hold lines (the rest :data:`EVERYTHING`, which
    bound nothing; default all).

    One line slot at a time over the segments whose polygons have a line there (segments sorted
    by their polygons' line counts, so a prefix), the table rows' normal lengths computed once;
    only the few pairs parallel to a line, with the segment on or below it, are tested one by
    one for being outside."""
    m, n_lines = len(start), table.shape[1]
    if m == 0:
        return np.zeros(0), np.zeros(0)
    per = np.full(m, n_lines) if used is None else np.minimum(np.take(used, line_row), n_lines)
    rank = np.argsort((n_lines - per).astype(np.min_scalar_type(n_lines)), kind="stable")   # most lines first (radix)
    live = m - np.cumsum(np.bincount(per, minlength=n_lines + 1))[:n_lines]   # segments with a line h
    row = np.take(line_row, rank)
    sx, sy, dx, dy = (np.take(x, rank) for x in (start[:, 0], start[:, 1], delta[:, 0], delta[:, 1]))
    length = np.take(_length(delta), rank)
    scaled = COINCIDENT * length
    on_tol = COINCIDENT * np.maximum(length, 1.0)
    same_in = np.take(np.broadcast_to(inside_same, (m,)), rank)
    other_in = np.take(np.broadcast_to(inside_other, (m,)), rank)
    line_a, line_b, line_c = (np.ascontiguousarray(table[..., i].T) for i in range(3))   # [H, T]
    normal_len = np.hypot(line_a, line_b)
    floor_len = np.maximum(normal_len, 1e-300)
    lower, upper = np.full(m, -np.inf), np.full(m, np.inf)
    outside = np.zeros(m, bool)
    for h in range(n_lines):
        n = int(live[h])
        if n == 0:
            break
        r = row[:n]
        a, b, c = np.take(line_a[h], r), np.take(line_b[h], r), np.take(line_c[h], r)
        num = a * sx[:n] + b * sy[:n] + c
        den = a * dx[:n] + b * dy[:n]
        tol = scaled[:n] * np.take(floor_len[h], r)
        with np.errstate(divide="ignore", invalid="ignore"):
            bound = -num / den
        np.maximum(lower[:n], bound, out=lower[:n], where=den > tol)      # not parallel, entering
        np.minimum(upper[:n], bound, out=upper[:n], where=den < -tol)     # leaving
        # outside: parallel and below the line, or on it with the segment not counted inside
        near = np.flatnonzero((np.abs(den) <= tol) & (num <= on_tol[:n]))
        if len(near):
            n_r = num[near]
            on = (np.abs(n_r) <= on_tol[near]) & (np.take(normal_len[h], r[near]) > 0)
            same = (a[near] * -dy[near] + b[near] * dx[near]) > 0
            inside = np.where(same, same_in[near], other_in[near])
            outside[near[(~on & (n_r < 0)) | (on & ~inside)]] = True
    upper[outside] = -1.0
    s, e = np.empty(m), np.empty(m)
    s[rank], e[rank] = np.maximum(lower, 0.0), np.minimum(upper, 1.0)
    return s, e


def _trim(s_list, e_list):
    """``[0, 1]`` less the intervals ``(s_j, e_j)`` (arrays [m, n], empty where ``e <= s``): up to
    ``n + 1`` pieces ``(a, b, live)`` [m, n + 1], starting at 0 and at each interval's end that
    lies in no other interval (each start once), ending at the next interval's start or at 1."""
    m, n = s_list.shape
    real = e_list > s_list
    starts = np.concatenate([np.zeros((m, 1)), np.where(real, e_list, 2.0)], axis=1)
    ok = np.concatenate([np.ones((m, 1), bool), real], axis=1)
    live = ok & (starts < 1.0)
    live &= ~np.any(real[:, None, :] & (s_list[:, None, :] <= starts[:, :, None])
                    & (starts[:, :, None] < e_list[:, None, :]), axis=2)
    earlier = np.tril(np.ones((n + 1, n + 1), bool), -1)
    earlier[:, 0] = False                         # the start at 0 does not hide an equal interval end
    live &= ~np.any(earlier[None] & ok[:, None, :] & (starts[:, None, :] == starts[:, :, None]), axis=2)
    ends = np.where(real[:, None, :] & (s_list[:, None, :] > starts[:, :, None]), s_list[:, None, :], 1.0).min(axis=2, initial=1.0)
    return starts, ends, live & (ends > starts)


def boundary(base: np.ndarray, base_count: np.ndarray, cut: np.ndarray, cut_count: np.ndarray):
    """The oriented boundary of ``base`` less the union of its cut-outs (all convex,
    counter-clockwise, padded with their first corner).

    Parameters
    ----------
    base : float64 [g, V, 2]
    base_count : int64 [g]
    cut : float64 [g, n, W, 2]
        The cut-outs of each base (inside it; empty ones have count 0).
    cut_count : int64 [g, n]

    Returns
    -------
    (owner int64 [s], start float64 [s, 2], end float64 [s, 2]): each segment's base and ends,
    counter-clockwise about the lit region (around holes clockwise).
    """
    g, n = cut_count.shape
    width = cut.shape[2]
    cut_lines = edge_lines(cut.reshape(g * n, width, 2), cut_count.reshape(-1)).reshape(g, n, width, 3)
    cut_lines = np.where((cut_count > 0)[..., None, None], cut_lines, np.array([0.0, 0.0, -1.0]))   # empty: nowhere
    base_lines = edge_lines(base, base_count)
    owners = np.broadcast_to(np.arange(g)[:, None], (g, base.shape[1]))
    # the base's own edges, less what lies in a cut-out (an edge along a cut-out's edge with the
    # cut-out on its inside is covered)
    delta = np.roll(base, -1, axis=1) - base
    live = corner_slots(base_count, base.shape[1]) & (np.linalg.norm(delta, axis=2) > 0)
    s, e = _interval(base[:, :, None, :], delta[:, :, None, :], cut_lines[:, None], lambda same: same)
    out = [_pieces(base, delta, s, e, live, owners, False)]
    for i in range(n):
        c = cut[:, i]
        delta_c = np.roll(c, -1, axis=1) - c
        live_c = corner_slots(cut_count[:, i], width) & (np.linalg.norm(delta_c, axis=2) > 0)
        # the part inside the base (an edge along the base's edge is the base's, which it covers)
        s0, e0 = _interval(c, delta_c, base_lines[:, None], lambda same: ~same)
        others = [j for j in range(n) if j != i]
        earlier = np.array([j < i for j in others], bool)
        s, e = _interval(c[:, :, None, :], delta_c[:, :, None, :], cut_lines[:, others][:, None],
                         lambda same: ~same | earlier[None, None, :, None])
        # the segment restricted to the base's interval [s0, e0], its other intervals rescaled to it
        span = np.where(e0 > s0, e0 - s0, 1.0)
        start_in = c + s0[..., None] * delta_c
        delta_in = delta_c * span[..., None]
        s, e = (s - s0[..., None]) / span[..., None], (e - s0[..., None]) / span[..., None]
        out.append(_pieces(start_in, delta_in, s, e, live_c & (e0 > s0), owners[:, :1].repeat(width, 1), True))
    return tuple(np.concatenate([o[k] for o in out]) for k in range(3))


#: Slack [m] of the bounding-box test that pairs a boundary edge with the cut-outs that may hold
#: part of it (face coordinates are at most kilometres: float64 rounds them to picometres).
BOX_SLACK = 1e-6


def lit_boundary(base: np.ndarray, base_count: np.ndarray, cut: np.ndarray, cut_count: np.ndarray,
                 cut_owner: np.ndarray):
    """:func:`boundary` with the cut-outs as one flat list: each edge is trimmed only by the
    cut-outs whose bounding boxes meet its own, and the parts left are the gaps in the union of
    its intervals (sorted, a running maximum), so the cost follows the overlaps, not the square of
    the most cut-outs a piece has (docs/physics.md (M4)).

    Parameters
    ----------
    base : float64 [g, V, 2]
    base_count : int64 [g]
        0 for a base that returns nothing.
    cut : float64 [c, W, 2]
        Cut-outs (convex, counter-clockwise, padded, at least 3 corners), inside their bases.
    cut_count : int64 [c]
    cut_owner : int64 [c]
        Each cut-out's base. Of two cut-outs of one base along one line, with their insides on the
        same side, the one listed first keeps the edge.

    Returns
    -------
    As :func:`boundary`: ``(owner int64 [s], start float64 [s, 2], end float64 [s, 2])``.
    """
    g, width = len(base), cut.shape[1]
    cut_lines = edge_lines(cut, cut_count)
    base_lines = edge_lines(base, base_count)
    lo, hi = cut[:, 0].copy(), cut[:, 0].copy()      # padded with the first corner: the corners' box
    for k in range(1, width):
        np.minimum(lo, cut[:, k], out=lo)
        np.maximum(hi, cut[:, k], out=hi)
    # the edges: the bases' (index -1) and the cut-outs' restricted to their bases' insides
    delta_b = np.roll(base, -1, axis=1) - base
    live_b = corner_slots(base_count, base.shape[1]) & (_length(delta_b) > 0)
    at_b = np.flatnonzero(live_b)                               # flat (base, corner) slots
    rb = at_b // base.shape[1]
    delta_c = np.roll(cut, -1, axis=1) - cut
    live_c = corner_slots(cut_count, width) & (_length(delta_c) > 0)
    at_c = np.flatnonzero(live_c)
    rc = at_c // width
    dc, pc = np.take(delta_c.reshape(-1, 2), at_c, axis=0), np.take(cut.reshape(-1, 2), at_c, axis=0)
    owner_c = np.take(cut_owner, rc)
    s0, e0 = _interval_rows(pc, dc, base_lines, owner_c, False, True, base_count)
    inner = np.flatnonzero(e0 > s0)
    rc, s0, e0, dc, pc, owner_c = (np.take(x, inner, axis=0) for x in (rc, s0, e0, dc, pc, owner_c))
    start = np.concatenate([np.take(base.reshape(-1, 2), at_b, axis=0), pc + s0[:, None] * dc])
    delta = np.concatenate([np.take(delta_b.reshape(-1, 2), at_b, axis=0), dc * (e0 - s0)[:, None]])
    owner = np.concatenate([rb, owner_c])
    own = np.concatenate([np.full(len(rb), -1), rc])
    # each edge against the other cut-outs of its base whose boxes meet its own
    order = np.argsort(cut_owner, kind="stable")
    first = np.searchsorted(cut_owner[order], np.arange(g))
    per = np.take(np.bincount(cut_owner, minlength=g), owner)
    edge = np.repeat(np.arange(len(owner)), per)
    other = np.take(order, np.repeat(np.take(first, owner) - (np.cumsum(per) - per), per) + np.arange(int(per.sum())))
    end = start + delta
    e_lo, e_hi = np.minimum(start, end), np.maximum(start, end)
    hi_s, lo_s = hi + BOX_SLACK, lo - BOX_SLACK
    meet = np.take(own, edge) != other
    for i in range(2):
        meet &= np.take(e_lo[:, i], edge) <= np.take(hi_s[:, i], other)
        meet &= np.take(e_hi[:, i], edge) >= np.take(lo_s[:, i], other)
    meet = np.flatnonzero(meet)
    edge, other = np.take(edge, meet), np.take(other, meet)
    own_e = np.take(own, edge)
    is_base = own_e < 0
    s, e = _interval_rows(np.take(start, edge, axis=0), np.take(delta, edge, axis=0), cut_lines, other,
                          is_base | (other < own_e), ~is_base, cut_count)
    real = np.flatnonzero(e > s)
    edge, s, e = np.take(edge, real), np.take(s, real), np.take(e, real)
    # the gaps in the union of each edge's intervals: sorted by start, after the running end
    rank = np.lexsort((s, edge))
    edge, s, e = np.take(edge, rank), np.take(s, rank), np.take(e, rank)
    reach = _running_max(e, edge)
    head = np.ones(len(edge), bool)
    head[1:] = edge[1:] != edge[:-1]
    before = np.where(head, 0.0, np.roll(reach, 1))
    tail = np.ones(len(edge), bool)
    tail[:-1] = edge[1:] != edge[:-1]
    touched = np.zeros(len(owner), bool)
    touched[edge] = True
    untouched = np.flatnonzero(~touched)
    row = np.concatenate([edge, edge[tail], untouched])
    a = np.concatenate([before, reach[tail], np.zeros(len(untouched))])
    b = np.concatenate([s, np.ones(int(tail.sum())), np.ones(len(untouched))])
    keep = np.flatnonzero((b > a) & ((b - a) * np.take(_length(delta), row) > 1e-12))
    row, a, b = np.take(row, keep), np.take(a, keep), np.take(b, keep)
    d, o = np.take(delta, row, axis=0), np.take(start, row, axis=0)
    p = o + a[:, None] * d
    q = o + b[:, None] * d
    flip = (np.take(own, row) >= 0)[:, None]
    return np.take(owner, row), np.where(flip, q, p), np.where(flip, p, q)


def _running_max(values: np.ndarray, group: np.ndarray) -> np.ndarray:
    """The running maximum of ``values`` in each run of equal ``group`` (sorted), exact, by doubling (not
    ``accumulate(values + 2 group) - 2 group``: rounding by the edge's index in its launch)."""
    out, d = values.copy(), 1
    while d < len(out) and np.any(same := group[d:] == group[:-d]):
        np.maximum(out[d:], out[:-d], out=out[d:], where=same)       # (inputs read before the writes)
        d *= 2
    return out


def _pieces(start, delta, s, e, live, owner, reverse: bool):
    """Segments ``start + [a, b] delta`` of ``[0, 1]`` less the intervals ``(s, e)`` [..., n]."""
    rows_n = int(np.prod(live.shape))
    a, b, ok = _trim(s.reshape(rows_n, s.shape[-1]), e.reshape(rows_n, e.shape[-1]))
    ok &= live.reshape(-1, 1) & ((b - a) * np.linalg.norm(delta.reshape(-1, 2), axis=1)[:, None] > 1e-12)
    rows, k = np.nonzero(ok)
    p = start.reshape(-1, 2)[rows] + a[rows, k, None] * delta.reshape(-1, 2)[rows]
    q = start.reshape(-1, 2)[rows] + b[rows, k, None] * delta.reshape(-1, 2)[rows]
    if reverse:
        p, q = q, p
    return owner.reshape(-1)[rows], p, q


@dataclass(frozen=True)
class ClippedPieces:
    """Mixed pieces cut to what the antenna sees of them (face coordinates).

    Attributes
    ----------
    piece : int64 [m]
        Their rows in the bounce order's pieces.
    owner : int64 [s]
        For each boundary segment, its piece (an index into ``piece``).
    start, end : float64 [s, 2]
        The segments, counter-clockwise about the lit region.
    area : float64 [m]
    centroid : float64 [m, 2]
    second : float64 [m, 3]
        Second moments about the centroid (``Ixx, Ixy, Iyy``).
    diagonal : float64 [m]
        Their lit regions' bounding-box diagonals.
    """

    piece: np.ndarray
    owner: np.ndarray
    start: np.ndarray
    end: np.ndarray
    area: np.ndarray
    centroid: np.ndarray
    second: np.ndarray
    diagonal: np.ndarray

    def __len__(self) -> int:
        return len(self.piece)

    def merged(self, distance: float) -> "ClippedPieces":
        """The same lit regions, each straight run of boundary segments one segment and no
        segment shorter than ``distance`` [m] (cut-outs whose edges meet on one line split it
        where rounding decides; the geometric derivatives compare outlines without those splits,
        docs/physics.md (AD4))."""
        start, end, owner = self.start.copy(), self.end.copy(), self.owner.copy()
        keep = np.linalg.norm(end - start, axis=1) > distance
        for _ in range(len(start)):
            rows = np.flatnonzero(keep)
            if len(rows) < 2:
                break
            tree = cKDTree(np.column_stack([start[rows], owner[rows] * 1e9]))
            gap, nxt = tree.query(np.column_stack([end[rows], owner[rows] * 1e9]))
            a, b = end[rows] - start[rows], end[rows[nxt]] - start[rows[nxt]]
            cross = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
            # the next segment starts at this one's end and its end lies on this one's line
            straight = (gap <= distance) & (nxt != np.arange(len(rows))) & (np.einsum("ij,ij->i", a, b) > 0) \
                & (cross <= distance * np.linalg.norm(a, axis=1))
            if not np.any(straight):
                break
            i = np.flatnonzero(straight)[0]                     # one join at a time: chains stay whole
            end[rows[i]] = end[rows[nxt[i]]]
            keep[rows[nxt[i]]] = False
        rows = np.flatnonzero(keep)
        return dataclasses.replace(self, owner=owner[rows], start=start[rows], end=end[rows])

    @classmethod
    def empty(cls) -> "ClippedPieces":
        """No pieces."""
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0),
                   np.zeros((0, 2)), np.zeros((0, 3)), np.zeros(0))


def clip_mixed(surfaces: Surfaces, lit, antenna: np.ndarray, only: np.ndarray | None = None,
               receiver: np.ndarray | None = None, kernels=None) -> ClippedPieces:
    """Every mixed piece of ``lit`` (:class:`sarmitsuba.tracing.visibility.lit_pieces.LitPieces`) whose
    occluders are all mesh parts, cut to its lit region: the piece less the shadows of the
    occluders its rays met, on the leg they met them (eq. (M4)). ``antenna`` [n_chains, 3];
    ``only``: just these rows of ``lit.pieces``; ``receiver`` [n_chains, 3]: bistatic, where the
    return legs end (docs/physics.md (B2)); ``kernels``: ``fused.GeometryKernels`` in place of ours."""
    blockers = lit.blockers
    usable = lit.mixed & blockers.mesh_only(len(lit.mixed))
    if only is not None:
        chosen = np.zeros(len(usable), bool)
        chosen[only] = True
        usable &= chosen
    rows = np.flatnonzero(usable)
    pieces = lit.pieces.select(rows)
    poly, count = pieces.polygons()
    pair_piece, key = blockers.rows(rows, mesh=True)
    leg, occluder = key // surfaces.n_parts, key % surfaces.n_parts
    chain = pieces.region[pair_piece]
    lines, = (kernels.shadow_lines if kernels else shared_shadow_lines)(
        surfaces, lit.chains, chain, occluder, leg, antenna, receivers=None if receiver is None else (receiver,))
    # empty cut-outs cut nothing; a cut-out that is the whole piece leaves nothing lit
    cut, cut_count, dark = (kernels.cut_outs if kernels else cut_outs)(poly, count, pair_piece, lines)
    real = (cut_count >= 3) & ~np.take(dark, pair_piece)
    cut, cut_count, pair_piece = cut[real], cut_count[real], pair_piece[real]
    owner, start, end = (kernels.lit_boundary if kernels else lit_boundary)(poly, np.where(dark, 0, count), cut, cut_count, pair_piece)
    area, centroid, second, diagonal = segment_moments(owner, start, end, len(rows))
    keep = area > 1e-12 * pieces.patch ** 2
    new = np.cumsum(keep) - 1
    seg_keep = np.take(keep, owner)
    return ClippedPieces(piece=rows[keep], owner=np.take(new, owner[seg_keep]), start=start[seg_keep],
                         end=end[seg_keep], area=area[keep], centroid=centroid[keep], second=second[keep],
                         diagonal=diagonal[keep])


def replace_pieces(old: ClippedPieces, new: ClippedPieces, rows: np.ndarray) -> ClippedPieces:
    """``old`` with the pieces ``rows`` (rows of the bounce order's pieces) taken from ``new``."""
    keep = ~np.isin(old.piece, rows)
    index = np.cumsum(keep) - 1
    seg = keep[old.owner]
    return ClippedPieces(piece=np.concatenate([old.piece[keep], new.piece]),
                         owner=np.concatenate([index[old.owner[seg]], int(keep.sum()) + new.owner]),
                         start=np.concatenate([old.start[seg], new.start]), end=np.concatenate([old.end[seg], new.end]),
                         area=np.concatenate([old.area[keep], new.area]),
                         centroid=np.concatenate([old.centroid[keep], new.centroid]),
                         second=np.concatenate([old.second[keep], new.second]),
                         diagonal=np.concatenate([old.diagonal[keep], new.diagonal]))


def segment_moments(owner: np.ndarray, start: np.ndarray, end: np.ndarray, n: int):
    """Area, centroid, second moments about the centroid (``Ixx, Ixy, Iyy``) and bounding-box
    diagonal of regions given by closed oriented boundaries (Green's theorem over each region's
    segments ``owner`` [s]); ``n`` regions."""
    x0, y0, x1, y1 = start[:, 0], start[:, 1], end[:, 0], end[:, 1]
    cross = x0 * y1 - x1 * y0
    area = 0.5 * np.bincount(owner, weights=cross, minlength=n)
    safe = np.where(area != 0, area, 1.0)
    cx = np.bincount(owner, weights=(x0 + x1) * cross, minlength=n) / (6 * safe)
    cy = np.bincount(owner, weights=(y0 + y1) * cross, minlength=n) / (6 * safe)
    ixx = np.bincount(owner, weights=(x0 * x0 + x0 * x1 + x1 * x1) * cross, minlength=n) / 12 - area * cx * cx
    iyy = np.bincount(owner, weights=(y0 * y0 + y0 * y1 + y1 * y1) * cross, minlength=n) / 12 - area * cy * cy
    ixy = np.bincount(owner, weights=(x0 * y1 + 2 * x0 * y0 + 2 * x1 * y1 + x1 * y0) * cross, minlength=n) / 24 \
        - area * cx * cy
    # the box: each segment's, then per region over its segments sorted by region
    lo = np.full((n, 2), np.inf)
    hi = np.full((n, 2), -np.inf)
    if len(owner):
        rank = np.argsort(owner, kind="stable")
        ranked = np.take(owner, rank)
        head = np.flatnonzero(np.concatenate([[True], ranked[1:] != ranked[:-1]]))
        first, last = np.take(start, rank, axis=0), np.take(end, rank, axis=0)
        lo[ranked[head]] = np.minimum.reduceat(np.minimum(first, last), head, axis=0)
        hi[ranked[head]] = np.maximum.reduceat(np.maximum(first, last), head, axis=0)
    diagonal = np.where(np.isfinite(lo[:, 0]), _length(hi - lo), 0.0)
    return area, np.stack([cx, cy], axis=1), np.stack([ixx, ixy, iyy], axis=1), diagonal
