"""Rough surfaces in the renderer (docs/physics.md (RS6)): the monostatic table's interpolation
against the model, the kernel's interpolation against its NumPy reference, a rough plate's
calibrated image against the I2EM sigma nought, and the bistatic form after a mirror against an
independent radar-equation integral over the mirrored ground. The tables at their nodes are
checked against Ulaby and Long's code in tests/test_rough_tables.py."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba as sm
import drjit as dr
import mitsuba as mi
from sarmitsuba.analysis.point_target import energy_widths
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.loader import SceneError, load_scene, material_table
from sarmitsuba.scene.materials import itu_permittivity
from sarmitsuba.scene.rough_tables import rough_tables
from sarmitsuba.scene.roughness import RoughSurface, i2em_bistatic, sigma0_backscatter
from sarmitsuba.tracing.integration.rough_sigma import (azimuth_cosine, bistatic_sigma0_table, mono_sigma0,
                                                         reference_bistatic, reference_mono)

PLATE = str(Path(__file__).parent / "scenes" / "rough_plate.xml")
SURFACE = RoughSurface(0.003, 0.02)               # the plate's: k s = 0.61, k l = 4.0 at 9.6 GHz
K = 2 * math.pi * 9.6e9 / 299792458.0
#: The plate's image: 36 m square about its centre, 0.5 m pixels (the 32 m box measured and its edges).
IMAGE = {"image_size": (72, 72), "image_spacing": 0.5}


@pytest.mark.parametrize("degrees", [25, 45, 60])
def test_the_monostatic_table_interpolates_the_model_within_0_05_db(degrees):
    eta = itu_permittivity("medium_dry_ground", 9.6e9)
    tables = rough_tables([SURFACE], [eta], K)
    c = math.cos(math.radians(degrees))
    direct = sigma0_backscatter(SURFACE, eta, K, c)
    for p, name in enumerate(("HH", "VV", "HV")):
        assert 10 * math.log10(reference_mono(tables.mono, 0, p, c) / direct[name]) == pytest.approx(0, abs=0.05)


def test_kernel_interpolation_is_its_numpy_reference():
    tables = rough_tables([None, SURFACE], [None, 5 - 0.4j], K)
    arrays = {"rough_mono": mi.Float(tables.mono.ravel()), "rough_bi": mi.Float(tables.bistatic.ravel())}
    read = lambda name, index, active=True: dr.gather(mi.Float, arrays[name], index, active)   # noqa: E731
    rng = np.random.default_rng(3)
    ci, cs, cp = rng.uniform(0, 1, 200), rng.uniform(0, 1, 200), rng.uniform(-1, 1, 200)
    ci[:2], cs[:2], cp[:2] = (0.0, 1.0), (1.0, 0.0), (-1.0, 1.0)              # the table's edges
    row = mi.UInt32(np.ones(200, np.uint32))
    for p in (0, 1, 2):
        got = np.array(mono_sigma0(read, row, p, mi.Float(ci)))
        assert np.allclose(got, reference_mono(tables.mono, 1, p, ci), rtol=2e-5, atol=0)
    for p in (0, 1):
        got = np.array(bistatic_sigma0_table(read, row, p, mi.Float(ci), mi.Float(cs), mi.Float(cp)))
        assert np.allclose(got, reference_bistatic(tables.bistatic, 1, p, ci, cs, cp), rtol=2e-5, atol=0)


@pytest.mark.parametrize("tilt", [0.0, 30.0])
@pytest.mark.parametrize("theta", [20.0, 55.0])
def test_azimuth_cosine_of_back_forward_and_side_scattering(theta, tilt):
    t, a = math.radians(theta), math.radians(tilt)
    n = np.array([0.0, math.sin(a), math.cos(a)])
    u = np.cross(n, [0.0, 1.0, 0.0]) if tilt == 0 else np.cross(n, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    d = math.sin(t) * u - math.cos(t) * n                          # travelling along +u, downward
    cases = {-1.0: -d, 1.0: d + 2 * math.cos(t) * n,               # back to the source; specular
             0.0: math.sin(0.7) * w + math.cos(0.7) * n,           # out of the plane, at 90 deg azimuth
             math.cos(math.radians(135)): math.sin(0.4) * (math.cos(math.radians(135)) * u + math.sin(math.radians(135)) * w)
             + math.cos(0.4) * n}
    v = lambda x: mi.Vector3f(*map(float, x))                        # noqa: E731
    for expect, b in cases.items():
        assert float(azimuth_cosine(v(d), v(b), v(n))[0]) == pytest.approx(expect, abs=1e-6)


def _plate_sigma0(image, raw, polarization):
    """Calibrated mean intensity over the plate's interior (K2) and the model's mean sigma0 over
    the same pixels' incidence."""
    az, gr = np.meshgrid(image.azimuth, image.range, indexing="ij")
    box = (np.abs(az) < 16.0) & (np.abs(gr) < 16.0)
    values, positions = image.data[box], image.positions()[box]
    antenna = raw.tx_position.mean(axis=0)
    cos_theta = (antenna[2] - positions[:, 2]) / np.linalg.norm(antenna - positions, axis=1)
    eta = itu_permittivity("medium_dry_ground", 9.6e9)
    model = sigma0_backscatter(SURFACE, eta, K, cos_theta)[polarization].mean()
    return np.mean(np.abs(values) ** 2) / np.prod(energy_widths(image)), model


