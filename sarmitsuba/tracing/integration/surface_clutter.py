"""Rough surfaces' scatterers in the lit pieces of the patches, and every pulse's return from
them (docs/physics.md (C), (M7)).

A rough part carries one scatterer per cell of a square lattice ``c`` wide in its face's frame
(the patches' frame: a patch holds ``m x m`` whole cells, ``P = m c``), at a position jittered
inside the cell and with a phase, both hashed from the cell, the shape, the side met, the plane
and the seed (:mod:`sarmitsuba.tracing.integration.clutter_lattice`'s hash, in NumPy here). A lit piece holds
the scatterers that lie in it: every one of a whole patch, those inside a border piece's polygon
or a mixed piece's lit region. So each scatterer is counted once per pulse and bounce order
whatever the pieces, and a moved or turned shape keeps its scatterers (they are fixed in its own
frame). Every pulse evaluates each scatterer at its own exact two-way length through its chain
(:class:`ClutterKernel`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from .clutter_lattice import CROSS_PHASE_SALT, JITTER_STEP, NORMAL_QUANTUM, PHASE_SALT, PHASE_STEP
from ..deposit.fast_time import SPECTRAL_ORDERS
from ..device import device_array
from . import jones as pol
from .pulse_view import receive_leg
from ..deposit.replay import run_pulses

__all__ = ["hash32", "surface_keys", "cell_hash", "ScattererLanes", "ClutterKernel", "points_inside_boundary"]

_U32 = np.uint32


def hash32(x: np.ndarray) -> np.ndarray:
    """Wellons' lowbias32 in NumPy uint32 arithmetic: the clutter lattice's hash
    (:func:`sarmitsuba.tracing.integration.clutter_lattice.hash32`)."""
    x = np.asarray(x, np.uint32)
    with np.errstate(over="ignore"):
        x = x ^ (x >> _U32(16))
        x = x * _U32(0x7FEB352D)
        x = x ^ (x >> _U32(15))
        x = x * _U32(0x846CA68B)
        return x ^ (x >> _U32(16))


def _u32(values) -> np.ndarray:
    """Signed integers as their two's-complement uint32."""
    return (np.asarray(values, np.int64) & 0xFFFFFFFF).astype(np.uint32)


def surface_keys(shape_key: np.ndarray, back: np.ndarray, normal: np.ndarray, plane_offset: np.ndarray,
                 axes: np.ndarray, c: float, seed: int) -> np.ndarray:
    """The hash key of each surface's lattice (uint32 [n]), as
    :func:`sarmitsuba.tracing.integration.clutter_lattice.surface_key`: the shape, the side, the plane (its
    offset ``plane_offset = n . (x - origin)`` in cells and its normal quantised in the shape's
    ``axes`` [n, 3, 3]) and the seed."""
    with np.errstate(over="ignore"):
        plane = (_u32(np.round(plane_offset / c))
                 ^ (_u32(np.round(np.einsum("ni,ni->n", normal, axes[:, 0]) * NORMAL_QUANTUM)) * _U32(0x01000193))
                 ^ (_u32(np.round(np.einsum("ni,ni->n", normal, axes[:, 1]) * NORMAL_QUANTUM)) * _U32(0x00010001))
                 ^ (_u32(np.round(np.einsum("ni,ni->n", normal, axes[:, 2]) * NORMAL_QUANTUM)) * _U32(0x00000101)))
        return hash32(np.asarray(shape_key, np.uint32) ^ (np.asarray(back, np.uint32) << _U32(31))
                      ^ hash32(plane ^ _U32(seed)))


def cell_hash(iu: np.ndarray, iv: np.ndarray, key: np.ndarray) -> np.ndarray:
    """The hash of lattice cell ``(iu, iv)`` of a surface keyed ``key`` (uint32)."""
    with np.errstate(over="ignore"):
        return hash32(_u32(iu) * _U32(0x9E3779B1) ^ _u32(iv) * _U32(0x85EBCA77) ^ key)


