"""Two holes a mutation audit found in the tests of the edge (diffraction) code, docs/physics.md
(E1), (E4), closed against independent truths: hand-worked topology (which edges of a box and a
leaning plate touch another face), image theory (the fringe of one wedge edge lit through a
ground mirror, both orderings of its path, from the NumPy reference :func:`edges.edge_field`) and
that reference's quadrature of a ridge seen directly; each wedge's term counted exactly once.
The geometry is oblique throughout (heading 20 deg, incidence 35 deg, faces turned 25 deg off the
look, a ground sloping 12 deg), so that no sine equals its cosine.

Deliberate bugs these tests were run against (each fails at least one):
  * the deferral rule of a wedge's fringe (``EdgeTerms.fringe``, sarmitsuba/tracing/integration/edge_terms.py:
    face N "lit and seen" taken as "lit or seen"): an edge lit through a mirror whose other face
    is lit but not seen is carried by neither face (the mirrored wedge's image theory: 10 dB
    off; the parts' order: -4 dB against bit-identical);
  * the same rule's ``carry = ~(wedge_defer & lit_n)`` with ``|`` (the mirrored wedge, 10 dB;
    the ridge);
  * the lanes' deferral flag ``wedge_defer = (other >= 0) & (other < lane_part)`` with ``|``
    (term_lanes.py: every wedge lane defers, so a wedge lit and seen on both faces is carried by
    neither: the ridge, 3.4 dB high);
  * the junction tolerance ``junctions.JUNCTION`` 100 times looser (1e-1 m for 1e-3 m): edges 2 and
    5 cm off another face stop diffracting (the topology counts).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.pipeline import simulate
from sarmitsuba.tracing.integration import edges
from sarmitsuba.tracing.integration import patch_terms as integration

from test_edges import _surfaces
from test_patches import image_weights, look_and_track, rectangle, sensor


# --------------------------------------------------------------------------- hole 6: junctions
def _classify(s):
    """Every border edge of every part (as :func:`edges.find_wedges` lists them) and the
    diffracting edge under it when the whole edge is taken as a lit segment."""
    w = edges.find_wedges(s)
    corner = np.arange(len(w.part)) - w.base[w.part]
    p2 = s.polygon[w.part, corner]
    q2 = s.polygon[w.part, np.where(corner + 1 < s.n_corners[w.part], corner + 1, 0)]
    return w, edges.segment_wedges(s, w, w.part, p2, q2)


def _rotation(axis, angle_deg: float) -> np.ndarray:
    """Rodrigues' rotation by ``angle_deg`` about ``axis``."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    a = math.radians(angle_deg)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * cross + (1 - math.cos(a)) * cross @ cross


def _sloping_scene(gap: float):
    """A 3 m square ground sloping 12 deg (about a horizontal axis at 30 deg), and above it, ``gap``
    [m] off its plane along its normal: a closed box 0.8 x 0.5 x 0.4 m turned 25 deg about the
    ground's normal, its floor parallel to the ground, and a 0.6 x 0.3 m plate leaning at 35 deg
    whose lower rim runs parallel to the ground (the rim's direction 25 deg + 90 deg off the
    ground's first axis). Returns the meshes and the ground's unit normal (its plane holds the
    origin)."""
    tilt = _rotation([math.cos(math.radians(30)), math.sin(math.radians(30)), 0.0], 12.0)
    u, v, normal = tilt[:, 0], tilt[:, 1], tilt[:, 2]
    ground = rectangle((0, 0, 0), 1.5 * u, 1.5 * v)
    frame = tilt @ _rotation([0, 0, 1.0], 25.0)             # the box's axes: turned about the normal
    box = trimesh.creation.box((0.8, 0.5, 0.4))
    vertices = (box.vertices + [0, 0, 0.2 + gap]) @ frame.T + (-0.4 * u + 0.3 * v)
    box = trimesh.Trimesh(vertices, box.faces, process=False)
    rim = frame[:, 1]                                        # in the ground's plane
    rise = math.cos(math.radians(35)) * frame[:, 0] + math.sin(math.radians(35)) * normal
    foot = 0.6 * u - 0.5 * v + gap * normal
    plate = trimesh.Trimesh([foot - 0.3 * rim, foot + 0.3 * rim, foot + 0.3 * rim + 0.6 * rise,
                             foot - 0.3 * rim + 0.6 * rise], [[0, 1, 2], [0, 2, 3]], process=False)
    return [box, plate, ground], normal