def test_rough_plate_gives_the_models_sigma0_in_every_channel():
    """Quad pol at 30 deg: HH, VV and HV of a 48 m plate (s = 3 mm, l = 20 mm; I2EM -8.9, -7.2
    and -24.6 dB) within 0.5 dB (measured +0.00, -0.00, +0.06 dB). The 32 m box holds ~700
    resolution cells: 0.16 dB standard error. The channels differ by 1.7 and 16 dB: a swapped
    table row (HH read as VV) or the constant cross level of (P7) miss."""
    sim = simulate(PLATE, sensor_overrides={"incidence_angle": 30.0, "polarization": "quad"},
                   integrator_overrides={"ray_spacing": 0.2, "seed": 1}, **IMAGE)
    for name in ("HH", "VV", "HV"):
        measured, model = _plate_sigma0(sim.channels[name].image, sim.raw, name)
        assert abs(10 * math.log10(measured / model)) < 0.5, (name, 10 * math.log10(measured), 10 * math.log10(model))


def test_rough_plate_scalar_vv_at_60_deg():
    """The scalar model (``polarimetry = scalar``) reads the table of its own channel: VV at 60 deg
    within 0.5 dB of the I2EM (-12.7 dB; measured -0.15 dB). HH there is 5.2 dB lower, and
    the bistatic form at backscatter (no transition coefficient, no shadowing) misses too."""
    sim = simulate(PLATE, sensor_overrides={"incidence_angle": 60.0, "polarization": "VV"},
                   integrator_overrides={"ray_spacing": 0.2, "seed": 1, "polarimetry": "scalar"}, **IMAGE)
    measured, model = _plate_sigma0(sim.image, sim.raw, "VV")
    assert abs(10 * math.log10(measured / model)) < 0.5, (10 * math.log10(measured), 10 * math.log10(model))


@pytest.mark.parametrize("lit_regions", ["patches", "tiles"])
def test_rough_plate_at_grazing_incidence(lit_regions):
    """At 87 deg (cos 0.052) the calibrated mean is the I2EM's HH (-39.2 dB) within 0.5 dB
    (measured +0.06 dB with the mesh-anchored patches, +0.01 dB with the tube preview). The tube
    preview shortens each footprint below the clutter's CLUTTER_COS_MIN = 0.1 and raises sigma0 by
    the same factor, for the table as for constant gamma (C): without the raise it reads low."""
    sim = simulate(PLATE, sensor_overrides={"incidence_angle": 87.0, "polarization": "HH"},
                   integrator_overrides={"seed": 0, "lit_regions": lit_regions}, **IMAGE)
    measured, model = _plate_sigma0(sim.image, sim.raw, "HH")
    assert abs(10 * math.log10(measured / model)) < 0.5, (10 * math.log10(measured), 10 * math.log10(model))


