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
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

import sarmitsuba  # noqa: F401
from sarmitsuba import canonical as C
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


def _quad(tmp_path: Path, mesh, material: str, depth: int, name: str, **sensor) -> dict[str, complex]:
    xml = C.scene_xml(tmp_path, mesh, material, depth, name=name)
    return _peak(simulate(str(xml), sensor_overrides={"polarization": "quad", **sensor}))


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
    """A 3 m square of the dielectric on the ground: every return is a single bounce at the
    incidence angle, so HH / VV = r_TE / r_TM in magnitude (0.2 dB) and phase (5 deg)."""
    plate = trimesh.Trimesh([[-1.5, -1.5, 0], [1.5, -1.5, 0], [1.5, 1.5, 0], [-1.5, 1.5, 0]],
                            [[0, 1, 2], [0, 2, 3]], process=False)
    s = _quad(tmp_path, plate, DIELECTRIC, 1, f"half_space_{incidence:g}", incidence_angle=incidence)
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
