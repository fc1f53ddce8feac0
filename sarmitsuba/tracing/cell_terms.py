"""Cell pieces in the kernel: every pulse's physical-optics integral over each piece of a mixed
cell, at any bounce order (docs/physics.md (T6), (PO1), (PO2), (PO5)); a part of
:class:`sarmitsuba.tracing.returns.Returns`.

The host plans the pieces (:func:`sarmitsuba.tracing.cell_plan.plan_cells`). Here each piece is the
cell's rectangle on the aim plane cut, as each pulse sees them, by the convex polygons of its
chain (each part mirrored in the planes of the parts before it and projected from the pulse's
antenna onto the aim plane) and by its occluders' projections (their side in front only), and
integrated as a flux through its boundary segments (Gordon 1975), each term at its own point.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from .cell_clip import inside, pack, packed_size
from .cell_plan import NONE, RECEIVE, LaneTable, plan_cells
from .clutter_lattice import FootprintCells
from .deposit import SPECTRAL_ORDERS
from .device import device_array
from .facets import MAX_PART_VERTICES, scene_parts
from .pulse_view import receive_leg

__all__ = ["CellTerms", "PartTable", "FLAT_PHASE", "CROSSING_TOLERANCE"]

#: Below this ``k |u_t| sqrt(A)`` a piece's phase is flat: one term, its area at its centroid
#: (the neglected second moment is below a 24th of its square), eq. (T6).
FLAT_PHASE = 0.01
#: An occluder's corners closer than this to a part's plane [m] lie on it (a wall standing on a
#: roof touches the roof's plane).
CROSSING_TOLERANCE = 1e-4
_INVALID = 0xFFFFFFFF
# flags of kernel.Flags (repeated here: the kernel imports this module through returns)
_SPLIT_1, _SPLIT_2, _BACK, _UNDECIDED_1, _UNDECIDED_2, _PIECED = 32, 64, 128, 256, 512, 1024


@dataclass
class PartTable:
    """The convex parts of a scene's meshes (:func:`sarmitsuba.tracing.facets.scene_parts`) on the device:
    each triangle's part (INVALID for degenerate ones), the corner slots (``part *
    MAX_PART_VERTICES + slot``), unit normals and plane offsets (float64), each part's Mitsuba
    shape id, the NumPy arrays the host's plan needs, and ``slots``, the most corners of any part
    (the slots beyond a part's corners repeat its last one, so the kernels read only ``slots``)."""

    triangle_part: mi.UInt32
    corners: mi.Array3f64
    normal: mi.Array3f64
    offset: mi.Float64
    shape: mi.UInt32
    host: tuple
    slots: int = MAX_PART_VERTICES

    @staticmethod
    def of(scene) -> "PartTable":
        parts = scene_parts(scene)
        corners = parts.vertices.reshape(-1, 3)
        part = np.where(parts.triangle_part < 0, _INVALID, parts.triangle_part.astype(np.int64))  # int32 cannot hold INVALID
        ids = np.array([int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(s))[0]) for s in scene.shapes()], np.uint32)
        return PartTable(mi.UInt32(part.astype(np.uint32)),
                         mi.Array3f64(*(corners[:, c].copy() for c in range(3))),
                         mi.Array3f64(*(parts.normal[:, c].copy() for c in range(3))),
                         mi.Float64(parts.offset.copy()), mi.UInt32(ids[parts.shape] if len(parts.shape) else ids[:0]),
                         (parts.vertices, parts.face.astype(np.int64), parts.normal, parts.offset,
                          parts.adjacency_start, parts.adjacency.astype(np.int64),
                          parts.closed if parts.closed is not None else np.zeros(parts.n_parts, bool)),
                         int(parts.n_vertices.max(initial=3)))


def _reflect_point(x, plane):
    n, o = plane
    return x - n * (2.0 * (dr.dot(n, x) - o))


def _reflect_plane(plane, mirror):
    """The plane ``n . x = o`` mirrored in ``mirror``."""
    (n, o), (m, p) = plane, mirror
    c = dr.dot(n, m)
    return n - m * (2.0 * c), o - 2.0 * c * p


