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


def test_covered_pairs_of_many_coplanar_parts_match_every_pair_checked():
    """200 squares of three shapes, scattered in one plane so that some overlap, and a few in a
    second plane: the pairs ``covered_parts`` finds through its tree of boxes are those a check of
    every pair finds (shapely's own intersection areas), each once. Bug: a pair missed where one
    square's box holds the other's, or listed twice (once from each side of the tree's query)."""
    import shapely
    from sarmitsuba.tracing.mesh.covers import covered_parts
    rng = np.random.default_rng(7)
    n = 200
    lo = rng.uniform(0, 40, (n, 2))
    size = rng.uniform(0.5, 6, n)
    z = np.where(np.arange(n) % 17 == 0, 1.0, 0.0)
    corners = [np.array([[x, y, h], [x + s, y, h], [x + s, y + s, h], [x, y + s, h]])
               for (x, y), s, h in zip(lo, size, z)]
    normal, offset = np.tile([0.0, 0.0, 1.0], (n, 1)), z.copy()
    shape, area = np.arange(n) % 3, size**2
    found = covered_parts(normal, offset, corners, shape, area)
    expected = []
    for a in range(n):
        for b in range(a + 1, n):
            if z[a] != z[b] or shape[a] == shape[b]:
                continue
            pa, pb = shapely.Polygon(corners[a][:, :2]), shapely.Polygon(corners[b][:, :2])
            if pa.intersection(pb).area > 1e-9:
                expected.append((b, a) if (area[a], a) < (area[b], b) else (a, b))
    assert len(expected) > 50
    assert len(found) == len(expected) and sorted(map(tuple, found.tolist())) == sorted(expected)
