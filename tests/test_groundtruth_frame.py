"""Ground-truth masks of a scene far from the origin (products/groundtruth.py, docs/physics.md (G1)-(G3)).

A scene more than ``RECENTER_DISTANCE`` from the origin is traced in a local frame (world minus
``LoadedScene.offset``), while its images are in the world frame. Truth: the same block on the
same ground at the origin, whose masks ``tests/test_groundtruth.py`` checks against the closed
forms of (G1)-(G3); translated by 100 km east, 30 km south and 120 m up (its local frame's origin
then 125 m up: the box's centre, rounded), every mask is the same pixel set, the wall feet are the
same points moved by the translation, and the image plane's height is the translated one.

Deliberate bug this test was run against: the frame offset left out (the world-frame grid cast
against the local scene, as before it was moved): every mask of the far scene empty, its image
plane 245 m up.
"""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.core.geometry import acquisition_geometry
from sarmitsuba.core.image import SarImage
from sarmitsuba.pipeline import image_grid
from sarmitsuba.products import groundtruth
from sarmitsuba.scene.loader import load_scene

FAR = np.array([1e5, -3e4, 120.0])
MASKS = ("layover", "shadow", "footprint", "double_bounce", "scene_area")


def _scene(shift: np.ndarray, incidence: float) -> sarmitsuba.Scene:
    """A 20 x 20 x 10 m block on a 90 m square ground, both moved by ``shift`` [m]."""
    block = trimesh.creation.box((20.0, 20.0, 10.0))
    block.apply_translation(shift + (0.0, 0.0, 5.0))
    ground = trimesh.Trimesh(np.array([[-45, -45, 0], [45, -45, 0], [45, 45, 0], [-45, 45, 0]], float) + shift,
                             [[0, 1, 2], [0, 2, 3]])
    sensor = {"incidence_angle": incidence, "n_pulses": 16, "altitude": 1000.0,
              "scene_center": ", ".join(repr(float(c)) for c in shift)}
    return sarmitsuba.Scene(meshes=[(block, "concrete", "block"), (ground, "concrete", "ground")], sensor=sensor)


def _image(loaded) -> SarImage:
    """An all-zero image on the grid the pipeline focuses on, in the world frame (as it writes it)."""
    grid = image_grid(loaded, acquisition_geometry(loaded.params))
    return SarImage(data=np.zeros(grid.shape, np.complex64), azimuth=np.array(grid.azimuth),
                    range=np.array(grid.range), origin=np.array(grid.origin) + loaded.offset,
                    azimuth_direction=np.array(grid.azimuth_direction),
                    range_direction=np.array(grid.range_direction))


@pytest.mark.parametrize("incidence", [35.0, 55.0])
def test_a_scene_far_from_the_origin_has_the_masks_it_has_at_the_origin(incidence):
    near = load_scene(_scene(np.zeros(3), incidence))
    far = load_scene(_scene(FAR, incidence))
    assert not np.any(near.offset) and np.linalg.norm(far.offset) > 1e4        # traced in a local frame
    near_image, far_image = _image(near), _image(far)
    want, got = groundtruth.ground_truth(near, near_image), groundtruth.ground_truth(far, far_image)
    for name in MASKS:
        assert getattr(want, name).sum() > 10, name                            # something to compare
        assert np.array_equal(getattr(got, name), getattr(want, name)), name
    assert np.array_equal(groundtruth.shadow_mask(far, far_image), want.shadow)
    assert np.array_equal(groundtruth.layover_mask(far, far_image), want.layover)
    assert got.z0 == pytest.approx(FAR[2], abs=1e-9) and want.z0 == 0.0
    feet = groundtruth.facade_foot_points(far, far_image)
    assert feet.shape == groundtruth.facade_foot_points(near, near_image).shape and len(feet) > 10
    np.testing.assert_allclose(feet, groundtruth.facade_foot_points(near, near_image) + FAR, rtol=0, atol=1e-6)