@pytest.mark.parametrize("gap", [0.02, 0.05])
def test_edges_a_few_centimetres_off_another_face_still_diffract(gap):
    """Hand-worked topology: a closed box hovering ``gap`` = 2 or 5 cm above a sloping ground
    touches nothing, so all 12 of its edges are convex right-angle wedges, each listed from both
    its faces (24 diffracting border edges with a partner face, exterior angle 3/2 pi, those of its
    floor included); a plate leaning with its lower rim ``gap`` above the ground has four free rims
    (half-planes, no partner); the ground's four rims are free. The edges near the ground are
    found as the ones within ``gap`` + 1 mm of its plane (8 box entries, 1 plate rim), to check
    that the case is the one meant. Caught: ``junctions.JUNCTION`` 1e-1 m for 1e-3 m (the floor's 8
    wedge entries taken for junctions, the plate's rim taken as lying on the ground)."""
    meshes, normal = _sloping_scene(gap)
    s = _surfaces(meshes)
    w, seg = _classify(s)
    shape = s.shape_id[w.part]
    height = np.maximum(np.abs(w.start @ normal), np.abs(w.end @ normal))      # off the ground's plane
    near = height < gap + 1e-3
    box, plate, ground = shape == 0, shape == 1, shape == 2
    assert box.sum() == 24 and plate.sum() == 4 and ground.sum() == 4
    assert (near & box).sum() == 8 and (near & plate).sum() == 1
    assert seg["on"][box].all() and (seg["other"][box] >= 0).all()
    n0 = s.normal[w.part[box]]                                  # the box's outward normals
    assert edges.exterior_angle(seg["x0"][box], n0, seg["xn"][box]) == pytest.approx(np.full(24, 1.5))
    assert seg["on"][plate].all() and (seg["other"][plate] == -1).all()
    assert seg["on"][ground].all() and (seg["other"][ground] == -1).all()


def test_edges_on_another_face_do_not_diffract():
    """The same scene with no gap (hand-worked: the box stands on the ground, the plate leans on
    it): the box's floor edges lie on the ground, a concave corner on either side of each, and
    its 8 entries do not diffract (junctions); its other 16 do; the plate's rim on the ground is
    no free edge (it does not diffract), its 3 others are. The counterpart of the gap test above,
    which shows the tolerance is not simply switched off."""
    meshes, normal = _sloping_scene(0.0)
    s = _surfaces(meshes)
    w, seg = _classify(s)
    shape = s.shape_id[w.part]
    height = np.maximum(np.abs(w.start @ normal), np.abs(w.end @ normal))      # off the ground's plane
    box, plate = shape == 0, shape == 1
    on_ground = (height < 1e-9) & (box | plate)
    assert (on_ground & box).sum() == 8 and (on_ground & plate).sum() == 1
    assert not seg["on"][on_ground].any()
    assert seg["on"][box & ~on_ground].sum() == 16 and seg["on"][plate & ~on_ground].sum() == 3


# --------------------------------------------------------------------------- hole 1: deferral
HEADING, INCIDENCE, TURN = 20.0, 35.0, 25.0


def _mirrored_wedge():
    """A PEC triangle standing on its 1 m base 0.4 m above the ground, its normal turned ``TURN``
    deg off the look in azimuth (facing the antenna), and a PEC triangle hanging back from the
    same base, horizontal (an overhang's underside): a convex right-angle wedge along the base.
    Seen through the ground's mirror, the wave travels upward: it lights both faces of the wedge,
    and the antenna sees the standing face only (the underside faces down, away from it). Returns
    both meshes and the base's ends, the standing face's normal and the base's unit tangent."""
    look, _ = look_and_track(HEADING)
    horizontal = np.array([look[0], look[1], 0.0]) / np.hypot(look[0], look[1])
    normal = _rotation([0, 0, 1.0], TURN) @ horizontal
    tangent = np.cross([0, 0, 1.0], normal)
    foot = np.array([0.0, 0.0, 0.4])
    ends = np.array([foot - 0.5 * tangent, foot + 0.5 * tangent])
    wall = trimesh.Trimesh([ends[0], ends[1], foot + 0.1 * tangent + [0, 0, 0.6]], [[0, 1, 2]], process=False)
    under = trimesh.Trimesh([ends[0], ends[1], foot - 0.15 * tangent - 0.5 * normal], [[0, 2, 1]], process=False)
    return wall, under, ends, normal, tangent


