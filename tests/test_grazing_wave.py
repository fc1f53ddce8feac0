"""The grazing wave on a real surface, docs/physics.md (E2), (E6'): the surface impedance a grazing
wave sees, Norton's attenuation function, the kernel's table of it, and what a lone plate of ITU
metal or concrete returns.

Deliberate bugs these were run against, each failing a test here: the grazing wave's weight read
from ``r_TM`` at exactly grazing (1 on pec, 0 on any other material: three plate cases fail); the
unlit face's TM coefficient read at exactly grazing (metal 2.3 dB low at 45 deg VV); ``exp(-w)
erfc(j sqrt w)`` taken as ``wofz(+sqrt w)``; the numerical distance without its ``-j``; the kernel
table's offset without the factor 1/2; the unlit face's ``1 - 2 F`` taken as ``1 + 2 F`` (the
wide concrete plate, against the NumPy references' sheet).
"""
from __future__ import annotations

import cmath
import math

import numpy as np
import pytest

import sarmitsuba
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene import materials
from sarmitsuba.tracing.integration import ground_wave

from test_patches import WAVELENGTH, rectangle, sensor

FREQUENCY = 9.6e9


@pytest.mark.parametrize("name", ["concrete", "metal", "marble", "glass"])
@pytest.mark.parametrize("frequency", [3.0e9, 9.6e9])
def test_grazing_impedance_reproduces_fresnel_near_grazing(name, frequency):
    """The impedance boundary ``r = (Delta - c) / (Delta + c)`` with the material's ``Delta``
    against the half space's Fresnel ``r_TM`` (:func:`materials.reflection_coefficient`) near
    grazing: equal to ``O(c^2)`` (within ``c / |Delta|`` relative, at ``c`` 1e-4 and 1e-3 of
    ``|Delta|``), and an impedance missing its ``1 / eta`` is off."""
    eta = materials.itu_permittivity(name, frequency)
    half_space = materials.Material(name, eta, "half_space")
    delta = materials.grazing_impedance(half_space, frequency)
    for share in (1e-4, 1e-3):
        c = share * abs(delta)
        fresnel = complex(materials.reflection_coefficient(half_space, np.array([c]), frequency, "VV")[0])
        assert abs((delta - c) / (delta + c) - fresnel) < 4 * share ** 2 + 1e-12, (name, share)
    normal = cmath.sqrt(eta - 1)
    c = 1e-3 * abs(delta)
    fresnel = complex(materials.reflection_coefficient(half_space, np.array([c]), frequency, "VV")[0])
    assert abs((normal - c) / (normal + c) - fresnel) > 1e-4


def test_grazing_impedance_of_pec_and_of_a_slab():
    """``pec``: 0. A slab: its material's half space (Sionna's metal and concrete of 0.1 m)."""
    assert materials.grazing_impedance(materials.Material.pec(), FREQUENCY) == 0
    for name in ("metal", "concrete"):
        slab, half = (materials.grazing_impedance(materials.Material.itu(name, FREQUENCY, model), FREQUENCY)
                      for model in ("slab", "half_space"))
        assert slab == half


@pytest.mark.parametrize("p", [0.01, 0.1, 0.3, 1.0, 2.0, 5.0, 10.0, 30.0, 100.0])
def test_norton_attenuation_follows_nortons_curve(p):
    """For a ground where conduction dominates the numerical distance is real and ``|F|`` is
    Norton's ground-wave curve, well fitted by ``(2 + 0.3 p) / (2 + p + 0.6 p^2)`` (Norton, Proc.
    IRE 29(12), 1941; within 13 % from 0.01 to 100)."""
    fit = (2 + 0.3 * p) / (2 + p + 0.6 * p * p)
    assert abs(ground_wave.norton_attenuation(p)) == pytest.approx(fit, rel=0.13)


@pytest.mark.parametrize("angle", [0.0, -0.25 * math.pi, -0.5 * math.pi, -0.75 * math.pi, -0.95 * math.pi])
def test_norton_attenuation_tends_to_its_asymptotes(angle):
    """``F -> -1 / (2 p) - 3 / (4 p^2)`` for ``|p| -> oo`` and ``1 - j sqrt(pi p)`` for ``p -> 0``,
    across the half plane a passive half space puts ``p`` in (``-pi <= arg p <= 0``)."""
    w = 1e3 * cmath.exp(1j * angle)
    far = complex(ground_wave.norton_attenuation(w))
    assert abs(far - (-1 / (2 * w) - 3 / (4 * w * w))) < 1e-3 * abs(1 / (2 * w))
    w = 1e-6 * cmath.exp(1j * angle)
    near = complex(ground_wave.norton_attenuation(w))
    assert abs(abs(near - 1) - math.sqrt(math.pi * 1e-6)) < 1e-5


