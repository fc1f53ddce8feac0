"""The Python API: ``sarmitsuba.simulate / render / refocus / analyze`` and scenes built in
Python (``sarmitsuba.Scene``), checked against the same scenes written as XML files."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.core.raw import RawData
from sarmitsuba.scene.loader import SceneError, load_scene, resolve_source

SCENES = Path(__file__).resolve().parent.parent / "scenes"
WAVELENGTH = 299_792_458.0 / 9.6e9
#: The sensor of the built-in scenes (scenes/dihedral.xml, scenes/trihedral.xml).
SENSOR = {"frequency": 9.6e9, "bandwidth": 150e6, "sampling_rate": 180e6, "prf": 250, "velocity": 100,
          "altitude": 1000, "incidence_angle": 45, "scene_center": (0, 0, 0), "azimuth_beamwidth": 1.2}
BRICK = {"material": "brick", "model": "slab", "thickness": 0.25, "gamma_db": -8}
GROUND = {"type": "radar", "material": "medium_dry_ground", "gamma_db": -14}


def nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(np.sum(np.abs(a - b) ** 2) / np.sum(np.abs(b) ** 2) + 1e-30))


def quad(corners) -> trimesh.Trimesh:
    """Two triangles (0, 1, 2), (0, 2, 3): normal along (c1 - c0) x (c2 - c0)."""
    return trimesh.Trimesh(np.array(corners, float), [[0, 1, 2], [0, 2, 3]], process=False)


def house_scene(offset=(0.0, 0.0, 0.0)) -> sarmitsuba.Scene:
    """A 6 x 4 x 3 m brick box on a 30 m rough ground plate, everything shifted by ``offset``."""
    offset = np.asarray(offset, float)
    box = trimesh.creation.box((6, 4, 3))
    box.apply_translation(offset + (0, 0, 1.5))
    ground = quad([(-15, -15, 0), (15, -15, 0), (15, 15, 0), (-15, 15, 0)])
    ground.apply_translation(offset)
    sensor = {"frequency": 9.6e9, "bandwidth": 150e6, "sampling_rate": 180e6, "n_pulses": 8,
              "scene_center": offset.tolist()}
    return sarmitsuba.Scene([(box, BRICK, "house"), (ground, GROUND, "ground")], sensor=sensor,
                            integrator={"max_depth": 2}, name="house")


@pytest.fixture(scope="module")
def house():
    return sarmitsuba.simulate(house_scene(), image_size=(16, 16))


# ---- the API ---------------------------------------------------------------------------------------

def test_import_is_cheap_and_exposes_the_entries():
    """``import sarmitsuba`` does not import the pipeline; the entries appear on first use."""
    code = ("import sys, sarmitsuba; assert 'sarmitsuba.pipeline' not in sys.modules; "
            "import sarmitsuba.pipeline as p; assert sarmitsuba.simulate is p.simulate; "
            "assert sarmitsuba.render is p.render and sarmitsuba.refocus is p.refocus; "
            "import sarmitsuba.focus as f; assert sarmitsuba.focus is f and callable(f.focus); "
            "assert callable(sarmitsuba.analyze) and isinstance(sarmitsuba.Scene, type); print('ok')")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr
    assert {"simulate", "render", "refocus", "focus", "analyze", "Scene"} <= set(dir(sarmitsuba))
    with pytest.raises(AttributeError, match="no attribute 'simulat'"):
        sarmitsuba.simulat


# ---- scenes built in Python against the same scenes in XML ---------------------------------------

def test_python_dihedral_equals_the_builtin_xml():
    """scenes/dihedral.xml (two Mitsuba rectangles) rebuilt as two trimesh quads: the same raw data.
    Catches wrong winding (normals), a lost sensor or integrator parameter, the wrong material.
    The rectangles' patch grids sit in their shape frames and the quads' in the world frame, so
    the two integrate over different (equally valid) patch lattices: they agree to -58 dB, the
    lattice's own error (docs/physics.md, "Scattering anchored to the mesh"), not to float32."""
    ground = quad([(-10, 0, 0), (10, 0, 0), (10, 10, 0), (-10, 10, 0)])      # normal +z
    wall = quad([(-10, 0, 0), (-10, 0, 5), (10, 0, 5), (10, 0, 0)])          # normal +y, toward the sensor
    scene = sarmitsuba.Scene([(ground, "pec", "ground"), (wall, "pec", "wall")],
                             sensor={**SENSOR, "n_pulses": 8}, integrator={"max_depth": 2}, name="dihedral")
    built = sarmitsuba.simulate(scene, image_size=(16, 16))
    xml = sarmitsuba.simulate("dihedral", sensor_overrides={"n_pulses": 8}, image_size=(16, 16))
    assert built.raw.data.shape == xml.raw.data.shape
    assert np.abs(xml.raw.data).max() > 0
    assert nrmse_db(built.raw.data, xml.raw.data) < -50


