"""Physically inconsistent radar settings: warnings where the user may mean it (issue 5)."""
from __future__ import annotations

import warnings

import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.pipeline import simulate
from sarmitsuba.planning import AcquisitionWarning


def test_prf_below_doppler_bandwidth_warns_of_azimuth_ambiguities():
    with pytest.warns(AcquisitionWarning, match="below the Doppler bandwidth.*azimuth ambiguities"):
        simulate("trihedral", sensor_overrides={"prf": 80.0})


def test_prf_too_high_for_the_scene_depth_warns_of_range_ambiguities():
    # urban: ~300 m of ground range -> ~0.75 us of echo window at 45 deg; PRF 2 MHz is far above c/(2 depth)
    with pytest.warns(AcquisitionWarning, match="range ambiguities"):
        simulate("dihedral", sensor_overrides={"prf": 2e6, "n_pulses": 8})


def test_scene_outside_the_beam_warns():
    with pytest.warns(AcquisitionWarning, match="outside the beam footprint"):
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

    from sarmitsuba import planning
    from sarmitsuba.pipeline import simulate
    from sarmitsuba.planning import AcquisitionWarning

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
    from sarmitsuba.planning import check_window_energy
    assert check_window_energy(0.0, 1.0, 3) is None
    assert check_window_energy(0.5e-3, 1.0, 3) is None
    with pytest.warns(UserWarning, match="max_depth = 3"):
        message = check_window_energy(0.25, 0.75, 3)
    assert message.startswith("25 %")            # of the total returned energy, 0.25 / (0.25 + 0.75)
