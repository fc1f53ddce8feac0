"""The stack's truth: where pixels' iso-range circles meet a block and the ground (products/elevation_truth.py).

A 20 x 20 x 10 m block on a 90 x 90 m ground plate, seen from a track at altitude H flying +x
with the sensor on the +y side at incidence theta (flat earth: the track at y_s = H tan(theta),
the zero-Doppler antenna of every row straight abeam). The closed forms, written here from the
iso-range geometry alone: pixel y_p on the ground has slant range
R_p = sqrt((y_s - y_p)^2 + H^2); its circle meets the facing wall (y = 10) at
h = H - sqrt(R_p^2 - (y_s - 10)^2) and the roof (z = 10) where the circle's point at height 10
lies over the roof. So the roof lays over onto the band y_p in [-10 + d, 10 + d],
d = 10 / tan(theta) nearly, the wall onto [10, 10 + d]; behind the block the ground is shadowed
over 10 tan(theta), and only the ground images in front of the band.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.core.image import SarImage
from sarmitsuba.products import elevation_truth
from sarmitsuba.products.elevation_truth import iso_range_heights, nearest_truth
from sarmitsuba.scene.loader import load_scene

ALTITUDE = 1000.0
BLOCK = 10.0          # m, the block's height (its facing wall at y = 10, its back at y = -10)
SPACING = 0.5         # m, the test images' ground-range pixel spacing


def _scene(incidence: float, shift: float = 0.0, lift: float = 0.0):
    block = trimesh.creation.box((20.0, 20.0, BLOCK))
    block.apply_translation((shift, 0.0, BLOCK / 2 + lift))
    ground = trimesh.Trimesh(np.array([[-45, -45, 0], [45, -45, 0], [45, 45, 0], [-45, 45, 0]], float)
                             + [shift, 0, lift], [[0, 1, 2], [0, 2, 3]])
    sensor = {"incidence_angle": incidence, "n_pulses": 16, "altitude": ALTITUDE,
              "scene_center": f"{shift}, 0, {lift}"}
    return sarmitsuba.Scene(meshes=[(block, "concrete", "block"), (ground, "concrete", "ground")], sensor=sensor)


def _image(shift: float = 0.0, lift: float = 0.0, near: float = -40.0, far: float = 40.0,
           azimuth=(-1.0, 0.0, 1.0), phase: float = 0.0) -> SarImage:
    """A ground grid in the world frame through (shift, 0, lift); range runs along -y (away from
    the sensor), so pixel y = -range; its columns at ``near + phase + k SPACING``."""
    rg = np.arange(near, far + 1e-6, SPACING) + phase
    az = np.asarray(azimuth, float)
    return SarImage(data=np.zeros((az.size, rg.size), np.complex64), azimuth=az, range=rg,
                    origin=np.array([shift, 0.0, lift]), azimuth_direction=np.array([1.0, 0.0, 0.0]),
                    range_direction=np.array([0.0, -1.0, 0.0]))


def _column(image: SarImage, y: float) -> int:
    return int(np.argmin(np.abs(-image.range - y)))


def _crossings(heights: np.ndarray, image: SarImage, y: float, row: int = 1) -> np.ndarray:
    h = heights[row, _column(image, y)]
    return h[np.isfinite(h)]


def _wall(incidence: float, y_pixel: float) -> float:
    """Height where pixel y_pixel's circle about the track meets the plane y = 10 (closed form)."""
    y_s = ALTITUDE * math.tan(math.radians(incidence))
    r_p = math.hypot(y_s - y_pixel, ALTITUDE)
    return ALTITUDE - math.sqrt(r_p ** 2 - (y_s - 10.0) ** 2)


