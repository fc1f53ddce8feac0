"""Every pulse's physical-optics return from the lit pieces of the mesh's patches, in Dr.Jit
(docs/physics.md (M5), (PO1), (PO3), (A), (R1), (P4)).

The host (:mod:`sarmitsuba.tracing.driver.mesh_trace`) turns a bounce order's lit pieces into *term lanes*
(:class:`TermLanes`): one per point term of a piece's boundary segments in Gordon's edge form, or
one area term for a piece near the specular direction. For every pulse of its sub-aperture each
lane evaluates its point's exact float64 two-way length through the chain of mirrors, the
directions there, the PO density (obliquity, reflection coefficient or Jones matrix, antenna
pattern, spreading) and its term, and deposits it on the fast-time grid
(:class:`sarmitsuba.tracing.deposit.accumulate.Accumulator`):

* ``SPLIT``: an end of a segment ``a`` whose phase runs ``|alpha| = |k u . a| / 2 >= alpha_s``
  across it, ``sigma n . (u_t x a^) / (k^2 |u_t|^2 u . a^)`` (spectral order -1), ``sigma = +1`` at
  its start and -1 at its end; ``u = d - b`` at the point itself, so that an end shared by two
  segments or pieces is the same number with opposite signs;
* ``SINC``: a segment's midpoint, ``(j / (k |u_t|^2)) n . (u_t x a) sinc(alpha)`` with the
  sinc's first-order change across the band (orders 0 and 1);
* ``OPEN``: the three candidates of a segment split for some pulses only, each pulse keeping those
  its own ``alpha`` at the midpoint calls for;
* ``AREA``: a piece within ``tau / (k D)`` of the specular direction, its exact linear-phase
  integral about its centroid with the quadratic phase's first-order term (orders 1 and 0).

A piece near the specular direction for some pulse (not *stable*) gates its lanes per pulse at
its centroid: its area term where ``k |u_t| D < tau``, its segments elsewhere. The NumPy reference
of the terms is :func:`sarmitsuba.tracing.integration.physical_optics.piece_terms`; tests compare the two.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from ..deposit.fast_time import SPECTRAL_ORDERS
from .catalogue import LaneSums
from .edge_terms import EdgeTerms, end_slope, sinc, x_dsinc
from ..device import device_array
from . import jones as pol
from .pulse_view import receive_leg
from ..deposit.replay import run_pulses, shared_read
from ..loops import loop_mode

__all__ = ["TermLanes", "PieceTable", "PatchTerms", "SPLIT_START", "SPLIT_END", "SINC", "OPEN_START", "OPEN_END",
           "OPEN_MID", "AREA", "NEAR_SPECULAR", "TAYLOR_BELOW", "piece_moves"]

#: Lane kinds: a split segment's start and end, a segment's sinc at its midpoint, the three
#: candidates of a segment split for some pulses only, a piece's area term.
SPLIT_START, SPLIT_END, SINC, OPEN_START, OPEN_END, OPEN_MID, AREA = 0, 1, 2, 3, 4, 5, 6
#: A piece is integrated as one area term where ``k |u_t| D`` (``D`` its bounding-box diagonal) is
#: below this: near the specular direction Gordon's edge terms grow as ``1 / (k |u_t| D)^2`` and
#: their local phase gradients stop describing the piece (docs/physics.md (M5)). Measured on
#: plates near normal incidence against brute-force quadrature: 3 keeps both forms within -30 dB
#: of the exact integral (6: -17 dB at 0.5 deg tilt).
NEAR_SPECULAR = 3.0
#: Below this ``k |u_t| D`` the area term takes the Taylor series of its linear phase (to second
#: order) instead of Gordon's sum, whose terms cancel to ``1 / (k |u_t| D)^2`` of float32 there.
TAYLOR_BELOW = 0.03
_SQRT_4PI = math.sqrt(4.0 * math.pi)


@dataclass(frozen=True)
class PieceTable:
    """Per piece of a bounce order (NumPy, uploaded once per launch): where it is and what its
    area term needs. ``centroid`` and ``centroid_unfolded`` float64 [p, 3] (m); ``diagonal``
    float32 [p] (m, its bounding box's); ``area`` [p] (m^2); ``moments`` float32 [p, 3] (``Ixx,
    Ixy, Iyy`` about the centroid in face coordinates, m^4); ``axis_u``, ``axis_v`` float32 [p, 3]
    (the face's axes); ``segment_start``, ``segment_count`` uint32 [p] (its boundary segments'
    rows); ``segment_mid``, ``segment_edge`` float32 [s, 3] (midpoint relative to the centroid and
    edge vector, m)."""

    centroid: np.ndarray
    centroid_unfolded: np.ndarray
    diagonal: np.ndarray
    area: np.ndarray
    moments: np.ndarray
    axis_u: np.ndarray
    axis_v: np.ndarray
    segment_start: np.ndarray
    segment_count: np.ndarray
    segment_mid: np.ndarray
    segment_edge: np.ndarray
    segment_mid_rate: np.ndarray | None = None
    segment_edge_rate: np.ndarray | None = None


def piece_moves(pieces: PieceTable) -> np.ndarray:
    """bool [p]: whether any of each piece's boundary segments moves (a rate not zero, eq. (M8))."""
    moving = np.any(pieces.segment_mid_rate != 0, axis=1) | np.any(pieces.segment_edge_rate != 0, axis=1)
    counted = np.concatenate([[0], np.cumsum(moving)])
    start = pieces.segment_start.astype(np.int64)
    return counted[start + pieces.segment_count.astype(np.int64)] > counted[start]


