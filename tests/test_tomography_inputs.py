"""What ``tomography`` inverts: the elevation interval of render folders, the clutter level of a
window, and the pixels chosen by default on the guide's example scene (sarmitsuba/stacks/
tomo_products.py, tomo_pixels.py; docs/physics.md (TS2), (TS7)).

The truths are independent of the code under test: the scenes' heights from their meshes
(trimesh), ``s = h / sin(theta)`` up the iso-range circle (TS2); the mode of the log of an
exponential intensity at its mean (TS7), on speckle drawn here; and, on urban rendered with the
guide's 64 pulses, where each pixel's iso-range circle meets the geometry
(:func:`~sarmitsuba.products.elevation_truth.iso_range_heights`, ray casting: no image power).
"""
from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.pipeline import render, simulate
from sarmitsuba.products.elevation_truth import iso_range_heights
from sarmitsuba.scene import canonical
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.stacks.tomo_pixels import CLUTTER_MARGIN_DB, clutter_level, select_pixels
from sarmitsuba.stacks.tomo_products import read_stack

TOP, PIT = 2.0, -1.5          # m: the trihedral's apex height, the sunken plate's depth


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_render_folders_span_the_scene_in_elevation(tmp_path, incidence):
    """Three render folders (copies of one render: only the scene's extent counts here) give the
    elevations of the scene's bounding box, s = h / sin(theta): a trihedral reaching ``top`` m
    and a plate ``PIT`` m below the grid plane (``h sin(theta)`` fails at both angles)."""
    reflector = canonical.trihedral(0.4)
    reflector.apply_translation((0.0, 0.0, TOP))
    plate = trimesh.Trimesh(np.array([[4, -2, PIT], [8, -2, PIT], [8, 2, PIT], [4, 2, PIT]], float),
                            [[0, 1, 2], [0, 2, 3]])
    top = max(float(reflector.bounds[1][2]), 0.0)
    scene = sarmitsuba.Scene(meshes=[(reflector, "pec", "reflector"), (plate, "concrete", "plate")],
                             sensor={"incidence_angle": incidence, "altitude": 1000.0, "scene_center": "0, 0, 0",
                                     "n_pulses": 16, "prf": 250, "velocity": 100, "azimuth_beamwidth": 1.2},
                             integrator={"max_depth": 1})
    render(scene, tmp_path / "pass-0", progress=False)
    for n in (1, 2):
        shutil.copytree(tmp_path / "pass-0", tmp_path / f"pass-{n}")
    lo, hi = read_stack([tmp_path / f"pass-{n}" for n in range(3)]).interval
    sin_theta = math.sin(math.radians(incidence))
    assert lo == pytest.approx(PIT / sin_theta, abs=1e-3)
    assert hi == pytest.approx(top / sin_theta, abs=2e-3)


@pytest.mark.parametrize("mean, empty", [(1.0, 0.0), (3e-4, 0.45)])
def test_the_clutter_level_is_the_mean_of_speckle(mean, empty):
    """Fully developed speckle: intensity exponential with mean <I>; the mode of its log lies at
    <I> (TS7). 20 000 pixels of it, with a share ``empty`` of pixels 20 dB below (sidelobes where
    nothing scatters) and 1 % 40 dB above (a double-bounce line): the level within 1 dB of <I>."""
    rng = np.random.default_rng(7)
    power = mean * rng.exponential(size=20_000)
    k = int(empty * power.size)
    power[:k] = 0.01 * mean * rng.exponential(size=k)
    power[k:k + 200] = 1e4 * mean
    assert 10 * math.log10(clutter_level(power) / mean) == pytest.approx(0.0, abs=1.0)
    assert clutter_level(np.zeros(5)) == 0.0


@pytest.fixture(scope="module", params=[45.0, 35.0])
def urban(request):
    """The guide's scene at its quick stack's 64 pulses, one pass, and the geometry's truth of the
    window across the 25 m block (x = 10 to 14 m, ground range from 8 m before its layover band to
    8 m behind its front wall, y = -48 m)."""
    incidence = request.param
    overrides = {"n_pulses": 64, "incidence_angle": incidence}
    image = simulate("urban", sensor_overrides=overrides, progress=False).image
    rows = np.flatnonzero((image.azimuth > 10.0) & (image.azimuth < 14.0))
    band = 25.0 / math.tan(math.radians(incidence))
    cols = np.flatnonzero((image.range > 48.0 - band - 8.0) & (image.range < 56.0))
    truth = iso_range_heights(load_scene("urban", overrides), image, rows)[:, cols]
    return image, (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)), truth


def _chosen(image, region, min_power_db=None) -> np.ndarray:
    rows, cols = select_pixels([image], region, min_power_db)
    chosen = np.zeros((region[0].stop - region[0].start, region[1].stop - region[1].start), bool)
    chosen[rows - region[0].start, cols - region[1].start] = True
    return chosen


def test_the_default_inverts_the_facades_and_the_ground_of_the_guides_scene(urban):
    """Pixels whose circle meets the ground and the block's facade or roof (two or more heights,
    one above 1 m): 98 % inverted by default; those of the ground alone (one height, at 0), darker
    than the layover cells that set the window's clutter level: 80 % (measured 98 and 99 % for
    the former, 85 and 95 % for the latter at 45 and 35 deg). Relative to the brightest pixel
    (the wall's foot) at the former default -30 dB: under a third of either."""
    image, region, truth = urban
    count = np.isfinite(truth).sum(axis=-1)
    highest = np.max(np.where(np.isfinite(truth), truth, -np.inf), axis=-1)
    layover = (count >= 2) & (highest > 1.0)
    ground = (count == 1) & (np.abs(highest) < 0.1)
    assert layover.sum() >= 300 and ground.sum() >= 80
    chosen = _chosen(image, region)
    assert chosen[layover].mean() >= 0.98 and chosen[ground].mean() >= 0.8, (chosen[layover].mean(),
                                                                             chosen[ground].mean())
    old = _chosen(image, region, -30.0)
    assert old[layover].mean() < 0.33 and old[ground].mean() < 0.33
    assert CLUTTER_MARGIN_DB == 15.0
