"""Tests of sarmitsuba.scene.materials: ITU-R P.2040 permittivities, Fresnel and slab
reflection coefficients, and the lookup table used by the tracer.

Oracles: closed forms (normal incidence, Brewster angle, grazing, PEC), an
independent 2x2 characteristic-matrix computation of the slab, Sionna RT's
ITU table (read from its source file without importing sionna) and per-bounce
magnitudes measured with Sionna RT 2.2 at 9.6 GHz.
"""

import ast
import importlib.util
import math
import pathlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.scene.materials import (ITU_MATERIALS, Material, MaterialError, fresnel_half_space,
                                        interpolate_table, itu_material_names, itu_permittivity, itu_valid_ranges,
                                        reflection_coefficient, reflection_table, slab_reflection,
                                        table_error_bound)

F_X = 9.6e9  # X-band frequency of the Sionna reference runs [Hz]


def _eta(eps_r, loss):
    """eta from eps_r and loss = sigma / (omega eps_0)."""
    return complex(eps_r, -loss)


# --------------------------------------------------------------------------
# Independent oracle: 2x2 characteristic matrix of a layer (Born & Wolf
# section 1.6.2; Macleod, Thin-Film Optical Filters, ch. 2), written from the
# boundary conditions, not from the Fresnel/P.2040 formulas.
# --------------------------------------------------------------------------

def transfer_matrix_slab(cos_theta, eta, thickness, frequency_hz):
    """(r_te, r_tm) of a slab in vacuum, mirror-image sign convention.

    Field F and its normalised normal derivative G = p * (forward - backward)
    are continuous; across the layer [F0, G0] = M [Fd, Gd] with
    M = [[cos d, j sin d / p1], [j p1 sin d, cos d]], d = k0 t s. TE uses
    F = E_y, p = k_z / k0. TM uses F = H_y, p = k_z / (k0 eta); its E-field
    coefficient in the mirror convention is -r_H (E_r = -Z0 H_r M(e_i)).
    """
    c = float(cos_theta)
    s = np.sqrt(complex(eta - (1 - c * c)))
    if s.imag > 0:
        s = -s  # decaying branch for exp(+j omega t)
    delta = 2 * math.pi * frequency_hz / SPEED_OF_LIGHT * thickness * s
    out = []
    for p0, p1 in ((c, s), (c, s / eta)):
        m = np.array([[np.cos(delta), 1j * np.sin(delta) / p1],
                      [1j * p1 * np.sin(delta), np.cos(delta)]])
        b, cc = m @ np.array([1.0, p0])  # substrate = vacuum, t = 1
        out.append((p0 * b - cc) / (p0 * b + cc))
    return out[0], -out[1]


def half_space_normal(eta):
    """Closed form at normal incidence: (1 - sqrt(eta)) / (1 + sqrt(eta))."""
    n = np.sqrt(complex(eta))
    return (1 - n) / (1 + n)


# --------------------------------------------------------------------------
# ITU-R P.2040 materials
# --------------------------------------------------------------------------

def _sionna_itu_table():
    """Sionna RT's ITU_MATERIALS_PROPERTIES, parsed without importing sionna
    (importing it would re-register Mitsuba plugins in this process)."""
    spec = importlib.util.find_spec("sionna")
    assert spec is not None and spec.origin is not None, \
        "sionna-rt (the 'sionna' extra, installed by make test) is needed to compare the ITU tables"
    path = pathlib.Path(spec.origin).parent / "rt" / "radio_materials" / "itu.py"
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and any(
                getattr(t, "id", None) == "ITU_MATERIALS_PROPERTIES" for t in node.targets):
            return ast.literal_eval(node.value)
    pytest.fail(f"ITU_MATERIALS_PROPERTIES not found in {path}")