def scatterer_offsets(h0: np.ndarray) -> np.ndarray:
    """The scatterer's position inside its cell, in cells, from the cell's hash: float64 [n, 2]."""
    return np.stack([(h0 & 0xFFFF).astype(np.float64) * JITTER_STEP, (h0 >> 16).astype(np.float64) * JITTER_STEP],
                    axis=1)


def scatterer_phases(h0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The scatterer's co- and cross-polarised phases [rad] from its cell's hash."""
    return (hash32(h0 ^ _U32(PHASE_SALT)).astype(np.float64) * PHASE_STEP,
            hash32(h0 ^ _U32(CROSS_PHASE_SALT)).astype(np.float64) * PHASE_STEP)


def points_inside_boundary(points: np.ndarray, owner: np.ndarray, seg_owner: np.ndarray, start: np.ndarray,
                           end: np.ndarray, n: int) -> np.ndarray:
    """bool [p]: whether each point [p, 2] lies inside its region ``owner`` [p], given by the closed
    oriented boundary segments ``seg_owner`` [s], ``start``, ``end`` [s, 2] of ``n`` regions (the
    crossing number of a ray toward +x)."""
    order = np.argsort(seg_owner, kind="stable")
    seg_owner, start, end = seg_owner[order], start[order], end[order]
    count = np.bincount(seg_owner, minlength=n)
    first = np.cumsum(count) - count
    width = int(count.max(initial=0))
    inside = np.zeros(len(points), bool)
    for k in range(width):
        has = count[owner] > k
        rows = np.flatnonzero(has)
        seg = first[owner[rows]] + k
        p, q = start[seg], end[seg]
        y = points[rows, 1]
        straddle = (p[:, 1] > y) != (q[:, 1] > y)
        x_cross = p[:, 0] + (y - p[:, 1]) * (q[:, 0] - p[:, 0]) / np.where(straddle, q[:, 1] - p[:, 1], 1.0)
        inside[rows] ^= straddle & (points[rows, 0] < x_cross)
    return inside


@dataclass(frozen=True)
class ScattererLanes:
    """One lane per scatterer in a lit piece (NumPy).

    ``point``, ``unfolded`` float64 [m, 3] (its position and ``U_d`` of it, m); ``normal`` float32
    [m, 3] (the part's); ``fold`` float32 [m, 3, 3] (as :class:`~.patch_terms.TermLanes`); ``sub``,
    ``row`` uint32 [m]; ``phase``, ``phase_cross`` float32 [m] (its hashed phases, rad); and the
    earlier bounces (``first``, ``window_row``, ``window_cos``, ``window_direction``,
    ``window_normal``) as :class:`~.patch_terms.TermLanes`.
    """

    point: np.ndarray
    unfolded: np.ndarray
    normal: np.ndarray
    fold: np.ndarray
    sub: np.ndarray
    row: np.ndarray
    phase: np.ndarray
    phase_cross: np.ndarray
    first: np.ndarray | None = None
    window_row: np.ndarray | None = None
    window_cos: np.ndarray | None = None
    window_direction: np.ndarray | None = None
    window_normal: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.row)


class _Record:
    def __init__(self, row, jones):
        self.row, self.jones = row, jones


class ClutterKernel:
    """Every pulse's return from scatterer lanes, eq. (C): ``a = sqrt(sigma0) c r_1 .. r_{k-1} g W
    exp(j phi)`` at the scatterer's own two-way length, deposited with spectral order 0.

    Parameters
    ----------
    returns : sarmitsuba.tracing.integration.returns.Returns
    cell : float
        The lattice cell ``c`` [m].
    arrival : callable
        ``(lanes, depth) -> (gamma, jones)``: the earlier bounces' factors per lane
        (:meth:`sarmitsuba.tracing.integration.patch_terms.PatchTerms.arrival`).
    """

    def __init__(self, returns, cell: float, arrival):
        self.r, self.c, self.arrival = returns, cell, arrival

    def __call__(self, ctx: dict, lanes: ScattererLanes, depth: int) -> None:
        if len(lanes) == 0:
            return
        self.deposit(ctx, self.upload(lanes, depth), lanes, depth)

    def upload(self, lanes: ScattererLanes, depth: int) -> dict:
        """The scatterer lanes on the device (Dr.Jit arrays by name), with ``gamma`` and the Jones matrix."""
        r = self.r
        a64, v3 = mi.Array3f64, mi.Vector3f
        data = dict(point=device_array(a64, lanes.point.T), unfolded=device_array(a64, lanes.unfolded.T),
                    normal=device_array(v3, lanes.normal.T), sub=device_array(mi.UInt32, lanes.sub),
                    row=device_array(mi.UInt32, lanes.row), phase=device_array(mi.Float, lanes.phase),
                    fold=[device_array(v3, lanes.fold[:, :, c].T) for c in range(3)] if depth > 0 else None)
        if r.polarimetric:
            data["phase_cross"] = device_array(mi.Float, lanes.phase_cross)
        data["gamma"], data["jones"] = self.arrival(lanes, depth)
        return data

    def deposit(self, ctx: dict, data: dict, lanes: ScattererLanes, depth: int) -> None:
        """Every pulse's return from scatterer lanes already on the device (:meth:`upload`)."""
        r = self.r
        count = dr.gather(mi.UInt32, ctx["count"], data["sub"])
        paths = r.sums.path_buffers(len(lanes) * ctx["max_count"]) if r.exact else None
        lane = dr.arange(mi.UInt32, len(lanes))
        found = np.sum(ctx["launch"].count[lanes.sub])
        ctx["evaluated"] += int(found)

        run_pulses(ctx, data, count, lambda d, q: self._pulse(ctx, d, q, depth, paths, lane), "scatterers")
        dr.scatter_add(ctx["scatterers"], mi.UInt32(int(found)), mi.UInt32(depth), mode=ctx["tally"])
        if paths is not None:
            r.sums.keep_paths(ctx, paths)

    def _pulse(self, ctx, data, q, depth: int, paths, lane) -> None:
        r = self.r
        pulse, antenna, lref, view = r._pulse(ctx, data["sub"], q)
        leg = data["unfolded"] - antenna
        s = dr.norm(leg)
        first = mi.Vector3f(leg / s)
        d = first if depth == 0 else (data["fold"][0] * first.x + data["fold"][1] * first.y + data["fold"][2] * first.z)
        outgoing, dist = receive_leg(view, antenna, data["point"], s)
        b = mi.Vector3f(outgoing / dist)
        n = data["normal"]
        facing = dr.select(dr.dot(n, d) < 0, 1.0, -1.0)
        cos_i, cos_b = dr.maximum(-facing * dr.dot(n, d), 0.0), dr.maximum(facing * dr.dot(n, b), 0.0)
        kind = dr.gather(mi.UInt32, r.tables.clutter_kind, data["row"])
        value = r.tables.read("clutter_value", data["row"])
        rec = _Record(data["row"], data["jones"])
        co, cross, level = r.rough_returns(rec, d, b, facing * n, (cos_i, cos_b), (kind, value), depth)   # (C2), (P7), (P9)
        active = level > 0
        if r.aim_mask:
            active &= r._in_beam(data["unfolded"], antenna, view)
        weight = r.weight(first, b, s, dist, lref, view)
        rel = s + dist - lref
        amplitude = data["gamma"] * r.carrier_phase(rel) * (self.c * weight)
        sn, cs = dr.sincos(data["phase"])
        here = amplitude * mi.Complex2f(cs, sn)
        values = [here * a for a in co]
        if cross is not None:
            sn, cs = dr.sincos(data["phase_cross"])
            there = amplitude * mi.Complex2f(cs, sn)
            values = [v + there * a for v, a in zip(values, cross)]
        inside = r.sums.deposit(ctx, pulse, depth, r.anchor(rel, lref), 0.0, values,
                                mi.UInt32(SPECTRAL_ORDERS.index(0)), active, paths, lane * ctx["max_count"] + q)
        power = dr.detach(dr.squared_norm(amplitude) * level)
        r.sums.tally(ctx, "energy", power, depth, active)
        r.sums.tally(ctx, "energy", power, r.settings.depth, active & ~inside)


_unused = (math, pol)
