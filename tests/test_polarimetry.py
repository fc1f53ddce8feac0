"""The polarimetric ray-optics reference (sarmitsuba.tracing.integration.polarimetry; docs/physics.md (P1)-(P6))
against closed forms: image theory, PEC plate, trihedral and dihedral (level and turned about
the line of sight), reciprocity, and dielectric half-space bounces (ITU-R P.2040 Fresnel
coefficients of sarmitsuba.scene.fresnel, mirror-image convention: r_tm = -R_TM of P.2040).

Geometry is built here independently of the module: mirror chains with ``_mirror``, rotations
with Rodrigues' formula, the BSA basis from its definition ``h = unit(z x l)``, ``v = l x h``.
Angles are never only 45 deg. Each test names the deliberate bugs it catches (each was planted
in a copy of the module and seen to fail): "s/p swapped" (r_te applied along p and r_tm along
s), "p' stale" (the TM vector not re-computed after reflection, p used for p'), "handedness"
(v = h x l, down-ish), "r_tm sign" (P.2040's R_TM used where the mirror-image r_tm is meant),
"FSA receive" (the receive basis taken from the return direction -l instead of the antenna's).
"""
from __future__ import annotations

import itertools
import math
from functools import partial

import numpy as np
import pytest

from sarmitsuba.scene.fresnel import fresnel_half_space
from sarmitsuba.tracing.integration.polarimetry import (PEC, antenna_jones, bsa_basis, facet_basis, project_bsa, reflect_jones,
                                            scattering_matrix)

ETA = 5.0 - 0.5j           # the ground of the dielectric tests
ETA_WALL = 3.0 - 0.2j      # a dielectric wall
Z = np.array([0.0, 0.0, 1.0])
ATOL = 1e-12


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _mirror(v, n):
    return v - 2.0 * np.dot(v, n) * n


def _rotate(v, axis, angle):
    """Rodrigues: ``v`` turned by ``angle`` [rad] right-handedly about the unit ``axis``."""
    v, axis = np.asarray(v, float), np.asarray(axis, float)
    return (v * math.cos(angle) + np.cross(axis, v) * math.sin(angle)
            + axis * np.dot(axis, v) * (1.0 - math.cos(angle)))


def _look(incidence_deg, heading=0.0):
    """A right-looking radar flying along +x turned by ``heading`` about z, looking down at
    ``incidence`` from the vertical toward -y (docs/design.md section 4)."""
    th = math.radians(incidence_deg)
    return _rotate([0.0, -math.sin(th), -math.cos(th)], Z, math.radians(heading))


def _hv(look):
    h = _unit(np.cross(Z, look))
    return h, np.cross(look, h)


def _fresnel(eta):
    return partial(fresnel_half_space, eta=eta)


def _chain_directions(normals, look):
    """Incident direction at each facet of a mirror chain, and the outgoing one."""
    d, out = np.asarray(look, float), []
    for n in normals:
        out.append(d)
        d = _mirror(d, n)
    return out, d


def _retro_chain(rng, look, k, plane=None):
    """k unit normals whose mirror chain sends ``look`` back along ``-look``: k - 1 random ones
    (in ``plane``, spanned by two given vectors, when given), the last ``unit(d + look)``."""
    normals, d = [], np.asarray(look, float)
    for _ in range(k - 1):
        n = _unit(rng.normal(size=3) if plane is None else rng.normal(size=2) @ np.asarray(plane))
        normals.append(n)
        d = _mirror(d, n)
    normals.append(_unit(d + look))
    return np.array(normals)


def _db(x):
    return 20.0 * math.log10(max(abs(x), 1e-300))


