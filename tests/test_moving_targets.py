"""Moving shapes against the closed forms of a moving point target (docs/physics.md (V1)-(V3)).

A lone trihedral, imaged in spotlight mode at L band from a short range (the target lit through
the whole aperture, its Doppler shift well inside the PRF) and focused by direct backprojection
with a rectangular window:

- a radial velocity ``v_r`` (range rate, positive away from the radar) displaces its image
  along track by ``-R v_r / V`` (Raney, "Synthetic aperture imaging radar and moving targets",
  IEEE TAES 7(3), 1971; Cumming & Wong, *Digital Processing of SAR Data*, 2005, sec. 4.4);
- an along-track velocity ``v_a`` changes its azimuth FM rate from ``2 V^2 / (lambda R)`` to
  ``2 (V - v_a)^2 / (lambda R)``: the stationary matched filter leaves the quadratic phase
  ``pi dK t^2`` across the aperture, and the impulse response is the Fresnel integral of it,
  evaluated here by quadrature (not by the simulator);
- at 800 km the wave's transmit leg takes 2.7 ms, in which a target at 20 m/s moves 5 cm: the
  echo's phase follows the target where the wave meets it, not where it stood when the pulse
  left (no stop-and-hop for the target).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.pipeline import simulate

REPO = Path(__file__).resolve().parent.parent
TRIHEDRAL = REPO / "scenes" / "trihedral.xml"
#: L band, 200 m/s at 350 m altitude and 45 deg incidence, spotlight on the trihedral: 300 pulses
#: at 1 kHz (a 59.8 m aperture, azimuth resolution lambda R / (2 L) = 0.99 m).
SENSOR = dict(frequency=1.25e9, bandwidth=150e6, sampling_rate=180e6, prf=1000.0, velocity=200.0, altitude=350.0,
              incidence_angle=45.0, mode="spotlight", n_pulses=300)
R0 = SENSOR["altitude"] / math.cos(math.radians(SENSOR["incidence_angle"]))        # closest slant range, m
WAVELENGTH = SPEED_OF_LIGHT / SENSOR["frequency"]
APERTURE_TIME = (SENSOR["n_pulses"] - 1) / SENSOR["prf"]
AZIMUTH_CELL = WAVELENGTH * R0 / (2.0 * SENSOR["velocity"] * APERTURE_TIME)
#: From the sensor toward the trihedral at mid-aperture (the sensor flies +x on the +y side).
LOOK = np.array([0.0, -math.sin(math.radians(45.0)), -math.cos(math.radians(45.0))])


def moving_trihedral(tmp_path: Path, velocity) -> Path:
    """The built-in trihedral scene with a velocity [m/s] on its shape, as XML in ``tmp_path``."""
    text = TRIHEDRAL.read_text().replace('value="meshes/', f'value="{REPO / "scenes"}/meshes/')
    v = ", ".join(repr(float(c)) for c in velocity)
    text = text.replace('<ref id="metal"/>', f'<ref id="metal"/>\n        <vector name="velocity" value="{v}"/>')
    path = tmp_path / f"trihedral_{abs(hash(v))}.xml"
    path.write_text(text)
    return path


def _peak(image):
    """(row, column) of the image's peak and its azimuth [m], refined by a parabola through the
    peak's row and its two neighbours."""
    a = np.abs(image.data)
    i, j = np.unravel_index(np.argmax(a), a.shape)
    y0, y1, y2 = a[i - 1, j], a[i, j], a[i + 1, j]
    step = image.azimuth[1] - image.azimuth[0]
    return i, j, image.azimuth[i] + 0.5 * (y0 - y2) / (y0 - 2.0 * y1 + y2) * step


