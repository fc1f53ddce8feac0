"""Quad-pol renders of canonical targets against closed forms (docs/physics.md (P1)-(P7)).

Each target is rendered once with ``polarization = quad`` at the default ray density; the four
channels' complex values are read at the pixel where the total power peaks. The truth is the
scattering matrix of Lee and Pottier, *Polarimetric Radar Imaging*, 2009, ch. 3, in the
backscatter alignment with H = unit(z x look) and V = look x H (up-ish), and image-theory signs
(docs/physics.md (P5)):

* trihedral at boresight ``S ~ [[1, 0], [0, 1]]``;
* dihedral, fold horizontal and normal to the line of sight ``S ~ [[1, 0], [0, -1]]``;
* the same dihedral turned about the line of sight by psi (fold from H toward V)
  ``S ~ [[cos 2psi, sin 2psi], [sin 2psi, -cos 2psi]]``;
* a dielectric half space seen at incidence theta, single bounce: ``HH / VV = r_TE / r_TM``
  (Fresnel, written out here from the permittivity);
* a perfectly conducting wall on that half space: ``HH / VV = -r_TE / r_TM`` of the ground (P6).

Bugs these catch: V and H swapped in the antenna basis or the rotation sense of psi reversed
(the sign of HV at psi = +-30 deg), the TE/TM tables swapped (the half-space ratio), the
(-1)^(k+1) of even bounces lost (HH = +VV on the dihedral), HV and VH swapped or one column not
carried (reciprocity), and cross-talk in the Jones algebra (HV of the trihedral).
"""
from __future__ import annotations

import cmath
import json
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

import sarmitsuba  # noqa: F401
from sarmitsuba.scene import canonical as C
from sarmitsuba.pipeline import simulate

PEC = C.PEC
#: Line of sight, antenna -> scene, of the canonical sensor (45 deg, from the +y side).
LOOK = -C.TOWARD_SENSOR
EPS_R, SIGMA, FREQ = 5.0, 0.01, 9.6e9        # the dielectric half space (explicit permittivity)
DIELECTRIC = (f'<float name="relative_permittivity" value="{EPS_R}"/>'
              f'<float name="conductivity" value="{SIGMA}"/>')


def _peak(sim) -> dict[str, complex]:
    """The four channels' complex values at the pixel where their summed power peaks."""
    images = {name: channel.image.data for name, channel in sim.channels.items()}
    total = sum(np.abs(a) ** 2 for a in images.values())
    index = np.unravel_index(int(np.argmax(total)), total.shape)
    return {name: complex(a[index]) for name, a in images.items()}


def _quad(tmp_path: Path, mesh, material: str, depth: int, name: str, integrator=None, **sensor) -> dict[str, complex]:
    xml = C.scene_xml(tmp_path, mesh, material, depth, name=name)
    return _peak(simulate(str(xml), sensor_overrides={"polarization": "quad", **sensor}, integrator_overrides=integrator))


def _db(ratio: complex) -> float:
    return 20.0 * math.log10(abs(ratio))


def _deg(ratio: complex) -> float:
    """Phase of ``ratio`` in (-180, 180] deg."""
    return math.degrees(cmath.phase(ratio))


def _turned_dihedral(psi_deg: float) -> trimesh.Trimesh:
    """The canonical dihedral (fold along H) turned about the line of sight by psi: a right-hand
    turn about LOOK takes H toward V = LOOK x H."""
    mesh = C.dihedral(0.3, 0.3)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(math.radians(psi_deg), LOOK))
    return mesh


def _fresnel(cos_theta: float) -> tuple[complex, complex]:
    """TE and TM reflection coefficients of the half space, Born and Wolf's r_perp and the
    mirror-image r_tm = -r_par of docs/physics.md (R): r_te = (c - w) / (c + w),
    r_tm = -(eta c - w) / (eta c + w), w = sqrt(eta - sin^2), eta = eps_r - j sigma / (omega eps_0)."""
    eta = EPS_R - 1j * SIGMA / (2 * math.pi * FREQ * 8.8541878128e-12)
    w = cmath.sqrt(eta - (1.0 - cos_theta**2))
    return (cos_theta - w) / (cos_theta + w), -(eta * cos_theta - w) / (eta * cos_theta + w)


