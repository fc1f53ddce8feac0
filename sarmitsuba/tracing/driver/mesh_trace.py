"""Scattering anchored to the mesh: one launch of sub-apertures, bounce order by bounce order
(docs/physics.md (M1)-(M8)).

For each sub-aperture of a :class:`sarmitsuba.tracing.driver.launches.Launch`, seen from its reference
position ``A``:

1. the first bounce's chains are the parts in the beam's reach (every part, in spotlight or on a
   curved track) that face ``A``;
2. :func:`sarmitsuba.tracing.visibility.lit_pieces.lit_pieces` cuts each chain's exact region into the
   patches' pieces and aims rays at their corners: lit, transmit-lit, mixed;
3. mixed pieces are cut exactly against the occluders their rays met
   (:func:`sarmitsuba.tracing.visibility.occlusion.lit_boundaries`);
4. every lit piece's boundary becomes term lanes (:mod:`sarmitsuba.tracing.integration.patch_terms`), with the
   segments that two stable whole neighbours share left out (their terms cancel), and every pulse
   of the sub-aperture evaluates and deposits them; rough parts add their scatterers;
5. *discovery*: rays reflected specularly from points of the transmit-lit pieces name the parts
   they meet next; each new (chain, part) pair is a chain of the next bounce order.

Nothing here depends on the ray lattice: the pieces are fixed on the mesh, the chains' regions
exact, and the discovery rays start on the pieces.
"""
from __future__ import annotations

import dataclasses
import threading

import drjit as dr
import numpy as np

from ...core.arrays import row_norm
from ..discovery.chains import Chains, image_source, region_lines, unfold
from ..discovery.specular import arriving_views, discover, discovery_subdivision, rays_beyond
from ..fused import geometry_kernels
from ..fused.matching import RowMatcher
from ..fused.segments import DEVICE_ROWS as SEGMENT_ROWS, SegmentKinds
from ..integration.catalogue import catalogued
from ..integration.patch_terms import AREA, NEAR_SPECULAR, OPEN_START, SINC, SPLIT_START, PatchTerms
from ..loops import RECORDING
from ..visibility.lit_pieces import RECHECKS, LitPieces, classify, lit_pieces, recheck, spread_occluders
from ..visibility.motion import endpoint_rates, line_rates
from ..visibility.occlusion import ClippedPieces, clip_mixed, replace_pieces
from ..mesh.polygons import REPEAT_DISTANCE, edge_lines
from .stages import StageClock
from ..timing import charged_to
from ..integration.surface_clutter import ClutterKernel
from ..integration.edges import find_wedges, segment_wedges
from ..integration.truncation import ground_parts, on_rim, rim_edges, without_rims
from ..integration.term_lanes import build_lanes, cancel_shared, kd_tree_pairs, scatterer_lanes, segments
from ..mesh.patches import Pieces, Surfaces
from ..integration.physical_optics import SINC_REGIME, split_threshold
from ..visibility.rays import PathVisibility, Rays

__all__ = ["MeshTracer", "STABLE_MARGIN", "REACH_MARGIN"]

#: A whole piece is *stable* (never near the specular direction within its sub-aperture) where all
#: three views (first, reference and last pulse) see ``k |u_t| D`` at least this many times
#: :data:`~sarmitsuba.tracing.integration.patch_terms.NEAR_SPECULAR`: the margin covers the pulses between them.
STABLE_MARGIN = 1.5
#: Extra reach [m] of the beam's along-track span beyond its first nulls, for rounding.
REACH_MARGIN = 1.0
#: Boundaries move with the antenna within a sub-aperture (eq. (M8)).
MOVING = True
#: A boundary segment whose end would move farther than this many patch sizes across its
#: sub-aperture (two nearly parallel lines meeting there) stays frozen (docs/physics.md (M8)).
MOVE_LIMIT = 4.0
#: The deepest order's share of a launch's carried power (``_carried``) from which it looks for
#: rays beyond that order (``rays_beyond``): the share at which ``analysis.orders.depth_warning``
#: warns of orders left out (``DEEPEST_SHARE``).
BEYOND_SHARE = 0.10