# ----------------------------------------------------------------------------------------------
# (P1) basis and (P3) single reflections
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("incidence, heading", [(20.0, 0.0), (35.0, 30.0), (70.0, -110.0)])
def test_bsa_basis_is_horizontal_up_ish_and_right_handed(incidence, heading):
    # catches: handedness (v = h x l points down, h x v = -l)
    look = _look(incidence, heading)
    h, v = bsa_basis(look)
    assert abs(h @ Z) < ATOL and abs(h @ look) < ATOL and abs(v @ look) < ATOL
    assert v @ Z == pytest.approx(math.sin(math.radians(incidence)), abs=ATOL)   # up-ish
    np.testing.assert_allclose(np.cross(h, v), look, atol=ATOL)
    np.testing.assert_allclose(_rotate(h, Z, -math.radians(heading)), [1.0, 0.0, 0.0], atol=ATOL)
    # broadcasting over leading axes, and the Jones matrix the antenna transmits
    hb, vb = bsa_basis(np.stack([look, 3.0 * look]))
    np.testing.assert_allclose(hb, [h, h], atol=ATOL)
    np.testing.assert_allclose(antenna_jones(look), np.stack([h, v], axis=-1), atol=ATOL)


@pytest.mark.parametrize("look", [[0.0, 0.0, -1.0], [0.0, 0.0, 2.0], [1e-12, 0.0, -1.0]])
def test_bsa_basis_is_undefined_at_nadir_and_zenith(look):
    with pytest.raises(ValueError, match="nadir"):
        bsa_basis(look)


def test_pec_mirror_is_image_theory():
    # PEC: E -> -E + 2 (n.E) n, d -> d - 2 (d.n) n, for either orientation of n and at normal
    # incidence. catches: p' stale (TM part left on p), r_tm sign (TM part would be +M E)
    rng = np.random.default_rng(11)
    for trial in range(40):
        n = _unit(rng.normal(size=3))
        d = -n if trial == 0 else _unit(rng.normal(size=3))
        d = _unit(d + 1e-7 * rng.normal(size=3)) if trial == 1 else d
        J = rng.normal(size=(3, 2)) + 1j * rng.normal(size=(3, 2))
        J -= np.outer(d, d @ J)                                       # transverse fields
        for normal in (n, -n):
            J1, d1 = reflect_jones(J, d, normal, *PEC)
            np.testing.assert_allclose(J1, -J + 2.0 * np.outer(n, n @ J), atol=ATOL)
            np.testing.assert_allclose(d1, _mirror(d, n), atol=ATOL)
            assert np.abs(d1 @ J1).max() < 1e-12                      # still transverse


def test_reflection_is_r_tm_mirror_plus_te_correction():
    # (P3'): J' = r_tm M J + (r_te - r_tm) s (s.J), s = unit(n x d), with dielectric
    # coefficients at the local incidence. catches: s/p swapped, p' stale, r_tm sign
    rng = np.random.default_rng(12)
    d = _unit(rng.normal(size=(30, 3)))
    n = _unit(rng.normal(size=(30, 3)))
    J = rng.normal(size=(30, 3, 2)) + 1j * rng.normal(size=(30, 3, 2))
    J -= d[:, :, None] * np.einsum("ni,nij->nj", d, J)[:, None, :]
    r_te, r_tm = fresnel_half_space(np.abs(np.sum(d * n, axis=1)), ETA)
    J1, d1 = reflect_jones(J, d, n, r_te, r_tm)                        # batched over 30 rays
    for i in range(30):
        s = _unit(np.cross(n[i], d[i]))
        mirror_J = J[i] - 2.0 * np.outer(n[i], n[i] @ J[i])
        expected = r_tm[i] * mirror_J + (r_te[i] - r_tm[i]) * np.outer(s, s @ J[i])
        np.testing.assert_allclose(J1[i], expected, atol=ATOL)
        np.testing.assert_allclose(d1[i], _mirror(d[i], n[i]), atol=ATOL)


