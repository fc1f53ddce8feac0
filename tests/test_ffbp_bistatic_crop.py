"""The range lines a bistatic FFBP sub-aperture reads (:func:`sarmitsuba.focus.ffbp_plan.residual_spread`,
docs/physics.md (F10)).

Each first-stage polar image reads its pulses' range lines cropped to its ranges ``rho`` widened by
the largest residual ``|L_p / 2 - rho|``, bounded by ``(|T_p - T_c| + |R_p - R_c|) / 2`` (the triangle
inequality on both legs), plus 48 guard samples. Here the transmitter creeps (5 m/s) and the
receiver closes on the scene or dives toward it (120 to 150 m/s), so over a 128-pulse sub-aperture
the target's half range sum moves by about 10 m, nearly all of it the receiver's, while the guard
holds 4.8 m (fs 1.5 GHz). Truth: direct backprojection of the same analytic data on the same grid
(exact on the range sum, no crop).

Deliberate bug this test was run against: the spread without the receiver's excursion (the
transmitter's alone, ``|T_p - T_c| / 2``): the crop cuts the target's echoes at the sub-aperture's
ends, about -10 dB from backprojection instead of -49.
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.analysis import synthetic
from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus import ImageGrid, backproject, ffbp

FC, B, FS, PRF, N = 9.6e9, 150e6, 1.5e9, 250.0, 256
TARGET = np.array([0.31, 150.17, 0.0])
#: The receiver's velocity [m/s] from (-500, 150, 500) m: closing along +x, or diving and turning.
RECEIVERS = {"closing": (120.0, 0.0, 0.0), "diving": (0.0, -60.0, -120.0)}


def acquisition(rx_velocity) -> "synthetic.RawData":
    """A unit point at TARGET: the transmitter 1000 m up and 1000 m to the side creeping along +x at
    5 m/s, the receiver from (-500, 150, 500) m at ``rx_velocity``; lines 300 m longer than the
    echoes on each side, so that the crop, not the data's end, bounds what a sub-aperture reads."""
    t = (np.arange(N) - (N - 1) / 2) / PRF
    v_tx = np.array([5.0, 0.0, 0.0])
    tx = np.array([0.0, 1000.0, 1000.0]) + t[:, None] * v_tx
    rx = np.array([-500.0, 150.0, 500.0]) + t[:, None] * np.asarray(rx_velocity)
    length = np.linalg.norm(tx - TARGET, axis=1) + np.linalg.norm(rx - TARGET, axis=1)
    n_samples = 2 * int(np.ceil((np.ptp(length) + 600.0) / C * FS / 2))
    return synthetic.simulate_point_targets(synthetic.PointTarget(TARGET, 1.0), tx, FC, B, FS,
                                            (length.min() - 300.0) / C, n_samples, prf=PRF,
                                            velocity=np.tile(v_tx, (N, 1)), pulse_length=2e-6, rx_position=rx)


@pytest.mark.parametrize("receiver", list(RECEIVERS))
def test_a_fast_receivers_excursion_widens_the_lines_read(receiver):
    """128-pulse sub-apertures: the target's half range sum moves by more than the guard within one
    (its spread across the sub-aperture, computed here from the geometry), the transmitter's part of
    that under 1 m; the FFBP image lies within -40 dB of direct backprojection's."""
    raw = acquisition(RECEIVERS[receiver])
    half_sum = 0.5 * (np.linalg.norm(raw.tx_position - TARGET, axis=1) + np.linalg.norm(raw.rx_position - TARGET, axis=1))
    tx_part = np.linalg.norm(raw.tx_position - TARGET, axis=1)
    guard = 48 * C / (2 * FS)
    assert np.ptp(half_sum[:128]) / 2 > guard + 0.5 and np.ptp(tx_part[:128]) / 2 < 1.0
    grid = ImageGrid.ground(np.round(TARGET), (1.0, 0.0, 0.0), (0.0, -1.0, -1.0), 8.0, 8.0, 0.1)
    fast, direct = ffbp(raw, grid, subaperture=128), backproject(raw, grid)
    error = np.sum(np.abs(fast.data.astype(complex) - direct.data) ** 2) / np.sum(np.abs(direct.data) ** 2)
    assert 10 * np.log10(error) < -40.0, 10 * np.log10(error)
