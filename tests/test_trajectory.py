"""Trajectories and echo timing (docs/physics.md (J1)-(J4)), against closed forms.

- The receive time on a uniform straight track solves ``c tau = |r| + |r + v tau|``, a quadratic
  with the root ``tau = 2 (c |r| + r.v) / (c^2 - v^2)`` (r = antenna - point): the iteration
  must reach it, at an airborne and at a spaceborne geometry, at a heading that is not 0.
- The circular track is the circle of radius ``H tan(theta)`` at height ``H``, clockwise when
  looking right (angular momentum along -z), through the broadside position at t = 0.
- The spline interpolants stay within their textbook error bounds on a circle
  (``h^4 |P''''| / 384`` for cubic Hermite, ``5 h^4 |P''''| / 384`` for the cubic spline) and
  reproduce a straight line exactly.
- A bad CSV is refused with its line and column.
- Motion errors lie horizontal and normal to the track, with the stated amplitude, and their
  velocity is the derivative of the stated sinusoid.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.core.geometry import acquisition_geometry, track_frame, trajectory_of
from sarmitsuba.core.radar import ParameterError, RadarParameters
from sarmitsuba.core import trajectory as tj


def _quadratic_delay(tx: np.ndarray, v: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The exact delay of (J3) on a uniform straight track, from the quadratic (module docstring)."""
    r = tx - point
    c = SPEED_OF_LIGHT
    return 2.0 * (c * np.linalg.norm(r, axis=-1) + r @ v) / (c * c - v @ v)


@pytest.mark.parametrize("altitude,velocity,heading", [(1000.0, 100.0, 30.0), (514e3, 7600.0, -25.0)],
                         ids=["airborne", "spaceborne"])
def test_receive_time_solves_the_echo_equation_exactly(altitude, velocity, heading):
    p = RadarParameters(scene_center=(12.0, -7.0, 3.0), n_pulses=9, prf=50.0, altitude=altitude, velocity=velocity,
                        heading=heading, incidence_angle=38.0)
    g = acquisition_geometry(p)
    tau = _quadratic_delay(g.positions, g.velocity[0], np.asarray(p.scene_center))
    assert np.abs((g.rx_time - g.pulse_time) - tau).max() < 1e-15 * 10 + 1e-12 * tau.max()
    # the antenna moves v tau during the echo (acceptance: within 1 %; here to rounding)
    moved = np.linalg.norm(g.rx_positions - g.positions, axis=1)
    assert np.allclose(moved, velocity * tau, rtol=1e-9)
    assert np.allclose((g.rx_positions - g.positions) / moved[:, None], track_frame(p)[0], atol=1e-9)
    if altitude > 1e5:   # 514 km: the antenna moves about 37 m while the echo travels (v 2 R / c)
        assert 30.0 < moved.mean() < 45.0
    # stop-and-hop: the receive position is the transmit position
    flat = acquisition_geometry(RadarParameters(**{**p.__dict__, "stop_and_hop": True}))
    assert flat.rx_time is None and np.array_equal(flat.rx_positions, flat.positions)


def test_echo_length_moves_the_receiver_to_each_pixels_own_echo():
    """``echo_length`` of a point 3 km from the reference point, from the recorded receive position
    of the reference echo, equals ``c tau`` of the point's own echo (quadratic) to micrometres;
    without the move (rx_delay None) it is off by about ``v (tau_x - tau_ref)`` along the line of sight."""
    p = RadarParameters(scene_center=(0.0, 0.0, 0.0), n_pulses=5, prf=3000.0, altitude=514e3, velocity=7600.0,
                        heading=20.0, incidence_angle=35.0, squint=4.0)
    g = acquisition_geometry(p)
    x = np.array([2100.0, -2200.0, 40.0])
    exact = SPEED_OF_LIGHT * _quadratic_delay(g.positions, g.velocity[0], x)
    got = tj.echo_length(g.positions, g.rx_positions, g.velocity, g.rx_time - g.pulse_time, x[None, :])
    assert np.abs(got - exact).max() < 1e-6
    unmoved = tj.echo_length(g.positions, g.rx_positions, g.velocity, None, x[None, :])
    assert np.abs(unmoved - exact).max() > 1e-3


