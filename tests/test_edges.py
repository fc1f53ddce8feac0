"""Equivalent edge currents (docs/physics.md (E1)-(E6)) against independent truths: Sommerfeld's
exact half-plane solution, the PO current radiating by quadrature, closed-form limits, the
topology of boxes and plates, a line quadrature of the NumPy reference against the tracer's
terms, reciprocity, and where an edge lands in the image.

Deliberate bugs these tests were run against (each fails at least one):
  * the soft and hard polarisations swapped in the 3-D currents (the reference quadrature, HH
    against VV; the exact half plane);
  * the PO edge term's sign flipped, so the fringe adds PO instead of subtracting it (the finite
    limit at the specular direction; the PO-current quadrature);
  * the fringe added without the visibility clip (every border edge of the part, lit or not: the
    shadowed plate's edge position test);
  * the grazing leg of the double diffraction left out of the path (the reference quadrature at
    60 deg).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import trimesh
from scipy.special import fresnel

import sarmitsuba
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.pipeline import simulate
from sarmitsuba.tracing.integration import edges, junctions
from sarmitsuba.tracing.mesh.facets import mesh_parts
from sarmitsuba.tracing.mesh.patches import surfaces_from

from test_patches import WAVELENGTH, image_weights, rectangle, sensor


# --------------------------------------------------------------------------- 2-D coefficients
def _fresnel_tail(a):
    """``int_a^inf exp(-j t^2) dt`` from SciPy's Fresnel integrals."""
    z = a * math.sqrt(2.0 / math.pi)
    s, c = fresnel(z)
    return math.sqrt(math.pi) * np.exp(-0.25j * math.pi) / 2 - math.sqrt(math.pi / 2) * (c - 1j * s)


def _sommerfeld(k, rho, phi, phi_i, sign):
    """Sommerfeld's exact total field of a half-plane (face at phi = 0 and 2 pi) lit by
    ``exp(j k rho cos(phi - phi_i))``; ``sign`` -1 soft (Dirichlet), +1 hard (Neumann); time
    dependence exp(+j omega t) (Bowman, Senior and Uslenghi, *Electromagnetic and Acoustic
    Scattering by Simple Shapes*, 1969, ch. 8)."""
    root = math.sqrt(2 * k * rho)
    return np.exp(0.25j * math.pi) / math.sqrt(math.pi) * (
        np.exp(1j * k * rho * math.cos(phi - phi_i)) * _fresnel_tail(-root * math.cos((phi - phi_i) / 2))
        + sign * np.exp(1j * k * rho * math.cos(phi + phi_i)) * _fresnel_tail(-root * math.cos((phi + phi_i) / 2)))


ANGLES = [(0.4, 0.9), (0.4, 4.0), (1.0, 0.3), (1.0, 2.6), (1.3, 5.5), (2.0, 1.9), (2.0, 4.0), (2.6, 1.5)]


@pytest.mark.parametrize("phi_i, phi", ANGLES)
def test_keller_is_the_exact_half_plane_far_field(phi_i, phi):
    """The half plane's exact field minus its geometrical optics, far from the edge, is Keller's
    coefficient of (E2) with PEC factors (soft -1, hard +1), both polarisations, to 1e-3. Catches
    swapped polarisations, a wrong sign of the reflection terms, a wrong normalisation."""
    k, rho = 2 * math.pi, 2e4
    for sign, r in ((-1, -1.0), (1, 1.0)):
        total = _sommerfeld(k, rho, phi, phi_i, sign)
        geometric = (np.exp(1j * k * rho * math.cos(phi - phi_i)) if abs(phi - phi_i) < math.pi else 0) \
            + (sign * np.exp(1j * k * rho * math.cos(phi + phi_i)) if phi + phi_i < math.pi else 0)
        d = (total - geometric) * math.sqrt(rho) * np.exp(1j * k * rho)
        x = d * math.sqrt(2 * math.pi * k) * np.exp(0.25j * math.pi)
        assert x == pytest.approx(edges.keller(phi, phi_i, 2.0, r, r), abs=1e-3 * (1 + abs(x)))