class TestItu:
    def test_names_and_parameters_match_sionna(self):
        ref = _sionna_itu_table()
        assert set(itu_material_names()) == set(ref)
        for name, rows in ref.items():
            ours = [((r[0], r[1]), r[2:]) for r in ITU_MATERIALS[name]]
            assert ours == list(rows.items()), name

    # Worked examples of ITU-R P.2040-1 eqs. (9a), (9b) and (12), evaluated by hand from Table 3:
    # eta' = a f^b, sigma = c f^d [S/m] (f in GHz), eta'' = 17.975 sigma / f (P.2040 eq. 9b with
    # 1 / (2 pi eps_0 1 GHz) = 17.975); eta = eta' - j eta''.
    @pytest.mark.parametrize("name, f_ghz, eta_real, eta_imag", [
        # concrete 9.6 GHz: 5.24; sigma = 0.0462 * 9.6^0.7822 = 0.0462 * 5.8659 = 0.27100
        ("concrete", 9.6, 5.24, 17.975 * 0.27100 / 9.6),                  # 0.50743
        # wet ground 5 GHz: 30 * 5^-0.4 = 30 * 0.52531 = 15.759; sigma = 0.15 * 5^1.3 = 0.15 * 8.1033 = 1.2155
        ("wet_ground", 5.0, 15.759, 17.975 * 1.2155 / 5.0),                # 4.3697
        # medium dry ground 2 GHz: 15 * 2^-0.1 = 15 * 0.93303 = 13.995; sigma = 0.035 * 2^1.63 = 0.035 * 3.0951 = 0.10833
        ("medium_dry_ground", 2.0, 13.995, 17.975 * 0.10833 / 2.0),        # 0.97362
        # brick 28 GHz: 3.91; sigma = 0.0238 * 28^0.16 = 0.0238 * 1.7043 = 0.040562
        ("brick", 28.0, 3.91, 17.975 * 0.040562 / 28.0),                   # 0.026040
        # plywood 10 GHz: d = 0, sigma = 0.33 at every frequency
        ("plywood", 10.0, 2.71, 17.975 * 0.33 / 10.0),                     # 0.59318
        # plasterboard 150 GHz lies in two rows (110-330 and 100-400): the first one applies,
        # 2.56; sigma = 0.0001 * 150^1.7799 = 0.0001 * 7468.4 = 0.74684
        ("plasterboard", 150.0, 2.56, 17.975 * 0.74684 / 150.0),           # 0.089496
        # plasterboard 105 GHz: only the 100-400 row, 2.65; sigma = 0.0002 * 105^1.598 = 0.0002 * 1697.7 = 0.33954
        ("plasterboard", 105.0, 2.65, 17.975 * 0.33954 / 105.0),           # 0.058126
        # metal 10 GHz: 1; sigma = 1e7 S/m
        ("metal", 10.0, 1.0, 17.975 * 1e7 / 10.0),                          # 1.7975e7
    ])
    def test_worked_examples_of_the_itu_formula(self, name, f_ghz, eta_real, eta_imag):
        """Against hand-evaluated values (4-5 digits). Catches: f in Hz instead of GHz in the power
        laws (wet ground: 30 * (5e9)^-0.4 = 4e-3), the exponents b and d swapped (wet ground eta'
        = 30 * 5^1.3 = 243), omega replaced by f (eta'' 2 pi too large), a positive imaginary part,
        the last matching row used instead of the first (plasterboard 150 GHz: 2.65, not 2.56)."""
        eta = itu_permittivity(name, f_ghz * 1e9)
        assert eta.real == pytest.approx(eta_real, rel=1e-4)
        assert eta.imag == pytest.approx(-eta_imag, rel=2e-4)

    def test_concrete_value(self):
        eta = itu_permittivity("concrete", F_X)
        sigma = 0.0462 * 9.6 ** 0.7822
        assert eta.real == pytest.approx(5.24)
        assert eta.imag == pytest.approx(-sigma / (2 * math.pi * F_X * 8.8541878128e-12))

    def test_range_bounds_inclusive(self):
        assert itu_permittivity("wet_ground", 1e9).real == pytest.approx(30.0)
        assert itu_permittivity("wet_ground", 10e9).real == pytest.approx(30.0 * 10 ** -0.4)
        assert itu_valid_ranges("wet_ground") == ((1.0, 10.0),)

    def test_unknown_name_lists_valid_names(self):
        with pytest.raises(MaterialError) as exc:
            itu_permittivity("steel", F_X)
        msg = str(exc.value)
        assert "'steel'" in msg
        for name in ("concrete", "brick", "metal", "wet_ground", "vacuum"):
            assert name in msg

    @pytest.mark.parametrize("name, f, text", [
        ("wet_ground", 20e9, "1-10 GHz"),
        ("brick", 60e9, "1-40 GHz, 110-330 GHz"),
        ("metal", 0.5e9, "1-100 GHz"),
    ])
    def test_out_of_range_names_range(self, name, f, text):
        with pytest.raises(MaterialError, match=text):
            itu_permittivity(name, f)

    @pytest.mark.parametrize("f", [0.0, -1e9, float("nan"), float("inf"), "abc"])
    def test_bad_frequency(self, f):
        with pytest.raises(MaterialError, match="frequency_hz"):
            itu_permittivity("concrete", f)

    def test_material_itu_constructor(self):
        m = Material.itu("brick", F_X)
        assert m.model == "slab" and m.thickness == 0.1
        assert m.relative_permittivity == itu_permittivity("brick", F_X)
        h = Material.itu("brick", F_X, model="half_space")
        assert h.thickness is None


