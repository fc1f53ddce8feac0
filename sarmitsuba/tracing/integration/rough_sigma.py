"""A randomly rough surface's sigma nought in the kernel: its material row's tables
(:class:`sarmitsuba.scene.rough_tables.RoughTables`) interpolated at the pulse's incidence and
scattering directions, docs/physics.md (RS6). Used by
:class:`sarmitsuba.tracing.integration.clutter_terms.ClutterTerms` for clutter kind 3.

The NumPy reference of both interpolations is :func:`reference_mono` and
:func:`reference_bistatic`.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ...scene.rough_tables import COS_SIZE, MONO_SIZE, PHI_SIZE

__all__ = ["azimuth_cosine", "mono_sigma0", "bistatic_sigma0_table", "reference_mono", "reference_bistatic"]


def azimuth_cosine(d, b, n):
    """``cos(phi_s)``: the cosine of the azimuth, about the facet normal ``n``, between the incident
    direction of travel ``d`` and the scattered one ``b`` (mi.Vector3f, unit): -1 back toward the
    source, +1 on to the specular side. -1 where either lies along the normal (its azimuth is
    undefined there)."""
    dt = d - dr.dot(d, n) * n
    bt = b - dr.dot(b, n) * n
    norm = dr.norm(dt) * dr.norm(bt)
    return dr.select(norm > 1e-12, dr.clip(dr.dot(dt, bt) / dr.maximum(norm, 1e-30), -1.0, 1.0), -1.0)


def _cell(x, size: int):
    """Index of the table interval holding ``x`` in [0, size - 1] and the weight within it."""
    i0 = mi.UInt32(dr.minimum(dr.floor(x), size - 2))
    return i0, x - mi.Float(i0)


def mono_sigma0(read, row, pol: int, cos_t, active=True):
    """Monostatic sigma nought of channel ``pol`` (0 HH, 1 VV, 2 HV) of material ``row`` at
    incidence cosine ``cos_t``: linear in the table ``rough_mono`` (``read(name, index, active)``
    gathers from it; 0 where not ``active``). mi.Float."""
    i0, w = _cell(dr.clip(cos_t, 0.0, 1.0) * (MONO_SIZE - 1), MONO_SIZE)
    idx = (row * 3 + pol) * MONO_SIZE + i0
    return dr.lerp(read("rough_mono", idx, active), read("rough_mono", idx + 1, active), w)


def bistatic_sigma0_table(read, row, pol: int, cos_i, cos_s, cos_phi, active=True):
    """Bistatic sigma nought of channel ``pol`` (0 HH, 1 VV) of material ``row``: trilinear in the
    table ``rough_bi`` over ``(cos_i, cos_s, cos_phi)``; 0 where not ``active``. mi.Float."""
    i, wi = _cell(dr.clip(cos_i, 0.0, 1.0) * (COS_SIZE - 1), COS_SIZE)
    j, wj = _cell(dr.clip(cos_s, 0.0, 1.0) * (COS_SIZE - 1), COS_SIZE)
    m, wm = _cell((dr.clip(cos_phi, -1.0, 1.0) + 1.0) * (0.5 * (PHI_SIZE - 1)), PHI_SIZE)
    base = ((row * 2 + pol) * COS_SIZE + i) * COS_SIZE * PHI_SIZE
    total = mi.Float(0.0)
    for di, fi in ((0, 1.0 - wi), (1, wi)):
        for dj, fj in ((0, 1.0 - wj), (1, wj)):
            at = base + (di * COS_SIZE + j + dj) * PHI_SIZE + m
            total += fi * fj * dr.lerp(read("rough_bi", at, active), read("rough_bi", at + 1, active), wm)
    return total


def _reference_cell(x: np.ndarray, size: int):
    i0 = np.minimum(np.floor(x), size - 2).astype(int)
    return i0, x - i0


def reference_mono(table: np.ndarray, row: int, pol: int, cos_t) -> np.ndarray:
    """NumPy reference of :func:`mono_sigma0` on ``RoughTables.mono`` (float64)."""
    i0, w = _reference_cell(np.clip(np.asarray(cos_t, np.float64), 0, 1) * (MONO_SIZE - 1), MONO_SIZE)
    t = table[row, pol].astype(np.float64)
    return (1 - w) * t[i0] + w * t[i0 + 1]


def reference_bistatic(table: np.ndarray, row: int, pol: int, cos_i, cos_s, cos_phi) -> np.ndarray:
    """NumPy reference of :func:`bistatic_sigma0_table` on ``RoughTables.bistatic``: SciPy's
    regular-grid linear interpolation (float64)."""
    from scipy.interpolate import RegularGridInterpolator
    c = np.linspace(0.0, 1.0, COS_SIZE)
    grid = RegularGridInterpolator((c, c, np.linspace(-1.0, 1.0, PHI_SIZE)), table[row, pol].astype(np.float64))
    points = np.stack(np.broadcast_arrays(np.clip(cos_i, 0, 1), np.clip(cos_s, 0, 1), np.clip(cos_phi, -1, 1)), -1)
    return grid(points)
