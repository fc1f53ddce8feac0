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
