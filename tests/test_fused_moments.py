"""Polygon moments on the Dr.Jit device (:func:`sarmitsuba.tracing.fused.moments.moments`) against
their NumPy reference (:func:`sarmitsuba.tracing.mesh.polygons.moments`, bit for bit) and against
closed forms (a rectangle's and a triangle's area, centroid and second moments).

Cases: random convex polygons of every width from 3 to 17 slots (NumPy sums rows of eight slots
or more in eight partial sums, fewer in order), turned by angles other than 0, 45 and 90 degrees
and moved 1e5 m; empty rows, polygons on one line or one point; every call the fused tracer
makes in ``simulate("urban")``.

Deliberate bugs these tests were run against (each fails the tests named):
  * the slots summed left to right at every width (NumPy's pairwise order ignored):
    ``test_random_polygons`` (urban's pieces have fewer than nine slots);
  * ``/ 12`` and ``/ 24`` as literals (Dr.Jit multiplies by their rounded reciprocals):
    ``test_random_polygons``, ``test_closed_forms``, ``test_urban_calls``;
  * ``- area cx cx`` left out of ``Ixx``: every test, ``test_fused.py``'s renders too;
  * the box without the last slot: ``test_random_polygons``, ``test_urban_calls``;
  * empty rows not zeroed: ``test_degenerate_rows``, ``test_random_polygons``, ``test_urban_calls``.
"""
from __future__ import annotations

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (the variant first)
from sarmitsuba.tracing.fused import moments as fused
from sarmitsuba.tracing.mesh import polygons
from sarmitsuba.tracing.mesh.polygons import pad

ANGLES = (0.3, 1.1, np.radians(37.0), -0.7, 2.5)


@pytest.fixture(autouse=True)
def _on_the_device(monkeypatch):
    """Every batch to the kernel, however small."""
    monkeypatch.setattr(fused, "DEVICE_ROWS", 0)


def _same(poly, count):
    """Assert the kernel's moments are the reference's, bit for bit (signed zeros too)."""
    got, want = fused.moments(poly, count), polygons.moments(poly, count)
    for g, w in zip(got, want):
        assert g.dtype == w.dtype and g.shape == w.shape
        assert np.array_equal(g, w) and np.array_equal(np.signbit(g), np.signbit(w))
    return got


def _random_batch(rng, n, width, angle, offset):
    """Random convex polygons (corners on circles), up to ``width`` corners, padded."""
    count = rng.integers(0, width + 1, n)
    poly = np.zeros((n, width, 2))
    for i, k in enumerate(count):
        t = np.sort(rng.uniform(0.0, 2.0 * np.pi, k)) + angle
        r = rng.uniform(0.05, 4.0)
        poly[i, :k] = np.stack([offset + r * np.cos(t), -offset + r * np.sin(t)], axis=1)
    pad(poly, count)
    return poly, count


@pytest.mark.parametrize("width", range(3, 18))
def test_random_polygons(width):
    rng = np.random.default_rng(width)
    for angle in ANGLES[:2]:
        for offset in (0.0, 1e5):
            _same(*_random_batch(rng, 700, width, angle, offset))


@pytest.mark.parametrize("angle", ANGLES)
@pytest.mark.parametrize("offset", (0.0, 1e5))
def test_closed_forms(angle, offset):
    """A 3 m x 1.2 m rectangle and a right triangle with legs 2 m and 0.8 m, turned by ``angle``
    and moved: area ``a b``, ``a b / 2``; centroid at the centre and at the mean of the corners;
    second moments about the centroid ``A a^2 / 12`` and ``A b^2 / 12`` along the rectangle's
    sides, and for the triangle ``A a^2 / 18``, ``A b^2 / 18``, product ``-A a b / 36`` along its
    legs, turned into face axes by ``R diag R^T``."""
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    shift = np.array([offset, -offset])
    rect = np.array([[0, 0], [3.0, 0], [3.0, 1.2], [0, 1.2]]) @ rot.T + shift
    tri = np.array([[0, 0], [2.0, 0], [0, 0.8]]) @ rot.T + shift
    poly = np.zeros((2, 9, 2))
    count = np.array([4, 3])
    poly[0, :4], poly[1, :3] = rect, tri
    pad(poly, count)
    area, centroid, second, diagonal = _same(poly, count)
    np.testing.assert_allclose(area, [3.6, 0.8], rtol=1e-9)
    np.testing.assert_allclose(centroid, [rect.mean(axis=0), tri.mean(axis=0)], rtol=1e-12, atol=1e-9)
    local = [np.diag([3.6 * 9.0 / 12, 3.6 * 1.44 / 12]),
             np.array([[0.8 * 4.0 / 18, -0.8 * 1.6 / 36], [-0.8 * 1.6 / 36, 0.8 * 0.64 / 18]])]
    for row, inertia in zip(second, local):
        face = rot @ inertia @ rot.T
        np.testing.assert_allclose(row, [face[0, 0], face[0, 1], face[1, 1]], atol=1e-9 * (1 + offset))
    box = [np.ptp(rect, axis=0), np.ptp(tri, axis=0)]
    np.testing.assert_allclose(diagonal, np.hypot(*np.transpose(box)), rtol=1e-12, atol=1e-9)


def test_degenerate_rows():
    """Empty rows (0, 1, 2 corners) are all zeros; polygons on one line (cross products of both
    signs of zero) and on one point have area +0; a square with a repeated corner, area 1."""
    line = [[0.0, 5.0], [-1.0, 5.0], [2.0, 5.0]]
    rows = [[], [[1.0, 1.0]], [[0.0, 0.0], [1.0, 1.0]], line, line[::-1], [[7.0, -3.0]] * 3,
            [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [1.0, 1.0], [0.0, 1.0]]]
    poly = np.zeros((len(rows), 9, 2))
    count = np.array([len(r) for r in rows])
    for i, r in enumerate(rows):
        poly[i, :len(r)] = np.reshape(r, (-1, 2))
    pad(poly, count)
    area, centroid, second, diagonal = _same(poly, count)
    assert np.all(area[:3] == 0) and np.all(centroid[:3] == 0) and np.all(second[:3] == 0) and np.all(diagonal[:3] == 0)
    assert not np.any(np.signbit(area[3:6])) and np.all(area[3:6] == 0)
    assert area[6] == 1.0


def test_urban_calls(monkeypatch):
    """Every call the fused tracer makes in ``simulate("urban")``: the inputs recorded, the kernel
    compared."""
    from sarmitsuba.pipeline import simulate
    calls = []

    def record(poly, count):
        calls.append((np.array(poly, copy=True), np.array(count, copy=True)))
        return polygons.moments(poly, count)

    monkeypatch.setattr(fused, "moments", record)
    simulate("urban", integrator_overrides={"geometry": "fused"})
    monkeypatch.undo()
    monkeypatch.setattr(fused, "DEVICE_ROWS", 0)
    assert len(calls) > 5 and sum(len(c[1]) for c in calls) > 1000
    for call in calls:
        _same(*call)