@pytest.mark.parametrize("phi_i, phi", [(0.5, 0.3), (1.0, 2.0), (2.2, 1.2), (0.3, 2.5)])
def test_po_edge_term_is_the_po_current_radiating(phi_i, phi):
    """Face 0's PO current ``2 n x H_i`` on the half line x > 0, radiated by quadrature with the
    two-dimensional Green's function's far form (a slowly tapered integral), is (E3)'s PO edge
    coefficient for both polarisations. Catches a sign error in the PO term the fringe subtracts."""
    k = 2 * math.pi
    x = np.linspace(0.0, 400.0, 800001)
    taper = np.exp(-(x / 150.0) ** 2)
    integral = np.trapezoid(np.exp(1j * k * x * (math.cos(phi) + math.cos(phi_i))) * taper, x)
    green = -(k / 4) * np.sqrt(2j / (math.pi * k))        # -(k eta / 4) H0^(2) far form, eta = 1
    d_soft = green * 2 * math.sin(phi_i) * integral           # J_z = 2 sin(phi_i) E_i
    d_hard = 1j * k * math.sin(phi) / (4j) * np.sqrt(2j / (math.pi * k)) * 2 * integral   # J_x = 2 H_i
    scale = np.exp(-0.25j * math.pi) / math.sqrt(2 * math.pi * k)
    soft, hard = edges.po_edge(phi, phi_i, -1.0, -1.0)
    assert d_soft / scale == pytest.approx(soft, rel=2e-3)
    assert d_hard / scale == pytest.approx(hard, rel=2e-3)


def test_fringe_is_finite_where_po_and_keller_are_not():
    """At the half plane's specular (normal) backscatter both Keller's and PO's terms diverge; the
    fringe tends to the closed form ``(sec - 1 - tan) / 2 -> -1/2`` (soft) and
    ``-(1 + (1 - sin) / cos) / 2 -> -1/2`` (hard). A PO term of the wrong sign makes it diverge."""
    for eps in (1e-2, 1e-4):
        phi = math.pi / 2 - eps
        soft, hard = edges.fringe(phi, phi, 2.0, -1.0, -1.0, -1.0, -1.0)
        assert soft == pytest.approx((1 / math.cos(phi) - 1 - math.tan(phi)) / 2, rel=1e-6)
        assert hard == pytest.approx(-(1 + (1 - math.sin(phi)) / math.cos(phi)) / 2, rel=1e-6)
        assert soft == pytest.approx(-0.5, abs=2 * eps) and hard == pytest.approx(-0.5, abs=2 * eps)


def test_a_concave_right_angle_does_not_diffract():
    """A wall's inner corner (exterior angle pi / 2) is solved exactly by images: no diffraction
    (Keller's ``sin(pi / N)`` vanishes), so no fringe."""
    assert edges.keller(0.7, 0.4, 0.5, -1.0, -1.0) == pytest.approx(0.0, abs=1e-12)
    soft, hard = edges.fringe(0.7, 0.4, 0.5, -1.0, -1.0, -1.0, -1.0)
    assert soft == 0 and hard == 0


def test_exterior_angle_of_a_right_angle_wedge_at_two_orientations():
    """Face 0 along +x (lit from +y), face N along -y: a convex right angle, N = 3/2; face N along
    +y: a concave one, N = 1/2; no face N: the half plane, N = 2. The same wedge turned 30 deg."""
    for turn in (0.0, math.radians(30.0)):
        c, s = math.cos(turn), math.sin(turn)
        rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
        x0, n0 = rot @ [1.0, 0, 0], rot @ [0, 1.0, 0]
        got = edges.exterior_angle(np.array([x0] * 3), np.array([n0] * 3), np.array([-n0, n0, 0 * n0]))
        assert got == pytest.approx([1.5, 0.5, 2.0])