def test_facet_basis_and_normal_incidence():
    # (P2): (s, p, d) right-handed, p' = M p = s x d'; at normal incidence any s normal to n,
    # and the reflection is continuous as d -> -n (r_te -> r_tm), including below the normal
    # incidence threshold (1e-13). catches: r_tm sign
    n = _unit([0.3, -0.2, 0.9])
    for angle in (0.7, 1e-4, 1e-8, 1e-11, 1e-13, 0.0):
        d = _rotate(-n, _unit(np.cross(n, [1.0, 0.0, 0.0])), angle)
        s, p, p1, d1 = facet_basis(d, n)
        np.testing.assert_allclose(np.cross(s, p), d, atol=ATOL)
        np.testing.assert_allclose(p1, _mirror(p, n), atol=ATOL)
        np.testing.assert_allclose(p1, np.cross(s, d1), atol=ATOL)
        assert abs(s @ n) < ATOL
        J = antenna_jones(d)
        r_te, r_tm = fresnel_half_space(abs(d @ n), ETA)
        J1, _ = reflect_jones(J, d, n, r_te, r_tm)
        r0 = fresnel_half_space(1.0, ETA)[0]
        # near normal incidence M J -> J (J tangential), so J' -> r(0) J
        np.testing.assert_allclose(J1, r0 * J, atol=2.0 * angle + ATOL)


@pytest.mark.parametrize("incidence", [30.0, 45.0, 60.0])
def test_ground_single_bounce_forward_is_te_and_tm(incidence):
    # A horizontal ground at incidence theta: h is its s vector (z x l is normal to the plane of
    # incidence), v its p. By (P3) the H column becomes r_te h and the V column r_tm M v.
    # A receiver at the specular position looks along l_r = -d' = -M l, so (P1) gives it
    # h_r = unit(z x -M l) = -h (M l has l's horizontal part) and v_r = l_r x h_r
    # = M l x h = M l x M h = -M (l x h) = -M v. Hence, in the receiver's BSA basis,
    # S = [[h_r.(r_te h), 0], [0, v_r.(r_tm M v)]] = -diag(r_te, r_tm): HH / VV = r_te / r_tm
    # exactly, HV = VH = 0 (the scalar model's HH = TE, VV = TM, common sign -1).
    # catches: s/p swapped, p' stale, r_tm sign, handedness, FSA receive
    look = _look(incidence, heading=25.0)
    h, v = _hv(look)
    r_te, r_tm = fresnel_half_space(math.cos(math.radians(incidence)), ETA)
    J1, d1 = reflect_jones(antenna_jones(look), look, Z, r_te, r_tm)
    np.testing.assert_allclose(J1[:, 0], r_te * h, atol=ATOL)
    np.testing.assert_allclose(J1[:, 1], r_tm * _mirror(v, Z), atol=ATOL)
    S = project_bsa(J1, -d1)
    np.testing.assert_allclose(S, -np.diag([r_te, r_tm]), atol=ATOL)
    assert S[0, 0] / S[1, 1] == pytest.approx(r_te / r_tm, rel=1e-12)
    assert abs(S[0, 0] / S[1, 1]) == pytest.approx(abs(r_te / r_tm), rel=1e-12)


# ----------------------------------------------------------------------------------------------
# (P5) canonical targets
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("incidence, heading", [(30.0, 0.0), (60.0, 40.0)])
def test_plate_at_normal_incidence(incidence, heading):
    # one facet with normal -l (either orientation): S = r(0) I, -I for a PEC (image theory)
    # catches: r_tm sign (VV = +1), FSA receive (HH = +1)
    look = _look(incidence, heading)
    np.testing.assert_allclose(scattering_matrix([-look], look, [PEC]), -np.eye(2), atol=ATOL)
    np.testing.assert_allclose(scattering_matrix([look], look, [PEC]), -np.eye(2), atol=ATOL)
    r0 = fresnel_half_space(1.0, ETA)[0]
    np.testing.assert_allclose(scattering_matrix([-look], look, [_fresnel(ETA)]), r0 * np.eye(2),
                               atol=ATOL)


def _random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


