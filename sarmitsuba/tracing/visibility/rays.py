"""Rays aimed at mesh points: which legs of a path are free, what blocks them, and where a
specular reflection goes next (docs/physics.md (M4), (M6)).

The geometry of every ray (its ends on the mesh, lifted off their surfaces) is float64 NumPy
(:mod:`sarmitsuba.tracing.discovery.chains`); :class:`Rays` casts them with Mitsuba (Embree, float32) and
maps what they hit to the convex parts of :class:`sarmitsuba.tracing.mesh.patches.Surfaces`.
"""
from __future__ import annotations

import threading

import drjit as dr
import mitsuba as mi
import numpy as np

from ..device import device_array
from ..timing import section
from ..mesh.covers import locate
from ..mesh.patches import Surfaces, face_partners, occluder_partners

__all__ = ["Rays", "lift", "NO_HIT", "NOT_A_MESH", "SURFACE_LIFT", "SURFACE_LIFT_RELATIVE", "CastCounter"]

#: A ray that met nothing.
NO_HIT = -1
#: A ray that met a shape that is not a triangle mesh (a sphere, say): no part.
NOT_A_MESH = -2
#: Rays leave (and stop short of) a surface this far off it, along its normal:
#: ``SURFACE_LIFT + SURFACE_LIFT_RELATIVE |p|`` [m]. 1e-4 m clears Embree's own intersection
#: error and ``1e-6 |p|`` the float32 rounding of ``p`` (6e-8 relative) with a factor ~16 to spare,
#: far below a wavelength, so no path length changes and visibility near edges does not depend
#: on where the scene sits (as the tube kernel's shadow rays, docs/physics.md (PO1)).
SURFACE_LIFT = 1e-4
SURFACE_LIFT_RELATIVE = 1e-6


class CastCounter:
    """A count of casts kept per thread (launches traced on several host threads count their own
    casts): ``counter.value`` reads and ``counter.add(n)`` adds to the calling thread's count."""

    def __init__(self):
        self._local = threading.local()

    @property
    def value(self) -> int:
        """The calling thread's count of casts."""
        return getattr(self._local, "count", 0)

    def add(self, n: int) -> None:
        """Add ``n`` casts to the calling thread's count."""
        self._local.count = self.value + int(n)


def lift(points: np.ndarray, normal: np.ndarray, toward: np.ndarray) -> np.ndarray:
    """``points`` [m, 3] moved off their planes (unit ``normal`` [m, 3]) to the side of ``toward``
    [m, 3], by ``SURFACE_LIFT + SURFACE_LIFT_RELATIVE |p|``; rows with a zero normal stay."""
    side = np.sign(np.einsum("mi,mi->m", normal, toward - points))
    size = SURFACE_LIFT + SURFACE_LIFT_RELATIVE * np.sqrt(np.add.reduce(points * points, axis=1))  # linalg.norm
    return points + normal * (side * size)[:, None]


