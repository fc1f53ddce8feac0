"""The receiver's anti-aliasing filter against the raised-cosine definition (Proakis and
Salehi, *Digital Communications*, 5th ed., eq. 9.2-26): flat over the band, and over the
roll-off ``x in [0, 1]`` from ``B/2`` to ``fs/2`` the power-complementary pair
``R(x) + R(1 - x) = 1`` with ``R(1/2) = 1/2``."""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.signal.signal_model import receiver_response


@pytest.mark.parametrize("fs, bandwidth", [(120e6, 100e6), (300e6, 150e6)])
def test_receiver_response_is_a_raised_cosine(fs, bandwidth):
    # catches a cos roll-off instead of cos^2 (R(1/2) = 0.707, the pair sums to up to 1.41), a
    # roll-off starting at fs/2 instead of B/2, or a filter that is not even in f
    edge, top = bandwidth / 2, fs / 2
    x = np.linspace(0.0, 1.0, 41)
    f = edge + x * (top - edge)
    r, r_mirror = receiver_response(f, fs, bandwidth), receiver_response(edge + (1 - x) * (top - edge), fs, bandwidth)
    np.testing.assert_allclose(r + r_mirror, 1.0, atol=1e-12)
    assert receiver_response(np.array([edge + 0.5 * (top - edge)]), fs, bandwidth)[0] == pytest.approx(0.5, abs=1e-12)
    inband = np.linspace(-edge, edge, 11)
    np.testing.assert_array_equal(receiver_response(inband, fs, bandwidth), 1.0)
    np.testing.assert_array_equal(receiver_response(-f, fs, bandwidth), r)
    assert receiver_response(np.array([top * 1.01]), fs, bandwidth)[0] == pytest.approx(0.0, abs=1e-30)


def test_brick_wall_when_sampled_at_the_bandwidth():
    # fs == B: no room for a roll-off, 1 inside the band and 0 outside
    f = np.array([-60e6, -50e6, 0.0, 49.9e6, 50.1e6])
    np.testing.assert_array_equal(receiver_response(f, 100e6, 100e6), [0.0, 1.0, 1.0, 1.0, 0.0])