def _strip(width: float, theta: np.ndarray, polarization: str) -> np.ndarray:
    """Echo width [lambda] of a PEC strip ``width`` wavelengths wide (edges along y) from the NumPy
    reference: physical optics' closed form plus both rims' fringe fields (:func:`edges.edge_field`)
    and the doubly diffracted fields across it (:func:`edges.double_field`), per unit length
    (``sigma_2D = 2 pi |S / l|^2`` at lambda = 1, the 3-D amplitude of a length ``l`` of strip)."""
    k = 2 * math.pi
    out = []
    for th in theta:
        u = np.array([math.sin(th), 0.0, math.cos(th)])
        d = -u
        h = np.array([0.0, -1.0, 0.0])
        e = (h if polarization == "soft" else np.cross(d, h)).astype(complex)[None]
        total = -1j * width * math.cos(th) * np.sinc(2 * width * math.sin(th))
        for side in (-1.0, 1.0):
            rim = np.array([side * width / 2, 0.0, 0.0])
            frame = (np.array([[0.0, 1.0, 0.0]]), np.array([[-side, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]))
            free = np.zeros((1, 3))
            single = edges.edge_field(*frame, free, d[None], u[None], e)[0] @ e[0]
            across = -2 * rim
            double = edges.double_field(*frame, across[None], free, free, d[None], u[None], e, k)[0] @ e[0]
            total += single * np.exp(2j * k * rim @ u)
            total += double * np.exp(1j * k * ((rim + across) @ u + rim @ u - width))
        out.append(2 * math.pi * abs(total) ** 2)
    return np.asarray(out)


@pytest.mark.parametrize("width, polarization, bound", [(4.0, "soft", 0.3), (4.0, "hard", 0.5), (2.0, "soft", 0.3),
                                                        (2.0, "hard", 1.0)])
def test_strip_pattern_matches_a_moment_method_solution(width, polarization, bound):
    """A PEC strip's monostatic echo width from 0 to 60 deg, wherever the moment-method solution
    (tests/mom2d.py, which first reproduces physical optics' ``k w^2`` at normal incidence to 0.25 dB) lies
    within 25 dB of its peak: PO plus the fringe waves of both rims, plus for the hard polarisation
    the double diffraction across the sheet (E6), agree within ``bound`` dB. Catches: the double
    diffraction left out, or taken on one face of the sheet only (hard: 2 to 4 dB off at 40-60
    deg); a fringe of the wrong sign; the soft and hard coefficients swapped."""
    import mom2d
    theta = np.radians(np.arange(0.0, 60.1, 1.0))
    reference = 10 * np.log10(mom2d.strip_echo_width(width, theta, polarization))
    assert reference[0] == pytest.approx(10 * math.log10(2 * math.pi * width ** 2), abs=0.25)
    got = 10 * np.log10(_strip(width, theta, polarization))
    window = reference >= reference.max() - 25.0
    assert np.max(np.abs(got - reference)[window]) < bound, np.round((got - reference)[window], 2)


def _square_cylinder(side: float, phi: np.ndarray) -> np.ndarray:
    """Echo width [lambda] of a PEC square cylinder (soft) from the NumPy reference: PO of its lit
    faces in closed form plus the fringe of each lit corner, a right-angle wedge (``N = 3/2``, face
    0 the lit face, face N the other), per unit length."""
    k = 2 * math.pi
    corners = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float) * side / 2
    e = np.array([[0.0, 0.0, 1.0]], complex)
    out = []
    for angle in phi:
        u = np.array([math.cos(angle), math.sin(angle), 0.0])
        total = 0j
        for i in range(4):
            a, c = corners[i], corners[(i + 1) % 4]
            normal = np.cross(c - a, [0.0, 0.0, 1.0]) / side          # outward (counter-clockwise)
            if normal @ u > 0:
                total += -1j * (normal @ u) * side * np.sinc(2 * (c - a) @ u) * np.exp(2j * k * 0.5 * (a + c) @ u)
            faces = [(corners[i - 1] - a) / side, (c - a) / side]       # along each face from corner a
            outward = [np.cross([0.0, 0.0, 1.0], f) * s for f, s in zip(faces, (1.0, -1.0))]
            lit = [j for j in (0, 1) if outward[j] @ u > 1e-12]
            if lit:
                j = lit[0]
                field = edges.edge_field(np.array([[0.0, 0.0, 1.0]]), faces[j][None], outward[j][None],
                                         faces[1 - j][None], -u[None], u[None], e)
                total += (field[0] @ e[0]) * np.exp(2j * k * a @ u)
        out.append(2 * math.pi * abs(total) ** 2)
    return np.asarray(out)