def _order2_edges(rows):
    """The second bounce order's image with diffraction minus without: its edge terms (and the
    simulation with diffraction)."""
    def run(diffraction):
        return simulate(sarmitsuba.Scene(rows, sensor=sensor(HEADING, incidence_angle=INCIDENCE, polarization="VV"),
                                         integrator={"max_depth": 2, "split_bounces": True,
                                                     "diffraction": diffraction}))
    on, off = run(True), run(False)
    return on, on.images_per_order[1].data - off.images_per_order[1].data


def _image_rcs_db(sim, rims, rim_term) -> float:
    """The image RCS [dBsm] of edge rims: ``rim_term(rim, tile, d, b, v, kk)`` each rim's summed term
    for the incident direction ``d``, the direction back ``b``, VV's ``v`` and wavenumber ``kk``
    (``tile`` repeats a vector for the rim's points), summed over the rims, weighted per pulse and
    frequency as the focused image weighs them (as tests/test_edges.py's plate)."""
    rhat, weight, frequencies, band = image_weights(sim, band_points=11)
    num = den = 0.0
    for k in np.flatnonzero(weight > 0):
        b = rhat[k]
        d = -b
        h = np.cross([0, 0, 1.0], d)
        h /= np.linalg.norm(h)
        v = np.cross(d, h)
        for f, w_band in zip(frequencies, band):
            kk = 2 * math.pi * f / SPEED_OF_LIGHT
            total = 0j
            for rim in rims:
                def tile(x, m=len(rim[0])):
                    return np.tile(x, (m, 1))
                total += rim_term(rim, tile, d, b, v, kk)
            w = (weight[k] * w_band) ** 2
            num, den = num + w * abs(total) ** 2, den + w
    return 10 * math.log10(num / den)


def _image_theory_db(sim, rims) -> float:
    """The image RCS [dBsm] of edges lit through a PEC ground ``z = 0``, by explicit path
    enumeration (image theory, as tests/test_edges.py's triangle): each rim ``(points [m, 3],
    tangent, x0 into the lit face, the face's normal, xn into the wedge's other face or zero,
    length per point, sign)`` is lit by the ground's reflection of the incident wave (``d -> M
    d``, ``E -> -M E``) and diffracts straight back (RD), and is lit directly and diffracts toward
    the ground, whose reflection carries it back (DR), each with its own fringe of
    :func:`edges.edge_field` (face N's PO subtracted where it is lit and seen on that leg), summed
    with ``sign``, integrated by quadrature, weighted per pulse and frequency as the focused
    image weighs them. VV."""
    mirror = np.array([1.0, 1.0, -1.0])

    def rim_term(rim, tile, d, b, v, kk):
        points, t, x0, normal, xn, dl, sign = rim
        lit_up = normal if normal @ (mirror * d) < 0 else -normal
        rd = edges.edge_field(tile(t), tile(x0), tile(lit_up), tile(xn), tile(mirror * d), tile(b),
                              tile(-(mirror * v)).astype(complex)) @ v
        lit_down = normal if normal @ d < 0 else -normal
        dr_ = edges.edge_field(tile(t), tile(x0), tile(lit_down), tile(xn), tile(d), tile(mirror * b),
                               tile(v).astype(complex)) @ -(mirror * v)
        phase = np.exp(1j * kk * points @ (b + mirror * b))
        return sign * math.sqrt(4 * math.pi) * dl * np.sum((rd + dr_) * phase)

    return _image_rcs_db(sim, rims, rim_term)


