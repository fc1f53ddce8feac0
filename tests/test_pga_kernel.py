"""The phase gradient kernel (sarmitsuba.focus.pga_kernel, docs/physics.md (PGA)) against closed forms:
the circular distance of the centred lines, the window it sets, and the gradient estimate of a
phase error injected by hand into the spectrum of a band-limited point (known up to a constant
and a linear phase, which PGA does not estimate).

After centring, a response sits about index 0 of a periodic line: its left half lies at the end
of the array (indices n - 1, n - 2, ...). The window and the first window's width must measure
distance round the circle; a plain distance ``k`` keeps the right half only and reads the left
half as ``n - k`` away.
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.focus.pga_kernel import (centre_lines, circular_distance, detrend_phase, estimate_phase,
                                         smear_width)

N = 512
FREQ = np.fft.fftshift(np.fft.fftfreq(N))               # cycles per sample, centred order
BAND = np.abs(FREQ) < 0.2


def _line(error: np.ndarray, position: int) -> np.ndarray:
    """complex [N, 1]: a point at ``position`` whose flat spectrum over BAND carries ``error`` [rad]."""
    spectrum = np.where(BAND, np.exp(1j * error - 2j * np.pi * FREQ * position), 0.0)
    return np.fft.ifft(np.fft.ifftshift(spectrum))[:, None]


def _no_trend(phase: np.ndarray) -> np.ndarray:
    k = np.arange(N)
    return phase - np.polyval(np.polyfit(k[BAND], phase[BAND], 1), k)


def test_circular_distance_is_the_shorter_way_round():
    """Closed form: index k of n lies min(k, n - k) from index 0 (7 of 10: 3). Catches a plain distance."""
    assert list(circular_distance(10)) == [0, 1, 2, 3, 4, 5, 4, 3, 2, 1]
    assert list(circular_distance(7)) == [0, 1, 2, 3, 3, 2, 1]


def test_the_first_window_holds_both_sides_of_a_centred_response():
    """Two echoes 12 samples either side of a peak (a sinusoidal error's paired echoes): after
    centring they lie at indices 12 and N - 12, and the first window is WIDEN x (2 x 12 + 1) = 38
    samples (-10 dB: the echoes at -6 dB count, the zeros between them do not). Catches the plain
    distance (the echo at N - 12 read 500 samples away: the window becomes the whole line)."""
    line = np.zeros((N, 1), complex)
    line[[88, 100, 112], 0] = [0.5, 1.0, 0.5]
    centred = centre_lines(line)
    assert np.flatnonzero(np.abs(centred[:, 0]) > 0).tolist() == [0, 12, N - 12]
    assert smear_width(centred, 10.0, 1.5) == int(np.ceil(1.5 * 25))


@pytest.mark.parametrize("position", [3, 250])
def test_the_window_keeps_the_left_half_of_the_response(position):
    """A quadratic error of 3 rad at the band's edge (its response some 10 samples wide) on a point
    at sample ``position`` (3: the response wraps round the end of the line): centred and windowed
    to 61 samples, the estimate is the injected error within 0.03 rad rms (0.020 measured: the
    window cuts the far sidelobes of the flat band) over the band, less a
    constant and a slope. Catches the plain distance in the window (only the right half kept)."""
    error = 3.0 * (FREQ / 0.2) ** 2
    centred = centre_lines(_line(error, position))
    phase, support, power = estimate_phase(centred, 61, 40.0, BAND)
    residual = _no_trend(phase) - _no_trend(error)
    assert support[BAND].all() and not support[~BAND].any()
    assert np.sqrt(np.mean(residual[BAND] ** 2)) < 0.03


def test_detrend_removes_a_constant_and_a_shift_only():
    """A phase ``a + b k + c k^2`` detrended with uniform weights over the whole line: what is left
    is ``c`` times ``k^2`` less its own least-squares line (closed form from numpy.polyfit of the
    quadratic alone). Catches a detrend that removes the curvature too, or none of the slope."""
    k = np.arange(N, dtype=float)
    phase = 2.0 - 0.03 * k + 1e-5 * k ** 2
    out = detrend_phase(phase, np.ones(N, bool), np.ones(N))
    quadratic = 1e-5 * k ** 2
    assert out == pytest.approx(quadratic - np.polyval(np.polyfit(k, quadratic, 1), k), abs=1e-9)