def test_square_cylinder_matches_a_moment_method_solution():
    """A building's corners in two dimensions: a 2-wavelength PEC square cylinder, soft
    polarisation, monostatic from 5 to 85 deg off a face normal: PO of the lit faces plus the
    right-angle wedges' fringe (N = 3/2, both faces lit or one) follows a moment-method solution
    (tests/mom2d.py) within 0.3 dB (measured 0.13). Catches a wrong exterior angle (N = 2 or 1/2
    at a convex corner), both faces' PO not subtracted where both are lit, the lit face's
    normal on the wrong side."""
    import mom2d
    phi = np.radians(np.arange(5.0, 86.0, 5.0))
    reference = 10 * np.log10(mom2d.square_echo_width(2.0, phi))
    got = 10 * np.log10(_square_cylinder(2.0, phi))
    assert np.max(np.abs(got - reference)) < 0.3, np.round(got - reference, 2)


def test_transition_function_against_fresnel_integrals():
    """Kouyoumjian and Pathak's transition function as the kernel approximates it (edges.transition)
    against its definition through SciPy's Fresnel integrals, from X = 1e-5 to 1e4: within 0.014;
    1 far from a boundary, sqrt(pi X) exp(j pi / 4) near one. Catches a conjugated exponent or a
    wrong scale of its argument."""
    x = np.geomspace(1e-5, 1e4, 400)
    s, c = fresnel(np.sqrt(2 * x / math.pi))
    exact = 2j * np.sqrt(x) * np.exp(1j * x) * math.sqrt(math.pi / 2) * ((0.5 - c) - 1j * (0.5 - s))
    assert np.max(np.abs(edges.transition(x) - exact)) < 0.014


# --------------------------------------------------------------------------- which edges diffract
def _surfaces(meshes):
    parts = mesh_parts([(np.asarray(m.vertices, float), np.asarray(m.faces)) for m in meshes])
    n = len(meshes)
    return surfaces_from(parts, np.arange(n), np.ones(n, bool), np.zeros((n, 3)), np.tile(np.eye(3), (n, 1, 1)),
                         np.zeros(n, np.int64))


def _classify(s):
    w = edges.find_wedges(s)
    corner = np.arange(len(w.part)) - w.base[w.part]
    p2 = s.polygon[w.part, corner]
    q2 = s.polygon[w.part, np.where(corner + 1 < s.n_corners[w.part], corner + 1, 0)]
    return w, edges.segment_wedges(s, w, w.part, p2, q2)


def test_a_box_has_twelve_right_angle_wedges_and_a_plate_four_free_edges():
    """A closed box: every border edge of its six faces is a convex right-angle wedge (each of its
    12 edges seen from both faces); a plate: its four rims are free edges; an open box (no floor)
    standing on a ground plate: the foot of its walls is a junction and does not diffract, the
    ground's rim does; a closed box standing there: its wall-floor wedges (a convex corner of the
    box alone) lie on the ground, a concave corner on either side: no diffraction, its roof's
    edges diffract."""
    box = trimesh.creation.box((2.0, 3.0, 4.0))
    s = _surfaces([box])
    w, seg = _classify(s)
    assert len(w.part) == 24 and seg["on"].all() and (seg["other"] >= 0).all()
    n0 = s.normal[w.part]                                  # the box's outward normals: the lit side
    assert edges.exterior_angle(seg["x0"], n0, seg["xn"]) == pytest.approx(np.full(24, 1.5))
    plate = rectangle((0, 0, 0), (1.0, 0, 0), (0, 0.5, 0))
    _, seg = _classify(_surfaces([plate]))
    assert seg["on"].sum() == 4 and (seg["other"] == -1).all()
    open_box = trimesh.Trimesh(box.vertices + [0, 0, 2.0], box.faces[np.abs(box.face_normals[:, 2] + 1) > 1e-9])
    ground = rectangle((0, 0, 0), (10.0, 0, 0), (0, 10.0, 0))
    s = _surfaces([open_box, ground])
    w, seg = _classify(s)
    foot = (np.abs(w.start[:, 2]) < 1e-9) & (np.abs(w.end[:, 2]) < 1e-9) & (np.abs(w.start[:, 0]) < 5)
    assert foot.sum() == 4 and not seg["on"][foot].any()
    rim = np.abs(w.start[:, 0]) > 5 - 1e-9
    assert seg["on"][rim].all()
    closed = trimesh.Trimesh(box.vertices + [0, 0, 2.0], box.faces)            # its floor on the ground
    s = _surfaces([closed, ground])
    w, seg = _classify(s)
    on_ground = (np.abs(w.start[:, 2]) < 1e-9) & (np.abs(w.end[:, 2]) < 1e-9) & (np.abs(w.start[:, 0]) < 5)
    roof = (np.abs(w.start[:, 2] - 4) < 1e-9) & (np.abs(w.end[:, 2] - 4) < 1e-9)
    assert on_ground.sum() == 8 and not seg["on"][on_ground].any()     # walls' feet and the floor's rim
    assert roof.sum() == 8 and seg["on"][roof].all()


