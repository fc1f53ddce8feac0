"""The Dr.Jit shoot-and-bounce-rays kernel: ray tubes traced once per sub-aperture, their hits
recorded, and every pulse's wideband-exact physical-optics return evaluated from the records
(docs/physics.md (T1)-(T3), (PO1)-(PO4), (C)).

One :class:`Kernel` is built per acquisition; its configuration decides which effects are
compiled in (docs/design.md section 7: bounce orders, clutter, antenna pattern, radiometric
spreading, beam steering). It is called once per :class:`Launch`: a few sub-apertures of
consecutive pulses and the ray tubes each of them casts. A launch runs bounce by bounce
(a wavefront: one kernel per bounce order, the tubes that left the scene dropped between
them):

============================  ======================================================  ================
step                          what                                                    equation
============================  ======================================================  ================
:meth:`Kernel.launch`         tubes from the sub-aperture's reference position        (T1), (T3)
                              toward the world-fixed aim lattice
:func:`intersect`             closest hit, the facet's float64 plane and hit point    (T1), (S1)
:func:`visible`               shadow ray toward the reference position                (PO1), (T3)
:func:`record`                what every pulse's return needs from the hit            (T3)
:func:`reflect`               specular reflection of the tube, its edges and its      (T1), (T3)
                              image source
:mod:`..integration.returns`  interior terms cancelled, then per pulse: PO terms      (PO2)-(PO5), (C)
                              and clutter scatterers deposited on the fast-time grid
============================  ======================================================  ================

The readable NumPy counterpart of the per-pulse PO terms is
:func:`sarmitsuba.tracing.integration.physical_optics.tube_terms`; tests check one against the other and both
against closed forms.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from ...core.constants import SPEED_OF_LIGHT
from ..deposit.adjoint import read
from ..deposit.fast_time import SPECTRAL_ORDERS
from ...scene.effects import EffectSet, rough_materials
from ..mesh.facets import triangle_table
from .mesh_trace import MeshTracer
from ..mesh.patches import surfaces_of
from .moving import MovingShapes
from .launches import Blocks, Launch
from ..integration import jones as pol
from ..integration.catalogue import lane_catalogue, rows_of
from ..integration.ground_wave import grazing_table
from ..integration.returns import COS_GRAZING, Returns, footprint_edges
from ..loops import RECORDING
from ...core.valid_ranges import ParameterError
from .stages import STAGES

__all__ = ["Blocks", "Launch", "Kernel", "Tube", "Hit", "Record", "intersect", "visible", "reflect", "record",
           "footprint_edges", "COS_GRAZING", "INVALID", "Flags", "SPECTRAL_ORDERS"]

#: No record / no lane.
INVALID = 0xFFFFFFFF
#: Rays leaving a surface (reflections, shadow rays) start this far off it, along the normal:
#: ``SURFACE_LIFT + SURFACE_LIFT_RELATIVE |p|`` [m]. 1e-4 m clears Embree's own intersection
#: error; 1e-6 |p| clears the float32 rounding of ``p`` (6e-8 relative) with a factor of ~16 to
#: spare, so visibility near edges does not depend on where the scene sits. Both stay far
#: below a wavelength (3 cm at X band) and a ray tube's footprint, so no path length changes.
SURFACE_LIFT = 1e-4
SURFACE_LIFT_RELATIVE = 1e-6


class Flags:
    """Bits of a tube's ``flags`` word (lattice neighbours, beam, split edges, side)."""

    HAS_I_LO, HAS_I_HI, HAS_J_LO, HAS_J_HI = 1, 2, 4, 8   # the lattice neighbour (i -+ 1, j -+ 1) exists
    INTERIOR = 16          # the aim point lies inside the beam of every pulse of the sub-aperture
    SPLIT_1, SPLIT_2 = 32, 64   # footprint edge split into its two end terms (PO2) for every pulse
    BACK = 128             # the ray met the surface from its back (against its own normal)
    UNDECIDED_1, UNDECIDED_2 = 256, 512   # split for some pulses of the sub-aperture only (T3)
    MESH_ONLY = 1024       # every hit so far on a triangle mesh: the patches return it (M1)-(M8)


