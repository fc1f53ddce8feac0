"""FFBP's fast paths against their readable references (issue 56).

``polar._coarse_geometry`` forms the first stage's residuals and beam positions from dot products
with the points' directions; ``polar._coarse_geometry_reference`` forms the vectors to every point.
They must agree to float64 rounding for stop-and-hop and continuous motion, with and without a
beam, on frames whose polar grid reaches beyond the plane (invalid points, which still set the
residual extremes), for one pulse and for a long, curved, spaceborne-fast sub-aperture.
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus import ImageGrid
from sarmitsuba.focus.polar import (BEAM_TABLE, PolarAxes, PolarFrame, _coarse_geometry, _coarse_geometry_reference,
                                    spline_tables)


def _case(n_pulses: int, speed: float, height: float, curved: bool, seed: int):
    """Frame, axes, coarse ranges and the pulses of a sub-aperture flying along +x at ``height``
    over a ground grid to its right."""
    rng = np.random.default_rng(seed)
    grid = ImageGrid(np.array([0.0, -height, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]),
                     np.linspace(-200.0, 200.0, 9), np.linspace(-300.0, 300.0, 11), "ground")
    t = (np.arange(n_pulses) - (n_pulses - 1) / 2) / 500.0
    tx = np.stack([speed * t, 0.0 * t, np.full_like(t, height)], axis=1)
    if curved:
        tx[:, 1] += 0.5 * 3.0 * t ** 2 * speed + rng.normal(0.0, 0.05, n_pulses)
        tx[:, 2] += rng.normal(0.0, 0.05, n_pulses)
    velocity = np.tile([speed, 0.0, 0.0], (n_pulses, 1)) + rng.normal(0.0, 0.01 * speed, (n_pulses, 3))
    axis = velocity / np.linalg.norm(velocity, axis=1, keepdims=True)
    delay = np.full(n_pulses, 2.0 * np.hypot(height, height) / C) * (1.0 + 0.1 * rng.random(n_pulses))
    rx = tx + velocity * delay[:, None]
    centre = np.concatenate([tx, rx]).mean(axis=0)
    frame = PolarFrame(centre, axis.mean(axis=0) / np.linalg.norm(axis.mean(axis=0)), grid)
    # ranges from below the plane's nearest (the first are invalid points) to 1.6 x the height
    axes = PolarAxes(-0.3, 0.6 / 40, 41, 0.8 * height, 0.8 * height / (16 * 12), 16 * 12)
    coarse = axes.r0 + axes.dr * 16 * np.arange(13)
    return frame, axes, coarse, tx, axis, (rx, velocity, delay)


@pytest.mark.parametrize("n_pulses, speed, height, curved", [(1, 100.0, 1000.0, False), (16, 100.0, 1000.0, True),
                                                             (64, 7500.0, 500e3, True)])
@pytest.mark.parametrize("continuous", [False, True])
@pytest.mark.parametrize("with_beam", [False, True])
def test_coarse_geometry_matches_reference(n_pulses, speed, height, curved, continuous, with_beam):
    frame, axes, coarse, tx, axis, receivers = _case(n_pulses, speed, height, curved, seed=n_pulses)
    beam = (np.zeros(BEAM_TABLE + 3, np.float32), -0.02, 0.02) if with_beam else None
    args = (frame, axes, coarse, tx, axis, beam, receivers if continuous else None)
    excess, position, valid = _coarse_geometry(*args)
    want_excess, want_position, want_valid = _coarse_geometry_reference(*args)
    assert excess.shape == want_excess.shape == (n_pulses, axes.n_s, coarse.size)
    assert not valid.all() and valid.any()          # the case reaches invalid points
    np.testing.assert_array_equal(valid, want_valid)
    # the reference's |x - a| - r cancels to r eps (r up to 600 km here): 1e-9 m is rounding
    np.testing.assert_allclose(excess, want_excess, rtol=0, atol=1e-12 * coarse.max() + 1e-12)
    if with_beam:
        assert position.dtype == np.float32
        np.testing.assert_allclose(position, want_position, rtol=0, atol=2e-3 if height > 1e5 else 1e-4)
    else:
        assert position is None and want_position is None


def test_continuous_excess_is_the_two_way_half_length():
    """Independent truth for one point: half the transmit leg plus the receive leg to where the
    receiver is when the echo arrives (eq. (J3): the arrival from the stop-and-hop legs), less the
    range from the centre."""
    frame, axes, coarse, tx, axis, (rx, velocity, delay) = _case(4, 120.0, 2000.0, True, seed=3)
    excess, _, valid = _coarse_geometry(frame, axes, coarse, tx, axis, None, (rx, velocity, delay))
    m, c = np.argwhere(valid)[len(np.argwhere(valid)) // 2]
    u, _ = frame.units(axes.s[m], coarse[c])
    x = frame.centre + coarse[c] * u
    for p in range(tx.shape[0]):
        out = np.linalg.norm(x - tx[p])
        tau = (out + np.linalg.norm(x - rx[p])) / C - delay[p]
        back = np.linalg.norm(x - rx[p] - tau * velocity[p])
        want = 0.5 * (out + back) - coarse[c]
        assert excess[p, m, c] == pytest.approx(want, abs=1e-9)


def test_spline_tables_are_cached_and_read_only():
    a, b = spline_tables(12), spline_tables(12)
    assert a[0] is b[0] and a[1] is b[1] and a[2] == 4096
    with pytest.raises(ValueError):
        a[0][0] = 0.0
