"""The Dr.Jit (P3') reflection of sarmitsuba.tracing.integration.jones against the NumPy reference
sarmitsuba.tracing.integration.polarimetry.reflect_jones (docs/physics.md (P2), (P3), (P3')) and image theory.

Inputs are rounded to float32 once and the same values fed to both, so the comparison measures
the kernel's float32 arithmetic only. Errors are relative to ``max(|r_te|, |r_tm|) |E|`` per lane.
Bugs these catch: s/p swapped (r_te applied to the TM part), the complex product written
wrong (a sign of the imaginary cross terms), the mirror M applied to the wrong vector or not at
all, s left un-normalised, and NaN at normal incidence (no fallback). Not caught: dropping the
Gram-Schmidt step (in float32 it changes s by rounding only, below these tolerances).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (first: picks libLLVM and sets the variant before drjit loads)
import drjit as dr  # noqa: I001
import mitsuba as mi
from sarmitsuba.tracing.integration import polarimetry
from sarmitsuba.tracing.integration.jones import reflect_jones

RTOL = 1e-5
N = 1000


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _f32(a):
    """Round to float32 (complex64 for complex), back in float64 / complex128."""
    a = np.asarray(a)
    return a.astype(np.complex64 if np.iscomplexobj(a) else np.float32).astype(a.dtype)


def _vec(a):
    return mi.Array3f(*(mi.Float(np.ascontiguousarray(a[:, i], dtype=np.float32)) for i in range(3)))


def _np(v):
    return np.stack([np.array(v.x), np.array(v.y), np.array(v.z)], axis=-1).astype(np.float64)


def _complex(z):
    return mi.Complex2f(mi.Float(z.real.astype(np.float32)), mi.Float(z.imag.astype(np.float32)))


def _transverse(rng, d):
    """Random complex field vectors normal to ``d``, rounded to float32."""
    g = rng.normal(size=d.shape) + 1j * rng.normal(size=d.shape)
    return _f32(g - np.sum(d * g, axis=-1, keepdims=True) * d)


def _coefficients(rng, n, scale=1.0):
    return _f32(scale * np.sqrt(rng.uniform(0, 1, n)) * np.exp(2j * np.pi * rng.uniform(0, 1, n)))


def _compare(d, n, e, r_te, r_tm):
    """Max relative error of the kernel's E' against the reference, and of d'."""
    d, n, e, r_te, r_tm = _f32(d), _f32(n), _f32(e), _f32(r_te), _f32(r_tm)
    out_re, out_im, out_d = reflect_jones(_vec(e.real), _vec(e.imag), _vec(d), _vec(n),
                                          _complex(r_te), _complex(r_tm))
    got = _np(out_re) + 1j * _np(out_im)
    assert np.all(np.isfinite(got)) and np.all(np.isfinite(_np(out_d)))
    J = np.stack([e, np.zeros_like(e)], axis=-1)
    ref, ref_d = polarimetry.reflect_jones(J, d, n, r_te, r_tm)
    scale = np.maximum(np.abs(r_te), np.abs(r_tm)) * np.linalg.norm(e, axis=-1)
    err = np.linalg.norm(got - ref[..., 0], axis=-1) / scale
    return float(np.max(err)), float(np.max(np.abs(_np(out_d) - ref_d)))


def test_random_geometry_and_coefficients():
    """~1000 random directions, normals (both orientations) and complex coefficients."""
    rng = np.random.default_rng(1)
    d = _unit(rng.normal(size=(N, 3)))
    n = _unit(rng.normal(size=(N, 3)))
    err, err_d = _compare(d, n, _transverse(rng, _f32(d)), _coefficients(rng, N), _coefficients(rng, N))
    assert err < RTOL and err_d < 1e-6


def test_grazing():
    """d . n from 0 to 1e-1 (either side): TE and TM still told apart, d' ~ d."""
    rng = np.random.default_rng(2)
    n = _unit(rng.normal(size=(N, 3)))
    t = _unit(np.cross(n, rng.normal(size=(N, 3))))                  # in the facet plane
    cos = np.concatenate([[0.0], np.logspace(-7, -1, N - 1)]) * rng.choice([-1.0, 1.0], N)
    d = _unit(np.sqrt(1 - cos[:, None] ** 2) * t + cos[:, None] * n)
    err, err_d = _compare(d, n, _transverse(rng, _f32(d)), _coefficients(rng, N), _coefficients(rng, N))
    assert err < RTOL and err_d < 1e-6


@pytest.mark.parametrize("axis_normals", [False, True])
def test_near_normal_incidence_is_continuous(axis_normals):
    """sin(theta) from 0 (d = -n, d = +n) to 1e-2, physical coefficients (r_te - r_tm ~
    sin^2 theta, equal at normal incidence): no NaN, no jump at the normal-incidence fallback;
    normals along the coordinate axes exercise each choice of the least-aligned axis."""
    rng = np.random.default_rng(3)
    if axis_normals:
        n = np.eye(3)[rng.integers(0, 3, N)] * rng.choice([-1.0, 1.0], (N, 1))
    else:
        n = _unit(rng.normal(size=(N, 3)))
    t = _unit(np.cross(n, rng.normal(size=(N, 3))))
    sin = np.concatenate([[0.0, 0.0], np.logspace(-8, -2, N - 2)])
    sign = np.where(np.arange(N) == 1, 1.0, -1.0)[:, None]          # lane 1: d = +n
    d = _unit(sign * np.sqrt(1 - sin[:, None] ** 2) * n + sin[:, None] * t)
    r_te = _coefficients(rng, N)
    r_tm = r_te + _coefficients(rng, N, scale=sin ** 2)
    err, err_d = _compare(d, n, _transverse(rng, _f32(d)), r_te, r_tm)
    assert err < RTOL and err_d < 1e-6