def test_a_wedge_lit_through_a_mirror_with_its_other_face_unseen_is_carried_once(monkeypatch):
    """The wedge of :func:`_mirrored_wedge` above a PEC ground (heading 20 deg, incidence 35 deg,
    VV), second bounce order, edge terms only (diffraction on minus off). Adding the underside
    turns the standing triangle's base from a half-plane into a right-angle wedge and changes
    nothing else the tracer forms (the underside is lit only from below, through the mirror, away
    from the antenna: no term of its own, (E5)). So the edge image with the underside minus the
    one without must equal, by image theory, the base's wedge fringe minus its half-plane fringe,
    both orderings (RD, DR) of each, within 0.3 dB, whichever of the two faces has the lower part
    index (the one that carries a wedge lit and seen on both faces). The two orderings of the
    parts must also give the same data (the parts' order is a label). Caught: the deferral rule
    "face N lit and seen" taken as "lit or seen" (edge_terms.py ``lit_n``: ``&`` -> ``|``), where
    the standing face defers to an underside that forms no term: the edge carried by neither, the
    difference reads the half-plane's fringe alone, 10 dB high, and the two orderings differ by
    -4 dB instead of 0. (That the case is the one meant is checked on the lanes the kernel
    receives: after the mirror, some of the standing face's edge lanes name a wedge partner of
    lower index with the underside first, none with the standing face first.)"""
    wall, under, ends, normal, tangent = _mirrored_wedge()
    deferring = []
    real = integration.PatchTerms.__call__

    def keep(self, ctx, lanes, pieces, depth):
        if depth == 1 and lanes.wedge_defer is not None:
            wedge = lanes.diffracting & np.any(lanes.wedge_xn != 0, axis=1)        # not a free rim
            deferring.append(bool(np.any(lanes.wedge_defer & wedge)))
        return real(self, ctx, lanes, pieces, depth)

    monkeypatch.setattr(integration.PatchTerms, "__call__", keep)
    ground = rectangle((0, 0, 0), (2.0, 0, 0), (0, 2.0, 0))    # small: its discovery grid finds the wedge
    rows_wall = [(wall, "pec", "wall"), (ground, "pec", "ground")]
    sim, alone = _order2_edges(rows_wall)
    deferring.clear()
    _, under_first = _order2_edges([(under, "pec", "under")] + rows_wall)
    assert any(deferring)
    deferring.clear()
    _, wall_first = _order2_edges([(wall, "pec", "wall"), (under, "pec", "under"), (ground, "pec", "ground")])
    assert deferring and not any(deferring)
    g = (np.arange(200) + 0.5) / 200
    points = ends[0] + g[:, None] * (ends[1] - ends[0])
    up = np.array([0.0, 0.0, 1.0])                           # into the standing face, from its base
    dl = float(np.linalg.norm(ends[1] - ends[0])) / len(g)
    rims = [(points, tangent, up, normal, -normal, dl, 1.0),           # the wedge: into the underside
            (points, tangent, up, normal, np.zeros(3), dl, -1.0)]      # minus the half-plane
    expected = _image_theory_db(sim, rims)
    neither = _image_theory_db(sim, rims[1:])                # the base's half-plane fringe alone
    assert abs(expected - neither) > 3.0                     # the case tells the two apart
    for data in (under_first, wall_first):
        got = sarmitsuba.analyze(dataclasses.replace(sim.images_per_order[1], data=data - alone), (0, 0, 0)).rcs_db
        assert got == pytest.approx(expected, abs=0.3), (got, expected, neither)
    assert np.sum(np.abs(under_first - wall_first) ** 2) <= 1e-6 * np.sum(np.abs(wall_first) ** 2)


def _monostatic_db(sim, rims) -> float:
    """The image RCS [dBsm] of edges seen directly (backscatter, VV): each rim ``(points [m, 3],
    tangent, x0 into face 0, face 0's normal on the lit side, xn into face N or zero, length per
    point, sign)`` with its fringe of :func:`edges.edge_field`, summed with ``sign``, integrated by
    quadrature, weighted per pulse and frequency as the focused image weighs them (as
    tests/test_edges.py's plate)."""
    def rim_term(rim, tile, d, b, v, kk):
        points, t, x0, n0, xn, dl, sign = rim
        single = edges.edge_field(tile(t), tile(x0), tile(n0), tile(xn), tile(d), tile(b),
                                  tile(v).astype(complex)) @ v
        return sign * math.sqrt(4 * math.pi) * dl * np.sum(single * np.exp(2j * kk * points @ b))

    return _image_rcs_db(sim, rims, rim_term)


