"""The generated footprint city of ``benchmarks/city_generator.py`` (issue 56, item 2).

Truths checked: the building count from the lot grid's parameters, each building's triangles
against the closed form of its kind, and every building mesh closed and of genus 0 (Euler:
``F = 2 V - 4``); the terrain a DEM grid of two triangles per pixel whose side is the closed form's
to a pixel; a pitched roof's ridge ``(short side / 2) tan 30 deg`` above its eaves; the size's
closed-form count near the requested one; the same seed the same city; and the Dask path's raw
data identical to one process on a small city.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import city_generator as cg  # noqa: E402

from sarmitsuba.scene.city import BASE_DEPTH  # noqa: E402
from sarmitsuba.scene.footprints import LEVEL_HEIGHT, ROOF_PITCH_DEG  # noqa: E402


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    out = tmp_path_factory.mktemp("city")
    return cg.generate(out, 1e4, seed=5)


@pytest.mark.parametrize("triangles", [1e4, 1e5, 1e6])
def test_plan_size_and_building_count_follow_the_parameters(triangles):
    plan = cg.plan_city(triangles, seed=1)
    lots = int(round(plan.side / cg.LOT))
    assert plan.side % (cg.LOT * cg.BLOCK) == 0
    assert len(plan.kinds) == (lots - lots // cg.BLOCK) ** 2           # every BLOCK-th row and column a street
    # the closed form lands near the request (the side is rounded to whole blocks of 70 m)
    side = math.sqrt(triangles / cg.density())
    assert abs(plan.side - side) <= cg.LOT * cg.BLOCK / 2
    assert 0.5 * triangles <= plan.triangles() <= 1.6 * triangles
    if triangles == 1e6:
        assert 0.85e6 <= plan.triangles() <= 1.2e6 and len(plan.kinds) > 3000
        assert set(plan.kinds) == set(cg.TRIANGLES_PER_KIND)


def test_same_seed_same_city_other_seed_other_city():
    a, b, c = cg.plan_city(1e5, seed=2), cg.plan_city(1e5, seed=2), cg.plan_city(1e5, seed=3)
    assert a.kinds == b.kinds and all(np.array_equal(x, y) for x, y in zip(a.outlines, b.outlines))
    assert np.array_equal(a.hills, b.hills)
    assert a.kinds != c.kinds


def test_buildings_match_the_closed_form_and_are_closed(small):
    xml, plan, city = small
    assert len(city.buildings) == len(plan.kinds)
    for footprint, mesh in city.buildings:
        kind = plan.kinds[footprint.index]
        assert len(mesh.faces) == cg.TRIANGLES_PER_KIND[kind], kind
        assert mesh.is_watertight and mesh.is_winding_consistent
        assert len(mesh.faces) == 2 * len(mesh.vertices) - 4            # Euler, genus 0
        assert footprint.roof_shape == kind.split("_")[1]


def test_pitched_roofs_rise_by_the_30_degree_pitch(small):
    _, plan, city = small
    checked = 0
    for footprint, mesh in city.buildings:
        kind = plan.kinds[footprint.index]
        ring = plan.outlines[footprint.index]
        short = min(np.ptp(ring[:, 0]), np.ptp(ring[:, 1]))
        roof = 0.5 * short * math.tan(math.radians(ROOF_PITCH_DEG)) if kind == "rect_gabled" else 0.0
        z = mesh.vertices[:, 2]
        # walls from BASE_DEPTH below the lowest ground under it, eaves levels x 3 m above that ground
        assert np.ptp(z) == pytest.approx(BASE_DEPTH + LEVEL_HEIGHT * plan.levels[footprint.index] + roof, abs=2e-3)
        checked += roof > 0
    assert checked > 10


def test_terrain_is_the_dem_grid_and_the_total_is_the_closed_form(small):
    xml, plan, city = small
    ground = city.ground
    n = plan.terrain_pixels()
    # a rows x cols window of DEM pixels, each side the closed form's to a pixel (the window is cut in
    # UTM, turned by the grid convergence from the local axes), two triangles per 2 x 2 pixel centres
    shapes = [(r, len(ground.vertices) // r) for r in range(n - 1, n + 2) if len(ground.vertices) % r == 0
              and abs(len(ground.vertices) // r - n) <= 1]
    assert shapes, (len(ground.vertices), n)
    assert any(len(ground.faces) == 2 * (r - 1) * (c - 1) for r, c in shapes)
    edges = np.linalg.norm(np.diff(ground.triangles[:, :2], axis=1), axis=2)
    assert np.median(edges) == pytest.approx(cg.DEM_PIXEL, rel=0.01)      # DEM pixels, in metres
    assert np.abs(ground.vertices[:, 2]).max() <= plan.hills[:, 4].sum() + 0.01
    assert np.ptp(ground.vertices[:, 2]) > 1.0                          # hills, not a plane
    written = cg.count_triangles(xml)
    assert written == plan.building_triangles() + len(ground.faces)
    assert abs(written - plan.triangles()) <= 4 * n + 4                   # the closed form, to a pixel row
    assert len(list((Path(xml).parent / "meshes").glob("*.ply"))) == 2 * len(plan.kinds) + 1   # walls, roofs, ground


def test_the_dask_path_gives_the_one_process_raw_data(small):
    pytest.importorskip("distributed", reason="dask[distributed] is not installed")
    from sarmitsuba import pipeline
    from sarmitsuba.tracing.driver import distributed
    xml = small[0]
    spec = dict(sensor_overrides={"n_pulses": 4},
                integrator_overrides={"max_depth": 2, "pulses_per_trace": 2, "max_batch_rays": 1024})
    one = pipeline.simulate(str(xml), **spec).raw.data
    old = distributed.LOCAL_WORKERS
    try:
        distributed.LOCAL_WORKERS = 2
        dask = pipeline.simulate(str(xml), scheduler="local", **spec).raw.data
    finally:
        distributed.LOCAL_WORKERS = old
    assert np.abs(one).max() > 0
    error = float(np.sum(np.abs(dask - one) ** 2)) / float(np.sum(np.abs(one) ** 2))
    assert error == 0.0 or 10 * math.log10(error) <= -100.0
