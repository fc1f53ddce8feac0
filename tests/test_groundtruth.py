"""Geometric ground truth (layover, shadow, footprints, double-bounce lines) against closed forms.

Expectations are docs/physics.md (G1)-(G3) on simple scenes, not earlier outputs:

* built-in ``dihedral``: a 5 m wall on the ground, fold line at y = 0 (ground range 0),
  45 deg incidence, 1000 m altitude. Shadow behind the wall ``h tan(theta) = 5 m`` (exactly
  ``5 * 1000 / 995`` m: the ray grazing the wall top), layover band of the wall face
  ``h / tan(theta) = 5 m`` toward the sensor, double-bounce line on the fold;
* ``tests/scenes/tower.xml``: a 30 m tower (8 m x 8 m, front face at y = 0): layover 30 m,
  footprint 8 m, shadow ``30 * 1008 / 970`` m behind its back face;
* built-in ``urban`` (rough facades, gamma -8 dB): the layover mask falls on bright returns.

Masks are pixel sets on the image grid, so "within one pixel" is the tolerance throughout.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (variant and plugins)
from sarmitsuba.products import groundtruth
from sarmitsuba.core.image import SarImage
from sarmitsuba.pipeline import image_grid, simulate
from sarmitsuba.core.geometry import acquisition_geometry
from sarmitsuba.scene.loader import load_scene

SCENES = Path(__file__).parent / "scenes"


def grid_image(loaded) -> SarImage:
    """An all-zero image on the grid the pipeline would focus on (no tracing needed)."""
    grid = image_grid(loaded, acquisition_geometry(loaded.params))
    return SarImage(data=np.zeros(grid.shape, np.complex64), azimuth=np.array(grid.azimuth),
                    range=np.array(grid.range), origin=np.array(grid.origin),
                    azimuth_direction=np.array(grid.azimuth_direction),
                    range_direction=np.array(grid.range_direction), metadata={"scene": loaded.source})


def runs(image: SarImage, mask: np.ndarray, azimuth: float) -> list[tuple[float, float, float]]:
    """(first range, last range, extent) of each run of the mask along the row nearest ``azimuth``;
    extent = pixel count x spacing (a band of length L covers L / spacing pixels)."""
    row = mask[int(np.argmin(np.abs(image.azimuth - azimuth)))]
    cols = np.flatnonzero(row)
    if cols.size == 0:
        return []
    spacing = image.range[1] - image.range[0]
    parts = np.split(cols, np.flatnonzero(np.diff(cols) > 1) + 1)
    return [(float(image.range[p[0]]), float(image.range[p[-1]]), float(p.size * spacing)) for p in parts]


@pytest.fixture(scope="module")
def dihedral():
    loaded = load_scene("dihedral")
    image = grid_image(loaded)
    return loaded, image, groundtruth.ground_truth(loaded, image)


@pytest.fixture(scope="module")
def tower():
    loaded = load_scene(str(SCENES / "tower.xml"))
    image = grid_image(loaded)
    return loaded, image, groundtruth.ground_truth(loaded, image)


# ============================================================================ dihedral: 5 m wall
def test_dihedral_shadow_is_h_tan_theta(dihedral):
    """(G3): the ground behind the wall (range 0 .. 5 m) is unseen over h tan(theta) = 5 m."""
    loaded, image, truth = dihedral
    spacing = 1.0001 * (image.range[1] - image.range[0])   # one pixel (with rounding)
    exact = 5.0 * 1000.0 / (1000.0 - 5.0)            # ray over the wall top to the antenna
    for az in (-8.0, 0.0, 8.0):
        (first, last, extent), = runs(image, truth.shadow, az)
        assert abs(extent - 5.0) <= spacing and abs(extent - exact) <= spacing, (az, extent)
        assert -spacing <= first <= spacing, "the shadow starts at the wall"
        assert abs(last - exact) <= spacing
    assert not runs(image, truth.shadow, 15.0), "no shadow beyond the end of the wall"


def test_dihedral_layover_is_h_over_tan_theta(dihedral):
    """(G2): the wall face (h up to 5 m) lays over toward the sensor onto range -5 .. 0."""
    loaded, image, truth = dihedral
    spacing = 1.0001 * (image.range[1] - image.range[0])   # one pixel (with rounding)
    (first, last, extent), = runs(image, truth.layover, 0.0)
    assert abs(extent - 5.0) <= spacing, extent
    assert abs(first + 5.0) <= spacing and -spacing <= last <= spacing, (first, last)
    # nothing elevated lays over away from the sensor, and the ground plate is not elevated
    assert not truth.layover[:, image.range > spacing].any()


def test_dihedral_double_bounce_line_on_the_fold(dihedral):
    """(G1): the wall-ground contact line visible from the sensor is the fold line y = 0."""
    loaded, image, truth = dihedral
    spacing = 1.0001 * (image.range[1] - image.range[0])   # one pixel (with rounding)
    cols = np.flatnonzero(truth.double_bounce.any(axis=0))
    assert cols.size >= 1 and np.all(np.abs(image.range[cols]) <= spacing)
    rows = np.flatnonzero(truth.double_bounce.any(axis=1))
    length = rows.size * (image.azimuth[1] - image.azimuth[0])
    assert abs(length - 20.0) <= 2 * spacing, f"the fold is 20 m long, the line {length:.2f} m"
    points = groundtruth.facade_foot_points(loaded, image)
    assert points.shape == (truth.double_bounce.sum(), 3)
    assert np.all(np.abs(points[:, 1]) < 1e-3) and np.all(points[:, 2] == 0.0)


def test_dihedral_footprint_of_a_thin_wall_is_at_most_one_pixel(dihedral):
    _, image, truth = dihedral
    cols = np.flatnonzero(truth.footprint.any(axis=0))
    assert cols.size <= 1


# ============================================================================ 30 m tower
def test_tower_layover_extent_30m(tower):
    """(G2): the 30 m tower's face and roof lay over onto range -30 .. 0 (45 deg; exactly
    -30.02 .. 0). The run counts every pixel the band touches: its length plus up to one
    pixel at each end."""
    loaded, image, truth = tower
    spacing = 1.0001 * (image.range[1] - image.range[0])   # one pixel (with rounding)
    for az in (-3.0, 2.5):                       # rows clear of the roof reflector (|x| < 1.1 m)
        (first, last, extent), = runs(image, truth.layover, az)
        assert -spacing <= extent - 30.0 <= 2 * spacing, (az, extent)
        assert abs(first + 30.0) <= spacing and -spacing <= last <= spacing


def test_tower_footprint_and_shadow(tower):
    """Footprint y = -8 .. 0 (range 0 .. 8 m); shadow behind it, exact length 30 * 1008 / 970 m."""
    loaded, image, truth = tower
    spacing = 1.0001 * (image.range[1] - image.range[0])   # one pixel (with rounding)
    (f_first, f_last, f_extent), = runs(image, truth.footprint, 2.5)   # clear of the roof reflector
    assert abs(f_extent - 8.0) <= spacing and abs(f_first) <= spacing and abs(f_last - 8.0) <= spacing
    (s_first, s_last, s_extent), = runs(image, truth.shadow, 2.5)
    exact = 30.0 * 1008.0 / 970.0
    assert abs(s_extent - exact) <= spacing and abs(s_first - 8.0) <= spacing, (s_first, s_extent)
    assert not (truth.shadow & truth.footprint).any()


def test_ground_truth_is_fast_and_vectorised():
    """The urban grid (675 x 981 pixels) takes a few seconds at most on 2 cores."""
    loaded = load_scene("urban")
    image = grid_image(loaded)
    start = time.perf_counter()
    truth = groundtruth.ground_truth(loaded, image)
    assert time.perf_counter() - start < 15.0
    fractions = truth.fractions()
    assert 0.02 < fractions["layover"] < 0.2 and 0.02 < fractions["shadow"] < 0.2
    assert truth.layover.shape == image.data.shape and truth.layover.dtype == bool


# ============================================================================ against images
def test_brightest_column_of_the_dihedral_image_is_the_contact_line():
    """The traced double bounce focuses on the wall-ground contact line of the ground truth."""
    sim = simulate("dihedral", integrator_overrides={"max_depth": 2})
    image = sim.image
    line = groundtruth.double_bounce_mask(sim.loaded, image)
    contact_col = np.bincount(np.nonzero(line)[1]).argmax()
    brightest_col = int(np.argmax((np.abs(image.data.astype(np.complex128)) ** 2).sum(axis=0)))
    assert abs(brightest_col - contact_col) <= 1, (image.range[brightest_col], image.range[contact_col])


def test_urban_layover_mask_is_bright():
    """Rough facades (gamma -8 dB) laid over are brighter than the image median: > 50 % of the
    layover-mask pixels exceed it by 6 dB, and every double-bounce pixel does."""
    sim = simulate("urban")
    truth = groundtruth.ground_truth(sim.loaded, sim.image)
    stats = groundtruth.agreement(sim.image, truth, threshold_db=6.0)
    assert stats["layover_overlap"] > 0.5, stats
    assert stats["double_bounce_bright"] > 0.9, stats
    assert stats["layover_mean_db"] > 6.0


# ============================================================================ API
def test_save_round_trip(dihedral, tmp_path):
    _, _, truth = dihedral
    path = truth.save(tmp_path / "truth.npz")
    with np.load(path) as f:
        for name in ("layover", "shadow", "footprint", "double_bounce"):
            assert np.array_equal(f[name], getattr(truth, name))
        assert float(f["height_threshold"]) == truth.height_threshold
    assert not any(p.name.endswith(".partial") for p in tmp_path.iterdir())


def test_single_masks_match_ground_truth(dihedral):
    loaded, image, truth = dihedral
    assert np.array_equal(groundtruth.layover_mask(loaded, image), truth.layover)
    assert np.array_equal(groundtruth.shadow_mask(loaded, image), truth.shadow)
    assert np.array_equal(groundtruth.footprint_mask(loaded, image), truth.footprint)


def test_bad_arguments(dihedral):
    loaded, image, _ = dihedral
    slant = SarImage(data=image.data, azimuth=image.azimuth, range=image.range, origin=image.origin,
                     azimuth_direction=image.azimuth_direction, range_direction=image.range_direction,
                     plane="slant")
    with pytest.raises(ValueError, match="ground-plane"):
        groundtruth.ground_truth(loaded, slant)
    with pytest.raises(ValueError, match="height_threshold"):
        groundtruth.layover_mask(loaded, image, height_threshold=0.0)
    with pytest.raises(ValueError, match="oversample"):
        groundtruth.layover_mask(loaded, image, oversample=0)


def test_layover_of_chosen_shapes(tower):
    """``layover_mask(shapes=...)``: every shape's layover is the whole layover; the ground (never
    elevated) lays over nothing; the tower alone lays over a part of it. Bug: shape indices taken
    for Mitsuba's registry ids (a mask of the wrong shapes, or none)."""
    loaded, image, truth = tower
    shapes = list(loaded.scene.shapes())
    index = {s.id(): k for k, s in enumerate(shapes)}
    assert np.array_equal(groundtruth.layover_mask(loaded, image, shapes=range(len(shapes))), truth.layover)
    assert not groundtruth.layover_mask(loaded, image, shapes=[index["ground"]]).any()
    alone = groundtruth.layover_mask(loaded, image, shapes=[index["tower"]])
    assert alone.any() and not np.any(alone & ~truth.layover)