def test_specular_reflection_carries_the_coherent_factor():
    """The rough material's reflection table is the smooth one times exp(-2 (k s cos)^2) (RS6)."""
    loaded = load_scene(PLATE)
    rough = material_table(loaded.scene, loaded.params.frequency, "VV")
    smooth = load_scene(PLATE, material_overrides={"gamma_db": -10})
    flat = material_table(smooth.scene, smooth.params.frequency, "VV")
    c = np.linspace(0, 1, rough.table.shape[1])
    ks = 2 * math.pi * loaded.params.frequency / 299792458.0 * 0.003
    assert np.allclose(rough.table[0], flat.table[0] * np.exp(-2 * (ks * c) ** 2), rtol=1e-5, atol=1e-7)
    assert rough.clutter[0].tolist() == [3, 1] and rough.rough is not None and flat.rough is None


def test_bad_rough_surfaces_name_the_parameter(tmp_path):
    text = Path(PLATE).read_text()
    cases = {'<float name="gamma_db" value="-10"/>': "gamma_db or rms_height",
             '<string name="correlation" value="fractal"/>': "correlation must be one of"}
    for extra, message in cases.items():
        path = tmp_path / "bad.xml"
        path.write_text(text.replace('<float name="correlation_length" value="0.02"/>',
                                     '<float name="correlation_length" value="0.02"/>' + extra))
        with pytest.raises((ParameterError, SceneError), match=message):
            load_scene(str(path))
    path.write_text(text.replace('<float name="correlation_length" value="0.02"/>', ""))
    with pytest.raises((ParameterError, SceneError), match="needs both rms_height and correlation_length"):
        load_scene(str(path))


# ---- a rough ground seen through a PEC wall: the bistatic form ------------------------------------
WALL_HEIGHT, GROUND_DEPTH, LENGTH = 8.0, 30.0, 300.0
GROUND = RoughSurface(0.004, 0.03)                 # k s = 0.8, k l = 6.0


def _wall_scene(theta: float, seed: int):
    import trimesh
    half = LENGTH / 2
    quad = lambda c: trimesh.Trimesh(np.array(c, float), [[0, 1, 2], [0, 2, 3]])   # noqa: E731
    ground = quad([[-half, 0, 0], [half, 0, 0], [half, GROUND_DEPTH, 0], [-half, GROUND_DEPTH, 0]])
    wall = quad([[-half, 0, 0], [half, 0, 0], [half, 0, WALL_HEIGHT], [-half, 0, WALL_HEIGHT]])
    material = {"material": "medium_dry_ground", "rms_height": GROUND.rms_height,
                "correlation_length": GROUND.correlation_length}
    sensor = {"bandwidth": 150e6, "azimuth_beamwidth": 1.2, "prf": 250, "scene_center": (0.0, 5.0, 0.0),
              "incidence_angle": theta, "polarization": "VV"}
    return sm.Scene(meshes=[(ground, material, "ground"), (wall, "pec", "wall")], sensor=sensor,
                    integrator={"max_depth": 2, "ray_spacing": 0.2, "seed": seed, "split_bounces": True},
                    name=f"roughwall{theta:g}_{seed}")