@pytest.mark.parametrize("into_corner", [(1.0, 1.0, 1.0), (1.0, 2.0, 0.7), (2.0, 0.5, 1.5)])
def test_pec_trihedral_is_identity(into_corner):
    # Faces x = 0, y = 0, z = 0 (normals e_x, e_y, e_z), looked into along -into_corner: the
    # symmetry axis (incidence 54.7 deg) and two off-axis looks; also the corner turned by a
    # random rotation. Every facet order: M_3 M_2 M_1 = -I, T = (-1)^3 (-I) = I, so S = +I
    # exactly and HV is 0 (< -25 dB below HH). catches: p' stale, r_tm sign, FSA receive
    rng = np.random.default_rng(int(10 * sum(into_corner)))
    for rotation in (np.eye(3), _random_rotation(rng), _random_rotation(rng)):
        look = rotation @ -_unit(into_corner)
        if abs(look @ Z) > 0.99:
            continue
        for order in itertools.permutations(range(3)):
            normals = rotation @ np.eye(3)[list(order)].T
            S = scattering_matrix(normals.T, look, [PEC] * 3)
            np.testing.assert_allclose(S, np.eye(2), atol=1e-12)
            assert _db(S[0, 1] / S[0, 0]) < -25.0 and _db(S[1, 0] / S[1, 1]) < -25.0


@pytest.mark.parametrize("incidence", [30.0, 60.0, 45.0])
@pytest.mark.parametrize("tilt", [0.0, 20.0])
def test_pec_dihedral_with_level_fold(incidence, tilt):
    # Wall (normal +y, facing the radar) and ground (+z), turned by `tilt` about the fold (x):
    # the fold is horizontal and normal to l; M_2 M_1 is the half turn about it: h -> h,
    # v -> -v, so S = diag(+1, -1) for both facet orders: HH = -VV, HV = 0.
    # catches: p' stale (VV = +1), FSA receive (HH = -1)
    look = _look(incidence)
    fold = np.array([1.0, 0.0, 0.0])
    normals = np.array([_rotate(n, fold, math.radians(tilt)) for n in ([0.0, 1.0, 0.0], Z)])
    for chain in (normals, normals[::-1]):
        S = scattering_matrix(chain, look, [PEC, PEC])
        np.testing.assert_allclose(S, np.diag([1.0, -1.0]), atol=ATOL)
        assert S[0, 0] == pytest.approx(-S[1, 1], abs=ATOL)


@pytest.mark.parametrize("psi_deg", [10.0, 22.5, 45.0, -30.0])
@pytest.mark.parametrize("incidence, heading", [(30.0, 0.0), (60.0, -35.0)])
def test_pec_dihedral_turned_about_the_line_of_sight(psi_deg, incidence, heading):
    # The level dihedral turned right-handedly about l by psi: fold f = cos(psi) h + sin(psi) v
    # (h toward v), g = l x f; the half turn about f maps E to (f.E) f - (g.E) g, so
    # S_HH = cos^2 - sin^2 = cos 2psi, S_VH = S_HV = 2 sin cos = sin 2psi, S_VV = -cos 2psi.
    # catches: handedness (off-diagonal sign), p' stale, FSA receive
    look = _look(incidence, heading)
    h, _ = _hv(look)
    psi = math.radians(psi_deg)
    wall, ground = _rotate([0.0, 1.0, 0.0], Z, math.radians(heading)), Z
    normals = np.array([_rotate(n, look, psi) for n in (wall, ground)])
    np.testing.assert_allclose(np.cross(*normals), _rotate(h, look, psi), atol=ATOL)  # the fold
    c, s = math.cos(2 * psi), math.sin(2 * psi)
    for chain in (normals, normals[::-1]):
        S = scattering_matrix(chain, look, [PEC, PEC])
        np.testing.assert_allclose(S, [[c, s], [s, -c]], atol=ATOL)