def test_python_scene_equals_xml_with_ply_meshes(tmp_path, house):
    """The house scene written as PLY files and an XML beside them: the same raw data, speckle
    included (a rough slab and rough ground). Catches shape ids not reaching Mitsuba (they key
    the clutter speckle) and material dicts applied wrongly."""
    scene = house_scene()
    for shape_id, mesh in (("house", trimesh.creation.box((6, 4, 3))),
                           ("ground", quad([(-15, -15, 0), (15, -15, 0), (15, 15, 0), (-15, 15, 0)]))):
        if shape_id == "house":
            mesh.apply_translation((0, 0, 1.5))
        mesh.export(tmp_path / f"{shape_id}.ply")
    (tmp_path / "house.xml").write_text("""<scene version="3.0.0">
  <sensor type="sar"><float name="frequency" value="9.6e9"/><float name="bandwidth" value="150e6"/>
    <float name="sampling_rate" value="180e6"/><integer name="n_pulses" value="8"/>
    <string name="scene_center" value="0, 0, 0"/></sensor>
  <integrator type="sbr"><integer name="max_depth" value="2"/></integrator>
  <shape type="ply" id="house"><string name="filename" value="house.ply"/><boolean name="face_normals" value="true"/>
    <bsdf type="radar"><string name="material" value="brick"/><string name="model" value="slab"/>
      <float name="thickness" value="0.25"/><float name="gamma_db" value="-8"/></bsdf></shape>
  <shape type="ply" id="ground"><string name="filename" value="ground.ply"/><boolean name="face_normals" value="true"/>
    <bsdf type="radar"><string name="material" value="medium_dry_ground"/><float name="gamma_db" value="-14"/></bsdf>
  </shape>
</scene>""")
    xml = sarmitsuba.simulate(str(tmp_path / "house.xml"), image_size=(16, 16))
    assert house.loaded.n_triangles == xml.loaded.n_triangles == scene.n_triangles == 14
    assert nrmse_db(house.raw.data, xml.raw.data) < -60


def test_far_from_origin_scene_is_the_near_one_shifted(house):
    """The house 1e6 m east (and 2e5 m south, 30 m up): traced in a local frame, finite, the
    same echoes, the track shifted by exactly the offset. Catches vertices rounded to float32
    before the offset is removed (6 cm steps at 1e6 m: radians of X-band phase)."""
    shift = np.array([1e6 + 0.3183, -2e5 + 0.2718, 30.1416])     # not multiples of float32 steps
    far = sarmitsuba.simulate(house_scene(shift), image_size=(16, 16))
    assert np.linalg.norm(far.loaded.offset) > 1e5
    assert np.all(np.abs(far.loaded.bbox_lo) < 100)                  # traced locally
    assert np.all(np.isfinite(far.raw.data))
    assert nrmse_db(far.raw.data, house.raw.data) < -60
    np.testing.assert_allclose(far.raw.tx_position - house.raw.tx_position, np.tile(shift, (8, 1)), atol=1e-6)
    np.testing.assert_allclose(far.image.origin - house.image.origin, shift, atol=1e-6)


def test_trihedral_built_in_python_simulate_refocus_analyze():
    """scenes/meshes/trihedral.obj read with trimesh, scaled and tilted as scenes/trihedral.xml:
    ``sarmitsuba.analyze`` finds the peak on the apex and the RCS of a triangular trihedral,
    4 pi a^4 / (3 lambda^2) on boresight (a = 1.5 m: 43.4 dBsm), within 0.5 dB; the image
    refocused with omega-K (``sarmitsuba.refocus``) peaks on the apex too."""
    mesh = trimesh.load(SCENES / "meshes" / "trihedral.obj", process=False, force="mesh")
    mesh.apply_scale(1.5)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.radians(9.7356), [1, 0, 0]))
    scene = sarmitsuba.Scene([(mesh, "pec", "trihedral")], sensor=SENSOR, integrator={"max_depth": 3})
    sim = sarmitsuba.simulate(scene)
    report = sarmitsuba.analyze(sim.image, (0.0, 0.0, 0.0), raw=sim.raw)
    expected_db = 10 * np.log10(4 * np.pi * 1.5**4 / (3 * WAVELENGTH**2))
    assert abs(report.rcs_db - expected_db) < 0.5
    assert abs(report.azimuth_error_cells) < 0.05 and abs(report.range_error_cells) < 0.05
    omegak = sarmitsuba.refocus(sim.raw, "omegak")
    report = sarmitsuba.analyze(omegak, (0.0, 0.0, 0.0), chip=32)
    assert abs(report.azimuth_error_cells) < 0.05 and abs(report.range_error_cells) < 0.05
    same = sarmitsuba.focus.focus(sim.raw, "omegak")
    np.testing.assert_array_equal(same.data, omegak.data)