@pytest.mark.parametrize("block", [1, 3, 1 << 17])
def test_points_in_spheres_are_every_pair_within_the_radius(monkeypatch, block):
    """The junction test's candidate pairs (spheres of radii over four classes, split in blocks of
    ``block`` spheres) are exactly the brute-force pairs of distance <= radius: a class or block
    left out, a class searched at its smallest radius instead of its largest, or a strict
    inequality, loses pairs; rows not mapped back to the class's spheres gives wrong ones."""
    rng = np.random.default_rng(7)
    centre = rng.uniform(-10, 10, (40, 3))
    radius = rng.choice([0.3, 1.1, 2.9, 7.5], 40) * rng.uniform(0.6, 1.0, 40)
    point = rng.uniform(-12, 12, (500, 3))
    point[0] = centre[3] + [radius[3], 0.0, 0.0]                       # on a sphere: inside
    monkeypatch.setattr(junctions, "SPHERE_BLOCK", block)
    got = sorted((int(a), int(b)) for pairs in junctions.points_in_spheres(centre, radius, point) for a, b in zip(*pairs))
    distance = np.linalg.norm(centre[:, None] - point[None], axis=2)
    assert got == sorted(zip(*map(lambda v: v.tolist(), np.nonzero(distance <= radius[:, None]))))
    assert (3, 0) in got


def test_junctions_do_not_depend_on_the_sphere_blocks(monkeypatch):
    """The open box on the ground classified with the spheres searched a few at a time: the same
    free edges and junctions as all at once (a block's pairs dropped or counted twice changes them)."""
    box = trimesh.creation.box((2.0, 3.0, 4.0))
    open_box = trimesh.Trimesh(box.vertices + [0, 0, 2.0], box.faces[np.abs(box.face_normals[:, 2] + 1) > 1e-9])
    s = _surfaces([open_box, rectangle((0, 0, 0), (10.0, 0, 0), (0, 10.0, 0)), box])
    whole = edges.find_wedges(s)
    monkeypatch.setattr(junctions, "SPHERE_BLOCK", 2)
    split = edges.find_wedges(s)
    assert whole.junction.any() and whole.free.any()
    np.testing.assert_array_equal(whole.junction, split.junction)
    np.testing.assert_array_equal(whole.free, split.free)


def test_junctions_do_not_depend_on_the_corner_blocks(monkeypatch):
    """The open box on a 16-cornered ground and a plate, the candidate pairs tested a few at a
    time in blocks of similar corner counts: the same free edges and junctions as all at once.
    Bug: a block's results written back to the wrong points (the pairs were sorted by corners)."""
    import shapely
    box = trimesh.creation.box((2.0, 3.0, 4.0))
    open_box = trimesh.Trimesh(box.vertices + [0, 0, 2.0], box.faces[np.abs(box.face_normals[:, 2] + 1) > 1e-9])
    disc = trimesh.creation.extrude_polygon(shapely.Point(0, 0).buffer(8.0, quad_segs=4), 1.0)
    ground = trimesh.Trimesh(disc.vertices - [0, 0, 1.0], disc.faces[disc.face_normals[:, 2] > 0.5])
    s = _surfaces([open_box, ground, rectangle((6.0, 0, 0.5), (1.0, 0, 0), (0, 1.0, 0)), box])
    whole = edges.find_wedges(s)
    assert len(np.unique(s.n_corners)) > 2
    monkeypatch.setattr(junctions, "_INSIDE_BLOCK", 3)
    split = edges.find_wedges(s)
    assert whole.junction.any() and whole.free.any()
    np.testing.assert_array_equal(whole.junction, split.junction)
    np.testing.assert_array_equal(whole.free, split.free)


