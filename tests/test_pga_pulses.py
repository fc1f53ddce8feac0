"""PGA on the pulses themselves (sarmitsuba.focus.pga_pulses, docs/physics.md (PGA7)) against analytic
point-target raw data (sarmitsuba.analysis.synthetic) with a phase error put into every pulse by
hand: the truth is that error, whatever its size, up to a constant and a linear phase.

X-band, 250 Hz, 100 m/s (a pulse every 0.4 m), the point 1000 m across and 1000 m below the track.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sarmitsuba.analysis.synthetic import PointTarget, stripmap
from sarmitsuba.focus.pga_kernel import apply_phase
from sarmitsuba.focus.pga_pulses import beam_centred, pulse_positions, recentred, target_samples

TRACK = {"position": [0.0, 1000.0, 1000.0], "direction": [1.0, 0.0, 0.0]}


def _raw(point, n_pulses: int = 151, beamwidth: float | None = None, error: np.ndarray | None = None):
    raw = stripmap(PointTarget(np.asarray(point, float)), fc=9.6e9, bandwidth=150e6, fs=180e6, prf=250.0, speed=100.0,
                   n_pulses=n_pulses, center=(0.0, 1000.0, 1000.0), beamwidth=beamwidth)
    if error is not None:
        raw = dataclasses.replace(raw, data=(raw.data * np.exp(1j * error)[:, None]).astype(np.complex64))
    return raw


@pytest.mark.parametrize("point", [(0.0, 0.0, 0.0), (6.0, -3.0, 2.0)])
def test_each_pulse_holds_the_error_at_the_point(point):
    """A sinusoidal error of 20 rad amplitude and 10 m period (up to 5 rad from one pulse to the
    next: its Doppler folds many times over the PRF): the samples read at the point carry it exactly,
    ``angle(c_p exp(-j phi_p))`` constant within 2e-3 rad over the pulses. Catches the carrier
    removed with the wrong sign (the samples then turn by 4 pi fc L / c across the track) and the
    delay taken one way."""
    s = (np.arange(151) - 75) * 0.4
    error = 20.0 * np.sin(2.0 * np.pi * s / 10.0)
    samples = target_samples(_raw(point, error=error), np.array([point]))[:, 0]
    residual = np.angle(samples * np.exp(-1j * error) * np.conj(samples[75] * np.exp(-1j * error[75])))
    assert np.max(np.abs(residual)) < 2e-3
    assert np.ptp(np.abs(samples)) < 0.02 * np.abs(samples).max()              # no beam: every pulse alike


def test_the_response_is_put_back_where_the_samples_were_read():
    """Samples of a point 7.3 samples of the period off the reading point (a linear phase across the
    pulses), corrected by a phase with no linear part: recentred adds the linear phase that brings
    the corrected response to index 0, where the samples were read (closed form: the image of
    ``exp(-j 2 pi f 7.3)`` peaks at 7.3: the phase removed is ``-2 pi f 7.3``, within the 0.15 samples
    by which the circular centroid of the sampled response misses its peak). Catches the shift's
    sign (the response at 14.6)."""
    n = 128
    f = (np.arange(n) - n // 2) / n
    samples = np.exp(-2j * np.pi * f * 7.3)[:, None]
    phase = recentred(samples, np.zeros(n), 0.0)
    image = np.abs(apply_phase(samples, phase)[:, 0])
    assert int(np.argmax(image)) == 0
    shift = -np.polyfit(2.0 * np.pi * f, phase, 1)[0]        # phase = -2 pi f shift: a straight line
    assert shift == pytest.approx(7.3, abs=0.2)              # the centroid of a sampled sinc, not its peak


def test_a_point_read_off_its_place_is_moved_to_where_the_beam_saw_it():
    """A point at x = 7 m seen through a 1.2 deg beam (pulses within 10.5 m of it), read first at
    x = 0: the centroid of its echo's power over the pulses, where the beam points at it, is 7 m
    (within a pulse spacing). Catches the point left where it was read (0 m)."""
    raw = _raw((7.0, 0.0, 0.0), n_pulses=201, beamwidth=1.2)
    moved = beam_centred(raw, np.array([[0.0, 0.0, 0.0]]), pulse_positions(raw.tx_position, TRACK), TRACK)
    assert moved[0] == pytest.approx([7.0, 0.0, 0.0], abs=0.4)
