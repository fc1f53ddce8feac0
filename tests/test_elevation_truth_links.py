"""The stack's truth on a scene of one mesh: a block and its ground as one shape
(products/elevation_truth.py, docs/physics.md (G2), (TS2)).

When the ground and a building are one shape, as in a city's single OBJ, the ray that grazes the
roof's far edge and the next one, which lands on the ground beyond the block's shadow, hit the
same shape metres apart: they are two surfaces, not one to interpolate across. Were they linked,
the shadow's pixels would get crossings between the roof's height and the ground's, where the
geometry has none.

Geometry as tests/test_elevation_truth.py, written from the iso-range circles alone: a
20 x 20 x 10 m block on a 90 x 90 m plate, the track at altitude H flying +x with the sensor at
y_s = H tan(theta); the roof lays over onto y_p in [-10 + d, 10 + d], d = 10 / tan(theta) nearly,
the facing wall (y = 10) onto [10, 10 + d], where pixel y_p's circle meets it at
h = H - sqrt(R_p^2 - (y_s - 10)^2), R_p = sqrt((y_s - y_p)^2 + H^2); behind the block the ground is
shadowed over 10 tan(theta).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.core.image import SarImage
from sarmitsuba.products.elevation_truth import iso_range_heights
from sarmitsuba.scene.loader import load_scene

ALTITUDE, BLOCK, SPACING = 1000.0, 10.0, 0.5


def _one_shape(incidence: float):
    block = trimesh.creation.box((20.0, 20.0, BLOCK))
    block.apply_translation((0.0, 0.0, BLOCK / 2))
    ground = trimesh.Trimesh(np.array([[-45, -45, 0], [45, -45, 0], [45, 45, 0], [-45, 45, 0]], float),
                             [[0, 1, 2], [0, 2, 3]])
    city = trimesh.util.concatenate([block, ground])
    return sarmitsuba.Scene(meshes=[(city, "concrete", "city")],
                            sensor={"incidence_angle": incidence, "n_pulses": 16, "altitude": ALTITUDE})


def _image() -> SarImage:
    """Ground grid through the origin, range along -y (pixel y = -range), 0.5 m columns."""
    rg = np.arange(-40.0, 40.0 + 1e-6, SPACING)
    return SarImage(data=np.zeros((3, rg.size), np.complex64), azimuth=np.array([-1.0, 0.0, 1.0]), range=rg,
                    origin=np.zeros(3), azimuth_direction=np.array([1.0, 0.0, 0.0]),
                    range_direction=np.array([0.0, -1.0, 0.0]))


def _wall(incidence: float, y_pixel: float) -> float:
    y_s = ALTITUDE * math.tan(math.radians(incidence))
    return ALTITUDE - math.sqrt(math.hypot(y_s - y_pixel, ALTITUDE) ** 2 - (y_s - 10.0) ** 2)


@pytest.mark.parametrize("incidence", [35.0, 55.0])
def test_a_shadow_between_hits_of_one_shape_holds_no_crossing(incidence):
    """The shadow's pixels (0.5 m inside its ends) have no crossing, and the layover band in front
    of the wall still has the ground, the wall and the roof (a linking tolerance 100 times looser
    joins the roof's far edge to the ground beyond the shadow and fills the shadow)."""
    image = _image()
    heights = iso_range_heights(load_scene(_one_shape(incidence)), image)
    y = -image.range
    shadow = (y < -10.5) & (y > -10.0 - BLOCK * math.tan(math.radians(incidence)) + 0.5)
    assert shadow.sum() >= 10
    assert np.all(np.isnan(heights[1][shadow])), heights[1][shadow][np.isfinite(heights[1][shadow])]
    band = (y > 11.0) & (y < 10.0 + 0.9 * BLOCK / math.tan(math.radians(incidence)))
    assert band.sum() >= 8
    for column in np.flatnonzero(band):
        found = heights[1, column][np.isfinite(heights[1, column])]
        assert found == pytest.approx([0.0, _wall(incidence, y[column]), BLOCK], abs=0.01), (y[column], found)
