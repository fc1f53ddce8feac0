"""The cut-outs of mixed pieces on the Dr.Jit device (:func:`sarmitsuba.tracing.fused.clipping.cut_outs`)
against their NumPy reference (:func:`sarmitsuba.tracing.visibility.cut_outs.cut_outs`, bit for bit)
and against closed forms (a square cut by a half-plane; a shadow that covers its piece).

Cases: random convex pieces of up to 12 corners, each paired with a few random convex shadows
(disjoint, partial, covering, equal to the piece), turned by angles other than 0, 45 and 90
degrees and moved 1e5 m; pieces in any order of the pairs, pieces no pair names; empty pieces;
batches the kernel leaves to the reference.

Deliberate bugs these tests were run against (each fails the tests named):
  * each lane clipping polygon ``i`` instead of its pair's piece: ``test_random_pairs``,
    ``test_closed_forms``;
  * ``>`` for the reference's ``>=`` in the cover test: ``test_random_pairs`` (shadows equal to
    their piece);
  * the cover test without its ``1 - 1e-12``: ``test_random_pairs``;
  * the piece's area with the cut-out's corner count: ``test_random_pairs``.

The cut-out's area summed left to right instead of in NumPy's pairwise order passes them: the
areas only decide the cover test, and a few ulps decide it only within 1e-16 of its threshold.
"""
from __future__ import annotations

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (the variant first)
from sarmitsuba.tracing.fused import clipping
from sarmitsuba.tracing.mesh.polygons import EVERYTHING, edge_lines, pad
from sarmitsuba.tracing.visibility import cut_outs as reference

ANGLES = (0.3, 1.1, np.radians(37.0), -0.7)
OFFSETS = ((0.0, 0.0), (1e5, -1e5))


@pytest.fixture(autouse=True)
def _on_the_device(monkeypatch):
    """Every batch to the kernels, however small."""
    monkeypatch.setattr(clipping, "DEVICE_PAIRS", 0)


def _same(poly, count, pair_piece, lines, device=True):
    """Assert the kernels' cut-outs and dark flags are the reference's, bit for bit (and, with
    ``device``, that the kernels made them: no fallback to the reference)."""
    ran = []
    real = clipping.clip_on_device

    def spy(*args, **kwargs):
        out = real(*args, **kwargs)
        ran.append(out is not None)
        return out

    clipping.clip_on_device = spy
    try:
        got = clipping.cut_outs(poly, count, pair_piece, lines)
    finally:
        clipping.clip_on_device = real
    assert ran == ([True] if device else [])
    want = reference.cut_outs(poly, count, pair_piece, lines)
    for g, w in zip(got, want):
        assert g.dtype == w.dtype and g.shape == w.shape
        assert np.array_equal(g, w) and np.array_equal(np.signbit(g), np.signbit(w))
    return got


def _convex(rng, k, centre, radius, angle):
    t = np.sort(rng.uniform(0.0, 2.0 * np.pi, k)) + angle
    return np.stack([centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)], axis=1)


def _batch(polys, width):
    poly = np.zeros((len(polys), width, 2))
    count = np.array([len(p) for p in polys])
    for i, p in enumerate(polys):
        poly[i, :len(p)] = p
    return pad(poly, count), count


