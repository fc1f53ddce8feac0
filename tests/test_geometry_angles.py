"""End-to-end geometry at 30 and 60 degrees incidence (docs/physics.md (G1)-(G2)).

At 45 degrees sin = cos and tan = 1 / tan, so a code that swaps them renders the same scene;
every check here is made at 30 and at 60 degrees, where each swap moves the answer by several
resolution cells (the size is stated at each assertion). Traced scenes: PEC trihedrals
(edge 1 m) tilted so that their boresight points at the mid-aperture sensor, flown at altitude
H = 1000 m on a straight track along +x, looking right (the sensor on the +y side, ground
range increasing towards -y); no ground, so each trihedral's triple bounce is a clean point
at its apex. Closed forms, written out here:

* a point on the ground images at its own (azimuth, ground range);
* a point at height h images displaced towards the sensor by the layover h / tan(theta_i)
  (first order in h / R; the exact form sqrt(Y0^2 - 2 H h + h^2) - Y0 for a point above
  the scene centre, Y0 = H tan(theta_i), equates the slant ranges sqrt((H - h)^2 + Y0^2) and
  sqrt(H^2 + (Y0 + g)^2) of the point and of its image g on the ground);
* the closest-approach slant range to the scene centre is H / cos(theta_look) (flat earth:
  look angle = incidence angle), read from the echo delay c t / 2 of the raw data.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (variant and plugins)
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.pipeline import simulate

C = 299_792_458.0
ALTITUDE = 1000.0                                  # m above the scene centre
MESH = Path(__file__).parents[1] / "scenes" / "meshes" / "trihedral.obj"
#: The mesh's symmetry axis (0, sqrt 2, 1) / sqrt 3 rises atan(1 / sqrt 2) = 35.26 deg.
MESH_ELEVATION = math.degrees(math.atan(1.0 / math.sqrt(2.0)))
GROUND_TARGET = (-12.0, 15.0)                      # azimuth, ground range [m], on the ground
RAISED_TARGET = (12.0, 10.0)                       # azimuth [m], height h [m] above the scene centre


def _scene(folder: Path, incidence: float, targets: list[tuple[float, float, float]]) -> str:
    """A scene file of PEC trihedrals with apexes at ``targets`` (world x, y, z [m]), each tilted
    to look up at the sensor's elevation ``90 - incidence`` deg, sensed at ``incidence``."""
    tilt = (90.0 - incidence) - MESH_ELEVATION
    shapes = "".join(
        f'<shape type="obj" id="corner{i}"><string name="filename" value="{MESH}"/>'
        f'<boolean name="face_normals" value="true"/><transform name="to_world">'
        f'<rotate x="1" angle="{tilt!r}"/><translate x="{x!r}" y="{y!r}" z="{z!r}"/></transform>'
        f'<ref id="metal"/></shape>' for i, (x, y, z) in enumerate(targets))
    path = folder / f"corners_{incidence:g}_{len(targets)}.xml"
    path.write_text(
        '<scene version="3.0.0"><sensor type="sar">'
        '<float name="frequency" value="9.6e9"/><float name="bandwidth" value="150e6"/>'
        '<float name="sampling_rate" value="180e6"/><float name="prf" value="250"/>'
        f'<float name="velocity" value="100"/><float name="altitude" value="{ALTITUDE!r}"/>'
        f'<float name="incidence_angle" value="{incidence!r}"/><string name="scene_center" value="0, 0, 0"/>'
        '<float name="azimuth_beamwidth" value="1.2"/></sensor>'
        '<integrator type="sbr"><integer name="max_depth" value="3"/></integrator>'
        f'<bsdf type="radar" id="metal"><string name="model" value="pec"/></bsdf>{shapes}</scene>')
    return str(path)


@pytest.fixture(scope="module", params=[30.0, 60.0], ids=["30deg", "60deg"])
def corners(request, tmp_path_factory):
    """(incidence, simulation) of three trihedrals: at the scene centre, on the ground off
    centre (GROUND_TARGET), and raised above the scene centre's ground range (RAISED_TARGET).
    The sensor is on the +y side, so ground range g lies at y = -g."""
    incidence = request.param
    azimuth, ground = GROUND_TARGET
    raised_azimuth, height = RAISED_TARGET
    targets = [(0.0, 0.0, 0.0), (azimuth, -ground, 0.0), (raised_azimuth, 0.0, height)]
    return incidence, simulate(_scene(tmp_path_factory.mktemp("angles"), incidence, targets))


def _imaged(sim, azimuth: float, ground_range: float):
    """The point-target report of the peak found near image coordinates (azimuth, ground range)."""
    return analyze_point_target(sim.image, [azimuth, ground_range])