@pytest.mark.parametrize("heading,look", [(30.0, "right"), (-120.0, "left")])
def test_circular_track_is_the_circle_of_the_incidence_angle(heading, look):
    p = RadarParameters(scene_center=(5.0, 3.0, 2.0), trajectory="circular", arc_deg=90.0, heading=heading,
                        look_side=look, altitude=800.0, incidence_angle=40.0, velocity=60.0, prf=20.0)
    from sarmitsuba.scene.planning import resolve_parameters
    p = resolve_parameters(p, np.zeros(3), np.ones(3))
    radius = 800.0 * math.tan(math.radians(40.0))
    assert p.n_pulses == math.floor(math.radians(90.0) * radius * 20.0 / 60.0) + 1
    assert p.mode == "spotlight"
    g = acquisition_geometry(p)
    rel = g.positions - np.array([5.0, 3.0, 2.0])
    assert np.allclose(np.hypot(rel[:, 0], rel[:, 1]), radius, rtol=1e-12) and np.allclose(rel[:, 2], 800.0)
    assert np.allclose(np.linalg.norm(g.velocity, axis=1), 60.0)
    spin = rel[:, 0] * g.velocity[:, 1] - rel[:, 1] * g.velocity[:, 0]            # (r x v) . z
    assert np.all(spin < 0) if look == "right" else np.all(spin > 0)
    track, look_dir = track_frame(p)
    broadside = np.array([5.0, 3.0, 2.0]) - radius * look_dir + np.array([0, 0, 800.0])
    path = trajectory_of(p)                        # at t = 0: the broadside position, flying along heading
    assert np.allclose(path.position(0.0), broadside, atol=1e-9) and np.allclose(path.velocity(0.0), 60.0 * track)
    assert abs(g.pulse_time[0] + g.pulse_time[-1]) < 1e-12                          # pulses centred on it
    turned = math.degrees(math.acos(np.clip(rel[0, :2] @ rel[-1, :2] / radius ** 2, -1, 1)))
    assert abs(turned - 90.0) <= math.degrees(60.0 / 20.0 / radius)            # within one pulse step
    # the scene lies to the look side of every pulse: toward the centre
    assert np.all(np.sum(g.beam_axes[:, :2] * (-rel[:, :2]), axis=1) < 1e-6 * radius)


def test_full_circle_has_no_pulse_twice_and_refuses_more():
    p = RadarParameters(scene_center=(0.0, 0.0, 0.0), trajectory="circular", altitude=500.0, incidence_angle=45.0,
                        velocity=50.0, prf=10.0)
    from sarmitsuba.scene.planning import resolve_parameters
    full = resolve_parameters(p, np.zeros(3), np.ones(3))
    assert full.n_pulses == round(2 * math.pi * 500.0 * 10.0 / 50.0)
    with pytest.raises(ParameterError, match="more than the full circle"):
        resolve_parameters(RadarParameters(**{**p.__dict__, "n_pulses": full.n_pulses + 1}), np.zeros(3), np.ones(3))
    with pytest.raises(ParameterError, match="squint"):
        RadarParameters(scene_center=(0.0, 0.0, 0.0), trajectory="circular", squint=5.0)
    with pytest.raises(ParameterError, match="arc_deg"):
        RadarParameters(trajectory="circular", arc_deg=400.0)


def test_splines_stay_within_their_error_bounds_and_reproduce_lines():
    radius, speed, step = 1000.0, 100.0, 1.0
    t = np.arange(0.0, 60.0 + step / 2, step)
    w = speed / radius

    def circle(time):
        return np.stack([radius * np.cos(w * time), radius * np.sin(w * time), np.full_like(time, 300.0)], -1)
    velocity = np.stack([-speed * np.sin(w * t), speed * np.cos(w * t), np.zeros_like(t)], -1)
    fine = np.linspace(t[3], t[-4], 2001)          # away from the not-a-knot ends
    fourth = speed ** 4 / radius ** 3              # |P''''| on a circle
    hermite = tj.from_state_vectors(tj.StateVectors(t, circle(t), velocity))
    spline = tj.from_state_vectors(tj.StateVectors(t, circle(t)))
    err_h = np.linalg.norm(hermite.position(fine) - circle(fine), axis=1).max()
    err_s = np.linalg.norm(spline.position(fine) - circle(fine), axis=1).max()
    assert err_h <= step ** 4 * fourth / 384 and err_s <= 5 * step ** 4 * fourth / 384
    assert np.linalg.norm(hermite.velocity(fine)[0] - [-speed * math.sin(w * fine[0]), speed * math.cos(w * fine[0]), 0]) < 1e-3
    line = tj.from_state_vectors(tj.StateVectors(t[:7], np.outer(t[:7], [3.0, -4.0, 0.5]) + [1.0, 2.0, 900.0]))
    assert np.abs(line.position(2.37) - (np.array([3.0, -4.0, 0.5]) * 2.37 + [1.0, 2.0, 900.0])).max() < 1e-9
    assert np.abs(line.acceleration(2.37)).max() < 1e-9