def test_a_finely_tessellated_curve_has_no_wedges():
    """A cylinder of 72 facets (5 deg between neighbours, below the 10 deg threshold): its side's
    vertical edges do not diffract; its rims against the caps do."""
    cyl = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=72)
    s = _surfaces([cyl])
    w, seg = _classify(s)
    vertical = np.abs(np.abs(w.direction[:, 2]) - 1) < 1e-9
    assert vertical.any() and not seg["on"][vertical].any()
    assert seg["on"][~vertical].sum() > 0


# --------------------------------------------------------------------------- the tracer
def _plate_response(sim, half, polarization):
    """The NumPy reference's image RCS of the horizontal PEC plate ``+-half`` (edges along x, y)
    [dBsm]: physical optics' closed form plus every edge's fringe (:func:`edges.edge_field`) and
    double diffraction (:func:`edges.double_field`) integrated by 100-point quadrature along the
    edge, per pulse and frequency, weighted as the focused image weighs them."""
    rhat, weight, frequencies, band = image_weights(sim, band_points=11)
    g = (np.arange(100) + 0.5) / 100 * 2 - 1
    rims = []                                           # (point [100, 3], tangent, into the plate)
    for axis in (0, 1):
        for side in (-1, 1):
            pts = np.zeros((100, 3))
            pts[:, axis] = side * half
            pts[:, 1 - axis] = g * half
            t = np.zeros(3)
            t[1 - axis] = 1.0
            x0 = np.zeros(3)
            x0[axis] = -side
            rims.append((pts, t, x0))
    num = den = 0.0
    for k in np.flatnonzero(weight > 0):
        look = -rhat[k]
        h = np.cross([0, 0, 1.0], look)
        h /= np.linalg.norm(h)
        v = np.cross(look, h)
        q = {"H": h, "V": v}[polarization[1]]
        rx = {"H": h, "V": v}[polarization[0]]
        for f, wband in zip(frequencies, band):
            kk = 2 * math.pi * f / SPEED_OF_LIGHT
            po = -1j * 2 * math.sqrt(math.pi) * f / SPEED_OF_LIGHT * abs(rhat[k][2]) * (2 * half) ** 2 \
                * np.sinc(2 * kk * rhat[k][0] * half / math.pi) * np.sinc(2 * kk * rhat[k][1] * half / math.pi)
            total = po * (rx @ q if polarization[0] == polarization[1] else 0.0)
            for pts, t, x0 in rims:
                m = len(pts)
                args = (np.tile(t, (m, 1)), np.tile(x0, (m, 1)), np.tile([0, 0, 1.0], (m, 1)))
                d, b = np.tile(look, (m, 1)), np.tile(-look, (m, 1))
                e = np.tile(q.astype(complex), (m, 1))
                single = edges.edge_field(*args, np.zeros((m, 3)), d, b, e) @ rx
                across = np.tile(2 * half * x0, (m, 1))
                double = edges.double_field(*args, across, np.zeros((m, 3)), np.zeros((m, 3)), d, b, e, kk) @ rx
                sin_i = np.linalg.norm(look - (look @ t) * t)
                phase = np.exp(2j * kk * pts @ rhat[k])
                phase2 = np.exp(1j * kk * ((pts + across) @ rhat[k] + pts @ rhat[k] - 2 * half * sin_i))
                dl = 2 * half / m
                total += math.sqrt(4 * math.pi) * dl * (np.sum(single * phase) + np.sum(double * phase2))
            wgt = (weight[k] * wband) ** 2
            num, den = num + wgt * abs(total) ** 2, den + wgt
    return 10 * math.log10(num / den)


@pytest.mark.parametrize("incidence, polarization", [(45.0, "HH"), (45.0, "VV"), (60.0, "VV"), (30.0, "HH")])
def test_tracer_terms_match_the_reference_by_quadrature(incidence, polarization):
    """A 4-wavelength horizontal PEC plate: the image's RCS with the tracer's edge terms (sinc and
    split forms, per pulse, Dr.Jit) equals the NumPy reference's PO closed form plus its fringe
    and doubly diffracted fields integrated by quadrature along each edge, within 0.3 dB. At 30
    and 60 deg the plate's PO is 20 dB below its edges, so the edge terms alone decide it."""
    half = 2 * WAVELENGTH
    plate = rectangle((0, 0, 0), (half, 0, 0), (0, half, 0))
    sim = simulate(sarmitsuba.Scene([(plate, "pec", "plate")], sensor=sensor(0.0, incidence_angle=incidence,
                                                                              polarization=polarization),
                                    integrator={"max_depth": 1}))
    got = sarmitsuba.analyze(sim.image, (0, 0, 0), raw=sim.raw).rcs_db
    assert got == pytest.approx(_plate_response(sim, half, polarization), abs=0.3)


