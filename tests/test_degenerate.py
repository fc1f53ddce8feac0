"""Degenerate geometry: loaded with a warning, traced without NaN (issue 5, item 4)."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import sarmitsuba  # noqa: F401
from sarmitsuba.scene import canonical as C
from sarmitsuba.scene.meshcheck import MeshDefectWarning
from sarmitsuba.pipeline import simulate


def _write(tmp_path, vertices, faces, name="bad"):
    mesh = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces), process=False)
    return C.scene_xml(tmp_path, mesh, C.PEC, 3, name=name)


PLATE = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [0, 0, 0], [2, 0, 0]]


@pytest.mark.parametrize("faces, defect", [
    ([[0, 1, 2], [0, 2, 3], [4, 4, 5]], "zero-area"),                 # a collapsed triangle
    ([[0, 1, 2], [0, 2, 3], [0, 1, 2]], "duplicate"),                  # the same face twice
    ([[0, 1, 2], [0, 3, 2]], "inconsistent normals"),                  # second face wound backwards
    ([[0, 1, 2], [0, 2, 3], [0, 2, 5]], "non-manifold"),               # three faces on edge 0-2
])
def test_defective_mesh_warns_and_traces_finite(tmp_path, faces, defect):
    xml = _write(tmp_path, PLATE, faces)
    with pytest.warns(MeshDefectWarning, match=defect):
        sim = simulate(str(xml), integrator_overrides={"ray_spacing": 0.05})
    assert np.all(np.isfinite(sim.raw.data)) and np.all(np.isfinite(sim.image.data))
    assert np.all(np.isfinite(sim.trace.energy_per_order))


def test_open_and_clean_meshes_do_not_warn(tmp_path, recwarn):
    xml = C.scene_xml(tmp_path, C.trihedral(0.5), C.PEC, 3)
    simulate(str(xml), integrator_overrides={"ray_spacing": 0.05})
    assert not [w for w in recwarn if issubclass(w.category, MeshDefectWarning)]


def test_batched_mesh_check_equals_the_trimesh_reference():
    """``check_all`` (every mesh of a scene at once, NumPy) reports what ``check_mesh`` (trimesh,
    one mesh at a time) reports, for each defect alone, for a closed cube, an open one, a cube
    with one face flipped, a mesh whose coincident vertices are listed twice (merged: watertight)
    and one whose copies differ by 1e-6 m (not merged: open), an empty mesh, and all of them in
    one batch (a mesh's vertices must not merge with another's)."""
    from sarmitsuba.scene.meshcheck import check_all, check_mesh
    cube = trimesh.creation.box()
    flipped = cube.faces.copy()
    flipped[0] = flipped[0, ::-1]
    split = trimesh.Trimesh(cube.vertices[cube.faces].reshape(-1, 3), np.arange(36).reshape(-1, 3), process=False)
    apart = split.vertices + np.random.default_rng(1).normal(0, 1e-6, split.vertices.shape)
    meshes = [(f"plate {i}", np.asarray(PLATE, float), np.asarray(f)) for i, f in enumerate((
        [[0, 1, 2], [0, 2, 3], [4, 4, 5]], [[0, 1, 2], [0, 2, 3], [0, 1, 2]], [[0, 1, 2], [0, 3, 2]],
        [[0, 1, 2], [0, 2, 3], [0, 2, 5]], [[0, 1, 2], [0, 2, 3]]))]
    meshes += [("cube", cube.vertices, cube.faces), ("open cube", cube.vertices, cube.faces[2:]),
               ("flipped cube", cube.vertices, flipped), ("split cube", split.vertices, split.faces),
               ("apart cube", apart, split.faces), ("empty", np.zeros((0, 3)), np.zeros((0, 3), np.int64)),
               ("cube again", cube.vertices, cube.faces)]
    reference = [check_mesh(*m) for m in meshes]
    assert check_all(meshes) == reference
    assert [check_all([m])[0] for m in meshes] == reference
    by_name = {r.shape: r for r in reference}
    assert not by_name["cube"].open and not by_name["cube"].defective and by_name["open cube"].open
    assert by_name["flipped cube"].inconsistent_winding and not by_name["split cube"].open
    assert by_name["apart cube"].open