@dataclass
class Tube:
    """State of one ray tube between bounces (docs/physics.md (T1), (T3)).

    ``t1``, ``t2`` are the tube's edges per metre of unfolded path, normal to its direction:
    at unfolded length ``s`` its cross-section is spanned by ``s t1`` and ``s t2``. ``origin``
    is the last hit point (the reference position before the first hit), ``direction`` the
    central ray's direction and ``s`` the unfolded length at ``origin``, all float64: the
    central ray is the float64 line ``origin + t direction``, of which ``ray`` is the float32
    copy Embree traces. ``m1, m2, m3`` are the columns of the linear part ``M`` of the mirrors
    met so far (the identity before the first bounce): a direction ``v`` of the unfolded path
    (the straight line from the reference position through the aim point) is ``M v`` in the
    scene. ``gamma`` is the product of the reflection coefficients so far (of the specular factors
    only when the tube carries a Jones matrix ``jones``, docs/physics.md (P3'); a
    :class:`~sarmitsuba.tracing.integration.jones.NoJones` in the scalar model), ``first_hit`` the first
    bounce's hit point (for the transmit pattern of later bounces). ``lattice`` is the tube's
    lattice id (its lane at launch), ``sub`` its sub-aperture, ``aim`` its aim point, ``key`` a
    hash of the facets met so far.
    """

    ray: mi.Ray3f
    t1: mi.Vector3f
    t2: mi.Vector3f
    s: mi.Float64
    origin: mi.Array3f64
    direction: mi.Array3f64
    m1: mi.Vector3f
    m2: mi.Vector3f
    m3: mi.Vector3f
    first_hit: mi.Array3f64
    gamma: mi.Complex2f
    jones: "pol.Jones | pol.NoJones"
    aim: mi.Array3f64
    lattice: mi.UInt32
    block: mi.UInt32
    sub: mi.UInt32
    flags: mi.UInt32
    key: mi.UInt32
    active: mi.Bool


@dataclass
class Hit:
    """What the tube meets at one bounce (all per lane), seen from the reference position."""

    valid: mi.Bool
    p: mi.Point3f
    p64: mi.Array3f64
    n64: mi.Array3f64       # the facet's unit normal, float64, facing the incoming ray
    n: mi.Vector3f          # unit normal facing the incoming ray
    back: mi.Bool           # the ray met the surface against its own normal
    cos_i: mi.Float         # -n . d
    b: mi.Vector3f          # unit direction from the hit to the reference position
    cos_b: mi.Float         # n . b
    dist: mi.Float64        # hit -> reference position, m
    s: mi.Float64           # unfolded length reference -> hit, m
    shape: mi.UInt32        # Mitsuba shape id
    plane: mi.UInt32        # hash of the facet's plane (quantised normal and offset)
    mesh: mi.Bool           # the hit lies on a triangle mesh


@dataclass
class Record:
    """One visible hit: everything the per-pulse returns need (docs/physics.md (T3)).

    ``e1``, ``e2`` are the footprint's edges on the facet at its centre, seen from the
    reference position (the clutter scatterers' tile, the same for every pulse). The unfolded
    path is the straight line from the antenna through the aim point ``aim``; ``unfolded`` is
    the hit's place on it (the reference position plus the unfolded length along the tube's
    first direction), ``n_unfolded`` the facet's normal there, ``M^T n``, and ``m1, m2, m3`` the
    columns of ``M``: a pulse's own tile corners, lengths and directions follow from its antenna
    position (eq. (T3)). ``gamma`` holds the reflection coefficients of the earlier bounces
    (with their specular factors), ``jones`` the Jones matrix arriving at the hit (as :class:`Tube`).
    """

    p64: mi.Array3f64
    n: mi.Vector3f
    e1: mi.Vector3f
    e2: mi.Vector3f
    unfolded: mi.Array3f64
    n_unfolded: mi.Vector3f
    m1: mi.Vector3f
    m2: mi.Vector3f
    m3: mi.Vector3f
    first_hit: mi.Array3f64
    gamma: mi.Complex2f
    jones: "pol.Jones | pol.NoJones"
    aim: mi.Array3f64
    row: mi.UInt32
    shape: mi.UInt32
    lattice: mi.UInt32
    block: mi.UInt32
    sub: mi.UInt32
    flags: mi.UInt32
    key: mi.UInt32


