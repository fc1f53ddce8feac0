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
from sarmitsuba.core.constants import BOLTZMANN
from sarmitsuba.pipeline import simulate
from sarmitsuba.core.radar import ParameterError

RADAR = {"transmit_power": 200.0, "antenna_gain_db": 30.0, "losses_db": 2.0}
P_T, GAIN, LOSSES = 200.0, 10 ** 3.0, 10 ** 0.2                  # RADAR, linear
TRIHEDRAL_EDGE = 1.5                                             # m, the built-in trihedral


def _snr_by_hand(rcs, slant, wavelength, bandwidth, noise_figure=10 ** 0.3, temperature=290.0):
    """Single-pulse SNR written out: P_t G^2 lambda^2 sigma / ((4 pi)^3 R^4 k T B F L)."""
    return (P_T * GAIN ** 2 * wavelength ** 2 * rcs
            / ((4 * math.pi) ** 3 * slant ** 4 * BOLTZMANN * temperature * bandwidth * noise_figure * LOSSES))


def test_single_pulse_snr_worked_example():
    """A worked example by hand: P_t 1 kW, G 30 dB, lambda 3 cm, sigma 1 m^2, R 10 km, T 290 K,
    B 1 MHz, F = L = 1: SNR = 1e3 x 1e6 x 9e-4 / (1984.40 x 1e16 x 4.00388e-15) = 9e5 / 79454
    = 11.327 (10.54 dB). Kills (4 pi)^2 for (4 pi)^3 (x 12.6), R^3 for R^4, G for G^2, lambda for lambda^2."""
    from sarmitsuba.scene.radar_equation import RadarEquation
    eq = RadarEquation(transmit_power=1e3, gain=1e3, losses=1.0, wavelength=0.03, bandwidth=1e6,
                       pulse_length=1e-5, noise_power=BOLTZMANN * 290.0 * 1e6)
    assert eq.snr(1.0, 10e3) == pytest.approx(11.327, rel=1e-3)
    assert eq.image_snr(1.0, 10e3, 100) == pytest.approx(11.327 * 10.0 * 100, rel=1e-3)   # x B T_p x N
NOISE = {"noise_figure_db": 3.0, "noise_temperature": 290.0}


def test_noise_power_per_sample_is_k_t_b_f(monkeypatch):
    """An empty beam with noise: raw samples have power k T B F within 2 %. (Loading refuses a beam
    that never reaches the scene, track_checks.check_beam_reach; this test wants noise alone, so it
    switches that check off.)"""
    from sarmitsuba.scene.planning import AcquisitionWarning
    monkeypatch.setattr("sarmitsuba.scene.loader.check_beam_reach", lambda *args: None)
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
    # written out here, not taken from the pipeline's RadarEquation: single-pulse SNR x B T_p x N_eff
    snr_expected = _snr_by_hand(rcs, slant, p.wavelength, p.bandwidth) * p.bandwidth * p.pulse_length * n_effective
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
    """1/R^4 at 800 km: finite, normal float32 values (no underflow), and the range-compressed
    peak amplitude is the closed form sqrt(P_r B T_p), P_r from the radar equation written out with
    the trihedral's boresight RCS 4 pi a^4 / (3 lambda^2), within [0.6, 1.15] in amplitude: below 1
    by at most the range window's peak loss and the sample straddle loss (at most -3.9 dB, 0.64, for
    a peak between two samples; measured 0.96), above 1 by at most the few % by which PO and the
    sampled beam pattern can exceed the geometric-optics RCS. (4 pi)^2 for (4 pi)^3 gives x 3.5,
    R^3 for R^4 x 900, a missing B T_p x 39."""
    sim = simulate("trihedral", sensor_overrides={**RADAR, "altitude": 800e3 * math.cos(math.pi / 4), "n_pulses": 3})
    peak = np.abs(sim.raw.data).max()
    assert np.all(np.isfinite(sim.raw.data)) and peak > np.finfo(np.float32).tiny * 1e6
    p = sim.loaded.params
    rcs = 4 * math.pi * TRIHEDRAL_EDGE ** 4 / (3 * p.wavelength ** 2)
    received = P_T * GAIN ** 2 * p.wavelength ** 2 * rcs / ((4 * math.pi) ** 3 * 800e3 ** 4 * LOSSES)
    expected = math.sqrt(received * p.bandwidth * p.pulse_length)
    assert 0.6 < peak / expected < 1.15, f"peak / closed form = {peak / expected:.3f}"