@dataclass(frozen=True)
class TermLanes:
    """The point and area terms of a bounce order's lit pieces (NumPy; one row per lane).

    Attributes
    ----------
    kind : uint32 [m]
        :data:`SPLIT_START`, :data:`SPLIT_END`, :data:`SINC`, :data:`OPEN_START`, :data:`OPEN_END`,
        :data:`OPEN_MID`, :data:`AREA`.
    point, unfolded : float64 [m, 3]
        The term's point on the last part, and ``U_d`` of it (the unfolded path's end), m.
    middle, middle_unfolded : float64 [m, 3]
        The segment's midpoint and ``U_d`` of it (where an ``OPEN`` lane decides), m.
    edge : float32 [m, 3]
        The segment ``a`` (counter-clockwise about ``normal``), m.
    normal : float32 [m, 3]
        The part's unit normal (the mesh's orientation).
    fold : float32 [m, 3, 3]
        ``lin_d^T`` (rows): a direction of the unfolded path in the scene at the last part.
    sub, row, piece : uint32 [m]
        Sub-aperture (in the launch), material row, piece (row of :class:`PieceTable`).
    stable : bool [m]
        The piece is never near the specular direction (nor at a hard beam edge) in its
        sub-aperture: its lanes are never gated.
    first : float32 [m, 3]
        The unfolded path's direction from the sub-aperture's reference position (bounce orders
        > 1: the transmitted field's launch direction).
    window_row : uint32 [m, d]
        Material row of each earlier bounce's part.
    window_cos : float32 [m, d]
        Cosine of the incidence angle there, from the reference position.
    window_direction, window_normal : float32 [m, d, 3]
        The wave's direction arriving there and the part's normal facing it (Jones matrices).
    origin : float64 [m, 3], optional
        The reference position of the lane's sub-aperture, m (lanes that move).
    axis : float32 [m, 3], optional
        The unit direction of travel their rates are per metre of.
    motion : float32 [m, 5, 3], optional
        Rates of ``point``, ``unfolded``, ``middle``, ``middle_unfolded`` and ``edge`` per metre
        of the antenna's travel along ``axis`` from ``origin``
        (:mod:`sarmitsuba.tracing.visibility.motion`, eq. (M8)): a pulse ``t`` metres along evaluates the
        lane at ``point + t rate``. None: nothing moves.
    diffracting : bool [m], optional
        The lane's segment lies on a diffracting edge and carries its fringe term
        (:mod:`sarmitsuba.tracing.integration.edges`, eq. (E4)). None: diffraction off.
    wedge_x0, wedge_xn : float32 [m, 3], optional
        Unit vectors normal to the edge, into the lane's part (face 0) and into the wedge's other
        face (zero on a free edge).
    wedge_row : uint32 [m], optional
        Material row of the other face (the part's own on a free edge).
    wedge_defer : bool [m], optional
        The other face is a part of lower index: where it is lit and seen too, it carries the
        edge's fringe term and this lane does not (each edge counted once).
    double : bool [m], optional
        The lane carries the doubly diffracted term of eq. (E6) instead: its ``unfolded`` (and
        ``middle_unfolded``) is the point across its face on the opposite edge, where the
        incident leg ends.
    across, across_xn : float32 [m, 3], optional
        The vector from the lane's segment to the diffracting edge across its face (zero: none),
        and the unit vector into that edge's other face (zero on a free edge).
    catalogue : dict, optional
        With the scatterer catalogue on: what it keeps of each lane, one row per lane
        (:meth:`sarmitsuba.tracing.integration.catalogue.LaneCatalogue.lanes`); its ``point`` is
        where the lane's terms are also summed coherently (SC2). None: the catalogue is off.
    """

    kind: np.ndarray
    point: np.ndarray
    unfolded: np.ndarray
    middle: np.ndarray
    middle_unfolded: np.ndarray
    edge: np.ndarray
    normal: np.ndarray
    fold: np.ndarray
    sub: np.ndarray
    row: np.ndarray
    piece: np.ndarray
    stable: np.ndarray
    first: np.ndarray | None = None
    window_row: np.ndarray | None = None
    window_cos: np.ndarray | None = None
    window_direction: np.ndarray | None = None
    window_normal: np.ndarray | None = None
    origin: np.ndarray | None = None
    axis: np.ndarray | None = None
    motion: np.ndarray | None = None
    diffracting: np.ndarray | None = None
    wedge_x0: np.ndarray | None = None
    wedge_xn: np.ndarray | None = None
    wedge_row: np.ndarray | None = None
    wedge_defer: np.ndarray | None = None
    double: np.ndarray | None = None
    across: np.ndarray | None = None
    across_xn: np.ndarray | None = None
    catalogue: dict | None = None

    def __len__(self) -> int:
        return len(self.kind)

    def moved(self, antenna: np.ndarray) -> "TermLanes":
        """The lanes as a pulse at ``antenna`` [3] (float64, m) evaluates them, eq. (M8): every
        moving point ``t`` metres of travel along (NumPy; the kernel does the same per pulse)."""
        if self.motion is None:
            return self
        t = np.einsum("mi,mi->m", np.asarray(antenna, float)[None] - self.origin, self.axis.astype(float))[:, None]
        rate = self.motion.astype(float)
        return dataclasses.replace(self, point=self.point + t * rate[:, 0], unfolded=self.unfolded + t * rate[:, 1],
                                   middle=self.middle + t * rate[:, 2], middle_unfolded=self.middle_unfolded + t * rate[:, 3],
                                   edge=(self.edge + t * rate[:, 4]).astype(np.float32), motion=None)


