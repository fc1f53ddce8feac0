"""The stack's truth: where pixels' iso-range circles meet a block and the ground (products/elevation_truth.py).

A 20 x 20 x 10 m block on a ground plate, seen from a track at altitude H flying +x with the
sensor on the +y side at incidence theta (flat earth: the track at y_s = H tan(theta)). The
closed forms, written here: pixel y_p on the ground has slant range
R_p = sqrt((y_s - y_p)^2 + H^2); its circle meets the facing wall (y = 10) at
h = H - sqrt(R_p^2 - (y_s - 10)^2) and the roof where h = 10; the roof lays over onto the band
y_p in [-10 + d, 10 + d], d = 10 / tan(theta) nearly; behind the block the ground is shadowed
over 10 tan(theta).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.core.image import SarImage
from sarmitsuba.products.elevation_truth import iso_range_heights, nearest_truth
from sarmitsuba.scene.loader import load_scene

ALTITUDE = 1000.0


def _scene(incidence: float, shift: float = 0.0, lift: float = 0.0):
    block = trimesh.creation.box((20.0, 20.0, 10.0))
    block.apply_translation((shift, 0.0, 5.0 + lift))
    ground = trimesh.Trimesh(np.array([[-45, -45, 0], [45, -45, 0], [45, 45, 0], [-45, 45, 0]], float)
                             + [shift, 0, lift], [[0, 1, 2], [0, 2, 3]])
    sensor = {"incidence_angle": incidence, "n_pulses": 16, "altitude": ALTITUDE,
              "scene_center": f"{shift}, 0, {lift}"}
    return sarmitsuba.Scene(meshes=[(block, "concrete", "block"), (ground, "concrete", "ground")], sensor=sensor)


def _image(shift: float = 0.0, lift: float = 0.0) -> SarImage:
    rg = np.arange(-40.0, 40.01, 0.5)                    # range along -y: pixel y = -range
    return SarImage(data=np.zeros((3, rg.size), np.complex64), azimuth=np.array([-1.0, 0.0, 1.0]), range=rg,
                    origin=np.array([shift, 0.0, lift]), azimuth_direction=np.array([1.0, 0.0, 0.0]),
                    range_direction=np.array([0.0, -1.0, 0.0]))


def _crossings(heights: np.ndarray, image: SarImage, y: float) -> np.ndarray:
    h = heights[1, int(np.argmin(np.abs(-image.range - y)))]
    return h[np.isfinite(h)]


@pytest.mark.parametrize("incidence, shift, lift", [(35.0, 0.0, 0.0), (55.0, 0.0, 0.0), (35.0, 4000.0, 120.0)])
def test_crossings_are_the_closed_forms(incidence, shift, lift):
    """Heights above the grid plane z0 = lift, also for a scene 4 km from the origin (traced in a
    local frame)."""
    loaded = load_scene(_scene(incidence, shift, lift))
    image = _image(shift, lift)
    heights = iso_range_heights(loaded, image)
    y_s = ALTITUDE * math.tan(math.radians(incidence))
    layover = 10.0 / math.tan(math.radians(incidence))
    for y in (10.5 + 0.4 * layover, 10.5 + 0.8 * layover):      # in front of the wall, inside the roof's layover
        y_pixel = round(y * 2) / 2
        found = _crossings(heights, image, y_pixel)
        r_p = math.hypot(y_s - y_pixel, ALTITUDE)
        wall = ALTITUDE - math.sqrt(r_p ** 2 - (y_s - 10.0) ** 2)
        assert found == pytest.approx([0.0, wall, 10.0], abs=0.01), (y_pixel, found)
    assert _crossings(heights, image, 5.0) == pytest.approx([10.0], abs=0.01)        # under the roof's layover only
    shadow = 10.0 * math.tan(math.radians(incidence))
    assert _crossings(heights, image, -10.5 - 0.5 * shadow).size == 0                 # in the block's shadow
    assert _crossings(heights, image, -12.0 - 1.2 * shadow) == pytest.approx([0.0], abs=0.01)   # open ground
    assert _crossings(heights, image, 12.0 + 1.2 * layover) == pytest.approx([0.0], abs=0.01)    # before the layover


def test_nearest_truth_picks_the_closest_crossing_and_nan_for_none():
    table = np.array([[0.0, 4.0, 10.0, np.nan], [np.nan] * 4])
    assert nearest_truth(table, np.array([6.5, 3.0]))[0] == 4.0
    assert np.isnan(nearest_truth(table, np.array([6.5, 3.0]))[1])
    assert nearest_truth(table[:1], np.array([7.5])) == pytest.approx([10.0])


def test_a_slant_image_is_refused():
    import dataclasses
    with pytest.raises(ValueError, match="ground-plane"):
        iso_range_heights(load_scene(_scene(45.0)), dataclasses.replace(_image(), plane="slant"))