@pytest.mark.parametrize("v_r", [5.0, 10.0, 20.0])
def test_a_radial_velocity_displaces_the_image_along_track_by_minus_r_vr_over_v(tmp_path, v_r):
    """Receding at ``v_r`` (along the line of sight): imaged ``-R v_r / V`` along track (backward
    for a receding target), within 0.1 of an azimuth cell (0.99 m). The sign of ``v_r`` flipped
    puts it 25-100 m on the other side; the target traced where it stood at mid-aperture, at 0."""
    shift = -R0 * v_r / SENSOR["velocity"]
    rows = int(2 * abs(shift) / 0.25) + 96
    sim = simulate(str(moving_trihedral(tmp_path, v_r * LOOK)), sensor_overrides=SENSOR, focuser="bp",
                   image_size=(rows, 32), image_spacing=0.25, window="rect")
    assert np.allclose(sim.image.azimuth_direction, [1.0, 0.0, 0.0])          # the flight direction
    _, _, azimuth = _peak(sim.image)
    assert abs(azimuth - shift) < 0.1 * AZIMUTH_CELL, (azimuth, shift)


def _fresnel_irw(v_a: float) -> float:
    """3 dB width [m] of the Fresnel integral ``|int exp(j pi dK t^2 + j 2 pi K x t / V) dt|^2``
    over the aperture (Cumming & Wong sec. 4.4), by quadrature on a fine grid."""
    v = SENSOR["velocity"]
    k = 2.0 * v ** 2 / (WAVELENGTH * R0)
    dk = 2.0 * ((v - v_a) ** 2 - v ** 2) / (WAVELENGTH * R0)
    t = np.linspace(-APERTURE_TIME / 2, APERTURE_TIME / 2, 3001)
    x = np.linspace(-8.0, 8.0, 8001)
    power = np.abs(np.exp(1j * np.pi * dk * t[None] ** 2 + 2j * np.pi * k * (x[:, None] / v) * t[None]).sum(axis=1)) ** 2
    return _width(power, x)


def _width(power: np.ndarray, x: np.ndarray) -> float:
    """3 dB width of the main lobe of ``power`` sampled at ``x``, by linear interpolation."""
    i = int(np.argmax(power))
    half = power[i] / 2.0
    left, right = i, i
    while power[left] > half:
        left -= 1
    while power[right] > half:
        right += 1
    x_left = np.interp(half, [power[left], power[left + 1]], [x[left], x[left + 1]])
    x_right = np.interp(half, [power[right], power[right - 1]], [x[right], x[right - 1]])
    return float(x_right - x_left)


@pytest.mark.parametrize("v_a", [0.0, 5.0, -6.0])
def test_an_along_track_velocity_broadens_the_irw_as_the_fresnel_integral_predicts(tmp_path, v_a):
    """The azimuth IRW within 5 % of the Fresnel integral's: 0.88 m still, 1.05 m at 5 m/s with the
    platform, 1.40 m at 6 m/s against it (quadratic phases of -2.3 and 2.9 rad at the aperture's
    ends; beyond about pi the main lobe splits and a 3 dB width means little). The velocity's
    sign reversed swaps 1.05 and 1.07 m only, so the displacement test above carries the sign."""
    sim = simulate(str(moving_trihedral(tmp_path, (v_a, 0.0, 0.0))), sensor_overrides=SENSOR, focuser="bp",
                   image_size=(320, 24), image_spacing=0.05, window="rect")
    i, j, _ = _peak(sim.image)
    measured = _width(np.abs(sim.image.data[:, j]) ** 2, sim.image.azimuth)
    expected = _fresnel_irw(v_a)
    assert abs(measured / expected - 1.0) < 0.05, (measured, expected)
    if v_a == -6.0:
        assert expected > 1.5 * _fresnel_irw(0.0)                              # the case really defocuses


