"""The Dr.Jit shoot-and-bounce-rays kernel: ray tubes with a wideband-exact physical-optics
return at every bounce and surface-attached clutter scatterers (docs/physics.md).

One :class:`Kernel` is built per acquisition; its configuration decides which effects are
compiled in (docs/design.md section 7: bounce loop, clutter, antenna pattern, radiometric
spreading, beam steering) and it is called once per :class:`Launch` (a batch of pulses and a
set of tubes per pulse). The body of the bounce loop is the model's steps, one function each:

====================  =====================================================  ==============
step                  what                                                   equation
====================  =====================================================  ==============
:func:`intersect`     closest hit, facing normal, float64 legs               (T1), (S1)
:func:`reflection`    reflection coefficient ``r(cos_i)`` of the material    (R)
:func:`po_terms`      the tube footprint's PO integral as 1, 2 or 4 terms    (PO1)-(PO3)
:func:`visible`       shadow ray to the antenna, bounded by its distance     (PO1)
:meth:`Kernel._deposit` terms onto the fine fast-time grid (or kept)         (D1)-(D5)
:meth:`Kernel._scatterers` clutter scatterers inside the footprint           (C)
:func:`reflect`       specular reflection of the ray and the tube edges      (T1)
====================  =====================================================  ==============

The readable NumPy counterpart of :func:`po_terms` is :func:`sarmitsuba.physical_optics.tube_terms`;
tests check one against the other and both against closed forms.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from .constants import SPEED_OF_LIGHT
from .deposit import LANCZOS_A, SPECTRAL_ORDERS, taps
from .physical_optics import SINC_REGIME

__all__ = ["Launch", "Kernel", "Tube", "Hit", "intersect", "reflection", "po_terms", "visible", "reflect"]

#: Hits this close to grazing (cos of the incidence angle) return nothing and end the tube: the
#: facet model needs a footprint, which is unbounded at grazing incidence.
COS_GRAZING = 1e-6
#: Below this cosine of the incidence angle (84.3 deg) a tube's clutter footprint is shortened to
#: 1 / CLUTTER_COS_MIN tube widths along the plane of incidence and its sigma0 raised by the same
#: factor (docs/physics.md (C)): the same clutter power, on scatterers near the hit, at a bounded
#: cost (a tube grazing a wall would otherwise loop over scatterers kilometres away).
CLUTTER_COS_MIN = 0.1


@dataclass(frozen=True)
class Launch:
    """One kernel launch: pulses ``p0 .. p0 + n_b - 1`` and the tubes each of them casts.

    Attributes
    ----------
    antenna : float64 [n_b, 3], m
        Antenna positions.
    r_near : float64 [n_b], m
        Distance from the antenna at which the rays start (float32 origins near the scene).
    lref : float64 [n_b], m
        Reference two-way lengths ``L_ref``.
    k0 : int64 [n_b]
        First along-track lattice cell of each pulse.
    along_limits : float64 [n_b, 2], m
        Along-track aim limits of each pulse.
    rows : (int, int)
        Coarse lattice rows ``[j0, j1)`` of this launch (coarse tubes only).
    refinement : Refinement or None
        Refined cells traced by this launch instead of coarse tubes.
    """

    antenna: np.ndarray
    r_near: np.ndarray
    lref: np.ndarray
    k0: np.ndarray
    along_limits: np.ndarray
    rows: tuple = (0, 0)
    refinement: object = None

    @property
    def n_pulses(self) -> int:
        return self.antenna.shape[0]


@dataclass
class Tube:
    """Loop state of one ray tube (docs/physics.md (T1)).

    ``t1``, ``t2`` are the tube's edges per metre of unfolded path, normal to ``ray.d``: at
    unfolded length ``s`` its cross-section is spanned by ``s t1`` and ``s t2``. ``origin`` is
    the last hit point (the antenna before the first hit), ``direction`` the central ray's
    direction and ``s`` the unfolded length at ``origin``, all float64: the central ray is the
    float64 line ``origin + t direction``, of which ``ray`` is the float32 copy Embree traces.
    ``gamma`` is the product of the reflection coefficients so far.
    """

    ray: mi.Ray3f
    t1: mi.Vector3f
    t2: mi.Vector3f
    s: mi.Float64
    origin: mi.Array3f64
    direction: mi.Array3f64
    gamma: mi.Complex2f
    depth: mi.UInt32
    active: mi.Bool


@dataclass
class Hit:
    """What the tube meets at one bounce (all per lane)."""

    valid: mi.Bool
    p: mi.Point3f
    p64: mi.Array3f64
    n64: mi.Array3f64       # the facet's unit normal, float64, facing the incoming ray
    n: mi.Vector3f          # unit normal facing the incoming ray
    n_geo: mi.Vector3f      # the surface's own normal (side-independent), for the scatterer lattice
    cos_i: mi.Float         # -n . d
    b: mi.Vector3f          # unit direction from the hit to the antenna
    cos_b: mi.Float         # n . b
    dist: mi.Float64        # hit -> antenna, m
    s: mi.Float64           # unfolded length antenna -> hit, m
    shape: mi.UInt32        # Mitsuba shape id


# ============================================================================ the steps
def intersect(scene, tube: Tube, antenna: mi.Array3f64, is_mesh: mi.UInt32) -> Hit:
    """Closest hit of the tube's central ray, the facing normal and the float64 legs, eq. (T1), (S1).

    Embree finds the hit in float32; on a mesh, the hit point is then recomputed in float64 as
    the central ray's float64 line meeting the triangle's plane (normal and offset from its
    float32 vertices, the same for every tube on the triangle). Neighbouring tubes on a facet
    then agree on their shared footprint corners to float64 precision, which the cancellation
    of their PO terms needs (float32 hit points 30 m from the origin are 2e-6 m apart from the
    plane: 4e-4 rad at X band, -48 dB of translation noise). The leg lengths are float64
    norms between these points (not ``si.t``, which a lifted origin would bias). ``is_mesh``:
    uint32 per shape id, 1 for meshes (other shapes keep Embree's float32 point).
    """
    si = scene.ray_intersect(tube.ray, ray_flags=mi.RayFlags.Minimal, coherent=False, active=tube.active)
    shape = dr.reinterpret_array(mi.UInt32, si.shape)
    found = tube.active & si.is_valid()
    mesh_hit = found & (dr.gather(mi.UInt32, is_mesh, shape, found) > 0)
    mesh = mi.MeshPtr(si.shape)
    face = mesh.face_indices(si.prim_index, mesh_hit)
    v0 = mi.Array3f64(mesh.vertex_position(face.x, mesh_hit))
    normal64 = dr.cross(mi.Array3f64(mesh.vertex_position(face.y, mesh_hit)) - v0,
                        mi.Array3f64(mesh.vertex_position(face.z, mesh_hit)) - v0)
    length = dr.norm(normal64)
    mesh_hit &= length > 0
    normal64 = dr.select(mesh_hit, normal64 / dr.select(length > 0, length, 1.0), mi.Array3f64(si.n))
    denominator = dr.dot(normal64, tube.direction)
    p64 = dr.select(mesh_hit & (dr.abs(denominator) > 0),
                    tube.origin + tube.direction * (dr.dot(normal64, v0 - tube.origin)
                                                    / dr.select(denominator != 0, denominator, 1.0)),
                    mi.Array3f64(si.p))
    n64 = dr.select(denominator > 0, -normal64, normal64)                  # facing the ray
    n_geo = mi.Vector3f(dr.select(dr.dot(normal64, mi.Array3f64(si.n)) < 0, -normal64, normal64))
    n = mi.Vector3f(n64)
    cos_i = -dr.dot(tube.ray.d, n)
    # degenerate triangles give a NaN normal; grazing hits have no bounded footprint
    valid = found & (dr.squared_norm(n_geo) > 0.5) & (cos_i > COS_GRAZING)
    to_ant = antenna - p64
    dist = dr.norm(to_ant)
    b = mi.Vector3f(to_ant / dist)
    return Hit(valid=valid, p=mi.Point3f(p64), p64=p64, n64=n64, n=n, n_geo=n_geo, cos_i=cos_i, b=b,
               cos_b=dr.dot(n, b), dist=dist, s=tube.s + dr.norm(p64 - tube.origin), shape=shape)


def reflection(table: "_Tables", hit: Hit) -> tuple[mi.UInt32, mi.Complex2f, mi.Float]:
    """Material row, reflection coefficient ``r(cos_i)`` at the hit, eq. (R), and the factor on its
    specular field (``sqrt(1 - S^2)`` for a Lambertian scatterer, else 1; eq. (C))."""
    row = dr.gather(mi.UInt32, table.row_of_shape, hit.shape, hit.valid)
    return row, reflection_at(table, row, hit.cos_i, hit.valid), dr.gather(mi.Float, table.specular, row, hit.valid)


def reflection_at(table: "_Tables", row: mi.UInt32, cos_i: mi.Float, active: mi.Bool) -> mi.Complex2f:
    """``r(cos_i)`` of material ``row``, linear in its 257-point table, eq. (R)."""
    x = dr.clip(cos_i, 0.0, 1.0) * (table.n_cos - 1)
    i0 = mi.UInt32(dr.minimum(dr.floor(x), table.n_cos - 2))
    w = x - mi.Float(i0)
    idx = row * table.n_cos + i0
    re = dr.lerp(dr.gather(mi.Float, table.re, idx, active), dr.gather(mi.Float, table.re, idx + 1, active), w)
    im = dr.lerp(dr.gather(mi.Float, table.im, idx, active), dr.gather(mi.Float, table.im, idx + 1, active), w)
    return mi.Complex2f(re, im)


@dataclass
class Terms:
    """The tube footprint's PO integral as point terms, eqs. (PO2), (PO4).

    ``terms`` holds four ``(rel, coefficient, active)``: each term's two-way length minus the
    pulse's reference (float64, exact: from its own point), its complex value at the carrier
    including the propagation phase ``exp(-j k rel)``, and whether it exists (an edge in the
    sinc regime has one term, a split one two). ``order_index`` indexes :data:`SPECTRAL_ORDERS`;
    ``carrier`` is the whole tube's value at the carrier, ``A sinc(alpha_1) sinc(alpha_2)`` times
    the amplitude density at the centre (before its propagation phase), for the energy tally.
    """

    terms: list
    order_index: mi.UInt32
    carrier: mi.Complex2f
    footprint: tuple        # (e1', e2'): the footprint's edge vectors on the facet at its centre, m


def footprint_edges(tube: Tube, n: mi.Vector3f, d: mi.Vector3f, s, cos_i) -> tuple:
    """The tube's footprint edges on the facet where its ray of direction ``d`` meets it at unfolded
    length ``s``: ``e_j' = e_j + d (n . e_j) / cos_i`` with ``e_j = s t_j``, eq. (T1)."""
    out = []
    for t in (tube.t1, tube.t2):
        e = t * s
        out.append(e + d * (dr.dot(n, e) / cos_i))
    return tuple(out)


def po_terms(k: float, tube: Tube, hit: Hit, antenna: mi.Array3f64, lref: mi.Float64, density) -> Terms:
    """The PO integral of the tube's footprint, exact at every frequency, eqs. (PO1)-(PO4).

    The footprint is the parallelogram spanned by ``e_j'`` (:func:`footprint_edges`); the
    two-way length varies across it as ``beta_j = (d - b) . e_j'`` per edge. Its integral
    ``A sinc(alpha_1) sinc(alpha_2)`` (``alpha_j = k beta_j / 2``) is split, per edge with
    ``|alpha_j| >= SINC_REGIME``, into the terms of the edge's two ends, eq. (PO2). Every term is
    then evaluated at its own point on the facet (eq. (PO4)): its exact two-way length, its
    directions, footprint edges and amplitude density ``density(cos_i, cos_b, b, s, R_rx)``
    (``j (2 sqrt(pi) / lambda) (cos_i + cos_b) / 2`` times the reflection coefficients, pattern
    and spreading). Two neighbouring tubes evaluate their shared edge or corner at the same
    point, so their terms cancel exactly, at every frequency, whatever the amplitude varies
    with: only the boundary of the lit area returns.
    """
    n = hit.n
    d = tube.ray.d
    centre_edges = footprint_edges(tube, n, d, mi.Float(hit.s), hit.cos_i)
    u = d - hit.b
    splits, sincs = [], []
    for e in centre_edges:
        alpha = 0.5 * k * dr.dot(u, e)
        splits.append(dr.abs(alpha) >= SINC_REGIME)
        sincs.append(dr.select(dr.abs(alpha) < 1e-4, 1.0, dr.sin(alpha) / alpha))
    area = dr.norm(dr.cross(*centre_edges))
    carrier = density(hit.cos_i, hit.cos_b, d, hit.b, hit.s, hit.dist) * (area * sincs[0] * sincs[1])
    source = hit.p64 - tube.direction * hit.s                    # the tube's (image) source, float64
    terms = []
    for a in (0, 1):
        for b_ in (0, 1):
            sigma = [dr.select(splits[0], 2.0 * a - 1.0, 0.0), dr.select(splits[1], 2.0 * b_ - 1.0, 0.0)]
            exists = (splits[0] | (a == 0)) & (splits[1] | (b_ == 0))
            # ---- the term's point, and the geometry there (float64 lengths) ----
            point = hit.p64 + mi.Array3f64(centre_edges[0] * (0.5 * sigma[0]) + centre_edges[1] * (0.5 * sigma[1]))
            incoming, outgoing = point - source, antenna - point
            s, dist = dr.norm(incoming), dr.norm(outgoing)
            d_x, b_x = mi.Vector3f(incoming / s), mi.Vector3f(outgoing / dist)
            cos_i, cos_b = -dr.dot(n, d_x), dr.dot(n, b_x)
            edges = footprint_edges(tube, n, d_x, mi.Float(s), cos_i)
            u_x = d_x - b_x
            value = density(cos_i, cos_b, d_x, b_x, s, dist) * (dr.norm(dr.cross(*edges)))
            for j, e in enumerate(edges):
                length = dr.norm(e)
                grad = dr.dot(u_x, e) / length                       # d(two-way length) / d(distance along e)
                alpha = 0.5 * k * grad * length
                sinc = dr.select(dr.abs(alpha) < 1e-4, 1.0, dr.sin(alpha) / alpha)
                # split end: -sigma / (j k grad) (the edge length cancels the area's); sinc: the edge's own
                value = value * dr.select(splits[j], mi.Complex2f(0.0, sigma[j] / (k * grad * length)),
                                          mi.Complex2f(sinc, 0.0))
            terms.append((s + dist - lref, value, exists))
    n_split = mi.UInt32(splits[0]) + mi.UInt32(splits[1])
    order_index = mi.UInt32(SPECTRAL_ORDERS.index(1)) - n_split     # order m = 1 - n_split
    return Terms(terms, order_index, carrier, centre_edges)


def visible(scene, hit: Hit, active: mi.Bool) -> mi.Bool:
    """Whether the antenna sees the hit point: a shadow ray toward it, no farther than the
    antenna (geometry behind the antenna must not occlude), eq. (PO1)."""
    lift = 1e-4 + 1e-6 * dr.norm(hit.p)
    ray = mi.Ray3f(hit.p + hit.n * lift, hit.b, mi.Float(hit.dist) * (1.0 - 1e-6) - lift, 0.0, [])
    return active & ~scene.ray_test(ray, active)


def reflect(tube: Tube, hit: Hit, r: mi.Complex2f, max_depth: int) -> Tube:
    """Specular reflection of the ray and the tube edges at the hit, eq. (T1)."""
    n = hit.n
    depth = tube.depth + 1
    active = hit.valid & (depth < max_depth)
    direction = tube.direction - 2.0 * dr.dot(tube.direction, hit.n64) * hit.n64       # float64 mirror
    return Tube(ray=_spawn(hit.p, n, mi.Vector3f(direction)),
                t1=tube.t1 - 2.0 * dr.dot(tube.t1, n) * n, t2=tube.t2 - 2.0 * dr.dot(tube.t2, n) * n,
                s=dr.select(active, hit.s, tube.s), origin=dr.select(active, hit.p64, tube.origin),
                direction=dr.select(active, direction, tube.direction),
                gamma=tube.gamma * r, depth=depth, active=active)


def _spawn(p, n, d):
    """Ray leaving the surface point ``p`` (normal ``n`` on the side of ``d``) toward ``d``.

    The origin is lifted ``1e-4 m + 1e-6 |p|`` off the surface: enough to clear float32
    rounding of ``p`` and Embree's own error, and (unlike Mitsuba's ``spawn_ray``, which lifts
    by ~9e-5 (1 + max|p_i|)) almost independent of where the scene sits, so a translated
    scene decides visibility near edges the same way.
    """
    lift = 1e-4 + 1e-6 * dr.norm(p)
    return mi.Ray3f(p + n * lift, d)


def _mesh_flags(scene, size: int) -> np.ndarray:
    """uint32 [size]: 1 at the shape id of every triangle mesh of the scene."""
    flags = np.zeros(size, np.uint32)
    for shape in scene.shapes():
        if shape.is_mesh():
            flags[int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])] = 1
    return flags


