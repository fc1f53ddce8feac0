"""The mesh tracer's cost model (issue 56): what each sub-aperture's reach holds.

:func:`sarmitsuba.analysis.cost.reach_work` counts the triangles, pieces and facing area in each
sub-aperture's along-track reach with sorted centroids and prefix sums. Checked against a second
method: the triangles of the written PLY files (trimesh), their centroids tested one sub-aperture at
a time against the reach interval built here from the tracer's rule (the antenna's first and last
along-track positions, the beam's sines times the farthest corner, ``REACH_MARGIN`` and a patch);
and against the generator's closed-form triangle count when the reach is the whole scene. The
timing constants themselves are fitted in ``benchmarks/scaling.py --calibrate`` (a benchmark, not
a test).
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import city_generator as cg  # noqa: E402

from sarmitsuba.analysis import cost  # noqa: E402
from sarmitsuba.core.geometry import acquisition_geometry  # noqa: E402
from sarmitsuba.scene import planning  # noqa: E402
from sarmitsuba.scene.loader import load_scene  # noqa: E402
from sarmitsuba.tracing.driver.mesh_trace import REACH_MARGIN  # noqa: E402

PATCH = 1.5
SIZE = 19


@pytest.fixture(scope="module")
def city(tmp_path_factory):
    xml, plan, _ = cg.generate(tmp_path_factory.mktemp("city"), 1e4, seed=7)
    loaded = load_scene(str(xml), {"n_pulses": 80})
    return xml, plan, loaded, acquisition_geometry(loaded.params)


def _trimesh_triangles(xml: Path) -> tuple[np.ndarray, np.ndarray]:
    """Centroids [n, 3] and areas [n] of every PLY's triangles (trimesh, the second method)."""
    meshes = [trimesh.load(p, process=False) for p in sorted((Path(xml).parent / "meshes").glob("*.ply"))]
    return (np.vstack([m.triangles_center for m in meshes]), np.concatenate([m.area_faces for m in meshes]))


def test_reach_counts_match_a_per_subaperture_brute_force(city):
    xml, plan, loaded, geometry = city
    pieces, triangles, area = cost.reach_work(loaded, geometry, PATCH, SIZE)
    n_pulses = len(geometry.positions)
    assert len(triangles) == math.ceil(n_pulses / SIZE)
    centroid, tri_area = _trimesh_triangles(xml)
    track = geometry.track_direction
    lo_b, hi_b = loaded.params.beam_sines
    corners = np.array([[x, y, z] for x in (loaded.bbox_lo[0], loaded.bbox_hi[0])
                        for y in (loaded.bbox_lo[1], loaded.bbox_hi[1]) for z in (loaded.bbox_lo[2], loaded.bbox_hi[2])])
    far = max(np.linalg.norm(a - c) for a in geometry.positions for c in corners)
    along = centroid @ track
    for k in range(len(triangles)):
        ends = geometry.positions[[k * SIZE, min(n_pulses, (k + 1) * SIZE) - 1]] @ track
        lo = ends.min() + lo_b * far - REACH_MARGIN - PATCH
        hi = ends.max() + hi_b * far + REACH_MARGIN + PATCH
        inside = (along >= lo) & (along < hi)
        # float32 PLY centroids against the float64 scene's: a triangle on the boundary may differ
        assert abs(triangles[k] - inside.sum()) <= 2, k
        one = np.where(np.sqrt(2 * tri_area) <= PATCH, 1.0, (np.sqrt(tri_area) / PATCH + 1) ** 2)
        assert pieces[k] == pytest.approx(one[inside].sum(), rel=1e-3, abs=20)
        assert 0 < area[k] <= tri_area[inside].sum() * (1 + 1e-6) + 1.0
    # the beam's reach is a strip: a sub-aperture in the middle of the track holds a share of the
    # city near (reach length) / (city length), far from all of it
    middle = triangles[len(triangles) // 2]
    assert 0.05 * len(centroid) < middle < 0.9 * len(centroid)


def test_without_a_straight_track_every_subaperture_reaches_the_whole_city(city):
    xml, plan, loaded, geometry = city
    pieces, triangles, area = cost.reach_work(loaded, geometry, PATCH, SIZE, straight=False)
    # the closed form of the generator: buildings exactly, terrain to a pixel row
    assert np.all(triangles == triangles[0])
    assert triangles[0] == cg.count_triangles(xml)
    assert abs(triangles[0] - plan.triangles()) <= 4 * plan.terrain_pixels() + 4


def test_trace_time_and_memory_follow_the_reach(city):
    """The estimate's parts are its constants times the counts of :func:`reach_work` (the model's
    bookkeeping; the constants are the calibration's)."""
    xml, plan, loaded, geometry = city
    p = loaded.params
    window = planning.fast_time_window(p, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings)
    footprint = planning.ray_footprint(p, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings,
                                       shape_boxes=loaded.shape_boxes)
    c = cost.cost_estimate(loaded, geometry, window, footprint)
    pieces, triangles, area = cost.reach_work(loaded, geometry, footprint.patch_size, c.pulses_per_trace)
    host = (cost.SETUP_TRIANGLE_SECONDS * loaded.n_triangles + cost.SUB_PIECE_SECONDS * pieces.sum()
            + cost.SUB_TRIANGLE_SECONDS * triangles.sum()
            + cost.CLUTTER_SCATTERER_PULSE_SECONDS * c.clutter_scatterer_pulses)
    assert c.mesh_host_time_s == pytest.approx(host, rel=1e-9)
    assert c.trace_time_low_s <= c.trace_time_s <= c.trace_time_high_s
    assert c.trace_time_s >= host
    assert c.reach_triangles_total == pytest.approx(triangles.sum())
    # the working set: a share for each sub-aperture of a launch
    share = min(cost.SUBAPERTURE_BYTES, cost.REACH_TRIANGLE_BYTES * triangles.max())
    assert c.trace_working_bytes >= share * c.subapertures_per_launch
    assert c.runtime_bytes >= cost.MESH_TRIANGLE_BYTES * loaded.n_triangles