def test_trihedral_at_boresight_is_hh_equal_vv(tmp_path):
    s = _quad(tmp_path, C.trihedral(0.5), PEC, 3, "trihedral")
    assert abs(_db(s["VV"] / s["HH"])) < 0.5 and abs(_deg(s["VV"] / s["HH"])) < 10.0, s
    assert max(_db(s["HV"] / s["HH"]), _db(s["VH"] / s["HH"])) < -25.0, s


def test_dihedral_with_horizontal_fold_is_hh_minus_vv(tmp_path):
    s = _quad(tmp_path, C.dihedral(0.3, 0.3), PEC, 2, "dihedral")
    assert abs(_db(s["VV"] / s["HH"])) < 0.5 and abs(abs(_deg(s["VV"] / s["HH"])) - 180.0) < 10.0, s
    assert max(_db(s["HV"] / s["HH"]), _db(s["VH"] / s["HH"])) < -25.0, s


@pytest.mark.parametrize("psi", [22.5, 30.0, -30.0])
def test_dihedral_turned_about_the_line_of_sight(tmp_path, psi):
    """S ~ [[cos 2psi, sin 2psi], [sin 2psi, -cos 2psi]]: every ratio to HH within 1 dB and 10 deg
    (at 22.5 deg all four have the same magnitude; at +-30 deg HV is 4.8 dB above HH, with the
    sign of psi); and HV = VH within 0.2 dB and 5 deg (reciprocity)."""
    s = _quad(tmp_path, _turned_dihedral(psi), PEC, 2, f"dihedral_{psi:g}")
    c, n = math.cos(math.radians(2 * psi)), math.sin(math.radians(2 * psi))
    for name, expected in (("HV", n / c), ("VH", n / c), ("VV", -1.0)):
        ratio = s[name] / s["HH"]
        assert abs(_db(ratio) - _db(expected)) < 1.0, (name, _db(ratio), _db(expected))
        assert abs((_deg(ratio) - _deg(expected) + 180.0) % 360.0 - 180.0) < 10.0, (name, _deg(ratio))
    assert abs(_db(s["HV"] / s["VH"])) < 0.2 and abs(_deg(s["HV"] / s["VH"])) < 5.0, s


def test_dihedral_turned_by_45_deg_is_purely_cross_polarised(tmp_path):
    """psi = 45 deg: S ~ [[0, 1], [1, 0]]."""
    s = _quad(tmp_path, _turned_dihedral(45.0), PEC, 2, "dihedral_45")
    assert abs(_db(s["HV"] / s["VH"])) < 0.2 and abs(_deg(s["HV"] / s["VH"])) < 5.0, s
    assert max(_db(s["HH"] / s["HV"]), _db(s["VV"] / s["HV"])) < -25.0, s