@pytest.mark.parametrize("incidence, shift, lift", [(35.0, 0.0, 0.0), (55.0, 0.0, 0.0), (35.0, 4000.0, 120.0)])
def test_crossings_are_the_closed_forms(incidence, shift, lift):
    """Heights above the grid plane z0 = lift, also for a scene 4 km from the origin (traced in a
    local frame 4 km and 125 m away: a frame offset left out misses the scene, heights taken in the
    local frame are 5 m off). Every pixel of the layover band in front of the wall has the ground,
    the wall and the roof (a crossing interpolated from the wrong end of its segment is centimetres
    off on the wall)."""
    loaded = load_scene(_scene(incidence, shift, lift))
    image = _image(shift, lift)
    heights = iso_range_heights(loaded, image)
    layover = BLOCK / math.tan(math.radians(incidence))
    band = -image.range[(-image.range > 11.0) & (-image.range < 10.0 + 0.9 * layover)]
    assert band.size >= 8
    for y in band:                                       # in front of the wall, inside the roof's layover
        found = _crossings(heights, image, y)
        assert found == pytest.approx([0.0, _wall(incidence, y), BLOCK], abs=0.01), (y, found)
    assert _crossings(heights, image, 5.0) == pytest.approx([BLOCK], abs=0.01)       # under the roof's layover only
    shadow = BLOCK * math.tan(math.radians(incidence))
    assert _crossings(heights, image, -10.5 - 0.5 * shadow).size == 0                 # in the block's shadow
    assert _crossings(heights, image, -12.0 - 1.2 * shadow) == pytest.approx([0.0], abs=0.01)   # open ground
    assert _crossings(heights, image, 12.0 + 1.2 * layover) == pytest.approx([0.0], abs=0.01)    # before the layover


@pytest.mark.parametrize("incidence", [35.0, 55.0])
def test_overlapping_faces_are_one_surface(incidence):
    """A membrane over the roof, triangulated otherwise, in its plane: the rays hit roof and
    membrane by turns (as the built-in urban scene's rooftop boxes on their roofs), so neither
    shape is one surface. Each layover pixel still has the ground, the wall and the roof once: the
    fragments' hits, single ones included, give the roof in the cell they image into, and equal
    heights of one pixel are one scatterer."""
    block = trimesh.creation.box((20.0, 20.0, BLOCK))
    block.apply_translation((0.0, 0.0, BLOCK / 2))
    ground = trimesh.Trimesh(np.array([[-45, -45, 0], [45, -45, 0], [45, 45, 0], [-45, 45, 0]], float),
                             [[0, 1, 2], [0, 2, 3]])
    membrane = trimesh.Trimesh(np.array([[-10, -10, BLOCK], [10, -10, BLOCK], [10, 10, BLOCK], [-10, 10, BLOCK]]),
                               [[0, 1, 3], [1, 2, 3]]).subdivide().subdivide()
    scene = sarmitsuba.Scene(meshes=[(block, "concrete", "block"), (ground, "concrete", "ground"),
                                     (membrane, "concrete", "membrane")],
                             sensor={"incidence_angle": incidence, "n_pulses": 16, "altitude": ALTITUDE})
    image = _image()
    heights = iso_range_heights(load_scene(scene), image, max_crossings=6)
    layover = BLOCK / math.tan(math.radians(incidence))
    for y in -image.range[(-image.range > 11.0) & (-image.range < 10.0 + 0.9 * layover)]:
        assert _crossings(heights, image, y) == pytest.approx([0.0, _wall(incidence, y), BLOCK], abs=0.01), y
    for y in -image.range[(-image.range > -9.0 + layover) & (-image.range < 9.5)]:
        assert _crossings(heights, image, y) == pytest.approx([BLOCK], abs=0.01), y


def test_each_row_has_its_own_circles_and_a_subset_is_the_same_rows(monkeypatch):
    """Each row's circles are about its own zero-Doppler antenna: rows across the block agree to a
    millimetre (a fan squinted from another row's antenna would not), a row 15 m along the track,
    beside the block, sees only ground in the block's layover band (one row's fan for all would
    not); ``rows`` picks rows in the order given; batches of one row give the table of one batch."""
    loaded = load_scene(_scene(35.0))
    image = _image(azimuth=(-8.0, 0.0, 8.0, 15.0))
    full = iso_range_heights(loaded, image)
    np.testing.assert_allclose(full[0], full[1], atol=1e-3)
    np.testing.assert_allclose(full[2], full[1], atol=1e-3)
    y = 10.0 + 0.5 * BLOCK / math.tan(math.radians(35.0))
    assert _crossings(full, image, y, row=3) == pytest.approx([0.0], abs=0.01)
    subset = iso_range_heights(loaded, image, rows=np.array([3, 0]))
    np.testing.assert_array_equal(subset, full[[3, 0]])
    monkeypatch.setattr(elevation_truth, "_BATCH_RAYS", 1)
    np.testing.assert_array_equal(iso_range_heights(loaded, image), full)


