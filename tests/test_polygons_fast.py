"""The fast polygon kernels (:mod:`sarmitsuba.tracing.mesh.polygons`) against their readable references,
bit for bit: :func:`clip` against :func:`clip_reference` (the padded batch clipped one half-plane
at a time), and :func:`moments`, :func:`drop_repeats`, :func:`pad` and :func:`edge_lines` against
the NumPy expressions they replaced (kept below). The batches mix random convex polygons with the
degenerate ones: empty and one- or two-corner rows, zero-area and collinear corners, the largest
corner count, half-planes that miss, hold everything, pass through corners or along edges,
padding half-planes between the real ones, and a polygon made non-convex (more than two
crossings, more corners than the batch has slots).

Deliberate bugs these tests were run against (each fails at least one of them):
  * :func:`clip` writing a crossing point over the corner it follows;
  * :func:`clip` taking the next corner of a row's last corner from the following row;
  * :func:`clip` keeping the first (not the last) crossing point in an overflowing row's last slot;
  * :func:`moments`' bounding box from the first ``V - 1`` slots only;
  * :func:`moments` in blocks with the last block's rows replaced by one row;
  * :func:`pad` copying the second corner (not the first) into the padding slots.
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.tracing.mesh import polygons
from sarmitsuba.tracing.mesh.polygon_kernels import clip_kernel
from sarmitsuba.tracing.mesh.polygons import (EVERYTHING, REPEAT_DISTANCE, clip, clip_reference, corner_slots,
                                         drop_repeats, edge_lines, moments, pad)


# --------------------------------------------------------------------------- references
def pad_reference(poly, count):
    poly[:] = np.where(corner_slots(count, poly.shape[1])[..., None], poly, poly[:, :1])
    return poly


def drop_repeats_reference(poly, count, distance=REPEAT_DISTANCE):
    poly = pad_reference(poly, count)
    width = poly.shape[1]
    gap = np.linalg.norm(np.roll(poly, -1, axis=1) - poly, axis=2)
    keep = corner_slots(count, width) & ((gap > distance) | (count[:, None] == 1))
    start = np.cumsum(keep, axis=1) - keep
    out = np.zeros_like(poly)
    rows = np.broadcast_to(np.arange(poly.shape[0])[:, None], keep.shape)
    out[rows[keep], start[keep]] = poly[keep]
    count = keep.sum(axis=1).astype(np.int64)
    return pad_reference(out, count), count


def edge_lines_reference(poly, count):
    edge = np.roll(poly, -1, axis=1) - poly
    length = np.linalg.norm(edge, axis=2)
    valid = corner_slots(count, poly.shape[1]) & (length > 0)
    safe = np.where(valid, length, 1.0)
    a = np.where(valid, -edge[..., 1] / safe, 0.0)
    b = np.where(valid, edge[..., 0] / safe, 0.0)
    c = np.where(valid, -(a * poly[..., 0] + b * poly[..., 1]), 1.0)
    return np.stack([a, b, c], axis=2)


def moments_reference(poly, count):
    x0, y0 = poly[:, :1, 0], poly[:, :1, 1]
    x, y = poly[..., 0] - x0, poly[..., 1] - y0
    x1, y1 = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    cross = x * y1 - x1 * y
    area = 0.5 * cross.sum(axis=1)
    safe = np.where(area != 0, area, 1.0)
    cx = ((x + x1) * cross).sum(axis=1) / (6 * safe)
    cy = ((y + y1) * cross).sum(axis=1) / (6 * safe)
    ixx = ((x * x + x * x1 + x1 * x1) * cross).sum(axis=1) / 12 - area * cx * cx
    iyy = ((y * y + y * y1 + y1 * y1) * cross).sum(axis=1) / 12 - area * cy * cy
    ixy = ((x * y1 + 2 * x * y + 2 * x1 * y1 + x1 * y) * cross).sum(axis=1) / 24 - area * cx * cy
    diagonal = np.linalg.norm(poly.max(axis=1) - poly.min(axis=1), axis=1) if poly.shape[0] else np.zeros(0)
    centroid = np.stack([cx + x0[:, 0], cy + y0[:, 0]], axis=1)
    empty = count < 3
    return (np.where(empty, 0.0, area), np.where(empty[:, None], 0.0, centroid),
            np.where(empty[:, None], 0.0, np.stack([ixx, ixy, iyy], axis=1)), np.where(empty, 0.0, diagonal))


def assert_identical(new, old):
    assert type(new) is type(old)
    if isinstance(new, tuple):
        assert len(new) == len(old)
        for a, b in zip(new, old):
            assert_identical(a, b)
        return
    assert new.shape == old.shape and new.dtype == old.dtype
    np.testing.assert_array_equal(new, old)


# --------------------------------------------------------------------------- batches
def regular(n_corners, centre, radius, phase):
    angle = phase + 2 * np.pi * np.arange(n_corners) / n_corners
    return np.asarray(centre) + radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)


def batch(rng, n=300, width=8, n_lines=7):
    """Padded polygons ``(poly [n, width, 2], count [n], lines [n, n_lines, 3])`` with degenerate rows
    and degenerate half-planes mixed in."""
    rows, counts = [], []
    for i in range(n):
        kind = i % 10
        if kind == 0:                                  # empty
            corners = np.zeros((0, 2))
        elif kind == 1:                                # one or two corners
            corners = rng.normal(size=(1 + i % 2, 2))
        elif kind == 2:                                # zero area: one point repeated
            corners = np.repeat(rng.normal(size=(1, 2)), 4, axis=0)
        elif kind == 3:                                # collinear corners
            corners = rng.normal(size=(1, 2)) + np.linspace(0, 1, 5)[:, None] * rng.normal(size=(1, 2))
        elif kind == 4:                                # the largest corner count
            corners = regular(width, rng.normal(size=2), 1 + rng.random(), rng.random())
        elif kind == 5:                                # a unit square on the integer grid (corners on lines)
            corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) + rng.integers(-2, 2, size=2)
        else:
            corners = regular(rng.integers(3, width + 1), rng.normal(size=2) * 0.5, 0.5 + rng.random(),
                              rng.random())
        row = np.zeros((width, 2))
        row[:len(corners)] = corners
        rows.append(row)
        counts.append(len(corners))
    poly, count = pad(np.array(rows), np.array(counts, np.int64)), np.array(counts, np.int64)
    normal = rng.normal(size=(n, n_lines, 2))
    normal /= np.linalg.norm(normal, axis=2, keepdims=True)
    lines = np.concatenate([normal, rng.normal(size=(n, n_lines, 1)) * 0.7], axis=2)
    which = rng.random((n, n_lines))
    lines[which < 0.25] = EVERYTHING                                  # padding, also between lines
    lines[(which >= 0.25) & (which < 0.3)] = (0.0, 0.0, -1.0)         # holds nothing
    lines[(which >= 0.3) & (which < 0.35), 2] = 50.0                  # misses: holds the polygon
    lines[(which >= 0.35) & (which < 0.4), 2] = -50.0                 # misses: holds none of it
    grid = (which >= 0.4) & (which < 0.5)                             # through the grid's corners
    lines[grid] = np.array([(1.0, 0.0, 0.0), (0.0, -1.0, 1.0), (-1.0, 0.0, 0.0), (1.0, 1.0, -1.0)])[
        rng.integers(0, 4, size=grid.sum())]
    lines[rng.random(n) < 0.1] = EVERYTHING                           # rows with nothing to clip
    return poly, count, lines


def zigzag(width=8):
    """A polygon made non-convex by more than rounding, filling every slot, and a half-plane that
    crosses it four times: more corners than the batch's slots (the last slot's rule)."""
    corners = np.array([[0, 0], [4, 0], [4, 3], [3, 1], [2, 3], [1, 1], [0, 3], [0, 2]], float)[:width]
    lines = np.array([[[0.0, -1.0, 2.0], [0.0, 1.0, -0.5]]])
    return corners[None], np.array([width]), lines


# --------------------------------------------------------------------------- tests
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_clip_is_the_reference_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    poly, count, lines = batch(rng)
    before = poly.copy()
    out, out_count = clip(poly, count, lines)
    ref, ref_count = clip_reference(poly, count, lines)
    assert_identical(out, ref)
    assert_identical(out_count, ref_count)
    np.testing.assert_array_equal(poly, before)                       # the input is left alone
    assert np.any(out_count == 0) and np.any(out_count >= 3)          # the batch has both kinds
    assert out.flags.c_contiguous


def test_clip_degenerate_batches_match_the_reference():
    rng = np.random.default_rng(5)
    poly, count, lines = batch(rng, n=40)
    dense = batch(rng, n=40)[2][count > 0]
    dense[(dense[..., 0] == 0) & (dense[..., 1] == 0) & (dense[..., 2] > 0)] = (1.0, 1.0, 1.0)
    cases = [
        (np.zeros((0, 8, 2)), np.zeros(0, np.int64), np.zeros((0, 4, 3))),          # nothing
        (poly, count, lines[:, :0]),                                                 # no half-planes
        (poly, np.zeros_like(count), lines),                                         # all empty
        (poly, count, np.broadcast_to(np.array(EVERYTHING), lines.shape).copy()),    # all padding
        (poly, count, np.broadcast_to(np.array([0.0, 0.0, -1.0]), lines.shape).copy()),  # holds nothing
        (poly[:, :3], np.minimum(count, 3), lines),                                  # three slots
        (poly[:, :1], np.minimum(count, 1), lines),                                  # one slot
        (poly[count > 0], count[count > 0], dense),                                  # rows in order
        zigzag(),
        (np.concatenate([zigzag()[0], np.repeat(zigzag()[0][:, :1], 2, axis=1)], axis=1), zigzag()[1],
         zigzag()[2]),                                                               # room to grow
    ]
    for poly_, count_, lines_ in cases:
        out, out_count = clip(poly_, count_, lines_)
        ref, ref_count = clip_reference(poly_, count_, lines_)
        assert_identical(out, ref)
        assert_identical(out_count, ref_count)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_clip_kernel_is_the_reference_bit_for_bit(seed):
    """The Dr.Jit kernel against :func:`clip_reference` on the random and degenerate batches (its
    own arithmetic, corner order, repeated corners and padding); a non-convex row makes it decline
    (None), whatever else the batch holds. Deliberate bugs it caught: the next corner of a row's
    last corner read from the slot after it instead of the first; a crossing point written before
    the corner it follows; the repeated corners compared with the previous corner; a one-corner
    row's corner dropped as its own repeat; the padding taken from the second slot; a lane that
    gained two corners at a half-plane not declined."""
    rng = np.random.default_rng(seed)
    poly, count, lines = batch(rng, n=400 if seed < 3 else 40, n_lines=5 if seed < 3 else 30)
    count[6::10] = 1                                   # one-corner rows (kept by the repeat rule)
    lines[6::20] = EVERYTHING                          # half of them not cut at all
    poly = pad(poly, count)
    got = clip_kernel(poly, count, lines, REPEAT_DISTANCE)
    ref = clip_reference(poly, count, lines)
    assert got is not None
    assert_identical(got[0], ref[0])
    assert_identical(got[1], ref[1])
    assert np.any(got[1] == 0) and np.any(got[1] >= 5)
    zig_poly, zig_count, zig_lines = zigzag()
    assert clip_kernel(zig_poly, zig_count, zig_lines[:, :1], REPEAT_DISTANCE) is None


def test_large_batches_go_through_the_kernel(monkeypatch):
    """:func:`clip` hands a batch of :data:`polygons.KERNEL_ROWS` rows or more to the kernel, and
    its result is still the reference's."""
    rng = np.random.default_rng(11)
    poly, count, lines = batch(rng, n=200)
    calls = []
    monkeypatch.setattr(polygons, "clip_kernel", lambda *a: calls.append(len(a[0])) or clip_kernel(*a))
    monkeypatch.setattr(polygons, "KERNEL_ROWS", 100)
    out, out_count = clip(poly, count, lines)
    assert calls == [200]
    ref, ref_count = clip_reference(poly, count, lines)
    assert_identical(out, ref)
    assert_identical(out_count, ref_count)


