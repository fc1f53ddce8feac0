"""Radar equation, thermal noise and calibration (docs/physics.md (R1)-(R4), (K)).

Closed forms: noise power k T B F per sample; point-target image SNR =
P_t G^2 lambda^2 sigma / ((4 pi)^3 R^4 k T B F L) x B T_p x N_pulses (Skolnik, *Radar
Handbook*, 3rd ed., eq. 1.1 and ch. 17 for the SAR integration gain).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.constants import BOLTZMANN
from sarmitsuba.pipeline import simulate
from sarmitsuba.radar import ParameterError
from sarmitsuba.radiometry import radar_equation

RADAR = {"transmit_power": 200.0, "antenna_gain_db": 30.0, "losses_db": 2.0}
NOISE = {"noise_figure_db": 3.0, "noise_temperature": 290.0}


def test_noise_power_per_sample_is_k_t_b_f():
    """An empty beam with noise: raw samples have power k T B F within 2 %."""
    from sarmitsuba.planning import AcquisitionWarning
    with pytest.warns(AcquisitionWarning, match="outside the beam footprint"):
        sim = simulate("trihedral", sensor_overrides={**RADAR, **NOISE, "scene_center": "500, 500, 0",
                                                      "n_pulses": 300})
    p = sim.loaded.params
    expected = BOLTZMANN * 290.0 * p.bandwidth * 10 ** 0.3
    measured = float(np.mean(np.abs(sim.raw.data) ** 2))
    assert abs(measured / expected - 1.0) < 0.02, f"noise {measured:.4g} W, k T B F = {expected:.4g} W"


def test_point_target_image_snr_matches_radar_equation():
    """Image SNR of the trihedral = radar-equation SNR x B T_p x N_eff within 1 dB, N_eff the
    pattern-weighted number of pulses (Curlander and McDonough 1991, eq. 7.6.5, with the
    aperture's amplitude weighting)."""
    signal = simulate("trihedral", sensor_overrides=RADAR, window="rect")   # unweighted: no window SNR loss
    noisy = simulate("trihedral", sensor_overrides={**RADAR, **NOISE}, window="rect")
    p = signal.loaded.params
    peak = np.unravel_index(np.argmax(np.abs(signal.image.data)), signal.image.data.shape)
    rcs = float(np.abs(signal.image.data[peak]) ** 2)              # calibrated: |peak|^2 = sigma
    noise_image = noisy.image.data - signal.image.data
    full = np.abs(signal.image.azimuth) < 3.0          # rows with a full aperture, like the target's
    snr_measured = rcs / float(np.mean(np.abs(noise_image[full]) ** 2))
    equation = radar_equation(noisy.loaded.params)
    slant = float(np.linalg.norm(signal.raw.tx_position[signal.raw.n_pulses // 2]))   # apex at the origin
    # coherent gain of the pattern-weighted aperture: the echo of pulse p carries the two-way field
    # pattern g_p^2 = sinc^2(L sin(phi_p) / lambda); with every pulse of the traced beam summed
    # (rect window) the signal adds as sum g^2 and the noise as sqrt(N): N_eff = (sum g^2)^2 / N
    e = -signal.raw.tx_position                                         # to the apex at the origin
    sines = e[:, 0] / np.linalg.norm(e, axis=1)
    lo, hi = p.beam_sines
    g2 = np.sinc(p.pattern_length / p.wavelength * sines[(sines >= lo) & (sines <= hi)]) ** 2
    n_effective = g2.sum() ** 2 / g2.size
    assert n_effective < 0.75 * g2.size                                 # the taper costs integration gain
    snr_expected = equation.image_snr(rcs, slant, n_effective)
    assert abs(10 * math.log10(snr_measured / snr_expected)) < 1.0, \
        f"image SNR {10 * math.log10(snr_measured):.2f} dB, radar equation {10 * math.log10(snr_expected):.2f} dB"


def test_absolute_mode_is_calibrated_like_normalised_mode():
    """The calibrated image of absolute-unit raw data equals the normalised image (RCS unchanged)."""
    absolute = simulate("trihedral", sensor_overrides=RADAR)
    normalised = simulate("trihedral")
    a, b = np.abs(absolute.image.data).max() ** 2, np.abs(normalised.image.data).max() ** 2
    assert abs(10 * math.log10(a / b)) < 0.1
    assert absolute.raw.metadata["units"].startswith("sqrt(W)")
    assert np.abs(absolute.raw.data).max() < 1e-3 * np.abs(normalised.raw.data).max()   # really in sqrt(W)


def test_satellite_range_radiometry_representable_in_float32():
    """1/R^4 at 800 km with a small RCS: finite, non-zero, normal float32 values (no underflow)."""
    sim = simulate("trihedral", sensor_overrides={**RADAR, "altitude": 800e3 * math.cos(math.pi / 4), "n_pulses": 3})
    peak = np.abs(sim.raw.data).max()
    assert np.all(np.isfinite(sim.raw.data)) and peak > np.finfo(np.float32).tiny * 1e6
    expected = math.sqrt(radar_equation(sim.loaded.params).received_power(1.0, 800e3) * 1e3)  # order of magnitude
    assert 1e-3 < peak / expected < 1e5


@pytest.mark.parametrize("override, message", [
    ({"noise_figure_db": 3.0}, "need transmit_power"),
    ({"transmit_power": 100.0}, "needs the antenna gain"),
    ({"transmit_power": -1.0, "antenna_gain_db": 30}, "transmit_power = -1.0"),
])
def test_radiometry_parameter_errors_before_tracing(override, message):
    from sarmitsuba.scene import load_scene
    with pytest.raises(ParameterError, match=message):
        load_scene("trihedral", sensor_overrides=override)