def test_the_echo_follows_the_target_where_the_wave_meets_it(tmp_path):
    """At 800 km slant range (X band, 3 pulses at 250 Hz), a trihedral receding at 20 m/s: each
    pulse's range-compressed phase at the echo's peak, against the still trihedral's, is
    ``-k dL``, ``dL`` the two-way length to the apex at ``v (t_p + R_p / c)`` (the wave's transmit
    leg 2.7 ms long) less that to the still apex. Stop-and-hop for the target (``v t_p``) is
    21.5 rad off at the middle pulse; the target's motion within a sub-aperture dropped, 32 rad
    off at the outer pulses."""
    slant = 800e3
    overrides = {"altitude": slant * math.cos(math.pi / 4), "n_pulses": 3}
    v = 20.0 * LOOK
    still = simulate("trihedral", sensor_overrides=overrides)
    moving = simulate(str(moving_trihedral(tmp_path, v)), sensor_overrides=overrides)
    raw = still.raw
    k = 2.0 * math.pi * raw.fc / SPEED_OF_LIGHT
    times = raw.pulse_time - 0.5 * (raw.pulse_time[0] + raw.pulse_time[-1])      # from mid-aperture
    assert np.allclose(times, [-1 / 250.0, 0.0, 1 / 250.0])
    for p in range(3):
        sample = int(np.argmax(np.abs(raw.data[p])))
        measured = np.angle(moving.raw.data[p, sample] / raw.data[p, sample])
        tx, rx = raw.tx_position[p], raw.rx_position[p]
        hit = v * (times[p] + np.linalg.norm(tx) / SPEED_OF_LIGHT)           # the apex is at the origin
        d_length = (np.linalg.norm(hit - tx) + np.linalg.norm(hit - rx)) - (np.linalg.norm(tx) + np.linalg.norm(rx))
        expected = np.angle(np.exp(-1j * k * d_length))
        assert abs(np.angle(np.exp(1j * (measured - expected)))) < 0.05, (p, measured, expected, k * d_length)


@pytest.mark.parametrize("v_r", [1.0, -3.0])
def test_along_track_interferometry_phase_and_dpca_of_a_moving_trihedral(tmp_path, v_r):
    """Two phase centres 2 m apart along track (``ati_baseline``): at the trihedral's peak the
    interferogram ``I_fore I_aft*`` has the phase ``4 pi v_r d / (lambda V)`` (30 and -90 deg here)
    within 2 deg, from which ``radial_velocity`` reads the target's own ``v_r`` back within 0.1 m/s
    (caught: its ``4 pi`` as ``2 pi``, twice the speed), and the DPCA image ``I_fore - I_aft`` keeps ``2 |sin(phi / 2)|`` of the fore
    channel's amplitude (-5.7 and +3.0 dB) within 1 dB. The aft channel placed ahead instead of
    behind flips the phase's sign."""
    from sarmitsuba.stacks.along_track import ati_interferogram, ati_phase, dpca_image, radial_velocity
    d = 2.0
    shift = -R0 * v_r / SENSOR["velocity"]
    sim = simulate(str(moving_trihedral(tmp_path, v_r * LOOK)), sensor_overrides={**SENSOR, "ati_baseline": d},
                   focuser="bp", image_size=(int(2 * abs(shift) / 0.25) + 96, 32), image_spacing=0.25, window="rect")
    i, j, _ = _peak(sim.image)
    expected = 4.0 * math.pi * v_r * d / (WAVELENGTH * SENSOR["velocity"])
    assert ati_phase(v_r, WAVELENGTH, SENSOR["velocity"], d) == pytest.approx(expected)
    measured = np.angle(ati_interferogram(sim.image, sim.aft.image)[i, j])
    assert abs(math.degrees(measured - expected)) < 2.0, (math.degrees(measured), math.degrees(expected))
    assert radial_velocity(measured, WAVELENGTH, SENSOR["velocity"], d) == pytest.approx(v_r, abs=0.1)  # the truth
    ratio = np.abs(dpca_image(sim.image, sim.aft.image)[i, j]) / np.abs(sim.image.data[i, j])
    assert abs(20 * math.log10(ratio / (2 * abs(math.sin(expected / 2))))) < 1.0


