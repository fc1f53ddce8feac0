"""Bistatic acquisitions traced: a receiver on its own platform (docs/physics.md (B1)-(B4)).

Truth: a plate's position (its centre is the stationary point of the range sum ``R_t + R_r``),
physical optics' closed form of a rectangular plate at the bistatic angle, the monostatic
tracer itself where the receiver coincides with the transmitter, and walls that hide one leg.

Deliberate bugs these tests were run against (each fails one):
  * the bistatic range sum halved as a monostatic one (the return leg to the transmitter): the
    position test, by metres;
  * transmit and receive legs swapped in the visibility (the return leg's rays and shadows
    aimed at the transmitter): the wall tests;
  * the return leg's bit skipped at the first bounce, as monostatic visibility does: the wall
    hiding the receiver;
  * the receiver's shadow edges frozen within a sub-aperture (its last view taken as its
    reference): the sub-aperture test, -14 / -19 dB against its -40 dB bound;
  * the receiver's beam not steered at the scene centre: the pattern test;
  * the return leg's shadow polygon cast from the transmitter (the visibility rays still aimed
    at the receiver), or its rays alone aimed at the transmitter: the wall hiding part of the
    plate (the walls hiding all or none of it pass).
"""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.core.geometry import acquisition_geometry
from sarmitsuba.core.radar import ParameterError, RadarParameters
from sarmitsuba.core.trajectory import StateVectors
from sarmitsuba.pipeline import simulate

from test_patches import frame, rectangle

FREQUENCY = 9.6e9
WAVELENGTH = SPEED_OF_LIGHT / FREQUENCY
REPO = Path(__file__).resolve().parents[1]
#: A uniform beam: no pattern to weigh the closed forms with.
BASE = {"frequency": FREQUENCY, "bandwidth": 150e6, "incidence_angle": 45.0, "scene_center": (0.0, 0.0, 0.0),
        "beam": "uniform", "azimuth_beamwidth": 1.0}
#: Two receivers: beside the transmitter's track (14 deg) and across it, on a drone (about 60 deg).
RECEIVERS = {
    "beside": {"receiver_altitude": 1000.0, "receiver_incidence_angle": 45.0, "receiver_heading": 20.0,
               "receiver_velocity": 100.0},
    "drone": {"receiver_altitude": 300.0, "receiver_incidence_angle": 50.0, "receiver_heading": 90.0,
              "receiver_velocity": 15.0},
}