class CellTerms:
    """The cell-piece methods of :class:`sarmitsuba.tracing.returns.Returns` (which provides the tables,
    the footprint, ``_tile``, ``_pulse``, ``weight``, ``po_channels``, the accumulator)."""

    # ------------------------------------------------------------------ lane tables
    def open_lanes(self, ctx, traced, n_lanes: int) -> None:
        """Start a launch's lane tables (:class:`sarmitsuba.tracing.cell_plan.LaneTable`, one per bounce)."""
        ctx["traced"], ctx["n_lanes"], ctx["lanes"] = traced, n_lanes, []

    def note_lanes(self, ctx, lattice, hit_part, key, valid, visible, blocker) -> None:
        """Record one bounce order's lane table (device arrays; read back when planned)."""
        n = ctx["n_lanes"]
        tables = []
        for value, fill in ((hit_part, _INVALID), (key, _INVALID), (mi.UInt32(visible), 0), (blocker, _INVALID)):
            out = dr.full(mi.UInt32, fill, n)
            dr.scatter(out, value, lattice, valid)
            tables.append(out)
        dr.eval(tables)
        ctx["lanes"].append(tables)

    def _lane_tables(self, ctx, depth):
        out = []
        for part, key, vis, blocker in ctx["lanes"][:depth + 1]:
            conv = [a.numpy().astype(np.int64) for a in (part, key, vis, blocker)]
            for a in (conv[0], conv[1], conv[3]):
                a[a == _INVALID] = -1
            out.append(LaneTable(*conv))
        return out

    # ------------------------------------------------------------------ the plan
    def cells(self, ctx, rec, depth: int):
        """Plan bounce order ``depth``'s mixed cells on the host, flag the records whose tiles they
        replace, and return the launches of :meth:`cell_returns`: the pieces without occluders,
        then each group of pieces less their occluders (:data:`cell_plan.OCCLUDER_GROUPS`)."""
        launch = ctx["launch"]
        views = np.stack([launch.reference, launch.antenna[launch.first],
                          launch.antenna[launch.first + launch.count - 1]], 1)
        traced = ctx["traced"].numpy().astype(bool)
        plan = plan_cells(depth, self._lane_tables(ctx, depth), rec.lattice.numpy().astype(np.int64), traced,
                          launch.blocks, ctx["n_lanes"], self.tables.parts.host, views, self.fp)
        if len(plan.record) == 0:
            return None
        rec.flags |= dr.select(mi.Bool(plan.replaced), mi.UInt32(_PIECED), mi.UInt32(0))
        dr.eval(rec.flags)
        launches = []
        alone = np.setdiff1d(np.arange(len(plan.record)), np.concatenate([c[0] for c in plan.cuts] + [np.zeros(0, np.int64)]))
        base = (alone, np.zeros((len(alone), 0), np.int64), np.zeros((len(alone), 0), np.int64))
        for piece, occ_parts, occ_levels in [base] + list(plan.cuts):
            if len(piece) == 0:
                continue
            u32 = lambda a: device_array(mi.UInt32, np.ascontiguousarray(a).astype(np.uint32))   # noqa: E731
            pieces = dr.gather(type(rec), rec, u32(plan.record[piece]))
            bounds = [device_array(mi.Float64, plan.bounds[piece, c].copy()) for c in range(4)]
            chain = [u32(plan.chain[piece, i]) for i in range(depth + 1)]
            m = mi.Float64(dr.gather(mi.UInt32, ctx["block_m"], pieces.block))
            aim = self._aim_point(0.5 * (bounds[0] + bounds[1]), 0.5 * (bounds[2] + bounds[3]), m)
            pieces = self._retarget(ctx, pieces, chain, aim, depth)
            occluders = [(u32(occ_parts[:, k]), u32(occ_levels[:, k])) for k in range(occ_parts.shape[1])]
            dr.eval(pieces, bounds, chain, occluders)
            launches.append((pieces, bounds, chain, occluders))
        return launches

    def _plane(self, part):
        parts = self.tables.parts
        return dr.gather(mi.Array3f64, parts.normal, part), dr.gather(mi.Float64, parts.offset, part)

    def _retarget(self, ctx, rec, chain, aim, depth: int):
        """The records of ``chain`` (its parts, level by level) at the cells aimed at ``aim``: the
        central ray from the sub-aperture's reference position, reflected in each part's plane in
        turn (inside the part or not). The donor's reflection coefficients and Jones matrix are
        kept; every pulse decides the tile's splits at the piece's centre."""
        reference = dr.gather(mi.Array3f64, ctx["reference"], rec.sub)
        x = reference
        d = dr.normalize(aim - reference)
        d0 = d
        s = mi.Float64(0.0)
        columns = [mi.Array3f64(1.0, 0.0, 0.0), mi.Array3f64(0.0, 1.0, 0.0), mi.Array3f64(0.0, 0.0, 1.0)]
        first_hit = None
        for level in range(depth + 1):
            n, o = self._plane(chain[level])
            den = dr.dot(n, d)
            t = (o - dr.dot(n, x)) / dr.select(den != 0, den, 1.0)
            x = x + d * t
            s += t
            first_hit = x if level == 0 else first_hit
            if level < depth:
                d = d - n * (2.0 * dr.dot(d, n))
                columns = [c - n * (2.0 * dr.dot(c, n)) for c in columns]
            else:
                back = den > 0
                n_face = dr.select(back, -n, n)
        m1, m2, m3 = (mi.Vector3f(c) for c in columns)
        nf = mi.Vector3f(n_face)
        shape = dr.gather(mi.UInt32, self.tables.parts.shape, chain[depth])
        rec.p64, rec.unfolded, rec.first_hit, rec.n = x, reference + d0 * s, first_hit, nf
        rec.n_unfolded = mi.Vector3f(dr.dot(m1, nf), dr.dot(m2, nf), dr.dot(m3, nf))
        rec.m1, rec.m2, rec.m3 = m1, m2, m3
        rec.part, rec.shape, rec.aim = chain[depth], shape, aim
        rec.row = dr.gather(mi.UInt32, self.tables.row_of_shape, shape)
        rec.flags = (rec.flags & ~mi.UInt32(_BACK | _SPLIT_1 | _SPLIT_2)) | dr.select(back, mi.UInt32(_BACK), mi.UInt32(0)) \
            | mi.UInt32(_UNDECIDED_1 | _UNDECIDED_2)
        return rec

    # ------------------------------------------------------------------ geometry on the aim plane
    def _lines(self, antenna, point, m):
        """The (unfolded) scene ``point`` seen from ``antenna`` on the aim plane, in lattice lines
        of tube size ``m``: ``(x, y)``, float64 (the central projection of (T3): lines stay lines)."""
        fp = self.fp
        origin, track, look = (mi.Array3f64(*v.tolist()) for v in (fp.origin, fp.track, fp.look))
        normal = mi.Array3f64(*np.cross(fp.track, fp.look).tolist())
        w = point - antenna
        x = antenna + w * (dr.dot(normal, origin - antenna) / dr.dot(normal, w)) - origin
        return dr.dot(x, track) / fp.spacing_azimuth * m, (dr.dot(x, look) - fp.range_min) / fp.spacing_range * m

    def _aim_point(self, x, y, m):
        """The aim-plane point at lattice lines ``(x, y)`` of tube size ``m`` (float64)."""
        fp = self.fp
        return mi.Array3f64(*fp.origin.tolist()) + mi.Array3f64(*fp.track.tolist()) * ((x / m) * fp.spacing_azimuth) \
            + mi.Array3f64(*fp.look.tolist()) * ((y / m) * fp.spacing_range + fp.range_min)

    def _corners(self, part):
        """The corner slots of ``part`` (float64 points, the scene's ``slots`` of them)."""
        return [dr.gather(mi.Array3f64, self.tables.parts.corners, part * MAX_PART_VERTICES + k)
                for k in range(self.tables.parts.slots)]

    def _unfold(self, points, mirrors):
        """Scene ``points`` after the mirrors ``mirrors`` (planes of the chain's earlier parts, the
        first part's first): in the unfolded frame, where the path from the antenna is straight."""
        for mirror in reversed(mirrors):
            points = [_reflect_point(p, mirror) for p in points]
        return points

    def _polygons(self, ctx, rec, reference, antenna, bounds, chain, occluders, depth: int):
        """The convex polygons whose intersection is the piece for the pulse at ``antenna``, on the
        aim plane as ``reference`` sees it (lattice lines of tube size ``m``): the rectangle
        ``bounds`` and the last part of the chain, fixed on the surface as the tiles are (T3);
        each earlier level's part in the unfolded frame and for each occluder the cut-out
        ``([projection, half-plane where it lies in front (:meth:`_half_plane`)], live)``, live
        where it is not padding, as the pulse sees them on the last part's plane. Returns
        ``(polygons, cutouts, m)``."""
        m = mi.Float64(dr.gather(mi.UInt32, ctx["block_m"], rec.block))
        planes = [self._plane(p) for p in chain]
        mirrors = planes[:depth]
        levels = []
        for level in range(depth + 1):
            corners = self._unfold(self._corners(chain[level]), mirrors[:level])
            plane = planes[level]
            for mirror in reversed(mirrors[:level]):
                plane = _reflect_plane(plane, mirror)
            levels.append((corners, plane))
        last = [self._lines(reference, c, m) for c in levels[-1][0]]
        x0, x1, y0, y1 = self._box(last, bounds)
        box = (0.5 * (x0 + x1), 0.5 * (y0 + y1)), 0.5 * dr.maximum(x1 - x0, y1 - y0) + 2.0
        if antenna is reference:
            seen, box_p = (lambda poly: poly), box
        else:           # the pulse's view, carried over the last part's plane into the reference's
            seen = lambda poly: [self._rebase(p, antenna, reference, levels[-1][1], m) for p in poly]   # noqa: E731
            box_p = self._rebase(box[0], reference, antenna, levels[-1][1], m), box[1]
        polygons = [last, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]] \
            + [seen([self._lines(antenna, c, m) for c in corners]) for corners, _ in levels[:-1]]
        cutouts = [([seen(p) for p in self._occluder(ctx, rec, antenna, part, level, levels, mirrors, box_p, m, depth)],
                    level != NONE) for part, level in occluders]
        return polygons, cutouts, m

    def _rebase(self, point, source, target, plane, m):
        """Lattice lines ``point`` on the aim plane seen from ``source``, seen from ``target``: the
        ray from ``source`` meets the (unfolded) ``plane`` there, and ``target`` projects that
        point back onto the aim plane (central projections: lines stay lines)."""
        normal, offset = plane
        w = self._aim_point(point[0], point[1], m) - source
        den = dr.dot(normal, w)
        on_plane = source + w * ((offset - dr.dot(normal, source)) / dr.select(den != 0, den, 1.0))
        return self._lines(target, on_plane, m)

    def _occluder(self, ctx, rec, antenna, part, level, levels, mirrors, box, m, depth):
        """An occluder's two polygons (its projection, and the half-plane where it is in front):
        at transmit level ``i`` (``level < RECEIVE``) the part mirrored as the chain's part of that
        level is, in front of it along the unfolded ray; on the receive side, the part's shadow on
        the last part's plane cast from the antenna, where it lies between that plane and the
        antenna. Levels are per lane: the mirrors below the lane's level apply (selected), so one
        projection serves every level."""
        raw = self._corners(part)
        plane_o = self._plane(part)
        receive = level == RECEIVE
        if depth > 0:                      # receive side: the shadow cast on the last part's real plane
            n_d, o_d = self._plane(rec.part)
            for k, b in enumerate(raw):
                den = dr.dot(n_d, b - antenna)
                shadow = antenna + (b - antenna) * ((o_d - dr.dot(n_d, antenna)) / dr.select(den != 0, den, 1.0))
                raw[k] = dr.select(receive, shadow, b)
        n_mirrors = dr.select(receive, depth, level)
        corners, plane, part_plane = raw, plane_o, levels[0][1]
        for i in range(1, depth + 1):
            pick = level == i
            part_plane = (dr.select(pick, levels[i][1][0], part_plane[0]), dr.select(pick, levels[i][1][1], part_plane[1]))
        for index in reversed(range(depth)):
            use = index < n_mirrors
            corners = [dr.select(use, _reflect_point(c, mirrors[index]), c) for c in corners]
            reflected = _reflect_plane(plane, mirrors[index])
            plane = (dr.select(use, reflected[0], plane[0]), dr.select(use, reflected[1], plane[1]))
        poly = [self._lines(antenna, c, m) for c in corners]
        half = self._half_plane(part_plane, plane, corners, antenna, box, m)
        if depth > 0:
            other = self._receive_half(rec, antenna, (n_d, o_d), plane_o, self._corners(part), mirrors, box, m)
            half = [tuple(dr.select(receive, a, b) for a, b in zip(pa, pb)) for pa, pb in zip(other, half)]
        return [poly, half]

    def _half_plane(self, part_plane, occ_plane, points, antenna, box, m):
        """Where an occluder (plane ``occ_plane``, corners ``points``) lies between the antenna and
        the part's plane ``part_plane``, along the rays from ``antenna`` (all in one frame): the
        half-plane of the aim plane whose rays meet the occluder's plane on the antenna's side of
        the part's plane, as a quadrilateral far beyond ``box`` (its centre and half-size in
        lattice lines); the whole plane, or none of it, where the corners lie on one side.

        For a ray ``w`` meeting the occluder's plane ``n_o . x = d_o`` at ``q``, the part's plane
        ``n_p . x = d_p`` has ``f(q) = n_p . q - d_p`` with ``f(q) (n_o . w) = G . w``,
        ``G = f(a) n_o + (d_o - n_o . a) n_p``: linear in ``w``, so affine in the lattice lines;
        ``n_o . w`` keeps one sign over the occluder, eq. (T6)."""
        (n_p, d_p), (n_o, d_o) = part_plane, occ_plane
        f_a = dr.dot(n_p, antenna) - d_p
        front, behind = mi.Bool(False), mi.Bool(False)
        for corner in points:
            side = dr.select(f_a >= 0, 1.0, -1.0) * (dr.dot(n_p, corner) - d_p)
            front |= side > CROSSING_TOLERANCE
            behind |= side < -CROSSING_TOLERANCE
        g = f_a * n_o + (d_o - dr.dot(n_o, antenna)) * n_p
        sign = dr.select((dr.dot(n_o, points[0] - antenna) >= 0) == (f_a >= 0), 1.0, -1.0)
        return self._quad(g, sign, antenna, front & behind, front | ~behind, box, m)

    def _receive_half(self, rec, antenna, last_plane, occ_plane, points, mirrors, box, m):
        """Where an occluder (real plane ``occ_plane``, corners ``points``) hides the last part's
        points from the antenna: the half-plane of the aim plane whose points' last-part points
        lie on the far side of the occluder's plane from the antenna (so that the way back to the
        antenna crosses it), as :meth:`_half_plane` builds it. With the last part's unfolded plane
        ``n_u . y = o_u`` and the occluder's unfolded ``n_b . y = o_b``, the side of a point ``y``
        reached by ``w`` is ``(n_b . y - o_b)(n_u . w) = G . w``,
        ``G = (n_b . a - o_b) n_u + (o_u - n_u . a) n_b``."""
        (n_d, o_d), (n_o, d_o) = last_plane, occ_plane
        f_a = dr.dot(n_d, antenna) - o_d                         # the antenna's side of the last part
        front, behind = mi.Bool(False), mi.Bool(False)           # the occluder's corners, that side first
        for corner in points:
            side = dr.select(f_a >= 0, 1.0, -1.0) * (dr.dot(n_d, corner) - o_d)
            front |= side > CROSSING_TOLERANCE
            behind |= side < -CROSSING_TOLERANCE
        unfolded_last, unfolded_occ = (n_d, o_d), (n_o, d_o)
        for mirror in reversed(mirrors):
            unfolded_last = _reflect_plane(unfolded_last, mirror)
            unfolded_occ = _reflect_plane(unfolded_occ, mirror)
        (n_u, o_u), (n_b, o_b) = unfolded_last, unfolded_occ
        g = (dr.dot(n_b, antenna) - o_b) * n_u + (o_u - dr.dot(n_u, antenna)) * n_b
        side_a = dr.dot(n_o, antenna) - d_o                      # the antenna's side of the occluder (real)
        w = rec.unfolded - antenna
        sign = -dr.select(side_a >= 0, 1.0, -1.0) * dr.select(dr.dot(n_u, w) >= 0, 1.0, -1.0)
        return self._quad(g, sign, antenna, front & behind, front | ~behind, box, m)

    def _quad(self, g, sign, antenna, crossing, whole, box, m):
        """The half-plane ``sign (G . w) >= 0`` of the aim plane (``w`` from ``antenna`` to the aim
        point) as a quadrilateral with one side on its line and the others far beyond ``box``; where
        not ``crossing``, the whole plane (``whole``) or none of it."""
        fp = self.fp
        track, look = mi.Array3f64(*fp.track.tolist()), mi.Array3f64(*fp.look.tolist())
        a = sign * dr.dot(g, track) * (fp.spacing_azimuth / m)
        b = sign * dr.dot(g, look) * (fp.spacing_range / m)
        c = sign * dr.dot(g, mi.Array3f64(*fp.origin.tolist()) + look * fp.range_min - antenna)
        (cx, cy), size = box
        norm = dr.sqrt(a * a + b * b)
        crossing &= norm > 0
        safe = dr.select(crossing, norm, 1.0)
        ux, uy = dr.select(crossing, a / safe, 1.0), dr.select(crossing, b / safe, 0.0)
        reach = 2.0 * size
        dist = dr.select(crossing, (a * cx + b * cy + c) / safe, dr.select(whole, reach, -reach))
        dist = dr.clip(dist, -reach, reach)
        px, py, far = cx - dist * ux, cy - dist * uy, 4.0 * size
        return [(px + far * uy, py - far * ux), (px - far * uy, py + far * ux),
                (px - far * uy + far * ux, py + far * ux + far * uy), (px + far * uy + far * ux, py - far * ux + far * uy)]

    @staticmethod
    def _box(corners, bounds):
        """The rectangle ``bounds`` brought in to one line beyond the polygon ``corners``."""
        xs, ys = [c[0] for c in corners], [c[1] for c in corners]
        lo_x, hi_x, lo_y, hi_y = xs[0], xs[0], ys[0], ys[0]
        for x_, y_ in zip(xs[1:], ys[1:]):
            lo_x, hi_x = dr.minimum(lo_x, x_), dr.maximum(hi_x, x_)
            lo_y, hi_y = dr.minimum(lo_y, y_), dr.maximum(hi_y, y_)
        return (dr.maximum(bounds[0], lo_x - 1.0), dr.minimum(bounds[1], hi_x + 1.0),
                dr.maximum(bounds[2], lo_y - 1.0), dr.minimum(bounds[3], hi_y + 1.0))

    def _area_centroid(self, rec, antenna, ends, n_live, m, cell, nu, depth, normal, centre):
        """Area and centroid of a piece on the facet (float64, about ``centre``) from its
        ``n_live`` boundary segments in the local buffers ``ends`` (x0, y0, x1, y1)."""
        def step(i, twice_area, moment):
            a, b = (self._tile(rec, antenna, antenna, self._aim_point(ends[0 + e][i], ends[1 + e][i], m), cell, nu, depth)[0]
                    for e in (0, 2))
            cross = dr.dot(mi.Array3f64(normal), dr.cross(a - centre, b - centre))
            return i + 1, twice_area + cross, moment + (a + b - 2.0 * centre) * cross
        _, twice_area, moment = dr.while_loop((mi.UInt32(0), mi.Float64(0.0), mi.Array3f64(0.0)),
                                              lambda i, t, mo: i < n_live, step, label="cell_area")
        return 0.5 * twice_area, centre + moment / (3.0 * dr.select(twice_area != 0, twice_area, 1.0))

    # ------------------------------------------------------------------ the returns
    def cell_returns(self, ctx, rec, bounds, chain, occluders, depth: int) -> None:
        """The returns of one launch of pieces (:meth:`cells`): their physical optics
        (:meth:`cell_po`) and, at the first bounce on rough parts, their scatterers
        (:meth:`cell_clutter`)."""
        self.cell_po(ctx, rec, bounds, chain, occluders, depth)
        if self.clutter_on and depth == 0:
            self.cell_clutter(ctx, rec, bounds, chain, occluders)

    def cell_po(self, ctx, rec, bounds, chain, occluders, depth: int) -> None:
        """Per pulse, the PO integral over each piece, eqs. (T6), (PO1), (PO2), (PO5).

        Gordon's edge form: per boundary segment ``a`` of the piece on the last part (counter-
        clockwise about its normal ``N``), ``j (N . (u_t x a)) / (k |u_t|^2)`` times
        ``sinc(k u . a / 2)`` at the segment's midpoint, or split into its ends as (PO2) where its
        own ``|alpha|`` reaches the threshold; where the phase is flat over the piece
        (``(k |u_t|)^2 A`` below :data:`FLAT_PHASE`) one term, its area at its centroid. Every term
        is evaluated at its own point as the tile terms are (:meth:`_tile`: exact float64 legs, the
        amplitude and ``u = d - b`` there). The boundary is the chain's polygons' less the exact
        union of the occluders' cut-outs (:func:`sarmitsuba.tracing.cell_clip.boundary`); its live
        segments are gathered into local memory and integrated in a loop, so one copy of the
        term code serves any number of occluders."""
        n, nu = rec.n, mi.Array3f64(rec.n_unfolded)
        # segments run counter-clockwise about the part's own normal (its corners' order)
        normal = mi.Vector3f(dr.gather(mi.Array3f64, self.tables.parts.normal, rec.part))
        specular, count = dr.gather(mi.Float, self.tables.specular, rec.row), dr.gather(mi.UInt32, ctx["count"], rec.sub)
        cell = self._cell(ctx, rec.block)
        n_segments = packed_size(depth + 2, len(occluders), max(self.tables.parts.slots, 4))
        lane, slots = dr.arange(mi.UInt32, dr.width(rec.sub)), 3 * n_segments + 1
        paths = self.sums.path_buffers(dr.width(rec.sub) * slots * ctx["max_count"]) if self.exact else None
        ctx["evaluated"] += slots * int(dr.sum(count)[0])

        # the piece on the aim plane as the reference position sees it: the cell and the last
        # part fixed on the surface, as the tiles are (T3); what the chain's earlier parts and
        # the occluders leave of it is each pulse's own
        reference = dr.gather(mi.Array3f64, ctx["reference"], rec.sub)
        centre = self._tile(rec, reference, reference, rec.aim, cell, nu, depth)[0]      # the tile's centre

        def piece(antenna):
            polygons, cutouts, m = self._polygons(ctx, rec, reference, antenna, bounds, chain, occluders, depth)
            ends, n_live = pack(polygons, cutouts)
            return (ends, n_live, m, *self._area_centroid(rec, reference, ends, n_live, m, cell, nu, depth, normal, centre))
        # a first-bounce piece without occluders is the same for every pulse: cut once
        shared = piece(reference) if depth == 0 and not occluders else None

        def body(q):
            pulse, antenna, lref, view = self._pulse(ctx, rec.sub, q)
            ends, n_live, m, area, centroid = shared if shared is not None else piece(antenna)
            active = self._in_beam(rec.aim, antenna, view) if self.aim_mask else mi.Bool(True)
            _, _, d_c, edges_c = self._tile(rec, reference, antenna, rec.aim, cell, nu, depth)
            u_c = d_c - mi.Vector3f(dr.normalize(antenna - centre))
            active &= area > 0
            regime = self._regime(rec, reference, antenna, cell, nu, depth, u_c, edges_c, normal, area, centroid, m)
            flat, (c_point, c_s, c_d, c_dist) = regime[2], regime[4]

            def term(point, s, d, factor, order, live, slot, rel=None):
                outgoing, dist = receive_leg(view, antenna, point, s)          # (J3)
                b = mi.Vector3f(outgoing / dist)
                cos_i, cos_b = -dr.dot(n, d), dr.dot(n, b)
                scale = (math.sqrt(math.pi) / self.lam) * (cos_i + cos_b) * specular \
                    * self.weight(self._d_first(depth, d, rec.first_hit, antenna), b, s, dist, lref, view)
                rel = s + dist - lref if rel is None else rel
                value = mi.Complex2f(0.0, scale) * rec.gamma * factor * self.carrier_phase(rel)
                live &= active & (cos_i > self.cos_grazing) & (s > 0)
                self.sums.deposit(ctx, pulse, depth, self.anchor(rel, lref), 0.0,
                                  [value * c for c in self.po_channels(rec, d, b, n, cos_i, depth)],
                                  order, live, paths, (lane * slots + slot) * ctx["max_count"] + q)

            c_rel = c_s + c_dist - lref
            term(c_point, c_s, c_d, mi.Complex2f(mi.Float(area), 0.0), mi.UInt32(SPECTRAL_ORDERS.index(1)), flat, 0, c_rel)

            def step(index):
                self._segment_terms(rec, reference, antenna, [b[index] for b in ends], m, cell, nu, depth, normal, regime,
                                    u_c, c_rel, term, index)
                return (index + 1,)
            dr.while_loop((mi.UInt32(0),), lambda i: i < n_live, step, label="cell_segments")
            return (q + 1,)

        dr.while_loop((mi.UInt32(0),), lambda q: q < count, body, label="cell_pulses")
        if paths is not None:
            self.sums.keep_paths(ctx, paths)

    def _segment_terms(self, rec, reference, antenna, segment, m, cell, nu, depth, normal, regime, u_c, c_rel, term, index):
        """The terms of one boundary segment ``(x0, y0, x1, y1)`` (:meth:`cell_po`): in the linear
        regime one at its midpoint, in the split regime the flux along the split tile edge at its
        ends (or its middle), each at its own point; ``index`` numbers its path slots."""
        k = self.k
        along_1, split_any, _, linear, (c_point, c_s, c_d, _), u_g, u_gt = regime
        x0, y0, x1, y1 = segment
        start, stop, middle = (self._tile(rec, reference, antenna, self._aim_point(x, y, m), cell, nu, depth)
                               for x, y in ((x0, y0), (x1, y1), (0.5 * (x0 + x1), 0.5 * (y0 + y1))))
        seg = mi.Vector3f(stop[0] - start[0])
        # the linear regime: one term per segment at its midpoint, the flux of u_t at the
        # centroid, the phase linear about it (exact for that phase, eq. (T6))
        g_lin = dr.dot(u_g, seg)
        flux_lin = dr.dot(normal, dr.cross(u_gt, seg)) / (k * dr.select(linear, dr.squared_norm(u_gt), 1.0))
        rel_lin = c_rel + mi.Float64(dr.dot(u_g, mi.Vector3f(middle[0] - c_point)))
        term(c_point, c_s, c_d, mi.Complex2f(0.0, flux_lin * self.sinc(0.5 * k * g_lin)),
             mi.UInt32(SPECTRAL_ORDERS.index(0)), linear, 3 * index + 1, rel_lin)
        # the split regime: the flux along the split tile edge, each term at its own point
        cut = dr.abs(0.5 * k * dr.dot(u_c, seg)) >= self.split_at
        for end in range(2):       # the stop (split) or the middle (sinc); the start (split)
            point, s, d, edges = start if end else (
                *(dr.select(cut, a, b) for a, b in zip(stop[:3], middle[:3])),
                [dr.select(cut, a, b) for a, b in zip(stop[3], middle[3])])
            u = d - mi.Vector3f(dr.normalize(antenna - point))
            v = dr.select(along_1, edges[0], edges[1])         # the tile's edge at the point
            up = dr.dot(u, v)
            flux = dr.dot(normal, dr.cross(v, seg)) / (k * dr.select(split_any & (up != 0), up, 1.0))
            g = dr.dot(u, seg)
            g_safe = dr.select(g != 0, g, 1.0)
            if end == 0:
                factor = dr.select(cut, mi.Complex2f(-flux / (k * g_safe), 0.0),
                                   mi.Complex2f(0.0, flux * self.sinc(0.5 * k * g)))
                order = dr.select(cut, mi.UInt32(SPECTRAL_ORDERS.index(-1)), mi.UInt32(SPECTRAL_ORDERS.index(0)))
                live = split_any
            else:
                factor = mi.Complex2f(flux / (k * g_safe), 0.0)
                order = mi.UInt32(SPECTRAL_ORDERS.index(-1))
                live = split_any & cut
            term(point, s, d, factor, order, live, 3 * index + 2 + end)

    def _regime(self, rec, reference, antenna, cell, nu, depth, u_c, edges_c, normal, area, centroid, m):
        """A piece's term form for one pulse, eq. (T6). Where the tile at the cell's centre would
        split an edge (``split_any``, (PO2); ``u_c`` and ``edges_c`` there), the flux runs along its edge of larger ``|alpha|``
        (``along_1``) and every term is evaluated at its own point, as the tiles' terms are; where
        it keeps both sincs, the piece's phase is taken as the linear one about its centroid (as
        the tile's sincs take it about the centre) and integrated exactly (Gordon, ``linear``), or
        as flat (one area term, ``flat``) where ``k |u_t| sqrt(A)`` is below :data:`FLAT_PHASE`.
        Returns ``(along_1, split_any, flat, linear, (point, s, d, distance) at the centroid, u
        there, its part in the plane)``."""
        k = self.k
        alpha = [0.5 * k * dr.dot(u_c, e) for e in edges_c]
        along_1 = dr.abs(alpha[0]) >= dr.abs(alpha[1])
        split_any = dr.maximum(dr.abs(alpha[0]), dr.abs(alpha[1])) >= self.split_at
        c_point, c_s, c_d, _ = self._tile(rec, reference, antenna, self._centroid_aim(centroid, rec, reference, nu, m, depth),
                                          cell, nu, depth)
        c_out = antenna - c_point
        c_dist = dr.norm(c_out)
        u_g = c_d - mi.Vector3f(c_out / c_dist)
        u_gt = u_g - normal * dr.dot(u_g, normal)
        flat = ~split_any & (k * dr.norm(u_gt) * dr.sqrt(dr.abs(mi.Float(area))) < FLAT_PHASE)
        return along_1, split_any, flat, ~split_any & ~flat, (c_point, c_s, c_d, c_dist), u_g, u_gt

    def _centroid_aim(self, centroid, rec, antenna, nu, m, depth):
        """The aim point whose unfolded ray from ``antenna`` meets the facet at ``centroid``."""
        unfolded = rec.unfolded + mi.Array3f64(self._unfolded_vector(rec, mi.Vector3f(centroid - rec.p64), depth))
        x, y = self._lines(antenna, unfolded, m)
        return self._aim_point(x, y, m)

    @staticmethod
    def _unfolded_vector(rec, v, depth):
        """``M^T v``: a scene vector in the unfolded frame."""
        if depth == 0:
            return v
        return mi.Vector3f(dr.dot(rec.m1, v), dr.dot(rec.m2, v), dr.dot(rec.m3, v))

    def cell_clutter(self, ctx, rec, bounds, chain, occluders) -> None:
        """Per pulse, the rough surface's scatterers inside each first-bounce piece, eqs. (C), (T6).

        The piece is the one :meth:`cell_po` integrates, as the sub-aperture's reference position
        sees it (the view in which whole tiles count theirs, so pieces and tiles hand out every
        scatterer exactly once). Its cells are those of the box of its boundary on the facet; a
        scatterer counts where its projection onto the aim plane lies in every polygon of the
        chain and in no occluder's cut-out (:func:`sarmitsuba.tracing.cell_clip.inside`)."""
        rough = dr.compress(dr.gather(mi.UInt32, self.tables.clutter_kind, rec.row) > 0)
        if not dr.width(rough):
            return
        rec = dr.gather(type(rec), rec, rough)
        bounds = [dr.gather(mi.Float64, b, rough) for b in bounds]
        chain = [dr.gather(mi.UInt32, c, rough) for c in chain]
        occluders = [tuple(dr.gather(mi.UInt32, a, rough) for a in o) for o in occluders]
        reference = dr.gather(mi.Array3f64, ctx["reference"], rec.sub)
        polygons, cutouts, m = self._polygons(ctx, rec, reference, reference, bounds, chain, occluders, 0)
        lattice = self._clutter_lattice(ctx, rec, 0)
        c, cells = self.fp.scatterer_spacing, lattice["cells"]
        u_axis, v_axis = (mi.Array3f64(a) for a in lattice["axes"])
        normal = mi.Array3f64(rec.n)
        lo_u, hi_u, lo_v, hi_v = mi.Float64(math.inf), mi.Float64(-math.inf), mi.Float64(math.inf), mi.Float64(-math.inf)
        ends, n_live = pack(polygons, cutouts)

        def grow(i, lo_u, hi_u, lo_v, hi_v):
            for x, y in ((ends[0][i], ends[1][i]), (ends[2][i], ends[3][i])):
                w = self._aim_point(x, y, m) - reference
                offset = reference + w * (dr.dot(normal, rec.p64 - reference) / dr.dot(normal, w)) - rec.p64
                du, dv = dr.dot(offset, u_axis) / c, dr.dot(offset, v_axis) / c
                lo_u, hi_u, lo_v, hi_v = dr.minimum(lo_u, du), dr.maximum(hi_u, du), dr.minimum(lo_v, dv), dr.maximum(hi_v, dv)
            return i + 1, lo_u, hi_u, lo_v, hi_v
        _, lo_u, hi_u, lo_v, hi_v = dr.while_loop((mi.UInt32(0), lo_u, hi_u, lo_v, hi_v), lambda i, *_: i < n_live, grow,
                                                  label="cell_box")
        some = lo_u <= hi_u
        iu0 = mi.Int32(dr.floor(mi.Float64(cells.pu) + dr.select(some, lo_u, 0.0)))
        iv0 = mi.Int32(dr.floor(mi.Float64(cells.pv) + dr.select(some, lo_v, 0.0)))
        nu = dr.maximum(mi.Int32(dr.floor(mi.Float64(cells.pu) + dr.select(some, hi_u, 0.0))) - iu0 + 1, 1)
        nv = dr.maximum(mi.Int32(dr.floor(mi.Float64(cells.pv) + dr.select(some, hi_v, 0.0))) - iv0 + 1, 1)

        def held(du, dv):
            """Whether the scatterer ``(du, dv)`` cells from the hit lies in the piece."""
            x, y = self._lines(reference, rec.p64 + u_axis * (c * mi.Float64(du)) + v_axis * (c * mi.Float64(dv)), m)
            return inside(x, y, polygons, cutouts)

        lattice.update(cells=FootprintCells(cells.pu, cells.pv, iu0, iv0, mi.UInt32(nu),
                                            dr.select(some, mi.UInt32(nu * nv), 0), 0.0, 0.0, 0.0, 0.0),
                       inside=held, raise_by=1.0)
        self.clutter(ctx, rec, 0, lattice)