def test_an_overflowing_row_keeps_the_last_crossing_point():
    # the zigzag cut at y = 2 asks for 11 corners, 8 slots and one more: the last slot holds the
    # last crossing point, (0, 2) (its corner (0, 2) came after it but was written first)
    poly, count, lines = zigzag()
    lines = lines[:, :1]
    out, out_count = clip(poly, count, lines)
    assert out_count[0] == 9 and out.shape == (1, 9, 2)
    np.testing.assert_array_equal(out[0, 7:], [[1, 1], [0, 2]])
    assert_identical((out, out_count), clip_reference(poly, count, lines))


def test_clip_falls_back_for_corners_that_are_not_finite_or_not_padded():
    rng = np.random.default_rng(7)
    poly, count, lines = batch(rng, n=30)
    nan = poly.copy()
    nan[4, 0] = np.nan                                                # row 4 holds the largest count
    stray = poly.copy()
    row = int(np.flatnonzero((count >= 3) & (count < poly.shape[1]))[0])
    stray[row, count[row]] += 1.0                                     # padding not the first corner
    for p in (nan, stray):
        out, out_count = clip(p, count, lines)
        ref, ref_count = clip_reference(p, count, lines)
        np.testing.assert_array_equal(out_count, ref_count)
        np.testing.assert_array_equal(out, ref)