def test_pec_image_theory():
    """PEC (r_te = r_tm = -1): E' = -E + 2 (n . E) n, normal to d', for any geometry."""
    rng = np.random.default_rng(4)
    d = _f32(_unit(rng.normal(size=(N, 3))))
    n = _f32(_unit(rng.normal(size=(N, 3))))
    n[:10] = -d[:10]                                                 # exactly normal incidence
    e = _transverse(rng, d)
    pec = np.full(N, -1.0 + 0.0j)
    out_re, out_im, out_d = reflect_jones(_vec(e.real), _vec(e.imag), _vec(d), _vec(n),
                                          _complex(pec), _complex(pec))
    got = _np(out_re) + 1j * _np(out_im)
    image = -e + 2.0 * np.sum(n * e, axis=-1, keepdims=True) * n
    norm_e = np.linalg.norm(e, axis=-1)
    assert np.max(np.linalg.norm(got - image, axis=-1) / norm_e) < RTOL
    assert np.max(np.abs(np.sum(got * _np(out_d), axis=-1)) / norm_e) < RTOL
    assert np.allclose(_np(out_d), d - 2.0 * np.sum(d * n, axis=-1, keepdims=True) * n, atol=1e-6)


def test_single_lane_and_dtypes():
    """One lane works (no lane loop, no shape assumptions) and float32 results come back."""
    out_re, out_im, out_d = reflect_jones(mi.Array3f(1, 0, 0), mi.Array3f(0, 0, 0), mi.Array3f(0, 0, -1),
                                          mi.Array3f(0, 0, 1), mi.Complex2f(0.5, 0.1), mi.Complex2f(-0.3, 0.2))
    assert dr.width(out_re) == 1 and isinstance(out_re.x, mi.Float)
    # d = -z at normal incidence on a level facet: E' = r_tm M E = r_tm E for horizontal E, + the
    # s-term with r_te - r_tm along the fallback s; compare with the reference.
    ref, _ = polarimetry.reflect_jones(np.array([[1.0], [0.0], [0.0]]) * np.array([1.0, 0.0]),
                                       [0, 0, -1], [0, 0, 1], 0.5 + 0.1j, -0.3 + 0.2j)
    got = _np(out_re)[0] + 1j * _np(out_im)[0]
    assert np.allclose(got, ref[:, 0], atol=1e-6)


# ---- the tube's Jones matrix: launch, scatter, receive ----------------------------------------------
def _jones_of(h, v):
    """A Jones matrix with real columns h, v (float64 [n, 3])."""
    from sarmitsuba.tracing.integration import jones
    zero = _vec(np.zeros_like(h))
    return jones.Jones(h_re=_vec(h), h_im=zero, v_re=_vec(v), v_im=zero)


def test_scatter_in_the_specular_direction_is_the_reflection():
    """(P4') with b = d' equals (P3'): the NumPy reference's reflection of both columns. Fails if
    s_b or p_b is built with the wrong sign (p_b = b x s_b instead of (-b) x s_b gives -p')."""
    from sarmitsuba.tracing.integration import jones
    rng = np.random.default_rng(5)
    d = _f32(_unit(rng.normal(size=(N, 3))))
    n = _f32(_unit(rng.normal(size=(N, 3))))
    h, v = polarimetry.bsa_basis(np.where(np.abs(d[:, 2:3]) > 0.99, [[0.3, 0.2, -0.9]], d))
    h = h - np.sum(h * d, axis=1, keepdims=True) * d
    h = _f32(_unit(h))
    v = _f32(np.cross(d, h))
    r_te, r_tm = _coefficients(rng, N), _coefficients(rng, N)
    d_out = d - 2 * np.sum(d * n, axis=1, keepdims=True) * n
    out = jones.scatter(_jones_of(h, v), _vec(d), _vec(d_out), _vec(n), _complex(r_te), _complex(r_tm))
    ref, _ = polarimetry.reflect_jones(np.stack([h, v], axis=-1).astype(complex), d, n, r_te, r_tm)
    for column, (re, im) in enumerate(((out.h_re, out.h_im), (out.v_re, out.v_im))):
        got = _np(re) + 1j * _np(im)
        assert np.max(np.linalg.norm(got - ref[..., column], axis=-1)) < 1e-5


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_backscatter_from_level_ground_is_diagonal_in_h_and_v(incidence):
    """Ground (n = z) seen at ``incidence`` and scattering straight back (b = -d): S = [[a_te,
    a_x], [a_x, a_tm]] in the antenna's h, v (P7), so HH carries a_te, VV a_tm (the Kirchhoff
    backscatter); fails if TE and TM are swapped or the cross term is not symmetric."""
    from sarmitsuba.tracing.integration import jones
    t = math.radians(incidence)
    d = np.array([[0.0, -math.sin(t), -math.cos(t)]])
    h, v = polarimetry.bsa_basis(d)
    a_te, a_tm, a_x = np.array([0.5 + 0.1j]), np.array([-0.2 + 0.3j]), np.array([0.05 - 0.02j])
    up = np.array([[0.0, 0.0, 1.0]])
    out = jones.scatter(_jones_of(h, v), _vec(d), _vec(-d), _vec(up), _complex(a_te), _complex(a_tm), _complex(a_x))
    s = jones.receive(out, _vec(d), _vec(np.array([[1.0, 0.0, 0.0]])), ("HH", "HV", "VH", "VV"))
    got = [complex(np.array(c.real)[0], np.array(c.imag)[0]) for c in s]
    expected = [a_te[0], a_x[0], a_x[0], a_tm[0]]
    assert np.allclose(got, expected, atol=1e-6), (got, expected)