class _Record:
    """What :meth:`sarmitsuba.tracing.integration.returns.Returns.po_channels` reads of a term: its material
    row and arriving Jones matrix."""

    def __init__(self, row, jones):
        self.row, self.jones = row, jones


#: The entries of an upload that are per piece or per boundary segment (read by gathers), not per lane.
PER_PIECE = frozenset({"centroid", "centroid_unfolded", "diagonal", "piece_area", "moments", "axis_u", "axis_v",
                       "segment_start", "segment_count", "segment_most", "segment_mid", "segment_edge", "segment_mid_rate",
                       "segment_edge_rate", "piece_moves"})


class PatchTerms:
    """Per-pulse PO terms of lit pieces (configuration fixed per acquisition).

    Parameters
    ----------
    returns : sarmitsuba.tracing.integration.returns.Returns
        The acquisition's per-pulse helpers: antenna pattern, spreading, reflection tables, Jones
        channels, carrier phase, fast-time anchor and accumulator.
    alpha_s : float
        The split threshold :func:`sarmitsuba.tracing.integration.physical_optics.split_threshold`.
    """

    def __init__(self, returns, alpha_s: float):
        self.r = returns
        self.k = returns.k
        self.alpha_s = alpha_s
        self.edges = EdgeTerms(returns, self.k)

    def __call__(self, ctx: dict, lanes: TermLanes, pieces: PieceTable, depth: int) -> None:
        """Deposit the lanes' terms for every pulse of their sub-apertures (bounce order ``depth + 1``).
        Lanes that carry a ``catalogue`` are also summed at their image points (SC2), into a
        :class:`~sarmitsuba.tracing.integration.catalogue.LaneSums` appended with it to the
        launch's ``ctx["catalogue"]``."""
        if len(lanes) == 0:
            return
        sums = None
        if lanes.catalogue is not None:
            sums = LaneSums(lanes.catalogue["point"], len(self.r.channels), lanes.catalogue["side"])
            ctx.setdefault("catalogue", []).append((sums, lanes.catalogue))
        self.deposit(ctx, self.upload(lanes, pieces, depth), lanes, depth, sums)

    def deposit(self, ctx: dict, data: dict, lanes: TermLanes, depth: int, sums=None) -> None:
        """Deposit the terms of lanes already on the device (``data``, :meth:`upload`)."""
        if sums is not None:
            data = {**data, "catalogue": sums.points}
            ctx["catalogue_sums"] = sums
        count = dr.gather(mi.UInt32, ctx["count"], data["sub"])
        paths = self.r.sums.path_buffers(len(lanes) * ctx["max_count"] * 2) if self.r.exact else None
        lane = dr.arange(mi.UInt32, len(lanes))
        ctx["evaluated"] += int(np.sum(ctx["launch"].count[lanes.sub]))

        run_pulses(ctx, data, count, lambda d, q: self._pulse(ctx, d, q, depth, paths, lane), "patch terms",
                   shared=PER_PIECE)
        if paths is not None:
            self.r.sums.keep_paths(ctx, paths)

    # ------------------------------------------------------------------ upload
    def upload(self, lanes: TermLanes, pieces: PieceTable, depth: int) -> dict:
        """The lanes and pieces on the device, with each lane's ``gamma`` and Jones matrix: a dict
        of Dr.Jit arrays (and lists of them) by name, and flags (bool) saying which are there."""
        a64, v3 = mi.Array3f64, mi.Vector3f
        data = dict(kind=device_array(mi.UInt32, lanes.kind), point=device_array(a64, lanes.point.T),
                    unfolded=device_array(a64, lanes.unfolded.T), edge=device_array(v3, lanes.edge.T),
                    normal=device_array(v3, lanes.normal.T), sub=device_array(mi.UInt32, lanes.sub),
                    row=device_array(mi.UInt32, lanes.row), piece=device_array(mi.UInt32, lanes.piece),
                    stable=device_array(mi.Bool, lanes.stable))
        data["fold"] = [device_array(v3, lanes.fold[:, :, c].T) for c in range(3)] if depth > 0 else None
        data["open"] = bool(np.any((lanes.kind >= OPEN_START) & (lanes.kind <= OPEN_MID)))
        if data["open"]:
            data["middle"] = device_array(a64, lanes.middle.T)
            data["middle_unfolded"] = device_array(a64, lanes.middle_unfolded.T)
        data["moving"] = lanes.motion is not None and bool(np.any(lanes.motion != 0))
        if data["moving"]:
            data["origin"] = device_array(a64, lanes.origin.T)
            data["axis"] = device_array(v3, lanes.axis.T)
            data["motion"] = [device_array(v3, lanes.motion[:, c].T) for c in range(5)]
        data["gated"] = bool(np.any(~lanes.stable))
        if data["gated"]:
            data["centroid"] = device_array(a64, pieces.centroid.T)
            data["centroid_unfolded"] = device_array(a64, pieces.centroid_unfolded.T)
            data["diagonal"] = device_array(mi.Float, pieces.diagonal)
        data["area"] = bool(np.any(lanes.kind == AREA))
        if data["area"]:
            data["piece_area"] = device_array(mi.Float, pieces.area)
            data["moments"] = [device_array(mi.Float, pieces.moments[:, c]) for c in range(3)]
            data["axis_u"], data["axis_v"] = device_array(v3, pieces.axis_u.T), device_array(v3, pieces.axis_v.T)
            data["segment_start"] = device_array(mi.UInt32, pieces.segment_start)
            data["segment_count"] = device_array(mi.UInt32, pieces.segment_count)
            data["segment_most"] = int(pieces.segment_count.max(initial=0))
            data["segment_mid"] = device_array(v3, pieces.segment_mid.T)
            data["segment_edge"] = device_array(v3, pieces.segment_edge.T)
            data["segment_moving"] = data["moving"] and pieces.segment_mid_rate is not None
            if data["segment_moving"]:
                data["segment_mid_rate"] = device_array(v3, pieces.segment_mid_rate.T)
                data["segment_edge_rate"] = device_array(v3, pieces.segment_edge_rate.T)
                data["piece_moves"] = device_array(mi.Bool, piece_moves(pieces))
        data["gamma"], data["jones"] = self.arrival(lanes, depth)
        data["diffraction"] = lanes.diffracting is not None and bool(np.any(lanes.diffracting))
        if data["diffraction"]:
            data["diffracting"] = device_array(mi.Bool, lanes.diffracting)
            data["wedge_x0"] = device_array(v3, lanes.wedge_x0.T)
            data["wedge_xn"] = device_array(v3, lanes.wedge_xn.T)
            data["wedge_row"] = device_array(mi.UInt32, lanes.wedge_row)
            data["wedge_defer"] = device_array(mi.Bool, lanes.wedge_defer)
            data["double"] = bool(np.any(lanes.double))
            data["across"] = device_array(v3, lanes.across.T)       # also face N's width, (E2)
            if data["double"]:
                data["is_double"] = device_array(mi.Bool, lanes.double)
                data["across_xn"] = device_array(v3, lanes.across_xn.T)
            if depth > 0 and data["jones"] is None:
                data["edge_jones"] = self.edges.mirrored(lanes, depth)
        return data

    def arrival(self, lanes, depth: int):
        """Each lane's product of the earlier bounces' reflection coefficients (of their specular
        factors only with Jones matrices) and the Jones matrix arriving at its point, from the
        reference position (docs/physics.md (R), (P3')); ``(1, None)`` at the first bounce."""
        r = self.r
        gamma = mi.Complex2f(1.0, 0.0)
        if depth == 0:
            return gamma, None
        jones = pol.launch(device_array(mi.Vector3f, lanes.first.T), mi.Vector3f(*r.track)) if r.polarimetric else None
        for i in range(depth):
            row = device_array(mi.UInt32, lanes.window_row[:, i])
            cos = device_array(mi.Float, lanes.window_cos[:, i])
            specular = r.tables.read("specular", row)
            if r.polarimetric:
                r_te, r_tm = r.reflection_pair(row, cos, True)
                jones = pol.reflect(jones, device_array(mi.Vector3f, lanes.window_direction[:, i].T),
                                    device_array(mi.Vector3f, lanes.window_normal[:, i].T), r_te, r_tm)
                gamma = gamma * specular
            else:
                gamma = gamma * r.reflection_at(row, cos, True) * specular
        dr.eval(gamma, jones)
        return gamma, jones

    # ------------------------------------------------------------------ geometry at a point
    def _at(self, data, antenna, view, point, unfolded, depth: int):
        """The pulse's view of a point of the last part: unfolded length ``s``, receive leg
        ``dist`` (float64), first-leg direction, arriving direction ``d`` and return ``b`` there."""
        leg = unfolded - antenna
        s = dr.norm(leg)
        first = mi.Vector3f(leg / s)
        d = first if depth == 0 else (data["fold"][0] * first.x + data["fold"][1] * first.y
                                       + data["fold"][2] * first.z)
        outgoing, dist = receive_leg(view, antenna, point, s)
        return s, dist, first, d, mi.Vector3f(outgoing / dist)

    def _tangential(self, n, d, b):
        u = d - b
        ut = u - n * dr.dot(u, n)
        return u, ut, dr.squared_norm(ut)

    # ------------------------------------------------------------------ one pulse
    def _pulse(self, ctx, data, q, depth: int, paths, lane) -> None:
        r, k = self.r, self.k
        kind, n = data["kind"], data["normal"]
        pulse, antenna, lref, view = r._pulse(ctx, data["sub"], q)
        if data["moving"]:
            data = self._moved(data, antenna)
        s, dist, first, d, b = self._at(data, antenna, view, data["point"], data["unfolded"], depth)
        u, ut, ut2 = self._tangential(n, d, b)
        facing = dr.select(dr.dot(n, d) < 0, 1.0, -1.0)            # +1: the wave meets the normal's side
        cos_i, cos_b = -facing * dr.dot(n, d), facing * dr.dot(n, b)
        # lit: the wave meets the face; PO also needs the receiver on the face's side, the fringe
        # term only the receiver outside the wedge (eq. (E4), in EdgeTerms.fringe)
        edge_live = cos_i > 1e-6
        if r.aim_mask:
            edge_live &= r._in_beam(data["unfolded"], antenna, view)
        split = (kind == SPLIT_START) | (kind == SPLIT_END)
        if data["open"]:
            decide = self._open_split(data, antenna, view, depth)
            opened = (kind >= OPEN_START) & (kind <= OPEN_MID)
            split |= opened & (kind != OPEN_MID) & decide
            edge_live &= ~opened | dr.select(kind == OPEN_MID, ~decide, decide)
        active = edge_live & (cos_b > 1e-6)                      # a new mask: the fringe term is never gated
        if data["gated"]:
            near = self._near(data, antenna, view, depth)
            active &= data["stable"] | dr.select(kind == AREA, near, ~near)
        specular = r.tables.read("specular", data["row"])
        weight = r.weight(first, b, s, dist, lref, view)
        density = (math.sqrt(math.pi) / r.lam) * (cos_i + cos_b) * specular * weight
        base = mi.Complex2f(0.0, 1.0) * data["gamma"] * density
        channels = r.po_channels(_Record(data["row"], data["jones"]), d, b, facing * n, cos_i, depth)
        rel = s + dist - lref
        phase = r.carrier_phase(rel)
        anchor = r.anchor(rel, lref)
        value, order, second, second_order = self._coefficients(data, u, ut, ut2, split, antenna, view, s, dist,
                                                                d, b, depth)
        fringe = None
        if data["diffraction"]:
            fringe, carry, sin_i = self.edges.fringe(data, d, b, facing * n, cos_i, depth)
            edge_live = edge_live & data["diffracting"] & carry
            if data["double"]:
                double = data["is_double"]
                twice = self.edges.double(data, d, b, facing * n, sin_i, depth)
                fringe = [dr.select(double, g, f) for f, g in zip(fringe, twice)]
                # the grazing leg across the face, eq. (E6)
                rel = rel + dr.select(double, dr.norm(data["across"]) * sin_i, 0.0)
                phase, anchor = r.carrier_phase(rel), r.anchor(rel, lref)
                active = active & ~double
            scale = data["gamma"] * specular * weight * _SQRT_4PI
            fringe = [f * scale for f in fringe]
            line, line_second = self.edges.line(data, (kind == SPLIT_START) | (kind == OPEN_START), u, split)
        catalogue = ctx["catalogue_sums"].phases(r, data["catalogue"], antenna, view, lref) \
            if "catalogue" in data else None
        for which, (term, index) in enumerate(((value, order), (second, second_order))):
            live = active if which == 0 else active & ~split
            values = [base * term * phase * c for c in channels]
            if fringe is not None:
                f_live = edge_live if which == 0 else edge_live & ~split
                factor = (line if which == 0 else line_second) * phase
                values = [dr.select(live, v, 0.0) + dr.select(f_live, f * factor, 0.0) for v, f in zip(values, fringe)]
                live = live | f_live
            power = dr.detach(dr.squared_norm(values[0]))
            inside = r.sums.deposit(ctx, pulse, depth, anchor, 0.0, values, index, live, paths,
                                    (lane * ctx["max_count"] + q) * 2 + which)
            if catalogue is not None:               # the scatterer catalogue's sums (SC2)
                ctx["catalogue_sums"].add(ctx, catalogue, lane, values, live & inside)
            r.sums.tally(ctx, "energy", power, depth, live)
            r.sums.tally(ctx, "energy", power, r.settings.depth, live & ~inside)

    @staticmethod
    def _moved(data, antenna):
        """``data`` with the lanes' points, midpoints and edges where the pulse at ``antenna``
        sees them: ``x + t rate``, ``t`` the antenna's travel along the lane's axis, eq. (M8)."""
        t = mi.Float(dr.dot(mi.Vector3f(antenna - data["origin"]), data["axis"]))
        rate = data["motion"]
        moved = dict(data, travel=t, point=data["point"] + mi.Array3f64(rate[0] * t),
                     unfolded=data["unfolded"] + mi.Array3f64(rate[1] * t), edge=data["edge"] + rate[4] * t)
        if data["open"]:
            moved["middle"] = data["middle"] + mi.Array3f64(rate[2] * t)
            moved["middle_unfolded"] = data["middle_unfolded"] + mi.Array3f64(rate[3] * t)
        return moved

    def _coefficients(self, data, u, ut, ut2, split, antenna, view, s, dist, d, b, depth: int):
        """A lane's term before the density and the carrier phase, eq. (M5): ``(value, order,
        second, second_order)`` with the orders as indices of
        :data:`~sarmitsuba.tracing.deposit.fast_time.SPECTRAL_ORDERS` (the second term only for sinc and area
        lanes: the first-order change of their band-limited factor across the band)."""
        k, kind, n = self.k, data["kind"], data["normal"]
        a_len = dr.norm(data["edge"])
        a_hat = data["edge"] / dr.maximum(a_len, 1e-30)
        ua = dr.dot(u, a_hat)
        cross = dr.dot(n, dr.cross(ut, a_hat))
        safe_ut2 = dr.maximum(ut2, 1e-30)
        sign = dr.select((kind == SPLIT_START) | (kind == OPEN_START), 1.0, -1.0)
        split_value = mi.Complex2f(sign * cross / (k * k * safe_ut2 * end_slope(ua, a_len, k)), 0.0)
        alpha = 0.5 * k * ua * a_len
        sinc_base = mi.Complex2f(0.0, cross * a_len / (k * safe_ut2))
        s1 = x_dsinc(alpha)
        value = dr.select(split, split_value, sinc_base * (sinc(alpha) - s1))
        second = sinc_base * s1
        minus, zero, plus = (mi.UInt32(SPECTRAL_ORDERS.index(m)) for m in (-1, 0, 1))
        order = dr.select(split, minus, zero)
        second_order = plus
        if data["area"]:
            f, kdf = self._area_integral(data, antenna, view, s, dist, d, b, u, depth)
            area = kind == AREA
            value, second = dr.select(area, f + kdf, value), dr.select(area, -kdf, second)
            order, second_order = dr.select(area, plus, order), dr.select(area, zero, second_order)
        return value, order, second, second_order

    def _near(self, data, antenna, view, depth: int):
        """Whether the pulse sees each lane's piece within ``tau / (k D)`` of the specular direction."""
        piece = data["piece"]
        point = shared_read(data, "centroid", piece)
        unfolded = shared_read(data, "centroid_unfolded", piece)
        _, _, _, d, b = self._at(data, antenna, view, point, unfolded, depth)
        _, _, ut2 = self._tangential(data["normal"], d, b)
        return self.k * dr.sqrt(ut2) * shared_read(data, "diagonal", piece) < NEAR_SPECULAR

    def _open_split(self, data, antenna, view, depth: int):
        """Whether the pulse splits each lane's segment: ``|k u . a| / 2 >= alpha_s`` at its midpoint."""
        _, _, _, d, b = self._at(data, antenna, view, data["middle"], data["middle_unfolded"], depth)
        return 0.5 * self.k * dr.abs(dr.dot(d - b, data["edge"])) >= self.alpha_s

    def _area_integral(self, data, antenna, view, s, dist, d, b, u, depth: int):
        """``F = int exp(-j k (L(r) - L_c)) dA`` over the lane's piece about its centroid (the lane's
        point), with the quadratic phase to first order, and ``k dF / dk``."""
        k, piece, n = self.k, data["piece"], data["normal"]
        area = shared_read(data, "piece_area", piece)
        ixx, ixy, iyy = shared_read(data, "moments", piece)
        eu, ev = shared_read(data, "axis_u", piece), shared_read(data, "axis_v", piece)
        inv_s, inv_r = 1.0 / mi.Float(s), 1.0 / mi.Float(dist)

        def q_form(x, y):               # x^T Q y, Q = ((I - d d^T) / s + (I - b b^T) / R) / 2
            return 0.5 * ((dr.dot(x, y) - dr.dot(x, d) * dr.dot(y, d)) * inv_s
                          + (dr.dot(x, y) - dr.dot(x, b) * dr.dot(y, b)) * inv_r)
        quad = q_form(eu, eu) * ixx + 2.0 * q_form(eu, ev) * ixy + q_form(ev, ev) * iyy
        uu, uv = dr.dot(u, eu), dr.dot(u, ev)
        spread = uu * uu * ixx + 2.0 * uu * uv * ixy + uv * uv * iyy
        ut2 = uu * uu + uv * uv
        # Taylor: F = A - (k^2 / 2) <(u . r)^2> - j k tr(Q M2); k dF/dk doubles the second-order term
        taylor = mi.Complex2f(area - 0.5 * k * k * spread, -k * quad)
        taylor_k = mi.Complex2f(-k * k * spread, -k * quad)
        diag = shared_read(data, "diagonal", piece)
        gordon = (self.k * dr.sqrt(ut2) * diag >= TAYLOR_BELOW) & (data["kind"] == AREA)
        start = dr.gather(mi.UInt32, data["segment_start"], piece)
        moving = bool(data.get("segment_moving"))
        # moving boundaries (eq. (M8)): the Taylor form takes the area of the moved segments too
        walk = (gordon | (data["kind"] == AREA)) if moving else gordon
        stop = start + dr.select(walk, dr.gather(mi.UInt32, data["segment_count"], piece), 0)
        ut = u - n * dr.dot(u, n)
        inv = 1.0 / (k * dr.maximum(ut2, 1e-30))

        def step(e, f, kdf, shoelace):
            mid = shared_read(data, "segment_mid", e)
            edge = shared_read(data, "segment_edge", e)
            if moving:
                mid += shared_read(data, "segment_mid_rate", e) * data["travel"]
                edge += shared_read(data, "segment_edge_rate", e) * data["travel"]
                shoelace += 0.5 * dr.dot(n, dr.cross(mid, edge))
            alpha = 0.5 * k * dr.dot(u, edge)
            sn, cs = dr.sincos(-k * dr.dot(u, mid))
            common = mi.Complex2f(cs, sn) * mi.Complex2f(0.0, inv * dr.dot(n, dr.cross(ut, edge)))
            value = sinc(alpha)
            # k d/dk of (1 / k) sinc(alpha) exp(-j k u . m): -1, the sinc's own change, -j k u . m
            derivative = common * mi.Complex2f(x_dsinc(alpha) - value, -k * dr.dot(u, mid) * value)
            return e + 1, f + common * value, kdf + derivative, shoelace

        state = (start, mi.Complex2f(0.0, 0.0), mi.Complex2f(0.0, 0.0), mi.Float(0.0))
        if data.get("replayed"):
            # unrolled to the upload's longest boundary: Dr.Jit 1.5 does not reverse a loop nested
            # in the replay's pulse loop on the LLVM backend (invalid code, or zero gradients)
            last = mi.UInt32(max(dr.width(data["segment_mid"]), 1) - 1)
            for _ in range(data["segment_most"]):
                e, f, kdf, shoelace = state
                _, f1, kdf1, shoelace1 = step(dr.minimum(e, last), f, kdf, shoelace)
                on = e < stop
                state = (e + 1, dr.select(on, f1, f), dr.select(on, kdf1, kdf), dr.select(on, shoelace1, shoelace))
            _, f, kdf, shoelace = state
        else:
            _, f, kdf, shoelace = dr.while_loop(state, lambda e, *_: e < stop, step, mode=loop_mode(),
                                                label="area segments")
        if moving:
            # the moved piece's own area and size decide between the Taylor and Gordon forms; a
            # piece whose boundary stays keeps its own (not the shoelace's rounding of it: a
            # sub-aperture's terms must not depend on whether a launch-mate's pieces move, (D7))
            moves = dr.gather(mi.Bool, data["piece_moves"], piece)
            taylor = taylor + mi.Complex2f(dr.select(moves, shoelace - area, 0.0), 0.0)
            size = dr.select(moves, dr.maximum(diag, dr.sqrt(dr.abs(shoelace))), diag)
            gordon = (self.k * dr.sqrt(ut2) * size >= TAYLOR_BELOW) & (data["kind"] == AREA)
            f, kdf = dr.select(gordon, f, 0.0), dr.select(gordon, kdf, 0.0)
        correction = mi.Complex2f(0.0, -k * quad)
        return dr.select(gordon, f + correction, taylor), dr.select(gordon, kdf + correction, taylor_k)
