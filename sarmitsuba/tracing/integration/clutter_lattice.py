"""The rough surface's own scatterers: the lattice geometry of docs/physics.md (C), in Dr.Jit.

A rough surface carries a square lattice of cells ``c`` wide in the plane of each facet, one
scatterer per cell at a hashed position inside it with a hashed phase. A tube reports the
scatterers inside its footprint. The steps, in the order :meth:`sarmitsuba.tracing.integration.returns.Returns.clutter`
takes them:

1. :func:`shortened_footprint` -- near grazing, the footprint shortened and sigma0 raised;
2. :func:`lattice_frame` and :func:`footprint_cells` -- the lattice's in-plane frame, and the
   hit and the footprint in cells: which cells to visit;
3. :func:`surface_key` -- the hash key of the surface (shape, side, plane, seed);
4. :func:`length_expansion` -- per pulse, the two-way length offset of a scatterer to second order;
5. :func:`scatterer` -- per cell, the scatterer's offset, whether the footprint holds it, its
   length offset and phase.

Dr.Jit arrays are float32 unless stated; lengths in m, offsets in cells.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi

__all__ = ["hash32", "CLUTTER_COS_MIN", "shortened_footprint", "lattice_frame", "FootprintCells",
           "footprint_cells", "surface_key", "length_expansion", "scatterer"]

#: Below this cosine of the incidence angle (84.3 deg) a tube's clutter footprint is shortened to
#: 1 / CLUTTER_COS_MIN tube widths along the plane of incidence and its sigma0 raised by the same
#: factor (docs/physics.md (C)): the same clutter power, on scatterers near the hit, at a bounded
#: cost (a tube grazing a wall would otherwise loop over scatterers kilometres away).
CLUTTER_COS_MIN = 0.1
#: Floor of a squared norm or a ratio before it divides: a tube along the facet normal has no
#: elongation direction (0 / 0), and exact grazing no shortening ratio. Far below any float32
#: quantity that matters here, above float32's smallest normal (1.2e-38).
DIVISION_FLOOR = 1e-30
#: A facet whose normal is within 0.81 deg of its shape's first axis (``|n . a1|`` above this)
#: takes its lattice's ``u`` axis from the shape's second axis, as docs/physics.md (C) defines it
#: (the first axis' projection on the plane would be ill-conditioned).
ALONG_FIRST_AXIS = 0.9999
#: The facet normal is quantised to 1/1024 per component in the plane's hash: float32 round-off
#: of one plane's normal (~1e-7) keeps its key, planes ~1e-3 rad apart get their own lattices.
NORMAL_QUANTUM = 1024.0
#: The cell hash's low and high 16 bits jitter the scatterer along ``u`` and ``v`` in steps of
#: 1/65536 cell: uniform inside the cell, eq. (C).
JITTER_STEP = 1.0 / 65536.0
#: A 32-bit hash to a phase uniform in [0, 2 pi), eq. (C).
PHASE_STEP = 2.0 * math.pi / 4294967296.0
#: Salt that makes the phase hash independent of the position hash of the same cell.
PHASE_SALT = 0x68E31DA4
#: Salt of the cross-polarised phase (polarimetric runs, eq. (P7)): independent of both.
CROSS_PHASE_SALT = 0x2C1B3C6D


def hash32(x):
    """A 32-bit integer hash with full avalanche (two xorshift-multiply rounds, Wellons' "lowbias32")."""
    x = x ^ (x >> 16)
    x = x * 0x7FEB352D
    x = x ^ (x >> 15)
    x = x * 0x846CA68B
    return x ^ (x >> 16)


def shortened_footprint(e1, e2, n, n_geo, d_ref):
    """Near grazing (``cos_i < CLUTTER_COS_MIN``) the footprint edges ``e1, e2`` (Vector3f, m),
    ``1 / cos_i`` long along the plane of incidence, shortened to ``1 / CLUTTER_COS_MIN``, and
    the factor sigma0 is raised by to keep the tube's clutter power, eq. (C). ``n`` is the hit's
    normal, ``n_geo`` the surface's own, ``d_ref`` the incoming direction at the reference
    position. Returns ``(e1, e2, raise_by)``."""
    shorten = dr.maximum(-dr.dot(n, d_ref), 0.0) / CLUTTER_COS_MIN
    grazing = shorten < 1.0
    along = d_ref - n_geo * dr.dot(n_geo, d_ref)                    # the elongation direction
    along = along * dr.rsqrt(dr.maximum(dr.squared_norm(along), DIVISION_FLOOR))
    e1 = dr.select(grazing, e1 - along * ((1.0 - shorten) * dr.dot(e1, along)), e1)
    e2 = dr.select(grazing, e2 - along * ((1.0 - shorten) * dr.dot(e2, along)), e2)
    raise_by = dr.select(grazing, 1.0 / dr.maximum(shorten, DIVISION_FLOOR), 1.0)
    return e1, e2, raise_by


def lattice_frame(n_geo, axes):
    """The lattice's unit axes ``(u, v)`` in the plane of normal ``n_geo`` (Vector3f), eq. (C):
    ``u`` is the shape's first axis ``a1`` projected on the plane and normalised, or its second
    axis' projection where ``n`` lies along ``a1``; ``v = n x u``. ``axes`` are the shape's own
    axes ``(a1, a2, a3)`` (Vector3f each, :func:`sarmitsuba.scene.loader.shape_frame`), so the lattice
    turns with the shape."""
    along = dr.abs(dr.dot(n_geo, axes[0])) > ALONG_FIRST_AXIS
    u_axis = dr.select(along, axes[1], axes[0])
    u_axis = dr.normalize(u_axis - n_geo * dr.dot(n_geo, u_axis))
    return u_axis, dr.cross(n_geo, u_axis)


@dataclass
class FootprintCells:
    """A footprint on the lattice (:func:`footprint_cells`), per lane.

    ``pu, pv`` the hit in cells; ``iu0, iv0`` (Int32) the first cell of the bounding box,
    ``nu`` (UInt32) its cells per row, ``cells`` (UInt32) its cell count (0 for a degenerate
    footprint); ``m11 .. m22`` the map from a cell offset to footprint coordinates ``(s1, s2)``,
    the footprint being ``[-1/2, 1/2)^2``."""
    pu: object
    pv: object
    iu0: object
    iv0: object
    nu: object
    cells: object
    m11: object
    m12: object
    m21: object
    m22: object


def footprint_cells(local, e1, e2, u_axis, v_axis, c: float) -> FootprintCells:
    """The hit (``local``: in the shape's frame, m) and the footprint of edges ``e1, e2`` in cells
    ``c`` wide on the lattice ``(u_axis, v_axis)``: the cells of its bounding box to visit."""
    pu, pv = dr.dot(local, u_axis) / c, dr.dot(local, v_axis) / c
    au, av = dr.dot(e1, u_axis) / c, dr.dot(e1, v_axis) / c
    bu, bv = dr.dot(e2, u_axis) / c, dr.dot(e2, v_axis) / c
    inv_det = 1.0 / (au * bv - av * bu)
    hu, hv = 0.5 * (dr.abs(au) + dr.abs(bu)), 0.5 * (dr.abs(av) + dr.abs(bv))
    iu0, iv0 = mi.Int32(dr.floor(pu - hu)), mi.Int32(dr.floor(pv - hv))
    nu = dr.maximum(mi.Int32(dr.floor(pu + hu)) - iu0 + 1, 1)
    nv = mi.Int32(dr.floor(pv + hv)) - iv0 + 1
    cells = mi.UInt32(dr.select(dr.isfinite(inv_det), nu * nv, 0))
    return FootprintCells(pu, pv, iu0, iv0, mi.UInt32(nu), cells,
                          bv * inv_det, -bu * inv_det, -av * inv_det, au * inv_det)


def surface_key(shape_key, back, n_geo, local, axes, c: float, seed: int):
    """The hash key of a surface's lattice (UInt32): the shape, the side (``back``), the facet
    plane (its offset in cells from the shape's origin and its normal quantised in the shape's
    own ``axes``, so that the key moves and turns with the shape) and the integrator's seed,
    eq. (C)."""
    plane = (mi.UInt32(mi.Int32(dr.round(dr.dot(n_geo, local) / c)))
             ^ (mi.UInt32(mi.Int32(dr.round(dr.dot(n_geo, axes[0]) * NORMAL_QUANTUM))) * 0x01000193)
             ^ (mi.UInt32(mi.Int32(dr.round(dr.dot(n_geo, axes[1]) * NORMAL_QUANTUM))) * 0x00010001)
             ^ (mi.UInt32(mi.Int32(dr.round(dr.dot(n_geo, axes[2]) * NORMAL_QUANTUM))) * 0x00000101))
    return hash32(shape_key ^ (mi.UInt32(back) << 31) ^ hash32(plane ^ mi.UInt32(seed)))


def length_expansion(d, b, s, dist, u_axis, v_axis, c: float):
    """The two-way length offset of a scatterer ``(du, dv)`` cells from the hit, to second order:
    ``g_u du + g_v dv + q_uu du^2 + q_uv du dv + q_vv dv^2``, the ``(d - b) . delta + delta^T Q
    delta`` of eq. (C), with the incoming direction ``d`` from the image source at distance ``s``
    and the outgoing ``b`` to the antenna at ``dist`` (float64). Returns ``(g_u, g_v, q_uu,
    q_uv, q_vv)``, m."""
    inv_s, inv_r = c * c / mi.Float(s), c * c / mi.Float(dist)
    du_d, dv_d, du_b, dv_b = dr.dot(d, u_axis), dr.dot(d, v_axis), dr.dot(b, u_axis), dr.dot(b, v_axis)
    g_u, g_v = c * (du_d - du_b), c * (dv_d - dv_b)
    q_uu = 0.5 * ((1.0 - du_d * du_d) * inv_s + (1.0 - du_b * du_b) * inv_r)
    q_vv = 0.5 * ((1.0 - dv_d * dv_d) * inv_s + (1.0 - dv_b * dv_b) * inv_r)
    q_uv = -(du_d * dv_d * inv_s + du_b * dv_b * inv_r)
    return g_u, g_v, q_uu, q_uv, q_vv


def scatterer(i, cells: FootprintCells, key0, expansion, n_cells, k: float, cross: bool = False, inside=None):
    """The scatterer of the footprint's ``i``-th cell (UInt32), eq. (C): whether the footprint
    holds it (and ``i < n_cells``, and ``inside(du, dv)`` of its offset from the hit in cells when
    given: a cell piece's own test, (M7)), its two-way length offset ``dl`` (m,
    :func:`length_expansion`) and its phase ``phi - k dl`` (rad). Returns ``(own, dl, phase,
    phase_x)``: ``phase_x`` is the phase of its cross-polarised return, ``phi_x - k dl`` with
    ``phi_x`` hashed independently of ``phi`` (eq. (P7)), when ``cross``; else None (nothing
    compiled)."""
    g_u, g_v, q_uu, q_uv, q_vv = expansion
    iv = i // cells.nu
    iu_, iv_ = cells.iu0 + mi.Int32(i - iv * cells.nu), cells.iv0 + mi.Int32(iv)
    h0 = hash32(mi.UInt32(iu_) * 0x9E3779B1 ^ mi.UInt32(iv_) * 0x85EBCA77 ^ key0)
    du = mi.Float(iu_) + mi.Float(h0 & 0xFFFF) * JITTER_STEP - cells.pu     # scatterer - hit, in cells
    dv = mi.Float(iv_) + mi.Float(h0 >> 16) * JITTER_STEP - cells.pv
    s1, s2 = cells.m11 * du + cells.m12 * dv, cells.m21 * du + cells.m22 * dv   # footprint coordinates
    own = (i < n_cells) & (s1 >= -0.5) & (s1 < 0.5) & (s2 >= -0.5) & (s2 < 0.5)
    if inside is not None:
        own &= inside(du, dv)
    dl = g_u * du + g_v * dv + q_uu * du * du + q_uv * du * dv + q_vv * dv * dv
    phase = mi.Float(hash32(h0 ^ PHASE_SALT)) * PHASE_STEP - k * dl
    phase_x = mi.Float(hash32(h0 ^ CROSS_PHASE_SALT)) * PHASE_STEP - k * dl if cross else None
    return own, dl, phase, phase_x