def _mirrored_edges_rcs_db(sim, corners: np.ndarray, polarization: str) -> float:
    """The image RCS [dBsm] of the edges of the PEC triangle ``corners`` [3, 3] seen through a PEC
    ground ``z = 0``, both ways, by explicit path enumeration (image theory): every rim is lit
    by the ground's reflection of the incident wave (``d -> M d``, ``E -> -M E``, ``M = diag(1, 1,
    -1)``) and diffracts straight back (RD), and is lit directly and diffracts toward the ground,
    whose reflection carries it back (DR); each with its own fringe of :func:`edges.edge_field`,
    integrated along the rim by quadrature per pulse and frequency and weighted as the image
    weighs them (as :func:`_plate_response`)."""
    mirror = np.array([1.0, 1.0, -1.0])
    rhat, weight, frequencies, band = image_weights(sim, band_points=11)
    normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    normal /= np.linalg.norm(normal)
    g = (np.arange(100) + 0.5) / 100
    rims = []
    for i in range(3):
        a, c = corners[i], corners[(i + 1) % 3]
        t = (c - a) / np.linalg.norm(c - a)
        x0 = np.cross(normal, t)
        x0 *= np.sign(x0 @ (corners.mean(axis=0) - a))
        rims.append((a + g[:, None] * (c - a), t, x0, np.linalg.norm(c - a) / len(g)))
    num = den = 0.0
    for k in np.flatnonzero(weight > 0):
        b = rhat[k]
        d = -b
        h = np.cross([0, 0, 1.0], d)
        h /= np.linalg.norm(h)
        q = {"H": h, "V": np.cross(d, h)}[polarization[1]]
        rx = {"H": h, "V": np.cross(d, h)}[polarization[0]]
        for f, w_band in zip(frequencies, band):
            kk = 2 * math.pi * f / SPEED_OF_LIGHT
            total = 0j
            for points, t, x0, dl in rims:
                def tile(v):
                    return np.tile(v, (len(points), 1))
                free = tile(np.zeros(3))
                lit_up = normal if normal @ (mirror * d) < 0 else -normal
                rd = edges.edge_field(tile(t), tile(x0), tile(lit_up), free, tile(mirror * d), tile(b),
                                      tile(-(mirror * q)).astype(complex)) @ rx
                lit_down = normal if normal @ d < 0 else -normal
                dr_ = edges.edge_field(tile(t), tile(x0), tile(lit_down), free, tile(d), tile(mirror * b),
                                       tile(q).astype(complex)) @ -(mirror * rx)
                total += math.sqrt(4 * math.pi) * dl * np.sum((rd + dr_) * np.exp(1j * kk * points @ (b + mirror * b)))
            w = (weight[k] * w_band) ** 2
            num, den = num + w * abs(total) ** 2, den + w
    return 10 * math.log10(num / den)


@pytest.mark.parametrize("incidence, polarization", [(45.0, "HH"), (30.0, "VV")])
def test_edges_seen_in_the_ground_mirror_match_image_theory(incidence, polarization):
    """A PEC triangle standing 0.4 m above a PEC ground, facing the track: its second bounce
    order with diffraction on minus off (the edges lit through the ground's mirror) equals the
    image-theory sum of both orderings, reflected-diffracted and diffracted-reflected, each with
    its own fringe (a triangle has no opposite edges: no (E6) terms), within 0.3 dB. Catches the
    untraced reverse path left out, or taken as the transpose of the traced one (the fringe is
    not reciprocal: +6 dB at 45 deg); a wrong mirror of the field; edge terms dropped after a
    bounce."""
    corners = np.array([[-0.6, 0.0, 0.4], [0.6, 0.0, 0.4], [0.0, 0.0, 1.4]])
    triangle = trimesh.Trimesh(corners, [[0, 1, 2]], process=False)
    ground = rectangle((0, 0, 0), (2.0, 0, 0), (0, 2.0, 0))     # small: its discovery grid finds the triangle

    def order2(diffraction):
        return simulate(sarmitsuba.Scene([(triangle, "pec", "triangle"), (ground, "pec", "ground")],
                                         sensor=sensor(0.0, incidence_angle=incidence, polarization=polarization),
                                         integrator={"max_depth": 2, "split_bounces": True,
                                                     "diffraction": diffraction}))

    on, off = order2(True), order2(False)
    edges_only = dataclasses.replace(on.images_per_order[1],
                                     data=on.images_per_order[1].data - off.images_per_order[1].data)
    got = sarmitsuba.analyze(edges_only, (0, 0, 0)).rcs_db
    assert got == pytest.approx(_mirrored_edges_rcs_db(on, corners, polarization), abs=0.3)