@pytest.mark.parametrize("text,match", [
    ("time_s,x_m,y_m,z_m\n0,0,0,100\n1,1,0,100\n", "line 1|4"),
    ("time_s,x_m,y_m,z_m\n0,0,0,100\n1,1,0,100\n1,2,0,100\n3,3,0,100\n", "line 4, column time_s"),
    ("time_s,x_m,y_m,z_m\n0,0,0,100\n1,1,0,nan\n2,2,0,100\n3,3,0,100\n", "line 3, column z_m"),
    ("time_s,x_m,y_m,z_m\n0,0,0,100\n1,1,0,100\n2,2,0,100\n30,30,0,100\n31,31,0,100\n", "line 5, column time_s: a gap"),
    ("time_s,x_m,y_m,height\n0,0,0,100\n", "line 1 \\(header\\): unknown column 'height'"),
    ("time_s,x_m,y_m,z_m,vx_mps\n0,0,0,100,1\n", "velocity needs all"),
    ("time_s,x_m,y_m,z_m\n0,0,0,100\n1,one,0,100\n", "line 3, column x_m: 'one' is not a number"),
], ids=["too few rows", "times not increasing", "nan", "gap", "unknown column", "partial velocity", "not a number"])
def test_bad_state_vectors_name_the_line_and_column(tmp_path, text, match):
    path = tmp_path / "track.csv"
    path.write_text(text)
    with pytest.raises(tj.TrajectoryError, match=match) as info:
        tj.read_state_vectors(path)
    assert "track.csv" in str(info.value) and isinstance(info.value, ParameterError)


def test_two_state_vectors_with_velocities_are_enough(tmp_path):
    path = tmp_path / "hermite.csv"
    path.write_text("vx_mps,time_s,x_m,y_m,z_m,vy_mps,vz_mps\n10,0,0,0,100,0,0\n10,2,20,0,100,0,0\n")
    track = tj.from_state_vectors(tj.read_state_vectors(path))
    assert np.allclose(track.position(0.5), [5.0, 0.0, 100.0]) and np.allclose(track.velocity(1.7), [10.0, 0, 0])


@pytest.mark.parametrize("heading,look", [(30.0, "right"), (135.0, "left")])
def test_sinusoidal_motion_error_is_horizontal_across_the_track(heading, look):
    amplitude, period, speed = 0.02, 7.0, 80.0
    p = RadarParameters(scene_center=(0.0, 0.0, 0.0), n_pulses=401, prf=100.0, velocity=speed, heading=heading,
                        look_side=look, motion_error=f"{amplitude}, {period}")
    g = acquisition_geometry(p)
    track, look_dir = track_frame(p)
    d = g.positions - g.nominal_positions
    assert np.abs(d @ track).max() < 1e-12 and np.abs(d[:, 2]).max() < 1e-12
    s = speed * g.pulse_time                       # distance flown from mid-aperture
    assert np.allclose(d @ look_dir, amplitude * np.sin(2 * math.pi * s / period), atol=1e-12)
    dv = (g.velocity - g.nominal_velocity) @ look_dir
    assert np.allclose(dv, amplitude * 2 * math.pi / period * speed * np.cos(2 * math.pi * s / period), atol=1e-9)
    assert np.allclose(g.nominal_positions, acquisition_geometry(RadarParameters(**{**p.__dict__, "motion_error": None})).positions)


def test_random_motion_error_has_its_rms_and_correlation_and_its_seed():
    p = RadarParameters(scene_center=(0.0, 0.0, 0.0), n_pulses=20001, prf=100.0, velocity=100.0,
                        motion_error="random, 0.03, 5, 7")
    g = acquisition_geometry(p)
    e = (g.positions - g.nominal_positions) @ track_frame(p)[1]       # 20 km of track: 4000 lengths
    assert 0.9 * 0.03 < e.std() < 1.1 * 0.03
    lag = 5                                                           # pulses 1 m apart: lag 5 m = one length
    corr = np.mean(e[:-lag] * e[lag:]) / np.mean(e * e)
    assert abs(corr - math.exp(-1.0)) < 0.1
    again = acquisition_geometry(p).positions
    other = acquisition_geometry(RadarParameters(**{**p.__dict__, "motion_error": "random, 0.03, 5, 8"})).positions
    assert np.array_equal(again, g.positions) and not np.allclose(other, g.positions)


@pytest.mark.parametrize("text", ["0.02", "0.02, 10, 3", "random, 0.02", "-0.02, 10", "0.02, 0", "abc, 2"])
def test_bad_motion_error_is_refused(text):
    with pytest.raises(ParameterError, match="motion_error"):
        RadarParameters(motion_error=text)