def _hash(x):
    """A 32-bit integer hash with full avalanche (two xorshift-multiply rounds, Wellons' "lowbias32")."""
    x = x ^ (x >> 16)
    x = x * 0x7FEB352D
    x = x ^ (x >> 15)
    x = x * 0x846CA68B
    return x ^ (x >> 16)


def _sinc_pi(x):
    """sin(pi x) / (pi x), 1 at 0 (normalised sinc, as numpy.sinc)."""
    y = math.pi * x
    return dr.select(dr.abs(y) < 1e-4, 1.0, dr.sin(y) / y)


@dataclass
class _Tables:
    """Material data uploaded once per kernel."""

    row_of_shape: mi.UInt32
    is_mesh: mi.UInt32
    specular: mi.Float
    re: mi.Float
    im: mi.Float
    n_cos: int
    clutter_kind: mi.UInt32 | None = None
    clutter_value: mi.Float | None = None
    shape_key: mi.UInt32 | None = None
    shape_origin: mi.Point3f | None = None


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
    """

    def __init__(self, scene, params, window, footprint, settings, material_table):
        self.scene = scene
        self.settings = settings
        self.window = window
        self.fp = footprint
        self.k = 2.0 * math.pi * params.frequency / SPEED_OF_LIGHT
        self.lam = params.wavelength
        half = math.sin(params.traced_half_angle)
        self.beam_sines = params.beam_sines if params.mode == "stripmap" else (-half, half)
        self.spotlight = params.mode == "spotlight"
        self.exact = settings.range_kernel == "exact"
        self.groups = settings.max_depth if settings.split_bounces else 1
        table = material_table
        self.tables = _Tables(mi.UInt32(table.row_of_shape.astype(np.uint32)),
                              mi.UInt32(_mesh_flags(scene, table.row_of_shape.size)),
                              mi.Float(table.specular if table.specular is not None
                                       else np.ones(table.table.shape[0], np.float32)),
                              mi.Float(table.table.real.ravel().astype(np.float32)),
                              mi.Float(table.table.imag.ravel().astype(np.float32)), table.table.shape[1])
        self.clutter = table.has_clutter
        if self.clutter:
            self.tables.clutter_kind = mi.UInt32(table.clutter[:, 0].astype(np.uint32))
            self.tables.clutter_value = mi.Float(table.clutter[:, 1].astype(np.float32))
            self.tables.shape_key = mi.UInt32(table.shape_key.astype(np.uint32))
            self.tables.shape_origin = mi.Point3f(*(table.shape_origin[:, c].astype(np.float32) for c in range(3)))
        # absolute radiometry: spreading R_ref^2 / (s R_rx) relative to the pulse's R_ref^2, eq. (R1)
        self.radiometry = params.transmit_power is not None
        # antenna pattern, eq. (A): the tapered default beam or the antenna's dimensions
        self.pattern = params.pattern_length > 0 or params.antenna_height > 0
        if self.pattern:
            boresight = footprint.look * params.ground_range - np.array([0.0, 0.0, params.altitude])
            boresight /= np.linalg.norm(boresight)
            squint = math.radians(params.squint) if params.mode == "stripmap" else 0.0
            self.aperture_axis = (math.cos(squint) * footprint.track - math.sin(squint) * boresight).tolist()
            self.elevation_axis = np.cross(footprint.track, boresight).tolist()
            self.length_in_wavelengths = params.pattern_length / params.wavelength
            self.height_in_wavelengths = params.antenna_height / params.wavelength
        i0, mask = footprint.refined_mask()
        self.refined_i0, self.refined_rows = i0, mask.shape[0]
        self.refined = mi.UInt32(mask.ravel().astype(np.uint32)) if footprint.refinements else None

    # ------------------------------------------------------------------ one launch
    def __call__(self, launch: Launch, capacity: int = 0) -> dict:
        """Trace one launch. Returns NumPy results: ``hist`` complex64 [n_orders, groups, n_b, n_fine]
        (gridded kernels) or ``paths`` (dict of arrays, ``exact``), and the counters."""
        st, win = self.settings, self.window
        n_b = launch.n_pulses
        tube, lanes = self._tubes(launch)
        n_lanes = dr.width(tube.active)
        ctx = dict(energy=dr.zeros(mi.Float, st.max_depth + 1), rays=dr.zeros(mi.UInt32, st.max_depth + 1),
                   carried=dr.zeros(mi.Float, st.max_depth), scatterers=dr.zeros(mi.UInt32, st.max_depth))
        if self.exact:
            # slots: 4 fixed ones per tube and bounce for the PO terms, then the clutter scatterers,
            # appended (one dr.scatter_inc per scatterer-loop iteration)
            fixed = 4 * n_lanes * st.max_depth
            capacity = capacity or max(1024, fixed)
            size = fixed + capacity
            ctx.update(count=dr.zeros(mi.UInt32, 1), fixed=fixed, lane=dr.arange(mi.UInt32, n_lanes),
                       path_pos=dr.zeros(mi.Float64, size), path_re=dr.zeros(mi.Float, size),
                       path_im=dr.zeros(mi.Float, size), path_order=dr.zeros(mi.UInt32, size),
                       path_pulse=dr.zeros(mi.UInt32, size), path_spectral=dr.zeros(mi.UInt32, size))
            outputs = ("count", "path_pos", "path_re", "path_im", "path_order", "path_pulse", "path_spectral")
        else:
            size = len(SPECTRAL_ORDERS) * self.groups * n_b * win.n_fine
            ctx.update(hist=dr.zeros(mi.Float, 2 * size), n_b=n_b)     # (re, im) packets
            outputs = ("hist",)
        ctx["capacity"] = capacity

        def body(tube):
            return (self._bounce(ctx, lanes, tube),)

        if st.max_depth == 1:                    # no reflection loop in the kernel at all
            body(tube)
        else:
            dr.while_loop((tube,), lambda t: t.active, body, label="sbr")
        dr.eval(*(ctx[name] for name in outputs), ctx["energy"], ctx["rays"], ctx["carried"], ctx["scatterers"])
        energy = ctx["energy"].numpy().astype(np.float64)
        rays = ctx["rays"].numpy().astype(np.int64)
        out = dict(energy=energy[:st.max_depth], outside=float(energy[st.max_depth]), rays=rays[:st.max_depth],
                   shadow=int(rays[st.max_depth]), carried=ctx["carried"].numpy().astype(np.float64),
                   scatterers=ctx["scatterers"].numpy().astype(np.int64))
        if self.exact:
            count = int(ctx["count"].numpy()[0])
            if count > capacity:                  # too many scatterers for the buffer: run again, larger
                return self(launch, capacity=count + 1024)
            filled = np.flatnonzero(ctx["path_order"].numpy())
            out["paths"] = {name: ctx[name].numpy()[filled] for name in outputs[1:]}
        else:
            hist = ctx["hist"].numpy().view(np.complex64)
            out["hist"] = hist.reshape(len(SPECTRAL_ORDERS), self.groups, n_b, win.n_fine)
        return out

    # ------------------------------------------------------------------ the lanes
    def _tubes(self, launch: Launch):
        """Initial tubes of a launch: lane -> (pulse, aim point) -> ray and tube edges, eq. (T1)."""
        fp = self.fp
        f64, a64 = mi.Float64, mi.Array3f64
        n_b = launch.n_pulses
        ref = launch.refinement
        if ref is None:
            j0, j1 = launch.rows
            per_pulse = fp.n_azimuth * (j1 - j0)
            lane = dr.arange(mi.UInt32, n_b * per_pulse)
            pulse = lane // per_pulse
            rest = lane - pulse * per_pulse
            ii = rest // (j1 - j0)
            j = rest - ii * (j1 - j0) + j0
            i = mi.Int32(ii) + dr.gather(mi.Int32, mi.Int32(launch.k0.astype(np.int32)), pulse)
            along = (f64(i) + 0.5) * fp.spacing_azimuth
            across = (f64(j) + 0.5) * fp.spacing_range + fp.range_min
            size_a, size_r = fp.spacing_azimuth, fp.spacing_range
            keep = mi.Bool(True)
            if self.refined is not None:         # cells traced by finer tubes instead
                row = i - self.refined_i0
                inside = (row >= 0) & (row < self.refined_rows)
                flag = dr.gather(mi.UInt32, self.refined, mi.UInt32(dr.maximum(row, 0)) * fp.n_range + j, inside)
                keep = ~(inside & (flag > 0))
        else:
            m = ref.factor
            per_pulse = ref.cells.shape[0] * m * m
            lane = dr.arange(mi.UInt32, n_b * per_pulse)
            pulse = lane // per_pulse
            rest = lane - pulse * per_pulse
            cell = rest // (m * m)
            sub = rest - cell * (m * m)
            a = sub // m
            b = sub - a * m
            ci = dr.gather(mi.Int32, mi.Int32(ref.cells[:, 0].astype(np.int32)), cell)
            cj = dr.gather(mi.Int32, mi.Int32(ref.cells[:, 1].astype(np.int32)), cell)
            along = (f64(ci) + (f64(a) + 0.5) / m) * fp.spacing_azimuth
            across = (f64(cj) + (f64(b) + 0.5) / m) * fp.spacing_range + fp.range_min
            size_a, size_r = fp.spacing_azimuth / m, fp.spacing_range / m
            keep = mi.Bool(True)
        antenna = dr.gather(a64, a64(*(launch.antenna[:, c].copy() for c in range(3))), pulse)
        origin, track, look = (a64(*v.tolist()) for v in (fp.origin, fp.track, fp.look))
        aim = origin + track * along + look * across
        to_p = aim - antenna
        r = dr.norm(to_p)
        d64 = to_p / r
        # ---- traced beam: sin(squint - h) <= sin(phi_ray) <= sin(squint + h); spotlight: relative to
        #      the direction of the scene centre ----
        sin_ray = dr.dot(to_p, track) / r
        steer = None
        if self.spotlight:
            to_c = origin - antenna
            steer = mi.Float(dr.dot(to_c, track) / dr.norm(to_c))
            sin_ray -= steer
        lo = dr.gather(f64, f64(launch.along_limits[:, 0].copy()), pulse)
        hi = dr.gather(f64, f64(launch.along_limits[:, 1].copy()), pulse)
        active = mi.Bool((sin_ray >= self.beam_sines[0]) & (sin_ray <= self.beam_sines[1])
                         & (along >= lo) & (along <= hi)) & keep
        # ---- tube edges: the aim cell's edges seen normal to the ray, per metre of path; at
        #      unfolded length s they scale by s / r, so on the aim plane footprints tile the cells ----
        d = mi.Vector3f(d64)
        e1 = mi.Vector3f(track * size_a / r)
        e2 = mi.Vector3f(look * size_r / r)
        e1 = e1 - d * dr.dot(d, e1)
        e2 = e2 - d * dr.dot(d, e2)
        rn = dr.gather(f64, f64(launch.r_near.copy()), pulse)
        tube = Tube(ray=mi.Ray3f(mi.Point3f(antenna + d64 * rn), d), t1=e1, t2=e2, s=f64(0.0), origin=a64(antenna),
                    direction=d64, gamma=mi.Complex2f(1.0, 0.0), depth=mi.UInt32(0), active=active)
        lanes = dict(antenna=antenna, pulse=pulse, lref=dr.gather(f64, f64(launch.lref.copy()), pulse), steer=steer)
        lanes["g_tx"] = self._gain(d, lanes) if self.pattern else None
        return tube, lanes

    # ------------------------------------------------------------------ one bounce
    def _bounce(self, ctx, lanes, tube: Tube) -> Tube:
        """One bounce: intersect, PO return and clutter toward the antenna, reflect."""
        st = self.settings
        dr.scatter_add(ctx["rays"], mi.UInt32(1), tube.depth, tube.active)
        hit = intersect(self.scene, tube, lanes["antenna"], self.tables.is_mesh)
        row, r, specular = reflection(self.tables, hit)
        dr.scatter_add(ctx["carried"], dr.norm(dr.cross(tube.t1, tube.t2)) * dr.squared_norm(tube.gamma),
                       tube.depth, hit.valid)
        # ---- what multiplies every return of this hit: pattern (A) and spreading (R1) at the centre ----
        weight = self._weight(lanes, tube.depth, tube.ray.d, hit.b, hit.s, hit.dist)
        # ---- PO return of the tube footprint, eqs. (PO1)-(PO4) ----
        gamma_before = tube.gamma

        def density(cos_i, cos_b, d, b, s, dist):
            """PO amplitude per unit footprint area at a point of the facet, eq. (PO1): its own
            reflection coefficient, pattern and spreading."""
            r_here = reflection_at(self.tables, row, cos_i, hit.valid)
            scale = (math.sqrt(math.pi) / self.lam) * (cos_i + cos_b) * specular \
                * self._weight(lanes, tube.depth, d, b, s, dist)
            return mi.Complex2f(0.0, scale) * (gamma_before * r_here)

        terms = po_terms(self.k, tube, hit, lanes["antenna"], lanes["lref"], density)
        # ---- visibility from the antenna ----
        vis = visible(self.scene, hit, hit.valid & (hit.cos_b > 0))
        dr.scatter_add(ctx["rays"], mi.UInt32(1), st.max_depth, vis)
        inside = mi.Bool(True)
        for t, (rel_t, value, exists) in enumerate(terms.terms):
            inside &= self._deposit(ctx, lanes, tube.depth, self._anchor(lanes, rel_t), 0.0,
                                    value * self._carrier_phase(rel_t), terms.order_index, vis & exists,
                                    term=t) | ~exists
        power = dr.squared_norm(terms.carrier)
        dr.scatter_add(ctx["energy"], power, tube.depth, vis)
        dr.scatter_add(ctx["energy"], power, mi.UInt32(st.max_depth), vis & ~inside)
        rel = hit.s + hit.dist - lanes["lref"]                  # the centre's L - L_ref, float64
        carrier = self._carrier_phase(rel)
        anchor = self._anchor(lanes, rel)
        # ---- distributed clutter: the surface's own scatterers inside the footprint, eq. (C) ----
        if self.clutter:
            self._scatterers(ctx, lanes, tube, hit, row, r, terms.footprint, anchor, carrier, weight, vis)
        return reflect(tube, hit, r * specular, st.max_depth)

    # ------------------------------------------------------------------ deposit
    def _weight(self, lanes, depth, d, b, s, dist):
        """Antenna pattern (A) and radiometric spreading (R1) of a return from a point reached along
        ``d`` at unfolded length ``s`` and leaving toward the antenna along ``b``, ``dist`` away
        (float64 lengths): the two-way pattern ``g(d_first) g(-b)`` (the first leg is ``d`` itself at
        the first bounce, the tube's central first leg after it) and ``R_ref^2 / (s R_rx)``; 1 when
        neither effect is on."""
        weight = mi.Float(1.0)
        if self.pattern:
            weight *= dr.select(depth == 0, self._gain(d, lanes), lanes["g_tx"]) * self._gain(-b, lanes)
        if self.radiometry:
            rref = mi.Float(0.5 * lanes["lref"])
            weight *= rref * rref / (mi.Float(s) * mi.Float(dist))
        return weight

    def _carrier_phase(self, rel) -> mi.Complex2f:
        """``exp(-j k rel)`` for a float64 length ``rel`` (reduced mod 2 pi in float64 first), eq. (S1)."""
        phase = -self.k * rel
        phase = mi.Float(phase - (2.0 * math.pi) * dr.round(phase * (1.0 / (2.0 * math.pi))))
        sn, cs = dr.sincos(phase)
        return mi.Complex2f(cs, sn)

    def _anchor(self, lanes, rel) -> tuple[mi.Int32, mi.Float]:
        """A tube centre's delay on the fine grid, from ``L - L_ref`` (float64): ``(bin, frac)``,
        ``bin + frac`` fine bins after ``t0``, ``frac`` in [0, 1). Its terms are placed relative to it
        in float32."""
        position = (rel + (lanes["lref"] - SPEED_OF_LIGHT * self.window.t0)) * (1.0 / self.window.fine_step_length)
        first = dr.floor(position)
        return mi.Int32(first), mi.Float(position - first)

    def _deposit(self, ctx, lanes, depth, anchor, offset, value, order_index, mask, term=None) -> mi.Bool:
        """Deposit ``value`` at the two-way length ``offset`` [m] (float32) beyond the tube centre's
        ``anchor``, eqs. (D1)-(D4); ``term`` numbers a PO term of the tube (0-3; None for a clutter
        scatterer). Returns whether the term lies inside the fast-time window."""
        st, win = self.settings, self.window
        position = anchor[1] + offset * (1.0 / win.fine_step_length)       # fine bins after anchor[0]
        if self.exact:
            coarse = (mi.Float64(anchor[0]) + mi.Float64(position)) * (1.0 / win.oversample)
            if term is None:                      # a clutter scatterer: the next free slot
                slot = dr.scatter_inc(ctx["count"], mi.UInt32(0), mask)
                keep = mask & (slot < ctx["capacity"])
                slot = slot + ctx["fixed"]
            else:                                 # PO term: its own slot
                slot = (ctx["lane"] * self.settings.max_depth + depth) * 4 + term
                keep = mask
            dr.scatter(ctx["path_pos"], coarse, slot, keep)
            dr.scatter(ctx["path_re"], value.real, slot, keep)
            dr.scatter(ctx["path_im"], value.imag, slot, keep)
            dr.scatter(ctx["path_order"], depth + 1, slot, keep)
            dr.scatter(ctx["path_pulse"], lanes["pulse"], slot, keep)
            dr.scatter(ctx["path_spectral"], order_index, slot, keep)
            return (coarse >= 0) & (coarse <= win.n_samples - 1)
        k0, tap_list, (lo, hi) = taps(position, st.range_kernel)
        k0 = k0 + anchor[0]
        inside = (k0 >= lo) & (k0 < win.n_fine - hi)
        group = depth if st.split_bounces else mi.UInt32(0)
        base = ((order_index * self.groups + group) * ctx["n_b"] + lanes["pulse"]) * win.n_fine
        for offset, w in tap_list:            # one (re, im) packet per tap
            dr.scatter_add(ctx["hist"], mi.Array2f(value.real * w, value.imag * w), base + mi.UInt32(k0 + offset),
                           mask & inside, mode=dr.ReduceMode.Expand)
        return inside

    # ------------------------------------------------------------------ clutter scatterers
    def _scatterers(self, ctx, lanes, tube, hit, row, r, footprint, anchor, carrier, weight, vis):
        """Clutter: every scatterer of the surface's own lattice inside the footprint, eq. (C).

        The lattice lies in the plane of the hit (frame ``u, v`` from the surface normal, origin
        at a point fixed to the shape), cells ``c`` wide; cell ``(iu, iv)`` of a shape holds one scatterer at a hashed position inside
        it with a hashed phase (an integer hash of the shape, the plane, the cell and the seed). Its
        amplitude is ``sqrt(sigma0) c prod(r_1 .. r_{k-1})``; its two-way length is the tube's
        expanded to second order in the offset from the tube centre. Footprints tile a plane,
        so every scatterer is counted once per pulse: the same scatterers, with the same phases
        and positions, for every pulse, bounce order and pass.
        """
        c = self.fp.scatterer_spacing
        kind = dr.gather(mi.UInt32, self.tables.clutter_kind, row, vis)
        value = dr.gather(mi.Float, self.tables.clutter_value, row, vis)
        cosines = dr.maximum(hit.cos_i, 0.0) * dr.maximum(hit.cos_b, 0.0)
        sigma0 = dr.select(kind == 1, value * dr.sqrt(cosines),
                           dr.select(kind == 2, value * dr.squared_norm(r) * cosines, 0.0))
        # ---- near grazing (cos_i < CLUTTER_COS_MIN) the footprint, 1 / cos_i long along the plane of
        #      incidence, is shortened to 1 / CLUTTER_COS_MIN and sigma0 raised by the same factor:
        #      the tube keeps its clutter power, and no tube loops over kilometres of scatterers ----
        e1, e2 = footprint
        shorten = dr.maximum(hit.cos_i, 0.0) / CLUTTER_COS_MIN
        grazing = shorten < 1.0
        n = hit.n_geo
        along = tube.ray.d - n * dr.dot(n, tube.ray.d)                 # the elongation direction
        along = along * dr.rsqrt(dr.maximum(dr.squared_norm(along), 1e-30))
        e1 = dr.select(grazing, e1 - along * ((1.0 - shorten) * dr.dot(e1, along)), e1)
        e2 = dr.select(grazing, e2 - along * ((1.0 - shorten) * dr.dot(e2, along)), e2)
        sigma0 = dr.select(grazing, sigma0 / dr.maximum(shorten, 1e-30), sigma0)
        rough = vis & (sigma0 > 0)
        # ---- the plane's frame and the footprint in it (units of cells) ----
        horizontal = dr.abs(n.z) > 0.9999
        u_axis = dr.select(horizontal, mi.Vector3f(1.0, 0.0, 0.0), dr.cross(mi.Vector3f(0.0, 0.0, 1.0), n))
        u_axis = dr.normalize(u_axis - n * dr.dot(n, u_axis))
        v_axis = dr.cross(n, u_axis)
        # the hit in the shape's own frame (float64 difference, then float32)
        local = mi.Vector3f(hit.p64 - mi.Array3f64(dr.gather(mi.Point3f, self.tables.shape_origin, hit.shape, rough)))
        pu, pv = dr.dot(local, u_axis) / c, dr.dot(local, v_axis) / c
        au, av = dr.dot(e1, u_axis) / c, dr.dot(e1, v_axis) / c
        bu, bv = dr.dot(e2, u_axis) / c, dr.dot(e2, v_axis) / c
        inv_det = 1.0 / (au * bv - av * bu)
        hu, hv = 0.5 * (dr.abs(au) + dr.abs(bu)), 0.5 * (dr.abs(av) + dr.abs(bv))
        iu0, iv0 = mi.Int32(dr.floor(pu - hu)), mi.Int32(dr.floor(pv - hv))
        nu = dr.maximum(mi.Int32(dr.floor(pu + hu)) - iu0 + 1, 1)
        nv = mi.Int32(dr.floor(pv + hv)) - iv0 + 1
        count = mi.UInt32(dr.select(rough & dr.isfinite(inv_det), nu * nv, 0))
        # ---- which surface: shape, side, plane offset and direction ----
        shape_key = dr.gather(mi.UInt32, self.tables.shape_key, hit.shape, rough)
        side = mi.UInt32(dr.dot(n, tube.ray.d) > 0)
        plane = (mi.UInt32(mi.Int32(dr.round(dr.dot(n, local) / c)))
                 ^ (mi.UInt32(mi.Int32(dr.round(n.x * 1024.0))) * 0x01000193)
                 ^ (mi.UInt32(mi.Int32(dr.round(n.y * 1024.0))) * 0x00010001)
                 ^ (mi.UInt32(mi.Int32(dr.round(n.z * 1024.0))) * 0x00000101))
        key0 = _hash(shape_key ^ (side << 31) ^ _hash(plane ^ mi.UInt32(self.settings.seed)))
        # ---- two-way length offset of a scatterer at (du, dv) cells from the hit, to second order:
        #      incoming from the image source at distance s, outgoing to the antenna at R_rx ----
        d, b = tube.ray.d, hit.b
        inv_s, inv_r = c * c / mi.Float(hit.s), c * c / mi.Float(hit.dist)
        du_d, dv_d, du_b, dv_b = dr.dot(d, u_axis), dr.dot(d, v_axis), dr.dot(b, u_axis), dr.dot(b, v_axis)
        g_u, g_v = c * (du_d - du_b), c * (dv_d - dv_b)
        q_uu = 0.5 * ((1.0 - du_d * du_d) * inv_s + (1.0 - du_b * du_b) * inv_r)
        q_vv = 0.5 * ((1.0 - dv_d * dv_d) * inv_s + (1.0 - dv_b * dv_b) * inv_r)
        q_uv = -(du_d * dv_d * inv_s + du_b * dv_b * inv_r)
        m11, m12, m21, m22 = bv * inv_det, -bu * inv_det, -av * inv_det, au * inv_det
        amplitude = tube.gamma * carrier * (dr.sqrt(sigma0) * c * weight)   # times exp(-j k (L_c - L_ref))
        mid = mi.UInt32(SPECTRAL_ORDERS.index(0))
        nu32 = mi.UInt32(nu)

        def step(k, found, outside):
            kv = k // nu32
            iu, iv = iu0 + mi.Int32(k - kv * nu32), iv0 + mi.Int32(kv)
            h0 = _hash(mi.UInt32(iu) * 0x9E3779B1 ^ mi.UInt32(iv) * 0x85EBCA77 ^ key0)
            du = mi.Float(iu) + mi.Float(h0 & 0xFFFF) * (1.0 / 65536.0) - pu     # scatterer - hit, in cells
            dv = mi.Float(iv) + mi.Float(h0 >> 16) * (1.0 / 65536.0) - pv
            s1, s2 = m11 * du + m12 * dv, m21 * du + m22 * dv                    # footprint coordinates
            own = (k < count) & (s1 >= -0.5) & (s1 < 0.5) & (s2 >= -0.5) & (s2 < 0.5)
            dl = g_u * du + g_v * dv + q_uu * du * du + q_uv * du * dv + q_vv * dv * dv
            phase = mi.Float(_hash(h0 ^ 0x68E31DA4)) * (2.0 * math.pi / 4294967296.0) - self.k * dl
            sn, cs = dr.sincos(phase)
            inside = self._deposit(ctx, lanes, tube.depth, anchor, dl, amplitude * mi.Complex2f(cs, sn), mid, own)
            return k + 1, found + mi.UInt32(own), outside + mi.UInt32(own & ~inside)

        _, found, outside = dr.while_loop((mi.UInt32(0), mi.UInt32(0), mi.UInt32(0)), lambda k, *_: k < count,
                                          step, label="scatterers")
        power = dr.squared_norm(amplitude)
        dr.scatter_add(ctx["energy"], mi.Float(found) * power, tube.depth, rough)
        dr.scatter_add(ctx["energy"], mi.Float(outside) * power, mi.UInt32(self.settings.max_depth), rough)
        dr.scatter_add(ctx["scatterers"], found, tube.depth, rough)

    # ------------------------------------------------------------------ antenna pattern
    def _gain(self, v, lanes):
        """One-way field pattern of the uniform aperture toward unit direction ``v`` (antenna -> scene):
        ``sinc(L sin(phi_az) / lambda) sinc(H_a sin(phi_el) / lambda)``, eq. (A). In spotlight the
        beam is steered at the scene centre, as a phased array steers: ``sin(phi_az)`` is taken
        relative to the centre's, ``sin(phi) - sin(phi_c)``."""
        axis = mi.Vector3f(*self.aperture_axis)
        along = dr.dot(v, axis)
        gain = mi.Float(1.0)
        if self.length_in_wavelengths > 0:
            steered = along - lanes["steer"] if lanes["steer"] is not None else along
            gain *= _sinc_pi(self.length_in_wavelengths * steered)
        if self.height_in_wavelengths > 0:
            across = dr.normalize(v - axis * along)
            gain *= _sinc_pi(self.height_in_wavelengths * dr.dot(across, mi.Vector3f(*self.elevation_axis)))
        return gain


__all__ += ["CLUTTER_COS_MIN", "COS_GRAZING", "LANCZOS_A"]