def _mirrored_ground_rcs(antenna: np.ndarray, along: float) -> float:
    """The radar equation over the ground seen through the wall, with the I2EM's bistatic VV
    evaluated directly (no table): at each ground point both orderings (wall first: met from the
    antenna's image A', leaving toward A; ground first: met from A, leaving toward A'), each at its
    own incidence, scattering and azimuth angles, amplitudes added, |r_wall| = 1 [m^2]."""
    image = antenna * np.array([1.0, -1.0, 1.0])
    step = 0.01
    y = np.arange(step / 2, GROUND_DEPTH, step)
    g = np.stack([np.full_like(y, antenna[0]), y, np.zeros_like(y)], axis=-1)
    height = image[2] + (-image[1] / (y - image[1])) * (0.0 - image[2])
    seen = (height >= 0) & (height <= WALL_HEIGHT)
    eta = itu_permittivity("medium_dry_ground", 9.6e9)

    def ordering(source, sink):
        d, b = g - source, sink - g
        d /= np.linalg.norm(d, axis=1)[:, None]
        b /= np.linalg.norm(b, axis=1)[:, None]
        dt, bt = d[:, :2], b[:, :2]
        cos_phi = np.sum(dt * bt, 1) / (np.linalg.norm(dt, axis=1) * np.linalg.norm(bt, axis=1))
        return i2em_bistatic(GROUND, eta, K, -d[:, 2], b[:, 2], np.arccos(np.clip(cos_phi, -1, 1)))[0]

    per_area = (np.sqrt(ordering(image, antenna)) + np.sqrt(ordering(antenna, image))) ** 2
    return float(np.sum(per_area[seen]) * step * along)


def test_double_bounce_rough_ground_uses_the_bistatic_model():
    """Bounce order 2 of a rough ground in front of a PEC wall at 40 deg, rendered with two seeds:
    their difference holds no PO (the same in both) and twice the clutter's power. Its integrated
    RCS over the middle 280 m, ``sum |I_1 - I_2|^2 dA / (2 rho_az rho_gr)``, within 0.5 dB of
    :func:`_mirrored_ground_rcs` (measured 0.00 dB; -0.12 dB at 55 deg). The ground is met in the
    forward plane, near its specular lobe: the geometric mean of the monostatic values, (C2)'s
    rule, would read 14 dB low (11 dB at 55 deg)."""
    one, two = (simulate(_wall_scene(40.0, seed)) for seed in (1, 2))
    a, b = one.images_per_order[1], two.images_per_order[1]
    along = LENGTH - 20.0
    rows = np.abs(a.azimuth) < along / 2
    cell = abs(a.azimuth[1] - a.azimuth[0]) * abs(a.range[1] - a.range[0])
    measured = np.sum(np.abs(a.data[rows] - b.data[rows]) ** 2) * cell / (2 * np.prod(energy_widths(a)))
    expected = _mirrored_ground_rcs(one.raw.tx_position.mean(axis=0), along)
    error_db = 10 * math.log10(measured / expected)
    assert abs(error_db) < 0.5, f"{measured:.2f} m^2 against {expected:.2f} m^2 ({error_db:+.2f} dB)"


# ---- the city preset and info ---------------------------------------------------------------------
def _itu_scene():
    import trimesh
    rows = []
    for i, (kind, extra) in enumerate((("concrete", {"scattering_coefficient": 0.3}), ("metal", {}),
                                       ("medium_dry_ground", {}), ("brick", {}))):
        box = trimesh.creation.box((4.0, 4.0, 4.0))
        box.apply_translation((8.0 * i - 12.0, 0.0, 2.0))
        rows.append((box, {"plugin": "itu-radio-material", "type": kind, **extra}, kind))
    box = trimesh.creation.box((4.0, 4.0, 4.0))
    box.apply_translation((0.0, 10.0, 2.0))
    rows.append((box, {"material": "concrete", "gamma_db": -12}, "explicit_gamma"))
    return sm.Scene(rows, sensor={"incidence_angle": 35.0}, name="itu_classes")


def _surfaces(loaded):
    return {s.bsdf().name: (s.bsdf().surface, s.bsdf().clutter[0]) for s in loaded.scene.shapes()}