# --------------------------------------------------------------------------
# Half-space Fresnel coefficients: closed forms
# --------------------------------------------------------------------------

class TestHalfSpace:
    @pytest.mark.parametrize("eta", [4.0, 3.91 - 0.064j, 5.24 - 0.51j, 80 - 300j,
                                     1 - 1.87e7j, 1.0 + 0j, 1.0001])
    def test_normal_incidence(self, eta):
        r_te, r_tm = fresnel_half_space(1.0, eta)
        expected = half_space_normal(eta)
        # mirror-image convention: both polarisations equal at normal incidence
        assert r_te == pytest.approx(expected, abs=1e-14)
        assert r_tm == pytest.approx(expected, abs=1e-14)
        assert abs(r_te) == pytest.approx(abs((1 - np.sqrt(eta)) / (1 + np.sqrt(eta))))

    @pytest.mark.parametrize("eps", [1.5, 3.91, 5.24, 30.0, 81.0])
    def test_brewster_angle(self, eps):
        cos_b = 1 / math.sqrt(1 + eps)  # tan(theta_B) = sqrt(eps)
        r_te, r_tm = fresnel_half_space(cos_b, eps)
        assert abs(r_tm) < 1e-14
        assert abs(r_te) > 0.05
        # r_tm changes sign across the Brewster angle (real for lossless media)
        _, r_lo = fresnel_half_space(cos_b * 0.9, eps)
        _, r_hi = fresnel_half_space(cos_b * 1.1, eps)
        assert r_lo.real * r_hi.real < 0

    @pytest.mark.parametrize("eta", [3.91 - 0.064j, 5.24 - 0.51j, 1.5, 80 - 300j])
    def test_grazing(self, eta):
        r_te, r_tm = fresnel_half_space(0.0, eta)
        assert r_te == pytest.approx(-1.0, abs=1e-15)
        assert r_tm == pytest.approx(1.0, abs=1e-15)
        r_te, r_tm = fresnel_half_space(1e-7, eta)
        assert abs(r_te) > 0.9999 and abs(r_tm) > 0.999

    def test_pec_limit_matches_pec_model(self):
        # a very good conductor tends to the PEC model: r = -1, both polarisations
        cos = np.linspace(0.05, 1.0, 20)
        r_te, r_tm = fresnel_half_space(cos, 1 - 1e14j)
        np.testing.assert_allclose(r_te, -1.0, atol=1e-5)
        np.testing.assert_allclose(r_tm, -1.0, atol=1e-5)
        pec = Material.pec()
        for pol in ("HH", "VV"):
            r = reflection_coefficient(pec, cos, F_X, pol)
            assert r.dtype == np.complex128 and r.shape == cos.shape
            np.testing.assert_array_equal(r, -1.0)
            np.testing.assert_array_equal(np.abs(r), 1.0)

    def test_vacuum_has_no_reflection(self):
        cos = np.linspace(0.0, 1.0, 11)
        for r in fresnel_half_space(cos, 1.0):
            np.testing.assert_array_equal(r, 0.0)

    def test_broadcasting_and_dtype(self):
        cos = np.linspace(0, 1, 5)[:, None]
        eta = np.array([2.0, 3 - 1j, 10 - 0.1j])
        r_te, r_tm = fresnel_half_space(cos, eta)
        assert r_te.shape == r_tm.shape == (5, 3)
        assert r_te.dtype == r_tm.dtype == np.complex128


