"""Meshes as they come from CAD (docs/physics.md (M0)): duplicate triangles traced once, closed
bodies wound outward, open meshes of inconsistent winding named.

The truth is the clean mesh: the same box, each triangle once and wound outward, traced by the
same simulator. A duplicated triangle that is traced twice doubles its field (0 dB NRMSE, the
issue's +6 dB line); an inside-out box without repair is 32 dB off at 35 deg (rough concrete: the
clutter lattice is seeded by the side hit, (C)), a partly flipped one 36 dB off.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.meshcheck import MeshDefectWarning
from sarmitsuba.scene.meshrepair import repaired_faces

BOX = trimesh.creation.box((4.0, 4.0, 3.0)).apply_translation((0.0, 0.0, 1.5))
ROUGH = {"material": "concrete", "gamma_db": -10}


def _scene(faces, incidence, vertices=BOX.vertices, name="box"):
    ground = trimesh.Trimesh([[-15, -15, 0], [15, -15, 0], [15, 15, 0], [-15, 15, 0]], [[0, 1, 2], [0, 2, 3]])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    return sarmitsuba.Scene(meshes=[(ground, "pec", "ground"), (mesh, ROUGH, name)],
                            sensor={"frequency": 9.6e9, "bandwidth": 150e6, "incidence_angle": incidence,
                                    "scene_center": (0, 0, 0), "azimuth_beamwidth": 1.0, "prf": 200.0},
                            integrator={"max_depth": 2, "ray_spacing": 0.25})


def _simulate(faces, incidence, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sim = simulate(_scene(faces, incidence, **kw))
    return sim, [str(w.message) for w in caught if issubclass(w.category, MeshDefectWarning)]


def _nrmse_db(a, b):
    return 20.0 * np.log10(max(np.linalg.norm(a - b), 1e-30) / np.linalg.norm(b))


@pytest.fixture(scope="module", params=[35.0, 55.0])
def clean(request):
    sim, said = _simulate(BOX.faces, request.param)
    assert not said
    return request.param, sim


def test_every_triangle_twice_images_as_the_clean_mesh(clean):
    """Each triangle listed twice, the copy with its corners rotated and its winding reversed
    (any order is the same triangle): within -60 dB of the clean box, 12 triangles traced, and
    the warning says the duplicates were traced once."""
    incidence, truth = clean
    copy = np.roll(BOX.faces[:, ::-1], 1, axis=1)
    sim, said = _simulate(np.r_[BOX.faces, copy], incidence)
    assert _nrmse_db(sim.image.data, truth.image.data) < -60.0
    assert _nrmse_db(sim.raw.data, truth.raw.data) < -60.0
    assert sim.loaded.n_triangles == 2 + 12
    assert len(said) == 1 and "12 duplicate triangles in box: traced once" in said[0]
    assert "non-manifold" not in said[0]                      # the duplicates' shared edges are gone too


def test_closed_box_wound_inward_images_as_outward(clean):
    """Every normal inward: within -40 dB of the outward box (it is the same box)."""
    incidence, truth = clean
    sim, said = _simulate(BOX.faces[:, ::-1], incidence)
    assert _nrmse_db(sim.image.data, truth.image.data) < -40.0
    assert _nrmse_db(sim.raw.data, truth.raw.data) < -40.0
    assert not said                                           # nothing left wrong once rewound


def test_closed_box_partly_flipped_images_as_outward(clean):
    """Four of twelve triangles wound backwards (inconsistent): rewound outward, within -40 dB of
    the clean box, and the warning names the box and says so."""
    incidence, truth = clean
    faces = BOX.faces.copy()
    faces[[0, 3, 7, 8]] = faces[[0, 3, 7, 8], ::-1]
    sim, said = _simulate(faces, incidence)
    assert _nrmse_db(sim.image.data, truth.image.data) < -40.0
    assert len(said) == 1 and "inconsistent normals in box: closed: wound consistently, outward" in said[0]


def test_open_mesh_of_inconsistent_winding_is_named():
    """A box without its floor (open: no inside to decide) with two walls' triangles flipped:
    the warning names it and says its outside cannot be decided; the same open box wound
    consistently is not named."""
    keep = np.flatnonzero(BOX.face_normals[:, 2] > -0.5)            # no floor
    faces = BOX.faces[keep].copy()
    faces[[0, 4]] = faces[[0, 4], ::-1]
    _, said = _simulate(faces, 45.0, name="shed")
    assert len(said) == 1 and "inconsistent normals in shed:" in said[0] and "cannot be decided" in said[0]
    _, said = _simulate(BOX.faces[keep], 45.0, name="shed")
    assert not said


def _outward(vertices, faces):
    """Whether every triangle's normal points away from the body's centre (true outward for a
    convex body, whatever the repair's method)."""
    tri = vertices[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = np.mean(np.unique(vertices[faces.ravel()], axis=0), axis=0)
    return np.einsum("ij,ij->i", normal, tri.mean(axis=1) - centre) > 0


def test_repaired_faces_per_body():
    """Two cubes in one mesh, one inside out and one partly flipped, plus a duplicate and a
    zero-area triangle: the duplicate goes (the first copy stays), both cubes end up outward
    (each judged by its own centre), the zero-area triangle is kept as it is, and the rows keep
    their order."""
    cube = trimesh.creation.box()
    vertices = np.r_[cube.vertices, cube.vertices + (5.0, 0.0, 0.0)]
    inside_out = cube.faces[:, ::-1]
    partly = cube.faces + 8
    partly[[1, 2, 9]] = partly[[1, 2, 9], ::-1]
    sliver = [[0, 0, 1]]
    faces = np.r_[inside_out, partly, sliver, np.roll(partly[5:6], 2, axis=1)]
    fixed, dropped, rewound, undecided = repaired_faces(vertices, faces)
    assert (dropped, rewound, undecided) == (1, 12 + 3, False)
    assert len(fixed) == 25 and np.array_equal(fixed[24], [0, 0, 1])
    assert np.array_equal(np.sort(fixed[:24], axis=1), np.sort(faces[:24], axis=1))
    assert _outward(vertices, fixed[:12]).all() and _outward(vertices, fixed[12:24]).all()
