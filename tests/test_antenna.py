"""Two-way antenna pattern (docs/physics.md (A)) against the uniform-aperture closed form."""
from __future__ import annotations

import math

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.pipeline import simulate


def _pulse_peaks(overrides):
    # a fixed ray spacing: the automatic one follows the azimuth resolution, which the antenna changes
    sim = simulate("trihedral", sensor_overrides=overrides, integrator_overrides={"ray_spacing": 0.1})
    return sim, np.abs(sim.raw.data).max(axis=1)


def test_azimuth_pattern_is_two_way_sinc_squared():
    """Pulse by pulse, the trihedral's echo with a 1 m antenna over the echo of a uniform beam
    as wide as the antenna's traced main lobe (same pulses) is sinc^2(L_a sin(phi_az) / lambda)
    within 0.1 dB over the -6 dB main lobe (the 1.5 m trihedral spans +-0.05 % of the beam, so
    its faces see slightly different gains)."""
    lam = 299_792_458.0 / 9.6e9
    nulls = math.degrees(2 * math.asin(lam / 1.0))            # the 1 m antenna's main lobe, null to null
    common = {"prf": 500.0, "azimuth_beamwidth": 0}            # PRF above that lobe's Doppler bandwidth
    sim, with_pattern = _pulse_peaks({**common, "antenna_length": 1.0})
    assert sim.loaded.params.traced_beamwidth == pytest.approx(nulls)
    _, without = _pulse_peaks({**common, "beam": "uniform", "azimuth_beamwidth": nulls})
    e = -sim.raw.tx_position                               # apex at the origin
    sin_az = (e @ np.array([1.0, 0.0, 0.0])) / np.linalg.norm(e, axis=1)
    model = np.sinc(1.0 / sim.loaded.params.wavelength * sin_az) ** 2
    seen = (without > 0) & (model > 0.5)
    assert seen.sum() > 50
    error_db = 20 * np.log10(with_pattern[seen] / without[seen] / model[seen])
    assert np.abs(error_db).max() < 0.1, f"max error {np.abs(error_db).max():.3f} dB"
    edge = (without > 0) & (model > 0.05) & (model < 0.2)   # the steep flank still follows it
    assert np.abs(20 * np.log10(with_pattern[edge] / without[edge] / model[edge])).mean() < 0.5


def test_elevation_pattern_off_boresight():
    """A target 20 m off the beam centre in ground range is weighted by sinc^2(H_a sin(phi_el)/lambda)."""
    center = {"scene_center": "0, -20, 0"}
    sim, with_pattern = _pulse_peaks({**center, "antenna_height": 1.5})
    _, without = _pulse_peaks(center)
    p = sim.loaded.params
    antenna = sim.raw.tx_position[len(with_pattern) // 2]
    boresight = np.array([0.0, -20.0, 0.0]) - antenna
    to_target = -antenna
    phi = math.atan2(boresight[2], -boresight[1]) - math.atan2(to_target[2], -to_target[1])
    expected = np.sinc(1.5 / p.wavelength * math.sin(phi)) ** 2
    measured = with_pattern.max() / without.max()
    assert abs(20 * math.log10(measured / expected)) < 0.1, f"{measured:.4f} vs {expected:.4f}"
    assert expected < 0.8                                   # the target really is off boresight


def test_pattern_sets_the_beam_and_resolution():
    """A 2 m antenna: resolution L_a / 2, 3 dB beamwidth 2 asin(0.443 lambda / L_a) (where
    sinc^2 = 1/2), traced to the first nulls 2 asin(lambda / L_a)."""
    sim = simulate("trihedral", sensor_overrides={"antenna_length": 2.0, "azimuth_beamwidth": 0})
    p = sim.loaded.params
    assert p.azimuth_resolution == 1.0
    # worked by hand, lambda = c / 9.6 GHz = 0.0312284 m: 2 asin(0.442946 * 0.0312284 / 2)
    # = 2 asin(0.00691625) = 0.792550 deg (a half-power point at 0.886 lambda / L, i.e. the
    # two-way pattern's 3 dB taken for the one-way one, gives 1.585 deg; a beamwidth left in
    # radians, 0.01383)
    assert p.azimuth_beamwidth == pytest.approx(0.792550, abs=2e-6)
    # first nulls 2 asin(0.0312284 / 2) = 2 asin(0.0156142) = 1.789327 deg (3 dB instead: 0.79)
    assert p.traced_beamwidth == pytest.approx(1.789327, abs=2e-6)
    # and the pattern is indeed at half power there (second method: the pattern itself)
    assert np.sinc(2.0 / p.wavelength * math.sin(math.radians(p.azimuth_beamwidth / 2))) ** 2 == pytest.approx(0.5)


def test_default_beam_is_tapered_and_uniform_on_request():
    """No antenna dimensions: the default beam is the aperture whose 3 dB width is
    azimuth_beamwidth (1 deg), traced to its nulls; ``beam = uniform`` is the hard-edged beam of
    that full width, with resolution lambda / (2 beta); a uniform beam with an antenna is refused."""
    from sarmitsuba.core.radar import ParameterError, RadarParameters
    tapered, uniform = RadarParameters(), RadarParameters(beam="uniform")
    beta = math.radians(1.0)
    # worked by hand: L = 0.442946 lambda / sin(0.5 deg) = 0.442946 * 0.0312284 / 0.00872654
    # = 1.585108 m (sin(1 deg), the full width for the half: 0.7927 m)
    assert tapered.pattern_length == pytest.approx(1.585108, abs=2e-6)
    assert np.sinc(tapered.pattern_length / tapered.wavelength * math.sin(beta / 2)) ** 2 == pytest.approx(0.5)
    # nulls: 2 asin(0.0312284 / 1.585108) = 2 asin(0.0197011) = 2.257727 deg; resolution L / 2
    assert tapered.traced_beamwidth == pytest.approx(2.257727, abs=2e-6)
    assert tapered.azimuth_resolution == pytest.approx(0.792554, abs=2e-6)
    assert uniform.pattern_length == 0 and uniform.traced_beamwidth == pytest.approx(1.0)
    # lambda / (2 beta) = 0.0312284 / (2 * 0.0174533) = 0.894627 m (beta in degrees: 0.0156)
    assert uniform.azimuth_resolution == pytest.approx(0.894627, abs=2e-6)
    with pytest.raises(ParameterError, match="beam = 'uniform'"):
        RadarParameters(beam="uniform", antenna_length=1.0)
    with pytest.raises(ParameterError, match="disagrees with antenna_length"):
        RadarParameters(antenna_length=1.0, azimuth_beamwidth=3.5)