def test_launch_basis_is_h_horizontal_and_v_up():
    """(P1): h = unit(z x d) horizontal and normal to d, v = d x h with v . z > 0, at 30 and 60
    deg incidence and with the track turned (heading): fails if v points down (the sign
    convention of texts using theta-hat) or h is not horizontal."""
    from sarmitsuba.tracing.integration import jones
    for incidence, heading in ((30.0, 0.0), (60.0, 37.0)):
        t, a = math.radians(incidence), math.radians(heading)
        d = np.array([[math.sin(t) * math.sin(a), -math.sin(t) * math.cos(a), -math.cos(t)]])
        j = jones.launch(_vec(d), _vec(np.array([[math.cos(a), math.sin(a), 0.0]])))
        h, v = _np(j.h_re)[0], _np(j.v_re)[0]
        assert abs(h[2]) < 1e-7 and abs(h @ d[0]) < 1e-6 and abs(np.linalg.norm(h) - 1) < 1e-6
        assert np.allclose(v, np.cross(d[0], h), atol=1e-6) and v[2] == pytest.approx(math.sin(t), abs=1e-6)


@pytest.mark.parametrize("incidence, heading", [(35.0, 20.0), (62.0, -48.0)])
def test_receive_reads_rows_by_receive_and_columns_by_transmit(incidence, heading):
    """(P4) with an asymmetric Jones matrix: transmit H arrives as 2 v, transmit V as 0.5j h, so
    S = [[0, 0.5j], [2, 0]] (rows receive H, V; columns transmit H, V): HV (receive H, transmit V)
    is 0.5j and VH is 2. Truth: the BSA basis built by hand (h = unit(z x look), v = look x h).
    Swapping the bases (S instead of S^T) gives HV = 2; images symmetrised later would hide it."""
    from sarmitsuba.tracing.integration import jones
    t, a = math.radians(incidence), math.radians(heading)
    look = np.array([math.sin(t) * math.sin(a), -math.sin(t) * math.cos(a), -math.cos(t)])
    h = np.cross([0.0, 0.0, 1.0], look)
    h /= np.linalg.norm(h)
    v = np.cross(look, h)
    j = jones.Jones(h_re=_vec(2.0 * v[None]), h_im=_vec(np.zeros((1, 3))),
                    v_re=_vec(np.zeros((1, 3))), v_im=_vec(0.5 * h[None]))
    s = jones.receive(j, _vec(look[None]), _vec(np.array([[math.cos(a), math.sin(a), 0.0]])), ("HH", "HV", "VH", "VV"))
    got = [complex(np.array(c.real)[0], np.array(c.imag)[0]) for c in s]
    assert np.allclose(got, [0.0, 0.5j, 2.0, 0.0], atol=1e-6), got


@pytest.mark.parametrize("incidence", [30.0, 70.0])
def test_power_is_one_at_launch_and_scales_with_the_reflection(incidence):
    """``power`` is the power averaged over the two transmit channels: 1 at launch (each column a
    unit vector), still 1 after a PEC reflection (r_te = r_tm = -1) and 0.36 after one with
    |r_te| = |r_tm| = 0.6 (|r|^2). Without its 1/2 it reads 2 at launch, doubling every order's
    energy."""
    from sarmitsuba.tracing.integration import jones
    t = math.radians(incidence)
    d = np.array([[0.0, -math.sin(t), -math.cos(t)]])
    j = jones.launch(_vec(d), _vec(np.array([[1.0, 0.0, 0.0]])))
    assert np.array(jones.power(j))[0] == pytest.approx(1.0, abs=1e-6)
    n = _vec(np.array([[0.0, 0.0, 1.0]]))
    for r, expected in ((-1.0 + 0j, 1.0), (0.6j, 0.36)):
        coefficient = mi.Complex2f(r.real, r.imag)
        out = jones.reflect(j, _vec(d), n, coefficient, coefficient)
        assert np.array(jones.power(out))[0] == pytest.approx(expected, abs=1e-6)