@pytest.mark.parametrize("incidence", [30.0, 45.0, 60.0])
def test_half_space_single_bounce_ratio_is_fresnel(tmp_path, incidence):
    """A 3 m square of the dielectric on the ground, physical optics alone: every return is a
    single bounce at the incidence angle, so HH / VV = r_TE / r_TM in magnitude (0.2 dB) and phase
    (5 deg). (Seen 30 to 60 deg off its normal, the square returns only from its rim, where the
    edge currents (E4) set the ratio instead: ``diffraction`` is off for this PO check.)"""
    plate = trimesh.Trimesh([[-1.5, -1.5, 0], [1.5, -1.5, 0], [1.5, 1.5, 0], [-1.5, 1.5, 0]],
                            [[0, 1, 2], [0, 2, 3]], process=False)
    s = _quad(tmp_path, plate, DIELECTRIC, 1, f"half_space_{incidence:g}", {"diffraction": False},
              incidence_angle=incidence)
    r_te, r_tm = _fresnel(math.cos(math.radians(incidence)))
    ratio = s["HH"] / s["VV"]
    assert abs(_db(ratio) - _db(r_te / r_tm)) < 0.2, (_db(ratio), _db(r_te / r_tm))
    assert abs(_deg(ratio / (r_te / r_tm))) < 5.0, (_deg(ratio), _deg(r_te / r_tm))


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_metal_wall_on_dielectric_ground_double_bounce(tmp_path, incidence):
    """A PEC wall standing on the half space, the sensor at ``incidence``: the double bounce meets
    the ground at the incidence angle, so HH / VV = -r_TE / r_TM of the ground (P6); at 30 and
    60 deg the two differ (no tan = cot coincidence)."""
    a = 0.6
    ground = trimesh.Trimesh([[-a, 0, 0], [a, 0, 0], [a, 2 * a, 0], [-a, 2 * a, 0]], [[0, 1, 2], [0, 2, 3]],
                             process=False)
    wall = trimesh.Trimesh([[-a, 0, 0], [a, 0, 0], [a, 0, a], [-a, 0, a]], [[1, 0, 2], [0, 3, 2]], process=False)
    folder = tmp_path / f"wall_{incidence:g}"
    C.scene_xml(folder, ground, DIELECTRIC, 2, name="ground")
    C.scene_xml(folder, wall, PEC, 2, name="wall")
    xml = folder / "scene.xml"
    xml.write_text(f"""<scene version="3.0.0">
    {C.SENSOR}
    <integrator type="sbr"><integer name="max_depth" value="2"/></integrator>
    <bsdf type="radar" id="soil">{DIELECTRIC}</bsdf>
    <bsdf type="radar" id="metal">{PEC}</bsdf>
    <shape type="ply"><string name="filename" value="ground.ply"/><boolean name="face_normals" value="true"/>
        <ref id="soil"/></shape>
    <shape type="ply"><string name="filename" value="wall.ply"/><boolean name="face_normals" value="true"/>
        <ref id="metal"/></shape>
</scene>""")
    s = _peak(simulate(str(xml), sensor_overrides={"polarization": "quad", "incidence_angle": incidence}))
    r_te, r_tm = _fresnel(math.cos(math.radians(incidence)))
    expected = -r_te / r_tm
    ratio = s["HH"] / s["VV"]
    assert abs(_db(ratio) - _db(expected)) < 0.5, (_db(ratio), _db(expected))
    assert abs((_deg(ratio) - _deg(expected) + 180.0) % 360.0 - 180.0) < 10.0, (_deg(ratio), _deg(expected))


# ---- one trace, four channels; single channels as before ------------------------------------------
SCENES = Path(__file__).parent / "scenes"
ROUGH = str(SCENES / "rough_ground.xml")        # 80 m of rough ground, gamma -10 dB


def _nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    """10 log10(sum |a - b|^2 / sum |b|^2) [dB]; -inf for identical arrays."""
    error = float(np.sum(np.abs(a - b) ** 2))
    return -math.inf if error == 0.0 else 10.0 * math.log10(error / float(np.sum(np.abs(b) ** 2)))


def test_single_channels_equal_quad_channels_and_the_scalar_model_where_it_is_exact(tmp_path):
    """A concrete dihedral with its fold along H: a single-channel HH or VV render equals the quad
    render's channel (the same Jones model), and so does the scalar model (``polarimetry =
    scalar``), which is exact here because every facet contains H (P6). Quad casts exactly the
    rays of a single channel (the geometry is traced once for all four). A single HV render equals
    quad's HV on the dihedral turned by 30 deg. Fails if the scalar VV loses the (-1)^(k+1) of
    even bounces, or if quad traces per channel."""
    concrete = '<string name="material" value="concrete"/>'
    xml = str(C.scene_xml(tmp_path, C.dihedral(0.3, 0.3), concrete, 2, name="concrete_dihedral"))
    quad = simulate(xml, sensor_overrides={"polarization": "quad"})
    for name in ("HH", "VV"):
        single = simulate(xml, sensor_overrides={"polarization": name})
        scalar = simulate(xml, sensor_overrides={"polarization": name}, integrator_overrides={"polarimetry": "scalar"})
        assert _nrmse_db(quad.channels[name].image.data, single.image.data) < -60.0, name
        assert _nrmse_db(quad.channels[name].image.data, scalar.image.data) < -40.0, name
        assert single.trace.rays_per_order.tolist() == quad.trace.rays_per_order.tolist()
        assert single.trace.shadow_rays == quad.trace.shadow_rays
    turned = str(C.scene_xml(tmp_path, _turned_dihedral(30.0), PEC, 2, name="turned"))
    quad = simulate(turned, sensor_overrides={"polarization": "quad"})
    single = simulate(turned, sensor_overrides={"polarization": "HV"})
    assert _nrmse_db(quad.channels["HV"].image.data, single.image.data) < -60.0