@pytest.mark.parametrize("seed", [0, 1])
def test_moments_edges_repeats_and_padding_are_the_references(seed):
    rng = np.random.default_rng(seed)
    poly, count, lines = batch(rng)
    clipped, clipped_count = clip(poly, count, lines)
    for p, c in ((poly, count), (clipped, clipped_count), (poly[:, :3], np.minimum(count, 3)),
                 (np.zeros((0, 8, 2)), np.zeros(0, np.int64))):
        assert_identical(moments(p, c), moments_reference(p, c))
        assert_identical(edge_lines(p, c), edge_lines_reference(p, c))
        a, b = p.copy(), p.copy()
        assert_identical(drop_repeats(a, c), drop_repeats_reference(b, c))
        np.testing.assert_array_equal(a, b)                           # both pad their input in place
        # padding a batch whose padding slots hold something else
        junk = p + rng.normal(size=p.shape) * ~corner_slots(c, p.shape[1])[..., None]
        a, b = junk.copy(), junk.copy()
        assert pad(a, c) is a
        np.testing.assert_array_equal(a, pad_reference(b, c))
        a, b = np.asfortranarray(junk), junk.copy()                    # not one corner per element
        assert pad(a, c) is a
        np.testing.assert_array_equal(a, pad_reference(b, c))


def test_moments_in_blocks_are_the_reference(monkeypatch):
    rng = np.random.default_rng(3)
    poly, count, lines = batch(rng, n=100)
    poly, count = clip(poly, count, lines)
    monkeypatch.setattr(polygons, "MOMENT_ROWS", 7)                  # 15 blocks, the last short
    assert_identical(moments(poly, count), moments_reference(poly, count))


def test_repeated_corners_are_dropped_whatever_the_distance():
    # corners nearer than the distance to their next one go, the last one against the first
    poly = np.array([[[0, 0], [1, 0], [1, 0], [1, 1], [0, 1e-12]]], float)
    for distance in (REPEAT_DISTANCE, 0.5, 2.0):
        assert_identical(drop_repeats(poly.copy(), np.array([5]), distance),
                         drop_repeats_reference(poly.copy(), np.array([5]), distance))
    out, count = drop_repeats(poly.copy(), np.array([5]))
    assert count[0] == 3
    np.testing.assert_array_equal(out[0, :4], [[0, 0], [1, 0], [1, 1], [0, 0]])