# --------------------------------------------------------------------------
# Slab: against the transfer-matrix oracle and in its limits
# --------------------------------------------------------------------------

class TestSlab:
    @pytest.mark.parametrize("eta, d, f", [
        (3.91 - 0.064j, 0.1, F_X),
        (5.24 - 0.507j, 0.1, F_X),
        (2.73 - 0.1j, 0.0125, 5e9),
        (6.31 - 0.02j, 0.006, 28e9),
        (4.0, 0.05, 3e9),             # lossless
        (1.2 - 0.001j, 0.3, 1e9),
        (30 - 20j, 0.02, 2e9),
    ])
    def test_against_transfer_matrix(self, eta, d, f):
        cos = np.linspace(0.0, 1.0, 41)
        r_te, r_tm = slab_reflection(cos, eta, d, f)
        for i, c in enumerate(cos):
            o_te, o_tm = transfer_matrix_slab(c, eta, d, f)
            assert r_te[i] == pytest.approx(o_te, abs=1e-10)
            assert r_tm[i] == pytest.approx(o_tm, abs=1e-10)

    def test_against_transfer_matrix_random(self):
        rng = np.random.default_rng(2040)
        for _ in range(200):
            eta = complex(rng.uniform(1, 20), -rng.uniform(0, 5))
            d = rng.uniform(1e-3, 0.3)
            f = rng.uniform(1e9, 40e9)
            c = rng.uniform(0, 1)
            s = np.sqrt(eta - (1 - c * c))
            if abs(2 * math.pi * f / SPEED_OF_LIGHT * d * s.imag) > 200:
                continue  # cos/sin of the oracle would overflow
            r = slab_reflection(c, eta, d, f)
            o = transfer_matrix_slab(c, eta, d, f)
            assert r[0] == pytest.approx(o[0], abs=1e-9)
            assert r[1] == pytest.approx(o[1], abs=1e-9)

    def test_thick_lossy_slab_tends_to_half_space(self):
        cos = np.linspace(0.0, 1.0, 33)
        eta = itu_permittivity("concrete", F_X)
        slab = slab_reflection(cos, eta, 10.0, F_X)
        half = fresnel_half_space(cos, eta)
        for a, b in zip(slab, half):
            np.testing.assert_allclose(a, b, atol=1e-12)

    @pytest.mark.parametrize("eta", [1 + 1e-7 - 1e-8j, 1.0 + 0j, 1 - 1e-9j])
    def test_transparent_slab_does_not_reflect(self, eta):
        cos = np.linspace(0.0, 1.0, 33)
        for r in slab_reflection(cos, eta, 0.1, F_X):
            assert np.all(np.isfinite(r)) and np.all(np.abs(r) <= 1)
            # near grazing |r| ~ |eta - 1| / cos^2 still grows (r(0) = -1/+1)
            assert np.max(np.abs(r[cos >= 0.25])) < 1e-5

    def test_half_wave_slab_is_transparent_at_normal_incidence(self):
        eps = 4.0
        lam = SPEED_OF_LIGHT / F_X
        d = lam / (2 * math.sqrt(eps))  # Fabry-Perot: 2q = 2 pi
        r_te, r_tm = slab_reflection(1.0, eps, d, F_X)
        assert abs(r_te) < 1e-12 and abs(r_tm) < 1e-12

    def test_quarter_wave_slab_closed_form(self):
        eps = 4.0
        lam = SPEED_OF_LIGHT / F_X
        d = lam / (4 * math.sqrt(eps))
        r_te, _ = slab_reflection(1.0, eps, d, F_X)
        # quarter-wave layer in vacuum: r = (1 - eps) / (1 + eps)
        assert r_te == pytest.approx((1 - eps) / (1 + eps), abs=1e-12)

    def test_huge_loss_is_finite(self):
        cos = np.array([0.0, 1e-9, 0.3, 1.0])
        for d in (1e-6, 0.1, 100.0):
            for r in slab_reflection(cos, 1 - 1e12j, d, 100e9):
                assert np.all(np.isfinite(r)) and np.all(np.abs(r) <= 1 + 1e-12)