# ----------------------------------------------------------------------------------------------
# Dielectric chains: (P6) and the wall-ground double bounce
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("incidence", [30.0, 45.0, 60.0])
def test_wall_ground_double_bounce_with_dielectric_ground(incidence):
    # l = (0, -sin t, -cos t); wall normal +y meets the ray at cos = sin t, ground (+z) at
    # cos = cos t. h = +x lies in both facets: it is s at both, S_HH = r_te,w r_te,g.
    # v = l x h = (0, -cos t, sin t). Ground first: v -> r_tm,g M_z v = r_tm,g (0, -cos t, -sin t)
    # (its p'); the wall then reflects that TM field (its p) to r_tm,w M_y (...) =
    # r_tm,w r_tm,g (0, cos t, -sin t) = -r_tm,w r_tm,g v, so S_VV = -r_tm,w r_tm,g; wall first
    # gives the same (reciprocity). PEC wall (-1, -1): S = diag(-r_te,g, r_tm,g), and
    # HH / VV = -r_te,g / r_tm,g: |HH / VV| = |r_te / r_tm| of the ground, and -1 as the
    # ground tends to a conductor (HH = -VV). A dielectric wall multiplies in its own r_te, r_tm.
    # catches: s/p swapped (HH/VV = -r_tm/r_te), p' stale, FSA receive, and the r_tm sign of
    # coefficients handed in (HH/VV = +r_te/r_tm; see test_the_tests_catch_a_wrong_r_tm_convention:
    # a sign flipped inside the module at every facet cancels in a double bounce and is caught
    # by the plate, trihedral and single-bounce tests)
    t = math.radians(incidence)
    look = _look(incidence)
    wall, ground = np.array([0.0, 1.0, 0.0]), Z
    rg_te, rg_tm = fresnel_half_space(math.cos(t), ETA)
    rw_te, rw_tm = fresnel_half_space(math.sin(t), ETA_WALL)
    for chain, coeffs in (([ground, wall], [_fresnel(ETA), PEC]), ([wall, ground], [PEC, _fresnel(ETA)])):
        S = scattering_matrix(chain, look, coeffs)
        np.testing.assert_allclose(S, np.diag([-rg_te, rg_tm]), atol=ATOL)
        assert S[0, 0] / S[1, 1] == pytest.approx(-rg_te / rg_tm, rel=1e-12)
        assert abs(S[0, 0] / S[1, 1]) == pytest.approx(abs(rg_te / rg_tm), rel=1e-12)
    S = scattering_matrix([ground, wall], look, [_fresnel(ETA), _fresnel(ETA_WALL)])
    np.testing.assert_allclose(S, np.diag([rw_te * rg_te, -rw_tm * rg_tm]), atol=ATOL)


def test_the_tests_catch_a_wrong_r_tm_convention():
    # P.2040's R_TM (= -r_tm) passed for the ground, the PEC wall right: VV changes sign and
    # HH/VV = +r_te/r_tm, which the previous test's closed form rejects
    look = _look(30.0)
    rg_te, rg_tm = fresnel_half_space(math.cos(math.radians(30.0)), ETA)
    wrong = scattering_matrix([Z, [0.0, 1.0, 0.0]], look, [(rg_te, -rg_tm), PEC])
    assert wrong[0, 0] / wrong[1, 1] == pytest.approx(rg_te / rg_tm, rel=1e-12)
    assert not np.allclose(wrong, np.diag([-rg_te, rg_tm]), atol=1e-6)


@pytest.mark.parametrize("k", [1, 2, 3, 4])
@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_chains_in_the_plane_of_the_look_are_the_scalar_model(k, incidence):
    # (P6): normals in the vertical plane of l (span of z and the horizontal look): h is s at
    # every facet, and S = diag(prod r_te, (-1)^(k+1) prod r_tm) with each facet's own
    # dielectric coefficients at its incidence. catches: s/p swapped (k >= 2), p' stale (k >= 2),
    # r_tm sign (odd k), FSA receive
    look = _look(incidence, heading=15.0)
    plane = [Z, _unit(look - (look @ Z) * Z)]
    rng = np.random.default_rng(100 * k + int(incidence))
    etas = [ETA, ETA_WALL, 2.5 - 0.1j, 8.0 - 2.0j][:k]
    for _ in range(5):
        normals = _retro_chain(rng, look, k, plane)
        directions, _ = _chain_directions(normals, look)
        te, tm = zip(*(fresnel_half_space(abs(d @ n), e) for d, n, e in zip(directions, normals, etas)))
        S = scattering_matrix(normals, look, [_fresnel(e) for e in etas])
        expected = np.diag([np.prod(te), (-1) ** (k + 1) * np.prod(tm)])
        np.testing.assert_allclose(S, expected, atol=ATOL)


# ----------------------------------------------------------------------------------------------
# (P5) reciprocity
# ----------------------------------------------------------------------------------------------

