"""Band-limited DFT interpolation against signals whose values between samples are known."""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.signal.bandlimited import Interpolant2D, dft_rows


@pytest.mark.parametrize("n", [15, 16])
def test_interpolates_a_band_limited_cosine_between_samples(n):
    # cos(2 pi f u / n) with f < n/2 is its own band-limited interpolant: at u = 0.37 or
    # 5.81 the value is the cosine's, not a neighbouring sample's (a wrong sign in the
    # exponent or a missing 1/n breaks this)
    f = 3
    x = np.cos(2 * np.pi * f * np.arange(n) / n + 0.4)
    u = np.array([0.37, 5.81, n - 0.5])
    got = dft_rows(n, u) @ np.fft.fft(x)
    assert np.allclose(got, np.cos(2 * np.pi * f * u / n + 0.4), atol=1e-12)


def test_even_length_nyquist_term_keeps_a_real_signal_real():
    # the alternating sequence sits entirely in the Nyquist bin: its band-limited
    # interpolant is cos(pi u) (real); an unsplit bin would give exp(+-j pi u)
    n = 8
    x = (-1.0) ** np.arange(n)
    u = np.array([0.25, 0.5, 3.3])
    got = dft_rows(n, u) @ np.fft.fft(x)
    assert np.allclose(got, np.cos(np.pi * u), atol=1e-12)


def test_2d_passes_through_samples_and_separates():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(6, 9)) + 1j * rng.normal(size=(6, 9))
    f = Interpolant2D(a)
    assert np.allclose(f(np.arange(6), np.arange(9)), a, atol=1e-12)
    # a product of two 1-D band-limited tones is interpolated as the product
    ti, tj = np.arange(6)[:, None], np.arange(9)[None, :]
    b = np.exp(2j * np.pi * (ti / 6 + 2 * tj / 9))
    u, v = np.array([1.5, 4.2]), np.array([0.3, 7.7])
    assert np.allclose(Interpolant2D(b)(u, v), np.exp(2j * np.pi * (u[:, None] / 6 + 2 * v[None, :] / 9)), atol=1e-12)