def test_kernel_table_matches_the_reference():
    """The Dr.Jit lookup (per material row, linear in log10 |p|) against the NumPy reference over
    eight decades of path length, for a conductor, a lossy and a lossless dielectric, two lossy
    media of low permittivity (``arg p`` near ``-pi``) and pec."""
    import drjit as dr
    import mitsuba as mi
    etas = [materials.itu_permittivity(name, FREQUENCY) for name in ("metal", "concrete")] + [6.0, 1.5 - 2.0j, 1.05 - 0.5j]
    deltas = np.array([cmath.sqrt(eta - 1) / eta for eta in etas] + [0.0])
    offset, table = ground_wave.grazing_table(deltas)
    rng = np.random.default_rng(3)
    rows = rng.integers(0, len(deltas), 4000)
    kd = 10 ** rng.uniform(-1, 7, rows.size)
    got = ground_wave.lookup(mi.Float(offset), mi.Float(table.real.ravel()), mi.Float(table.imag.ravel()),
                             mi.UInt32(rows.astype(np.uint32)), mi.Float(kd))
    got = np.array(dr.real(got)) + 1j * np.array(dr.imag(got))
    expected = ground_wave.grazing_weight(deltas[rows], kd)
    assert np.max(np.abs(got - expected)) < 2e-3


def _plate_sim(material, half: float, incidence: float, polarization: str):
    plate = rectangle((0, 0, 0), (half, 0, 0), (0, half, 0))
    return simulate(sarmitsuba.Scene([(plate, material, "plate")],
                                     sensor=sensor(0.0, incidence_angle=incidence, polarization=polarization),
                                     integrator={"max_depth": 1}))


def _plate_rcs(material, half: float, incidence: float, polarization: str) -> float:
    sim = _plate_sim(material, half, incidence, polarization)
    return sarmitsuba.analyze(sim.image, (0, 0, 0), raw=sim.raw).rcs_db


@pytest.mark.parametrize("incidence", [20.0, 45.0, 60.0])
@pytest.mark.parametrize("polarization", ["HH", "VV"])
def test_itu_metal_plate_is_a_pec_plate(incidence, polarization):
    """The issue's acceptance: on the full-wave tables' 4-wavelength square plate, ITU ``metal``
    (Sionna's slab of 0.1 m) within 0.2 dB of ``pec`` at every angle, HH and VV. With ``r_TM``
    read at exactly grazing it was 3.6 dB low in VV at 45 and 60 deg."""
    half = 2 * WAVELENGTH
    metal = _plate_rcs({"plugin": "itu-radio-material", "type": "metal"}, half, incidence, polarization)
    pec = _plate_rcs("pec", half, incidence, polarization)
    assert metal == pytest.approx(pec, abs=0.2)


def _sheet_vv(half: float, k: float, toward: np.ndarray, eta: complex, grazing: bool) -> complex:
    """VV ``S`` of a lone dielectric square ``+-half`` in z = 0 by the NumPy references (as
    :func:`edges.plate_scattering` sums a PEC sheet): PO times ``-r_TM``, every rim's fringe with
    face 0 at its Fresnel pair and the unlit back at ``r_TE = -1``, ``r_TM = 1 - 2 F`` (Norton's
    ``F`` over the width along the Keller cone), and the double diffraction across the sheet with
    ``F``; ``grazing`` False: the exact-grazing rule (``r_TM = +1``, no double diffraction)."""
    from sarmitsuba.tracing.integration import edges
    from sarmitsuba.tracing.integration.physical_optics import polygon_integral
    corners = np.array([[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]])
    normal, d, points = np.array([0.0, 0.0, 1.0]), -toward, 400
    h = np.cross([0.0, 0.0, 1.0], d)
    v = np.cross(d, h / np.linalg.norm(h))
    r_te, r_tm = (complex(x[0]) for x in materials.fresnel_half_space(np.array([toward[2]]), eta))
    delta = cmath.sqrt(eta - 1) / eta
    out = -1j * k / (2 * np.pi) * toward[2] * polygon_integral(corners, normal, 2 * k * toward) * (-r_tm) * v
    g = (np.arange(points) + 0.5) / points
    tile = lambda x: np.tile(x, (points, 1))                     # noqa: E731
    for i in range(4):
        a, c = corners[i], corners[(i + 1) % 4]
        t = (c - a) / np.linalg.norm(c - a)
        x0, p = np.cross(normal, t), a + g[:, None] * (c - a)
        width, sin_i = 2 * half, np.linalg.norm(d - (d @ t) * t)
        f = complex(ground_wave.grazing_weight(delta, k * width / sin_i)) if grazing else 0.0
        args = (tile(t), tile(x0), tile(normal), tile(np.zeros(3)))
        single = edges.edge_field(*args, tile(d), tile(toward), tile(v.astype(complex)), r0=(r_te, r_tm), rn=(-1.0, 1 - 2 * f))
        out = out + np.linalg.norm(c - a) / points * np.exp(2j * k * p @ toward) @ single
        if grazing:
            double = edges.double_field(args[0], args[1], args[2], tile(width * x0), args[3], args[3], tile(d),
                                        tile(toward), tile(v.astype(complex)), k, delta=delta)
            out = out + np.linalg.norm(c - a) / points * np.exp(1j * k * ((p + width * x0) @ toward + p @ toward
                                                                           - width * sin_i)) @ double
    return complex(v @ out)


