""":func:`sarmitsuba.tracing.mesh.covers.locate` (all points at once) against its point-by-point
reference: the same part for points inside one candidate, inside several, on shared edges and
corners, outside all (the nearest), with wholly covered candidates (fewer than 3 corners) first,
between and alone, and polygons padded to the widest."""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.tracing.mesh.covers import locate, locate_reference


def _polygons(rng, n, width):
    """n convex polygons (counter-clockwise, padded with their last corner) of 0 .. width corners."""
    polygons = np.zeros((n, width, 2))
    counts = rng.integers(0, width + 1, n)
    counts[: min(n, 3)] = [width, 3, 0][: min(n, 3)]
    for k, c in enumerate(counts):
        angle = np.sort(rng.uniform(0, 2 * np.pi, c))
        centre, radius = rng.uniform(-1, 1, 2), rng.uniform(0.3, 1.5)
        corners = centre + radius * np.stack([np.cos(angle), np.sin(angle)], 1)
        polygons[k, :c] = corners
        if 0 < c < width:
            polygons[k, c:] = corners[-1]
    return polygons, counts


@pytest.mark.parametrize("seed", range(5))
def test_locate_is_its_reference(seed):
    rng = np.random.default_rng(seed)
    polygons, counts = _polygons(rng, 12, 7)
    # the unit square split along its diagonal: points on the shared edge and the corners
    polygons[3, :3] = [[0, 0], [1, 0], [1, 1]]
    polygons[4, :3] = [[0, 0], [1, 1], [0, 1]]
    polygons[3:5, 3:] = polygons[3:5, 2:3]
    counts[3:5] = 3
    m = 400
    points = rng.uniform(-2.5, 2.5, (m, 2))
    points[:40] = rng.uniform(0, 1, (40, 1)) * [1.0, 1.0]             # on the diagonal
    points[40:44] = [[0, 0], [1, 0], [1, 1], [0, 1]]
    polygons[5] = polygons[3]                                         # a duplicate polygon
    counts[5] = 3
    candidates = []
    for k in range(m):
        if k < 60:
            options = rng.permutation([3, 4, 5, 2])[: rng.integers(1, 5)]
        else:
            options = rng.choice(12, rng.integers(1, 6), replace=False)
        candidates.append(np.asarray(options, np.int64))
    candidates[44] = np.array([2], np.int64)                          # only a wholly covered part
    candidates[45] = np.array([2, 2, 3], np.int64)
    np.testing.assert_array_equal(locate(points, candidates, polygons, counts),
                                  locate_reference(points, candidates, polygons, counts))


def test_locate_of_no_points():
    assert locate(np.zeros((0, 2)), [], np.zeros((2, 3, 2)), np.array([3, 3])).shape == (0,)