def test_the_lowest_crossings_are_kept():
    """``max_crossings = 2`` keeps the ground and the wall, not the roof (nor an unsorted pair)."""
    loaded = load_scene(_scene(55.0))
    image = _image()
    y = -image.range[_column(image, 10.0 + 0.5 * BLOCK / math.tan(math.radians(55.0)))]
    two = iso_range_heights(loaded, image, max_crossings=2)
    assert two.shape == (3, image.range.size, 2)
    assert _crossings(two, image, y) == pytest.approx([0.0, _wall(55.0, y)], abs=0.01)


@pytest.mark.parametrize("incidence", [35.0, 55.0])
def test_edges_lay_over_into_the_cells_that_show_them(incidence):
    """The roof's front edge (the top of the wall, the block's nearest point to the track) images
    at the ground point y_c of its slant range; the column 0.1 m nearer the sensor has a smaller
    range than any point of the block, but its cell holds y_c: the ground and the edge, to a hit
    spacing (without the edges: the ground alone). The wall's foot is one scatterer with the
    ground (a wall's lowest hit a few centimetres up is not a crossing of its own)."""
    loaded = load_scene(_scene(incidence))
    y_s = ALTITUDE * math.tan(math.radians(incidence))
    corner = math.hypot(y_s - 10.0, ALTITUDE - BLOCK)
    y_c = y_s - math.sqrt(corner ** 2 - ALTITUDE ** 2)
    image = _image(phase=(-(y_c + 0.1)) % SPACING)
    heights = iso_range_heights(loaded, image)
    assert -image.range[_column(image, y_c + 0.1)] == pytest.approx(y_c + 0.1)
    assert _crossings(heights, image, y_c + 0.1) == pytest.approx([0.0, BLOCK], abs=0.2)
    foot = iso_range_heights(loaded, _image())
    assert _crossings(foot, _image(), 10.0) == pytest.approx([0.0, BLOCK], abs=0.01)


@pytest.mark.parametrize("incidence", [35.0, 55.0])
def test_the_roof_lays_over_into_an_image_that_ends_inside_the_band(incidence):
    """An image whose far edge lies inside the roof's layover band: the roof's far part images
    there from rays that land h (tan(theta) + 1 / tan(theta)) beyond the far edge, farther than a
    fan cut short at the far edge (or at 1.5 h beyond it) reaches."""
    loaded = load_scene(_scene(incidence))
    layover = BLOCK / math.tan(math.radians(incidence))
    far_y = -10.0 + layover + 1.0                        # 1 m inside the band's far end
    image = _image(far=-far_y)
    heights = iso_range_heights(loaded, image)
    assert _crossings(heights, image, far_y) == pytest.approx([BLOCK], abs=0.01)


def test_nearest_truth_picks_the_closest_crossing_and_nan_for_none():
    table = np.array([[0.0, 4.0, 10.0, np.nan], [np.nan] * 4, [0.0, 4.0, np.nan, np.nan]])
    found = nearest_truth(table, np.array([6.5, 3.0, 2.0]))
    assert found[0] == 4.0 and np.isnan(found[1]) and found[2] == 0.0          # a tie: the lower
    assert nearest_truth(table[:1], np.array([7.5])) == pytest.approx([10.0])
    assert nearest_truth(table[:1].astype(np.float32), np.array([-3.0])) == pytest.approx([0.0])
    with pytest.raises(ValueError, match="M = 2"):
        nearest_truth(table, np.array([1.0, 2.0]))


def test_bad_images_and_arguments_are_refused():
    loaded = load_scene(_scene(45.0))
    with pytest.raises(ValueError, match="ground-plane"):
        iso_range_heights(loaded, dataclasses.replace(_image(), plane="slant"))
    with pytest.raises(ValueError, match="along"):
        iso_range_heights(loaded, dataclasses.replace(_image(), azimuth_direction=np.array([0.0, 1.0, 0.0]),
                                                      range_direction=np.array([1.0, 0.0, 0.0])))
    with pytest.raises(ValueError, match="rows"):
        iso_range_heights(loaded, _image(), rows=[3])
    with pytest.raises(ValueError, match="oversample"):
        iso_range_heights(loaded, _image(), oversample=0)
    with pytest.raises(ValueError, match="max_crossings"):
        iso_range_heights(loaded, _image(), max_crossings=0)
