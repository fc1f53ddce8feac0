"""Trajectories through the scene loader and the raw data (docs/physics.md (J1)-(J4)).

- A straight track given as state vectors reproduces the built-in straight track's raw data
  (issue 30 acceptance: <= -50 dB NRMSE), at a heading of 30 deg.
- State vectors set the platform parameters from the mid-aperture state, worked out by hand:
  antenna 800 m above and 600 m beside the scene centre gives 36.87 deg incidence.
- A trajectory file named in a scene is read relative to the scene's folder.
- RawData keep the receive times and the nominal track through save / load, and ``on_track``
  swaps the nominal track in.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from sarmitsuba.core.radar import ParameterError
from sarmitsuba.core.raw import RawData, RawDataError
from sarmitsuba.core.trajectory import StateVectors
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.scene.planning import AcquisitionWarning


def _write_track(path, times, positions, velocities=None):
    header = "time_s,x_m,y_m,z_m" + (",vx_mps,vy_mps,vz_mps" if velocities is not None else "")
    rows = [header]
    for i, t in enumerate(times):
        values = [t, *positions[i]] + ([] if velocities is None else list(velocities[i]))
        rows.append(",".join(repr(float(v)) for v in values))
    path.write_text("\n".join(rows) + "\n")


def test_straight_state_vectors_reproduce_the_built_in_track(tmp_path):
    over = {"heading": 30.0}
    built_in = simulate("trihedral", sensor_overrides=over, focuser="bp", image_size=(8, 8))
    raw = built_in.raw
    n = raw.n_pulses
    span = (n - 1) / raw.prf
    times = np.linspace(-span / 2, span / 2, 9)                 # 9 samples over the track
    mid = 0.5 * (raw.tx_position[0] + raw.tx_position[-1])
    _write_track(tmp_path / "line.csv", times, mid + np.outer(times, raw.velocity[0]))
    given = simulate("trihedral", sensor_overrides={**over, "trajectory": str(tmp_path / "line.csv")}, focuser="bp",
                     image_size=(8, 8))
    assert given.raw.n_pulses == n and np.abs(given.raw.pulse_time - raw.pulse_time).max() < 1e-12
    assert np.abs(given.raw.tx_position - raw.tx_position).max() < 1e-9
    assert np.abs(given.raw.rx_position - raw.rx_position).max() < 1e-9
    error = np.sum(np.abs(given.raw.data - raw.data) ** 2) / np.sum(np.abs(raw.data) ** 2)
    assert 10 * math.log10(max(error, 1e-30)) <= -50.0
    assert given.raw.metadata["radar"]["trajectory"] == "line.csv"          # a name, not the path


def test_state_vectors_set_the_platform_parameters(tmp_path):
    """Mid-aperture antenna 600 m from the scene centre (10, 20, 5) toward heading 30 deg's left
    (so looking right), 800 m above it, flying 50 m/s along 30 deg: incidence atan(600 / 800)."""
    heading = math.radians(30.0)
    track = np.array([math.cos(heading), math.sin(heading), 0.0])
    left = np.array([-math.sin(heading), math.cos(heading), 0.0])
    centre = np.array([10.0, 20.0, 5.0])
    times = np.arange(0.0, 10.01, 0.5)
    positions = centre + 600.0 * left + [0, 0, 800.0] + np.outer(times - 5.0, 50.0 * track)
    _write_track(tmp_path / "drone.csv", times, positions)
    xml = tmp_path / "scene.xml"
    xml.write_text("""<scene version="3.0.0">
        <sensor type="sar"><string name="scene_center" value="10, 20, 5"/><float name="prf" value="20"/>
            <float name="altitude" value="1000"/><string name="trajectory" value="drone.csv"/></sensor>
        <bsdf type="radar" id="m"><string name="model" value="pec"/></bsdf>
        <shape type="rectangle"><transform name="to_world"><scale x="2" y="2"/><translate x="10" y="20" z="5"/>
        </transform><ref id="m"/></shape></scene>""")
    with pytest.warns(AcquisitionWarning, match=r"altitude 1000 -> 800"):
        loaded = load_scene(str(xml))                               # read next to the scene file
    p = loaded.params
    assert isinstance(p.trajectory, StateVectors) and p.trajectory.source == "drone.csv"
    assert math.isclose(p.altitude, 800.0) and math.isclose(p.incidence_angle, math.degrees(math.atan2(600, 800)))
    assert math.isclose(p.velocity, 50.0) and math.isclose(p.heading, 30.0) and p.look_side == "right"
    assert p.n_pulses == 201                                        # 10 s at 20 Hz, both ends
    with pytest.raises(ParameterError, match="drone.csv"):          # an override is read from the working folder
        load_scene(str(xml), sensor_overrides={"trajectory": "drone.csv"})


def test_a_circle_smaller_than_the_scene_is_refused(tmp_path):
    """A circle of radius H tan(theta) = 10 m about a 30 m plane passes over it."""
    xml = tmp_path / "wide.xml"
    xml.write_text("""<scene version="3.0.0"><sensor type="sar"><string name="scene_center" value="0, 0, 0"/>
        <string name="trajectory" value="circular"/><float name="altitude" value="10"/>
        <float name="incidence_angle" value="45"/></sensor>
        <bsdf type="radar" id="m"><string name="model" value="pec"/></bsdf>
        <shape type="rectangle"><transform name="to_world"><scale x="15" y="15"/></transform><ref id="m"/></shape>
        </scene>""")
    with pytest.raises(ParameterError, match="passes over the scene.*radius is the ground range 10.0 m"):
        load_scene(str(xml))


def _raw(n=6, nominal=True):
    rng = np.random.default_rng(3)
    tx = rng.normal(size=(n, 3)) + [0, 0, 1000.0]
    extra = dict(nominal_tx_position=tx + 0.01, nominal_rx_position=tx + 0.02, nominal_velocity=np.ones((n, 3))) \
        if nominal else {}
    return RawData(data=(rng.normal(size=(n, 8)) + 1j).astype(np.complex64), fast_time=1e-5 + np.arange(8) / 1e8,
                   pulse_time=np.arange(n) / 100.0, tx_position=tx, rx_position=tx + [0.001, 0, 0],
                   velocity=np.tile([100.0, 0, 0], (n, 1)), fc=9.6e9, bandwidth=1e8, chirp_rate=1e13,
                   pulse_length=1e-5, fs=1e8, prf=100.0, rx_time=np.arange(n) / 100.0 + 1e-5, **extra)


def test_raw_data_keep_receive_times_and_the_nominal_track(tmp_path):
    raw = _raw()
    back = RawData.load(raw.save(tmp_path / "raw.npz"))
    for name in ("rx_time", "nominal_tx_position", "nominal_rx_position", "nominal_velocity"):
        assert np.array_equal(getattr(back, name), getattr(raw, name)), name
    nominal = back.on_track("nominal")
    assert np.array_equal(nominal.tx_position, raw.nominal_tx_position)
    assert np.array_equal(nominal.rx_position, raw.nominal_rx_position)
    assert np.array_equal(nominal.velocity, raw.nominal_velocity) and nominal.metadata["track"] == "nominal"
    assert back.on_track("true") is back
    with pytest.raises(RawDataError, match="no nominal track"):
        _raw(nominal=False).on_track("nominal")
    with pytest.raises(RawDataError, match="valid values"):
        back.on_track("nominl")
    with pytest.raises(RawDataError, match="together"):
        RawData(**{**_raw().__dict__, "nominal_velocity": None})
    with pytest.raises(RawDataError, match="rx_time"):
        RawData(**{**_raw().__dict__, "rx_time": np.zeros(3)})


def test_stop_and_hop_and_motion_error_reach_the_raw_data():
    """The default render receives each echo v tau further along (0.94 mm at 100 m/s and 1.41 km);
    stop_and_hop keeps tx = rx; a motion error keeps the nominal track beside the true one."""
    sim = simulate("trihedral", sensor_overrides={"n_pulses": 16, "motion_error": "0.02, 10"}, focuser="bp",
                   image_size=(8, 8))
    raw = sim.raw
    tau = raw.rx_time - raw.pulse_time
    assert np.allclose(tau, 2 * 1000 / math.cos(math.radians(45)) / 299_792_458.0, rtol=1e-3)
    assert np.allclose(np.linalg.norm(raw.rx_position - raw.tx_position, axis=1), 100.0 * tau, rtol=0.01)
    assert raw.has_nominal_track and np.abs(raw.nominal_tx_position - raw.tx_position).max() > 0.005
    with warnings.catch_warnings():
        flat = simulate("trihedral", sensor_overrides={"n_pulses": 16, "stop_and_hop": True}, focuser="bp",
                        image_size=(8, 8)).raw
    assert flat.rx_time is None and np.array_equal(flat.rx_position, flat.tx_position) and not flat.has_nominal_track
