"""The mesh tracer of a scene with moving shapes (docs/physics.md (V1)-(V3)).

:class:`MovingShapes` stands in for :attr:`sarmitsuba.tracing.driver.kernel.Kernel.mesh`. Each launch
holds one sub-aperture; before tracing it, every moving shape is put where the wave meets it
(V1): at the sub-aperture's reference time (the mean of its first and last pulses' transmit
times) plus the transmit leg's delay ``|A_ref - c_shape| / c`` from the reference position to
the shape's centre, not at the transmit time (no stop-and-hop for the target). The Mitsuba
scene's vertices are rewritten (the rays meet the moved shapes), the host geometry is rebuilt
from the float64 positions, and a :class:`~sarmitsuba.tracing.visibility.moving_shapes.TargetMotion`
moves every lane with its shape from pulse to pulse (V2). The shapes are put back after each
launch.
"""
from __future__ import annotations

import math
from time import perf_counter

import drjit as dr
import mitsuba as mi
import numpy as np

from scipy.spatial.transform import Rotation

from ...core.constants import SPEED_OF_LIGHT
from ...scene.motion import ShapeMotion
from ..mesh.facets import scene_meshes, set_vertices
from ..mesh.patches import moved_surfaces
from ..derivatives.lane_pairs import GeometryChange, align_terms, tangent_lanes, topology_change
from ..visibility.moving_shapes import TargetMotion
from .stages import STAGES

__all__ = ["MovingShapes", "shape_positions"]


def shape_positions(base: np.ndarray, velocity: np.ndarray, time: float, reference: np.ndarray,
                    angular: np.ndarray | None = None, centre: np.ndarray | None = None) -> np.ndarray:
    """Vertices float64 [n_v, 3] (m) of a shape given at ``base`` [n_v, 3] at mid-aperture, moving
    at ``velocity`` [3] (m/s) and turning at ``angular`` [3] (rad/s) about ``centre`` [3] (m; the
    middle of ``base``'s box by default), as the wave transmitted at ``time`` [s, from
    mid-aperture] from ``reference`` [3] meets it, ``tau = time + |reference - centre| / c`` later:
    ``centre + v tau + R(w tau) (base - centre)`` (V1), ``R`` the rotation by the angle vector
    ``w tau`` (``scipy.spatial.transform.Rotation.from_rotvec``)."""
    centre = 0.5 * (base.min(axis=0) + base.max(axis=0)) if centre is None else np.asarray(centre, float)
    tau = time + float(np.linalg.norm(np.asarray(reference, float) - centre)) / SPEED_OF_LIGHT
    moved = base - centre
    if angular is not None and np.any(angular):
        moved = Rotation.from_rotvec(np.asarray(angular, float) * tau).apply(moved)
    return centre + moved + np.asarray(velocity, float) * tau


#: The moving shapes' largest displacement [m] between the two geometries whose lanes are
#: differenced for their rates (V2): far below a patch, far above float32 rounding of the lanes.
RATE_DISPLACEMENT = 1e-3
#: Pairing tolerance of those lanes, in units of that displacement.
ALIGN_TOLERANCE = 50.0
#: The lanes' rates from the lit geometry differenced (V2); False: the rigid rates alone (V3),
#: which leave still the boundaries that a moving shape draws on still parts (its shadow, its
#: double bounce's footprint on the road). ``benchmarks/moving.py`` measures both.
DIFFERENCED = True


#: The farthest [m] a moving shape travels within one automatic sub-aperture (V2): the lanes'
#: rates are first-order and a boundary that a moving shape drags across a patch line changes the
#: pieces it cuts. Chosen from ``benchmarks/moving.py``.
MOVING_TRAVEL = 0.5


def moving_pulses(motion: ShapeMotion | None, prf: float) -> int | float:
    """The most pulses [count] an automatic sub-aperture may hold while the fastest moving shape
    travels at most :data:`MOVING_TRAVEL`; ``inf`` when nothing moves."""
    speed = 0.0 if motion is None else float(motion.speeds().max())
    if speed == 0 or not math.isfinite(MOVING_TRAVEL):
        return math.inf
    return max(1, math.floor(MOVING_TRAVEL * prf / speed))


