"""The readable NumPy reference of the patch terms' kernel (:mod:`sarmitsuba.tracing.integration.patch_terms`),
one pulse at a time, term by term (docs/physics.md (M5)).

:func:`lane_terms` evaluates :class:`~sarmitsuba.tracing.integration.patch_terms.TermLanes` for one antenna
position in float64 with the formulas of physics.md written out: the lane's point reached through
its chain of mirrors, ``u = d - b``, the near-specular gate at its piece's centroid, the split
decision of open segments at their midpoint, and the term's coefficient and spectral orders. The
density (obliquity, reflection coefficients, pattern, spreading) is a callable, as in
:func:`sarmitsuba.tracing.integration.physical_optics.tube_terms`. tests/test_patch_kernel.py compares it with
the kernel's path list.
"""
from __future__ import annotations

import math

import numpy as np

from .patch_terms import AREA, NEAR_SPECULAR, OPEN_END, OPEN_MID, OPEN_START, SINC, SPLIT_END, SPLIT_START, TermLanes

__all__ = ["lane_terms", "polygon_linear_integral"]


def _sinc(x):
    return np.where(np.abs(x) < 1e-8, 1.0, np.sin(x) / np.where(x == 0, 1.0, x))


def polygon_linear_integral(mid: np.ndarray, edge: np.ndarray, normal: np.ndarray, u: np.ndarray, k: float):
    """``int exp(-j k u . r) dA`` over a polygon given by its boundary segments (midpoints ``mid``
    relative to the centroid and edge vectors ``edge``, [s, 3], counter-clockwise about
    ``normal``), Gordon's closed form, and ``k d/dk`` of it; ``(area, 0)`` when ``u`` has no part
    in the plane."""
    u_t = u - normal * (u @ normal)
    ut2 = float(u_t @ u_t)
    if ut2 == 0.0:
        area = 0.5 * float(np.sum(np.cross(mid - 0.5 * edge, edge) @ normal))
        return complex(area), 0j
    alpha = 0.5 * k * (edge @ u)
    common = np.exp(-1j * k * (mid @ u)) * 1j * (np.cross(u_t, edge) @ normal) / (k * ut2)
    sinc = _sinc(alpha)
    f = np.sum(common * sinc)
    derivative = np.sum(common * ((np.cos(alpha) - sinc) - sinc - 1j * k * (mid @ u) * sinc))
    return complex(f), complex(derivative)