class MeshTracer:
    """The mesh-anchored tracer of one acquisition (configuration fixed at construction).

    Parameters
    ----------
    scene : mitsuba.Scene
    surfaces : Surfaces
    returns : sarmitsuba.tracing.integration.returns.Returns
        Per-pulse helpers and the accumulator (shared with the tube kernel).
    params : RadarParameters
    settings : TraceSettings
    patch : float
        Patch size [m] (:attr:`sarmitsuba.scene.trace_inputs.RayFootprint.patch_size`).
    straight : bool
        A straight stripmap track: pieces are cut only within the beam's along-track span.
    bbox : (float64 [3], float64 [3])
        The scene's bounding box (for the beam's reach).
    """

    def __init__(self, scene, surfaces: Surfaces, returns, params, settings, patch: float, straight: bool, bbox,
                 table=None, cell: float = 0.0):
        self.surfaces, self.returns = surfaces, returns
        self.rays = Rays(scene, surfaces)
        self.visibility = PathVisibility(scene, surfaces)
        self.alpha_s = split_threshold(params.bandwidth, params.frequency)
        self.terms = PatchTerms(returns, self.alpha_s)
        self.table, self.cell, self.seed = table, cell, settings.seed
        self.clutter = ClutterKernel(returns, cell, self.terms.arrival) if returns.clutter_on else None
        self.rough_row = (table.clutter[:, 0] > 0) if table is not None and table.clutter is not None else None
        self.k = returns.k
        self.depth = settings.depth
        self.cancel = settings.cancel_interior
        #: The Dr.Jit kernels of the stages that have one (docs/design.md section 10.1).
        self.fused = settings.geometry == "fused"
        self.kernels = geometry_kernels(settings.geometry)
        self.segment_kinds = SegmentKinds(surfaces, self.k, self.alpha_s, STABLE_MARGIN * NEAR_SPECULAR, SINC_REGIME,
                                          (SPLIT_START, SINC, OPEN_START)) if self.fused else None
        # a ground shape's free rims are truncations: no PO rim terms, no edge currents (M10)
        ground = ground_parts(scene, surfaces, settings.ground_shapes)
        wedges = find_wedges(surfaces) if returns.diffraction or np.any(ground) else None
        self.rim = rim_edges(surfaces, wedges, ground) if np.any(ground) else None
        self.wedges = (wedges if self.rim is None else without_rims(wedges, self.rim)) if returns.diffraction else None
        self.patch = patch
        self.straight = straight
        self.track = np.asarray(returns.fp.track, float)
        self.subdivision = discovery_subdivision(surfaces, patch)
        self.moving = MOVING
        #: Pieces without collinear corners (the geometric derivatives' tracers, docs/physics.md (AD4)).
        self.simplify = False
        #: Moving shapes: a :class:`~sarmitsuba.tracing.visibility.moving_shapes.TargetMotion` that moves
        #: their lanes per pulse (docs/physics.md (V2)); None: the scene holds still.
        self.target = None
        #: The scatterer catalogue's configuration (:class:`~sarmitsuba.tracing.integration.catalogue.LaneCatalogue`,
        #: docs/physics.md (SC1)-(SC4)); None: the catalogue is off.
        self.catalogue = None
        self._static = None
        self._body_box = None
        # launches on several host threads share these caches: the first to need one builds it
        # while the others wait (a 1 M-triangle mesh's pieces are 0.6 GB, built once)
        self._cache_lock = threading.Lock()
        self.bbox = (np.asarray(bbox[0], float), np.asarray(bbox[1], float))

    # ------------------------------------------------------------------ one launch
    def __call__(self, ctx: dict, launch) -> dict:
        """Trace ``launch``'s sub-apertures, depositing every pulse's returns into ``ctx``; returns
        this launch's counters ``{"pieces": [per order], "lanes": [...], "chains": [...], "casts": int,
        "overflow": int}`` (``overflow``: rows the fused kernels left to the NumPy stages). Launches
        may run on several host threads at once (:func:`~sarmitsuba.tracing.driver.trace.trace`)."""
        clock = StageClock(self.depth + 1)           # (the last row: the deposit, kernel.Kernel)
        with charged_to(clock):                      # the casts below time themselves
            return self._orders(ctx, launch, clock)

    def _orders(self, ctx: dict, launch, clock: StageClock) -> dict:
        """:meth:`__call__`'s bounce orders, timed by ``clock``."""
        reference = launch.reference
        views = self._views(launch)
        rx = self._receiver(launch)
        stats = {"pieces": [], "lanes": [], "chains": [], "samples": [], "carried": [], "discovery": []}
        match = RowMatcher() if self.fused else None
        casts_before = self.rays.casts + self.visibility.casts
        with clock("first bounce"):
            lit = self._first_bounce(launch)
        for depth in range(self.depth):
            clock.order = depth
            if depth > 0:
                casts = self.rays.casts
                with clock("discovery"):
                    chains = discover(self.surfaces, lit, reference, self.rays, self.subdivision, self.patch,
                                          self.depth)
                stats["discovery"].append(self.rays.casts - casts)
                if len(chains) == 0:
                    break
                with clock("visibility"):
                    lit = lit_pieces(self.surfaces, chains, reference[chains.sub], self.rays, self.visibility,
                                     self.patch, self._span(launch, chains) if self.straight else None,
                                     None if rx is None else rx[0][chains.sub], self.kernels.pieces_of)
            stats["chains"].append(len(lit.chains))
            stats["samples"].append(lit.samples)
            with clock("energy"):
                stats["carried"].append(self._carried(lit, reference, launch.count))
            with clock("lanes"):
                lanes, table, clipped, cut_lit, lane_chain = self._lanes(lit, views, depth, reference, clock, rx, match)
                if self.catalogue is not None:           # the scatterer catalogue's lanes (SC1)
                    lanes = catalogued(self.catalogue, self.surfaces, lanes, lane_chain, lit.chains, launch, rx,
                                       np.asarray(lanes.kind) == AREA)
            stats["pieces"].append(int(cut_lit.lit.sum()))
            stats["lanes"].append(len(lanes))
            with clock("terms"), RECORDING:
                self.terms(ctx, lanes, table, depth)
                if self.clutter is not None:
                    scatterers = scatterer_lanes(self.surfaces, lit.chains, lit.pieces.select(cut_lit.lit), clipped,
                                                 lit.pieces, self.rough_row, self.table, self.cell, self.seed,
                                                 reference, depth)
                    self.clutter(ctx, scatterers, depth)
                # the terms' deposits are side effects that the next kernel launch would run:
                # evaluated here, so that their time is this stage's
                dr.eval()
                dr.sync_thread()
            with clock("terms"):                     # this order's histogram, for its energy (D6)
                self.returns.sums.order_done(ctx, depth)
        stats["overflow"] = match.overflow if match is not None else 0
        carried = stats["carried"]
        stats["beyond"] = None                       # unknown: not checked
        if len(carried) < self.depth:                # no chains past an order: nothing beyond
            stats["beyond"] = 0
        elif self.depth > 1 and carried[-1] >= BEYOND_SHARE * sum(carried):
            with clock("discovery"):
                stats["beyond"] = rays_beyond(self.surfaces, lit, reference, self.rays, self.subdivision, self.patch)
        stats["casts"] = self.rays.casts + self.visibility.casts - casts_before
        stats["seconds"] = clock.seconds
        return stats

    def _carried(self, lit: LitPieces, reference: np.ndarray, count: np.ndarray) -> float:
        """The power the transmitted wave carries into a bounce order's transmit-lit pieces, times
        their pulses: ``sum Omega |r_1 .. r_d|^2`` (solid angle from the image source, the earlier
        bounces' reflection coefficients at the reference position): the energy check of the
        chains (as the tubes' ``carried_power_per_order``)."""
        s, chains = self.surfaces, lit.chains
        reached = np.flatnonzero(lit.sent > 0)              # mixed pieces by the share of their samples
        if len(reached) == 0 or self.table is None:
            return 0.0
        chain = lit.pieces.region[reached]
        area, centroid2, _, _ = lit.pieces.geometry_of(reached, self.kernels.moments)   # (kept for _lanes)
        point = s.to_world(chains.last[chain], centroid2)
        source = image_source(chains, reference[chains.sub])[chain]
        leg = point - source
        distance = row_norm(leg)                              # (np.linalg.norm's sum, bitwise)
        omega = lit.sent[reached] * area * np.abs(np.einsum("mi,mi->m", leg, np.take(s.normal, np.take(chains.last, chain),
                                                                                    axis=0))) / distance ** 3
        first = chains.unfolded(point, chain) - np.take(reference, np.take(chains.sub, chain), axis=0)
        first /= row_norm(first)[:, None]
        # with Jones matrices, the mean over the transmit channels of TE and TM carried through
        # (as the tubes' |J|^2 / 2 where the planes of incidence agree); else the channel's own r
        tables = (self.table.table_te, self.table.table_tm) if self.returns.polarimetric else (self.table.table,)
        powers = [np.ones(len(chain)) for _ in tables]
        for i in range(int(chains.order.max(initial=0))):
            live = chains.order[chain] > i
            window = np.maximum(np.take(chains.parts[:, i], chain), 0)
            d = np.einsum("mji,mj->mi", np.take(chains.lin[:, i], chain, axis=0), first)
            cos = np.abs(np.einsum("mi,mi->m", np.take(s.normal, window, axis=0), d))
            for power, table in zip(powers, tables):
                index = np.clip(np.round(cos * (table.shape[1] - 1)).astype(np.int64), 0, table.shape[1] - 1)
                factor = np.abs(table[s.row[window], index]) ** 2 * self.table.specular[s.row[window]] ** 2
                power *= np.where(live, factor, 1.0)
        carried = float(np.sum(omega * (sum(powers) / len(powers)) * count[chains.sub[chain]]))
        # a power the float32 kernels could not hold is 0 there (flush to zero), and 0 here
        return carried if carried >= np.finfo(np.float32).tiny else 0.0

    def _views(self, launch, antenna: np.ndarray | None = None, reference: np.ndarray | None = None) -> np.ndarray:
        """float64 [n_s, 3, 3]: each sub-aperture's first pulse, reference position and last pulse
        (of the transmitter, or of ``antenna`` [n_b, 3] with its ``reference`` [n_s, 3])."""
        antenna = launch.antenna if antenna is None else antenna
        first = antenna[launch.first]
        last = antenna[launch.first + launch.count - 1]
        return np.stack([first, launch.reference if reference is None else reference, last], axis=1)

    def _receiver(self, launch):
        """Bistatic (docs/physics.md (B2)): ``(receiver reference [n_s, 3], receiver views [n_s, 3,
        3])``, where each sub-aperture's return legs end and its receiver's first, reference and
        last positions; None when the transmitter receives."""
        if launch.receiver_reference is None:
            return None
        return launch.receiver_reference, self._views(launch, launch.received, launch.receiver_reference)

    # ------------------------------------------------------------------ the first bounce
    def _first_pieces(self) -> tuple[Pieces, np.ndarray]:
        """Every part cut into its pieces once per acquisition (a part is its own first-bounce
        region), sorted by their centroids' coordinate along the track (with those coordinates)."""
        with self._cache_lock:
            if self._static is None:
                self._static = self._sorted_pieces()
        return self._static

    def _sorted_pieces(self) -> tuple[Pieces, np.ndarray]:
        """:meth:`_first_pieces`, built."""
        s = self.surfaces
        pieces = self.kernels.pieces_of(s.polygon, s.n_corners, self.patch)
        _, centroid, _, _ = pieces.geometry(self.kernels.moments)
        along = s.to_world(pieces.region, centroid) @ self.track
        order = np.argsort(along, kind="stable")
        return pieces.select(order), along[order]

    def _first_bounce(self, launch) -> LitPieces:
        """The first bounce: per sub-aperture the pieces of every part within the beam's
        along-track reach (every part, in spotlight or on a curved track), one chain per part
        that does not hold the reference position in its plane, and what the antenna sees."""
        s = self.surfaces
        pieces, along = self._first_pieces()
        n_sub = launch.n_subapertures
        if self.straight:
            lo, hi = self._reach(launch, 0)
            first = np.searchsorted(along, lo - self.patch)
            last = np.searchsorted(along, hi + self.patch)
        else:
            first, last = np.zeros(n_sub, np.int64), np.full(n_sub, len(along))
        size = last - first
        sub = np.repeat(np.arange(n_sub), size)
        rows = np.repeat(first, size) + np.arange(int(size.sum())) - np.repeat(np.cumsum(size) - size, size)
        part = pieces.region[rows]
        height = np.einsum("ni,ni->n", s.normal[part], launch.reference[sub]) - s.offset[part]
        # the inside of a closed body: dark whatever the rays would say (docs/physics.md (M4))
        inside = (s.seen_side[part] * height < 0) & ~self._in_body_box(part, launch.reference[sub])
        held = (np.abs(height) > 0) & ~inside
        rows, sub, part = rows[held], sub[held], part[held]
        keys, chain = _unique_keys(sub * s.n_parts + part, n_sub * s.n_parts)
        parts = np.full((len(keys), self.depth), -1, np.int64)
        parts[:, 0] = keys % s.n_parts
        chains = unfold(s, parts, np.zeros(len(keys), np.int64), keys // s.n_parts)
        selected = pieces.select(rows)
        selected = Pieces(chain.reshape(-1), selected.cell, selected.whole, selected.border, selected.polygon,
                          selected.count, selected.patch)
        rx = None if launch.receiver_reference is None else launch.receiver_reference[chains.sub]
        return classify(s, chains, selected, launch.reference[chains.sub], self.rays, self.visibility, receiver=rx)

    def _in_body_box(self, part: np.ndarray, points: np.ndarray) -> np.ndarray:
        """bool: ``points`` [m, 3] lie in the bounding box of ``part``'s body (where its inside
        is not known to be hidden)."""
        with self._cache_lock:
            if self._body_box is None:
                self._body_box = self._body_boxes()
        body, lo, hi = self._body_box
        b = body[part]
        return np.all((points >= lo[b]) & (points <= hi[b]), axis=1)

    def _body_boxes(self):
        """``(body of each part, lo, hi)``: each body's bounding box (:meth:`_in_body_box`)."""
        s = self.surfaces
        body = np.unique(s.body if s.body is not None else s.shape_id, return_inverse=True)[1]
        corners = s.to_world(np.arange(s.n_parts), s.polygon)
        lo = np.full((int(body.max(initial=-1)) + 1, 3), np.inf)
        hi = np.full_like(lo, -np.inf)
        np.minimum.at(lo, body, corners.min(axis=1))
        np.maximum.at(hi, body, corners.max(axis=1))
        return body, lo, hi

    def _reach(self, launch, depth: int) -> tuple[np.ndarray, np.ndarray]:
        """Along-track interval ``[lo, hi]`` [m] of ``track . y`` that the beam of each
        sub-aperture's pulses reaches, for unfolded points ``y`` at most the scene's far corner plus
        ``depth`` box diagonals away (a multi-bounce path's unfolded length), from that
        sub-aperture's own pulses (not the launch's: the reach, and so the image, does not depend
        on how sub-apertures are grouped into launches)."""
        lo_b, hi_b = self.returns.beam_sines
        corners = np.array(np.meshgrid(*zip(*self.bbox), indexing="ij")).reshape(3, -1).T
        far = np.linalg.norm(corners[None] - launch.antenna[:, None], axis=2).max(axis=1)
        far = np.maximum.reduceat(far, launch.first) if len(launch.first) else far[:0]
        far += depth * float(np.linalg.norm(self.bbox[1] - self.bbox[0]))
        along = launch.antenna @ self.track
        first = along[launch.first]
        last = along[launch.first + launch.count - 1]
        return (np.minimum(first, last) + lo_b * far - REACH_MARGIN,
                np.maximum(first, last) + hi_b * far + REACH_MARGIN)

    def _span(self, launch, chains: Chains):
        lo, hi = self._reach(launch, int(chains.order.max(initial=0)))
        return np.broadcast_to(self.track, (len(chains), 3)), lo[chains.sub], hi[chains.sub]

    # ------------------------------------------------------------------ discovery
    # ------------------------------------------------------------------ term lanes
    def _lanes(self, lit: LitPieces, views: np.ndarray, depth: int, reference: np.ndarray, clock=None, rx=None,
               match=None):
        """The term lanes and piece table of a bounce order's lit pieces, whole, border and cut
        from mixed ones (:func:`sarmitsuba.tracing.visibility.occlusion.clip_mixed`), eq. (M5);
        ``rx``: bistatic, :meth:`_receiver`'s receiver reference and views (B2); ``match``: the
        device matcher of the segments and junctions that cancel (None: the k-d tree reference)."""
        s, chains = self.surfaces, lit.chains
        if self.simplify:                   # (AD4): outlines whose corners do not hang on rounding
            lit = dataclasses.replace(lit, pieces=lit.pieces.simplified())
        antenna = reference[chains.sub]
        receiver, rx_views = (None, views) if rx is None else (rx[0][chains.sub], rx[1])
        clock = clock or StageClock()
        with clock("clipping"):
            was_lit = lit.lit
            lit, clipped, spread = self._clip(lit, antenna, receiver)
        if len(spread):
            # the neighbours that no occluder cuts stay what they were: wholly lit (their shared
            # edges cancel) or dark (wholly in the occluders' shadows: no piece left)
            full = lit.pieces.geometry_of(clipped.piece, self.kernels.moments)[0]
            uncut = clipped.piece[np.isin(clipped.piece, spread) & (clipped.area >= (1.0 - 1e-12) * full)]
            back = np.concatenate([uncut, np.setdiff1d(spread, clipped.piece)])
            clipped = replace_pieces(clipped, ClippedPieces.empty(), uncut)
            lit_now, mixed_now = lit.lit.copy(), lit.mixed.copy()
            lit_now[back], mixed_now[back] = was_lit[back], False
            lit = dataclasses.replace(lit, lit=lit_now, mixed=mixed_now)
        if self.simplify:
            clipped = clipped.merged(REPEAT_DISTANCE * max(self.patch, 1.0))
        pieces_rows = np.flatnonzero(lit.lit)
        pieces = lit.pieces.select(pieces_rows)
        cut = lit.pieces.select(clipped.piece)
        region = np.concatenate([pieces.region, cut.region])
        part = chains.last[region]
        area, centroid2, second, diagonal = (np.concatenate([a, b]) for a, b in zip(
            lit.pieces.geometry_of(pieces_rows, self.kernels.moments),
            (clipped.area, clipped.centroid, clipped.second, clipped.diagonal)))
        centroid = s.to_world(part, centroid2)
        stable = self._stable(chains, region, centroid, diagonal, views, rx_views)
        n = len(pieces)
        seg_piece, p2, q2 = segments(pieces, stable[:n], self.cancel)
        seg_piece = np.concatenate([seg_piece, n + clipped.owner])
        p2, q2 = np.concatenate([p2, clipped.start]), np.concatenate([q2, clipped.end])
        if self.cancel:
            shared = cancel_shared(s, chains, region[seg_piece], p2, q2, stable[seg_piece], match or kd_tree_pairs)
            kept = np.flatnonzero(~shared)              # (np.take: row gathers, not boolean masks)
            seg_piece, p2, q2 = np.take(seg_piece, kept), np.take(p2, kept, axis=0), np.take(q2, kept, axis=0)
        if self.rim is not None:
            # a stable piece's segments on a truncation rim: the continuing plane cancels them (M10)
            kept = np.flatnonzero(~(np.take(stable, seg_piece) & on_rim(s, self.rim, np.take(part, seg_piece), p2, q2)))
            seg_piece, p2, q2 = np.take(seg_piece, kept), np.take(p2, kept, axis=0), np.take(q2, kept, axis=0)
        seg_region = np.take(region, seg_piece)
        kind = self._kinds(chains, seg_region, np.take(part, seg_piece), p2, q2, views, rx_views)
        # every boundary segment of the pieces that may need their area term
        rows = np.flatnonzero(~stable[:n])
        t_piece, t_start, t_end, _ = pieces.edges(rows)
        unstable_cut = ~stable[n:][clipped.owner]
        table_segments = (np.concatenate([t_piece, n + clipped.owner[unstable_cut]]),
                          np.concatenate([t_start, clipped.start[unstable_cut]]),
                          np.concatenate([t_end, clipped.end[unstable_cut]]))
        geometry = (region, part, centroid, centroid2, area, second, diagonal)
        motion = None
        if self.moving:
            # the term lanes' segments and the area terms' segments in one pass (their pieces overlap)
            all_rows = np.concatenate([pieces_rows, clipped.piece])
            piece_of = np.concatenate([seg_piece, table_segments[0]])
            with clock("rates"):
                p_rate, q_rate, last = self._motion(lit, all_rows[piece_of], piece_of >= n,
                                                    np.concatenate([p2, table_segments[1]]),
                                                    np.concatenate([q2, table_segments[2]]), views,
                                                    None if rx is None else rx[1])
            m = len(seg_piece)
            motion = (p_rate[:m], q_rate[:m], last)
            table_segments = table_segments + (p_rate[m:], q_rate[m:])
        edges = segment_wedges(s, self.wedges, part[seg_piece], p2, q2) if self.wedges is not None else None
        lanes, table = build_lanes(s, chains, geometry, stable, (seg_piece, p2, q2), kind, table_segments, reference, depth,
                                   self.cancel, motion, edges, match)
        lane_chain = np.take(region, lanes.piece.astype(np.int64))
        if self.target is not None:
            lanes = self.target.moved(lanes, s, chains, lane_chain, reference)
        return lanes, table, clipped, lit, lane_chain

    def _clip(self, lit: LitPieces, antenna: np.ndarray, receiver: np.ndarray | None = None):
        """The mixed pieces of ``lit`` cut against their occluders, the occluders spread to the
        neighbours their shadows run into and rechecked from the cut regions (eq. (M4)): the new
        ``lit``, the :class:`ClippedPieces` and the rows made mixed by the spread (``receiver``:
        bistatic, where the return legs end, (B2))."""
        s = self.surfaces
        kernels = self.kernels
        clipped = clip_mixed(s, lit, antenna, receiver=receiver, kernels=kernels)
        lit, spread = spread_occluders(lit, clipped)
        if len(spread):
            clipped = replace_pieces(clipped, clip_mixed(s, lit, antenna, spread, receiver, kernels), spread)
        checked = clipped
        for _ in range(RECHECKS):
            blockers, changed = recheck(s, lit, checked, antenna, self.rays, self.visibility, receiver)
            if len(changed) == 0:
                break
            lit = dataclasses.replace(lit, blockers=blockers)
            checked = clip_mixed(s, lit, antenna, changed, receiver, kernels)
            clipped = replace_pieces(clipped, checked, changed)
            # the next pass samples only the pieces cut again: another's samples, region and hits
            # are this pass's, and every occluder they met is known now
        return lit, clipped, spread

    def _motion(self, lit: LitPieces, rows, cut, p2, q2, views, rx_views=None):
        """The rates of boundary segments' ends [m per m of travel] toward each sub-aperture's last
        pulse, eq. (M8): ``(p_rate, q_rate, last)`` for :func:`build_lanes` (``rows`` the segments'
        rows of ``lit.pieces``, ``cut`` whether a segment bounds a piece cut against occluders).
        Bistatic (``rx_views``, (B2)): the return legs' shadows move with the receiver, which
        flies its own line in the same time."""
        s, chains, pieces = self.surfaces, lit.chains, lit.pieces
        a, b = views[chains.sub, 1], views[chains.sub, 2]
        step = np.linalg.norm(b - a, axis=1)
        chain = pieces.region[rows]
        p_rate, q_rate = np.zeros_like(p2), np.zeros_like(q2)
        # segments that can move: on a chain's mirrored windows (order >= 2) or an occluder's shadow
        need = np.flatnonzero((step[chain] > 0) & (cut | (chains.order[chain] > 0)))
        if len(need) == 0:
            return p_rate, q_rate, b
        held, owner = np.unique(rows[need], return_inverse=True)          # the pieces, and each segment's
        owners, table, rates = [], [], []

        def add(piece, lines, line_rates_):
            for out, value in zip((owners, table, rates), _unit_rows(piece, lines, line_rates_)):
                out.append(value)

        poly, count = pieces.select(held).polygons()
        add(np.arange(len(held)), edge_lines(poly, count), None)            # the piece's own edges
        region = pieces.region[held]
        windowed = np.flatnonzero(chains.order[region] > 0)
        if len(windowed):
            used, at = np.unique(region[windowed], return_inverse=True)
            lines_a = region_lines(s, chains.select(used), a[used])[0]
            lines_b = region_lines(s, chains.select(used), b[used])[0]
            add(windowed, lines_a[at], line_rates(lines_a, lines_b, step[used])[at])
        shaded = np.unique(owner[cut[need]])
        if len(shaded):
            pair, key = lit.blockers.rows(held[shaded], mesh=True)
            leg, occluder = key // s.n_parts, key % s.n_parts
            c = region[shaded[pair]]
            receivers = None if rx_views is None else (rx_views[chains.sub, 1], rx_views[chains.sub, 2])
            lines_a, lines_b = self.kernels.shadow_lines(s, chains, c, occluder, leg, a, b, receivers=receivers)
            add(shaded[pair], lines_a, line_rates(lines_a, lines_b, step[c]))
        p_rate[need], q_rate[need] = endpoint_rates(p2[need], q2[need], owner, np.concatenate(owners),
                                                    np.concatenate(table), np.concatenate(rates))
        # an end that would move farther than MOVE_LIMIT patches within the sub-aperture sits where two lines
        # are nearly parallel: its first-order motion spans changes of the piece's shape that it
        # cannot describe (the end runs past the piece's corners), so the segment stays frozen
        travel = np.maximum(np.linalg.norm(views[:, 0] - views[:, 1], axis=1), np.linalg.norm(views[:, 2] - views[:, 1], axis=1))
        reach = travel[chains.sub[chain]]
        wild = np.maximum(_norm2(p_rate), _norm2(q_rate)) * reach > MOVE_LIMIT * pieces.patch
        p_rate[wild], q_rate[wild] = 0.0, 0.0
        return p_rate, q_rate, b

    def _stable(self, chains, chain, points, diagonal, views, rx_views) -> np.ndarray:
        """:meth:`_never_specular` with ``views``, ``rx_views`` [n_sub, 3, 3] per sub-aperture: the
        fused kernel's (:class:`~sarmitsuba.tracing.fused.segments.SegmentKinds`) or the reference's."""
        if self.segment_kinds is not None and len(chain) >= SEGMENT_ROWS:
            return self.segment_kinds.never_specular(chains, chain, points, diagonal, views, rx_views)
        at = np.take(chains.sub, chain)
        return self._never_specular(chains, chain, points, diagonal, np.take(views, at, axis=0),
                                    np.take(rx_views, at, axis=0))

    def _kinds(self, chains, chain, part, p2, q2, views, rx_views) -> np.ndarray:
        """:meth:`_split_kinds` with ``views``, ``rx_views`` per sub-aperture, as :meth:`_stable`."""
        if self.segment_kinds is not None and len(chain) >= SEGMENT_ROWS:
            return self.segment_kinds.split_kinds(chains, chain, part, p2, q2, views, rx_views)
        at = np.take(chains.sub, chain)
        return self._split_kinds(chains, chain, part, p2, q2, np.take(views, at, axis=0), np.take(rx_views, at, axis=0))

    def _never_specular(self, chains, chain, points, diagonal, views, rx_views) -> np.ndarray:
        """bool: every pulse of the sub-aperture sees each piece at least ``STABLE_MARGIN
        NEAR_SPECULAR / (k D)`` off the specular direction. ``u_t`` moves almost linearly with the
        antenna along its track, so its smallest size over the sub-aperture is the distance from 0
        to the path it draws through the three views (first, reference and last pulse; the
        return toward ``rx_views``, the receiver's, (B2))."""
        normal = np.take(self.surfaces.normal, np.take(chains.last, chain), axis=0)
        u_t = []
        arriving = arriving_views(chains, chain, points, views)
        for v in range(3):
            d = arriving[v]
            b = rx_views[:, v] - points
            b /= row_norm(b)[:, None]
            u = d - b
            u_t.append(u - normal * np.einsum("mi,mi->m", u, normal)[:, None])
        smallest = np.minimum(_distance_to_segment(u_t[0], u_t[1]), _distance_to_segment(u_t[1], u_t[2]))
        return self.k * smallest * diagonal >= STABLE_MARGIN * NEAR_SPECULAR

    def _split_kinds(self, chains, chain, part, p2, q2, views, rx_views) -> np.ndarray:
        """Each segment's kind over its sub-aperture (docs/physics.md (PO2), (T3)): split when all
        three views see ``|alpha| >= SINC_REGIME`` with one sign and some see ``>= alpha_s``; its
        sinc when none reaches ``alpha_s``; decided per pulse otherwise."""
        s = self.surfaces
        m = len(part)
        world = s.to_world(np.concatenate([part, part, part]), np.concatenate([0.5 * (p2 + q2), q2, p2]))
        mid = world[:m]
        edge = world[m:2 * m] - world[2 * m:]
        alphas = []
        arriving = arriving_views(chains, chain, mid, views)
        for v in range(3):
            d = arriving[v]
            b = rx_views[:, v] - mid
            b /= row_norm(b)[:, None]
            alphas.append(0.5 * self.k * np.einsum("mi,mi->m", d - b, edge))
        alpha = np.stack(alphas, axis=1)
        size = np.abs(alpha)
        same = np.all(np.sign(alpha) == np.sign(alpha[:, :1]), axis=1)
        split = same & (size.min(axis=1) >= SINC_REGIME) & (size.max(axis=1) >= self.alpha_s)
        sinc = size.max(axis=1) < self.alpha_s
        return np.where(split, SPLIT_START, np.where(sinc, SINC, OPEN_START))


def _unique_keys(keys: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(keys, return_inverse=True)`` of int64 ``keys`` in ``[0, size)``: by a table of
    ``size`` flags where that is not much larger than the keys (no sort), else by ``np.unique``."""
    if size > max(8 * len(keys), 1 << 20):
        return np.unique(keys, return_inverse=True)
    present = np.zeros(size, bool)
    present[keys] = True
    rank = np.cumsum(present) - 1
    return np.flatnonzero(present), rank[keys]


def _unit_rows(piece: np.ndarray, lines: np.ndarray, rates: np.ndarray | None):
    """The half-plane rows of ``lines`` float64 [k, H, 3] whose ``(a, b)`` is unit (not padding):
    ``(piece[k] int64 [r], lines float64 [r, 3], rates float64 [r, 3])`` in row-major order,
    ``rates`` [k, H, 3] gathered alike (0 when None). Gathered by flat index with np.take (a
    ``[k, j]`` fancy gather is several times slower on this NumPy)."""
    flat_lines = lines.reshape(-1, 3)
    real = np.abs(np.sqrt(flat_lines[:, 0] * flat_lines[:, 0] + flat_lines[:, 1] * flat_lines[:, 1]) - 1.0) < 1e-6
    flat = np.flatnonzero(real)
    return (np.take(piece, flat // max(lines.shape[1], 1)), np.take(flat_lines, flat, axis=0),
            np.take(rates.reshape(-1, 3), flat, axis=0) if rates is not None else np.zeros((len(flat), 3)))


def _distance_to_segment(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from the origin to each segment ``a -> b`` (float64 [m, 3] each)."""
    ab = b - a
    t = np.clip(-np.einsum("mi,mi->m", a, ab) / np.maximum(np.einsum("mi,mi->m", ab, ab), 1e-300), 0.0, 1.0)
    return row_norm(a + t[:, None] * ab)


def _norm2(x: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(x, axis=1)`` of float64 [m, 2] rows (the same sum, bitwise equal)."""
    return np.sqrt(x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1])