def _recorded(tracer, ctx: dict, launch, clutter: bool = True) -> tuple[list, dict]:
    """Run ``tracer`` on ``launch`` without depositing: the ``(kind, lanes, pieces, depth)`` it
    would deposit, in order (``kind`` ``"terms"`` or ``"clutter"``; with ``clutter`` false no
    scatterers are formed: a geometry only differenced needs none), and its counters."""
    calls = []
    terms, kernel = tracer.terms, tracer.clutter
    tracer.terms = lambda ctx, lanes, pieces, depth: calls.append(("terms", lanes, pieces, depth))
    if kernel is not None:
        tracer.clutter = (lambda ctx, lanes, depth: calls.append(("clutter", lanes, None, depth))) if clutter else None
    try:
        return calls, tracer(ctx, launch)
    finally:
        tracer.terms, tracer.clutter = terms, kernel


def _with_rates(calls: list, moved: list, step: float, target: TargetMotion, reference: np.ndarray,
                shift: float = 0.0) -> list:
    """``calls`` (:func:`_recorded`, the geometry ``shift`` seconds after the reference time) with
    every term lane's and piece's rate of the shapes' motion added: the difference of its pair in
    ``moved`` (the geometry ``step`` seconds later) over ``step``, per metre of the antenna's
    travel, and its positions carried back by ``shift`` at those rates (V2). GeometryChange where
    the two do not pair."""
    moved = iter([call for call in moved if call[0] == "terms"])
    out = []
    for kind, lanes, pieces, depth in calls:
        if kind != "terms":                         # scatterers: on still shapes only (V1), no rates
            out.append((kind, lanes, pieces, depth))
            continue
        _, lanes_m, pieces_m, _ = next(moved, (None, None, None, None))
        if lanes_m is None or (len(lanes) == 0) != (len(lanes_m) == 0):
            raise topology_change("lit pieces")
        if len(lanes):
            tolerance = ALIGN_TOLERANCE * RATE_DISPLACEMENT + 1e-9
            plus, plus_pieces = align_terms(lanes, pieces, lanes_m, pieces_m, tolerance)
            lanes, pieces = target.with_rates(lanes, pieces, tangent_lanes(lanes, plus, step),
                                              tangent_lanes(pieces, plus_pieces, step), reference, shift)
        out.append((kind, lanes, pieces, depth))
    if next(moved, None) is not None:
        raise topology_change("bounce orders reached")
    return out