def lane_terms(lanes: TermLanes, pieces, antenna: np.ndarray, k: float, alpha_s: float, depth: int, density,
               edge_field=None):
    """The terms of every lane for one antenna position (stop and hop), float64.

    Parameters
    ----------
    lanes : TermLanes
    pieces : PieceTable
    antenna : float64 [3], m
    k : float
        Carrier wavenumber [rad/m].
    alpha_s : float
        The split threshold.
    depth : int
        Bounce order - 1.
    density : callable
        ``(lane, d, b, s, R, cos_i, cos_b) -> complex``: the PO density at the lane's point
        (``j (sqrt(pi) / lambda) (cos_i + cos_b)`` times coefficients, pattern and spreading).
    edge_field : callable, optional
        ``(lanes, lane, d, b) -> complex``: the channel's edge field per metre at a diffracting lane
        of ``lanes`` (as the pulse moved them, eq. (M8))
        (``sqrt(4 pi) b_rx . F`` of docs/physics.md (E4), or of (E6) for a ``double`` lane, times
        the pattern and the earlier bounces' factors; 0 where the lane does not carry it), after
        mirrors with the untraced reverse path's fringe added (``reverse`` of
        :func:`~sarmitsuba.tracing.integration.edges.edge_field`). None: no edge terms (and no doubly
        diffracted lanes).

    Returns
    -------
    list of (lane, length L [m], value complex, spectral order) for every deposited term.
    """
    out = []
    travel = np.zeros(len(lanes))                # boundaries that move with the antenna, eq. (M8)
    if lanes.motion is not None:
        travel = np.einsum("mi,mi->m", np.asarray(antenna, float)[None] - lanes.origin, lanes.axis.astype(float))
    lanes = lanes.moved(antenna)
    for m in range(len(lanes)):
        def at(point, unfolded):
            first = unfolded - antenna
            s = float(np.linalg.norm(first))
            first = first / s
            d = lanes.fold[m].astype(float) @ first if depth else first
            back = antenna - point
            r = float(np.linalg.norm(back))
            return s, r, d, back / r
        n = lanes.normal[m].astype(float)
        kind = int(lanes.kind[m])
        s, r, d, b = at(lanes.point[m], lanes.unfolded[m])
        facing = 1.0 if n @ d < 0 else -1.0
        cos_i, cos_b = -facing * (n @ d), facing * (n @ b)
        if not cos_i > 1e-6:
            continue
        piece = int(lanes.piece[m])
        split = kind in (SPLIT_START, SPLIT_END)
        if kind in (OPEN_START, OPEN_END, OPEN_MID):
            _, _, dm, bm = at(lanes.middle[m], lanes.middle_unfolded[m])
            decide = 0.5 * k * abs((dm - bm) @ lanes.edge[m].astype(float)) >= alpha_s
            if decide == (kind == OPEN_MID):
                continue
            split = decide
        diffracting = edge_field is not None and lanes.diffracting is not None and bool(lanes.diffracting[m])
        if diffracting:                            # never gated to the area form, eq. (E4)
            out += _edge_terms(lanes, m, edge_field(lanes, m, d, b), s + r, d, b, k, kind, split)
            if lanes.double[m]:
                continue
        if not cos_b > 1e-6:                       # PO: the receiver on the face's side
            continue
        if not lanes.stable[m]:
            _, _, dc, bc = at(pieces.centroid[piece], pieces.centroid_unfolded[piece])
            uc = dc - bc
            near = k * np.linalg.norm(uc - n * (uc @ n)) * float(pieces.diagonal[piece]) < NEAR_SPECULAR
            if near != (kind == AREA):
                continue
        u = d - b
        u_t = u - n * (u @ n)
        ut2 = float(u_t @ u_t)
        base = density(m, d, b, s, r, cos_i, cos_b)
        length = s + r
        if kind == AREA:
            start, count = int(pieces.segment_start[piece]), int(pieces.segment_count[piece])
            mid = pieces.segment_mid[start:start + count].astype(float)
            edge = pieces.segment_edge[start:start + count].astype(float)
            if pieces.segment_mid_rate is not None:
                mid = mid + travel[m] * pieces.segment_mid_rate[start:start + count]
                edge = edge + travel[m] * pieces.segment_edge_rate[start:start + count]
            f, kdf = polygon_linear_integral(mid, edge, n, u, k)
            quad = _quadratic(pieces, piece, d, b, s, r)
            f, kdf = f - 1j * k * quad, kdf - 1j * k * quad
            out += [(m, length, base * (f + kdf), 1), (m, length, base * -kdf, 0)]
            continue
        a = lanes.edge[m].astype(float)
        a_len = float(np.linalg.norm(a))
        a_hat = a / a_len
        cross = n @ np.cross(u_t, a_hat)
        if split:
            sign = 1.0 if kind in (SPLIT_START, OPEN_START) else -1.0
            out.append((m, length, base * sign * cross / (k * k * ut2 * (u @ a_hat)), -1))
            continue
        alpha = 0.5 * k * (u @ a)
        sinc_base = 1j * cross * a_len / (k * ut2)
        change = math.cos(alpha) - float(_sinc(alpha))
        out += [(m, length, base * sinc_base * (float(_sinc(alpha)) - change), 0),
                (m, length, base * sinc_base * change, 1)]
    return out


def _edge_terms(lanes, m: int, field: complex, length: float, d, b, k: float, kind: int, split: bool) -> list:
    """A diffracting lane's terms: its field per metre times the line integral of
    ``exp(-j k L)`` along its segment, split at its ends or as a sinc at its midpoint (E4); a
    doubly diffracted lane's path runs across the face as well, ``+ w sin(beta')`` (E6)."""
    a = lanes.edge[m].astype(float)
    a_len = float(np.linalg.norm(a))
    a_hat = a / a_len
    if lanes.double[m]:
        length += float(np.linalg.norm(lanes.across[m])) * float(np.linalg.norm(d - (d @ a_hat) * a_hat))
    ua = (d - b) @ a_hat
    if split:
        sign = 1.0 if kind in (SPLIT_START, OPEN_START) else -1.0
        return [(m, length, field * -sign * 1j / (k * ua), -1)]
    alpha = 0.5 * k * ua * a_len
    change = math.cos(alpha) - float(_sinc(alpha))
    return [(m, length, field * a_len * (float(_sinc(alpha)) - change), 0), (m, length, field * a_len * change, 1)]


def _quadratic(pieces, piece: int, d, b, s: float, r: float) -> float:
    """``tr(Q M2)`` of a piece: the quadratic phase ``Q = ((I - d d^T) / s + (I - b b^T) / R) / 2``
    against its second moments."""
    q = 0.5 * ((np.eye(3) - np.outer(d, d)) / s + (np.eye(3) - np.outer(b, b)) / r)
    eu, ev = pieces.axis_u[piece].astype(float), pieces.axis_v[piece].astype(float)
    ixx, ixy, iyy = pieces.moments[piece].astype(float)
    return float(eu @ q @ eu * ixx + 2 * eu @ q @ ev * ixy + ev @ q @ ev * iyy)