def test_scalar_model_carries_no_jones_matrix():
    """With ``polarimetry = scalar`` HH and VV launch tubes without a Jones matrix (nothing
    compiled); by default, and for HV and quad, with one, whose columns at launch are the BSA h
    and v of the tube's direction (P1): h horizontal and normal to it, v = d x h up-ish."""
    from sarmitsuba.tracing.integration import jones
    from sarmitsuba.scene import planning
    from sarmitsuba.scene.effects import active_effects
    from sarmitsuba.tracing.driver.kernel import Blocks, Kernel, Launch
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.scene.loader import load_scene, material_table
    from sarmitsuba.tracing.driver.trace import subapertures
    cases = (("HH", "scalar", False), ("VV", "scalar", False), ("VV", "jones", True), ("HV", "jones", True),
             ("quad", "jones", True))
    for polarization, model, carried in cases:
        loaded = load_scene(ROUGH, {"n_pulses": 2, "polarization": polarization},
                            {"ray_spacing": 4.0, "polarimetry": model})
        p = loaded.params
        geometry = acquisition_geometry(p)
        window = planning.fast_time_window(p, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings)
        fp = planning.ray_footprint(p, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings)
        kernel = Kernel(loaded.scene, p, window, fp, loaded.settings,
                        material_table(loaded.scene, p.frequency, p.polarization), active_effects(loaded))
        subs = subapertures(geometry, fp, loaded.scene, 1)
        launch = Launch(antenna=geometry.positions[:1], lref=np.array([2 * np.linalg.norm(geometry.positions[0])]),
                        first=np.array([0]), count=np.array([1]), reference=subs.reference[:1],
                        r_near=subs.r_near[:1], along_limits=subs.along_limits[:1],
                        blocks=Blocks.of([(0, int(subs.k0[0]), 0, subs.n_i, fp.n_range, 1)]))
        tube, _ = kernel.launch(launch)
        assert isinstance(tube.jones, jones.Jones) == carried, polarization
        if carried:
            d = np.array(tube.ray.d).T
            h, v = np.array(tube.jones.h_re).T, np.array(tube.jones.v_re).T
            assert np.allclose(h[:, 2], 0, atol=1e-6) and np.allclose(np.sum(h * d, axis=1), 0, atol=1e-6)
            assert np.allclose(v, np.cross(d, h), atol=1e-6) and np.all(v[:, 2] > 0)


# ---- distributed clutter (P7) ---------------------------------------------------------------------
def _rough_quad(tmp_path: Path, cross_pol_db: float | None) -> dict[str, np.ndarray]:
    """The rough ground rendered in quad, its interior pixels (away from the plate's edges)."""
    text = Path(ROUGH).read_text()
    if cross_pol_db is not None:
        text = text.replace('<float name="gamma_db" value="-10"/>',
                            f'<float name="gamma_db" value="-10"/><float name="cross_pol_db" value="{cross_pol_db}"/>')
    xml = tmp_path / "rough.xml"
    xml.write_text(text)
    sim = simulate(str(xml), sensor_overrides={"polarization": "quad", "n_pulses": 256})
    out = {}
    for name, channel in sim.channels.items():
        image = channel.image
        az, rg = np.meshgrid(image.azimuth, image.range, indexing="ij")
        out[name] = image.data[(np.abs(az) < 20.0) & (np.abs(rg) < 20.0)]
    return out