# ============================================================================ the steps
def intersect(scene, tables: "_Tables", tube: Tube, reference: mi.Array3f64) -> Hit:
    """Closest hit of the tube's central ray, the facet's plane and the float64 legs, eq. (T1), (S1).

    Embree finds the hit in float32 (``ray_intersect_preliminary``: no surface interaction, so the
    kernel does not visit every shape). On a mesh the hit point is the central ray's float64 line
    met with the triangle's float64 plane (the kernel's triangle table), so neighbouring tubes on a
    facet agree on shared footprint corners to float64 precision, as (PO5) needs (float32 points
    30 m out are 2e-6 m off the plane: 4e-4 rad at X band). Other shapes take Mitsuba's float32
    point and normal. The leg lengths are float64 norms between these points.
    """
    pi = scene.ray_intersect_preliminary(tube.ray, coherent=False, active=tube.active)
    found = tube.active & pi.is_valid()
    shape = dr.reinterpret_array(mi.UInt32, pi.shape)
    mesh_hit = found & (dr.gather(mi.UInt32, tables.is_mesh, shape, found) > 0)
    triangle = dr.gather(mi.UInt32, tables.triangle_base, shape, mesh_hit) + pi.prim_index
    normal64 = dr.gather(mi.Array3f64, tables.triangle_normal, triangle, mesh_hit)
    offset = dr.gather(mi.Float64, tables.triangle_offset, triangle, mesh_hit)
    denominator = dr.dot(normal64, tube.direction)
    p64 = tube.origin + tube.direction * ((offset - dr.dot(normal64, tube.origin))
                                          / dr.select(denominator != 0, denominator, 1.0))
    if tables.other_shapes:           # spheres, disks, ...: Mitsuba's own surface interaction
        other = found & ~mesh_hit
        si = pi.compute_surface_interaction(tube.ray, mi.RayFlags.Minimal, other)
        normal64 = dr.select(other, mi.Array3f64(si.n), normal64)
        p64 = dr.select(other, mi.Array3f64(si.p), p64)
        denominator = dr.dot(normal64, tube.direction)
        offset = dr.select(other, dr.dot(normal64, p64), offset)
    back = denominator > 0
    n64 = dr.select(back, -normal64, normal64)                          # facing the ray
    n = mi.Vector3f(n64)
    cos_i = -dr.dot(tube.ray.d, n)
    # degenerate triangles have a zero normal; grazing hits have no bounded footprint
    valid = found & (dr.squared_norm(n) > 0.5) & (cos_i > COS_GRAZING)
    to_ref = reference - p64
    dist = dr.norm(to_ref)
    b = mi.Vector3f(to_ref / dist)
    plane = (mi.UInt32(mi.Int32(dr.round(offset * 100.0)))                   # the facet's plane: offset [cm],
             ^ (mi.UInt32(mi.Int32(dr.round(normal64.x * 16384.0))) * 0x01000193)   # normal to 6e-5
             ^ (mi.UInt32(mi.Int32(dr.round(normal64.y * 16384.0))) * 0x00010001)
             ^ (mi.UInt32(mi.Int32(dr.round(normal64.z * 16384.0))) * 0x00000101))
    return Hit(valid=valid, p=mi.Point3f(p64), p64=p64, n64=n64, n=n, back=back, cos_i=cos_i, b=b,
               cos_b=dr.dot(n, b), dist=dist, s=tube.s + dr.norm(p64 - tube.origin), shape=shape, plane=plane, mesh=mesh_hit)


def shadow_ray(hit: Hit) -> mi.Ray3f:
    """The shadow ray from the hit toward the reference position, lifted off the surface and no
    farther than the antenna (geometry behind the antenna must not occlude), eq. (PO1)."""
    lift = SURFACE_LIFT + SURFACE_LIFT_RELATIVE * dr.norm(hit.p)
    return mi.Ray3f(hit.p + hit.n * lift, hit.b, mi.Float(hit.dist) * (1.0 - 1e-6) - lift, 0.0, [])


def visible(scene, hit: Hit, active: mi.Bool) -> mi.Bool:
    """Whether the reference position sees the hit point (:func:`shadow_ray`); one test serves
    every pulse of the sub-aperture, eq. (T3)."""
    return active & ~scene.ray_test(shadow_ray(hit), active)


def record(tube: Tube, hit: Hit, unfolded: mi.Array3f64, row: mi.UInt32, edges: tuple, first: bool) -> Record:
    """The visible hit's record: the footprint from the reference position, the hit's place
    ``unfolded`` on the unfolded path and the mirror chain, the reflections so far and the
    lattice bookkeeping, eq. (T3) (the edges' splits are added by
    :meth:`sarmitsuba.tracing.integration.returns.Returns.splits`). ``first``: this is the first bounce (the hit is
    the tube's first hit)."""
    flags = (tube.flags | dr.select(hit.back, Flags.BACK, 0)) & dr.select(hit.mesh, mi.UInt32(0xFFFFFFFF), mi.UInt32(0xFFFFFFFF ^ Flags.MESH_ONLY))
    n_unfolded = mi.Vector3f(dr.dot(tube.m1, hit.n), dr.dot(tube.m2, hit.n), dr.dot(tube.m3, hit.n))
    return Record(p64=hit.p64, n=hit.n, e1=edges[0], e2=edges[1], unfolded=unfolded, n_unfolded=n_unfolded,
                  m1=tube.m1, m2=tube.m2, m3=tube.m3, first_hit=hit.p64 if first else tube.first_hit,
                  gamma=tube.gamma, jones=tube.jones, aim=tube.aim, row=row, shape=hit.shape, lattice=tube.lattice, block=tube.block,
                  sub=tube.sub,
                  flags=mi.UInt32(flags), key=_facet_key(tube, hit))