@pytest.mark.parametrize("override, message", [
    ({"noise_figure_db": 3.0}, "need transmit_power"),
    ({"transmit_power": 100.0}, "needs the antenna gain"),
    ({"transmit_power": -1.0, "antenna_gain_db": 30}, "transmit_power = -1.0"),
])
def test_radiometry_parameter_errors_before_tracing(override, message):
    from sarmitsuba.scene.loader import load_scene
    with pytest.raises(ParameterError, match=message):
        load_scene("trihedral", sensor_overrides=override)


def test_antenna_gain_from_its_dimensions_worked_example():
    """G = 4 pi L_a H_a / lambda^2 (uniform aperture, efficiency 1), by hand: 1 m x 0.5 m at
    9.6 GHz: lambda = 299792458 / 9.6e9 = 0.0312284 m, lambda^2 = 9.75212e-4 m^2,
    G = 4 pi x 0.5 / 9.75212e-4 = 6.28319 / 9.75212e-4 = 6442.9 (38.09 dBi).
    With P_t = 100 W, L = 1: constant P_t G^2 lambda^2 / (4 pi)^3 = 100 (2 pi)^2 / lambda^2 / 1984.40
    = 100 x 39.4784 / 9.75212e-4 / 1984.40 = 2040.0 W m^2.
    Kills lambda^2 -> lambda * 2 in the gain (G = 402)."""
    from sarmitsuba.core.radar import RadarParameters
    from sarmitsuba.scene.radar_equation import radar_equation
    eq = radar_equation(RadarParameters(frequency=9.6e9, antenna_length=1.0, antenna_height=0.5,
                                        transmit_power=100.0))
    assert eq.gain == pytest.approx(6442.9, rel=1e-4)
    assert 10 * math.log10(eq.gain) == pytest.approx(38.09, abs=0.01)
    assert eq.constant == pytest.approx(2040.0, rel=1e-4)


@pytest.mark.parametrize("antenna_length, squint", [(2.0, 0.0), (0.5, 20.0)])
def test_effective_pulses_match_the_integrated_two_way_pattern(antenna_length, squint):
    """Second method: N_eff = (sum g^2)^2 / N -> N (mean of g^2 over the traced beam)^2 for many
    pulses spread evenly in sine, the mean taken by quadrature of the two-way pattern
    g^2 = sinc^2(L sin(phi) / lambda), phi = asin(s) - squint, over the beam sines [lo, hi].
    (Closed form, any L and squint: substituting s = sin(squint + phi) the mean is
    int_0^1 sinc^2(u) du = 0.45141, so N_eff = 0.20377 N.) Two antenna lengths, one squinted.
    Kills L / lambda * sin(...) -> L / lambda / sin(...)."""
    from scipy.integrate import quad

    from sarmitsuba.core.radar import RadarParameters
    from sarmitsuba.signal.radiometry import effective_pulses
    p = RadarParameters(frequency=9.6e9, antenna_length=antenna_length, squint=squint)
    lam = 299_792_458.0 / 9.6e9
    lo, hi = p.beam_sines
    sq = math.radians(squint)
    integral, _ = quad(lambda s: np.sinc(antenna_length / lam * math.sin(math.asin(s) - sq)) ** 2, lo, hi,
                       epsabs=0, epsrel=1e-10)
    mean = integral / (hi - lo)
    assert mean == pytest.approx(0.45141, rel=1e-4)
    n = 4001
    assert effective_pulses(p, n) == pytest.approx(n * mean ** 2, rel=2e-3)


@pytest.mark.parametrize("receiver", [{}, {"receiver_antenna_length": 1.5}])
def test_bistatic_effective_pulses_integrate_the_one_way_pattern(receiver):
    """A bistatic echo's two-way pattern is g_t g_r: the transmitter's one-way g_t = sinc(u) times
    the receiver's, which is 1 at the scene centre it stares at (docs/physics.md (B3)), with or
    without an antenna of its own. So N_eff = N (mean of |g_t| over the traced beam)^2, the mean
    int_0^1 sinc(u) du = Si(pi) / pi = 0.58949 (scipy.special.sici), 0.3475 N; the monostatic g^2,
    0.2038 N, would read 2.3 dB low."""
    from scipy.special import sici

    from sarmitsuba.core.radar import RadarParameters
    from sarmitsuba.signal.radiometry import effective_pulses
    base = {"frequency": 9.6e9, "antenna_length": 2.0, "n_pulses": 16}
    p = RadarParameters.from_mapping({**base, "receiver_altitude": 300.0, **receiver})
    assert p.bistatic
    n = 4001
    assert effective_pulses(p, n) == pytest.approx(n * (sici(math.pi)[0] / math.pi) ** 2, rel=2e-3)
    assert effective_pulses(RadarParameters.from_mapping(base), n) == pytest.approx(0.20377 * n, rel=2e-3)
