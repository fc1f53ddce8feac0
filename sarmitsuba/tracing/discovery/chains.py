"""Chains of mirrors: the exact geometry of a multi-bounce path through a sequence of planar parts
(docs/physics.md (M3)), in float64 NumPy.

A chain ``(X_0, ..., X_d)`` reflects the antenna's wave specularly in the parts ``X_0 .. X_{d-1}``
and returns physical optics from ``X_d`` (``d = 0``: the first bounce). *Unfolding* mirrors the
scene after each reflection into the plane it reflects in, so that the path from the antenna
``A`` is one straight line (image theory): ``U_0`` is the identity and ``U_{i+1} = U_i o R_i``, with
``R_i`` the reflection in the plane of ``X_i``. A point ``x`` of ``X_d`` lies at ``y = U_d(x)`` on the
unfolded path, the image source is ``U_d^{-1}(A)``, and ``x`` is reached through the chain exactly
when the segment from ``A`` to ``y`` crosses every unfolded window ``U_i(X_i)``, in order
(:func:`region_lines`: half-planes of ``X_d``'s face coordinates, linear in ``y``). The reflection
points are where the segment crosses the windows, mapped back (:func:`path_points`).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..mesh.patches import Surfaces
from ..mesh.polygons import EVERYTHING

__all__ = ["Chains", "unfold", "region_lines", "unfolded_lines", "unfolded_frame", "to_face_lines", "path_points",
           "image_source", "facing_sign"]


@dataclass(frozen=True)
class Chains:
    """A batch of chains, each seen from its own sub-aperture (float64).

    Attributes
    ----------
    sub : int64 [n]
        Sub-aperture (in the batch) the chain is evaluated for.
    parts : int64 [n, D]
        ``X_0 .. X_d``, -1 beyond; ``D`` the traced depth.
    order : int64 [n]
        ``d``: the mirrors before the last part (0 for the first bounce).
    lin, shift : float64 [n, D, 3, 3], [n, D, 3]
        The unfolding maps ``U_i(x) = lin_i x + shift_i``, ``i = 0 .. D - 1`` (identity beyond ``d``).
    """

    sub: np.ndarray
    parts: np.ndarray
    order: np.ndarray
    lin: np.ndarray
    shift: np.ndarray

    def __len__(self) -> int:
        return len(self.order)

    @cached_property
    def last(self) -> np.ndarray:
        """int64 [n]: ``X_d`` of each chain (computed once: the arrays are not changed in place)."""
        return _frozen(self.parts[np.arange(len(self.order)), self.order])

    @cached_property
    def lin_last(self) -> np.ndarray:
        """float64 [n, 3, 3]: ``lin_d`` of each chain (``U_d``'s linear part)."""
        return _frozen(self.lin[np.arange(len(self.order)), self.order])

    @cached_property
    def shift_last(self) -> np.ndarray:
        """float64 [n, 3]: ``shift_d`` of each chain."""
        return _frozen(self.shift[np.arange(len(self.order)), self.order])

    def select(self, keep) -> "Chains":
        """The chains where ``keep`` (a boolean mask or an index array) selects them."""
        return Chains(self.sub[keep], self.parts[keep], self.order[keep], self.lin[keep], self.shift[keep])

    def unfolded(self, points: np.ndarray, chain: np.ndarray) -> np.ndarray:
        """``U_d(x)`` float64 [m, 3] of points ``x`` [m, 3] on the last parts of chains ``chain`` [m]."""
        lin = np.take(self.lin_last, chain, axis=0)         # (np.take: row gathers, not fancy indexing)
        # np.einsum("mij,mj->mi", lin, points) summed as einsum sums three terms (bitwise equal)
        y = (lin[:, :, 0] * points[:, 0, None] + lin[:, :, 2] * points[:, 2, None]) + lin[:, :, 1] * points[:, 1, None]
        return y + np.take(self.shift_last, chain, axis=0)


def _frozen(a: np.ndarray) -> np.ndarray:
    """``a`` made read-only (a cached property's value is shared by every caller)."""
    a.flags.writeable = False
    return a


def unfold(surfaces: Surfaces, parts: np.ndarray, order: np.ndarray, sub: np.ndarray) -> Chains:
    """The :class:`Chains` of part sequences ``parts`` [n, D] (``-1`` padded beyond ``order``),
    with their unfolding maps, eq. (M3)."""
    n, depth = parts.shape
    lin = np.tile(np.eye(3), (n, depth, 1, 1))
    shift = np.zeros((n, depth, 3))
    for i in range(depth - 1):
        active = order > i
        p = np.where(active, parts[:, i], 0)
        normal, offset = surfaces.normal[p], surfaces.offset[p]
        reflect = np.eye(3)[None] - 2.0 * normal[:, :, None] * normal[:, None, :]
        new_lin = lin[:, i] @ reflect
        new_shift = np.einsum("nij,nj->ni", lin[:, i], 2.0 * offset[:, None] * normal) + shift[:, i]
        lin[:, i + 1] = np.where(active[:, None, None], new_lin, lin[:, i])
        shift[:, i + 1] = np.where(active[:, None], new_shift, shift[:, i])
    return Chains(sub=np.asarray(sub, np.int64), parts=np.asarray(parts, np.int64), order=np.asarray(order, np.int64),
                  lin=lin, shift=shift)


def image_source(chains: Chains, antenna: np.ndarray) -> np.ndarray:
    """``U_d^{-1}(A)`` float64 [n, 3]: the antenna ``antenna`` [n, 3] seen through each chain's
    mirrors (the image source of its last leg)."""
    k = chains.order
    rows = np.arange(len(k))
    return np.einsum("nji,nj->ni", chains.lin[rows, k], antenna - chains.shift[rows, k])


def facing_sign(surfaces: Surfaces, part: np.ndarray, source: np.ndarray) -> np.ndarray:
    """+1 where ``source`` [n, 3] lies on the side of ``part``'s normal, -1 behind, 0 on its plane."""
    return np.sign(np.einsum("ni,ni->n", surfaces.normal[part], source) - surfaces.offset[part])


def _windows(surfaces: Surfaces, chains: Chains, i: int, rows: np.ndarray):
    """Window ``i`` of chains ``rows`` unfolded: unit normal, offset, corners [m, V, 3], corner count."""
    part = chains.parts[rows, i]
    lin, shift = chains.lin[rows, i], chains.shift[rows, i]
    normal = np.einsum("mij,mj->mi", lin, surfaces.normal[part])
    offset = surfaces.offset[part] + np.einsum("mi,mi->m", normal, shift)
    corners = np.take(surfaces.world_polygon, part, axis=0)
    corners = np.einsum("mij,mvj->mvi", lin, corners) + shift[:, None, :]
    return normal, offset, corners, surfaces.n_corners[part]


def region_lines(surfaces: Surfaces, chains: Chains, antenna: np.ndarray,
                 receiver: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The half-planes, in the face coordinates of each chain's last part, of the points the
    antenna reaches through the chain, eq. (M3), and whether the chain returns at all.

    Parameters
    ----------
    surfaces : Surfaces
    chains : Chains
    antenna : float64 [n, 3]
        The antenna position each chain is seen from (its sub-aperture's reference position).
    receiver : float64 [n, 3], optional
        Bistatic: the receiver's reference position, which the return leg ends at (docs/physics.md
        (B2)); default the antenna.

    Returns
    -------
    lines : float64 [n, H, 3]
        Rows ``(a, b, c)``: the point ``(x, y)`` is reached where every ``a x + b y + c >= 0``
        (``(a, b)`` unit, or zero for a condition that holds everywhere or nowhere). For each
        window: the segment from ``A`` crosses its plane (``A`` and ``y`` on opposite sides), and
        inside it (one plane through ``A`` and each window edge); consecutive windows crossed in
        order, the last one before ``y``.
    valid : bool [n]
        The chain exists: no plane of the chain holds the antenna or its image in the earlier
        mirrors.
    returns : bool [n]
        It can also return physical optics: the antenna (the receiver) sees the last part from the
        side the wave arrives on (its image source's). A chain that does not return may still light its region
        for the next bounce order. A wave arriving on the inner side of a closed body's part
        (:attr:`~sarmitsuba.tracing.mesh.patches.Surfaces.seen_side`) is no chain: it would have
        crossed the body. (Where the winding is unknown, the visibility rays decide.)
    """
    n, depth = chains.parts.shape
    last = chains.last
    source = image_source(chains, antenna)
    arriving = facing_sign(surfaces, last, source)
    valid = (arriving != 0) & (surfaces.seen_side[last] * arriving >= 0)
    returns = valid & (arriving == facing_sign(surfaces, last, antenna if receiver is None else receiver))
    width = max(depth - 1, 0) * (2 + surfaces.polygon.shape[1]) + max(depth - 2, 0)
    lines = np.tile(np.asarray(EVERYTHING), (n, max(width, 1), 1))
    k = chains.order
    frame_o, frame_u, frame_v = unfolded_frame(surfaces, chains)
    slot = 0
    previous = None
    for i in range(depth - 1):
        rows = np.flatnonzero(k > i)
        normal, offset, corners, n_corners = _windows(surfaces, chains, i, rows)
        a = offset - np.einsum("mi,mi->m", normal, antenna[rows])              # n . (p - A)
        valid[rows] &= a != 0
        window_side = facing_sign(surfaces, chains.parts[rows, i], _source_of(chains, rows, i, antenna[rows]))
        valid[rows] &= (window_side != 0) & (surfaces.seen_side[chains.parts[rows, i]] * window_side >= 0)
        # A and y on opposite sides of the window's plane: sign(a) n . (y - A) > 0
        g = np.sign(a)[:, None] * normal
        lines[rows, slot] = to_face_lines(g, -np.einsum("mi,mi->m", g, antenna[rows]), frame_o[rows], frame_u[rows], frame_v[rows])
        slot += 1
        # the last window crossed before y itself (t < 1): sign(a) n . (y - A) > |a|
        last_window = k[rows] == i + 1
        before = to_face_lines(g, -np.einsum("mi,mi->m", g, antenna[rows]) - np.abs(a), frame_o[rows], frame_u[rows],
                               frame_v[rows])
        lines[rows, slot] = np.where(last_window[:, None], before, EVERYTHING)
        slot += 1
        slots = np.arange(corners.shape[1])[None, :] < n_corners[:, None]
        centre = (corners * slots[..., None]).sum(axis=1) / n_corners[:, None]
        # every corner's edge plane through A at once (tests/test_tracing_fast.py keeps the edge-at-a-time loop)
        m, v = corners.shape[:2]
        nxt = np.where(np.arange(v)[None, :] + 1 < n_corners[:, None], np.arange(v)[None, :] + 1, 0)
        a_rows = antenna[rows]
        p = corners - a_rows[:, None, :]
        q = np.take_along_axis(corners, nxt[..., None], axis=1) - a_rows[:, None, :]
        g = np.cross(p, q)
        g *= np.sign(_dot3(g, (centre - a_rows)[:, None, :]))[..., None]
        g = g.reshape(m * v, 3)
        line = to_face_lines(g, -_dot3(g, np.repeat(a_rows, v, axis=0)), np.repeat(frame_o[rows], v, axis=0),
                             np.repeat(frame_u[rows], v, axis=0), np.repeat(frame_v[rows], v, axis=0))
        lines[rows, slot:slot + v] = np.where(slots[..., None], line.reshape(m, v, 3), EVERYTHING)
        slot += v
        if previous is not None:           # t_{i-1} < t_i: (n_{i-1} / a_{i-1} - n_i / a_i) . (y - A) > 0
            prev_rows, prev_normal, prev_a = previous
            g = prev_normal[np.searchsorted(prev_rows, rows)] / prev_a[np.searchsorted(prev_rows, rows), None] \
                - normal / np.where(a != 0, a, 1.0)[:, None]
            lines[rows, slot] = to_face_lines(g, -np.einsum("mi,mi->m", g, antenna[rows]), frame_o[rows], frame_u[rows],
                                         frame_v[rows])
            slot += 1
        previous = (rows, normal, np.where(a != 0, a, 1.0))
    return lines, valid, returns & valid


def unfolded_frame(surfaces: Surfaces, chains: Chains):
    """The last part's face frame carried by ``U_d``: origin (on the plane), ``u``, ``v`` [n, 3]."""
    rows, k, last = np.arange(len(chains)), chains.order, chains.last
    lin = chains.lin[rows, k]
    origin = np.einsum("nij,nj->ni", lin, surfaces.plane_point(last)) + chains.shift[rows, k]
    return origin, np.einsum("nij,nj->ni", lin, surfaces.axis_u[last]), np.einsum("nij,nj->ni", lin, surfaces.axis_v[last])


def unfolded_lines(surfaces: Surfaces, chains: Chains, g: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Half-spaces ``g . y + h >= 0`` of the unfolded point ``y = U_d(x)`` (``g`` [n, k, 3], ``h``
    [n, k]) as half-planes of ``x``'s face coordinates on each chain's last part: [n, k, 3]."""
    origin, u, v = unfolded_frame(surfaces, chains)
    return np.stack([to_face_lines(g[:, j], h[:, j], origin, u, v) for j in range(g.shape[1])], axis=1)


def _source_of(chains: Chains, rows: np.ndarray, i: int, antenna: np.ndarray) -> np.ndarray:
    """The image source seen by window ``i`` of chains ``rows``: ``U_i^{-1}(A)``."""
    return np.einsum("mji,mj->mi", chains.lin[rows, i], antenna - chains.shift[rows, i])


def _dot3(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``x . y`` over the last axis (3) of broadcast float64 arrays, summed as ``np.einsum("mi,mi->m")``
    sums three terms: ``(x0 y0 + x2 y2) + x1 y1``."""
    return (x[..., 0] * y[..., 0] + x[..., 2] * y[..., 2]) + x[..., 1] * y[..., 1]


def to_face_lines(g: np.ndarray, h: np.ndarray, origin: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The 3-D half-space ``g . y + h >= 0`` on the plane ``origin + x u + y v`` as a normalised
    face half-plane ``(a, b, c)`` float64 [m, 3]; a plane parallel to the face becomes ``(0, 0,
    +-1)``."""
    a, b = np.einsum("mi,mi->m", g, u), np.einsum("mi,mi->m", g, v)
    c = np.einsum("mi,mi->m", g, origin) + h
    norm = np.hypot(a, b)
    # np.linalg.norm(g, axis=1), summed in its order
    scale = np.sqrt(g[:, 0] * g[:, 0] + g[:, 1] * g[:, 1] + g[:, 2] * g[:, 2]) * 1e-12
    flat = norm <= scale
    safe = np.where(flat, 1.0, norm)
    return np.stack([np.where(flat, 0.0, a / safe), np.where(flat, 0.0, b / safe),
                     np.where(flat, np.where(c >= 0, 1.0, -1.0), c / safe)], axis=1)


def path_points(surfaces: Surfaces, chains: Chains, chain: np.ndarray, points: np.ndarray,
                antenna: np.ndarray) -> np.ndarray:
    """The reflection points of the paths from ``antenna`` [m, 3] through chains ``chain`` [m] to
    ``points`` [m, 3] (on their last parts): float64 [m, D, 3], row ``i < d`` the point on ``X_i``
    (in the scene), row ``d`` the point itself, rows beyond repeat it, eq. (M3)."""
    depth = chains.parts.shape[1]
    y = chains.unfolded(points, chain)
    out = np.repeat(points[:, None, :], depth, axis=1)
    order = chains.order[chain]
    for i in range(depth - 1):
        rows = np.flatnonzero(order > i)
        if len(rows) == 0:
            continue
        c = chain[rows]
        lin, shift, part = chains.lin[c, i], chains.shift[c, i], chains.parts[c, i]
        normal = np.einsum("mij,mj->mi", lin, surfaces.normal[part])
        offset = surfaces.offset[part] + np.einsum("mi,mi->m", normal, shift)
        ray = y[rows] - antenna[rows]
        t = (offset - np.einsum("mi,mi->m", normal, antenna[rows])) / np.einsum("mi,mi->m", normal, ray)
        crossing = antenna[rows] + t[:, None] * ray
        out[rows, i] = np.einsum("mji,mj->mi", lin, crossing - shift)        # U_i^{-1}
    return out