def test_city_preset_gives_each_itu_class_its_row():
    """``roughness=city``: concrete takes its row (replacing Sionna's Lambertian S), metal stays
    smooth, the ground is the soil row, and a ``radar`` material of an ITU class takes that class's
    row too, its gamma replaced; ``roughness=none`` makes every material smooth."""
    from sarmitsuba.scene.rough_presets import CITY
    got = _surfaces(load_scene(_itu_scene(), material_overrides={"roughness": "city"}))
    assert got["concrete"] == (CITY["concrete"].surface, 3)
    assert got["metal"] == (None, 0)
    assert got["medium_dry_ground"] == (CITY["medium_dry_ground"].surface, 3)
    assert got["brick"][0].rms_height == pytest.approx(0.002)
    assert got["explicit_gamma"] == (CITY["concrete"].surface, 3)       # a radar concrete is a concrete
    none = _surfaces(load_scene(_itu_scene(), material_overrides={"roughness": "none"}))
    assert all(kind == 0 for _, kind in none.values())


def test_every_preset_row_names_its_source_or_says_it_is_an_assumption():
    from sarmitsuba.scene.materials import itu_material_names
    from sarmitsuba.scene.rough_presets import CITY
    assert set(CITY) == set(itu_material_names())
    for name, row in CITY.items():
        assert row.source and ("assumption" in row.source or any(c.isdigit() for c in row.source)), name


def test_bad_presets_name_the_choice():
    with pytest.raises((ParameterError, SceneError), match="roughness preset"):
        load_scene(_itu_scene(), material_overrides={"roughness": "village"})
    with pytest.raises((ParameterError, SceneError), match="cannot be combined with gamma_db"):
        load_scene(_itu_scene(), material_overrides={"roughness": "city", "gamma_db": -10})


def test_info_prints_each_rough_class_sigma0_at_the_scenes_incidence():
    """info's line for a rough material carries HH and VV of the model at the scene's incidence
    (35 deg here), for the material's own permittivity at the carrier."""
    import re
    from sarmitsuba.info import scene_info
    info = scene_info(_itu_scene(), material_overrides={"roughness": "city"})
    ground = next(m for m in info.scene.materials if m.name == "medium_dry_ground")
    hh, vv = (float(x) for x in re.search(r"HH (-?[\d.]+) dB, VV (-?[\d.]+) dB at 35 deg", ground.roughness).groups())
    eta = complex(ground.permittivity_real, ground.permittivity_imag)
    model = sigma0_backscatter(RoughSurface(0.006, 0.06), eta, K, math.cos(math.radians(35.0)))
    assert hh == pytest.approx(10 * math.log10(model["HH"]), abs=0.05)
    assert vv == pytest.approx(10 * math.log10(model["VV"]), abs=0.05)


def test_rough_derivative_parameters_are_checked():
    """rms_height of a smooth material, or gamma of a rough one: refused with the material named."""
    from sarmitsuba.derivatives import MaterialParameter, raw_derivative
    with pytest.raises(ParameterError, match="'field' has no gamma"):
        raw_derivative(PLATE, MaterialParameter("field", "gamma"), sensor_overrides={"n_pulses": 8})
    with pytest.raises(ParameterError, match="'metal' has no rms_height"):
        raw_derivative("trihedral", MaterialParameter("metal", "rms_height"), sensor_overrides={"n_pulses": 8})


