"""Physically inconsistent radar settings: warnings where the user may mean it (issue 5)."""
from __future__ import annotations

import warnings

import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.planning import AcquisitionWarning


def test_prf_below_doppler_bandwidth_warns_of_azimuth_ambiguities():
    with pytest.warns(AcquisitionWarning, match="below the Doppler bandwidth.*azimuth ambiguities"):
        simulate("trihedral", sensor_overrides={"prf": 80.0})


def test_prf_too_high_for_the_scene_depth_warns_of_range_ambiguities():
    # urban: ~300 m of ground range -> ~0.75 us of echo window at 45 deg; PRF 2 MHz is far above c/(2 depth)
    with pytest.warns(AcquisitionWarning, match="range ambiguities"):
        simulate("dihedral", sensor_overrides={"prf": 2e6, "n_pulses": 8})


def test_scene_outside_the_beam_is_refused():
    """A track whose beam never reaches the scene is refused before tracing (issue 55: it rendered
    an all-zero image with a warning); tests/test_track_refusals.py tests the criterion."""
    from sarmitsuba.core.radar import ParameterError
    with pytest.raises(ParameterError, match="no pulse's beam reaches the scene"):
        simulate("trihedral", sensor_overrides={"scene_center": "500, 500, 0", "n_pulses": 4})


def test_sound_settings_do_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error", AcquisitionWarning)
        simulate("trihedral")


def test_energy_outside_the_window_is_warned_about(monkeypatch):
    # a fast-time window cut to its first quarter closes before the dihedral's echo (at the
    # scene centre, mid-window) arrives: the render must drop that energy, count it and say so;
    # with the planned window it must not (a warning that always or never fires fails one half)
    import dataclasses
    import warnings as _warnings

    from sarmitsuba.scene import planning
    from sarmitsuba.pipeline import simulate
    from sarmitsuba.scene.planning import AcquisitionWarning

    overrides = {"n_pulses": 8}
    with _warnings.catch_warnings(record=True) as caught:
        _warnings.simplefilter("always")
        sim = simulate("dihedral", sensor_overrides=overrides)
    assert sim.trace.energy_outside_window == 0.0
    assert not [w for w in caught if "fast-time window" in str(w.message)]
    planned = planning.fast_time_window
    monkeypatch.setattr(planning, "fast_time_window", lambda *a, **k: dataclasses.replace(
        planned(*a, **k), n_samples=planned(*a, **k).n_samples // 4))
    with pytest.warns(AcquisitionWarning, match="came back after the fast-time window closed"):
        sim = simulate("dihedral", sensor_overrides=overrides)
    assert sim.trace.energy_outside_window > 0


def test_window_energy_threshold():
    from sarmitsuba.scene.planning import check_window_energy
    assert check_window_energy(0.0, 1.0, 3) is None
    assert check_window_energy(0.5e-3, 1.0, 3) is None
    with pytest.warns(UserWarning, match="max_depth = 3"):
        message = check_window_energy(0.25, 0.75, 3)
    assert message.startswith("25 %")            # of the total returned energy, 0.25 / (0.25 + 0.75)


def test_automatic_spotlight_aperture_gives_integration_angle_lambda_over_two_rho():
    """Spotlight, n_pulses = 0: integration angle dtheta = lambda / (2 rho_slant), by hand:
    fc = 9.6 GHz, B = 96 MHz: rho = c / (2 B) = 1.56142 m, lambda = 0.0312284 m,
    dtheta = lambda / (2 rho) = B / fc = 0.01 rad. Altitude 1000 m, incidence 45 deg:
    R = 1000 / cos 45 = 1414.214 m, aperture dtheta R = 14.142 m, flown at v = 100 m/s with
    prf = 150 Hz: 14.142 x 150 / 100 = 21.21 pulse intervals -> ceil + 1 = 23 pulses.
    Kills lambda / (2 rho) -> lambda / (2 / rho) (0.0244 rad, 53 pulses)."""
    import numpy as np

    from sarmitsuba.scene.planning import resolve_parameters
    from sarmitsuba.core.radar import RadarParameters
    p = RadarParameters(frequency=9.6e9, bandwidth=96e6, altitude=1000.0, incidence_angle=45.0, velocity=100.0,
                        prf=150.0, mode="spotlight", n_pulses=0)
    resolved = resolve_parameters(p, np.array([-10.0, -10.0, 0.0]), np.array([10.0, 10.0, 5.0]))
    assert resolved.n_pulses == 23
    # the n - 1 = 22 pulse intervals flown, (n - 1) v / (prf R) = 0.010371 rad, cover the 0.01 rad
    # asked for, by less than one interval (v / (prf R) = 4.714e-4 rad) more
    flown = (resolved.n_pulses - 1) * 100.0 / (150.0 * 1414.214)
    assert 0.01 <= flown < 0.01 + 100.0 / (150.0 * 1414.214)


def test_scene_far_from_the_origin_inside_the_beam_does_not_warn():
    """A scene 5 km from the origin (along track and across) that the beam covers: no footprint
    warning; the same box moved 500 m along track (beam footprint about +-28 m, aperture 43 m) warns.
    Kills measuring the antennas' along-track offsets from -scene_center instead of scene_center."""
    import numpy as np

    from sarmitsuba.scene import planning
    from sarmitsuba.core.radar import RadarParameters
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.scene.trace_inputs import TraceSettings
    center = np.array([5000.0, -3000.0, 0.0])
    p = RadarParameters(scene_center=tuple(center), n_pulses=64)
    geometry = acquisition_geometry(p)
    for shift, warns in ((0.0, False), (500.0, True)):
        lo = center + np.array([shift - 5.0, -5.0, 0.0])
        hi = center + np.array([shift + 5.0, 5.0, 3.0])
        window = planning.fast_time_window(p, geometry, lo, hi, TraceSettings())
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            messages = planning.check_acquisition(p, geometry, window, lo, hi)
        footprint = [m for m in messages if "outside the beam footprint" in m]
        assert bool(footprint) == warns, (shift, messages)
        assert bool([w for w in caught if issubclass(w.category, AcquisitionWarning)]) == bool(messages)
