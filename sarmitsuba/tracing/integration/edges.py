"""The mesh's diffracting edges and their equivalent edge currents: the fringe-wave (PTD)
correction to physical optics, docs/physics.md (E1)-(E5).

Physical optics stops a face's current at its edge; the true current does not. The difference,
the *fringe* current, radiates from the edge. Integrated across the faces it becomes an equivalent
edge current (Michaeli, IEEE TAP 32(3) 1984 and 34(7) 1986; Ufimtsev, *Fundamentals of the
Physical Theory of Diffraction*, 2007, ch. 7), whose far field per unit length of edge is written
here with the wedge's two-dimensional coefficients (Keller's minus the faces' PO, (E2), (E3)) in
the edge-fixed form of Knott's method of equivalent currents (Knott, Shaeffer and Tuley, *Radar
Cross Section*, 2nd ed., 2004, sec. 5.5), eq. (E4).

* :func:`find_wedges` -- which border edges of the scene's convex parts diffract: shared by two
  faces whose normals differ by more than :data:`WEDGE_ANGLE` (a wedge), or by no other face and
  lying on no other part (a free edge: a lone plate's rim, a half-plane);
* :func:`segment_wedges` -- the wedge of each lit boundary segment (face coordinates) that lies
  on a diffracting edge;
* :func:`keller`, :func:`po_edge`, :func:`fringe` -- the dimensionless 2-D coefficients (E2), (E3);
* :func:`edge_field` -- the fringe far field per unit length of an edge for an incident field
  (E4): the NumPy reference of the tracer's Dr.Jit evaluation
  (:class:`sarmitsuba.tracing.integration.patch_terms.PatchTerms`).

Everything is float64 NumPy; time dependence ``exp(+j omega t)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...core.arrays import unique_rows
from ..mesh.patches import Surfaces
from .ground_wave import grazing_weight
from .junctions import JUNCTION, on_other_part, part_spheres

__all__ = ["WEDGE_ANGLE", "ON_EDGE", "JUNCTION", "SINGULAR_WINDOW", "SINGULAR_STEP", "GRAZING_EDGE", "Wedges", "find_wedges",
           "boundary_clearance", "boundary_step",
           "segment_wedges", "keller", "po_edge", "fringe", "edge_field", "double_field", "exterior_angle",
           "plate_scattering", "transition", "keller_uniform"]

#: Two faces meeting at an edge diffract there when their normals differ by more than this
#: [rad] (10 deg); below it the edge is a facet of a tessellated smooth surface.
WEDGE_ANGLE = math.radians(10.0)
#: A lit segment lies on a part's border edge when both its ends are within this [m] of the
#: edge's line (relative to the part's size, plus an absolute floor).
ON_EDGE = 1e-6
#: Rounding of the line keys that group collinear border edges: directions to 1e-5, the line's
#: closest point to the frame origin to 0.1 mm.
_DIRECTION_KEY, _OFFSET_KEY = 1e5, 1e4
#: At a shadow or reflection boundary (within ``SINGULAR_WINDOW`` rad) the fringe coefficients are
#: evaluated ``SINGULAR_STEP`` rad off it: both terms of (E3) grow as one over the distance and
#: their difference is smooth, and in float32 the kernel loses ``eps / window`` of the fringe to
#: their cancellation (6e-6 at 1e-2 rad); the step costs about 1 % of the fringe (its slope is
#: about 1/4 per rad at a half plane's normal incidence).
SINGULAR_WINDOW = 1e-2
SINGULAR_STEP = 2e-2
#: Above this argument the transition function takes its asymptotic series (:func:`transition`).
TRANSITION_SERIES = 6.0
#: An edge within this sine of the line of sight (0.06 deg) returns no fringe term: the currents
#: of (E4) grow as ``1 / sin(beta)^2`` toward the edge's own direction, where the equivalent
#: currents stop describing it (the Ufimtsev singularity).
GRAZING_EDGE = 1e-3


@dataclass(frozen=True)
class Wedges:
    """The border edges of a scene's parts, grouped by line.

    Attributes
    ----------
    start, end : float64 [e, 3]
        World ends of every border edge of every part, m; edge ``base[part] + i`` runs from corner
        ``i`` to corner ``i + 1`` (counter-clockwise about the part's normal).
    part : int64 [e]
    base : int64 [n_parts]
        First edge of each part.
    group : int64 [e]
        Edges on one line (within the key's rounding) share a group.
    along : float64 [e, 2]
        The edge's extent ``[lo, hi]`` along its group's direction, m.
    free : bool [e]
        No other face's edge runs along it, and it lies on no other part: it diffracts as a
        half-plane (E1).
    direction : float64 [e, 3]
        Unit direction of each edge's group (its line), canonical sign.
    junction : bool [e]
        Another face's edge runs along it (a wedge), and it lies inside another part's polygon
        (a closed building's wall foot on the ground): that part's plane splits the outside into
        two concave corners, and it does not diffract (E1).
    """

    start: np.ndarray
    end: np.ndarray
    part: np.ndarray
    base: np.ndarray
    group: np.ndarray
    along: np.ndarray
    direction: np.ndarray
    free: np.ndarray
    junction: np.ndarray


def _line_keys(start: np.ndarray, end: np.ndarray):
    """Unit direction with a canonical sign, and integer keys of each edge's infinite line."""
    direction = end - start
    length = np.linalg.norm(direction, axis=1, keepdims=True)
    direction = direction / np.where(length > 0, length, 1.0)
    lead = np.argmax(np.abs(direction), axis=1)
    direction *= np.sign(direction[np.arange(len(direction)), lead])[:, None]
    closest = start - np.einsum("ei,ei->e", start, direction)[:, None] * direction
    keys = np.concatenate([np.round(direction * _DIRECTION_KEY), np.round(closest * _OFFSET_KEY)], axis=1)
    return direction, keys.astype(np.int64)


def find_wedges(s: Surfaces) -> Wedges:
    """The border edges of ``s``'s parts, grouped by line, with the free ones marked, eq. (E5)."""
    count = np.where(s.n_corners > 0, s.n_corners, 0)
    part = np.repeat(np.arange(s.n_parts), count)
    corner = np.arange(len(part)) - np.repeat(np.cumsum(count) - count, count)
    base = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    nxt = np.where(corner + 1 < s.n_corners[part], corner + 1, 0)
    start = s.to_world(part, s.polygon[part, corner])
    end = s.to_world(part, s.polygon[part, nxt])
    direction, keys = _line_keys(start, end)
    if len(part):
        _, group = unique_rows(keys, return_inverse=True)
    else:
        group = np.zeros(0, np.int64)
    # the group's direction is its first edge's (the keys' rounding lets members differ slightly)
    first = np.zeros(int(group.max(initial=-1)) + 1, np.int64)
    first[group[::-1]] = np.arange(len(group))[::-1]
    gdir = direction[first[group]] if len(group) else direction
    t0, t1 = np.einsum("ei,ei->e", start, gdir), np.einsum("ei,ei->e", end, gdir)
    along = np.stack([np.minimum(t0, t1), np.maximum(t0, t1)], axis=1)
    wedges = Wedges(start=start, end=end, part=part, base=base, group=group, along=along, direction=gdir,
                    free=np.zeros(len(part), bool), junction=np.zeros(len(part), bool))
    mid = 0.5 * (start + end)
    shared = _partners_at(s, wedges, np.arange(len(part)), np.einsum("ei,ei->e", mid, gdir), any_face=True) >= -1
    free = np.zeros(len(part), bool)
    candidate = np.flatnonzero(~shared)
    spheres = part_spheres(s)
    free[candidate] = ~on_other_part(s, part[candidate], mid[candidate], spheres=spheres)
    junction = np.zeros(len(part), bool)
    candidate = np.flatnonzero(shared)
    junction[candidate] = on_other_part(s, part[candidate], mid[candidate], strict=True, spheres=spheres)
    return Wedges(start=start, end=end, part=part, base=base, group=group, along=along, direction=gdir, free=free,
                  junction=junction)


def _partners_at(s: Surfaces, w: Wedges, edge: np.ndarray, t: np.ndarray, any_face: bool = False) -> np.ndarray:
    """For each queried border edge ``edge`` [q] at position ``t`` [q] along its line: the part of
    another face whose border edge runs along the same line over ``t`` and whose normal differs by
    more than :data:`WEDGE_ANGLE` (the lowest such part), ``-1`` where another face's edge runs
    there at a smaller angle (a smooth crease or a coplanar neighbour), ``-2`` where none does.
    ``any_face``: ``-1`` for any other face's edge (the smooth test skipped)."""
    out = np.full(len(edge), -2, np.int64)
    if len(edge) == 0:
        return out
    order, group_start = _cached(w, "group_order", lambda: _group_order(w))
    lo = group_start[w.group[edge]]
    size = group_start[w.group[edge] + 1] - lo
    q = np.repeat(np.arange(len(edge)), size)
    other = order[np.repeat(lo, size) + (np.arange(int(size.sum())) - np.repeat(np.cumsum(size) - size, size))]
    a, b = w.part[edge[q]], w.part[other]
    tol = 1e-6 * (1.0 + np.abs(t[q]))
    keep = (s.face[a] != s.face[b]) & (w.along[other, 0] - tol <= t[q]) & (t[q] <= w.along[other, 1] + tol)
    q, b = q[keep], b[keep]
    if any_face:
        out[q] = -1
        return out
    cos = np.abs(np.einsum("ei,ei->e", s.normal[w.part[edge[q]]], s.normal[b]))
    sharp = cos < math.cos(WEDGE_ANGLE)
    out[q[~sharp]] = -1
    best = np.full(len(edge), np.iinfo(np.int64).max)
    np.minimum.at(best, q[sharp], b[sharp])
    has = best < np.iinfo(np.int64).max
    out[has] = best[has]
    return out


def _cached(w: Wedges, name: str, make):
    """A value computed once per :class:`Wedges` (kept in its ``__dict__``: it is frozen)."""
    if name not in w.__dict__:
        object.__setattr__(w, name, make())
    return w.__dict__[name]


def _group_order(w: Wedges):
    """The edges sorted by group (stable), and where each group starts in that order (int64
    [n_groups + 1]: group ``g`` is ``order[start[g]:start[g + 1]]``)."""
    order = np.argsort(w.group, kind="stable")
    start = np.concatenate([[0], np.cumsum(np.bincount(w.group, minlength=int(w.group.max(initial=-1)) + 1))])
    return order, start.astype(np.int64)


def _part_edges(s: Surfaces):
    """Every part's polygon edges (corner ``i`` to ``i + 1`` over all slots): length float64
    [n_parts, V] and unit direction [n_parts, V, 2] (face coordinates)."""
    edge = np.roll(s.polygon, -1, axis=1) - s.polygon
    length = np.linalg.norm(edge, axis=2)
    return length, edge / np.maximum(length, 1e-30)[..., None]


def _part_centres(s: Surfaces) -> np.ndarray:
    """float64 [n_parts, 3]: the mean of each part's corners (world), as :func:`_into` takes it."""
    part = np.arange(s.n_parts)
    corners = s.to_world(part, s.polygon)
    valid = np.arange(corners.shape[1])[None, :] < s.n_corners[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sum(corners * valid[..., None], axis=1) / s.n_corners[:, None]


def segment_wedges(s: Surfaces, w: Wedges, part: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> dict:
    """The diffracting edge under each lit segment ``(part [m], p2, q2 [m, 2] face coordinates)``.

    Returns a dict of arrays [m]: ``on`` (bool: the segment lies on a free edge or a wedge of
    :func:`find_wedges`), ``x0`` float64 [m, 3] (unit, in the part's plane, normal to the edge,
    pointing into the part), ``xn`` float64 [m, 3] (the same for the wedge's other face; zero on a
    free edge), ``other`` int64 (the other face's part, -1 on a free edge)."""
    m = len(part)
    out = dict(on=np.zeros(m, bool), x0=np.zeros((m, 3)), xn=np.zeros((m, 3)), other=np.full(m, -1, np.int64))
    if m == 0 or len(w.part) == 0:
        return out
    poly = np.take(s.polygon, part, axis=0)            # (np.take: row gathers ~10x faster than x[idx])
    length_all, unit_all = _cached(w, "part_edges", lambda: _part_edges(s))
    length, unit = np.take(length_all, part, axis=0), np.take(unit_all, part, axis=0)

    def distance(x):
        rel = x[:, None, :] - poly
        return np.abs(unit[..., 0] * rel[..., 1] - unit[..., 1] * rel[..., 0])

    scale = ON_EDGE * (1.0 + length)
    valid = (np.arange(poly.shape[1])[None, :] < np.take(s.n_corners, part)[:, None]) & (length > 0)
    fits = valid & (distance(p2) <= scale) & (distance(q2) <= scale)
    rows = np.flatnonzero(np.any(fits, axis=1))
    if len(rows) == 0:
        return out
    corner = np.argmax(fits[rows], axis=1)
    e = w.base[part[rows]] + corner
    mid = s.to_world(part[rows], 0.5 * (p2[rows] + q2[rows]))
    t = np.einsum("ei,ei->e", mid, w.direction[e])
    other = _partners_at(s, w, e, t)
    wedge = (other >= 0) & ~w.junction[e]
    free = (other == -2) & w.free[e]
    on = wedge | free
    rows, e, other, corner, mid = rows[on], e[on], other[on], corner[on], mid[on]
    tangent = w.direction[e]
    a = part[rows]
    out["on"][rows] = True
    centres = _cached(w, "part_centres", lambda: _part_centres(s))
    x0 = _into(s, a, tangent, mid, centres)
    out["x0"][rows] = x0
    b = other >= 0
    if np.any(b):
        out["xn"][rows[b]] = _into(s, other[b], tangent[b], mid[b], centres)
        out["other"][rows[b]] = other[b]
    _opposite(s, w, out, rows, a, corner, unit, mid, x0, centres)
    return out


def _opposite(s: Surfaces, w: Wedges, out: dict, rows, part, corner, unit, mid, x0, centres=None) -> None:
    """The diffracting edge across the part from each segment's midpoint, eq. (E6): an edge of the
    same part running the other way (within 1 deg), which the line from the midpoint along ``x0``
    (into the part) meets within its extent, and which diffracts there. Sets ``out["across"]``
    (float64 [m, 3]: the vector from the midpoint to that point, zero where there is none) and
    ``out["xn_across"]`` (into that edge's other face; zero on a free edge)."""
    m = len(out["on"])
    out["across"], out["xn_across"] = np.zeros((m, 3)), np.zeros((m, 3))
    if len(rows) == 0:
        return
    own = unit[rows, corner]                                        # [r, 2] the segment's edge direction
    anti = np.einsum("rvi,ri->rv", unit[rows], own) < -math.cos(math.radians(1.0))
    slots = np.arange(unit.shape[1])[None, :] < s.n_corners[part][:, None]
    anti &= slots
    r, j = np.nonzero(anti)
    if len(r) == 0:
        return
    e = w.base[part[r]] + j
    start, end = w.start[e], w.end[e]
    direction = end - start
    length = np.linalg.norm(direction, axis=1)
    direction /= np.maximum(length, 1e-30)[:, None]
    # where the line mid + lambda x0 meets edge j (both lie in the part's plane)
    rel = mid[r] - start
    ortho = x0[r] - np.einsum("ri,ri->r", x0[r], direction)[:, None] * direction
    reach = np.einsum("ri,ri->r", ortho, ortho)
    lam = -np.einsum("ri,ri->r", rel, ortho) / np.maximum(reach, 1e-30)
    hit = mid[r] + lam[:, None] * x0[r]
    along = np.einsum("ri,ri->r", hit - start, direction)
    ok = (lam > 0) & (along >= 0) & (along <= length)
    r, e, hit, lam = r[ok], e[ok], hit[ok], lam[ok]
    if len(r) == 0:
        return
    first = np.unique(r, return_index=True)[1]                      # one opposite edge per segment
    r, e, hit, lam = r[first], e[first], hit[first], lam[first]
    other = _partners_at(s, w, e, np.einsum("ri,ri->r", hit, w.direction[e]))
    diffracts = (other >= 0) | ((other == -2) & w.free[e])
    r, e, hit, other = r[diffracts], e[diffracts], hit[diffracts], other[diffracts]
    out["across"][rows[r]] = hit - mid[r]
    b = other >= 0
    if np.any(b):
        out["xn_across"][rows[r[b]]] = _into(s, other[b], w.direction[e[b]], hit[b], centres)


def _into(s: Surfaces, part: np.ndarray, tangent: np.ndarray, point: np.ndarray, centres=None) -> np.ndarray:
    """Unit vector in ``part``'s plane, normal to ``tangent``, from ``point`` (on its border)
    toward the part's interior (its corners' mean; ``centres`` [n_parts, 3] those of every part,
    :func:`_part_centres`, else computed here)."""
    x = np.cross(s.normal[part], tangent)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    if centres is not None:
        centre = centres[part]
    else:
        corners = np.take(s.world_polygon, part, axis=0)
        valid = np.arange(corners.shape[1])[None, :] < s.n_corners[part][:, None]
        centre = np.sum(corners * valid[..., None], axis=1) / s.n_corners[part][:, None]
    return x * np.where(np.einsum("ei,ei->e", centre - point, x) >= 0, 1.0, -1.0)[:, None]


# ---------------------------------------------------------------------------------------------
# The two-dimensional coefficients, docs/physics.md (E2), (E3)
def exterior_angle(x0: np.ndarray, n0: np.ndarray, xn: np.ndarray) -> np.ndarray:
    """The wedge's exterior angle over pi, ``N`` [m], eq. (E1): the angle from face 0 (``x0``,
    into it) through the side of its normal ``n0`` (the illuminated side) to face N (``xn``); 2
    for a free edge (``xn`` zero: the half-plane). ``N <= 1`` is a concave corner."""
    psi = np.arctan2(np.einsum("mi,mi->m", xn, n0), np.einsum("mi,mi->m", xn, x0))
    n = np.where(psi >= 0, psi, 2 * np.pi + psi) / np.pi
    return np.where(np.linalg.norm(xn, axis=-1) > 0, n, 2.0)


def keller(phi, phi_i, n, r0, rn):
    """Keller's wedge coefficient over ``exp(-j pi/4) / sqrt(2 pi k)``, eq. (E2): the four-cotangent
    form, with ``r0``, ``rn`` the reflection factors of faces 0 and N (-1 for the soft, +1 for the
    hard polarisation of a PEC; otherwise Luebbers' heuristic). Angles in rad from face 0."""
    def cot(x):
        return np.cos(x) / np.sin(x)
    m, p = phi - phi_i, phi + phi_i
    return -(cot((np.pi + m) / (2 * n)) + cot((np.pi - m) / (2 * n)) + r0 * cot((np.pi - p) / (2 * n))
             + rn * cot((np.pi + p) / (2 * n))) / (2 * n)


def transition(x):
    """Kouyoumjian and Pathak's transition function ``F(X) = 2 j sqrt(X) exp(j X) int_sqrt(X)^inf
    exp(-j t^2) dt`` (Proc. IEEE 62(11), 1974; time dependence ``exp(+j omega t)``), eq. (E6): below
    ``X = 6`` as ``sqrt(2 pi X) (f(z) + j g(z))`` with ``z = sqrt(2 X / pi)`` and the auxiliary
    Fresnel functions ``f``, ``g`` by Abramowitz and Stegun's rational approximations 7.3.32 and
    7.3.33; above, its asymptotic series ``1 + j / (2 X) - 3 / (4 X^2) - 15 j / (8 X^3) + 75 /
    (16 X^4)``. Within 0.013 of the exact value everywhere (tests/test_edges.py, against SciPy's
    Fresnel integrals): 1 far from a shadow boundary, ``sqrt(pi X) exp(j pi / 4)`` at it. The
    kernel (:mod:`sarmitsuba.tracing.integration.edge_terms`) uses the same approximation."""
    x = np.asarray(x, float)
    z = np.sqrt(2.0 * x / np.pi)
    f = (1.0 + 0.926 * z) / (2.0 + 1.792 * z + 3.104 * z * z)
    g = 1.0 / (2.0 + 4.142 * z + 3.492 * z * z + 6.670 * z ** 3)
    inv = 1.0 / np.maximum(x, TRANSITION_SERIES)
    series = 1.0 - 0.75 * inv ** 2 + 75.0 / 16.0 * inv ** 4 + 1j * (0.5 * inv - 15.0 / 8.0 * inv ** 3)
    return np.where(x < TRANSITION_SERIES, np.sqrt(2.0 * np.pi * x) * (f + 1j * g), series)


def keller_uniform(phi, phi_i, n, r0, rn, kl):
    """:func:`keller` with each of its four terms times :func:`transition` of ``kl a``: the uniform
    coefficient (Kouyoumjian and Pathak 1974), finite across the shadow and reflection boundaries
    where Keller's is not; ``kl = k L`` with ``L`` the distance parameter [rad], ``a^+-(beta) =
    2 cos^2((2 pi N n^+- - beta) / 2)``, ``n^+-`` the integers nearest ``(beta +- pi) / (2 pi N)``."""
    def cot(x):
        return np.cos(x) / np.sin(x)

    def a(beta, sign):
        whole = np.round((beta + sign * np.pi) / (2 * np.pi * n))
        return 2.0 * np.cos((2 * np.pi * n * whole - beta) / 2) ** 2
    m, p = phi - phi_i, phi + phi_i
    return -(cot((np.pi + m) / (2 * n)) * transition(kl * a(m, 1)) + cot((np.pi - m) / (2 * n)) * transition(kl * a(m, -1))
             + r0 * cot((np.pi - p) / (2 * n)) * transition(kl * a(p, -1))
             + rn * cot((np.pi + p) / (2 * n)) * transition(kl * a(p, 1))) / (2 * n)


def po_edge(phi, phi_i, r_te, r_tm):
    """Physical optics' edge coefficient of face 0 (lit, the edge at its end), over the same
    factor, eq. (E3): ``(soft, hard) = (-r_te sin phi_i, r_tm sin phi) / (cos phi + cos phi_i)``
    (``r_te``, ``r_tm`` the face's reflection coefficients of (R), PEC -1, -1)."""
    den = np.cos(phi) + np.cos(phi_i)
    return -r_te * np.sin(phi_i) / den, r_tm * np.sin(phi) / den


def fringe(phi, phi_i, n, r_te0, r_tm0, r_ten, r_tmn):
    """The fringe coefficients ``(X_s, X_h)`` (complex), eq. (E3): Keller's minus the PO edge
    terms of the faces that are lit and seen, face 0 at ``(phi, phi_i)``, face N at
    ``(n pi - phi, n pi - phi_i)``. Zero for a concave corner (``n <= 1``)."""
    phi, phi_i, n = np.broadcast_arrays(*(np.asarray(a, float) for a in (phi, phi_i, n)))
    convex = n > 1.0
    nn = np.where(convex, n, 2.0)
    xs = keller(phi, phi_i, nn, r_te0, r_ten)
    xh = keller(phi, phi_i, nn, -r_tm0, -r_tmn)
    lit0 = (phi_i > 0) & (phi_i < np.pi) & (phi > 0) & (phi < np.pi)
    s0, h0 = po_edge(phi, phi_i, r_te0, r_tm0)
    pn, pin = nn * np.pi - phi, nn * np.pi - phi_i
    litn = (pin > 0) & (pin < np.pi) & (pn > 0) & (pn < np.pi)
    sn, hn = po_edge(pn, pin, r_ten, r_tmn)
    xs = xs - np.where(lit0, s0, 0) - np.where(litn, sn, 0)
    xh = xh - np.where(lit0, h0, 0) - np.where(litn, hn, 0)
    return np.where(convex, xs, 0), np.where(convex, xh, 0)


def boundary_clearance(phi, phi_i, n):
    """The distance [rad] of ``(phi, phi_i)`` from the nearest shadow or reflection boundary of
    either face, where Keller's and PO's terms of (E3) are both infinite: ``phi -+ phi_i = +-pi``
    and ``2 n pi - phi - phi_i = +-pi`` (``n`` of a convex wedge)."""
    out = np.full(np.shape(phi), np.inf)
    for x in (phi - phi_i, phi + phi_i, 2 * n * np.pi - phi - phi_i):
        out = np.minimum(out, np.minimum(np.abs(x - np.pi), np.abs(x + np.pi)))
    return out


def boundary_step(phi, phi_i, n):
    """The step [rad] added to ``phi_i`` before the fringe coefficients are evaluated at
    ``(phi, phi_i)``, eq. (E3): 0 at least :data:`SINGULAR_WINDOW` off every boundary, else
    ``+SINGULAR_STEP``, or ``-SINGULAR_STEP`` where the step up lands within the window of another
    boundary and the step down lands farther. Two boundaries cross where the incidence grazes a
    face (``phi_i -> 0``: the shadow and reflection boundaries lie ``2 phi_i`` apart), and no three
    cross for a convex wedge, so one of the two steps always clears both by the window."""
    phi, phi_i, n = np.broadcast_arrays(*(np.asarray(a, float) for a in (phi, phi_i, n)))
    up = boundary_clearance(phi, phi_i + SINGULAR_STEP, n)
    down = boundary_clearance(phi, phi_i - SINGULAR_STEP, n)
    step = np.where((up >= SINGULAR_WINDOW) | (up >= down), SINGULAR_STEP, -SINGULAR_STEP)
    return np.where(boundary_clearance(phi, phi_i, n) < SINGULAR_WINDOW, step, 0.0)


def _angle(v, t, x0, n0):
    """``(phi in [0, 2 pi), sin beta)`` of unit direction ``v`` about the edge ``t``, from face 0."""
    perp = v - np.einsum("mi,mi->m", v, t)[:, None] * t
    phi = np.arctan2(np.einsum("mi,mi->m", perp, n0), np.einsum("mi,mi->m", perp, x0))
    return np.where(phi < 0, phi + 2 * np.pi, phi), np.linalg.norm(perp, axis=1)


def edge_field(t, x0, n0, xn, d, b, field, r0=(-1.0, -1.0), rn=(-1.0, -1.0), reverse: bool = False):
    """The fringe far field per unit length of edge, eq. (E4) (complex [m, 3]): scattered toward
    ``b`` (unit, toward the receiver) for the incident ``field`` [m, 3] (complex, normal to ``d``)
    arriving along ``d`` (unit); ``E_s = F exp(-j k R) / R`` per metre of edge, phase referred to
    the edge point. ``t`` [m, 3] the edge's unit tangent (either sense), ``x0`` into face 0 (the lit
    face), ``n0`` its normal on the lit side, ``xn`` into face N (zero: a free edge). ``r0``,
    ``rn``: ``(r_te, r_tm)`` of faces 0 and N at their own incidence (PEC by default).
    ``reverse``: add the fringe of the reverse path (arriving along ``-b``, leaving along ``-d``)
    in the same frame: for an edge after mirrors, whose reverse path is not traced (E4)."""
    t, x0, n0, xn, d, b = (np.asarray(a, float) for a in (t, x0, n0, xn, d, b))
    phi_i, sin_i = _angle(-d, t, x0, n0)
    phi, sin_s = _angle(b, t, x0, n0)
    n = exterior_angle(x0, n0, xn)
    nn = np.where(n > 1, n, 2.0)
    xs, xh = fringe(phi, phi_i + boundary_step(phi, phi_i, nn), n, *r0, *rn)
    if reverse:
        back_s, back_h = fringe(phi_i, phi + boundary_step(phi_i, phi, nn), n, *r0, *rn)
        xs, xh = xs + back_s, xh + back_h
    ok = (sin_i > GRAZING_EDGE) & (sin_s > GRAZING_EDGE) & (phi < np.where(n > 1, n, 2.0) * np.pi)
    c_e = np.where(ok, xs / (2 * np.pi * np.maximum(sin_i, GRAZING_EDGE)**2), 0)
    c_m = np.where(ok, -xh / (2 * np.pi * np.maximum(sin_i * sin_s, GRAZING_EDGE**2)), 0)
    e_t = np.einsum("mi,mi->m", field, t)
    e_m = np.einsum("mi,mi->m", field, np.cross(t, d))
    along = t - np.einsum("mi,mi->m", b, t)[:, None] * b
    return (c_e * e_t)[:, None] * along + (c_m * e_m)[:, None] * np.cross(b, t)


def double_field(t, x0, n0, across, xn1, xn2, d, b, field, k, reverse: bool = False, delta=0.0):
    """The doubly diffracted far field per unit length of edge 2, eq. (E6) (complex [m, 3]): the
    wave of wavenumber ``k`` [rad/m] that edge 1 (at ``across`` [m, 3] from the point, running the
    other way; ``xn1`` into its other face) diffracts along the face, grazing, diffracted by edge 2
    (``t``, ``x0``, ``n0``, ``xn2`` as in :func:`edge_field`) toward ``b``. Phase referred to the
    incident wave at the point across plus the grazing leg ``|across| sin(beta')``, which the
    caller adds to the path. Hard polarisation only. ``reverse``: with the reverse path (edge 2
    first), its transpose by reciprocity: twice the field (E6). ``delta``: the face's normalised
    surface impedance at grazing (:func:`sarmitsuba.scene.materials.grazing_impedance`; 0, the
    default, for a perfect conductor): the grazing wave arrives as Norton's ground wave over its
    path ``|across| / sin(beta')`` (:func:`sarmitsuba.tracing.integration.ground_wave.grazing_weight`)."""
    t, x0, n0, across, xn1, xn2, d, b = (np.asarray(a, float) for a in (t, x0, n0, across, xn1, xn2, d, b))
    phi, sin_s = _angle(b, t, x0, n0)
    phi_1, sin_i = _angle(-d, t, -x0, n0)
    n1, n2 = exterior_angle(-x0, n0, xn1), exterior_angle(x0, n0, xn2)
    w = np.linalg.norm(across, axis=1)
    # the uniform coefficients over the distance across (L = w sin(beta')): the grazing wave runs
    # along a boundary of edge 1 where the incidence grazes the face, and edge 2 sees the receiver
    # near its own as the receiver nears the face's plane
    kl = k * w * sin_i
    x_1 = keller_uniform(0.0, phi_1, n1, 1.0, 1.0, kl)     # hard: toward the face, grazing
    x_2 = 0.5 * keller_uniform(phi, 0.0, n2, 1.0, 1.0, kl)  # half: grazing incidence
    # a sheet (both edges free) carries the grazing wave on its front and its back face: the two
    # arrive at edge 2 with opposite signs and leave with opposite coefficients, so they add
    sheet = np.where(~np.any(xn1 != 0, axis=1) & ~np.any(xn2 != 0, axis=1), 2.0, 1.0)
    sheet = sheet * grazing_weight(delta, k * w / np.maximum(sin_i, GRAZING_EDGE))
    g = sheet * np.exp(-0.25j * np.pi) * x_1 / np.sqrt(2 * np.pi * k * w * sin_i)
    ok = (n1 > 1) & (n2 > 1) & (sin_i > GRAZING_EDGE) & (sin_s > GRAZING_EDGE) & (phi < np.pi)
    c_m = np.where(ok, -g * x_2 / (2 * np.pi * np.maximum(sin_i * sin_s, GRAZING_EDGE**2)), 0)
    e_m = np.einsum("mi,mi->m", field, np.cross(t, d))
    return (2.0 if reverse else 1.0) * (c_m * e_m)[:, None] * np.cross(b, t)


def plate_scattering(corners: np.ndarray, k: float, toward: np.ndarray, points: int = 400) -> dict:
    """The monostatic scattering matrix of a lone flat PEC polygon (a sheet: every rim a free edge)
    by the NumPy reference: physical optics in closed form
    (:func:`sarmitsuba.tracing.integration.physical_optics.polygon_integral`), every rim's fringe field (E4)
    and the double diffraction across the sheet between anti-parallel rims (E6), integrated
    along the rims by ``points``-point midpoint quadrature. Plane-wave incidence, far field,
    phase referred to the origin; what the tracer evaluates per pulse without the lit-region
    clipping (the whole sheet is lit).

    Parameters
    ----------
    corners : float64 [c, 3]
        The polygon's corners in order [m], convex.
    k : float
        Wavenumber [rad/m].
    toward : float64 [n, 3]
        Unit directions from the plate to the radar (the incident wave travels along ``-toward``).

    Returns
    -------
    dict
        ``"hh"``, ``"hv"``, ``"vh"``, ``"vv"`` (first letter receive) -> complex [n]: ``S`` with
        ``E_s = S exp(-j k R) / R`` for a unit incident field, ``sigma = 4 pi |S|^2``; H and V in
        the backscatter alignment of docs/physics.md (P1) (``h = z x l / |z x l|``, ``v = l x h``,
        ``l = -toward``).
    """
    from .physical_optics import polygon_integral
    corners = np.asarray(corners, float)
    toward = np.atleast_2d(np.asarray(toward, float))
    normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    normal /= np.linalg.norm(normal)
    centre = corners.mean(axis=0)
    g = (np.arange(points) + 0.5) / points
    rims = []
    for i in range(len(corners)):
        a, c = corners[i], corners[(i + 1) % len(corners)]
        t = (c - a) / np.linalg.norm(c - a)
        x0 = np.cross(normal, t)
        x0 *= np.sign(x0 @ (centre - a))
        rims.append((a + g[:, None] * (c - a), t, x0, np.linalg.norm(c - a) / points))
    out = {c: np.zeros(len(toward), complex) for c in ("hh", "hv", "vh", "vv")}
    for m, b in enumerate(toward):
        d = -b
        h = np.cross([0.0, 0.0, 1.0], d)
        h = h / np.linalg.norm(h) if np.linalg.norm(h) > 1e-12 else np.array([1.0, 0.0, 0.0])
        basis = {"h": h, "v": np.cross(d, h)}
        n0 = normal if normal @ d < 0 else -normal
        po = -1j * k / (2 * np.pi) * abs(n0 @ b) * polygon_integral(corners, normal, 2 * k * b)
        for tx in "hv":
            field = basis[tx].astype(complex)
            scattered = po * basis[tx]                      # the far field [3]: PO, then every rim's terms
            for p, t, x0, dl in rims:
                def tile(v):
                    return np.tile(v, (len(p), 1))
                free = tile(np.zeros(3))
                single = edge_field(tile(t), tile(x0), tile(n0), free, tile(d), tile(b), tile(field))
                scattered = scattered + dl * np.exp(2j * k * p @ b) @ single
                for q, s, _, _ in rims:                       # the rim across, running the other way
                    if s @ t > -np.cos(np.radians(1.0)):
                        continue
                    width = (q[0] - p[0]) @ x0
                    double = double_field(tile(t), tile(x0), tile(n0), tile(width * x0), free, free, tile(d), tile(b),
                                          tile(field), k)
                    sin_i = np.linalg.norm(d - (d @ t) * t)
                    scattered = scattered + dl * np.exp(1j * k * ((p + width * x0) @ b + p @ b - width * sin_i)) @ double
            for rx in "hv":
                out[rx + tx][m] = basis[rx] @ scattered
    return out