# --------------------------------------------------------------------------
# Sionna RT reference magnitudes (9.6 GHz, normal incidence)
# --------------------------------------------------------------------------

@pytest.mark.parametrize("name, model, expected", [
    ("brick", "slab", 0.4289),
    ("concrete", "slab", 0.3954),
    ("brick", "half_space", 0.3283),
    ("metal", "slab", 0.9997),
])
@pytest.mark.parametrize("pol", ["HH", "VV"])
def test_sionna_per_bounce_magnitudes(name, model, expected, pol):
    """|r| per bounce from a Sionna RT 2.2 run (floor_wall scene, TX = RX at
    (1, 0.3, 1.5), wall x = 0 and floor z = 0 both at normal incidence,
    slab thickness 0.1 m)."""
    m = Material.itu(name, F_X, model=model)
    r = reflection_coefficient(m, 1.0, F_X, pol)
    assert abs(r) == pytest.approx(expected, abs=1e-3)


# --------------------------------------------------------------------------
# |r| <= 1 and finiteness everywhere
# --------------------------------------------------------------------------

@settings(max_examples=400, deadline=None, database=None)
@given(eps_r=st.floats(1.0, 100.0),
       loss=st.one_of(st.floats(0.0, 1e4), st.sampled_from([0.0, 1e-12, 1e4])),
       cos=st.one_of(st.floats(0.0, 1.0),
                     st.sampled_from([0.0, 5e-324, 1e-300, 1e-160, 1e-9, 1.0])),
       thickness=st.floats(1e-9, 10.0),
       f_ghz=st.floats(0.1, 100.0))
def test_passive_bound_property(eps_r, loss, cos, thickness, f_ghz):
    eta = _eta(eps_r, loss)
    f = f_ghz * 1e9
    for model, d in (("half_space", None), ("slab", thickness)):
        m = Material("x", eta, model, d)
        for pol in ("HH", "VV"):
            r = reflection_coefficient(m, cos, f, pol)
            assert np.isfinite(r), (model, pol)
            assert abs(r) <= 1 + 1e-12, (model, pol, abs(r))


@pytest.mark.parametrize("eta", [1.0, 1 + 1e-12, 1 - 1e-12j, 1 + 1e-6 - 1e-9j,
                                 2 - 1e10j, 1 - 1e15j, 100.0])
@pytest.mark.parametrize("model", ["half_space", "slab"])
def test_edge_cases_finite_and_bounded(eta, model):
    cos = np.concatenate([[0.0, 5e-324, 1e-300, 1e-151, 1e-149, 1e-12, 1e-6],
                          np.linspace(0, 1, 101)])
    m = Material("edge", eta, model, 0.1 if model == "slab" else None)
    for pol in ("HH", "VV"):
        r = reflection_coefficient(m, cos, F_X, pol)
        assert np.all(np.isfinite(r))
        assert np.all(np.abs(r) <= 1 + 1e-12)


# --------------------------------------------------------------------------
# Lookup table
# --------------------------------------------------------------------------

class TestTable:
    def test_shape_dtype_nodes(self):
        m = Material.itu("brick", F_X)
        t = reflection_table(m, F_X, "VV")
        assert t.shape == (257,) and t.dtype == np.complex64
        cos = np.linspace(0, 1, 257)
        exact = reflection_coefficient(m, cos, F_X, "VV")
        np.testing.assert_allclose(t, exact, atol=1e-7)
        np.testing.assert_allclose(interpolate_table(t, cos), t, atol=0)
        assert t[-1] == pytest.approx(reflection_coefficient(m, 1.0, F_X, "HH"), abs=1e-7)

    @pytest.mark.parametrize("name", ["brick", "concrete", "wet_ground", "glass"])
    @pytest.mark.parametrize("pol", ["HH", "VV"])
    def test_error_small_for_building_materials(self, name, pol):
        m = Material.itu(name, F_X)
        assert table_error_bound(m, F_X, pol) < 1e-3

    def test_error_converges_quadratically(self):
        m = Material.itu("brick", F_X, thickness=0.3)
        e1 = table_error_bound(m, F_X, "HH", n=65)
        e2 = table_error_bound(m, F_X, "HH", n=129)
        assert 3.0 < e1 / e2 < 5.0

    def test_good_conductor_tm_error_is_confined_to_grazing(self):
        m = Material.itu("metal", F_X)
        assert table_error_bound(m, F_X, "VV") > 0.5          # pseudo-Brewster swing
        assert table_error_bound(m, F_X, "VV", cos_min=4 / 256) < 1e-3
        assert table_error_bound(m, F_X, "HH") < 1e-6

    def test_pec_table(self):
        t = reflection_table(Material.pec(), F_X, "HH", n=5)
        np.testing.assert_array_equal(t, np.full(5, -1, np.complex64))

    @pytest.mark.parametrize("n", [1, 0, 2.5, True])
    def test_bad_n(self, n):
        with pytest.raises(MaterialError, match="n must be an integer >= 2"):
            reflection_table(Material.pec(), F_X, "HH", n=n)