def test_cross_polarisation_of_an_oblique_plate_is_reciprocal():
    """A plate turned 30 deg in azimuth, edges oblique to the plane of incidence: the edges give a
    cross-polarised return (PO alone gives none), and HV = VH in the image (reciprocity of the
    monostatic equivalent currents)."""
    half = 2 * WAVELENGTH
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    plate = rectangle((0, 0, 0), (half * c, half * s, 0), (-half * s, half * c, 0))
    sim = simulate(sarmitsuba.Scene([(plate, "pec", "plate")], sensor=sensor(0.0, incidence_angle=40.0,
                                                                              polarization="quad"),
                                    integrator={"max_depth": 1}))
    hv, vh, hh = (sim.channels[ch].image.data for ch in ("HV", "VH", "HH"))
    assert np.sum(np.abs(hv) ** 2) > 1e-4 * np.sum(np.abs(hh) ** 2)
    assert np.sum(np.abs(hv - vh) ** 2) < 1e-8 * np.sum(np.abs(hv) ** 2)


def test_edge_returns_sit_on_the_edges_and_only_where_lit():
    """A 2 m horizontal PEC plate at 30 deg incidence, 1.5 GHz of bandwidth (0.25 m of ground
    range resolution; PO is far below its edges there): the
    diffraction image (with minus without) peaks at the pixels of the near and far rims' midpoints
    (from their geometry, ``SarImage.pixel_of``); a wall standing across the plate's middle, which
    shadows its far half, takes the far rim's peak down by more than 10 dB (an edge no ray from
    the antenna reaches returns no fringe: the visibility clip)."""
    from test_patches import look_and_track
    half = 1.0
    look, _ = look_and_track(0.0)
    near = np.array([0.0, math.copysign(half, look[1]), 0.0])
    far = -near
    plate = rectangle((0, 0, 0), (half, 0, 0), (0, half, 0))
    wall = rectangle((0, 0, 2.0), (1.5, 0, 0), (0, 0, 2.0))     # its shadow reaches 2.3 m beyond it

    def image(rows, diffraction):
        return simulate(sarmitsuba.Scene(rows, sensor=sensor(0.0, incidence_angle=30.0, bandwidth=1.5e9),
                                         integrator={"max_depth": 1, "diffraction": diffraction}),
                        image_size=(96, 96), image_spacing=0.05).image

    def level(img, point):
        a, r = (int(round(x)) for x in img.pixel_of(point))
        return float(np.max(np.abs(img.data[a - 1:a + 2, r - 1:r + 2])))

    open_on, open_off = image([(plate, "pec", "plate")], True), image([(plate, "pec", "plate")], False)
    diff = open_on.data - open_off.data
    edges_only = dataclasses.replace(open_on, data=diff)
    a, r = np.unravel_index(np.argmax(np.abs(diff)), diff.shape)
    rims = [edges_only.pixel_of(p) for p in (near, far)]
    assert min(abs(r - rim[1]) for rim in rims) <= 1.0 and min(abs(a - rim[0]) for rim in rims) <= 3.0
    for p in (near, far):
        assert level(edges_only, p) > 0.3 * np.abs(diff).max()
    rows = [(plate, "pec", "plate"), (wall, "pec", "wall")]
    shaded = dataclasses.replace(open_on, data=image(rows, True).data - image(rows, False).data)
    assert level(shaded, far) < 10 ** (-10 / 20) * level(edges_only, far)
    assert level(shaded, near) > 10 ** (-3 / 20) * level(edges_only, near)
