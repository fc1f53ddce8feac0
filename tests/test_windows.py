"""Windows and their impulse-response figures against closed forms and the reference table below.

``TABLE_4B`` was computed numerically with a 512-point window and a 256x zero-padded FFT
(window definitions and their standard figures: Harris, Proc. IEEE 66(1), 1978, for Hann,
Hamming and Kaiser; Carrara, Goodman and Majewski 1995, appendix D, for Taylor; Cumming and
Wong 2005, section 2.6, for Kaiser beta = 2.5); here the figures come from the closed-form
compressed pulse of the continuous window, so the tolerances allow for the sampled window:
broadening within 1 %, PSLR within 0.5 dB (ISLR within 0.5 dB as well).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.signal.windows as sw
import scipy.special

from sarmitsuba.focus import windows as w

# name, params, IRW [1/B], k_w, PSLR [dB], ISLR null-bounded over +-20 cells [dB], first null [1/B]
TABLE_4B = [
    ("rect", {}, 0.886, 1.000, -13.26, -9.91, 1.00),
    ("kaiser", {"beta": 2.5}, 1.043, 1.177, -20.98, -18.73, 1.28),
    ("taylor", {"nbar": 4, "sll": -30}, 1.125, 1.270, -30.31, -23.97, 1.51),
    ("taylor", {"nbar": 4, "sll": -35}, 1.184, 1.337, -35.17, -27.91, 1.66),
    ("taylor", {"nbar": 5, "sll": -40}, 1.246, 1.407, -40.13, -32.32, 1.83),
    ("hann", {}, 1.441, 1.626, -31.47, -32.88, 2.00),
    ("hamming", {}, 1.303, 1.471, -42.67, -35.43, 2.00),
    ("kaiser", {"beta": 6}, 1.405, 1.586, -43.82, -43.99, 2.16),
]


@pytest.mark.parametrize("name, params, irw, k_w, pslr, islr20, null", TABLE_4B,
                         ids=[f"{r[0]}{r[1]}" for r in TABLE_4B])
def test_table_4b(name, params, irw, k_w, pslr, islr20, null):
    assert w.impulse_response_width(name, **params) == pytest.approx(irw, rel=0.01)
    assert w.broadening_factor(name, **params) == pytest.approx(k_w, rel=0.01)
    assert w.pslr_theory(name, **params) == pytest.approx(pslr, abs=0.5)
    assert w.first_null(name, **params) == pytest.approx(null, rel=0.01)
    # TABLE_4B integrates the sidelobes over +-20 cells (1/B) from the peak
    u1 = w.first_null(name, **params)
    assert w.islr_theory(name, sidelobes=20.0 / u1 - 1.0, **params) == pytest.approx(islr20, abs=0.5)


def test_rect_closed_forms():
    """sinc^2: half power at u = 0.44295 (2 x = 0.88589), first null 1, highest sidelobe at
    tan(pi u) = pi u, u = 1.4303; E_main = 2 Si(2 pi) / pi, E_total = 1."""
    assert w.impulse_response_width("rect") == pytest.approx(0.885893, abs=2e-6)
    assert w.first_null("rect") == pytest.approx(1.0, abs=1e-9)
    u_side = 1.4302966531242027  # root of tan(pi u) = pi u in (1, 1.5)
    assert w.pslr_theory("rect") == pytest.approx(20 * np.log10(abs(np.sinc(u_side))), abs=1e-6)
    assert w.pslr_theory("rect") == pytest.approx(-13.2619, abs=1e-3)
    main = 2 * scipy.special.sici(2 * np.pi)[0] / np.pi
    assert w.islr_theory("rect") == pytest.approx(10 * np.log10((1 - main) / main), abs=1e-6)
    assert w.islr_theory("rect") == pytest.approx(-9.68, abs=0.005)
    # ISCE3 convention, 10 null distances of sidelobes: E_side = 1 - main - 2 int_11^inf sinc^2
    tail = 1.0 - 2 * scipy.integrate.quad(lambda u: np.sinc(u) ** 2, 0, 11, limit=500, epsabs=1e-13)[0]
    assert w.islr_theory("rect", sidelobes=10) == pytest.approx(10 * np.log10((1 - main - tail) / main), abs=1e-5)
    assert w.islr_theory("rect", sidelobes=10) == pytest.approx(-10.11, abs=0.01)
    assert w.energy_width("rect") == pytest.approx(1.0) and w.window_mean("rect") == pytest.approx(1.0)


def test_means_and_energy_widths():
    # Hamming mean = alpha; Hann: int (0.5 + 0.5 cos)^2 = 3/8, mean 1/2, energy width 3/2
    assert w.window_mean("hamming", alpha=0.6) == pytest.approx(0.6, rel=1e-10)
    assert w.window_mean("hann") == pytest.approx(0.5, rel=1e-10)
    assert w.energy_width("hann") == pytest.approx(1.5, rel=1e-10)
    # Kaiser: int I0(beta sqrt(1 - 4x^2)) dx = sinh(beta) / beta (the transform at u = 0)
    assert w.window_mean("kaiser", beta=2.5) == pytest.approx(np.sinh(2.5) / 2.5 / scipy.special.i0(2.5), rel=1e-10)


@pytest.mark.parametrize("name, params", [("rect", {}), ("hamming", {}), ("hann", {}), ("kaiser", {"beta": 2.5}),
                                          ("taylor", {"nbar": 4, "sll": -35}), ("kaiser", {"beta": 6.0})])
def test_compressed_pulse_is_the_transform_of_the_window(name, params):
    """p(u) = int w(x) exp(j 2 pi u x) dx / int w, by quadrature at a few u."""
    norm = scipy.integrate.quad(lambda x: w.spectral_window(name, x, 1.0, **params), -0.5, 0.5, epsabs=1e-14)[0]
    for u in (0.0, 0.37, 1.0, 1.9, 4.3, 11.7):
        value = scipy.integrate.quad(lambda x: w.spectral_window(name, x, 1.0, **params) * np.cos(2 * np.pi * u * x),
                                     -0.5, 0.5, epsabs=1e-14, limit=200)[0] / norm
        assert w.compressed_pulse(u, 1.0, name, **params) == pytest.approx(value, abs=1e-10)
    # time and bandwidth enter only as B t
    assert w.compressed_pulse(2e-9, 150e6, name, **params) == pytest.approx(
        w.compressed_pulse(0.3, 1.0, name, **params), abs=1e-12)


def test_sampled_windows_match_scipy_and_the_continuous_form():
    n = 257
    x_sym = np.arange(n) / (n - 1) - 0.5
    assert np.allclose(w.window("rect", n), 1.0)
    assert np.allclose(w.window("hamming", n), sw.hamming(n), atol=1e-15)
    assert np.allclose(w.window("hann", n), sw.hann(n), atol=1e-15)
    assert np.allclose(w.window("kaiser", n, beta=2.5), sw.kaiser(n, 2.5), atol=1e-15)
    assert np.allclose(w.window("taylor", n, nbar=4, sll=-35), sw.taylor(n, 4, 35), atol=1e-15)
    for name, params in (("hamming", {}), ("hann", {}), ("kaiser", {"beta": 2.5})):
        assert np.allclose(w.window(name, n, **params), w.spectral_window(name, x_sym, 1.0, **params), atol=1e-13)
    x_taylor = (np.arange(n) - (n - 1) / 2) / n  # scipy's taylor samples
    assert np.allclose(w.window("taylor", n), w.spectral_window("taylor", x_taylor, 1.0), atol=1e-13)
    assert w.window("hamming", 16).dtype == np.float64


def test_spectral_window_support_and_centre():
    f = np.linspace(-100e6, 100e6, 2001)
    for name in w.WINDOWS:
        v = w.spectral_window(name, f, 150e6)
        assert v.shape == f.shape and np.all(v[np.abs(f) > 75e6] == 0) and np.all(v[np.abs(f) < 74e6] > 0)
        assert w.spectral_window(name, 0.0, 150e6) == pytest.approx(1.0)


@pytest.mark.parametrize("call, match", [
    (lambda: w.window("gauss", 8), "unknown window"),
    (lambda: w.window("kaiser", 8, nbar=3), "no parameter"),
    (lambda: w.window("kaiser", 8, beta=-1), "beta"),
    (lambda: w.window("taylor", 8, nbar=2.5), "nbar"),
    (lambda: w.window("taylor", 8, sll=-10), "sll"),
    (lambda: w.window("hamming", 8, alpha=1.5), "alpha"),
    (lambda: w.window("rect", 0), "length n"),
    (lambda: w.spectral_window("rect", [0.0], -1.0), "bandwidth"),
    (lambda: w.islr_theory("rect", sidelobes=0), "sidelobes"),
])
def test_rejects_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_sll_sign_and_aliases():
    assert w.check_window("Taylor", sll=35) == ("taylor", {"nbar": 4, "sll": -35.0})
    assert w.check_window("none") == ("rect", {})
    assert w.pslr_theory("taylor", sll=35) == w.pslr_theory("taylor", sll=-35)