# --------------------------------------------------------------------------
# Argument validation
# --------------------------------------------------------------------------

class TestValidation:
    @pytest.mark.parametrize("cos", [-0.1, 1.0000001, float("nan"), [0.5, 2.0]])
    def test_cos_out_of_range(self, cos):
        with pytest.raises(MaterialError, match=r"cos_theta must lie in \[0, 1\]"):
            fresnel_half_space(cos, 2.0)

    @pytest.mark.parametrize("eta", [2 + 0.1j, 0.0, float("nan"), complex("inf"), None])
    def test_bad_eta(self, eta):
        with pytest.raises(MaterialError, match="eta"):
            fresnel_half_space(0.5, eta)

    @pytest.mark.parametrize("d", [0.0, -0.1, float("inf"), None])
    def test_bad_thickness(self, d):
        with pytest.raises(MaterialError, match="thickness"):
            slab_reflection(0.5, 2.0, d, F_X)

    @pytest.mark.parametrize("f", [0.0, -1.0, float("nan")])
    def test_bad_frequency(self, f):
        with pytest.raises(MaterialError, match="frequency_hz"):
            slab_reflection(0.5, 2.0, 0.1, f)
        with pytest.raises(MaterialError, match="frequency_hz"):
            reflection_coefficient(Material.pec(), 0.5, f, "HH")

    @pytest.mark.parametrize("pol", ["HV", "VH", "x", None])
    def test_bad_polarization(self, pol):
        with pytest.raises(MaterialError, match="polarization"):
            reflection_coefficient(Material.pec(), 0.5, F_X, pol)

    def test_polarization_aliases(self):
        m = Material.itu("brick", F_X)
        assert reflection_coefficient(m, 0.3, F_X, "hh") == reflection_coefficient(m, 0.3, F_X, "TE")
        assert reflection_coefficient(m, 0.3, F_X, "vv") == reflection_coefficient(m, 0.3, F_X, "TM")
        assert reflection_coefficient(m, 0.3, F_X, "HH") != reflection_coefficient(m, 0.3, F_X, "VV")

    @pytest.mark.parametrize("kwargs, text", [
        (dict(name="a", relative_permittivity=2.0, model="mirror"), "model must be one of"),
        (dict(name="a", relative_permittivity=None, model="slab", thickness=0.1),
         "needs a complex relative_permittivity"),
        (dict(name="a", relative_permittivity=2.0, model="slab"), "thickness"),
        (dict(name="a", relative_permittivity=2.0, model="half_space", thickness=0.1),
         "only used by model='slab'"),
        (dict(name="a", relative_permittivity=2.0, model="pec"), "'pec' material takes"),
        (dict(name="a", relative_permittivity=2 + 1j, model="half_space"), "passive"),
    ])
    def test_inconsistent_material(self, kwargs, text):
        with pytest.raises(MaterialError, match=text):
            Material(**kwargs)

    def test_material_is_frozen_and_coerced(self):
        m = Material("a", 4, "slab", 1)
        assert isinstance(m.relative_permittivity, complex) and isinstance(m.thickness, float)
        with pytest.raises(AttributeError):
            m.thickness = 0.2

    def test_not_a_material(self):
        with pytest.raises(MaterialError, match="Material"):
            reflection_coefficient("concrete", 0.5, F_X, "HH")
