"""A receiver on its own platform in the acquisition checks (docs/physics.md (B1)): the Doppler
band its motion adds to the echoes (:func:`sarmitsuba.scene.track_checks.bistatic_doppler_band`),
against the monostatic closed form and the transmitter's own part, and the warning ``info`` and
``render`` give when that band exceeds the PRF."""
from __future__ import annotations

import pytest

import sarmitsuba  # noqa: F401  (the variant first)
from sarmitsuba.core.geometry import acquisition_geometry
from sarmitsuba.info import scene_info
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.scene.track_checks import bistatic_doppler_band

#: The gallery's bistatic example: urban lit from orbit in spotlight, received on a drone.
ORBIT = {"trajectory": "orbit", "altitude": 693e3, "mode": "spotlight", "n_pulses": 160}
DRONE = {"receiver_trajectory": "straight", "receiver_altitude": 300.0, "receiver_incidence_angle": 60.0,
         "receiver_heading": -60.0}


def _band(source: str, sensor: dict) -> tuple[float, float]:
    loaded = load_scene(source, sensor)
    return bistatic_doppler_band(loaded.params, acquisition_geometry(loaded.params), loaded.bbox_lo, loaded.bbox_hi)


@pytest.mark.parametrize("heading", [0.0, 35.0])
def test_a_receiver_riding_with_the_transmitter_doubles_its_band_and_a_still_one_adds_nothing(heading):
    """A receiver on the transmitter's own track (the same altitude, incidence, heading and speed):
    every echo's Doppler is twice the transmitter's one-way part, ``2 v . u / lambda`` (monostatic),
    so the band is exactly twice the transmitter's; a receiver hovering (1 cm/s) adds under 1 %.
    Stripmap on the dihedral, the beam narrower than the scene at 45 deg incidence. (Caught: the
    receiver's term with the wrong sign, 0; with the transmitter's velocity, twice.)"""
    base = {"mode": "stripmap", "heading": heading, "altitude": 1000.0, "incidence_angle": 45.0, "velocity": 100.0}
    same = {"receiver_altitude": 1000.0, "receiver_incidence_angle": 45.0, "receiver_heading": heading,
            "receiver_velocity": 100.0}
    band, own = _band("urban", {**base, **same})
    assert own > 0 and band == pytest.approx(2.0 * own, rel=1e-9)
    band, own = _band("urban", {**base, **same, "receiver_velocity": 0.01})
    assert band == pytest.approx(own, rel=0.01)


def test_the_transmitters_part_is_the_beams_one_way_doppler_band_on_a_wide_scene():
    """Stripmap over a scene far wider than the beam's footprint: the transmitter's part is the
    traced beam's one-way Doppler band ``v (sin_hi - sin_lo) / lambda`` (half of Cumming and Wong's
    eq. 4.36 for the traced beam), to 1e-6: the grid's lines are cut at the beam's edges."""
    sensor = {"mode": "stripmap", "altitude": 1000.0, "velocity": 100.0, "receiver_altitude": 800.0,
              "receiver_velocity": 50.0, "receiver_heading": 30.0}
    loaded = load_scene("urban", sensor)
    p = loaded.params
    sin_lo, sin_hi = p.beam_sines
    _, own = _band("urban", sensor)
    assert own == pytest.approx(p.velocity * (sin_hi - sin_lo) / p.wavelength, rel=1e-6)


@pytest.mark.parametrize("speed, warned", [(15.0, True), (3.0, False)])
def test_info_warns_of_a_receiver_fast_enough_to_alias(speed, warned):
    """The gallery's drone (600 m from the city at 60 deg) at 15 m/s spreads the echoes over 312 Hz
    against the satellite's 250 Hz PRF (its own part 74 Hz): ``info`` warns, naming
    ``receiver_velocity`` and a speed that fits; at 3 m/s (101 Hz) it does not."""
    sensor = {**ORBIT, **DRONE, "receiver_velocity": speed}
    notes = [w for w in scene_info("urban", sensor_overrides=sensor).warnings if "receiver_velocity" in w]
    assert bool(notes) == warned, notes
    if warned:
        assert "above prf = 250 Hz" in notes[0] and "slow the receiver to about" in notes[0]


def test_info_gives_the_receivers_own_range_and_the_angle_between_the_two_looks():
    """The transmitter 1000 m up at 45 deg incidence (1414 m away), the receiver 300 m up at 60 deg
    on a heading 90 deg off: ``info`` puts the receiver 300 / cos(60 deg) = 600 m from the scene
    centre at mid-aperture, and the bistatic angle is the angle between the two lines of sight,
    computed here from the looks' closed-form directions. (Caught: the receiver's range taken from
    the transmitter, 1414 m.)"""
    import math
    import numpy as np
    sensor = {"altitude": 1000.0, "incidence_angle": 45.0, "heading": 0.0, "receiver_altitude": 300.0,
              "receiver_incidence_angle": 60.0, "receiver_heading": 90.0}
    b = scene_info("urban", sensor_overrides=sensor).radar.bistatic
    assert b["receiver_range_m"] == pytest.approx(600.0, rel=1e-6)
    # unit vectors from the centre toward each antenna: right-looking, so the antenna stands on the
    # left of its heading; heading h from +x toward +y (0: +x; 90: +y)
    def toward(h, inc):
        left = np.array([-math.sin(math.radians(h)), math.cos(math.radians(h)), 0.0])
        return math.sin(math.radians(inc)) * left + math.cos(math.radians(inc)) * np.array([0.0, 0.0, 1.0])
    angle = math.degrees(math.acos(float(toward(0.0, 45.0) @ toward(90.0, 60.0))))
    assert b["angle_deg"] == pytest.approx(angle, abs=0.05)


@pytest.mark.parametrize("heading", [0.0, 35.0])
def test_the_speed_the_warning_names_clears_it(heading):
    """A receiver on the transmitter's own track (5 pulses: its look directions those of the
    transmitter) adds ``v_r / v_t`` of the transmitter's band ``B_t = v_t (sin_hi - sin_lo) /
    lambda``, so the band is ``B_t (1 + v_r / v_t)`` and falls to the PRF at ``v_r = prf lambda /
    (sin_hi - sin_lo) - v_t``: 57.7 m/s at the PRF chosen here. The warning at 150 m/s names that
    speed, rounded down (within 1 %, never above it), and the receiver flown at the speed named
    warns no more. (Caught: the speed rounded to the nearest of two digits, 58 m/s, which still
    warns; and the speed never checked against its closed form.)"""
    import math
    import re
    base = {"mode": "stripmap", "heading": heading, "altitude": 1000.0, "incidence_angle": 45.0, "velocity": 100.0,
            "n_pulses": 5, "receiver_altitude": 1000.0, "receiver_incidence_angle": 45.0,
            "receiver_heading": heading}
    p = load_scene("urban", base).params
    sin_lo, sin_hi = p.beam_sines
    prf = 157.7 / 100.0 * p.velocity * (sin_hi - sin_lo) / p.wavelength
    closed = prf * p.wavelength / (sin_hi - sin_lo) - p.velocity
    assert closed == pytest.approx(57.7, rel=1e-9)

    def notes(speed):
        return [w for w in scene_info("urban", sensor_overrides={**base, "prf": prf, "receiver_velocity": speed}).warnings
                if "receiver_velocity" in w]
    warned = notes(150.0)
    assert len(warned) == 1
    named = float(re.search(r"slow the receiver to about ([0-9.]+) m/s", warned[0]).group(1))
    assert 0.99 * closed <= named <= closed and math.isfinite(named)
    assert notes(named) == []