def test_a_wedge_lit_and_seen_on_both_faces_is_carried_once():
    """A ridge of two PEC triangles on a common 1 m base, each sloping down 33 deg from it, the base
    horizontal and turned ``TURN`` deg off the look in azimuth (heading 20 deg, incidence 35 deg,
    VV, no ground): both faces lit and seen, a convex wedge (exterior angle 246 deg). The edge
    image of the ridge minus those of each triangle alone (whose base is then a half-plane; their
    other rims are the same free edges, unshadowed, in all three) must equal the base's wedge
    fringe minus the two half-plane fringes, by the NumPy reference's quadrature, within 0.3 dB,
    in either order of the parts (exactly one face carries the wedge's term). Caught: the deferral
    flag of the lanes ``wedge_defer`` with ``&`` -> ``|`` (term_lanes.py: every wedge lane defers,
    so a wedge lit and seen on both faces is carried by neither: 3.4 dB high), and
    ``carry = ~(wedge_defer & lit_n)`` with ``|`` (edge_terms.py, the same). Not a check of the
    mirror rule ``lit_n``: backscatter has ``phi = phi'``."""
    look, _ = look_and_track(HEADING)
    horizontal = np.array([look[0], look[1], 0.0]) / np.hypot(look[0], look[1])
    toward = _rotation([0, 0, 1.0], TURN) @ horizontal
    tangent = np.cross([0, 0, 1.0], toward)
    slope, up = math.radians(33.0), np.array([0.0, 0.0, 1.0])
    down_near = math.cos(slope) * toward - math.sin(slope) * up        # into each face, from the base
    down_far = -math.cos(slope) * toward - math.sin(slope) * up
    top = np.array([0.0, 0.0, 0.3])
    ends = np.array([top - 0.5 * tangent, top + 0.5 * tangent])
    near = trimesh.Trimesh([ends[0], ends[1], top + 0.1 * tangent + 0.5 * down_near], [[0, 1, 2]], process=False)
    far = trimesh.Trimesh([ends[0], ends[1], top - 0.15 * tangent + 0.5 * down_far], [[0, 2, 1]], process=False)
    n_near, n_far = (np.cross(tangent, x) * np.sign(np.cross(tangent, x)[2]) for x in (down_near, down_far))
    sight = math.sin(math.radians(INCIDENCE)) * horizontal + math.cos(math.radians(INCIDENCE)) * up
    assert n_near @ sight > 0.3 and n_far @ sight > 0.3                # both faces seen (and lit)

    def edges_only(rows):
        def run(diffraction):
            return simulate(sarmitsuba.Scene(rows, sensor=sensor(HEADING, incidence_angle=INCIDENCE,
                                                                 polarization="VV"),
                                             integrator={"max_depth": 1, "diffraction": diffraction}))
        on, off = run(True), run(False)
        return on, on.image.data - off.image.data

    sim, alone_near = edges_only([(near, "pec", "near")])
    _, alone_far = edges_only([(far, "pec", "far")])
    g = (np.arange(200) + 0.5) / 200
    points = ends[0] + g[:, None] * (ends[1] - ends[0])
    dl = float(np.linalg.norm(ends[1] - ends[0])) / len(g)
    rims = [(points, tangent, down_near, n_near, down_far, dl, 1.0),
            (points, tangent, down_near, n_near, np.zeros(3), dl, -1.0),
            (points, tangent, down_far, n_far, np.zeros(3), dl, -1.0)]
    expected = _monostatic_db(sim, rims)
    neither, twice = _monostatic_db(sim, rims[1:]), _monostatic_db(sim, rims[:1] * 2 + rims[1:])
    assert min(abs(expected - neither), abs(expected - twice)) > 3.0     # the case tells them apart
    for rows in ([(near, "pec", "near"), (far, "pec", "far")], [(far, "pec", "far"), (near, "pec", "near")]):
        _, ridge = edges_only(rows)
        got = sarmitsuba.analyze(dataclasses.replace(sim.image, data=ridge - alone_near - alone_far), (0, 0, 0)).rcs_db
        assert got == pytest.approx(expected, abs=0.3), (got, expected, neither, twice)