def test_two_facet_chains_are_symmetric():
    # A retro-reflecting pair is a right-angle dihedral with its fold normal to l, whatever its
    # orientation: S = S^T for PEC and for two different dielectrics, and the reversed chain
    # gives the same S. catches: FSA receive (S_HV = -S_VH); the other planted bugs keep a
    # pair's S symmetric, so this is a property test first
    rng = np.random.default_rng(21)
    cross = []
    for _ in range(20):
        look = _unit(rng.normal(size=3) - [0.0, 0.0, 1.5])
        normals = _retro_chain(rng, look, 2)
        for coeffs in ([PEC, PEC], [_fresnel(ETA), _fresnel(ETA_WALL)]):
            S = scattering_matrix(normals, look, coeffs)
            np.testing.assert_allclose(S, S.T, atol=ATOL)
            np.testing.assert_allclose(scattering_matrix(normals[::-1], look, coeffs[::-1]), S, atol=ATOL)
            cross.append(abs(S[0, 1]))
    assert max(cross) > 0.3                                      # HV is exercised, not a zero


def test_three_facet_chains_and_their_reverses_are_transposes():
    # A chain and its reverse (same facets, reverse order) give S and S^T, so their sum, the
    # monostatic return of the three facets, has HV = VH; a single non-palindromic chain is
    # not symmetric (a PEC one is a rotation about l). catches: p' stale, r_tm sign (the PEC
    # rotation's determinant), FSA receive
    rng = np.random.default_rng(31)
    asymmetry = []
    for _ in range(20):
        look = _unit(rng.normal(size=3) - [0.0, 0.0, 1.5])
        normals = _retro_chain(rng, look, 3)
        for coeffs in ([PEC] * 3, [_fresnel(ETA), _fresnel(ETA_WALL), _fresnel(2.5 - 0.1j)]):
            S = scattering_matrix(normals, look, coeffs)
            S_rev = scattering_matrix(normals[::-1], look, coeffs[::-1])
            np.testing.assert_allclose(S_rev, S.T, atol=ATOL)
            np.testing.assert_allclose(S + S_rev, (S + S_rev).T, atol=ATOL)
            asymmetry.append(abs(S[0, 1] - S[1, 0]))
        S = scattering_matrix(normals, look, [PEC] * 3)
        np.testing.assert_allclose(S @ S.T, np.eye(2), atol=ATOL)
        assert np.linalg.det(S).real == pytest.approx(1.0, abs=ATOL)
    assert max(asymmetry) > 0.1


# ----------------------------------------------------------------------------------------------
# Batches and errors
# ----------------------------------------------------------------------------------------------

def test_batched_chains_equal_one_at_a_time():
    rng = np.random.default_rng(41)
    looks = _unit(rng.normal(size=(6, 3)) - [0.0, 0.0, 1.5])
    normals = np.array([_retro_chain(rng, look, 3) for look in looks])
    coeffs = [_fresnel(ETA), PEC, _fresnel(ETA_WALL)]
    S = scattering_matrix(normals, looks, coeffs)
    assert S.shape == (6, 2, 2) and S.dtype == np.complex128
    for i in range(6):
        np.testing.assert_allclose(S[i], scattering_matrix(normals[i], looks[i], coeffs), atol=ATOL)


def test_bad_chains_are_refused():
    look = _look(40.0)
    with pytest.raises(ValueError, match="does not return"):
        scattering_matrix([Z], look, [PEC])
    with pytest.raises(ValueError, match="entries"):
        scattering_matrix([-look], look, [PEC, PEC])
    with pytest.raises(ValueError, match="k >= 1"):
        scattering_matrix(np.zeros((0, 3)), look, [])
    with pytest.raises(ValueError, match="nadir"):
        scattering_matrix([Z], [0.0, 0.0, -1.0], [PEC])
    with pytest.raises(ValueError, match=r"\[\.\.\., 3, 2\]"):
        reflect_jones(np.zeros((3, 3)), look, Z, *PEC)
    with pytest.raises(ValueError, match="non-zero"):
        facet_basis(look, [0.0, 0.0, 0.0])