class MovingShapes:
    """The kernel's mesh tracer, rebuilt for every launch with the moving shapes moved.

    Parameters
    ----------
    kernel : sarmitsuba.tracing.driver.kernel.Kernel
        Its scene, material table and :meth:`~sarmitsuba.tracing.driver.kernel.Kernel.mesh_tracer`.
    motion : ShapeMotion
    """

    def __init__(self, kernel, motion: ShapeMotion):
        self.kernel, self.motion = kernel, motion
        meshes = scene_meshes(kernel.scene)
        self.base = {k: meshes[k][0].copy() for k in motion.shapes}
        self.velocity = dict(zip(motion.shapes, motion.velocities()))
        self.angular = dict(zip(motion.shapes, motion.angular_velocities()))
        self.centre = dict(zip(motion.shapes, np.asarray(motion.centre, float).reshape(-1, 3))) if motion.centre \
            else {k: None for k in motion.shapes}
        shapes = list(kernel.scene.shapes())
        self.mitsuba_ids = {k: int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shapes[k]))[0]) for k in motion.shapes}
        self.surfaces = kernel.mesh.surfaces if kernel.mesh is not None else None
        #: Launches whose two geometries did not pair, traced with the rigid rates (V3) instead.
        self.fallbacks = 0

    def __call__(self, ctx: dict, launch) -> dict:
        """Trace ``launch`` (one sub-aperture; ``launch.pulse_time`` from mid-aperture) with the
        shapes where its pulses meet them; returns the tracer's counters, its stage seconds with
        what the tracer's own clock did not see (moving the shapes, the geometry at the
        neighbouring times, the recorded lanes' deposits) as the ``moving shapes`` stage."""
        start = perf_counter()
        stats = self._traced(ctx, launch)
        seconds = stats["seconds"]
        seconds[-1, STAGES.index("moving shapes")] += max(perf_counter() - start - float(np.sum(seconds)), 0.0)
        return stats

    def _traced(self, ctx: dict, launch) -> dict:
        """:meth:`__call__`'s tracing."""
        if launch.n_subapertures != 1 or launch.pulse_time is None:
            raise RuntimeError("moving shapes: a launch must hold one sub-aperture and its pulse times")
        first, last = int(launch.first[0]), int(launch.first[0] + launch.count[0] - 1)
        time = 0.5 * (launch.pulse_time[first] + launch.pulse_time[last])
        reference = launch.reference[0]
        vertices = self._vertices(time, reference)
        span = launch.pulse_time[last] - launch.pulse_time[first]
        antenna = (launch.antenna[last] - launch.antenna[first]) / span if span > 0 else np.zeros(3)
        if launch.count[0] == 1 or not DIFFERENCED:     # (one pulse: no travel, no rates)
            return self._rigid(ctx, launch, vertices, antenna)
        try:
            tracer = self._tracer(vertices)
            target = TargetMotion(self._part_velocity(tracer.surfaces), antenna[None])
            self.surfaces = tracer.surfaces
            step = RATE_DISPLACEMENT / max(float(self.motion.speeds().max()), 1e-300)
            calls, stats = _recorded(tracer, ctx, launch)
            lanes = self._differenced(calls, ctx, launch, time, step, target)
        except GeometryChange:             # (V2) falls back to the rigid rates (V3) for this launch
            self.fallbacks += 1
            return self._rigid(ctx, launch, vertices, antenna)
        finally:                           # the scene as given, whatever happens
            set_vertices(self.kernel.scene, self.base)
        done = None                        # each order's deposits, then its histogram read (D6), as traced
        for kind, data, pieces, depth in lanes:
            if done is not None and depth != done:
                tracer.returns.sums.order_done(ctx, done)
            done = depth
            if kind == "terms":
                tracer.terms(ctx, data, pieces, depth)
            else:
                tracer.clutter(ctx, data, depth)
        if done is not None:
            tracer.returns.sums.order_done(ctx, done)
        return stats

    def _vertices(self, time: float, reference: np.ndarray) -> dict:
        """Every moving shape's vertices where the wave sent at ``time`` [s, from mid-aperture] from
        ``reference`` meets it (V1)."""
        return {k: shape_positions(self.base[k], self.velocity[k], time, reference, self.angular[k], self.centre[k])
                for k in self.base}

    def _differenced(self, calls: list, ctx: dict, launch, time: float, step: float, target) -> list:
        """``calls`` with the rates of the geometry ``step`` seconds later, or earlier (V2). Where
        neither pairs with the sub-aperture's own (a boundary on a corner at the reference time,
        slivers there and nowhere else), the lanes of the geometry ``+-step`` later, paired with
        the one ``+-2 step`` later and carried back to the reference time. GeometryChange where
        none pairs."""
        recorded = {0.0: calls}

        def at(t: float) -> list:
            if t not in recorded:
                tracer = self._tracer(self._vertices(time + t, launch.reference[0]))
                recorded[t] = _recorded(tracer, ctx, launch, clutter=t == 0.0)[0]
            return recorded[t]

        for base, h in ((0.0, step), (0.0, -step), (step, step), (-step, -step)):
            try:
                lanes = _with_rates(at(base), at(base + h), h, target, launch.reference, base)
            except GeometryChange:
                continue
            # a shifted geometry's recording holds no scatterers: the reference's (on still shapes)
            return lanes if base == 0.0 else lanes + [call for call in calls if call[0] != "terms"]
        raise topology_change("lanes")

    def _rigid(self, ctx: dict, launch, vertices: dict, antenna: np.ndarray) -> dict:
        """Trace ``launch`` with the shapes at ``vertices`` and their lanes at the rigid rates (V3)."""
        try:
            tracer = self._tracer(vertices)
            tracer.target = TargetMotion(self._part_velocity(tracer.surfaces), antenna[None])
            return tracer(ctx, launch)
        finally:
            set_vertices(self.kernel.scene, self.base)

    def _tracer(self, vertices: dict):
        """A mesh tracer of the scene with the moving shapes at ``vertices`` (the Mitsuba scene's
        buffers rewritten: its rays meet them there)."""
        set_vertices(self.kernel.scene, vertices)
        tracer = self.kernel.mesh_tracer(*moved_surfaces(self.kernel.scene, self.kernel.material_table, vertices))
        tracer.simplify = DIFFERENCED      # outlines whose corners do not hang on rounding, as (AD4)'s: they pair
        return tracer

    def _part_velocity(self, surfaces) -> np.ndarray:
        """float64 [n_parts, 3]: each part's velocity (its shape's; zero for still shapes)."""
        out = np.zeros((len(surfaces.normal), 3))
        for k, shape_id in self.mitsuba_ids.items():
            out[surfaces.shape_id == shape_id] = self.velocity[k]
        return out
