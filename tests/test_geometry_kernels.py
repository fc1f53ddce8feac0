"""The mesh tracer's geometry kernels in Dr.Jit against their NumPy references and against the
geometry they stand for (docs/physics.md (M4)): the visibility samples of pieces computed on the
device (:func:`sarmitsuba.tracing.visibility.lit_pieces.device_samples`).

Deliberate bugs these tests were run against (each fails at least one of them):
  * a border piece's sample pulled toward the first corner instead of the centroid;
  * the centroid divided by the slots (the polygon's width) instead of its corners;
  * a whole patch's samples inset by twice :data:`SAMPLE_INSET`;
  * the corners of a whole patch in another order (x and y of the unit square swapped).
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.tracing.visibility.lit_pieces import SAMPLE_INSET, corner_samples, device_samples
from sarmitsuba.tracing.mesh.piece_cuts import pieces_of


def _regions(rng, n: int, corners: int = 6):
    """Random convex regions (counter-clockwise, padded), oblique to the patch grid, some far
    from the origin (face coordinates of kilometres)."""
    angle = np.sort(rng.uniform(0.0, 2.0 * np.pi, (n, corners)), axis=1)
    centre = rng.uniform(-30.0, 30.0, (n, 1, 2)) + (rng.random((n, 1, 1)) < 0.3) * 2500.0
    radius = rng.uniform(0.3, 6.0, (n, 1, 1))
    poly = centre + radius * np.stack([np.cos(angle), np.sin(angle)], axis=2)
    return np.concatenate([poly, poly[:, :2]], axis=1), np.full(n, corners)


@pytest.mark.parametrize("seed, patch", [(0, 0.7), (1, 1.3), (2, 0.25)])
def test_device_samples_are_the_host_samples_and_sit_inset(seed, patch):
    rng = np.random.default_rng(seed)
    pieces = pieces_of(*_regions(rng, 120), patch)
    assert pieces.whole.any() and (~pieces.whole).any()
    (x, y), owner = device_samples(pieces)
    want, want_owner = corner_samples(pieces)
    np.testing.assert_array_equal(owner, want_owner)
    np.testing.assert_array_equal(x.numpy(), want[:, 0])                # bit for bit
    np.testing.assert_array_equal(y.numpy(), want[:, 1])
    got = np.stack([x.numpy(), y.numpy()], axis=1)
    inset = SAMPLE_INSET * patch
    # a whole patch: its four corners (bottom-left, bottom-right, top-right, top-left) moved
    # inset along both axes toward its centre
    whole = np.flatnonzero(pieces.whole)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    expected = pieces.cell[whole][:, None, :] * patch + square * patch + (1.0 - 2.0 * square) * inset
    at = np.searchsorted(owner, whole)
    for k in range(4):
        np.testing.assert_allclose(got[at + k], expected[:, k], rtol=0, atol=1e-9 * (1.0 + np.abs(expected[:, k]).max()))
    # a border piece: each corner moved toward the mean of the corners by min(inset, half the way)
    for b in np.flatnonzero(~pieces.whole)[:200]:
        row = pieces.border[b]
        corners = pieces.polygon[row, :pieces.count[row]]
        centre = corners.mean(axis=0)
        span = np.linalg.norm(centre - corners, axis=1)
        step = np.minimum(inset, 0.5 * span)
        want_b = corners + (centre - corners) * (step / np.where(span > 0, span, 1.0))[:, None]
        np.testing.assert_allclose(got[owner == b], want_b, rtol=0, atol=1e-9 * (1.0 + np.abs(corners).max()))


def test_device_samples_of_no_pieces_and_only_whole_ones():
    rng = np.random.default_rng(3)
    pieces = pieces_of(*_regions(rng, 10), 0.5)
    none = pieces.select(np.zeros(0, np.int64))
    (x, y), owner = device_samples(none)
    assert len(owner) == 0 and x.numpy().size == 0
    only = pieces.select(np.flatnonzero(pieces.whole))
    (x, y), owner = device_samples(only)
    want, _ = corner_samples(only)
    np.testing.assert_array_equal(np.stack([x.numpy(), y.numpy()], axis=1), want)