def _rough_trihedral(folder: Path, eps_r: float, s: float, length: float) -> str:
    """The built-in trihedral made of a rough half-space (``s``, ``l``): its PO carries the
    coherent factor, its clutter the monostatic table at bounce 1 and the bistatic one after; a
    smooth plate out of the beam takes table row 0."""
    import re
    repo = Path(__file__).parent.parent
    xml = (repo / "scenes" / "trihedral.xml").read_text()
    material = (f'<bsdf type="radar" id="metal"><float name="relative_permittivity" value="{eps_r!r}"/>'
                f'<float name="conductivity" value="0.05"/><float name="rms_height" value="{s!r}"/>'
                f'<float name="correlation_length" value="{length!r}"/></bsdf>')
    xml = re.sub(r'<bsdf type="radar" id="metal">.*?</bsdf>', material, xml, flags=re.S)
    xml = xml.replace('value="meshes/trihedral.obj"', f'value="{repo / "scenes" / "meshes" / "trihedral.obj"}"')
    # a smooth plate far outside the beam, first in the file: the rough material is table row 1
    far = ('<bsdf type="radar" id="far"><float name="relative_permittivity" value="3.0"/></bsdf>'
           '<shape type="rectangle" id="far_plate"><transform name="to_world"><translate x="300"/></transform>'
           '<ref id="far"/></shape>')
    xml = re.sub(r"(<scene[^>]*>)", lambda m: m.group(1) + far, xml, count=1)
    path = folder / f"rough_trihedral_{eps_r!r}_{s!r}_{length!r}.xml"
    path.write_text(xml)
    return str(path)


@pytest.mark.parametrize("parameter, index, step", [("relative_permittivity", 0, 6e-3), ("rms_height", 1, 4e-5),
                                                    ("correlation_length", 2, 2e-4)])
def test_raw_derivative_of_a_rough_material_matches_central_differences(tmp_path, parameter, index, step):
    """``d raw / dp`` of a rough trihedral (eta 6 - 0.09j, s = 4 mm, l = 20 mm; forward-mode AD
    through the reflection tables with their coherent factor and through both sigma nought tables)
    against ``(raw(p + h) - raw(p - h)) / 2h`` of two renders, within 1 % (measured 2.4e-5, 1.8e-5
    and 6.8e-5). Catches a tangent without the coherent factor's derivative, a sigma nought table
    left out of the differentiable tables or its tangent placed on another row, and the infinite
    derivative of sqrt at a smooth row's zero sigma nought (every return non-finite)."""
    from sarmitsuba.derivatives import MaterialParameter, raw_derivative
    pulses = {"n_pulses": 16}
    base = [6.0, 0.004, 0.02]
    derivative = raw_derivative(_rough_trihedral(tmp_path, *base), MaterialParameter("metal", parameter),
                                sensor_overrides=pulses)
    raws = []
    for sign in (1, -1):
        moved = list(base)
        moved[index] += sign * step
        raws.append(simulate(_rough_trihedral(tmp_path, *moved), sensor_overrides=pulses).raw.data.astype(np.complex128))
    fd = (raws[0] - raws[1]) / (2 * step)
    assert np.linalg.norm(fd) > 0
    error = np.linalg.norm(derivative.data - fd) / np.linalg.norm(fd)
    assert error <= 1e-2, f"relative error {error:.2e}"


@pytest.mark.parametrize("parameter, index, step", [("rms_height", 1, 4e-5), ("correlation_length", 2, 2e-4)])
def test_image_gradient_of_a_rough_material_matches_central_differences(tmp_path, parameter, index, step):
    """Reverse mode (``gradients`` of an image loss, the tables' adjoints collected by their
    sinks) on the rough trihedral against the loss's central difference over two renders, within
    1 % (measured 1.8e-4 and 7.8e-4)."""
    import sarmitsuba
    from sarmitsuba.derivatives import AmplitudeLoss, MaterialParameter
    size = {"image_size": (32, 32), "image_spacing": 0.5, "sensor_overrides": {"n_pulses": 32}}
    loss = AmplitudeLoss(np.zeros((32, 32)))
    base = [6.0, 0.004, 0.02]
    wanted = MaterialParameter("metal", parameter)
    gradient = sarmitsuba.gradients(_rough_trihedral(tmp_path, *base), loss, [wanted], **size).gradient[wanted]
    losses = []
    for sign in (1, -1):
        moved = list(base)
        moved[index] += sign * step
        losses.append(sarmitsuba.gradients(_rough_trihedral(tmp_path, *moved), loss, [], **size).loss)
    fd = (losses[0] - losses[1]) / (2 * step)
    assert fd != 0 and abs(gradient - fd) <= 1e-2 * abs(fd), (gradient, fd)