def test_displaced_phase_centres_cancel_the_still_clutter_of_urban():
    """urban with ``ati_baseline = 2`` m: the DPCA image holds at least 20 dB less energy than the
    fore image (measured 35.6 dB), and the interferogram's phase is near zero where the image is
    bright (its still buildings, wall and ground)."""
    from sarmitsuba.stacks.along_track import ati_interferogram, dpca_image
    sim = simulate("urban", sensor_overrides={"ati_baseline": 2.0})
    fore = np.sum(np.abs(sim.image.data) ** 2)
    assert 10 * np.log10(np.sum(np.abs(dpca_image(sim.image, sim.aft.image)) ** 2) / fore) < -20.0
    bright = np.abs(sim.image.data) > 0.1 * np.abs(sim.image.data).max()
    phase = np.angle(ati_interferogram(sim.image, sim.aft.image)[bright])
    assert np.percentile(np.abs(phase), 95) < math.radians(10.0)
    assert np.array_equal(sim.aft.raw.pulse_time, sim.raw.pulse_time)
    along = (sim.raw.tx_position - sim.aft.raw.tx_position) @ np.array([1.0, 0.0, 0.0])
    assert np.allclose(along, 2.0)                                       # the aft channel trails by d


def test_a_radial_velocity_walks_the_echo_through_range_cells(tmp_path):
    """Receding at 20 m/s for the 0.3 s aperture: the range-compressed echo's peak walks 6 m, six
    range cells (c / 2B = 1 m); each pulse's peak (interpolated 32 times) lies, against
    the still trihedral's, where the two-way length to the apex at ``v (t_p + R_p / c)`` puts it
    (within 5 % of a range cell). The velocity applied at mid-aperture only walks nothing."""
    v = 20.0 * LOOK
    still = simulate("trihedral", sensor_overrides=SENSOR, focuser="bp", image_size=(16, 16))
    moving = simulate(str(moving_trihedral(tmp_path, v)), sensor_overrides=SENSOR, focuser="bp", image_size=(16, 16))
    raw = still.raw
    times = raw.pulse_time - 0.5 * (raw.pulse_time[0] + raw.pulse_time[-1])

    def peak(data, p, up=32):
        """The two-way length [m] at pulse ``p``'s peak, the band-limited samples interpolated
        ``up`` times by zero-padding their spectrum (each raw data set has its own window)."""
        n = data.data.shape[1]
        spectrum = np.fft.fftshift(np.fft.fft(data.data[p]))
        padded = np.zeros(n * up, complex)
        padded[(n * up - n) // 2:(n * up - n) // 2 + n] = spectrum
        k = int(np.argmax(np.abs(np.fft.ifft(np.fft.ifftshift(padded)))))
        return SPEED_OF_LIGHT * (data.fast_time[0] + k / up * (data.fast_time[1] - data.fast_time[0]))

    walked = np.array([peak(moving.raw, p) - peak(raw, p) for p in range(0, len(times), 25)])
    expected = []
    for p in range(0, len(times), 25):
        tx, rx = raw.tx_position[p], raw.rx_position[p]
        hit = v * (times[p] + np.linalg.norm(tx) / SPEED_OF_LIGHT)
        expected.append(np.linalg.norm(hit - tx) + np.linalg.norm(hit - rx) - np.linalg.norm(tx) - np.linalg.norm(rx))
    expected = np.array(expected)
    cell = SPEED_OF_LIGHT / (2 * SENSOR["bandwidth"])
    assert np.ptp(expected) / 2 > 5 * cell                                  # the walk spans cells (one way)
    assert np.max(np.abs(walked - expected)) < 0.05 * 2 * cell, np.max(np.abs(walked - expected))


@pytest.mark.parametrize("w", [60.0, -90.0])
def test_a_turning_trihedral_is_displaced_by_its_apex_radial_velocity(tmp_path, w):
    """The trihedral turning at ``w`` deg/s about the x axis through the middle of its box
    (``angular_velocity``): its apex, the triple bounce's phase centre, moves at ``w x (apex -
    centre)``, whose range rate (-0.25 and +0.38 m/s) displaces the image by ``-R v_r / V``
    (+0.63 and -0.94 m) within 0.1 of an azimuth cell. The rotation left out, or taken about the
    apex, leaves the image in place."""
    text = TRIHEDRAL.read_text().replace('value="meshes/', f'value="{REPO / "scenes"}/meshes/')
    path = tmp_path / "turning.xml"
    path.write_text(text.replace('<ref id="metal"/>',
                                 f'<ref id="metal"/>\n        <vector name="angular_velocity" value="{w}, 0, 0"/>'))
    from sarmitsuba.scene.loader import load_scene
    loaded = load_scene(str(path), SENSOR)
    box = loaded.shape_boxes[loaded.motion.shapes[0]]
    centre = 0.5 * (box[0] + box[1])                       # the trihedral's apex is at the origin
    v_apex = np.cross(np.radians([w, 0.0, 0.0]), -centre)
    shift = -R0 * float(v_apex @ LOOK) / SENSOR["velocity"]
    assert abs(shift) > 0.5 * AZIMUTH_CELL
    sim = simulate(str(path), sensor_overrides=SENSOR, focuser="bp", image_size=(int(2 * abs(shift) / 0.25) + 96, 32),
                   image_spacing=0.25, window="rect")
    _, _, azimuth = _peak(sim.image)
    assert abs(azimuth - shift) < 0.1 * AZIMUTH_CELL, (azimuth, shift)


def test_an_ati_baseline_no_shorter_than_the_track_is_refused_before_tracing():
    """The sensor above flies (300 - 1) / 1 kHz x 200 m/s = 59.8 m: a trailing channel 60 m
    behind shares no stretch of track with the leading one (its echoes miss the window or the
    beam: an empty aft channel, a phase of 0 and a DPCA image equal to the fore image), so it is
    refused before any tracing, naming the parameter and the track's length; 59 m is accepted."""
    from sarmitsuba.core.radar import ParameterError
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.scene.loader import load_scene
    from sarmitsuba.scene.planning import check_ati_baseline
    with pytest.raises(ParameterError, match=r"ati_baseline = 60 m .*\(59.8 m\)"):
        simulate("trihedral", sensor_overrides={**SENSOR, "ati_baseline": 60.0})
    params = load_scene("trihedral", {**SENSOR, "ati_baseline": 59.0}).params
    check_ati_baseline(params, acquisition_geometry(params))


def test_ati_products_refuse_images_on_different_grids():
    """The interferogram and the DPCA image of an image and its copy 0.7 rad later: the phase
    0.7 rad (not its negative: the fore channel times the aft's conjugate) and ``I (1 - e^{-0.7 j})``;
    of two images whose grids differ by a metre: refused, naming the grid (a pixel-by-pixel
    product of different places would look like motion)."""
    import dataclasses
    from sarmitsuba.stacks.along_track import ati_interferogram, dpca_image
    from sarmitsuba.stacks.interferometry import InterferometryError
    image = simulate("trihedral", sensor_overrides={"n_pulses": 16}, image_size=(16, 16)).image
    moved = dataclasses.replace(image, origin=image.origin + np.array([1.0, 0.0, 0.0]))
    late = dataclasses.replace(image, data=(image.data * np.exp(-0.7j)).astype(np.complex64))   # 0.7 rad behind
    lit = np.abs(image.data) > 0
    assert lit.sum() > 100
    assert np.allclose(np.angle(ati_interferogram(image, late)[lit]), 0.7, atol=1e-5)   # I_fore I_aft* = |I|^2 e^{0.7j}
    assert np.allclose(dpca_image(image, late), image.data * (1.0 - np.exp(-0.7j)), atol=1e-5 * np.abs(image.data).max())
    for product in (ati_interferogram, dpca_image):
        with pytest.raises(InterferometryError, match="origin"):
            product(image, moved)
