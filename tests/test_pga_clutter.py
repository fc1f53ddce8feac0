"""PGA's estimate from the clutter (sarmitsuba.focus.pga_clutter, docs/physics.md (PGA8)) and the
window's signal-to-clutter ratio that decides whether a target's own lines may be learnt from
(sarmitsuba.focus.pga_pulses.window_scr_db), against synthetic truth: complex Gaussian clutter of a
known, symmetric Doppler spectrum under a known phase error, and closed forms of the geometry.

Deliberate bugs tried (each fails a test below): the lag-one product conjugated on the wrong pulse
(the error comes out mirrored); the bins summed by their energy instead of each weighing alike (a
bright point's Doppler ramp takes the estimate over); steps taken over the pulses whose beam leaves
the scene (their one-sided Doppler tilts the estimate); the slant range taken as ``c t`` instead of
``c t / 2``; the window's half width taken as its width.
"""
from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.focus.pga_clutter import COMMON_SCALE, across_range, common_bins, look_sine
from sarmitsuba.focus.pga_pulses import window_scr_db

N_PULSES = 400
#: A sinusoidal error of whole periods over the pulses: no linear part for the detrend to take.
ERROR = 3.0 * np.sin(2.0 * np.pi * np.arange(N_PULSES) / 50.0)
APERTURE = 80


def _clutter(bins: int, seed: int = 1) -> np.ndarray:
    """complex [N_PULSES, bins]: white complex Gaussian noise filtered along the pulses by the
    symmetric real taps (0.5, 1, 0.5): a Doppler spectrum symmetric about zero, lag-one correlation
    2 / 3, every bin independent, under ``ERROR``."""
    rng = np.random.default_rng(seed)
    white = rng.standard_normal((N_PULSES + 2, bins)) + 1j * rng.standard_normal((N_PULSES + 2, bins))
    clutter = 0.5 * white[:-2] + white[1:-1] + 0.5 * white[2:]
    return clutter * np.exp(1j * ERROR)[:, None]


def _residual(phase: np.ndarray, keep: np.ndarray | None = None) -> float:
    """rms [rad] of ``phase - ERROR`` over ``keep`` (default every pulse), less a straight line in
    each run of :data:`APERTURE` pulses (a synthetic aperture's worth: a linear phase only shifts the
    image, and the estimate's noise is a random walk, which grows over the whole track)."""
    keep = np.ones(N_PULSES, bool) if keep is None else keep
    d = np.unwrap(np.angle(np.exp(1j * (phase - ERROR))))
    out = []
    for start in range(0, N_PULSES - APERTURE + 1, APERTURE):
        k = np.arange(start, start + APERTURE)
        k = k[keep[k]]
        if k.size >= APERTURE // 2:
            out.append(np.mean((d[k] - np.polyval(np.polyfit(k, d[k], 1), k)) ** 2))
    return float(np.sqrt(np.mean(out)))


def test_the_error_is_read_from_the_clutter_and_its_noise_falls_with_the_lines():
    """The estimate from 16 range bins and from 256: the injected error (3 rad, 50 pulses a period)
    comes back, and its error falls as the bins grow in number, about as ``1 / sqrt(L)`` (a random
    walk of steps whose variance is ``(1 - rho^2) / (2 L rho^2)`` at a lag-one coherence ``rho``:
    16 times the bins, 4 times less; measured 3.4, asserted at least 2.5) and within 0.3 rad at 256
    (0.16 measured; rms over apertures of 80 pulses, each less a straight line). Catches the product
    conjugated on the wrong pulse (the error mirrored: about 4 rad off)."""
    few = _residual(across_range(_clutter(16))[0])
    many = _residual(across_range(_clutter(256))[0])
    assert many < 0.3
    assert few / many > 2.5


def test_a_bright_point_does_not_take_the_estimate_over():
    """256 bins of clutter and one bin holding a point 35 dB over a clutter bin whose Doppler sweeps across the
    band as the beam passes (a chirp, ``exp(j 0.01 p^2)``): each bin weighs alike, so the point's bin
    is one of 257 and the estimate stays within 0.3 rad (0.16 measured, as without the point);
    summed by energy, its chirp would be read as the error. Catches the bins summed by their energy."""
    p = np.arange(N_PULSES) - N_PULSES / 2
    point = 100.0 * np.exp(1j * 0.01 * p ** 2) * np.exp(1j * ERROR)
    data = np.concatenate([_clutter(256), point[:, None]], axis=1)
    assert _residual(across_range(data)[0]) < 0.3