def test_render_and_info_of_a_python_scene(tmp_path):
    """render writes every product and names the scene python:<name>; the metadata have no
    scene file, and the figures' scene reload and ``info`` cope with that."""
    from sarmitsuba.products.figures import _scene_of
    from sarmitsuba.core.image import SarImage
    from sarmitsuba.info import format_text, scene_info
    ground = quad([(-10, 0, 0), (10, 0, 0), (10, 10, 0), (-10, 10, 0)])
    wall = quad([(-10, 0, 0), (-10, 0, 5), (10, 0, 5), (10, 0, 0)])
    scene = sarmitsuba.Scene([(ground, "metal"), (wall, "concrete")], sensor={**SENSOR, "n_pulses": 8},
                             integrator={"max_depth": 2}, name="plates")
    summary = sarmitsuba.render(scene, tmp_path / "out", progress=False)
    assert summary.scene == "python:plates"
    assert {"raw.npz", "image.npz", "image.png", "summary.json"} <= {p.name for p in (tmp_path / "out").iterdir()}
    raw = RawData.load(tmp_path / "out" / "raw.npz")
    assert raw.metadata["scene"] == "python:plates" and raw.metadata["scene_path"] is None
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["scene"] == "python:plates"
    assert _scene_of(SarImage.load(tmp_path / "out" / "image.npz")) is None
    info = scene_info(scene)
    assert info.scene.n_triangles == 4 and "python:plates" in format_text(info)


def test_load_scene_accepts_a_python_scene():
    box = trimesh.creation.box((2, 2, 2))
    scene = sarmitsuba.Scene([(box, "concrete")], sensor={"n_pulses": 4}, name="cube")
    assert resolve_source(scene) is None
    loaded = load_scene(scene, sensor_overrides={"incidence_angle": 30})
    assert loaded.source == "python:cube" and loaded.path is None and loaded.has_sensor
    assert loaded.params.incidence_angle == 30 and loaded.params.n_pulses == 4
    np.testing.assert_allclose(loaded.bbox_lo, [-1, -1, -1])
    assert [s.id() for s in loaded.scene.shapes()] == ["mesh0"]


# ---- bad input ------------------------------------------------------------------------------------

def _box():
    return trimesh.creation.box((1, 1, 1))


@pytest.mark.parametrize("meshes, error, words", [
    ([(_box(), "concrete"), ("box.ply", "concrete")], SceneError, ["meshes[1]", "trimesh"]),
    ([(trimesh.Trimesh(), "concrete")], SceneError, ["meshes[0]", "empty mesh"]),
    ([(_box(), "concret")], ParameterError, ["meshes[0]", "'concret'", "concrete", "brick", "metal", "pec"]),
    ([(_box(), {"material": "brick", "model": "slab"})], ParameterError, ["meshes[0]", "thickness"]),
    ([(_box(), {"material": "brick", "roughness": 1})], ParameterError, ["meshes[0]", "'roughness'"]),
    ([(_box(), {"plugin": "diffuse"})], ParameterError, ["meshes[0]", "'diffuse'", "itu-radio-material"]),
    ([(_box(), 3.0)], ParameterError, ["meshes[0]", "material must be a name"]),
    ([(trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]], [[0, 1, 2]], process=False), "metal")], SceneError,
     ["meshes[0]", "not finite"]),
    ([(trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False), "metal"),
      (trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 7]], process=False), "metal")],
     SceneError, ["meshes[1]", "face indices", "[0, 2]"]),
    ([_box()], SceneError, ["meshes[0]", "(mesh, material)"]),
    ([(_box(), "metal", "a"), (_box(), "metal", "a")], SceneError, ["'a'", "more than once"]),
    ([(_box(), "metal", "roof.north")], SceneError, ["meshes[0]", "'roof.north'", "'.'"]),
    ([], SceneError, ["non-empty"]),
    ([(trimesh.Scene([_box()]), "metal")], SceneError, ["meshes[0]", "trimesh.Scene", "dump"]),
])
def test_bad_meshes_and_materials_are_named(meshes, error, words):
    with pytest.raises(error) as info:
        sarmitsuba.Scene(meshes)
    for word in words:
        assert word in str(info.value), (word, str(info.value))


def test_bad_sensor_and_integrator_parameters_are_named():
    with pytest.raises(ParameterError, match="unknown sar sensor parameter 'frequenc'; did you mean 'frequency'[?] valid: .*frequency"):
        sarmitsuba.Scene([(_box(), "metal")], sensor={"frequenc": 9.6e9})
    with pytest.raises(ParameterError, match="incidence_angle"):
        sarmitsuba.Scene([(_box(), "metal")], sensor={"incidence_angle": 95})
    with pytest.raises(ParameterError, match="scene_center"):
        sarmitsuba.Scene([(_box(), "metal")], sensor={"scene_center": (0, 0)})
    with pytest.raises(ParameterError, match="unknown sbr integrator parameter 'max_dept'; did you mean 'max_depth'[?] valid: .*seed"):
        sarmitsuba.Scene([(_box(), "metal")], integrator={"max_dept": 3})


def test_a_python_scene_with_a_bad_override_exits_through_load_scene():
    """Overrides are checked as for an XML scene (ParameterError, nothing traced)."""
    scene = sarmitsuba.Scene([(_box(), "metal")])
    with pytest.raises(ParameterError, match="unknown sar sensor parameter"):
        sarmitsuba.simulate(scene, sensor_overrides={"nope": 1})
