"""Degenerate geometry: loaded with a warning, traced without NaN (issue 5, item 4)."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import sarmitsuba  # noqa: F401
from sarmitsuba import canonical as C
from sarmitsuba.meshcheck import MeshDefectWarning
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