@pytest.mark.parametrize("angle", ANGLES)
@pytest.mark.parametrize("offset", OFFSETS)
def test_random_pairs(angle, offset):
    """Random pieces and shadows: disjoint, partial, covering, and a shadow equal to its piece
    (the cover test's boundary), the pairs in random order of their pieces."""
    rng = np.random.default_rng(int(1e3 * angle) % 997)
    centre = np.array(offset)
    pieces = [_convex(rng, rng.integers(3, 13), centre + rng.normal(size=2) * 5.0, rng.uniform(0.2, 2.0), angle)
              for _ in range(300)]
    poly, count = _batch(pieces, 12)
    count[::37] = 0                                       # empty pieces
    pair_piece = rng.integers(0, len(pieces), 1500)
    shadows, kinds = [], rng.choice(3, len(pair_piece), p=[0.9, 0.04, 0.06])
    for p, kind in zip(pair_piece, kinds):
        own = poly[p, :max(count[p], 3)]
        mean = own.mean(axis=0)
        if kind == 0:                                     # partial, or disjoint
            shadows.append(_convex(rng, rng.integers(3, 8), mean + rng.normal(size=2) * 2.0, rng.uniform(0.1, 2.0), angle))
        elif kind == 1:                                   # covering: a hexagon of inradius 8.7 m
            t = angle + np.arange(6) * np.pi / 3
            shadows.append(mean + 10.0 * np.stack([np.cos(t), np.sin(t)], axis=1))
        else:                                             # the piece itself (its own lines)
            shadows.append(own if count[p] >= 3 else _convex(rng, 3, mean, 1.0, angle))
    shadow, shadow_count = _batch(shadows, 12)
    lines = edge_lines(shadow, shadow_count)
    cut, cut_count, dark = _same(poly, count, pair_piece, lines)
    hit = pair_piece[kinds == 1]
    assert np.all(dark[hit[count[hit] >= 3]])              # a covering shadow darkens its piece
    assert np.any(~dark) and np.any((cut_count >= 3) & ~dark[pair_piece])


@pytest.mark.parametrize("angle", ANGLES)
@pytest.mark.parametrize("offset", OFFSETS)
def test_closed_forms(angle, offset):
    """A 2 m square turned by ``angle`` and moved: the half-plane through its middle, parallel to
    a side, leaves the 2 m x 1 m half (corners known); a shadow of 3 m about it covers it; its
    own lines cover it (equal areas); a shadow 10 m away cuts nothing."""
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    shift = np.array(offset)
    square = np.array([[0, 0], [2.0, 0], [2.0, 2.0], [0, 2.0]]) @ rot.T + shift
    poly, count = _batch([square], 4)
    n = rot @ np.array([1.0, 0.0])                       # inward normal of the half x' >= 1
    half = np.array([[n[0], n[1], -(n @ (rot @ np.array([1.0, 0.0]) + shift))]] + [EVERYTHING] * 3)
    big = edge_lines(*_batch([np.array([[-0.5, -0.5], [2.5, -0.5], [2.5, 2.5], [-0.5, 2.5]]) @ rot.T + shift], 4))[0]
    far = edge_lines(*_batch([square + rot @ np.array([10.0, 0.0])], 4))[0]
    lines = np.stack([half, big, edge_lines(poly, count)[0], far])
    cut, cut_count, dark = _same(poly, count, np.zeros(4, np.int64), lines)
    assert list(cut_count) == [4, 4, 4, 0]
    want = np.array([[1.0, 0], [2.0, 0], [2.0, 2.0], [1.0, 2.0]]) @ rot.T + shift
    got = cut[0, :4]
    assert min(np.abs(np.roll(got, k, axis=0) - want).max() for k in range(4)) < 1e-9 * (1.0 + abs(offset[0]))
    assert dark[0]                                       # the covering and the equal shadows


def test_batches_left_to_the_reference():
    """Pieces not padded, corners not finite and small batches get the reference's own results."""
    rng = np.random.default_rng(5)
    poly, count = _batch([_convex(rng, 5, (0.0, 0.0), 1.0, 0.2) for _ in range(4)], 8)
    lines = edge_lines(*_batch([_convex(rng, 4, (0.3, 0.0), 1.0, 0.1)] * 4, 8))
    pairs = np.array([0, 1, 2, 3])
    unpadded = poly.copy()
    unpadded[1, 5] = (7.0, 7.0)
    _same(unpadded, count, pairs, lines, device=False)
    nan = poly.copy()
    nan[2, 1] = np.nan
    got = clipping.cut_outs(nan, count, pairs, lines)
    want = reference.cut_outs(nan, count, pairs, lines)
    assert all(np.array_equal(g, w, equal_nan=True) for g, w in zip(got, want))
