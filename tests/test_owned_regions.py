"""The owned partition (docs/physics.md (T6)) tiles a convex facet exactly, for any lattice and view.

Truth: Gordon's closed form over the whole facet (``physical_optics.polygon_integral``, itself
tested against numerical quadrature) and the shoelace area."""
import math

import numpy as np
import pytest

from sarmitsuba.owned_regions import owned_regions, region_polygons
from sarmitsuba.physical_optics import polygon_integral


def _rotated(points, deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.asarray(points, float) @ np.array([[c, s], [-s, c]])


def _lattice(origin, e1, e2):
    """Cell point ``(i + fa, j + fg)`` of an affine lattice (``e1 x e2 > 0``)."""
    origin, e1, e2 = (np.asarray(v, float) for v in (origin, e1, e2))
    return lambda i, j, fa=0.5, fg=0.5: origin + (i + fa) * e1 + (j + fg) * e2


def _members(facet, cell, n=80):
    """Cells whose centre lies inside the counter-clockwise convex ``facet``."""
    out = set()
    for i in range(-n, n):
        for j in range(-n, n):
            x = cell(i, j)
            if all((b - a)[0] * (x - a)[1] - (b - a)[1] * (x - a)[0] > 0
                   for a, b in zip(facet, np.roll(facet, -1, axis=0))):
                out.add((i, j))
    return out


def _integral(poly, q):
    """Gordon's closed form over a polygon in the plane z = 0."""
    return polygon_integral(np.c_[poly, np.zeros(len(poly))], np.array([0.0, 0.0, 1.0]), np.r_[q, 0.0])


def _lines(origin, e1, e2):
    """The view's lattice lines, directed as :func:`owned_regions` asks."""
    origin, e1, e2 = (np.asarray(v, float) for v in (origin, e1, e2))
    column = lambda i: (origin + i * e1, origin + i * e1 + e2)     # noqa: E731  (left: column i - 1)
    row = lambda j: (origin + j * e2, origin + j * e2 - e1)        # noqa: E731  (left: row j - 1)
    return column, row


FACETS = {
    "triangle 30 deg": _rotated([[-2.0, -1.5], [2.5, -1.0], [0.3, 2.2]], 30.0),
    "triangle 60 deg": _rotated([[-2.0, -1.5], [2.5, -1.0], [0.3, 2.2]], 60.0),
    "square 30 deg": _rotated([[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]], 30.0),
    "sliver 10 deg": _rotated([[-3.0, -0.2], [3.0, -0.1], [2.8, 0.3]], 10.0),
}
# (lattice at the reference position, lattice as the pulse sees it): moved, scaled, skewed
VIEWS = {
    "same view": (((0.05, 0.11), (0.2, 0.0), (0.0, 0.283)), ((0.05, 0.11), (0.2, 0.0), (0.0, 0.283))),
    "parallax of 3.4 cells": (((0.05, 0.11), (0.2, 0.0), (0.0, 0.283)), ((0.73, -0.41), (0.207, 0.0), (0.0, 0.29))),
    "skewed view": (((0.05, 0.11), (0.2, 0.0), (0.0, 0.283)), ((-0.31, 0.2), (0.19, 0.03), (-0.04, 0.27))),
}


@pytest.mark.parametrize("facet_name", FACETS)
@pytest.mark.parametrize("view", VIEWS)
def test_owned_regions_tile_the_facet_exactly(facet_name, view):
    facet = FACETS[facet_name]
    at_reference, at_pulse = VIEWS[view]
    members = _members(facet, _lattice(*at_reference))
    pieces = region_polygons(facet, owned_regions(members, *_lines(*at_pulse)))
    polys = [p for ps in pieces.values() for p in ps]
    area = sum(0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]) for p in polys)
    exact_area = 0.5 * np.sum(facet[:, 0] * np.roll(facet[:, 1], -1) - np.roll(facet[:, 0], -1) * facet[:, 1])
    assert abs(area - exact_area) < 1e-12 * exact_area
    # the two-way phase gradient of X band at 45 deg: 280 rad/m, tens of radians across a cell
    for q in ((0.1, -284.5), (180.0, -220.0), (-95.0, 40.0)):
        facet3 = np.concatenate([facet, np.zeros((len(facet), 1))], axis=1)
        truth = polygon_integral(facet3, np.array([0.0, 0.0, 1.0]), np.array([*q, 0.0]))
        total = sum(_integral(p, np.array(q)) for p in polys)
        assert abs(total - truth) < 1e-9 * exact_area, (q, total, truth)
        # the staircase the kernel sums today (whole cells as the pulse sees them) is far off
        cell = _lattice(*at_pulse)
        stair = sum(_integral(np.array([cell(i, j, a, g) for a, g in ((0, 0), (1, 0), (1, 1), (0, 1))]),
                                        np.array(q)) for i, j in members)
        assert abs(stair - truth) > 10 * abs(total - truth) + 1e-6 * exact_area


def test_owned_regions_refuses_gaps_and_empty_sets():
    column, row = _lines((0, 0), (1, 0), (0, 1))
    with pytest.raises(ValueError, match="no members"):
        owned_regions(set(), column, row)
    with pytest.raises(ValueError, match="column 0 has a gap"):
        owned_regions({(0, 0), (0, 2)}, column, row)