def mid_geometry(receiver: dict) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors from the scene centre toward the transmitter and the receiver, mid-aperture."""
    g = acquisition_geometry(RadarParameters.from_mapping({**BASE, "n_pulses": 3, **receiver}))
    t, r = g.positions[1], g.rx_positions[1]
    return t / np.linalg.norm(t), r / np.linalg.norm(r)


def bisector_plate(receiver: dict, side: float, turn_deg: float):
    """A PEC plate ``side`` wavelengths square whose normal is the mid-aperture bisector turned
    ``turn_deg`` toward +x: ``(mesh, e1, e2, normal)`` (``e1``, ``e2`` its half sides)."""
    t, r = mid_geometry(receiver)
    normal = (t + r) / np.linalg.norm(t + r)
    turn = math.radians(turn_deg)
    normal = math.cos(turn) * normal + math.sin(turn) * np.array([1.0, 0.0, 0.0])
    normal /= np.linalg.norm(normal)
    e1, e2 = frame(normal, 10.0)
    half = side * WAVELENGTH / 2
    return rectangle((0, 0, 0), e1 * half, e2 * half), e1 * half, e2 * half, normal


def plate_sim(receiver: dict, plate, **sensor):
    return simulate(sarmitsuba.Scene([(plate, "pec", "plate")], sensor={**BASE, **receiver, **sensor},
                                     integrator={"max_depth": 1, "diffraction": False, "polarimetry": "scalar"}))


def po_rcs(tx: np.ndarray, rx: np.ndarray, e1, e2, normal, frequency: float) -> float:
    """Physical optics' bistatic RCS [m^2] of the PEC rectangle ``+-e1 +-e2`` at the origin seen from
    ``tx`` and received at ``rx`` (m): ``sigma = 4 pi |(cos_i + cos_s) / 2 int exp(j q . r) dA|^2 /
    lambda^2``, ``q = k (t + r)`` (unit vectors toward them), ``int = A sinc(q . e1) sinc(q . e2)``
    (Knott, Shaeffer and Tuley, *Radar Cross Section*, 2nd ed., 2004, eqs. 5.37-5.39; Balanis,
    *Advanced Engineering Electromagnetics*, 2nd ed., 2012, sec. 11.3.2)."""
    t, r = tx / np.linalg.norm(tx), rx / np.linalg.norm(rx)
    k = 2.0 * math.pi * frequency / SPEED_OF_LIGHT
    q = k * (t + r)
    area = 4.0 * np.linalg.norm(e1) * np.linalg.norm(e2)
    integral = area * np.sinc(q @ e1 / math.pi) * np.sinc(q @ e2 / math.pi)
    return 4.0 * math.pi * (0.5 * (abs(t @ normal) + abs(r @ normal)) * integral) ** 2 * (frequency / SPEED_OF_LIGHT) ** 2


@pytest.mark.parametrize("name", sorted(RECEIVERS))
def test_a_plate_is_imaged_at_its_position(name):
    """The plate facing the bisector, focused by backprojection on ``R_t + R_r``: its peak within
    0.05 m of its centre (a range sum halved as a monostatic one misplaces it by metres)."""
    plate, *_ = bisector_plate(RECEIVERS[name], 4, 0.0)
    sim = plate_sim(RECEIVERS[name], plate)
    found = np.asarray(sarmitsuba.analyze(sim.image, (0, 0, 0), raw=sim.raw).world_position)
    assert np.linalg.norm(found[:2]) < 0.05, found


def _pulse_energy(sim, pulse: int) -> float:
    return float(np.sum(np.abs(sim.raw.data[pulse]) ** 2))


@pytest.mark.parametrize("name, side, turn", [("beside", 4, 20.0), ("drone", 4, 20.0), ("drone", 8, 0.0)])
def test_bistatic_rcs_of_a_plate_is_physical_optics(name, side, turn):
    """The mid pulse's echo energy of the plate (a fixed number of compressed samples per unit
    RCS, whatever the geometry) over that of a monostatic plate: within 0.5 dB of the ratio of
    their physical optics closed forms, each at its own angles, averaged over the band."""
    receiver = RECEIVERS[name]
    plate, e1, e2, normal = bisector_plate(receiver, side, turn)
    bistatic = plate_sim(receiver, plate, n_pulses=5)
    mono_plate, m1, m2, m_normal = bisector_plate({}, 4, 10.0)
    mono = plate_sim({}, mono_plate, n_pulses=5)
    frequencies = FREQUENCY + np.linspace(-0.5, 0.5, 41) * 150e6

    def closed(sim, a, b, n):
        # normalised radiometry (no transmit_power): the echo's energy is sigma, without spreading
        tx, rx = sim.raw.tx_position[2], sim.raw.rx_position[2]
        return np.mean([po_rcs(tx, rx, a, b, n, f) for f in frequencies])

    got = 10 * math.log10(_pulse_energy(bistatic, 2) / _pulse_energy(mono, 2))
    expected = 10 * math.log10(closed(bistatic, e1, e2, normal) / closed(mono, m1, m2, m_normal))
    assert got == pytest.approx(expected, abs=0.5), (got, expected)


def _wall(x0, x1, y0, y1, height):
    box = trimesh.creation.box((x1 - x0, y1 - y0, height))
    box.apply_translation((0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * height))
    return box


@pytest.mark.parametrize("hidden", ["receiver", "transmitter", None])
def test_a_wall_hides_the_leg_it_stands_in(hidden):
    """The drone receives from the -x side, the transmitter sends from +y: a wall on the -x side
    hides the plate from the receiver only, one on the +y side from the transmitter only; either
    darkens the plate's echo by more than 30 dB, and a wall beside neither leaves it as it was
    (within 1 dB)."""
    receiver = {"receiver_altitude": 300.0, "receiver_incidence_angle": 45.0, "receiver_heading": 90.0,
                "receiver_velocity": 15.0}
    plate, *_ = bisector_plate(receiver, 4, 0.0)
    plate.apply_translation((0.0, 0.0, 0.3))
    wall = {"receiver": _wall(-2.2, -2.0, -3.0, 3.0, 6.0), "transmitter": _wall(-3.0, 3.0, 2.0, 2.2, 6.0),
            None: _wall(2.0, 2.2, -6.0, -3.0, 6.0)}[hidden]
    rows = [(plate, "pec", "plate"), (wall, "concrete", "wall")]
    sensor = {**BASE, **receiver, "n_pulses": 5}
    walled = simulate(sarmitsuba.Scene(rows, sensor=sensor, integrator={"max_depth": 1, "diffraction": False, "polarimetry": "scalar"}))
    alone = plate_sim(receiver, plate, n_pulses=5)
    ratio = 10 * math.log10(_plate_energy(walled) / _plate_energy(alone))
    if hidden is None:
        assert abs(ratio) < 1.0, ratio
    else:
        assert ratio < -30.0, ratio


def _lit_share(centre, e1, e2, toward, face_x: float, top: float) -> float:
    """The share of the rectangle ``centre +- e1 +- e2`` whose ray along ``toward`` (unit) clears
    a wall whose face toward it is the plane ``x = face_x`` and whose top is at ``top`` (the ray,
    rising toward -x, is above the top there): the half-plane ``z(face_x) >= top`` in the plate's
    coordinates ``(a, b)`` (``p = centre + a e1 + b e2``), clipped exactly by shapely."""
    import shapely
    slope = toward[2] / toward[0]
    g = np.array([e1[2] - e1[0] * slope, e2[2] - e2[0] * slope])          # g . (a, b) + h >= 0
    h = centre[2] + (face_x - centre[0]) * slope - top
    unit, along = g / np.linalg.norm(g), np.array([-g[1], g[0]]) / np.linalg.norm(g)
    foot = -h / np.linalg.norm(g) * unit
    half = shapely.Polygon([foot + 10 * along, foot - 10 * along, foot - 10 * along + 10 * unit, foot + 10 * along + 10 * unit])
    square = shapely.Polygon([(-1, -1), (1, -1), (1, 1), (-1, 1)])
    return square.intersection(half).area / square.area


@pytest.mark.parametrize("share_above", [0.0, 0.03])
def test_a_wall_hiding_part_of_the_plate_leaves_its_lit_polygon(share_above):
    """The drone's wall on the -x side made lower, its top's shadow (toward the receiver) across
    the plate: through its centre, and 3 cm higher (half and 30 % of it lit from the receiver,
    the transmitter seeing all of it). Facing the bisector, the plate's physical optics is its
    lit area times a constant phase (``q`` along its normal), so its echo energy is the lit
    share squared of the plate's alone (measured -6.24 / -10.56 dB against -6.24 / -10.56): within
    0.1 dB of ``20 log10`` of the share, clipped in closed form toward each pulse's receiver
    position. The rays alone mark the plate partly lit; the exact polygon decides the share.
    Catches the return leg's shadow polygon cast from the transmitter (the rays aimed right:
    +0.01 dB), its rays aimed at the transmitter, and its bit skipped at the first bounce (the
    plate dark: -80 dB), which the walls hiding all or none of the plate let through."""
    receiver = {"receiver_altitude": 300.0, "receiver_incidence_angle": 45.0, "receiver_heading": 90.0,
                "receiver_velocity": 15.0}
    plate, e1, e2, _ = bisector_plate(receiver, 4, 0.0)
    centre = np.array([0.0, 0.0, 0.3])
    plate.apply_translation(centre)
    _, toward = mid_geometry(receiver)
    top = centre[2] + (-2.0 - centre[0]) * toward[2] / toward[0] + share_above     # through the centre, + 3 cm
    rows = [(plate, "pec", "plate"), (_wall(-2.2, -2.0, -3.0, 3.0, top), "concrete", "wall")]
    walled = simulate(sarmitsuba.Scene(rows, sensor={**BASE, **receiver, "n_pulses": 5},
                                       integrator={"max_depth": 1, "diffraction": False, "polarimetry": "scalar"}))
    alone = plate_sim(receiver, plate, n_pulses=5)
    shares = [_lit_share(centre, e1, e2, (q - centre) / np.linalg.norm(q - centre), -2.0, top)
              for q in walled.raw.rx_position]
    assert 0.2 < min(shares) and max(shares) < 0.6
    expected = 10 * math.log10(np.mean(np.square(shares)))
    got = 10 * math.log10(_plate_energy(walled) / _plate_energy(alone))
    assert got == pytest.approx(expected, abs=0.1), (got, expected)


def _plate_energy(sim) -> float:
    """The echo energy of the plate: the compressed samples within 1 m of its range sum."""
    raw = sim.raw
    lengths = np.linalg.norm(raw.tx_position, axis=1) + np.linalg.norm(raw.rx_position, axis=1)
    near = np.abs(raw.fast_time[None, :] * SPEED_OF_LIGHT - lengths[:, None]) < 1.0
    return float(np.sum(np.abs(raw.data) ** 2 * near))


def block_scene() -> list:
    box = trimesh.creation.box((8.0, 6.0, 7.0))
    box.apply_translation((1.0, -2.0, 3.5))
    ground = rectangle((0, 0, 0), (20.0, 0.0, 0.0), (0.0, 20.0, 0.0))
    return [(box, "concrete", "box"), (ground, "concrete", "ground")]


@pytest.mark.parametrize("heading, incidence", [(20.0, 45.0), (70.0, 60.0)])
def test_a_receiver_on_the_transmitters_track_renders_the_monostatic_raw_data(heading, incidence):
    """A receiver flying the transmitter's own track (stop-and-hop, so both receive where they
    transmit): the bistatic path, with its own return legs, visibility, shadows and rates,
    reproduces the monostatic raw data of a box on the ground at two bounces bit for bit (the same
    positions, the same float operations on them, sums in fixed point (D7)), at two headings and
    incidences. (Caught: the receiver's clock a nanosecond off the transmitter's, 0.1 um along
    its track, which a -60 dB bound on the data and a 1 um tolerance on the positions let
    through.)"""
    sensor = {**BASE, "n_pulses": 32, "prf": 200.0, "heading": heading, "incidence_angle": incidence,
              "stop_and_hop": True}
    same = {"receiver_altitude": 1000.0, "receiver_incidence_angle": incidence, "receiver_heading": heading,
            "receiver_velocity": 100.0}
    integrator = {"max_depth": 2}
    mono = simulate(sarmitsuba.Scene(block_scene(), sensor=sensor, integrator=integrator))
    bi = simulate(sarmitsuba.Scene(block_scene(), sensor={**sensor, **same}, integrator=integrator))
    assert np.array_equal(bi.raw.rx_position, mono.raw.rx_position)
    assert np.sum(np.abs(mono.raw.data) ** 2) > 0
    assert np.array_equal(bi.raw.data, mono.raw.data)


TRIHEDRAL = REPO / "scenes" / "trihedral.xml"
#: L band spotlight on the 1.5 m trihedral from 495 m (its retro lobe, about lambda / a = 9 deg
#: wide, holds the receivers below).
L_BAND = dict(frequency=1.25e9, bandwidth=150e6, sampling_rate=180e6, prf=1000.0, velocity=200.0, altitude=350.0,
              incidence_angle=45.0, mode="spotlight", n_pulses=300)


@pytest.mark.parametrize("offset", [(-30.0, 0.0, 0.0), (0.0, 0.0, 40.0)])
def test_a_trihedral_is_imaged_at_its_apex(offset):
    """The receiver trails the transmitter by 30 m, or flies 40 m above it (bistatic angles of 3.5
    and 3.3 deg, inside the trihedral's retro lobe ``lambda / a``): the trihedral is imaged within
    0.05 m of its apex. Its triple bounce leaves antiparallel to the incoming wave across its 1.5 m
    aperture, so at such angles the receiver sees the aperture's diffraction, whose phase centre is
    the apex (range sum ``R_t + R_r``); geometric optics' ``|T + R - 2 O|`` would need the receiver
    inside a cone ``a / R`` wide (0.2 deg), and would put it 0.3 m away. A receive leg aimed at the
    transmitter misplaces it by metres in the second case."""
    sensor = {**L_BAND, "receiver_track_offset": offset}
    sim = simulate(str(TRIHEDRAL), sensor_overrides=sensor, focuser="bp", image_size=(160, 160), image_spacing=0.1,
                   window="rect")
    found = np.asarray(sarmitsuba.analyze(sim.image, (0, 0, 0), raw=sim.raw).world_position)
    assert np.linalg.norm(found[:2]) < 0.05, found


# --------------------------------------------------------------------------- bad input
def test_a_receiver_below_the_horizon_is_refused():
    """A receiver whose state vectors run 10 m below the scene centre never sees the scene."""
    t = np.linspace(-5.0, 5.0, 11)
    below = StateVectors(t, np.stack([50.0 * t, np.full_like(t, -500.0), np.full_like(t, -10.0)], axis=1))
    params = RadarParameters.from_mapping({**BASE, "n_pulses": 16, "receiver": {"trajectory": below}})
    with pytest.raises(ParameterError, match="receiver_trajectory.*horizon"):
        acquisition_geometry(params)


def test_a_bistatic_angle_beyond_150_degrees_is_refused():
    """Transmitter and receiver facing each other across the scene at 80 deg incidence: 160 deg."""
    params = RadarParameters.from_mapping({**BASE, "incidence_angle": 80.0, "n_pulses": 16, "receiver_look_side": "left",
                                           "receiver_incidence_angle": 80.0})
    with pytest.raises(ParameterError, match="bistatic angle.*150"):
        acquisition_geometry(params)


@pytest.mark.parametrize("values, message", [
    ({"receiver_bandwidth": 1e6}, "a receiver sets only"),
    ({"receiver_altitude": -5.0}, "receiver_altitude"),
    ({"receiver_altitude": 300.0, "ati_baseline": 2.0}, "ati_baseline"),
])
def test_bad_receiver_parameters_name_the_parameter(values, message):
    with pytest.raises(ParameterError, match=message):
        RadarParameters.from_mapping({**BASE, **values})


def test_a_receiver_facing_the_transmitter_on_the_command_line_exits_with_2(tmp_path):
    """``sarmitsuba info`` on urban with the receiver across the scene: exit code 2, one message
    naming the receiver's parameters and the bistatic angle, no traceback."""
    out = subprocess.run([sys.executable, "-m", "sarmitsuba", "info", str(REPO / "scenes" / "urban.xml"),
                          "--set", "incidence_angle=80", "--set", "receiver_look_side=left",
                          "--set", "receiver_incidence_angle=80"], capture_output=True, text=True)
    assert out.returncode == 2, out.stderr
    assert "receiver_" in out.stderr and "bistatic angle" in out.stderr
    assert "Traceback" not in out.stderr


def test_info_gives_the_bistatic_angle_and_resolutions():
    """urban's transmitter at 45 deg incidence on the +y side, a drone on the -x side at 45 deg:
    unit vectors (0, 1, 1)/sqrt 2 and (-1, 0, 1)/sqrt 2, so cos(beta) = 1/2 (60 deg); their sum
    (-1, 1, 2)/sqrt 2 has the horizontal share 1/sqrt 3, and at 150 MHz the resolution along the
    bisector is c / (2 B cos 30 deg) = 1.154 m, on the ground c / (2 B cos 30 deg / sqrt 3) =
    1.999 m along (-1, 1, 0)/sqrt 2 (Willis 2005, sec. 8.1)."""
    from sarmitsuba.info import scene_info
    info = scene_info("urban", sensor_overrides={"receiver_altitude": 300.0, "receiver_heading": 90.0,
                                                 "receiver_velocity": 15.0, "n_pulses": 3})
    b = info.radar.bistatic
    c_2b = SPEED_OF_LIGHT / (2 * 150e6)
    assert b["angle_deg"] == pytest.approx(60.0, abs=0.01)
    assert b["slant_range_resolution_m"] == pytest.approx(c_2b / math.cos(math.radians(30)), rel=1e-4)
    assert b["ground_range_resolution_m"] == pytest.approx(c_2b * math.sqrt(3) / math.cos(math.radians(30)), rel=1e-3)
    assert np.allclose(b["ground_direction"], np.array([-1.0, 1.0, 0.0]) / math.sqrt(2), atol=1e-3)
    assert scene_info("urban", sensor_overrides={"n_pulses": 3}).radar.bistatic is None


def test_a_built_in_receiver_track_is_at_mid_aperture_at_the_pulses_mid_time():
    """An orbiting transmitter's pulses sit about its closest approach (hundreds of seconds into its
    state vectors); a drone's straight track is still at its own mid-aperture position then:
    ``centre - ground_range look + altitude z``, 300 m up and 300 m across at 45 deg."""
    params = RadarParameters.from_mapping({**BASE, "trajectory": "orbit", "altitude": 693e3, "n_pulses": 5,
                                           "receiver_trajectory": "straight", "receiver_altitude": 300.0,
                                           "receiver_heading": 90.0, "receiver_velocity": 15.0})
    g = acquisition_geometry(params)
    assert g.pulse_time[2] > 1.0
    assert np.allclose(g.receiver_positions[2], [-300.0, 0.0, 300.0], atol=0.05)


def test_polarisation_turns_toward_the_receivers_other_channel():
    """The drone's plate at its specular point, 60 deg across the track: each antenna's H and V are
    its own line of sight's (P1), so the transmitted V reaches the receiver partly as H. Received
    on both channels the echo's energy is the scalar closed form's, |S_VV|^2 + |S_HV|^2 =
    |S_scalar|^2 within 0.5 dB, while VV alone falls more than 3 dB below it (the sum of the
    channels is what physical optics conserves for a PEC plate at specular reflection)."""
    receiver = RECEIVERS["drone"]
    plate, *_ = bisector_plate(receiver, 4, 0.0)
    scene = sarmitsuba.Scene([(plate, "pec", "plate")], sensor={**BASE, **receiver, "n_pulses": 5, "polarization": "quad"},
                             integrator={"max_depth": 1, "diffraction": False})
    quad = simulate(scene)
    scalar = plate_sim(receiver, plate, n_pulses=5)
    energy = {name: _pulse_energy(channel, 2) for name, channel in quad.channels.items()}
    total = 10 * math.log10((energy["VV"] + energy["HV"]) / _pulse_energy(scalar, 2))
    vv = 10 * math.log10(energy["VV"] / _pulse_energy(scalar, 2))
    assert abs(total) < 0.5, (total, vv)
    assert vv < -3.0, vv


def test_sicd_of_bistatic_data_is_refused_and_nothing_is_written(tmp_path, monkeypatch):
    """SICD describes a monostatic collection here: the writer refuses bistatic data naming CPHD, and
    a render asking for it is refused before it traces (the trace is replaced by a failure) and
    leaves no folder behind (the CPHD path is tests/test_bistatic_focus.py's)."""
    from sarmitsuba import pipeline
    from sarmitsuba.formats.sicd import SicdError, write_sicd
    from sarmitsuba.pipeline import render
    plate, *_ = bisector_plate(RECEIVERS["drone"], 4, 0.0)
    sim = plate_sim(RECEIVERS["drone"], plate, n_pulses=5)
    with pytest.raises(SicdError, match="bistatic.*--cphd"):
        write_sicd(sim.image, tmp_path / "image.nitf", raw=sim.raw)
    scene = sarmitsuba.Scene([(plate, "pec", "plate")], sensor={**BASE, **RECEIVERS["drone"], "n_pulses": 5},
                             integrator={"max_depth": 1})
    def traced(*args, **kwargs):
        raise AssertionError("traced before the formats were checked")
    monkeypatch.setattr(pipeline, "trace", traced)
    with pytest.raises(ParameterError, match="--sicd.*bistatic"):
        render(scene, tmp_path / "out", formats=("sicd",), progress=False)
    assert not (tmp_path / "out").exists()


def test_the_bistatic_radar_equation_takes_each_antennas_gain():
    """Absolute radiometry: a receiver on the transmitter's track with the transmitter's 30 dBi gives
    the monostatic raw data (the spreading is R_t R_r = R^2 there); with 20 dBi, a receive gain 10 dB
    lower, every echo is 10 dB weaker (P_t G_t G_r lambda^2 sigma / ((4 pi)^3 R_t^2 R_r^2 L), Willis
    2005, eq. 4.1); an isotropic receiver (no gain given, no dimensions) 30 dB weaker."""
    sensor = {**BASE, "n_pulses": 16, "stop_and_hop": True, "transmit_power": 1000.0, "antenna_gain_db": 30.0}
    same = {"receiver_altitude": 1000.0, "receiver_incidence_angle": 45.0, "receiver_heading": 0.0,
            "receiver_velocity": 100.0}
    plate, *_ = bisector_plate({}, 4, 10.0)

    def energy(**extra):
        sim = simulate(sarmitsuba.Scene([(plate, "pec", "plate")], sensor={**sensor, **extra},
                                        integrator={"max_depth": 1, "diffraction": False}))
        return float(np.sum(np.abs(sim.raw.data) ** 2))
    mono = energy()
    assert 10 * math.log10(energy(**same, receiver_antenna_gain_db=30.0) / mono) == pytest.approx(0.0, abs=1e-3)
    assert 10 * math.log10(energy(**same, receiver_antenna_gain_db=20.0) / mono) == pytest.approx(-10.0, abs=1e-3)
    assert 10 * math.log10(energy(**same) / mono) == pytest.approx(-30.0, abs=1e-3)


@pytest.mark.parametrize("receiver", [
    {"receiver_altitude": 300.0, "receiver_heading": 20.0, "receiver_velocity": 100.0, "receiver_incidence_angle": 50.0},
    {"receiver_altitude": 400.0, "receiver_heading": 110.0, "receiver_velocity": 20.0},
])
def test_sub_apertures_with_a_receiver_agree_with_one_pulse_per_trace(receiver):
    """A box on smooth ground (everything the ground returns near it is its two shadows' edges), at
    one bounce and 8 pulses per trace: within -40 dB of tracing every pulse from its own two
    positions (measured -46 / -65 dB). The receiver's shadow edges move with the receiver within
    a sub-aperture (B2), (M8): frozen at its reference position, they lie -14 / -19 dB off."""
    from test_patches import block, sensor as patches_sensor
    rows = block()
    sensor = {**patches_sensor(20.0, prf=200.0, velocity=100.0, n_pulses=96, antenna_length=2.0), **receiver}

    def raw(per_trace):
        scene = sarmitsuba.Scene([rows[0], rows[3]], sensor=sensor,
                                 integrator={"max_depth": 1, "pulses_per_trace": per_trace, "diffraction": False})
        return simulate(scene, image_size=(64, 64)).raw.data
    one, grouped = raw(1), raw(8)
    error = 10 * math.log10(float(np.sum(np.abs(grouped - one) ** 2) / np.sum(np.abs(one) ** 2)))
    assert error < -40.0, error


def test_the_receivers_pattern_stares_at_the_scene_centre():
    """A 2 m receive aperture on the drone (flying +y on the -x side, 40 m behind the scene centre),
    its beam steered at the centre: a plate at the centre keeps its echo; the same plate 3.5 m along
    the drone's track keeps ``sinc^2(L_r (sin(phi) - sin(phi_c)) / lambda)`` of its energy, the
    one-way pattern of a uniform aperture (A) about the receiver's own along-track axis (the
    transmitter's pattern is off: ``beam = uniform``). Without the steering both plates vanish."""
    receiver = {"receiver_altitude": 300.0, "receiver_incidence_angle": 45.0, "receiver_heading": 90.0,
                "receiver_velocity": 15.0, "receiver_track_offset": (0.0, -40.0, 0.0)}
    ratios, expected = [], []
    for offset in (0.0, 3.5):
        plate, *_ = bisector_plate(receiver, 4, 0.0)
        plate.apply_translation((0.0, offset, 0.0))
        with_pattern = plate_sim(receiver, plate, n_pulses=5, receiver_antenna_length=2.0)
        without = plate_sim(receiver, plate, n_pulses=5)
        ratios.append(_pulse_energy(with_pattern, 2) / _pulse_energy(without, 2))
        rx = without.raw.rx_position[2]
        to_plate, to_centre = np.array([0.0, offset, 0.0]) - rx, -rx
        sine = to_plate[1] / np.linalg.norm(to_plate) - to_centre[1] / np.linalg.norm(to_centre)
        expected.append(np.sinc(2.0 * sine / WAVELENGTH) ** 2)
    assert expected[1] < 0.7
    assert ratios == pytest.approx(expected, rel=0.05), (ratios, expected)


@pytest.mark.parametrize("kind", ["straight", "circular", "orbit", "state vectors"])
def test_the_receiver_flies_any_trajectory_kind(kind):
    """The receiver's mid-aperture position for each trajectory kind, against where that kind puts
    a platform of its altitude and incidence at the scene centre (J1), (J2), (J7): straight and
    circular 400 m up and 400 m away horizontally at 45 deg; an orbit 700 km above the ellipsoid
    seen at 45 deg incidence, about 1.0e6 m away; state vectors (a line 2 km up, passing
    (-1000, 500, 2000) at the pulses' mid-time) where they say."""
    receiver = {"altitude": 400.0, "incidence_angle": 45.0, "velocity": 20.0, "heading": 90.0}
    if kind == "circular":
        receiver["trajectory"] = "circular"
    if kind == "orbit":
        receiver = {"trajectory": "orbit", "altitude": 700e3, "incidence_angle": 45.0}
    if kind == "state vectors":
        t = np.linspace(-10.0, 10.0, 21)
        line = np.stack([np.full_like(t, -1000.0), 500.0 + 30.0 * t, np.full_like(t, 2000.0)], axis=1)
        receiver = {"trajectory": StateVectors(t, line)}
    g = acquisition_geometry(RadarParameters.from_mapping({**BASE, "n_pulses": 5, "receiver": receiver}))
    mid = g.receiver_positions[2]
    if kind in ("straight", "circular"):
        assert np.allclose(mid, [-400.0, 0.0, 400.0], atol=0.05), mid
    elif kind == "orbit":
        incidence = math.degrees(math.acos(mid[2] / np.linalg.norm(mid)))
        assert 1.0e6 > np.linalg.norm(mid) > 9.0e5 and abs(incidence - 45.0) < 3.0, (mid, incidence)
    else:
        assert np.allclose(mid, [-1000.0, 500.0 + 30.0 * g.pulse_time[2], 2000.0], atol=1e-6), mid


def test_derivatives_of_a_bistatic_acquisition_are_refused():
    """The derivatives' tracers cut monostatic return legs: refused, naming the receiver, rather
    than derived for the wrong acquisition."""
    from sarmitsuba.derivatives import MaterialParameter, raw_derivative
    plate, *_ = bisector_plate(RECEIVERS["drone"], 4, 0.0)
    scene = sarmitsuba.Scene([(plate, "concrete", "plate")], sensor={**BASE, **RECEIVERS["drone"], "n_pulses": 5},
                             integrator={"max_depth": 1})
    with pytest.raises(ParameterError, match="bistatic"):
        raw_derivative(scene, MaterialParameter("plate", "relative_permittivity"))


@pytest.mark.parametrize("name", sorted(RECEIVERS))
def test_a_traced_plates_ground_range_width_is_the_bistatic_resolution(name):
    """The traced plate's raw data (20 pulses: the azimuth response, tens of metres, does not narrow
    the cut) backprojected every 1 cm along the horizontal bisector through it: its -3 dB width is
    0.886 c / (2 B cos(beta / 2) |b_h|) within 5 % (Willis 2005, sec. 8.1; 0.886 for the unweighted
    band). The monostatic ground resolution c / (2 B sin(theta)), 1.41 m, is 1.5 % from the aircraft
    beside's 1.44 m and 36 % from the drone's 1.92 m: the drone's case tells them apart."""
    from sarmitsuba.analysis.bistatic import bistatic_ground_range_resolution, ground_range_direction
    from sarmitsuba.focus import ImageGrid, backproject
    from test_bistatic_focus import RECT_IRW, minus_3db_width
    plate, *_ = bisector_plate(RECEIVERS[name], 4, 0.0)
    raw = plate_sim(RECEIVERS[name], plate, n_pulses=20).raw
    tx, rx, centre = raw.tx_position.mean(axis=0), raw.rx_position.mean(axis=0), np.zeros(3)
    direction = ground_range_direction(tx, rx, centre)
    offsets = np.arange(-600, 601) * 0.01
    line = ImageGrid(centre, np.cross([0.0, 0.0, 1.0], direction), direction, np.array([0.0]), offsets)
    irw, peak = minus_3db_width(offsets, backproject(raw, line).data[0])
    expected = RECT_IRW * bistatic_ground_range_resolution(150e6, tx, rx, centre)
    assert irw == pytest.approx(expected, rel=0.05), (irw, expected)
    assert abs(peak) <= 0.05


@pytest.mark.parametrize("receiver", [{}, {"receiver_antenna_length": 0.6}])
def test_a_co_located_receiver_reads_the_monostatic_trihedral_rcs(receiver):
    """The built-in trihedral (1.5 m edges, X band, stripmap with the tapered beam) received on a
    platform of its own flying where the transmitter flies (``receiver_altitude`` 1000 m, the
    transmitter's): its echoes carry the transmitter's one-way pattern alone, and the receiver
    stares at the scene centre, where its own pattern (isotropic, or a 0.6 m antenna) is 1. The
    image's peak and integrated RCS read the closed form ``4 pi a^4 / (3 lambda^2)`` within 0.2 dB
    and the monostatic render's within 0.1 dB. (Caught: the normalisation and the impulse model
    with the two-way pattern: +0.84 dB; with the normalisation alone one-way: -0.71 dB.)"""
    import math
    from sarmitsuba.analysis.point_target import analyze_point_target
    from sarmitsuba.pipeline import simulate
    mono = analyze_point_target(simulate("trihedral").image, (0.0, 0.0, 0.0))
    bi = analyze_point_target(simulate("trihedral", sensor_overrides={"receiver_altitude": 1000.0, **receiver}).image,
                              (0.0, 0.0, 0.0))
    closed_form = 10 * math.log10(4 * math.pi * 1.5 ** 4 / (3 * (299792458.0 / 9.6e9) ** 2))
    assert bi.rcs_db == pytest.approx(closed_form, abs=0.2) and bi.rcs_db == pytest.approx(mono.rcs_db, abs=0.1)
    assert 20 * math.log10(bi.peak_magnitude) == pytest.approx(closed_form, abs=0.2)