def _facet_key(tube: Tube, hit: Hit) -> mi.UInt32:
    """Hash of the facets (shape and plane) met so far, this one included: tubes with equal keys
    reach their hits through the same mirrors, eq. (PO5). (MurmurHash3's finaliser constants,
    not the clutter's hash: a scene without clutter compiles no clutter hash.)"""
    x = (tube.key * 0xCC9E2D51) ^ hit.shape
    x = (x * 0x85EBCA6B) ^ hit.plane
    return (x ^ (x >> 13)) * 0xC2B2AE35


def reflect(tube: Tube, hit: Hit, r: mi.Complex2f, first: bool, jones=None) -> Tube:
    """Specular reflection of the ray, the tube edges and the mirror chain at the hit, eq. (T1),
    (T3): ``gamma`` times ``r``, and the reflected Jones matrix ``jones`` (docs/physics.md (P3'))
    when the tube carries one. ``first``: this is the first bounce (its hit becomes ``first_hit``)."""
    n, n64 = hit.n, hit.n64
    direction = tube.direction - 2.0 * dr.dot(tube.direction, n64) * n64       # float64 mirror

    def mirror(v):
        return v - 2.0 * dr.dot(v, n) * n

    return Tube(ray=_spawn(hit.p, n, mi.Vector3f(direction)), t1=mirror(tube.t1), t2=mirror(tube.t2), s=hit.s,
                origin=hit.p64, direction=direction, m1=mirror(tube.m1), m2=mirror(tube.m2),
                m3=mirror(tube.m3), first_hit=hit.p64 if first else tube.first_hit, gamma=tube.gamma * r,
                jones=tube.jones if jones is None else jones, aim=tube.aim, lattice=tube.lattice, block=tube.block, sub=tube.sub,
                flags=tube.flags & dr.select(hit.mesh, mi.UInt32(0xFFFFFFFF), mi.UInt32(0xFFFFFFFF ^ Flags.MESH_ONLY)),
                key=_facet_key(tube, hit), active=hit.valid)


def _spawn(p, n, d):
    """Ray leaving the surface point ``p`` (normal ``n`` on the side of ``d``) toward ``d``, its
    origin lifted ``1e-4 m + 1e-6 |p|`` off the surface: enough to clear float32 rounding of ``p``
    and Embree's own error, and (unlike Mitsuba's ``spawn_ray``, which lifts by ~9e-5 (1 + max|p_i|))
    almost independent of where the scene sits, so a translated scene decides visibility near
    edges the same way."""
    lift = SURFACE_LIFT + SURFACE_LIFT_RELATIVE * dr.norm(p)
    return mi.Ray3f(p + n * lift, d)


@dataclass
class _Tables:
    """Scene and material data uploaded once per kernel."""

    row_of_shape: mi.UInt32
    is_mesh: mi.UInt32
    triangle_base: mi.UInt32
    triangle_normal: mi.Array3f64
    triangle_offset: mi.Float64
    other_shapes: bool
    specular: mi.Float
    re: mi.Float
    im: mi.Float
    n_cos: int
    clutter_kind: mi.UInt32 | None = None
    clutter_value: mi.Float | None = None
    shape_key: mi.UInt32 | None = None
    shape_origin: mi.Array3f64 | None = None
    shape_axes: tuple | None = None           # three mi.Vector3f: each shape's own axes (C)
    re_tm: mi.Float | None = None             # Jones model: r_tm (re, im then hold r_te), (P3')
    im_tm: mi.Float | None = None
    cross_pol: mi.Float | None = None         # and the clutter's cross-polarised level, (P7)
    rough_mono: mi.Float | None = None        # rough surfaces' sigma0 tables, (RS6)
    rough_bi: mi.Float | None = None
    grazing_offset: mi.Float | None = None    # edge diffraction: each row's grazing-wave table, (E6')
    grazing_re: mi.Float | None = None
    grazing_im: mi.Float | None = None
    #: reverse mode: table name -> the AdjointSink its reads add their adjoints to in fixed point (D7)
    adjoint: dict = dataclasses.field(default_factory=dict)

    def read(self, name: str, index, active=True):
        """Table ``name`` at ``index``: a gather; in reverse mode its adjoint goes to the table's
        sink (:func:`sarmitsuba.tracing.deposit.adjoint.read`)."""
        return read(getattr(self, name), index, active, self.adjoint.get(name))


