"""Scene loading: built-in and Sionna RT scenes, default sensor, materials, clear errors."""
from __future__ import annotations

import math

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.core.radar import ParameterError, RadarParameters
from sarmitsuba.scene.loader import SceneError, load_scene, material_table, sionna_scenes


def test_builtin_scenes_have_sensor_and_integrator():
    """Each built-in scene leaves its depth to the probe (``max_depth = auto``, cap 8)."""
    for name in ("urban", "dihedral", "trihedral"):
        loaded = load_scene(name)
        assert loaded.has_sensor and loaded.settings.max_depth == "auto" and loaded.settings.depth == 8
        assert loaded.params.n_pulses > 0 and loaded.params.scene_center == (0.0, 0.0, 0.0)


def test_urban_scene_content():
    """The default scene: ground, a long wall facing the sensor (+y), a tower, buildings."""
    loaded = load_scene("urban")
    ids = {s.id() for s in loaded.scene.shapes()}
    assert {"ground", "long_wall", "tower", "tower_reflector"} <= ids and len(ids) >= 7
    assert loaded.bbox_hi[2] > 50.0            # the tower (50 m) and its roof reflector


@pytest.mark.skipif(not sionna_scenes(), reason="sionna-rt extra not installed")
def test_sionna_floor_wall_loads_unchanged_with_default_sensor():
    """Sionna's XML (itu-radio-material, no sar sensor) loads as is; the default sensor looks
    at the bounding-box centre at ground level; materials follow the 0.1 m ITU slab, whose
    normal-incidence |r| at 9.6 GHz Sionna gives as brick 0.4289 and concrete 0.3954."""
    loaded = load_scene("sionna:floor_wall", sensor_overrides={"frequency": 9.6e9})
    assert not loaded.has_sensor
    lo, hi = loaded.bbox_lo, loaded.bbox_hi
    assert loaded.params.scene_center == pytest.approx((0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2]))
    table = material_table(loaded.scene, 9.6e9, "VV")
    at_normal = {name: abs(complex(table.table[i, -1])) for i, name in enumerate(table.names)}
    assert sorted(at_normal.values()) == pytest.approx([0.3954, 0.4289], abs=1e-3)


@pytest.mark.skipif("munich" not in sionna_scenes(), reason="sionna-rt extra not installed")
def test_sionna_munich_loads_all_objects():
    """Munich loads whole; its few defective meshes (Sionna's own data) are reported, not fatal."""
    from sarmitsuba.scene.meshcheck import MeshDefectWarning
    with pytest.warns(MeshDefectWarning, match="non-manifold"):
        loaded = load_scene("sionna:munich")
    assert loaded.n_shapes > 2000 and loaded.n_triangles > 30000
    assert loaded.params.n_pulses > 0


def test_unknown_sionna_scene_lists_available():
    with pytest.raises(SceneError, match="unknown Sionna RT scene 'atlantis'; valid: .*munich"):
        load_scene("sionna:atlantis")


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(SceneError, match="does not exist.*built-in scenes: dihedral"):
        load_scene(str(tmp_path / "nope.xml"))


@pytest.mark.parametrize("xml, message", [
    ("<scene version='3.0.0'><shape type='rectangle'>", "cannot load scene"),          # malformed XML
    ("<scene version='3.0.0'><bsdf type='radar' id='m'><string name='model' value='pec'/></bsdf>"
     "<shape type='ply'><string name='filename' value='missing.ply'/><ref id='m'/></shape></scene>", "missing.ply"),
    ("<scene version='3.0.0'><sensor type='sar'><float name='frequncy' value='9e9'/></sensor>"
     "<shape type='rectangle'/></scene>", "unknown parameter 'frequncy'.*frequency"),
    ("<scene version='3.0.0'><bsdf type='radar' id='m'><string name='material' value='cheese'/>"
     "</bsdf><shape type='rectangle'><ref id='m'/></shape></scene>", "unknown ITU material 'cheese'.*concrete"),
], ids=["malformed-xml", "missing-mesh", "misspelt-sensor-parameter", "unknown-material"])
def test_bad_scene_file_is_a_clear_error(tmp_path, xml, message):
    """Each names what is wrong (and, for names, the valid ones)."""
    path = tmp_path / "bad.xml"
    path.write_text(xml)
    with pytest.raises(SceneError, match=message):
        load_scene(str(path))


def test_shape_without_radar_material_is_rejected(tmp_path):
    xml = tmp_path / "plain.xml"
    xml.write_text("<scene version='3.0.0'><shape type='rectangle'/></scene>")
    loaded = load_scene(str(xml))
    with pytest.raises(SceneError, match="no radar properties"):
        material_table(loaded.scene, 9.6e9, "VV")


