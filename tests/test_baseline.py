"""Baselines of a pass shifted by ``track_offset`` (sarmitsuba.scene.baseline, docs/physics.md (I1)-(I4)),
worked by hand at 30 and 60 deg incidence (not 45: there tan = cot and sin = cos).

Geometry: altitude H, flying +x, looking right toward -y, so the sensor sits at
``y = H tan(theta)`` and ``u = (0, sin theta, cos theta)`` points from the scene centre to it; the
look angle grows along ``e = (0, cos theta, -sin theta)``. Bugs these catch: B_perp and B_par
swapped, the sign of B_perp (it must be positive where the look angle grows), an along-track
offset counted in a baseline, sin/cos or tan swapped in the critical baseline or the height of
ambiguity (checked by second methods from the geometry: the interferometric phase's rate with
height, and the ground-range wavenumber shift between the passes; and ERS's published figures),
a factor 2 lost in either, and ``info`` printing something else.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from sarmitsuba.scene import baseline as bl
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.core.radar import RadarParameters

ALTITUDE, FREQ, BANDWIDTH = 3000.0, 9.6e9, 150e6


def _params(incidence: float, offset) -> RadarParameters:
    return RadarParameters(frequency=FREQ, bandwidth=BANDWIDTH, altitude=ALTITUDE, incidence_angle=incidence,
                           scene_center=(0.0, 0.0, 0.0), n_pulses=101, prf=250.0, azimuth_beamwidth=1.0,
                           track_offset=tuple(offset))


def _height_of_ambiguity_by_phase(master, slave, wavelength):
    """Second method: one cycle over the rate at which the repeat-pass interferometric phase
    ``4 pi / lambda (|S - P| - |M - P|)`` changes with the height of ``P`` moved along the
    master's iso-range circle (the master's phase fixed) at the scene centre, by a central
    difference over +-1 mm (the height of ambiguity is this first-order quantity, Hanssen 2001)."""
    r0 = np.linalg.norm(master)

    def point(h):        # the point at height h, range r0 from the master, in the look plane
        y = master[1] - math.sqrt(r0**2 - (master[2] - h) ** 2)
        return np.array([0.0, y, h])

    def phase(h):
        p = point(h)
        return 4 * math.pi / wavelength * (np.linalg.norm(slave - p) - np.linalg.norm(master - p))
    return 2 * math.pi / abs((phase(1e-3) - phase(-1e-3)) / 2e-3)


def _critical_by_geometry(master, e, wavelength):
    """Second method: the perpendicular baseline at which the two passes' ground-range
    wavenumbers ``4 pi / lambda sin(theta_i)`` (incidence at the scene centre from each antenna)
    differ by the span of the range bandwidth, ``4 pi B_w / c sin(theta)`` (Gatelli et al., 1994:
    the spectra no longer overlap), to first order in the baseline as the source has it: the
    wavenumber's rate per metre of perpendicular offset by a central difference over +-1 mm."""
    def sin_incidence(antenna):
        return math.hypot(antenna[0], antenna[1]) / np.linalg.norm(antenna)
    rate = (sin_incidence(master + 1e-3 * e) - sin_incidence(master - 1e-3 * e)) / 2e-3
    return (BANDWIDTH / SPEED_OF_LIGHT * sin_incidence(master)) / (rate / wavelength)


def test_ers_worked_example():
    """ERS-1/2 tandem (C band 5.3 GHz, 785 km up, 23 deg incidence, 15.55 MHz): a critical
    baseline of about 1.1 km and a height of ambiguity of about 9.4 km / B_perp (Hanssen,
    *Radar Interferometry*, 2001, section 2.5; Gatelli et al., 1994)."""
    params = RadarParameters(frequency=5.3e9, bandwidth=15.55e6, altitude=785e3, incidence_angle=23.0,
                             scene_center=(0.0, 0.0, 0.0), n_pulses=101, prf=1680.0, azimuth_beamwidth=0.3,
                             track_offset=(0.0, 100.0 * math.cos(math.radians(23.0)), -100.0 * math.sin(math.radians(23.0))))
    b = bl.baseline(params)
    assert b.perpendicular == pytest.approx(100.0, rel=1e-9)
    assert 1.0e3 < b.critical < 1.2e3
    assert b.height_of_ambiguity * 100.0 == pytest.approx(9.4e3, rel=0.03)


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_baseline_by_hand(incidence):
    t = math.radians(incidence)
    slant = ALTITUDE / math.cos(t)
    wavelength = SPEED_OF_LIGHT / FREQ
    # 4 m along e (perpendicular), 3 m along u (parallel), 7 m along track
    e = (0.0, math.cos(t), -math.sin(t))
    u = (0.0, math.sin(t), math.cos(t))
    offset = [7.0 + 0.0, 4 * e[1] + 3 * u[1], 4 * e[2] + 3 * u[2]]
    b = bl.baseline(_params(incidence, offset))
    assert b.perpendicular == pytest.approx(4.0, abs=1e-9)
    assert b.parallel == pytest.approx(3.0, abs=1e-9)
    assert b.along_track == pytest.approx(7.0, abs=1e-9)
    assert b.slant_range == pytest.approx(slant, rel=1e-12)
    master = np.array([0.0, ALTITUDE * math.tan(t), ALTITUDE])
    assert b.critical == pytest.approx(_critical_by_geometry(master, np.array(e), wavelength), rel=2e-3)
    assert b.height_of_ambiguity == pytest.approx(_height_of_ambiguity_by_phase(master, master + offset, wavelength),
                                                  rel=2e-3)
    flipped = bl.baseline(_params(incidence, [-v for v in offset]))
    assert flipped.perpendicular == pytest.approx(-4.0, abs=1e-9)


def test_zero_offset_has_no_height_of_ambiguity_and_info_prints_the_baseline(capsys):
    assert math.isinf(bl.baseline(_params(30.0, (0.0, 0.0, 0.0))).height_of_ambiguity)
    from sarmitsuba.cli import main
    assert main(["info", "dihedral", "--json", "--set", "track_offset=0, 0.5, -0.5"]) == 0
    radar = json.loads(capsys.readouterr().out)["radar"]
    assert radar["baseline_perpendicular_m"] == pytest.approx(math.sqrt(0.5), abs=1e-6)
    assert radar["baseline_parallel_m"] == pytest.approx(0.0, abs=1e-6)
    assert radar["height_of_ambiguity_m"] == pytest.approx(
        SPEED_OF_LIGHT / 9.6e9 * 1000 * math.sqrt(2) * math.sqrt(0.5) / (2 * math.sqrt(0.5)), rel=1e-3)


def test_bad_track_offset_exits_2(tmp_path, capsys):
    from sarmitsuba.cli import main
    for value in ("1, 2", "0, 0, 2e6", "a, b, c"):
        assert main(["render", "dihedral", "--out", str(tmp_path / "x"), "--set", f"track_offset={value}"]) == 2
        err = capsys.readouterr().err
        assert "track_offset" in err and "Traceback" not in err
    assert not (tmp_path / "x").exists()
