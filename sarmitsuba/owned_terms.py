"""Owned regions in the kernel: the first-bounce PO integral over each owned piece of a part,
per pulse (docs/physics.md (T6), (PO1), (PO2), (PO5)); a part of
:class:`sarmitsuba.returns.Returns`, with ``lit_regions = owned``.

The host plans which records own which pieces (:func:`sarmitsuba.owned_regions.plan`, the
readable NumPy reference of the partition); here each piece is cut to its part as each pulse sees
it, in lattice lines on the aim plane, and integrated as a flux through its boundary segments.
"""
from __future__ import annotations

from dataclasses import dataclass

import math

import drjit as dr
import mitsuba as mi
import numpy as np

from .clutter_lattice import FootprintCells
from .deposit import SPECTRAL_ORDERS
from .device import device_array
from .facets import MAX_PART_VERTICES, scene_parts
from .shadow_plan import CROSSING_TOLERANCE
from .owned_regions import plan as owned_plan

__all__ = ["OwnedTerms", "PartTable", "FLAT_PHASE"]

#: Below this ``(k |u_t|)^2 A`` a piece's phase is flat: one term, its area at its centroid (the
#: neglected second moment is below about a 24th of it), eq. (T6).
FLAT_PHASE = 2.5e-3
#: Boundary segments of an owned piece: the part's corner slots and the rectangle's four sides.
_SEGMENTS = MAX_PART_VERTICES + 4
_INVALID = 0xFFFFFFFF
# flags of kernel.Flags (repeated here: the kernel imports this module through returns)
_SPLIT_1, _SPLIT_2, _UNDECIDED_1, _UNDECIDED_2, _OWNED = 32, 64, 256, 512, 1024


@dataclass
class PartTable:
    """The convex parts of a scene's meshes (:func:`sarmitsuba.facets.scene_parts`) on the device:
    each triangle's part (INVALID for degenerate ones), the corner slots (``part *
    MAX_PART_VERTICES + slot``), unit normals and plane offsets (float64), and the corners again
    (NumPy, for the host's plan)."""

    triangle_part: mi.UInt32
    corners: mi.Array3f64
    normal: mi.Array3f64
    offset: mi.Float64
    vertices: np.ndarray

    @staticmethod
    def of(scene) -> "PartTable":
        parts = scene_parts(scene)
        corners = parts.vertices.reshape(-1, 3)
        part = np.where(parts.triangle_part < 0, _INVALID, parts.triangle_part.astype(np.int64))  # int32 cannot hold INVALID
        return PartTable(mi.UInt32(part.astype(np.uint32)),
                         mi.Array3f64(*(corners[:, c].copy() for c in range(3))),
                         mi.Array3f64(*(parts.normal[:, c].copy() for c in range(3))),
                         mi.Float64(parts.offset.copy()), parts.vertices)