def test_wide_dielectric_plate_keeps_its_small_grazing_wave(monkeypatch):
    """A concrete plate 20 wavelengths wide (``|F| = 0.05``) at 45 deg, VV: what its grazing wave
    changes in the image's RCS against the exact-grazing rule (no grazing wave, the unlit face at
    ``r_TM = +1``, forced here by setting ``F = 0``) is what the NumPy references predict for the
    sheet (:func:`_sheet_vv`, weighted over pulses and band as the image weighs them): within 0.03
    dB (measured -0.138 against -0.137), and less than 0.3 dB (the rule's error on a wide face).
    A 4-wavelength ITU metal plate under the same forcing loses more than 2 dB (what the forcing
    does where the grazing wave is real). Catches the unlit face's ``1 - 2 F`` taken as ``1 + 2 F``
    (+0.25 dB) and the double diffraction without ``F`` (the whole PEC grazing wave: -2.6 dB),
    which the former comparison with the forced render alone let through (within its 0.3 dB)."""
    import mitsuba as mi
    from sarmitsuba.core.constants import SPEED_OF_LIGHT
    from test_patches import image_weights

    wide, small = 10 * WAVELENGTH, 2 * WAVELENGTH
    metal_type = {"plugin": "itu-radio-material", "type": "metal"}
    sim = _plate_sim("concrete", wide, 45.0, "VV")
    concrete, metal = sarmitsuba.analyze(sim.image, (0, 0, 0), raw=sim.raw).rcs_db, _plate_rcs(metal_type, small, 45.0, "VV")
    rhat, weight, frequencies, band = image_weights(sim, band_points=9)
    eta = materials.itu_permittivity("concrete", FREQUENCY)
    power = {}
    for grazing in (True, False):
        num = den = 0.0
        for row in np.flatnonzero(weight > 0)[::20]:
            for f, b in zip(frequencies, band):
                s = _sheet_vv(wide, 2 * math.pi * f / SPEED_OF_LIGHT, rhat[row], eta, grazing)
                num, den = num + (weight[row] * b) ** 2 * abs(s) ** 2, den + (weight[row] * b) ** 2
        power[grazing] = num / den
    expected = 10 * math.log10(power[True] / power[False])
    monkeypatch.setattr(ground_wave, "lookup", lambda *args: mi.Complex2f(0.0, 0.0))
    effect = concrete - _plate_rcs("concrete", wide, 45.0, "VV")
    assert effect == pytest.approx(expected, abs=0.03), (effect, expected)
    assert abs(effect) < 0.3
    assert metal - _plate_rcs(metal_type, small, 45.0, "VV") > 2.0


@pytest.mark.parametrize("name", ["concrete", "glass"])
def test_table_tangent_matches_central_differences(name):
    """The grazing table's derivative for material gradients (the offset and every sample)
    against central differences of the table itself over ``Re eta`` and ``Im eta``."""
    eta = materials.itu_permittivity(name, FREQUENCY)

    def delta(e):
        return cmath.sqrt(e - 1) / e

    for d_eta in (1.0, -1j):
        h = 1e-4 * abs(eta)
        d_offset, d_table = ground_wave.table_tangent(delta(eta), (0.5 / (eta - 1) - 1 / eta) * d_eta)
        (o_plus, t_plus), (o_minus, t_minus) = (ground_wave.grazing_table(delta(eta + s * h * d_eta)) for s in (1, -1))
        assert d_offset == pytest.approx((o_plus[0] - o_minus[0]) / (2 * h), rel=2e-2, abs=1e-4)
        fd = (t_plus[0].astype(complex) - t_minus[0].astype(complex)) / (2 * h)
        assert np.max(np.abs(d_table - fd)) < 2e-2 * np.max(np.abs(d_table)) + 1e-3