def test_no_step_is_taken_where_the_beam_leaves_the_scene():
    """The first 60 pulses see the scene's edge: half the clutter power, and the clutter on one side
    only, a Doppler offset of 0.8 rad per pulse. Those pulses lie more than 1 dB below the others and
    are left out (``inside`` from pulse 60 on), and the error over the rest comes back within 0.3 rad
    (0.14 measured) with no tilt. Catches steps taken there (their 0.8 rad per pulse tilts
    the linear fit: radians across the track)."""
    data = _clutter(256)
    edge = np.arange(N_PULSES) < 60
    data[edge] *= np.sqrt(0.5) * np.exp(1j * 0.8 * np.arange(60))[:, None]
    phase, inside = across_range(data)
    assert np.array_equal(inside, ~edge)
    assert _residual(phase, inside) < 0.3
    # no linear part left beyond the error's own: the estimate is the error itself, not tilted
    slope = np.polyfit(np.flatnonzero(inside), np.angle(np.exp(1j * (phase - ERROR)))[inside], 1)[0]
    assert abs(slope) * inside.sum() < 2.0                    # 0.6 measured: the noise's own walk


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_look_sine_is_the_incidence(incidence):
    """A point ``h tan(theta)`` across from a track ``h`` above it is seen at ``sin(theta)``."""
    height = 1000.0
    assert look_sine(np.array([height * np.tan(np.radians(incidence))]), height)[0] == pytest.approx(
        np.sin(np.radians(incidence)), rel=1e-12)


@pytest.mark.parametrize("incidence", [45.0, 30.0])
def test_the_common_bins_are_those_where_the_sway_scales_alike(incidence):
    """Fast-time samples from 0.5 to 1.5 times the scene centre's slant range, the track ``h``
    above the image at ``h tan(theta)`` across: the bins kept are those whose slant range ``c t / 2``
    lies within ``[h / sqrt(1 - s_lo^2), h / sqrt(1 - s_hi^2)]``, ``s = sin(theta) (1 -+ COMMON_SCALE)``
    (closed form). Catches the slant range taken as the two-way path."""
    height = 1000.0
    ground = height * np.tan(np.radians(incidence))
    centre = np.hypot(ground, height)
    image = SimpleNamespace(metadata={"focus": {"track": {"position": [0.0, ground, height],
                                                          "direction": [1.0, 0.0, 0.0]}}},
                            origin=np.zeros(3), range=np.linspace(-50.0, 50.0, 101),
                            range_direction=np.array([0.0, -1.0, 0.0]), plane="ground")
    slant = np.linspace(0.5, 1.5, 4001) * centre
    raw = SimpleNamespace(fast_time=2.0 * slant / SPEED_OF_LIGHT)
    s = np.sin(np.radians(incidence)) * np.array([1.0 - COMMON_SCALE, 1.0 + COMMON_SCALE])
    low, high = height / np.sqrt(1.0 - s ** 2)
    expected = (slant >= low) & (slant <= high)
    kept = common_bins(raw, image)
    assert np.count_nonzero(kept != expected) <= 2           # the two samples at the limits, rounding
    assert kept.sum() > 100
    image.plane = "slant"                                     # its origin on the track: no ground to read angles on
    assert not common_bins(raw, image).any()


def test_pulses_without_echo_give_no_estimate_and_no_warning():
    """All-zero bins and bins of which more than 90 % are zero: the phase is zero, no pulse is
    inside, and nothing is divided by zero."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        phase, inside = across_range(np.zeros((50, 20), complex))
        assert not phase.any() and not inside.any()
        sparse = np.zeros((N_PULSES, 40), complex)
        sparse[:, :2] = _clutter(2)
        phase, inside = across_range(sparse)
    assert np.isfinite(phase).all() and inside.any()


def test_the_window_scr_is_the_targets_energy_over_the_clutter_it_holds():
    """Lines of clutter of constant intensity ``c`` (random phases) and a point of energy ``E`` at
    index 0 in place of the clutter there, a window of 21 samples (10 either side): the ratio is
    ``(E + 20 c - 21 c) / (21 c)`` (closed form), and ``inf`` without clutter. Catches the window's
    half width taken as its width (41 samples of clutter)."""
    rng = np.random.default_rng(3)
    n, c, energy = 512, 2.0, 5000.0
    lines = np.sqrt(c) * np.exp(2j * np.pi * rng.random((n, 2)))
    lines[0] = np.sqrt(energy / 2.0)
    expected = 10.0 * np.log10((energy + 20 * 2 * c - 21 * 2 * c) / (21 * 2 * c))
    assert window_scr_db(lines, 21) == pytest.approx(expected, abs=1e-9)
    alone = np.zeros((n, 1), complex)
    alone[0] = 1.0
    assert window_scr_db(alone, 21) == float("inf")