def _coherence(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(np.sum(a * np.conj(b))) / np.sqrt(np.sum(np.abs(a) ** 2) * np.sum(np.abs(b) ** 2)))


@pytest.mark.parametrize("cross_pol_db", [None, -8.0])
def test_rough_ground_cross_polarised_level_and_correlations(tmp_path, cross_pol_db):
    """Reflection symmetry (P7): HV at the material's level q below the mean co-polarised power
    (the default -15 dB, or -8 dB when set) within 1 dB; HV uncorrelated with HH (coherence below
    0.1 over ~1,000 speckle pixels, whose estimator alone gives ~0.03); HH and VV fully correlated
    (constant gamma: the same sigma0 and phase, coherence above 0.95); HV = VH exactly after
    one bounce as well (the scatterer's matrix is symmetric). Fails if q enters as an amplitude
    instead of a power, if the cross-polarised phase is the co-polarised one, or if the default
    level is not the documented one."""
    s = _rough_quad(tmp_path, cross_pol_db)
    expected = -15.0 if cross_pol_db is None else cross_pol_db
    co = 0.5 * (np.sum(np.abs(s["HH"]) ** 2) + np.sum(np.abs(s["VV"]) ** 2))
    level = 10.0 * math.log10(np.sum(np.abs(s["HV"]) ** 2) / co)
    assert abs(level - expected) < 1.0, (level, expected)
    assert s["HH"].size > 500
    assert _coherence(s["HH"], s["HV"]) < 0.1
    assert _coherence(s["HH"], s["VV"]) > 0.95
    assert _nrmse_db(s["HV"], s["VH"]) < -30.0


def test_cross_polarised_level_from_the_materials(tmp_path):
    """``itu-radio-material``'s xpd_coefficient K gives q = K / (1 - K) (K = 0.2: q = 0.25);
    ``radar``'s cross_pol_db = -10 gives q = 0.1; K = 1 is refused, naming the parameter."""
    from sarmitsuba.scene.loader import SceneError, load_scene, material_table
    xml = tmp_path / "materials.xml"
    body = """<scene version="3.0.0">
    <bsdf type="itu-radio-material" id="a"><string name="type" value="concrete"/>
        <float name="scattering_coefficient" value="0.3"/><float name="xpd_coefficient" value="{k}"/></bsdf>
    <bsdf type="radar" id="b"><string name="material" value="concrete"/><float name="gamma_db" value="-10"/>
        <float name="cross_pol_db" value="-10"/></bsdf>
    <shape type="rectangle"><ref id="a"/></shape>
    <shape type="rectangle"><transform name="to_world"><translate x="3"/></transform><ref id="b"/></shape>
</scene>"""
    xml.write_text(body.format(k=0.2))
    loaded = load_scene(str(xml), {"polarization": "quad"})
    table = material_table(loaded.scene, loaded.params.frequency, "quad")
    assert np.allclose(sorted(table.cross_pol), [0.1, 0.25], rtol=1e-6)
    xml.write_text(body.format(k=1.0))
    with pytest.raises(SceneError, match=r"line 2: itu-radio-material 'a': xpd_coefficient = 1.0 is outside"):
        load_scene(str(xml))


