"""Truncation rims (docs/physics.md (M10)): a ground shape's free rim is where its model was cut.

An infinite plane returns nothing away from its specular direction (its physical-optics integral
is a delta function in the Bragg vector, zero for backscatter off the normal); a finite plate
returns its rim. So a smooth plate marked as ground (``ground_shapes``) must return nothing at
all in backscatter off its normal, the same plate not marked must return its rims, and a ground
ending inside the beam around a building must leave no line where it ends.

Deliberate bugs these tests were run against (each fails one):
  * the rule switched off in the tracer (``self.rim = None``): every test but the names';
  * every border segment of a ground part dropped, not only those on free edges: the plinth;
  * ``ground_shapes = auto`` matching any id containing ``ground`` (``playground``);
  * ``without_rims`` made a no-op (the rims keep their edge currents): the plate facing the antenna;
  * ``on_rim``'s tolerance made 100 times looser, one end tested instead of both (the
    shapely comparison).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.ground import ground_shapes

FREQUENCY = 9.6e9
PRF, VELOCITY = 400.0, 100.0


def plate(half: float = 20.0, turn_deg: float = 0.0) -> trimesh.Trimesh:
    """A horizontal square ``2 half`` on a side at z = 0, turned ``turn_deg`` about z."""
    c, s = math.cos(math.radians(turn_deg)), math.sin(math.radians(turn_deg))
    corners = np.array([(-half, -half), (half, -half), (half, half), (-half, half)])
    xy = corners @ np.array([[c, s], [-s, c]])
    return trimesh.Trimesh(np.column_stack([xy, np.zeros(4)]), [[0, 1, 2], [0, 2, 3]], process=False)


def render(rows, heading: float, **integrator):
    sensor = {"frequency": FREQUENCY, "bandwidth": 150e6, "incidence_angle": 45.0, "scene_center": (0.0, 0.0, 0.0),
              "heading": heading, "prf": PRF, "velocity": VELOCITY, "n_pulses": 96, "antenna_length": 2.0}
    scene = sarmitsuba.Scene(rows, sensor=sensor, integrator={"max_depth": 2, **integrator})
    return simulate(scene, image_size=(160, 160), image_spacing=0.4)


def power(sim) -> float:
    return float(np.sum(np.abs(sim.raw.data.astype(np.complex128)) ** 2))


@pytest.mark.parametrize("heading, turn", [(20.0, 0.0), (0.0, 35.0)])
def test_a_smooth_ground_returns_nothing_off_its_normal(heading, turn):
    """A PEC plate seen 45 deg off its normal, rims oblique to the track: marked as ground it
    returns nothing (the infinite plane's zero), PO and edge currents alike; named otherwise, or
    with ``ground_shapes = none``, it returns its rims, the same raw data both ways. Relies on the
    bit-for-bit guarantee (docs/physics.md (D7)): the two renders differ only in a name and a
    setting that drop no term here, so any difference is the bug."""
    ground = render([(plate(turn_deg=turn), "pec", "ground")], heading)
    named = render([(plate(turn_deg=turn), "pec", "slab")], heading)
    kept = render([(plate(turn_deg=turn), "pec", "ground")], heading, ground_shapes="none")
    assert power(named) > 0
    assert np.array_equal(named.raw.data, kept.raw.data)
    assert power(ground) == 0.0


@pytest.mark.parametrize("heading", [0.0, 30.0])
def test_a_ground_ending_inside_the_beam_leaves_no_line(heading):
    """A box on a ground that ends 20 m from it, inside the beam, the ground's rims along and
    across the track (where a rim returns most: its far and near rims are lines of constant
    range). Off the azimuth and range lines through the box (its sidelobes), the image within
    1 m of the rim holds no more than twice the mean of the ground 3 to 5 m inside it (no line),
    where with the rim kept it held over a thousand times more; near the box (its walls, its
    double bounce with the ground) the image stays within -20 dB of the one with the rim kept."""
    turn = math.radians(heading)
    box = trimesh.creation.box((6.0, 6.0, 6.0))
    box.apply_transform(trimesh.transformations.rotation_matrix(turn + math.pi / 4, (0, 0, 1)))
    box.apply_translation((0.0, 0.0, 3.0))
    rows = [(box, "pec", "building"), (plate(turn_deg=heading), "pec", "mesh-ground")]
    cut = render(rows, heading)
    kept = render(rows, heading, ground_shapes="none")
    image = cut.image
    xyz = (image.origin + image.azimuth[:, None, None] * image.azimuth_direction
           + image.range[None, :, None] * image.range_direction)
    # the ground's own frame (turned with the track): its rims at |u| = 20 or |v| = 20
    u = xyz[..., 0] * math.cos(turn) + xyz[..., 1] * math.sin(turn)
    v = -xyz[..., 0] * math.sin(turn) + xyz[..., 1] * math.cos(turn)
    ring = np.maximum(np.abs(u), np.abs(v))
    az, rg = np.meshgrid(image.azimuth, image.range, indexing="ij")
    off_cross = (np.abs(az) > 12.0) & (np.abs(rg) > 12.0)
    rim, inside = (np.abs(ring - 20.0) < 1.0) & off_cross, (ring > 15.0) & (ring < 17.0) & off_cross
    mean = lambda sim, band: float(np.mean(np.abs(sim.image.data[band].astype(np.complex128)) ** 2))  # noqa: E731
    assert mean(kept, rim) > 1e3 * mean(cut, rim)
    assert mean(cut, rim) < 2.0 * mean(cut, inside)
    near_box = np.hypot(xyz[..., 0], xyz[..., 1]) < 12.0
    a, b = cut.image.data[near_box], kept.image.data[near_box]
    assert 10 * np.log10(np.sum(np.abs(a - b) ** 2) / np.sum(np.abs(b) ** 2)) < -20.0


def test_a_rim_that_a_face_meets_is_an_edge():
    """A ground that is a closed plinth (a 40 m slab 5 m thick, its top the ground): every rim of
    its top is a wedge with a side face, none is free, so nothing is a truncation and the raw data
    are the same with ``ground_shapes`` auto and none. Relies on the bit-for-bit guarantee
    (docs/physics.md (D7)): the two renders differ only in a setting that drops no term here, so any
    difference is the bug (the plinth's top alone, its rims then free and dropped: 0 dB NRMSE)."""
    slab = trimesh.creation.box((40.0, 40.0, 5.0))
    slab.apply_translation((0.0, 0.0, -2.5))
    auto = render([(slab, "pec", "ground")], 20.0)
    none = render([(slab, "pec", "ground")], 20.0, ground_shapes="none")
    assert power(none) > 0
    assert np.array_equal(auto.raw.data, none.raw.data)


def test_a_truncation_rim_keeps_its_segment_near_specular_but_does_not_diffract():
    """(M10)'s second line alone: a PEC plate 4 wavelengths square facing the antenna (its normal
    the mid-aperture line of sight), so every piece is near its specular direction and keeps its
    rim segments for its area term. Marked as ground its free rims are truncations, which neither
    diffract (E4) nor end a double diffraction (E6): its raw data with diffraction on are those
    with diffraction off (within -80 dB), and its PO those of the same plate not marked (the
    segments kept: the same energy within 1e-4). Named otherwise its rims diffract: -38 dB
    between the two (the sensitivity). Catches ``without_rims`` made a no-op (the rims' edge
    currents kept: -38 dB), which the plates seen off their normal miss (their rim segments,
    and so their edge lanes, are left out by (M10)'s first line)."""
    from test_patches import WAVELENGTH, frame, look_and_track, rectangle, sensor
    look, _ = look_and_track(0.0)
    e1, e2 = frame(look, 10.0)
    half = 2 * WAVELENGTH

    def raw(name, **integrator):
        rows = [(rectangle((0, 0, 0), e1 * half, e2 * half), "pec", name)]
        sim = simulate(sarmitsuba.Scene(rows, sensor=sensor(0.0, n_pulses=16), integrator={"max_depth": 1, **integrator}))
        return sim.raw.data.astype(np.complex128)

    nrmse = lambda a, b: 10 * math.log10(np.sum(np.abs(a - b) ** 2) / np.sum(np.abs(b) ** 2))   # noqa: E731
    ground, ground_po = raw("ground"), raw("ground", diffraction=False)
    named, named_po = raw("slab"), raw("slab", diffraction=False)
    assert np.sum(np.abs(ground_po) ** 2) == pytest.approx(np.sum(np.abs(named_po) ** 2), rel=1e-4)
    assert nrmse(named, named_po) > -45.0
    assert np.sum(np.abs(ground - ground_po) ** 2) <= 1e-8 * np.sum(np.abs(ground_po) ** 2), nrmse(ground, ground_po)


def test_on_rim_against_shapely():
    """``truncation.on_rim`` against shapely's distances: a segment is on a truncation edge when
    both its ends lie on that flagged edge (within 1e-9 m), on a square turned 20 deg and a
    triangle: pieces of flagged edges, of unflagged ones, parallels 1 cm and 0.1 mm inside,
    segments that leave a flagged edge, chords. Catches a tolerance made 100 times looser (the
    0.1 mm parallels, 9 times the tolerance's 1.1e-5 m on the 10 m square), one end tested
    instead of both, and the flags read one corner off."""
    import types

    import shapely

    from sarmitsuba.tracing.integration.truncation import on_rim
    t = math.radians(20.0)
    square = np.array([(-5.0, -5.0), (5.0, -5.0), (5.0, 5.0), (-5.0, 5.0)]) @ np.array([[math.cos(t), math.sin(t)],
                                                                                      [-math.sin(t), math.cos(t)]])
    triangle = np.array([(0.0, 0.0), (8.0, 1.0), (3.0, 6.0), (0.0, 0.0)])
    polygon = np.stack([square, triangle])
    s = types.SimpleNamespace(polygon=polygon, n_corners=np.array([4, 3]))
    rim = np.array([[True, False, True, False], [False, True, False, False]])   # edges from corner i to i + 1
    rng = np.random.default_rng(7)
    part, start, end = [], [], []
    for k in range(2):
        n = s.n_corners[k]
        for i in range(n):
            a, b = polygon[k, i], polygon[k, (i + 1) % n]
            inward = np.array([-(b - a)[1], (b - a)[0]]) / np.linalg.norm(b - a)     # counter-clockwise: left
            for _ in range(4):
                u, v = np.sort(rng.uniform(0.0, 1.0, 2))
                p, q = a + u * (b - a), a + v * (b - a)
                # parallels 1 cm and 0.1 mm inside: the latter within 100 times on_rim's tolerance
                # (1e-6 (1 + 10 m): 1.1e-5 m), so a tolerance 100 times looser flags them
                for shift in ((p, q), (p + 0.01 * inward, q + 0.01 * inward), (p + 1e-4 * inward, q + 1e-4 * inward),
                              (p, p + 0.5 * inward)):
                    part.append(k), start.append(shift[0]), end.append(shift[1])
        centre = polygon[k, :n].mean(axis=0)
        for _ in range(4):                                                          # chords through the middle
            part.append(k), start.append(polygon[k, rng.integers(n)]), end.append(centre)
    part, start, end = np.array(part), np.array(start), np.array(end)
    expected = np.zeros(len(part), bool)
    for m, (k, p, q) in enumerate(zip(part, start, end)):
        n = s.n_corners[k]
        for i in np.flatnonzero(rim[k, :n]):
            edge = shapely.LineString([polygon[k, i], polygon[k, (i + 1) % n]])
            expected[m] |= edge.distance(shapely.Point(p)) < 1e-9 and edge.distance(shapely.Point(q)) < 1e-9
    assert 10 < expected.sum() < len(part) - 10
    assert np.array_equal(on_rim(s, rim, part, start, end), expected)


def test_ground_shapes_names():
    """``auto`` takes ids ``ground``, ``*-ground``, ``*_ground`` only; a list takes its ids; an id
    the scene lacks is a ParameterError naming it and the scene's ids."""
    ids = ["mesh-ground", "Ground", "city_ground", "playground", "groundwork", "roof"]
    assert ground_shapes("auto", ids).tolist() == [True, True, True, False, False, False]
    assert ground_shapes("none", ids).tolist() == [False] * 6
    assert ground_shapes("roof, playground", ids).tolist() == [False, False, False, True, False, True]
    with pytest.raises(ParameterError, match="'lawn'.*mesh-ground"):
        ground_shapes("roof,lawn", ids)


def test_an_unknown_ground_shape_stops_the_load():
    """``ground_shapes`` naming a shape the scene lacks fails at load, before any tracing."""
    with pytest.raises(ParameterError, match="ground_shapes.*'moat'"):
        render([(plate(), "pec", "ground")], 0.0, ground_shapes="moat")