class OwnedTerms:
    """The owned-region methods of :class:`sarmitsuba.returns.Returns` (which provides the tables,
    the footprint, ``_tile``, ``_pulse``, ``weight``, ``po_channels``, the accumulator)."""

    def _owned(self, ctx, rec):
        """Plan the first-bounce records' owned regions on the host (:func:`owned_regions.plan`),
        flag the owned records (their tiles are not evaluated, and no neighbour cancels against
        them) and return the pieces, then the occluders cut out of them, then the pairs of
        occluders whose overlap is added back: a list of ``(records, bounds, occluding parts)``
        (none, one or two per piece), or None when no record owns pieces."""
        launch = ctx["launch"]
        part = rec.part.numpy().astype(np.int64)
        part[part == _INVALID] = -1
        views = np.stack([launch.reference, launch.antenna[launch.first],
                          launch.antenna[launch.first + launch.count - 1]], 1)
        result = owned_plan(rec.sub.numpy(), part, rec.block.numpy(), rec.lattice.numpy(), launch.blocks,
                            self.tables.parts.vertices, views, self.fp)
        if not result.owned.any():
            return None
        rec.flags |= dr.select(mi.Bool(result.owned), mi.UInt32(_OWNED), mi.UInt32(0))
        dr.eval(rec.flags)
        launches = []
        for piece, occluders in ((slice(None), ()), (result.cut_piece, (result.cut_part,)),
                                 (result.pair_piece, result.pair_parts)):
            records, bounds = result.record[piece], result.bounds[piece]
            if len(records) == 0:
                continue
            pieces = dr.gather(type(rec), rec, device_array(mi.UInt32, records.astype(np.uint32)))
            bounds = [device_array(mi.Float64, bounds[:, c]) for c in range(4)]
            occluders = tuple(device_array(mi.UInt32, o.astype(np.uint32)) for o in occluders)
            dr.eval(pieces, bounds, occluders)
            launches.append((pieces, bounds, occluders))
        return launches

    def _corner_lines(self, ctx, rec, antenna, part, corners=None):
        """The ``part`` as the pulse at ``antenna`` sees it on the aim plane, in the lattice lines
        of the record's tube size, counted from the scene's lattice origin (as
        :func:`owned_regions.lattice_lines`): the corner slots' ``(x, y)`` and the tube size ``m``.
        ``corners``: the part's corner slots (:meth:`_corners`), when already gathered."""
        m = mi.Float64(dr.gather(mi.UInt32, ctx["block_m"], rec.block))
        return [self._lines(antenna, c, m) for c in corners or self._corners(part)], m

    def _corners(self, part):
        """The corner slots of ``part`` (float64 points, :data:`MAX_PART_VERTICES` of them)."""
        return [dr.gather(mi.Array3f64, self.tables.parts.corners, part * MAX_PART_VERTICES + k)
                for k in range(MAX_PART_VERTICES)]

    def _lines(self, antenna, point, m):
        """The scene ``point`` seen from ``antenna`` on the aim plane, in lattice lines of tube size
        ``m``: ``(x, y)``, float64 (the central projection of (T3): lines stay lines)."""
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

    @staticmethod
    def _clip(p, q, t0, t1):
        """Narrow ``[t0, t1]`` to where ``p t <= q`` (Liang and Barsky 1984); ``p = 0``: all or nothing."""
        safe = dr.select(p != 0, p, 1.0)
        t0 = dr.select(p < 0, dr.maximum(t0, q / safe), t0)
        t1 = dr.select(p > 0, dr.minimum(t1, q / safe), t1)
        return t0, dr.select((p == 0) & (q < 0), -1.0, t1)

    def _polygons(self, ctx, rec, antenna, bounds, occluders):
        """The convex polygons whose intersection is the piece (the record's part, the rectangle
        ``bounds``, the ``occluders``' projections) as the pulse at ``antenna`` sees them, in
        lattice lines of tube size ``m``: ``(polygons, m)``, each a list of ``(x, y)`` corners."""
        corners, m = self._corner_lines(ctx, rec, antenna, rec.part)
        x0, x1, y0, y1 = self._box(corners, bounds)
        polygons = [corners, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]]
        if occluders:               # the part's centre and half-size in lattice lines, plus 2
            xs, ys = [p[0] for p in corners], [p[1] for p in corners]
            centre = (sum(xs[1:], xs[0]) / len(xs), sum(ys[1:], ys[0]) / len(ys))
            size = mi.Float64(2.0)
            for x_, y_ in corners:
                size = dr.maximum(size, dr.maximum(dr.abs(x_ - centre[0]), dr.abs(y_ - centre[1])) + 2.0)
        for occluder in occluders:
            points = self._corners(occluder)
            polygons.append(self._corner_lines(ctx, rec, antenna, occluder, points)[0])
            polygons.append(self._in_front(rec, antenna, occluder, points, (centre, size), m))
        return polygons, m

    def _in_front(self, rec, antenna, occluder, points, box, m):
        """Where the ``occluder`` lies between the pulse at ``antenna`` and the record's part: the
        half-plane of the aim plane (lattice lines of tube size ``m``) whose rays meet the
        occluder's plane on the antenna's side of the part's plane, as a quadrilateral with one
        side on that line and the others far beyond the part's projection (``box``: its centre
        and half-size plus 2, in lattice lines): the whole plane, or none of it, where the
        occluder's corner slots ``points`` lie on one side of the part's plane. An occluder that crosses the
        part's plane hides the part only with its side in front, eq. (T6).

        For a ray ``w`` (from the antenna to an aim point) meeting the occluder's plane
        ``n_o . x = d_o`` at ``q``, the part's plane ``n_p . x = d_p`` has ``f(q) = n_p . q - d_p``
        with ``f(q) (n_o . w) = G . w``, ``G = f(a) n_o + (d_o - n_o . a) n_p``: a linear form in
        ``w``, so affine in the lattice lines; ``n_o . w`` keeps one sign over the occluder."""
        fp, parts = self.fp, self.tables.parts
        n_p, d_p = dr.gather(mi.Array3f64, parts.normal, rec.part), dr.gather(mi.Float64, parts.offset, rec.part)
        n_o, d_o = dr.gather(mi.Array3f64, parts.normal, occluder), dr.gather(mi.Float64, parts.offset, occluder)
        f_a = dr.dot(n_p, antenna) - d_p
        front, behind = mi.Bool(False), mi.Bool(False)       # corners clearly on either side
        for corner in points:
            side = dr.select(f_a >= 0, 1.0, -1.0) * (dr.dot(n_p, corner) - d_p)
            front |= side > CROSSING_TOLERANCE
            behind |= side < -CROSSING_TOLERANCE
        g = f_a * n_o + (d_o - dr.dot(n_o, antenna)) * n_p
        sign = dr.select((dr.dot(n_o, points[0] - antenna) >= 0) == (f_a >= 0), 1.0, -1.0)
        track, look = mi.Array3f64(*fp.track.tolist()), mi.Array3f64(*fp.look.tolist())
        a = sign * dr.dot(g, track) * (fp.spacing_azimuth / m)
        b = sign * dr.dot(g, look) * (fp.spacing_range / m)
        c = sign * dr.dot(g, mi.Array3f64(*fp.origin.tolist()) + look * fp.range_min - antenna)
        (cx, cy), size = box
        norm = dr.sqrt(a * a + b * b)
        crossing = (norm > 0) & front & behind
        safe = dr.select(crossing, norm, 1.0)
        ux, uy = dr.select(crossing, a / safe, 1.0), dr.select(crossing, b / safe, 0.0)
        # the signed distance of the part's centre from the line, kept within twice its size
        reach = 2.0 * size
        dist = dr.select(crossing, (a * cx + b * cy + c) / safe, dr.select(front | ~behind, reach, -reach))
        dist = dr.clip(dist, -reach, reach)
        px, py, far = cx - dist * ux, cy - dist * uy, 4.0 * size
        return [(px + far * uy, py - far * ux), (px - far * uy, py + far * ux),
                (px - far * uy + far * ux, py + far * ux + far * uy), (px + far * uy + far * ux, py - far * ux + far * uy)]

    def _piece(self, ctx, rec, antenna, bounds, occluders):
        """The boundary segments of the piece (:meth:`_polygons`) as the pulse at ``antenna`` sees
        it: ``(segments, m)``."""
        polygons, m = self._polygons(ctx, rec, antenna, bounds, occluders)
        return self._segments(polygons), m

    @staticmethod
    def _orientation(corners):
        """+1 where the corners run counter-clockwise in ``(x, y)``, -1 where clockwise."""
        (px0, py0), area = corners[0], mi.Float64(0.0)
        for (ax, ay), (bx, by) in zip(corners, corners[1:] + corners[:1]):
            area += (ax - px0) * (by - py0) - (ay - py0) * (bx - px0)
        return dr.select(area >= 0, 1.0, -1.0)

    def _segments(self, polygons):
        """The boundary of the intersection of convex polygons (lists of ``(x, y)`` corners in
        lattice lines, either orientation, repeated corners allowed) as segments, all in the
        first polygon's orientation: each polygon's edges clipped to all the others (Cyrus and
        Beck 1978). Returns ``[(x0, y0, x1, y1, exists)]``, one per edge slot in order. An edge
        lying on a same-direction edge of an earlier polygon is left to that one (no double
        count)."""
        signs = [self._orientation(c) for c in polygons]
        out = []
        for n, corners in enumerate(polygons):
            flip = signs[n] != signs[0]          # traverse every boundary in the first's orientation
            for a, b in zip(corners, corners[1:] + corners[:1]):
                ax, ay = dr.select(flip, b[0], a[0]), dr.select(flip, b[1], a[1])
                dx, dy = dr.select(flip, a[0], b[0]) - ax, dr.select(flip, a[1], b[1]) - ay
                t0, t1 = mi.Float64(0.0), mi.Float64(1.0)
                keep = (dx != 0) | (dy != 0)
                for other, (sign, clip) in enumerate(zip(signs, polygons)):
                    if other == n:
                        continue
                    for (cx, cy), (ex, ey) in zip(clip, clip[1:] + clip[:1]):
                        fx, fy = ex - cx, ey - cy
                        p = -sign * (fx * dy - fy * dx)
                        q = sign * (fx * (ay - cy) - fy * (ax - cx))
                        if other < n:
                            keep &= ~((p == 0) & (q == 0) & (sign * signs[0] * (fx * dx + fy * dy) > 0))
                        t0, t1 = self._clip(p, q, t0, t1)
                out.append((ax + t0 * dx, ay + t0 * dy, ax + t1 * dx, ay + t1 * dy, keep & (t1 > t0)))
        return out

    @staticmethod
    def _box(corners, bounds):
        """The piece's rectangle ``bounds`` with its unbounded sides brought in to one line beyond
        the part's projection ``corners``."""
        xs, ys = [c[0] for c in corners], [c[1] for c in corners]
        lo_x, hi_x, lo_y, hi_y = xs[0], xs[0], ys[0], ys[0]
        for x_, y_ in zip(xs[1:], ys[1:]):
            lo_x, hi_x = dr.minimum(lo_x, x_), dr.maximum(hi_x, x_)
            lo_y, hi_y = dr.minimum(lo_y, y_), dr.maximum(hi_y, y_)
        return (dr.maximum(bounds[0], lo_x - 1.0), dr.minimum(bounds[1], hi_x + 1.0),
                dr.maximum(bounds[2], lo_y - 1.0), dr.minimum(bounds[3], hi_y + 1.0))

    @staticmethod
    def _area_centroid(ends, normal, centre):
        """Area and centroid of a piece from its boundary segments ``(a, b, exists)`` on the facet
        (float64, about the tube's centre ``centre``)."""
        twice_area, moment = mi.Float64(0.0), mi.Array3f64(0.0)
        for a, b, exists in ends:
            cross = dr.select(exists, dr.dot(mi.Array3f64(normal), dr.cross(a - centre, b - centre)), 0.0)
            twice_area += cross
            moment += (a + b - 2.0 * centre) * cross
        return 0.5 * twice_area, centre + moment / (3.0 * dr.select(twice_area != 0, twice_area, 1.0))

    def owned_returns(self, ctx, rec, bounds, occluders=()) -> None:
        """The returns of one launch of owned pieces (:meth:`_owned`): their physical optics
        (:meth:`owned_po`) and, on rough parts, their scatterers (:meth:`owned_clutter`)."""
        self.owned_po(ctx, rec, bounds, occluders)
        if self.clutter_on:
            self.owned_clutter(ctx, rec, bounds, occluders)

    def owned_po(self, ctx, rec, bounds, occluders=()) -> None:
        """Per pulse, the PO integral over each owned piece, eqs. (T6), (PO1), (PO2), (PO5).

        The piece is the rectangle ``bounds`` of the record's lattice lines cut to its part, both
        as the pulse sees them (the part's corners projected onto the aim plane from the pulse's
        antenna, :meth:`_corner_lines`). With one of ``occluders`` (a part in front, per piece)
        the integral over the piece cut to the occluder's projection too (its side in front of the
        part's plane, :meth:`_in_front`) is subtracted instead:
        the occluder's shadow on the piece as that pulse sees it; with two, the integral over
        their overlap there is added back (inclusion and exclusion). Its integral is Gordon's edge
        form: per boundary segment ``a`` (counter-clockwise about the part's normal ``N``), ``j (N . (u_t x a)) / (k |u_t|^2)``
        times ``sinc(k u . a / 2)`` at the segment's midpoint, or split into its ends as (PO2)
        (a side of the rectangle where the record's tile splits that edge, a part edge where its
        own ``|alpha|`` reaches the threshold). Every term is evaluated at its own point as the
        tile terms are (:meth:`_tile`: exact float64 legs, the amplitude and ``u = d - b``
        there). Where the phase is flat over the piece (``(k |u_t|)^2 A`` below
        :data:`FLAT_PHASE`) the piece returns one term, its area at its centroid. First bounce only.
        """
        k, n, nu, flags = self.k, rec.n, mi.Array3f64(rec.n_unfolded), rec.flags
        normal = mi.Vector3f(dr.gather(mi.Array3f64, self.tables.parts.normal, rec.part))
        specular, count = dr.gather(mi.Float, self.tables.specular, rec.row), dr.gather(mi.UInt32, ctx["count"], rec.sub)
        cell, decided = self._cell(ctx, rec.block), [(flags & bit) != 0 for bit in (_SPLIT_1, _SPLIT_2)]
        open_ = [(flags & bit) != 0 for bit in (_UNDECIDED_1, _UNDECIDED_2)]
        n_segments = _SEGMENTS + (MAX_PART_VERTICES + 4) * len(occluders)
        lane, slots, sign = dr.arange(mi.UInt32, dr.width(rec.sub)), 2 * n_segments + 1, (-1.0) ** len(occluders)
        paths = self.sums.path_buffers(dr.width(rec.sub) * slots * ctx["max_count"]) if self.exact else None
        ctx["evaluated"] += slots * int(dr.sum(count)[0])

        def body(q):
            pulse, antenna, lref, steer = self._pulse(ctx, rec.sub, q)
            active = self._in_beam(rec.aim, antenna) if self.aim_mask else mi.Bool(True)
            split, centre, u_c = self.pulse_split(rec, antenna, cell, nu, 0, decided, open_)
            segments, m = self._piece(ctx, rec, antenna, bounds, occluders)
            # each segment's ends on the facet (point, unfolded length, direction, tile edges)
            ends = [(self._tile(rec, antenna, self._aim_point(x0, y0, m), cell, nu, 0),
                     self._tile(rec, antenna, self._aim_point(x1, y1, m), cell, nu, 0))
                    for x0, y0, x1, y1, _ in segments]
            area, centroid = self._area_centroid([(a[0], b[0], seg[4]) for (a, b), seg in zip(ends, segments)],
                                                 normal, centre)
            active &= area > 0
            u_t = u_c - normal * dr.dot(u_c, normal)
            flat = ~split[0] & ~split[1] & ((k * k) * dr.squared_norm(u_t) * mi.Float(area) < FLAT_PHASE)

            def term(point, s, d, factor, order, live, slot):
                """Deposit ``j scale factor`` of a term at the facet point ``point`` (its unfolded
                length ``s``, incoming direction ``d``)."""
                outgoing = antenna - point
                dist = dr.norm(outgoing)
                b = mi.Vector3f(outgoing / dist)
                cos_i, cos_b = -dr.dot(n, d), dr.dot(n, b)
                scale = (math.sqrt(math.pi) / self.lam) * (cos_i + cos_b) * specular \
                    * self.weight(d, b, s, dist, lref, steer)
                rel = s + dist - lref
                value = mi.Complex2f(0.0, sign * scale) * rec.gamma * factor * self.carrier_phase(rel)
                live &= active & (cos_i > self.cos_grazing) & (s > 0)
                self.sums.deposit(ctx, pulse, 0, self.anchor(rel, lref), 0.0,
                                  [value * c for c in self.po_channels(rec, d, b, n, cos_i, 0)],
                                  order, live, paths, (lane * slots + slot) * ctx["max_count"] + q)

            # the flat piece: its area at its centroid (slot 0)
            w = centroid - antenna
            s_f = dr.norm(w)
            term(centroid, s_f, mi.Vector3f(w / s_f), mi.Complex2f(mi.Float(area), 0.0),
                 mi.UInt32(SPECTRAL_ORDERS.index(1)), flat, 0)
            for index, ((x0, y0, x1, y1, exists), (start, stop)) in enumerate(zip(segments, ends)):
                seg = mi.Vector3f(stop[0] - start[0])
                # a side of the rectangle takes its split from the record's tile, a part edge its own
                side = MAX_PART_VERTICES <= index < _SEGMENTS
                along_x, along_y = side and index % 2 == 0, side and index % 2 == 1
                own = dr.abs(0.5 * k * dr.dot(u_c, seg)) >= self.split_at
                cut = split[0] if along_x else split[1] if along_y else own
                middle = self._tile(rec, antenna, self._aim_point(0.5 * (x0 + x1), 0.5 * (y0 + y1), m), cell, nu, 0)
                for end in range(2):       # the stop (split) or the middle (sinc); the start (split)
                    point, s, d, edges = start if end else (
                        *(dr.select(cut, a, b) for a, b in zip(stop[:3], middle[:3])),
                        [dr.select(cut, a, b) for a, b in zip(stop[3], middle[3])])
                    u = d - mi.Vector3f(dr.normalize(antenna - point))
                    u_t = u - normal * dr.dot(u, normal)
                    up = dr.dot(u, u_t)
                    flux = dr.dot(normal, dr.cross(u_t, seg)) / (k * dr.select(up != 0, up, 1.0))
                    g = dr.dot(u, seg)
                    g_safe = dr.select(g != 0, g, 1.0)
                    if end == 0:
                        factor = dr.select(cut, mi.Complex2f(-flux / (k * g_safe), 0.0),
                                           mi.Complex2f(0.0, flux * self.sinc(0.5 * k * g)))
                        order = dr.select(cut, mi.UInt32(SPECTRAL_ORDERS.index(-1)), mi.UInt32(SPECTRAL_ORDERS.index(0)))
                        live = exists & ~flat
                    else:
                        factor = mi.Complex2f(flux / (k * g_safe), 0.0)
                        order = mi.UInt32(SPECTRAL_ORDERS.index(-1))
                        live = exists & ~flat & cut
                    term(point, s, d, factor, order, live, 2 * index + 1 + end)
            return (q + 1,)

        dr.while_loop((mi.UInt32(0),), lambda q: q < count, body, label="owned_pulses")
        if paths is not None:
            self.sums.keep_paths(ctx, paths)

    def owned_clutter(self, ctx, rec, bounds, occluders=()) -> None:
        """Per pulse, the rough surface's scatterers inside each owned piece, eqs. (C), (T6).

        The piece is the one :meth:`owned_po` integrates, as the sub-aperture's reference position
        sees it (the view in which the whole tiles of (C) count theirs, so that pieces and tiles
        share every scatterer out exactly once). Its cells are those of the box of its boundary
        on the facet; a scatterer counts where its projection onto the aim plane lies in every
        polygon of the piece. An occluder's cut-out (``occluders``) subtracts the same
        scatterers, a pair adds them back, as :meth:`owned_po` does. The record's tile, sigma0's
        raise near grazing and the tile's own scatterers are not used."""
        rough = dr.compress(dr.gather(mi.UInt32, self.tables.clutter_kind, rec.row) > 0)
        if not dr.width(rough):
            return
        rec = dr.gather(type(rec), rec, rough)
        bounds = [dr.gather(mi.Float64, b, rough) for b in bounds]
        occluders = tuple(dr.gather(mi.UInt32, o, rough) for o in occluders)
        reference = dr.gather(mi.Array3f64, ctx["reference"], rec.sub)
        polygons, m = self._polygons(ctx, rec, reference, bounds, occluders)
        signs = [self._orientation(p) for p in polygons]
        lattice = self._clutter_lattice(ctx, rec, 0)
        c, cells = self.fp.scatterer_spacing, lattice["cells"]
        u_axis, v_axis = (mi.Array3f64(a) for a in lattice["axes"])
        normal = dr.gather(mi.Array3f64, self.tables.parts.normal, rec.part)
        lo_u, hi_u, lo_v, hi_v = mi.Float64(math.inf), mi.Float64(-math.inf), mi.Float64(math.inf), mi.Float64(-math.inf)
        for x0, y0, x1, y1, exists in self._segments(polygons):
            for x, y in ((x0, y0), (x1, y1)):           # the boundary's ends on the facet, in cells from the hit
                w = self._aim_point(x, y, m) - reference
                offset = reference + w * (dr.dot(normal, rec.p64 - reference) / dr.dot(normal, w)) - rec.p64
                du, dv = dr.dot(offset, u_axis) / c, dr.dot(offset, v_axis) / c
                lo_u, hi_u = dr.select(exists, dr.minimum(lo_u, du), lo_u), dr.select(exists, dr.maximum(hi_u, du), hi_u)
                lo_v, hi_v = dr.select(exists, dr.minimum(lo_v, dv), lo_v), dr.select(exists, dr.maximum(hi_v, dv), hi_v)
        some = lo_u <= hi_u
        iu0 = mi.Int32(dr.floor(mi.Float64(cells.pu) + dr.select(some, lo_u, 0.0)))
        iv0 = mi.Int32(dr.floor(mi.Float64(cells.pv) + dr.select(some, lo_v, 0.0)))
        nu = dr.maximum(mi.Int32(dr.floor(mi.Float64(cells.pu) + dr.select(some, hi_u, 0.0))) - iu0 + 1, 1)
        nv = dr.maximum(mi.Int32(dr.floor(mi.Float64(cells.pv) + dr.select(some, hi_v, 0.0))) - iv0 + 1, 1)

        def inside(du, dv):
            """Whether the scatterer ``(du, dv)`` cells from the hit lies in every polygon."""
            x, y = self._lines(reference, rec.p64 + u_axis * (c * mi.Float64(du)) + v_axis * (c * mi.Float64(dv)), m)
            held = mi.Bool(True)
            for sign, corners in zip(signs, polygons):
                for (ax, ay), (bx, by) in zip(corners, corners[1:] + corners[:1]):
                    held &= sign * ((bx - ax) * (y - ay) - (by - ay) * (x - ax)) >= 0
            return held

        lattice.update(cells=FootprintCells(cells.pu, cells.pv, iu0, iv0, mi.UInt32(nu),
                                            dr.select(some, mi.UInt32(nu * nv), 0), 0.0, 0.0, 0.0, 0.0),
                       inside=inside, sign=(-1) ** len(occluders), raise_by=1.0)
        self.clutter(ctx, rec, 0, lattice)