@pytest.mark.parametrize("override, message", [
    ({"incidence_angle": 95}, r"incidence_angle = 95.0 deg is outside the valid range \(0, 90\)"),
    ({"frequency": -1}, "frequency = -1.0 must be a finite number > 0"),
    ({"sampling_rate": 50e6, "bandwidth": 100e6}, "sampling_rate = 5e\\+07 Hz is below bandwidth"),
    ({"prf": 0}, "prf = 0.0 must be a finite number > 0"),
    ({"n_pulses": -3}, "n_pulses = -3"),
    ({"look_side": "up"}, "look_side = 'up'"),
    ({"wavelength": 0.03}, "unknown sar sensor parameter 'wavelength'"),
])
def test_bad_sensor_override_names_parameter_and_range(override, message):
    with pytest.raises(ParameterError, match=message):
        load_scene("dihedral", sensor_overrides=override)


def test_bad_integrator_override():
    with pytest.raises(ParameterError, match=r"max_depth = 0 must be a whole number in \[1, 64\]"):
        load_scene("dihedral", integrator_overrides={"max_depth": 0})
    with pytest.raises(ParameterError, match="range_kernel = 'cubic'"):
        load_scene("dihedral", integrator_overrides={"range_kernel": "cubic"})


def test_derived_radar_quantities_follow_standard_formulas():
    p = RadarParameters(bandwidth=150e6, incidence_angle=30.0, azimuth_beamwidth=1.0, altitude=2000.0)
    assert p.sampling_rate == pytest.approx(180e6)          # automatic: 1.2 x bandwidth
    c = 299_792_458.0
    assert p.slant_range_resolution == pytest.approx(c / 3e8)
    assert p.ground_range_resolution == pytest.approx(c / 3e8 / 0.5)
    # tapered default beam: resolution L / 2 of the aperture whose 3 dB width is 1 deg
    assert p.azimuth_resolution == pytest.approx(0.44294647 * p.wavelength / math.sin(math.radians(0.5)) / 2)
    uniform = RadarParameters(bandwidth=150e6, azimuth_beamwidth=1.0, beam="uniform")
    assert uniform.azimuth_resolution == pytest.approx(p.wavelength / (2 * math.radians(1.0)))
    assert p.slant_range == pytest.approx(2000.0 / math.cos(math.radians(30)))
    assert p.ground_range == pytest.approx(2000.0 * math.tan(math.radians(30)))


def test_track_geometry_conventions():
    """Heading 0, right-looking: flying along +x, sensor on the +y side, at the altitude."""
    from sarmitsuba.core.geometry import acquisition_geometry
    p = RadarParameters(scene_center=(0.0, 0.0, 0.0), n_pulses=3, altitude=1000.0, incidence_angle=45.0)
    g = acquisition_geometry(p)
    assert np.allclose(g.positions[1], [0.0, 1000.0, 1000.0])
    assert np.allclose(np.diff(g.positions[:, 0]), p.velocity / p.prf)
    assert np.allclose(g.look_direction, [0, -1, 0]) and np.allclose(g.track_direction, [1, 0, 0])


def test_aperture_length_sets_the_pulse_count():
    """aperture_length [m] replaces n_pulses: round(aperture * prf / velocity)."""
    loaded = load_scene("dihedral", sensor_overrides={"aperture_length": 40.0})
    p = loaded.params
    assert p.n_pulses == round(40.0 * p.prf / p.velocity)
    with pytest.raises(ParameterError, match="aperture_length = -5.0 m"):
        load_scene("dihedral", sensor_overrides={"aperture_length": -5})


def test_explicit_permittivity_material_uses_fresnel(tmp_path):
    """radar material with relative_permittivity/conductivity: eta = eps_r - j sigma/(omega eps_0),
    half-space Fresnel at normal incidence |r| = |1 - sqrt(eta)| / |1 + sqrt(eta)|."""
    xml = tmp_path / "eps.xml"
    xml.write_text("<scene version='3.0.0'><bsdf type='radar' id='m'><float name='relative_permittivity' value='6'/>"
                   "<float name='conductivity' value='0.1'/></bsdf><shape type='rectangle'><ref id='m'/></shape></scene>")
    loaded = load_scene(str(xml))
    f = loaded.params.frequency
    eta = 6 - 1j * 0.1 / (2 * math.pi * f * 8.8541878128e-12)
    expected = abs((1 - np.sqrt(eta)) / (1 + np.sqrt(eta)))
    table = material_table(loaded.scene, f, "VV")
    assert abs(abs(complex(table.table[0, -1])) - expected) < 1e-4


def test_inline_materials_keep_their_own_tables(tmp_path):
    """Two id-less (inline) radar BSDFs of different materials get their own reflection rows."""
    xml = tmp_path / "inline.xml"
    xml.write_text("<scene version='3.0.0'>"
                   "<shape type='rectangle'><bsdf type='radar'><string name='model' value='pec'/></bsdf></shape>"
                   "<shape type='rectangle'><transform name='to_world'><translate x='5'/></transform>"
                   "<bsdf type='radar'><float name='relative_permittivity' value='4'/></bsdf></shape></scene>")
    loaded = load_scene(str(xml))
    table = material_table(loaded.scene, loaded.params.frequency, "VV")
    assert table.table.shape[0] == 2
    assert sorted(abs(complex(v)) for v in table.table[:, -1]) == pytest.approx([1 / 3, 1.0], abs=1e-4)