class Rays:
    """Ray casts against a scene, hits mapped to parts.

    Parameters
    ----------
    scene : mitsuba.Scene
    surfaces : Surfaces
        The scene's parts (``triangle_base``, ``triangle_part``).
    """

    def __init__(self, scene, surfaces: Surfaces):
        self.scene = scene
        self.surfaces = surfaces
        #: The other parts of each part's face (an occluder casts its whole face's shadow).
        self.face_partners = face_partners(surfaces)
        #: The parts that cast the rest of a met occluder's shadow: its face's other parts and the
        #: parts of its shape it shares a corner with (eq. (M4)).
        self.occluder_partners = occluder_partners(surfaces)
        #: Each part's bounding sphere: centre float64 [n, 3] and radius [n] (m).
        corners = surfaces.to_world(np.arange(surfaces.n_parts), surfaces.polygon)
        centre = 0.5 * (corners.min(axis=1) + corners.max(axis=1))
        self.part_sphere = (centre, np.linalg.norm(corners - centre[:, None], axis=2).max(axis=1, initial=0.0))
        size = max(len(surfaces.triangle_base), 1)
        base = np.zeros(size, np.int64)
        base[:len(surfaces.triangle_base)] = surfaces.triangle_base
        self.is_mesh = device_array(mi.UInt32, (base >= 0).astype(np.uint32))
        self.base = device_array(mi.UInt32, np.maximum(base, 0).astype(np.uint32))
        # a degenerate triangle belongs to no part (Embree should never report it)
        part = np.where(surfaces.triangle_part >= 0, surfaces.triangle_part, NOT_A_MESH)
        self.part = device_array(mi.Int32, np.append(part, NOT_A_MESH).astype(np.int32))
        self.counter = CastCounter()

    @property
    def casts(self) -> int:
        """Rays cast so far by the calling thread."""
        return self.counter.value

    def _ray(self, start: np.ndarray, end: np.ndarray | None, direction: np.ndarray | None) -> tuple:
        """Float32 rays from ``start`` toward ``end`` (stopping just short of it) or along
        ``direction`` (unbounded)."""
        direction, tmax = _direction_and_reach(start, end, direction)
        # one float32 upload (NumPy rounds float64 to float32 as Dr.Jit would, and much faster
        # than Dr.Jit's nested constructors); the cast's kernel gathers the columns
        n = len(start)
        packed = np.empty((n, 7), np.float32)
        packed[:, :3], packed[:, 3:6], packed[:, 6] = start, direction, np.minimum(tmax, 3.4e38)
        buffer = device_array(mi.Float, packed.reshape(-1))
        row = dr.arange(mi.UInt32, n) * 7
        column = [dr.gather(mi.Float, buffer, row + c) for c in range(7)]
        ray = mi.Ray3f(mi.Point3f(*column[:3]), mi.Vector3f(*column[3:6]))
        ray.maxt = column[6]
        self.counter.add(len(start))
        return ray

    def _ray_reference(self, start: np.ndarray, end: np.ndarray | None, direction: np.ndarray | None) -> tuple:
        """:meth:`_ray` as three uploads of the nested types (the reference of its packing)."""
        direction, tmax = _direction_and_reach(start, end, direction)
        ray = mi.Ray3f(device_array(mi.Point3f, start.T), device_array(mi.Vector3f, direction.T))
        ray.maxt = device_array(mi.Float, np.minimum(tmax, 3.4e38))
        return ray

    def free(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """bool [m]: nothing lies between ``start`` and ``end`` [m, 3] (both already lifted off
        their surfaces)."""
        if len(start) == 0:
            return np.zeros(0, bool)
        blocked = self.scene.ray_test(self._ray(start, end, None), coherent=False)
        with section("casts"):
            return ~blocked.numpy().astype(bool)

    def first_hit(self, start: np.ndarray, end: np.ndarray | None = None,
                  direction: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The part each ray meets first (int64 [m]; :data:`NO_HIT`, :data:`NOT_A_MESH`) and its
        distance (float64 [m], inf where none): rays from ``start`` toward ``end`` (bounded) or
        along unit ``direction`` (unbounded)."""
        if len(start) == 0:
            return np.zeros(0, np.int64), np.zeros(0)
        pi = self.scene.ray_intersect_preliminary(self._ray(start, end, direction), coherent=False)
        found = pi.is_valid()
        shape = dr.reinterpret_array(mi.UInt32, pi.shape)
        mesh = found & (dr.gather(mi.UInt32, self.is_mesh, shape, found) > 0)
        triangle = dr.gather(mi.UInt32, self.base, shape, mesh) + pi.prim_index
        part = dr.select(mesh, dr.gather(mi.Int32, self.part, triangle, mesh), NOT_A_MESH)
        part = dr.select(found, part, NO_HIT)
        # the distance masked in the cast's own kernel (reading ``found`` after it launched one
        # more kernel per call, and np.where another pass); inf float32 widens to inf float64
        t = dr.select(found, pi.t, dr.inf)
        with section("casts"):
            dr.eval(part, t)
            part, t = part.numpy().astype(np.int64), t.numpy().astype(np.float64)
        return self._resolve(part, t, start, end, direction), t

    def _resolve(self, part, t, start, end, direction) -> np.ndarray:
        """Hits on a covered part's triangles given to the part at the hit point
        (:mod:`sarmitsuba.tracing.mesh.covers`)."""
        s = self.surfaces
        if s.split_count is None:
            return part
        rows = np.flatnonzero((part >= 0) & (s.split_count[np.maximum(part, 0)] > 0))
        if len(rows) == 0:
            return part
        if direction is None:
            span = end[rows] - start[rows]
            unit = span / np.linalg.norm(span, axis=1, keepdims=True)
        else:
            unit = direction[rows]
        points = start[rows] + unit * t[rows, None]
        hit = part[rows]
        candidates = [s.split_parts[s.split_start[p]:s.split_start[p] + s.split_count[p]] for p in hit]
        part = part.copy()
        part[rows] = locate(s.to_face(hit, points), candidates, s.polygon, s.n_corners)
        return part


class PathVisibility:
    """Which legs of the paths through chains of mirrors to points of their last parts are free,
    in one Dr.Jit kernel per bounce order (docs/physics.md (M4)): the point from its face
    coordinates, the reflection points on the unfolded path (eq. (M3)), every leg lifted off its
    surfaces and cast. :func:`sarmitsuba.tracing.visibility.lit_pieces.legs` with :meth:`Rays.free` is its
    NumPy reference.

    Parameters
    ----------
    scene : mitsuba.Scene
    surfaces : Surfaces
    """

    def __init__(self, scene, surfaces: Surfaces):
        self.scene = scene
        a64 = mi.Array3f64
        self.origin = device_array(a64, surfaces.plane_point(np.arange(surfaces.n_parts)).T) if surfaces.n_parts \
            else None
        self.axis_u = device_array(a64, surfaces.axis_u.T) if surfaces.n_parts else None
        self.axis_v = device_array(a64, surfaces.axis_v.T) if surfaces.n_parts else None
        self.normal = device_array(a64, surfaces.normal.T) if surfaces.n_parts else None
        self.surfaces = surfaces
        self.counter = CastCounter()

    @property
    def casts(self) -> int:
        """Rays cast so far by the calling thread."""
        return self.counter.value

    def legs_clear(self, chains, chain: np.ndarray, coords: np.ndarray, antenna: np.ndarray, order: int,
                   receiver: np.ndarray | None = None) -> np.ndarray:
        """uint32 [m]: bit ``k`` set where leg ``k`` of the path to each point is free (legs ``0 ..
        order`` on the way out, from the antenna, bit ``order + 1`` the return; at the first bounce
        the one leg is both), for points ``coords`` [m, 2] (face coordinates; or their two columns
        as Dr.Jit Float64 arrays, computed on the device) on the last parts of chains ``chain``
        [m], all of bounce order ``order + 1``, seen from ``antenna`` [n_chains, 3]. Bistatic
        (``receiver`` [n_chains, 3], docs/physics.md (B2)) the return ends at the receiver and is
        its own leg at the first bounce too."""
        if len(chain) == 0:
            return np.zeros(0, np.uint32)
        if isinstance(coords, np.ndarray):
            coords = (device_array(mi.Float64, coords[:, 0]), device_array(mi.Float64, coords[:, 1]))
        a64, f64 = mi.Array3f64, mi.Float64
        ch = device_array(mi.UInt32, chain.astype(np.uint32))
        s = self.surfaces
        last = chains.last
        part = dr.gather(mi.UInt32, device_array(mi.UInt32, last.astype(np.uint32)), ch)
        ant = dr.gather(a64, device_array(a64, antenna.T), ch)
        x = (dr.gather(a64, self.origin, part) + dr.gather(a64, self.axis_u, part) * coords[0]
             + dr.gather(a64, self.axis_v, part) * coords[1])
        n_last = dr.gather(a64, self.normal, part)
        points, normals = [], []
        if order > 0:
            rows = np.arange(len(chains))
            y = _affine(ch, chains.lin[rows, order], chains.shift[rows, order], x)
            for i in range(order):
                lin, shift = chains.lin[:, i], chains.shift[:, i]
                window = chains.parts[:, i]
                n_u = np.einsum("nij,nj->ni", lin, s.normal[window])
                c_u = s.offset[window] + np.einsum("ni,ni->n", n_u, shift)
                n_u_d = dr.gather(a64, device_array(a64, n_u.T), ch)
                c_u_d = dr.gather(f64, device_array(f64, c_u), ch)
                ray = y - ant
                t = (c_u_d - dr.dot(n_u_d, ant)) / dr.dot(n_u_d, ray)
                w = ant + ray * t
                inverse = np.transpose(lin, (0, 2, 1))
                points.append(_affine(ch, inverse, -np.einsum("nij,nj->ni", inverse, shift), w))
                normals.append(dr.gather(a64, device_array(a64, s.normal[window].T), ch))
        points.append(x)
        normals.append(n_last)
        bits = mi.UInt32(0)
        for leg in range(order + 1):
            a_point = ant if leg == 0 else points[leg - 1]
            start, end = points[leg], a_point             # each ray starts on the mesh
            origin = _lifted(start, normals[leg], end)
            target = end if leg == 0 else _lifted(end, normals[leg - 1], start)
            bits |= dr.select(self._free(origin, target), mi.UInt32(1 << leg), 0)
        back = ant if receiver is None else dr.gather(a64, device_array(a64, receiver.T), ch)
        if order > 0 or receiver is not None:
            bits |= dr.select(self._free(_lifted(x, n_last, back), back), mi.UInt32(1 << (order + 1)), 0)
        with section("casts"):
            dr.eval(bits)
            bits = bits.numpy()
        self.counter.add(len(chain) * (order + 1 + (order > 0 or receiver is not None)))
        return bits

    def _free(self, origin, target):
        span = target - origin
        length = dr.norm(span)
        ray = mi.Ray3f(mi.Point3f(origin), mi.Vector3f(span / length))
        ray.maxt = mi.Float(length * (1.0 - 1e-6))
        return ~self.scene.ray_test(ray, coherent=False)


def _affine(index, lin: np.ndarray, shift: np.ndarray, point):
    """``lin point + shift`` with each lane's own ``lin`` [n, 3, 3] and ``shift`` [n, 3] (rows
    ``index``), float64."""
    a64 = mi.Array3f64
    rows = [dr.gather(a64, device_array(a64, lin[:, r].T), index) for r in range(3)]
    offset = dr.gather(a64, device_array(a64, shift.T), index)
    return a64(dr.dot(rows[0], point), dr.dot(rows[1], point), dr.dot(rows[2], point)) + offset


def _lifted(point, normal, toward):
    """``point`` moved :data:`SURFACE_LIFT` ``+ SURFACE_LIFT_RELATIVE |p|`` off its plane (unit
    ``normal``) to the side of ``toward`` (float64, Dr.Jit), as :func:`lift`."""
    side = dr.select(dr.dot(normal, toward - point) >= 0, 1.0, -1.0)
    return point + normal * (side * (SURFACE_LIFT + SURFACE_LIFT_RELATIVE * dr.norm(point)))


def _direction_and_reach(start: np.ndarray, end: np.ndarray | None, direction: np.ndarray | None):
    """Unit directions float64 [n, 3] from ``start`` toward ``end`` (or ``direction`` as given) and
    each ray's ``maxt`` [n]: just short of ``end``, else unbounded."""
    if end is None:
        return direction, np.full(len(start), np.inf)
    span = end - start
    length = np.linalg.norm(span, axis=1)
    return span / np.where(length > 0, length, 1.0)[:, None], length * (1.0 - 1e-6)