# ---- the interface ------------------------------------------------------------------------------
def test_quad_render_writes_four_channels_on_one_grid_and_a_pauli_picture(tmp_path, capsys):
    """``render --set polarization=quad``: raw_XX.npz and image_XX.npz for the four channels (no
    raw.npz / image.npz), every image on the same grid, pauli.png; ``analyze`` reads each channel
    and finds its raw data beside it; the one-channel names are unchanged for VV."""
    from sarmitsuba.cli import main
    from sarmitsuba.core.image import SarImage
    out = tmp_path / "quad"
    assert main(["render", "trihedral", "--out", str(out), "--no-progress", "--set", "polarization=quad"]) == 0
    names = {p.name for p in out.iterdir()}
    for channel in ("HH", "HV", "VH", "VV"):
        assert {f"raw_{channel}.npz", f"image_{channel}.npz", f"image_{channel}.png"} <= names, names
    assert "pauli.png" in names and "raw.npz" not in names and "image.npz" not in names
    images = {c: SarImage.load(out / f"image_{c}.npz") for c in ("HH", "HV", "VH", "VV")}
    for image in images.values():
        assert np.array_equal(image.azimuth, images["HH"].azimuth) and np.array_equal(image.range, images["HH"].range)
        assert image.metadata["polarization"] in images
    capsys.readouterr()
    assert main(["analyze", str(out / "image_VV.npz"), "--target", "0,0,0"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["carrier"] == "given", report          # from raw_VV.npz beside image_VV.npz ("estimated" without)
    single = tmp_path / "single"
    assert main(["render", "trihedral", "--out", str(single), "--no-progress"]) == 0
    assert {"raw.npz", "image.npz", "image.png"} <= {p.name for p in single.iterdir()}


@pytest.mark.parametrize("value", ["hv", "QUAD", "RR", "HH+VV"])
def test_bad_polarization_exits_2_naming_the_valid_values(tmp_path, capsys, value):
    from sarmitsuba.cli import main
    assert main(["render", "dihedral", "--out", str(tmp_path / "x"), "--set", f"polarization={value}"]) == 2
    err = capsys.readouterr().err
    assert "polarization" in err and "'quad'" in err and "'HV'" in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()


# ---- a real city: a crop of Sionna RT's Munich ------------------------------------------------------
def _munich_crop(folder: Path, half: float = 80.0) -> Path:
    """Sionna's Munich within ``half`` m of its centre: the shapes whose box meets the square,
    their triangles with centroids inside it, and the ground as a square of the crop."""
    import xml.etree.ElementTree as ET
    from sarmitsuba.scene.loader import sionna_scenes
    source = sionna_scenes()["munich"]
    tree = ET.parse(source)
    folder.mkdir(parents=True, exist_ok=True)
    for shape in list(tree.getroot().findall("shape")):
        filename = shape.find("string[@name='filename']")
        mesh = trimesh.load(source.parent / filename.get("value"), process=False)
        lo, hi = mesh.bounds
        if np.any(hi[:2] < -half) or np.any(lo[:2] > half):
            tree.getroot().remove(shape)
            continue
        if hi[2] - lo[2] < 1.0 and np.all(lo[:2] <= -half) and np.all(hi[:2] >= half):     # the ground
            z = lo[2]
            mesh = trimesh.Trimesh([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]],
                                   [[0, 1, 2], [0, 2, 3]], process=False)
        else:
            inside = np.flatnonzero(np.all(np.abs(mesh.triangles_center[:, :2]) <= half, axis=1))
            if inside.size == 0:
                tree.getroot().remove(shape)
                continue
            mesh = mesh.submesh([inside], append=True)
        name = Path(filename.get("value")).name
        mesh.export(folder / name)
        filename.set("value", name)
    tree.write(folder / "munich_crop.xml")
    return folder / "munich_crop.xml"


@pytest.mark.skipif(not __import__("sarmitsuba.scene.loader", fromlist=["x"]).sionna_scenes(),
                    reason="Sionna RT is not installed (pip install sionna-rt): no Munich scene")
def test_munich_crop_is_reciprocal_and_depolarises(tmp_path):
    """A 160 m crop of Munich (smooth ITU materials, so HV comes from geometry alone): HV carries
    a real part of the power (above -25 dB of the co-polarised channels: buildings turned against
    the track depolarise), and HV = VH within 0.2 dB and 5 deg at every pixel within 20 dB of
    the brightest HV pixel (P8)."""
    import warnings
    xml = _munich_crop(tmp_path / "munich")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                   # Munich's own mesh defects, reported on load
        sim = simulate(str(xml), sensor_overrides={"polarization": "quad"})
    s = {name: channel.image.data for name, channel in sim.channels.items()}
    co = 0.5 * (np.sum(np.abs(s["HH"]) ** 2) + np.sum(np.abs(s["VV"]) ** 2))
    assert 10 * math.log10(np.sum(np.abs(s["HV"]) ** 2) / co) > -25.0
    power = np.abs(s["HV"]) ** 2
    bright = power > power.max() * 1e-2
    ratio = s["HV"][bright] / s["VH"][bright]
    assert bright.sum() > 20
    assert np.max(np.abs(20 * np.log10(np.abs(ratio)))) < 0.2 and np.max(np.abs(np.degrees(np.angle(ratio)))) < 5.0


def _triple_bounce_peak(tmp_path: Path, mesh, material: str, name: str) -> dict[str, complex]:
    """The four channels of the triple bounce alone (``split_bounces``) at the pixel where their
    summed power peaks."""
    xml = C.scene_xml(tmp_path, mesh, material, 3, name=name)
    sim = simulate(str(xml), sensor_overrides={"polarization": "quad"}, integrator_overrides={"split_bounces": True})
    images = {n: channel.images_per_order[2].data for n, channel in sim.channels.items()}
    total = sum(np.abs(a) ** 2 for a in images.values())
    index = np.unravel_index(int(np.argmax(total)), total.shape)
    return {n: complex(a[index]) for n, a in images.items()}


def test_concrete_trihedral_against_the_chain_reference(tmp_path):
    """A concrete (half-space) trihedral at boresight: by its three-fold and mirror symmetry the
    six facet orders of the triple bounce light equal areas, so the triple bounce's S / S_PEC is
    the mean of the six chains' matrices, each computed by the NumPy reference
    (sarmitsuba.tracing.integration.polarimetry, (P5)) with Fresnel coefficients written out here: HH and VV
    within 0.5 dB and 10 deg, HV 25 dB below. (The whole image's peak also holds the faces' own
    single-bounce edge terms, a quarter of the concrete triple bounce there: |r| once against
    |r|^3.) The scalar model, |r_te(1/sqrt 3)|^3, is 16 dB brighter: the field turns from TE to TM
    between the facets."""
    import itertools
    from sarmitsuba.scene import materials
    from sarmitsuba.tracing.integration import polarimetry
    mesh = C.trihedral(0.5)
    eta = materials.itu_permittivity("concrete", FREQ)

    def fresnel(c):
        w = np.sqrt(eta - (1.0 - c**2) + 0j)
        return (c - w) / (c + w), -(eta * c - w) / (eta * c + w)

    reference = np.mean([polarimetry.scattering_matrix(mesh.face_normals[list(order)], LOOK, [fresnel] * 3)
                         for order in itertools.permutations(range(3))], axis=0)
    pec = _triple_bounce_peak(tmp_path, mesh, PEC, "trihedral_pec")
    concrete = _triple_bounce_peak(tmp_path, mesh, '<string name="material" value="concrete"/>', "trihedral_concrete")
    for name, (rx, tx) in (("HH", (0, 0)), ("VV", (1, 1))):
        ratio = concrete[name] / pec["HH"]
        assert abs(_db(ratio) - _db(reference[rx, tx])) < 0.5, (name, _db(ratio), _db(reference[rx, tx]))
        assert abs((_deg(ratio) - _deg(reference[rx, tx]) + 180.0) % 360.0 - 180.0) < 10.0, (name, _deg(ratio))
    assert _db(concrete["HV"] / concrete["HH"]) < -25.0
    scalar = 3 * _db(fresnel(1.0 / math.sqrt(3.0))[0])
    assert scalar - _db(reference[0, 0]) > 10.0           # what the scalar model would get wrong


def test_scalar_model_with_a_cross_polarised_channel_exits_2(tmp_path, capsys):
    """The scalar model has no cross-polarised channel: one message naming both parameters."""
    from sarmitsuba.cli import main
    out = tmp_path / "x"
    assert main(["render", "dihedral", "--out", str(out), "--set", "polarization=HV",
                 "--integrator-set", "polarimetry=scalar"]) == 2
    err = capsys.readouterr().err
    assert "polarimetry = 'scalar'" in err and "polarization = 'HV'" in err and "Traceback" not in err
    assert not out.exists()
    assert main(["render", "dihedral", "--out", str(out), "--integrator-set", "polarimetry=vector"]) == 2
    assert "'jones', 'scalar'" in capsys.readouterr().err
