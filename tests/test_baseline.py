"""Baselines of a pass shifted by ``track_offset`` (sarmitsuba.baseline, docs/physics.md (I1)-(I4)),
worked by hand at 30 and 60 deg incidence (not 45: there tan = cot and sin = cos).

Geometry: altitude H, flying +x, looking right toward -y, so the sensor sits at
``y = H tan(theta)`` and ``u = (0, sin theta, cos theta)`` points from the scene centre to it; the
look angle grows along ``e = (0, cos theta, -sin theta)``. Bugs these catch: B_perp and B_par
swapped, the sign of B_perp (it must be positive where the look angle grows), an along-track
offset counted in a baseline, sin/cos or tan swapped in the critical baseline or the height of
ambiguity, and ``info`` printing something else.
"""
from __future__ import annotations

import json
import math

import pytest

from sarmitsuba import baseline as bl
from sarmitsuba.constants import SPEED_OF_LIGHT
from sarmitsuba.radar import RadarParameters

ALTITUDE, FREQ, BANDWIDTH = 3000.0, 9.6e9, 150e6


def _params(incidence: float, offset) -> RadarParameters:
    return RadarParameters(frequency=FREQ, bandwidth=BANDWIDTH, altitude=ALTITUDE, incidence_angle=incidence,
                           scene_center=(0.0, 0.0, 0.0), n_pulses=101, prf=250.0, azimuth_beamwidth=1.0,
                           track_offset=tuple(offset))


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
    assert b.critical == pytest.approx(wavelength * slant * math.tan(t) * BANDWIDTH / SPEED_OF_LIGHT, rel=1e-12)
    assert b.height_of_ambiguity == pytest.approx(wavelength * slant * math.sin(t) / (2 * 4.0), rel=1e-12)
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