# ============================================================================ the kernel
class Kernel:
    """The tracing kernel of one acquisition (configuration fixed at construction).

    Parameters
    ----------
    scene : mitsuba.Scene
    params : RadarParameters
    window : FastTimeWindow
    footprint : RayFootprint
    settings : TraceSettings
    material_table : MaterialTable
    effects : EffectSet, optional
        Which effects to compile in (:func:`sarmitsuba.scene.effects.active_effects`); default: those of
        ``params``, ``settings`` and the rough materials of ``material_table``.
    """

    def __init__(self, scene, params, window, footprint, settings, material_table, effects: EffectSet | None = None):
        if effects is None:
            effects = EffectSet.of(params, settings, rough_materials(material_table))
        self.effects = effects
        self.scene = scene
        self.settings = settings
        self.window = window
        self.fp = footprint
        self.k = 2.0 * math.pi * params.frequency / SPEED_OF_LIGHT
        half = math.sin(params.traced_half_angle)
        self.spotlight = effects.spotlight
        self.beam_sines = (-half, half) if self.spotlight else params.beam_sines
        table = material_table
        size = table.row_of_shape.size
        is_mesh, base, normal, offset, other = triangle_table(scene, size)
        self.tables = _Tables(mi.UInt32(table.row_of_shape.astype(np.uint32)), mi.UInt32(is_mesh), mi.UInt32(base),
                              mi.Array3f64(*(normal[:, c].copy() for c in range(3))), mi.Float64(offset), other,
                              mi.Float(table.specular if table.specular is not None
                                       else np.ones(table.table.shape[0], np.float32)),
                              mi.Float(table.table.real.ravel().astype(np.float32)),
                              mi.Float(table.table.imag.ravel().astype(np.float32)), table.table.shape[1])
        if effects.polarimetric:
            self.tables.re = mi.Float(table.table_te.real.ravel().astype(np.float32))    # r_te, r_tm: (P3')
            self.tables.im = mi.Float(table.table_te.imag.ravel().astype(np.float32))
            self.tables.re_tm = mi.Float(table.table_tm.real.ravel().astype(np.float32))
            self.tables.im_tm = mi.Float(table.table_tm.imag.ravel().astype(np.float32))
            self.tables.cross_pol = mi.Float(table.cross_pol.astype(np.float32))
        if effects.diffraction and table.grazing_delta is not None:
            offset, weights = grazing_table(table.grazing_delta)
            self.tables.grazing_offset = mi.Float(offset)
            self.tables.grazing_re = mi.Float(weights.real.ravel())
            self.tables.grazing_im = mi.Float(weights.imag.ravel())
        if effects.clutter:
            self.tables.clutter_kind = mi.UInt32(table.clutter[:, 0].astype(np.uint32))
            self.tables.clutter_value = mi.Float(table.clutter[:, 1].astype(np.float32))
            self.tables.shape_key = mi.UInt32(table.shape_key.astype(np.uint32))
            if table.rough is not None:
                self.tables.rough_mono = mi.Float(table.rough.mono.ravel())
                self.tables.rough_bi = mi.Float(table.rough.bistatic.ravel())
            self.tables.shape_origin = mi.Array3f64(*(table.shape_origin[:, c].astype(np.float64) for c in range(3)))
            self.tables.shape_axes = tuple(mi.Vector3f(*(table.shape_axes[:, a, c].astype(np.float32) for c in range(3)))
                                           for a in range(3))
        self.returns = Returns(params, window, footprint, settings, self.tables, effects, self.beam_sines)
        self.mesh = None
        #: Whether the tubes are traced: ``tiles``, or patches with shapes that are not meshes (spheres).
        self.tubes = settings.lit_regions != "patches" or self.tables.other_shapes
        self.params, self.material_table = params, material_table
        if effects.bistatic:
            _check_bistatic(self.tubes, settings, effects)
        if settings.lit_regions == "patches":        # scattering anchored to the mesh (M1)-(M8)
            bbox = scene.bbox()
            self.bbox = (np.array(bbox.min, float), np.array(bbox.max, float))
            self.mesh = self.mesh_tracer(surfaces_of(scene, material_table), material_table)
            if effects.moving_shapes is not None:        # (V1)-(V3): one launch at a time, each its own geometry
                self.mesh, self.serial = MovingShapes(self, effects.moving_shapes), True
        i0, mask = footprint.refined_mask()
        self.refined_i0, self.refined_rows = i0, mask.shape[0]
        self.refined = mi.UInt32(mask.ravel().astype(np.uint32)) if footprint.refinements else None

    def mesh_tracer(self, surfaces, material_table) -> MeshTracer:
        """A :class:`~sarmitsuba.tracing.driver.mesh_trace.MeshTracer` of ``surfaces`` with this kernel's
        acquisition, returns and scene box (the geometric derivatives' moved copies, (AD4))."""
        fx = self.effects
        tracer = MeshTracer(self.scene, surfaces, self.returns, self.params, self.settings, self.fp.patch_size,
                            not (fx.spotlight or fx.curved_track), self.bbox, material_table, self.fp.scatterer_spacing)
        tracer.catalogue = lane_catalogue(self.scene, self.params, self.fp, fx) if fx.scatterers else None
        return tracer

    # ------------------------------------------------------------------ one launch
    def __call__(self, launch: Launch, capacity: int = 0) -> dict:
        """Trace one launch. Returns NumPy results: ``hist`` complex64 [n_orders, groups, n_b, n_fine]
        (gridded kernels) or ``paths`` (dict of arrays, ``exact``), and the counters."""
        st = self.settings
        ctx = self.returns.context(launch, capacity)
        if self.mesh is not None and launch.n_lanes == 0:      # the mesh's own launch (M1)-(M8)
            ctx["mesh"] = self.mesh(ctx, launch)
            start = time.perf_counter()
            with RECORDING:
                out = self.returns.collect(ctx)
            if out is None:                     # exact kernel: too many scatterers for the buffer
                return self(launch, capacity=ctx["needed"])
            out["mesh"] = stats = ctx["mesh"]
            out["stages"] = np.array(stats["seconds"], float)           # [max_depth + 1, stages]
            out["stages"][-1, STAGES.index("deposit")] += time.perf_counter() - start
            for depth, (samples, carried) in enumerate(zip(stats["samples"], stats["carried"])):
                out["rays"][depth] += samples          # the points rays were aimed at, per bounce order
                out["carried"][depth] += carried
            for depth, casts in enumerate(stats["discovery"]):
                out["rays"][depth + 1] += casts        # and the rays that looked for its chains
            # each sample's return leg, where it is a ray of its own: past the first bounce, and
            # bistatic at every bounce, toward the receiver (B2); the monostatic first bounce's
            # return is its transmit ray, counted above
            out["shadow"] += int(sum(n for depth, n in enumerate(stats["samples"]) if depth > 0 or self.effects.bistatic))
            out["overflow"] = stats["overflow"]          # rows the fused kernels left to the reference
            out["beyond_rays"] = stats["beyond"] or 0    # rays past the deepest order, where looked for
            out["beyond_unchecked"] = int(stats["beyond"] is None)
            out["catalogue"] = rows_of(ctx.pop("catalogue", []))     # the scatterer catalogue's rows (SC2)
            return out
        tube, n_lanes = self.launch(launch)
        for depth in range(st.depth):
            if tube is None or dr.width(tube.active) == 0:
                break
            tube = self._bounce(ctx, launch, tube, depth, n_lanes)
            self.returns.sums.order_done(ctx, depth)          # this order's histogram: its energy (D6)
        out = self.returns.collect(ctx)
        if out is None:                     # exact kernel: too many scatterers for the buffer
            return self(launch, capacity=ctx["needed"])
        out["beyond_unchecked"] = 1         # tubes do not look past their deepest order
        return out

    # ------------------------------------------------------------------ one bounce order
    def _bounce(self, ctx, launch: Launch, tube: Tube, depth: int, n_lanes: int) -> Tube:
        """One bounce order of a launch: intersect, shadow ray, record the visible hits and
        deposit their returns for every pulse (:mod:`..integration.returns`), reflect; the tubes that left the
        scene or ended are dropped."""
        st, ret = self.settings, self.returns
        reference = dr.gather(mi.Array3f64, ctx["reference"], tube.sub)
        dr.scatter_add(ctx["rays"], mi.UInt32(1), mi.UInt32(depth), tube.active, mode=ctx["tally"])
        hit = intersect(self.scene, self.tables, tube, reference)
        row = dr.gather(mi.UInt32, self.tables.row_of_shape, hit.shape, hit.valid)
        specular = self.tables.read("specular", row, hit.valid)
        if self.effects.polarimetric:          # docs/physics.md (P3'): the Jones matrix reflected
            r_te, r_tm = ret.reflection_pair(row, hit.cos_i, hit.valid)
            reflected = pol.reflect(tube.jones, tube.ray.d, hit.n, r_te, r_tm)
            carried = dr.squared_norm(tube.gamma) * pol.power(tube.jones)
            r = mi.Complex2f(dr.sqrt(pol.power(reflected)), 0.0)     # for the energy tally only
        else:
            r, reflected = ret.reflection_at(row, hit.cos_i, hit.valid), None
            carried = dr.squared_norm(tube.gamma)
        count = mi.Float(dr.gather(mi.UInt32, ctx["count"], tube.sub))
        ret.sums.tally(ctx, "carried", dr.norm(dr.cross(tube.t1, tube.t2)) * carried * count, depth, hit.valid)
        # ---- the footprint seen from the reference position, and which of its edges split (PO2):
        #      for every pulse of the sub-aperture (its first and last pulse agree), or per pulse ----
        d = tube.ray.d
        edges = footprint_edges(tube.t1, tube.t2, hit.n, d, mi.Float(hit.s), hit.cos_i)
        unfolded = reference + dr.normalize(tube.aim - reference) * hit.s
        rec = record(tube, hit, unfolded, row, edges, first=depth == 0)
        alpha, split, undecided = ret.splits(ctx, rec, reference, depth)
        rec.flags |= dr.select(split[0], Flags.SPLIT_1, 0) | dr.select(split[1], Flags.SPLIT_2, 0) \
            | dr.select(undecided[0], Flags.UNDECIDED_1, 0) | dr.select(undecided[1], Flags.UNDECIDED_2, 0)
        vis = visible(self.scene, hit, hit.valid & (hit.cos_b > 0))
        dr.scatter_add(ctx["rays"], mi.UInt32(1), mi.UInt32(st.depth), hit.valid & (hit.cos_b > 0), mode=ctx["tally"])
        ret.tally(ctx, rec, hit, d, alpha, specular, r, count, depth, vis)
        last = depth + 1 == st.depth          # the last bounce order: no reflection compiled
        if last:
            nxt = None
        elif reflected is None:
            nxt = reflect(tube, hit, r * specular, first=depth == 0)
        else:
            nxt = reflect(tube, hit, mi.Complex2f(specular, 0.0), first=depth == 0, jones=reflected)
        dr.eval(rec, vis, *(() if last else (nxt,)))
        keep = dr.compress(vis)
        if dr.width(keep):
            visible_hits = dr.gather(Record, rec, keep)
            dr.eval(visible_hits)             # one kernel for all fields (not one per field, later)
            ret.deposit(ctx, visible_hits, depth, n_lanes)
        if last:
            return None
        nxt = dr.gather(Tube, nxt, dr.compress(nxt.active))
        dr.eval(nxt)
        return nxt

    # ------------------------------------------------------------------ the tubes
    def launch(self, launch: Launch) -> tuple[Tube, int]:
        """Initial tubes of a launch: lane -> (sub-aperture, aim point) -> ray from the reference
        position and tube edges, eq. (T1), (T3). Returns the tubes that some pulse of their
        sub-aperture casts (compacted; each keeps its lane as its lattice id), and the number of
        lanes."""
        fp = self.fp
        f64, a64 = mi.Float64, mi.Array3f64
        blocks = launch.blocks
        lane = dr.arange(mi.UInt32, launch.n_lanes)
        block = launch.lane_block()
        rest = lane - dr.gather(mi.UInt32, mi.UInt32(blocks.start), block)
        n_a = dr.gather(mi.UInt32, mi.UInt32(blocks.n_a), block)
        n_j = dr.maximum(dr.gather(mi.UInt32, mi.UInt32(blocks.n_j), block), 1)   # never 0, even in padding lanes
        m = dr.gather(mi.UInt32, mi.UInt32(blocks.m), block)
        sub = dr.gather(mi.UInt32, mi.UInt32(blocks.sub), block)
        ii = rest // n_j
        jj = rest - ii * n_j
        i0 = dr.gather(mi.Int32, mi.Int32(blocks.i0), block)
        j0 = dr.gather(mi.Int32, mi.Int32(blocks.j0), block)
        scale = 1.0 / f64(m)
        along = (f64(i0) + (f64(ii) + 0.5) * scale) * fp.spacing_azimuth
        across = (f64(j0) + (f64(jj) + 0.5) * scale) * fp.spacing_range + fp.range_min
        size_a, size_r = mi.Float(fp.spacing_azimuth * scale), mi.Float(fp.spacing_range * scale)
        keep = mi.Bool(True)
        if self.refined is not None:         # coarse cells traced by finer tubes instead
            i, j = i0 + mi.Int32(ii), j0 + mi.Int32(jj)
            rrow = i - self.refined_i0
            inside = (m == 1) & (rrow >= 0) & (rrow < self.refined_rows)
            flag = dr.gather(mi.UInt32, self.refined, mi.UInt32(dr.maximum(rrow, 0)) * fp.n_range + mi.UInt32(j), inside)
            keep = ~(inside & (flag > 0))
        flags = dr.select(ii > 0, Flags.HAS_I_LO, 0) | dr.select(ii + 1 < n_a, Flags.HAS_I_HI, 0) \
            | dr.select(jj > 0, Flags.HAS_J_LO, 0) | dr.select(jj + 1 < n_j, Flags.HAS_J_HI, 0)
        reference = dr.gather(a64, a64(*(launch.reference[:, c].copy() for c in range(3))), sub)
        origin, track, look = (a64(*v.tolist()) for v in (fp.origin, fp.track, fp.look))
        aim = origin + track * along + look * across
        # ---- the sub-aperture's beam: every pulse between its first and last one (the along-track
        #      sine of the aim point changes monotonically along a straight track); spotlight:
        #      relative to the direction of the scene centre ----
        sines = []
        ends = (launch.first, launch.first + launch.count - 1)
        if launch.axes is not None:           # a curved track turns the beam: its middle pulse too
            ends += (launch.first + launch.count // 2,)
        for end in ends:
            antenna = dr.gather(a64, a64(*(launch.antenna[end, c].copy() for c in range(3))), sub)
            axis = None if launch.axes is None else dr.gather(a64, a64(*(launch.axes[end, 0, c].copy() for c in range(3))), sub)
            sines.append(self.returns.aim_sine(aim, antenna, axis))
        lo_s, hi_s = sines[0], sines[0]
        for sine in sines[1:]:
            lo_s, hi_s = dr.minimum(lo_s, sine), dr.maximum(hi_s, sine)
        lo_b, hi_b = self.beam_sines
        lo = dr.gather(f64, f64(launch.along_limits[:, 0].copy()), sub)
        hi = dr.gather(f64, f64(launch.along_limits[:, 1].copy()), sub)
        active = mi.Bool((hi_s >= lo_b) & (lo_s <= hi_b) & (along >= lo) & (along <= hi)) & keep
        if self.returns.aim_mask:       # hard-edged beam: pulses cut the lattice at different cells
            flags |= dr.select((lo_s >= lo_b) & (hi_s <= hi_b), Flags.INTERIOR, 0)
        else:
            flags |= Flags.INTERIOR
        if self.mesh is not None:            # patches return the chains of mesh parts; tubes only the rest
            flags |= Flags.MESH_ONLY
        to_p = aim - reference
        r = dr.norm(to_p)
        d64 = to_p / r
        # ---- tube edges: the aim cell's edges seen normal to the ray, per metre of path; at
        #      unfolded length s they scale by s / r, so on the aim plane footprints tile the cells ----
        d = mi.Vector3f(d64)
        e1 = mi.Vector3f(track * size_a / r)
        e2 = mi.Vector3f(look * size_r / r)
        e1 = e1 - d * dr.dot(d, e1)
        e2 = e2 - d * dr.dot(d, e2)
        rn = dr.gather(f64, f64(launch.r_near.copy()), sub)
        zero = mi.Vector3f(0.0)
        tube = Tube(ray=mi.Ray3f(mi.Point3f(reference + d64 * rn), d), t1=e1, t2=e2, s=f64(0.0), origin=reference,
                    direction=d64, m1=mi.Vector3f(1.0, 0.0, 0.0), m2=mi.Vector3f(0.0, 1.0, 0.0),
                    m3=mi.Vector3f(0.0, 0.0, 1.0), first_hit=a64(zero), gamma=mi.Complex2f(1.0, 0.0),
                    jones=pol.launch(d, mi.Vector3f(*fp.track.tolist())) if self.effects.polarimetric
                    else pol.NoJones(), aim=aim,
                    lattice=lane, block=block, sub=sub, flags=mi.UInt32(flags), key=mi.UInt32(0), active=active)
        dr.eval(tube)
        self._traced = tube.active
        alive = dr.compress(tube.active)
        out = dr.gather(Tube, tube, alive)
        dr.eval(out)
        return out, launch.n_lanes


def _check_bistatic(tubes: bool, settings, effects) -> None:
    """What a bistatic acquisition (docs/physics.md (B1)-(B4)) refuses: ray tubes (``lit_regions =
    tiles``, or shapes that are not triangle meshes) and moving shapes. Raises ParameterError."""
    if tubes:
        raise ParameterError("receiver_*: a bistatic acquisition traces triangle meshes with lit_regions = patches "
                             f"(lit_regions = {settings.lit_regions!r}, or a shape that is not a mesh, e.g. a sphere): "
                             "use lit_regions = patches and mesh shapes, or remove the receiver_* parameters")
    if effects.moving_shapes is not None:
        raise ParameterError("receiver_*: a bistatic acquisition traces a still scene; remove the shapes' velocity "
                             "or the receiver_* parameters")
