"""The image frame of a curved track follows the whole aperture, not its mid-aperture velocity
(sarmitsuba.core.geometry.aperture_axis, docs/physics.md (J2)).

The oracle is a straight line fitted here, independently: the track's own analytic positions,
densely sampled over the span that the pulses fill, rotated back by the heading and fitted by
``numpy.polyfit`` (cross-track against along-track). Two headings, neither a multiple of 45 deg,
so that a sine for a cosine or a swapped axis shows.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from sarmitsuba.core.geometry import acquisition_geometry
from sarmitsuba.focus.scene_grid import image_grid
from sarmitsuba.scene.loader import load_scene

SPEED, HEIGHT, STANDOFF = 10.0, 150.0, 150.0           # m/s; m above the scene; m beside it
SWAY, PERIOD, PHASE = 0.4, 24.0, 0.7                    # m, m, rad: the drone's sway (scenes/drone_track.csv)
SPAN = 2.2                                              # s of state vectors: a 22 m aperture


def _track(t: np.ndarray, heading_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities [n, 3] of a track flying ``heading_deg`` past the scene centre
    on its left (the radar looks right, at the origin), swaying across it."""
    h = math.radians(heading_deg)
    u, n = np.array([math.cos(h), math.sin(h), 0.0]), np.array([-math.sin(h), math.cos(h), 0.0])
    along = SPEED * (t - SPAN / 2)
    across = STANDOFF + SWAY * np.sin(2 * np.pi * along / PERIOD + PHASE)
    rate = SWAY * 2 * np.pi / PERIOD * np.cos(2 * np.pi * along / PERIOD + PHASE) * SPEED
    pos = along[:, None] * u + across[:, None] * n + np.array([0.0, 0.0, HEIGHT])
    vel = SPEED * u[None, :] + rate[:, None] * n
    return pos, vel


def _csv(path, heading_deg: float):
    t = np.linspace(0.0, SPAN, 45)
    pos, vel = _track(t, heading_deg)
    rows = np.column_stack([t, pos, vel])
    np.savetxt(path, rows, delimiter=",", fmt="%.9f", header="time_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps", comments="")
    return path


def _oracle_heading(heading_deg: float, t0: float, t1: float) -> float:
    """The least-squares line through the track over ``[t0, t1]``, by polyfit in the frame of
    the nominal heading: its heading [deg]."""
    h = math.radians(heading_deg)
    pos, _ = _track(np.linspace(t0, t1, 4001), heading_deg)
    x = pos[:, 0] * math.cos(h) + pos[:, 1] * math.sin(h)            # rotate back by the heading
    y = -pos[:, 0] * math.sin(h) + pos[:, 1] * math.cos(h)
    slope = np.polyfit(x, y, 1)[0]
    return heading_deg + math.degrees(math.atan(slope))


def _heading(v: np.ndarray) -> float:
    return math.degrees(math.atan2(v[1], v[0]))


@pytest.mark.parametrize("heading", [20.0, 115.0])
def test_the_frame_of_a_swaying_track_is_the_aperture_fit(tmp_path, heading):
    """Catches the frame taken from the mid-aperture velocity (2.8 deg off here), and a fit
    whose axes are swapped or rotated the wrong way (wrong by 2 x heading or 90 deg)."""
    csv = _csv(tmp_path / "track.csv", heading)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                  # the loader says what the trajectory replaced
        loaded = load_scene("trihedral", {"trajectory": str(csv), "mode": "spotlight"})
    geometry = acquisition_geometry(loaded.params)
    t = geometry.pulse_time
    expected = _oracle_heading(heading, float(t[0]), float(t[-1]))
    mid_velocity = _heading(_track(np.array([0.5 * (t[0] + t[-1])]), heading)[1][0])
    assert abs(mid_velocity - expected) > 2.0            # the sway makes the two differ: the test can tell
    assert _heading(geometry.track_direction) == pytest.approx(expected, abs=0.05)
    grid = image_grid(loaded, geometry)
    assert _heading(grid.azimuth_direction) == pytest.approx(expected, abs=0.05)
    # the look direction: horizontal, perpendicular, toward the scene centre (right of the track)
    look = geometry.look_direction
    assert abs(look[2]) < 1e-12 and abs(look @ geometry.track_direction) < 1e-12
    assert _heading(look) == pytest.approx(expected - 90.0, abs=0.05)


@pytest.mark.parametrize("heading", [20.0, 115.0])
def test_the_loaded_heading_and_incidence_follow_the_aperture_fit(tmp_path, heading):
    """The sensor's ``heading`` (what ``info`` and the metadata report) is the image frame's axis,
    the aperture's line fit, and the incidence is measured across that line. Catches the loader
    taking the heading from the mid-aperture velocity (2.8 deg off here, and then ``info``
    disagrees with the image), and the incidence measured across the swaying velocity: the oracle
    is the distance of the scene centre from the fitted line, by polyfit."""
    csv = _csv(tmp_path / "track.csv", heading)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loaded = load_scene("trihedral", {"trajectory": str(csv), "mode": "spotlight"})
    t = acquisition_geometry(loaded.params).pulse_time
    expected = _oracle_heading(heading, float(t[0]), float(t[-1]))
    assert loaded.params.heading == pytest.approx(expected, abs=0.05)
    # incidence: the scene centre's horizontal distance across the fitted line through the mid-aperture antenna
    mid = 0.5 * (t[0] + t[-1])
    antenna = _track(np.array([mid]), heading)[0][0]
    h = math.radians(expected)
    across = abs(-(0.0 - antenna[0]) * math.sin(h) + (0.0 - antenna[1]) * math.cos(h))
    assert loaded.params.incidence_angle == pytest.approx(math.degrees(math.atan2(across, antenna[2])), abs=1e-3)