def test_ground_point_images_at_its_ground_position(corners):
    """(a) A trihedral on the ground at (az -12 m, ground range +15 m) and one at the scene centre
    image where they stand, within 0.1 ground-range cell. A slant offset projected to ground
    with cos instead of sin (15 sin / cos) would put the first at 8.66 m at 30 deg (3.2 cells
    of 2.0 m) and 25.98 m at 60 deg (9.5 cells of 1.15 m)."""
    incidence, sim = corners
    cell_az, cell_gr = sim.loaded.params.azimuth_resolution, sim.loaded.params.ground_range_resolution
    # ground resolution c / (2 B sin(theta)) at 30 / 60 deg: 1.9986 / 1.1539 m (cos: the reverse)
    assert cell_gr == pytest.approx({30.0: 1.998616, 60.0: 1.153902}[incidence], abs=1e-6)
    for azimuth, ground in ((0.0, 0.0), GROUND_TARGET):
        rep = _imaged(sim, azimuth, ground)
        assert abs(rep.azimuth - azimuth) < 0.1 * cell_az, (incidence, azimuth, rep.azimuth)
        assert abs(rep.range - ground) < 0.1 * cell_gr, (incidence, ground, rep.range)


def test_raised_point_lays_over_by_h_over_tan_incidence(corners):
    """(b) A trihedral 10 m above the scene centre images 10 / tan(theta_i) towards the sensor:
    17.32 m at 30 deg, 5.77 m at 60 deg, within 0.15 ground-range cell (the first-order form's
    own error: 0.18 m = 0.09 cell at 30 deg, 0.02 m at 60 deg), and within 0.05 cell of the
    exact form. h tan(theta_i) instead (tan and cot swapped) gives 5.77 m at 30 deg (11.5 m off:
    5.8 cells of 2.0 m) and 17.32 m at 60 deg (11.5 m off: 10 cells of 1.15 m); h / sin(theta_i)
    gives 20.0 m at 30 deg (1.3 cells off) and 11.55 m at 60 deg (5 cells off)."""
    incidence, sim = corners
    cell_az, cell_gr = sim.loaded.params.azimuth_resolution, sim.loaded.params.ground_range_resolution
    azimuth, h = RAISED_TARGET
    layover = {30.0: 17.3205, 60.0: 5.7735}[incidence]          # 10 / tan(theta_i), worked by hand
    y0 = {30.0: 577.3503, 60.0: 1732.0508}[incidence]           # H tan(theta_i)
    exact = math.sqrt(y0**2 - 2.0 * ALTITUDE * h + h**2) - y0   # -17.50 m at 30 deg, -5.75 m at 60 deg
    rep = _imaged(sim, azimuth, -layover)
    assert abs(rep.azimuth - azimuth) < 0.1 * cell_az, (incidence, rep.azimuth)
    assert abs(rep.range + layover) < 0.15 * cell_gr, (incidence, rep.range, -layover)
    assert abs(rep.range - exact) < 0.05 * cell_gr, (incidence, rep.range, exact)


def _echo_slant_range(raw, pulse: int) -> float:
    """Slant range c t / 2 [m] of the strongest echo of one range-compressed pulse, its delay t
    read at 1/32 sample from the pulse's band-limited interpolation (FFT zero padding)."""
    row = raw.data[pulse].astype(np.complex128)
    up = 32
    spectrum = np.fft.fft(row)
    n = row.size
    padded = np.zeros(n * up, complex)
    padded[:n // 2] = spectrum[:n // 2]
    padded[-(n - n // 2):] = spectrum[n // 2:]
    k = int(np.argmax(np.abs(np.fft.ifft(padded))))
    delay = raw.fast_time[0] + k / (up * raw.fs)
    return C * delay / 2.0


@pytest.mark.parametrize("incidence, expected", [(30.0, 1154.7005), (60.0, 2000.0)])
def test_slant_range_to_the_scene_centre_from_the_echo_delay(incidence, expected, tmp_path):
    """(c) One trihedral at the scene centre: its echo at the mid-aperture pulse (closest
    approach, broadside) lies at slant range H / cos(theta_look) = 1000 / 0.866025 = 1154.70 m
    at 30 deg and 1000 / 0.5 = 2000 m at 60 deg, within 0.1 slant-range cell (c / 2B = 1 m).
    H / sin (sin and cos swapped, or the sensor placed H / tan instead of H tan from the
    ground track) gives 2000 m at 30 deg and 1154.70 m at 60 deg: 845 m off at both."""
    sim = simulate(_scene(tmp_path, incidence, [(0.0, 0.0, 0.0)]), sensor_overrides={"n_pulses": 33})
    assert sim.raw.range_compressed
    measured = _echo_slant_range(sim.raw, sim.raw.n_pulses // 2)
    assert abs(measured - expected) < 0.1, (incidence, measured, expected)
