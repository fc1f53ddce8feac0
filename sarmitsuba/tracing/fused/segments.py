"""The per-segment step on the Dr.Jit device: which pieces are never near the specular
direction within their sub-aperture, and each boundary segment's kind (docs/physics.md (PO2),
(T3), (M5); docs/design.md section 10.1, step 8).

The readable references are ``MeshTracer._never_specular`` and ``MeshTracer._split_kinds`` in
:mod:`sarmitsuba.tracing.driver.mesh_trace`. Here one lane per piece (per segment) unfolds its
point into the chain's last frame, forms the arriving and returning directions at the
sub-aperture's three views (first, reference and last pulse) and decides, with every float64
operation the reference's in its order, so that the decisions are the reference's bit for bit
(tests/test_fused_segments.py). NumPy's orders, measured on the NumPy this project pins:
``np.einsum("mi,mi->m")`` and ``np.einsum("mij,mj->mi")`` add their three products as
``(t_0 + t_2) + t_1``, ``np.einsum("mji,mj->mi")`` as ``(t_0 + t_1) + t_2``; ``row_norm`` as
``(x x + y y) + z z``; ``Surfaces.to_world`` as ``(o + x u) + y v``. Dr.Jit's LLVM backend does not
contract products and sums into FMAs.

The parts' frames and normals go to the device once per :class:`SegmentKinds` (one per
tracer); a call sends its chains' unfolding maps, the views of its sub-apertures and its rows.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..device import device_array, releasing, table_array

__all__ = ["SegmentKinds", "DEVICE_ROWS"]

#: Rows below which a call runs the reference's NumPy instead (launch and copies cost more).
DEVICE_ROWS = 1024


def _gather3(table, index):
    """The 3-vector rows ``index`` of a flat [n * 3] table, as three Float64."""
    return [dr.gather(mi.Float64, table, index * 3 + i) for i in range(3)]


def _dot(a, b):
    """``np.einsum("mi,mi->m")`` of two 3-vectors: ``(a0 b0 + a2 b2) + a1 b1``."""
    return (a[0] * b[0] + a[2] * b[2]) + a[1] * b[1]


def _norm(a):
    """``row_norm``: ``sqrt((a0 a0 + a1 a1) + a2 a2)``."""
    return dr.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


def _unit(a):
    """``a / row_norm(a)``, component by component."""
    n = _norm(a)
    return [c / n for c in a]


class SegmentKinds:
    """The stable flags and split kinds of one tracer's rows on the device.

    Parameters
    ----------
    surfaces : sarmitsuba.tracing.mesh.patches.Surfaces
    k : float
        Wavenumber [rad/m].
    alpha_s : float
        The split threshold (:func:`sarmitsuba.tracing.integration.physical_optics.split_threshold`).
    margin : float
        ``STABLE_MARGIN * NEAR_SPECULAR`` of ``MeshTracer._never_specular``.
    sinc_regime : float
        :data:`sarmitsuba.tracing.integration.physical_optics.SINC_REGIME`.
    kinds : (int, int, int)
        ``(SPLIT_START, SINC, OPEN_START)`` of :mod:`sarmitsuba.tracing.integration.patch_terms`.
    """

    def __init__(self, surfaces, k: float, alpha_s: float, margin: float, sinc_regime: float, kinds):
        self.surfaces = surfaces
        self.k, self.alpha_s, self.margin, self.sinc_regime = float(k), float(alpha_s), float(margin), float(sinc_regime)
        self.kinds = tuple(int(v) for v in kinds)
        self._tables = None

    def _part_tables(self):
        """Flat device tables of every part's normal and frame (origin, u, v)."""
        if self._tables is None:
            s = self.surfaces
            origin = s.plane_point(np.arange(s.n_parts))
            self._tables = tuple(table_array(mi.Float64, np.ascontiguousarray(a, np.float64).reshape(-1))
                                 for a in (s.normal, origin, s.axis_u, s.axis_v))
        return self._tables

    @staticmethod
    def _chain_tables(chains, views, rx_views):
        """Per-call device tables: the chains' last maps, shifts, parts and sub-apertures, and the
        sub-apertures' three views of transmitter and receiver."""
        return (table_array(mi.Float64, np.ascontiguousarray(chains.lin_last, np.float64).reshape(-1)),
                table_array(mi.Float64, np.ascontiguousarray(chains.shift_last, np.float64).reshape(-1)),
                table_array(mi.UInt32, chains.sub),
                table_array(mi.Float64, np.ascontiguousarray(views, np.float64).reshape(-1)),
                table_array(mi.Float64, np.ascontiguousarray(rx_views, np.float64).reshape(-1)))

    @staticmethod
    def _arriving(lin_table, shift_table, chain, point, view_table, sub):
        """``arriving_views``: the direction from each view to the unfolded point, folded back
        (three lists of three Float64)."""
        lin = [dr.gather(mi.Float64, lin_table, chain * 9 + i) for i in range(9)]
        shift = _gather3(shift_table, chain)
        y = [(lin[3 * i] * point[0] + lin[3 * i + 2] * point[2]) + lin[3 * i + 1] * point[1] + shift[i]
             for i in range(3)]
        out = []
        for v in range(3):
            at = _gather3(view_table, sub * 3 + v)
            first = _unit([y[i] - at[i] for i in range(3)])
            out.append([(lin[i] * first[0] + lin[3 + i] * first[1]) + lin[6 + i] * first[2] for i in range(3)])
        return out

    @releasing
    def never_specular(self, chains, chain, points, diagonal, views, rx_views):
        """``MeshTracer._never_specular``: bool [m] for pieces of chains ``chain`` int [m] at
        ``points`` float64 [m, 3] (world, m) with box diagonals ``diagonal`` [m] (m); ``views``,
        ``rx_views`` float64 [n_sub, 3, 3]: each sub-aperture's first, reference and last
        position of transmitter and receiver (not gathered per row)."""
        m = len(chain)
        normal_t, _, _, _ = self._part_tables()
        lin_t, shift_t, sub_t, view_t, rx_t = self._chain_tables(chains, views, rx_views)
        c = device_array(mi.UInt32, chain)
        p = [device_array(mi.Float64, np.ascontiguousarray(points[:, i])) for i in range(3)]
        sub = dr.gather(mi.UInt32, sub_t, c)
        normal = _gather3(normal_t, device_array(mi.UInt32, chains.last[chain]))
        arriving = self._arriving(lin_t, shift_t, c, p, view_t, sub)
        u_t = []
        for v in range(3):
            b = _unit([r - q for r, q in zip(_gather3(rx_t, sub * 3 + v), p)])
            u = [arriving[v][i] - b[i] for i in range(3)]
            dot = _dot(u, normal)
            u_t.append([u[i] - normal[i] * dot for i in range(3)])
        smallest = dr.minimum(_distance(u_t[0], u_t[1]), _distance(u_t[1], u_t[2]))
        stable = self.k * smallest * device_array(mi.Float64, diagonal) >= self.margin
        dr.eval(stable)
        return stable.numpy().astype(bool).reshape(m)

    @releasing
    def split_kinds(self, chains, chain, part, p2, q2, views, rx_views):
        """``MeshTracer._split_kinds``: the kind int64 [m] of segments ``p2 -> q2`` float64
        [m, 2] (face coordinates of ``part`` int [m], m) of chains ``chain`` int [m]; ``views``,
        ``rx_views`` as in :meth:`never_specular`."""
        m = len(chain)
        _, origin_t, u_t, v_t = self._part_tables()
        lin_t, shift_t, sub_t, view_t, rx_t = self._chain_tables(chains, views, rx_views)
        c = device_array(mi.UInt32, chain)
        sub = dr.gather(mi.UInt32, sub_t, c)
        pp = device_array(mi.UInt32, part)
        o, u, v = _gather3(origin_t, pp), _gather3(u_t, pp), _gather3(v_t, pp)
        p = [device_array(mi.Float64, np.ascontiguousarray(p2[:, i])) for i in range(2)]
        q = [device_array(mi.Float64, np.ascontiguousarray(q2[:, i])) for i in range(2)]
        middle = [0.5 * (p[i] + q[i]) for i in range(2)]

        def world(xy):
            return [(o[i] + xy[0] * u[i]) + xy[1] * v[i] for i in range(3)]
        mid, end, start = world(middle), world(q), world(p)
        edge = [end[i] - start[i] for i in range(3)]
        arriving = self._arriving(lin_t, shift_t, c, mid, view_t, sub)
        half_k = dr.opaque(mi.Float64, 0.5 * self.k)
        alphas = []
        for w in range(3):
            b = _unit([r - q for r, q in zip(_gather3(rx_t, sub * 3 + w), mid)])
            alphas.append(half_k * _dot([arriving[w][i] - b[i] for i in range(3)], edge))
        size = [dr.abs(a) for a in alphas]
        sign = [dr.select(a > 0, 1.0, dr.select(a < 0, -1.0, 0.0)) for a in alphas]
        nan = dr.isnan(alphas[0]) | dr.isnan(alphas[1]) | dr.isnan(alphas[2])
        same = (sign[1] == sign[0]) & (sign[2] == sign[0]) & ~nan
        smallest, largest = dr.minimum(dr.minimum(size[0], size[1]), size[2]), \
            dr.maximum(dr.maximum(size[0], size[1]), size[2])
        split = same & (smallest >= self.sinc_regime) & (largest >= self.alpha_s)
        sinc = largest < self.alpha_s
        split_start, sinc_kind, open_start = self.kinds
        kind = dr.select(split, split_start, dr.select(sinc, sinc_kind, open_start))
        kind = mi.Int32(kind)
        dr.eval(kind)
        return kind.numpy().astype(np.int64).reshape(m)


def _distance(a, b):
    """``_distance_to_segment``: the distance from 0 to the segment ``a -> b`` (3-vectors)."""
    ab = [b[i] - a[i] for i in range(3)]
    along = _dot(ab, ab)
    t = -_dot(a, ab) / dr.select(along > 1e-300, along, 1e-300)
    t = dr.select(t < 0.0, 0.0, dr.select(t > 1.0, 1.0, t))
    return _norm([a[i] + t * ab[i] for i in range(3)])
