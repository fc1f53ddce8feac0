"""Repeat-pass interferometry end to end: two traced passes of one scene, ``track_offset`` apart,
against the closed forms of docs/physics.md (I1)-(I4).

The secondary pass flies the primary's track shifted by ``track_offset``; both are focused by
backprojection onto one ground grid (the grid ignores the offset). Images are unweighted
(``window = rect``) and not range-filtered, as (I4) assumes. Bugs these catch: a grid that
moves with the offset (the pair is refused), clutter scatterers attached to rays instead of
surfaces (coherence collapses after any change of track), the flat-earth phase left in or
removed twice (the fringe rate), a wrong baseline sign or k_z (the building's height), and a
critical baseline off by a factor (the decorrelation slope).
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.stacks import interferometry as ifm
from sarmitsuba.scene.baseline import baseline
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.loader import load_scene

SCENES = Path(__file__).parent / "scenes"
GROUND = str(SCENES / "rough_ground.xml")         # 80 m x 80 m of rough ground (gamma -10 dB)
BUILDING = str(SCENES / "insar_building.xml")     # a 60 x 60 x 30 m rough box on rough ground
HEIGHT = 30.0


def _perpendicular(source: str, sensor: dict) -> tuple[np.ndarray, float]:
    """The unit vector of a purely perpendicular baseline (I1) and the critical baseline [m]."""
    p = load_scene(source, sensor).params
    nominal = baseline(dataclasses.replace(p, track_offset=(0.0, 0.0, 0.0)))
    theta = math.radians(p.incidence_angle)
    u = np.array([0.0, math.sin(theta), math.cos(theta)])         # toward the sensor (right-looking, +y side)
    e = np.cross(u, [1.0, 0.0, 0.0])                               # (I1): the look angle grows along e
    assert baseline(dataclasses.replace(p, track_offset=tuple(e))).perpendicular == pytest.approx(1.0)
    return e, nominal.critical


def _pass(source: str, sensor: dict, offset=(0.0, 0.0, 0.0)):
    sim = simulate(source, sensor_overrides={**sensor, "track_offset": tuple(float(v) for v in offset)}, window="rect")
    return sim.image, sim.raw


def _global_coherence(a: np.ndarray, b: np.ndarray) -> float:
    """|sum a b*| / sqrt(sum |a|^2 sum |b|^2) over a region: thousands of looks, bias < 0.01."""
    return float(np.abs(np.sum(a * np.conj(b))) / np.sqrt(np.sum(np.abs(a) ** 2) * np.sum(np.abs(b) ** 2)))


def _regions(image) -> dict[str, np.ndarray]:
    """Masks of the building scene: roof free of layover, facade layover (wall, roof and ground
    mixed), open ground in front (beyond the wall's layover)."""
    az, rg = np.meshgrid(image.azimuth, image.range, indexing="ij")
    along = np.abs(az) < 20.0
    return {"roof": along & (rg > -25.0) & (rg < -5.0), "layover": along & (rg > -55.0) & (rg < -35.0),
            "ground": along & (rg > -95.0) & (rg < -70.0)}


@pytest.fixture(scope="module")
def building_primary():
    return _pass(BUILDING, {"n_pulses": 200})


def test_zero_baseline_and_along_track_shift_keep_speckle(building_primary):
    """Zero baseline: coherence 1 on ground, roof and facade layover (the same scatterers). A 5 m
    shift along the track (no perpendicular or parallel baseline) moves every ray tube relative to
    the surfaces, yet the surface-attached scatterers keep their amplitudes and phases: coherence
    >= 0.98 on the rough ground, the roof 30 m up and the facade layover."""
    image, _ = building_primary
    same, _ = _pass(BUILDING, {"n_pulses": 200})
    shifted, _ = _pass(BUILDING, {"n_pulses": 200}, (5.0, 0.0, 0.0))
    for name, mask in _regions(image).items():
        assert _global_coherence(image.data[mask], same.data[mask]) >= 0.98, name
        assert _global_coherence(image.data[mask], shifted.data[mask]) >= 0.98, name


def test_grid_is_shared_and_a_different_grid_is_refused(building_primary, tmp_path):
    """The offset pass focuses on the primary's grid; a pair on different grids is refused."""
    image, raw = building_primary
    e, _ = _perpendicular(BUILDING, {"n_pulses": 200})
    other, other_raw = _pass(BUILDING, {"n_pulses": 200}, 3.0 * e)
    ifm.check_pair(image, other, raw, other_raw)
    moved = dataclasses.replace(other, range=other.range + 0.1)
    with pytest.raises(ValueError, match="range"):
        ifm.check_pair(image, moved, raw, other_raw)


@pytest.mark.parametrize("fraction", [0.2, 0.4, 0.6])
def test_geometric_decorrelation_follows_the_critical_baseline(fraction):
    """Rough flat ground, B_perp = 0.2, 0.4, 0.6 B_crit: coherence 1 - B_perp / B_crit within 0.05
    (I4), estimated over the ground's interior (~10,000 pixels, bias well below 0.02)."""
    sensor = {"n_pulses": 256}
    e, critical = _perpendicular(GROUND, sensor)
    primary, _ = _pass(GROUND, sensor)
    secondary, _ = _pass(GROUND, sensor, fraction * critical * e)
    az, rg = np.meshgrid(primary.azimuth, primary.range, indexing="ij")
    inside = (np.abs(az) < 25.0) & (np.abs(rg) < 25.0)
    gamma = _global_coherence(primary.data[inside], secondary.data[inside])
    assert abs(gamma - (1.0 - fraction)) < 0.05, (fraction, gamma)


def test_flat_earth_fringe_rate(tmp_path):
    """The flat-earth phase restored (remove_flat_earth=False) runs across ground range at
    (4 pi / lambda) B_perp cos(theta) / R (I2') within 2 %; the focused interferogram itself
    has none left (its fringe rate is below 2 % of that)."""
    sensor = {"n_pulses": 256}
    e, critical = _perpendicular(GROUND, sensor)
    p = load_scene(GROUND, sensor).params
    b_perp = 0.2 * critical
    primary, raw1 = _pass(GROUND, sensor)
    secondary, raw2 = _pass(GROUND, sensor, b_perp * e)
    az, rg = np.meshgrid(primary.azimuth, primary.range, indexing="ij")
    inside = (np.abs(az) < 25.0) & (np.abs(rg) < 25.0)
    theta = math.radians(p.incidence_angle)
    expected = 4.0 * math.pi / p.wavelength * b_perp * math.cos(theta) / baseline(p).slant_range
    rates = np.linspace(-2.0 * expected, 2.0 * expected, 4001)
    for remove, target in ((False, expected), (True, 0.0)):
        # the fringe rate maximising |sum I1 I2* exp(-j f y)| over the interior: the interferogram's
        # mean is gamma exp(j phi(y)) under its speckle, and its periodogram peaks at d phi / d y
        # (the sum taken over each range column first: the pixels of a column share their y)
        ifg = ifm.interferogram(primary, secondary, raw1, raw2, remove_flat_earth=remove)[inside]
        y, column = np.unique(rg[inside], return_inverse=True)
        summed = np.bincount(column, ifg.real) + 1j * np.bincount(column, ifg.imag)
        power = np.abs(np.exp(-1j * np.outer(rates, y)) @ summed)
        step = rates[int(np.argmax(power))]
        assert abs(step - target) < 0.02 * expected, (remove, step, target)


def test_building_height_from_phase(building_primary, tmp_path):
    """A 30 m box with a rough roof, rendered and paired through the CLI (``render --set
    track_offset=...`` then ``interferogram``) with a height of ambiguity of 90 m: the median
    height of the roof pixels free of layover within 5 % of 30 m, the open ground in front at
    0 within the same 1.5 m."""
    from sarmitsuba.cli import main
    sensor = {"n_pulses": 200}
    e, _ = _perpendicular(BUILDING, sensor)
    p = load_scene(BUILDING, sensor).params
    b_perp = p.wavelength * baseline(p).slant_range * math.sin(math.radians(p.incidence_angle)) / (2 * 90.0)
    offset = ",".join(f"{v:.9f}" for v in b_perp * e)
    for name, extra in (("primary", []), ("secondary", ["--set", f"track_offset={offset}"])):
        assert main(["render", BUILDING, "--out", str(tmp_path / name), "--no-progress", "--pulses", "200",
                     "--window", "rect", *extra]) == 0
    assert main(["interferogram", str(tmp_path / "primary"), str(tmp_path / "secondary"),
                 "--out", str(tmp_path / "pair"), "--looks", "9,9"]) == 0
    names = {f.name for f in (tmp_path / "pair").iterdir()}
    assert {"interferogram.npz", "coherence.npz", "height.npz", "interferogram.png"} <= names
    with np.load(tmp_path / "pair" / "height.npz") as f:
        heights = f["height"]
    regions = _regions(building_primary[0])
    assert abs(np.median(heights[regions["roof"]]) - HEIGHT) < 0.05 * HEIGHT
    assert abs(np.median(heights[regions["ground"]])) < 0.05 * HEIGHT
