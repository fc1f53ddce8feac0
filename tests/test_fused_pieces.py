"""Regions cut into pieces on the Dr.Jit device (:func:`sarmitsuba.tracing.fused.pieces.pieces_of`)
against its NumPy reference (:func:`sarmitsuba.tracing.mesh.piece_cuts.pieces_of`): the same
pieces in the same order, every field bit for bit; and, without the reference, pieces that tile
their region (docs/physics.md (M2)).

Cases: random convex regions (triangles to 12-gons) turned by several angles, at offsets 0 and
1e5 m, patches of 0.25 to 3 m; regions on the grid (edges and corners exactly on grid lines,
horizontal edges off the grid, a diamond with its corners on grid points); regions smaller than a
patch, regions with fewer than 3 corners, padding by the first and by the last corner; spans that
cut regions partly and wholly; horizontal edges on grid lines ending on grid points with the
edge before them rounding off its end (the corner-on-line term); one Dr.Jit thread against
several; ``moments=`` and the threshold to the reference; and every call of
``simulate("urban")``.

Deliberate bugs these tests were run against, each planted alone in
sarmitsuba/tracing/fused/pieces.py (the tests that failed; "all but" counts the 27 tests):
  * the whole range one cell too far (``floor(i_hi / P) - 1`` -> ``floor(i_hi / P)``), or one
    cell early (``ceil(i_lo / P) - 1``); the first cell by ``ceil``, the last by ``floor``,
    ``whole_first`` by ``floor``; the border cells right of the whole ones started one cell
    early: all but ``test_edge_cases``;
  * a cell at ``whole_last`` not whole in the pieces kernel: every test;
  * the rows of a region in decreasing order: all but ``test_pieces_tile_regions``;
  * the outer span without the reach's corners inside the slab: ``test_random_regions``,
    ``test_grid_regions``, ``test_spans``, ``test_pieces_tile_regions``,
    ``test_small_batches_and_moments``, ``test_thread_count``, ``test_urban_calls``;
  * the span ignored (the outer span from the region, not its reach): ``test_spans``,
    ``test_urban_calls``;
  * slivers kept as pieces: ``test_grid_regions``, ``test_spans``, ``test_urban_calls``;
  * the corner-on-line term dropped: ``test_corners_on_lines`` only;
  * the last corner's edge wrapping at the count, not the batch's width:
    ``test_grid_regions`` padded by the last corner only;
  * the division by the patch as a literal (Dr.Jit multiplies by its reciprocal):
    ``test_grid_regions`` at 0.7 m only.
No test failed for these, which we judge equivalent in the outputs: ``t >= 0`` -> ``t > 0``
(the crossing at an edge's start is its corner, which the corner-on-line term adds);
``t <= 1`` -> ``t < 1`` (the crossing at an edge's end is the next corner, exact from the next
edge's start and the corner-on-line term; only its rounding is lost, which can move an outer
span's end across a grid line by a cell the region meets in a point or a line, clipped to
nothing and dropped); ``np.maximum`` written as ``dr.maximum`` (they differ in the sign of zero
and for NaN; the extents reach the outputs only through ``floor`` and ``ceil`` to integers).
"""
from __future__ import annotations

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (the variant first)
from sarmitsuba.tracing.fused import pieces as fused
from sarmitsuba.tracing.mesh import piece_cuts
from sarmitsuba.tracing.mesh.polygons import moments, pad

ANGLES = (0.0, 0.3, np.radians(37.0), np.pi / 4, 1.1, np.pi / 2, 2.5, -0.7)
OFFSETS = ((0.0, 0.0), (1e5, -1e5))
FIELDS = ("region", "cell", "whole", "border", "polygon", "count")


@pytest.fixture(autouse=True)
def _kernels_always(monkeypatch):
    """The kernels for every batch, however small (the reference takes small ones in use)."""
    monkeypatch.setattr(fused, "KERNEL_REGIONS", 0)


def _same(polygon, count, patch, span=None) -> int:
    """Assert the device's pieces are the reference's, bit for bit; their number."""
    want = piece_cuts.pieces_of(polygon, count, patch, span)
    got = fused.pieces_of(polygon, count, patch, span)
    for name in FIELDS:
        g, w = getattr(got, name), getattr(want, name)
        assert g.dtype == w.dtype and g.shape == w.shape, name
        assert np.array_equal(g, w), name
    assert got.patch == want.patch
    return len(want)


def _batch(polys, width=None, last=False):
    """Corner lists as a padded batch ``(poly [n, W, 2], count [n])`` (padded by the first corner,
    or by the last with ``last``)."""
    width = width or max([len(p) for p in polys] + [3])
    poly = np.zeros((len(polys), width, 2))
    count = np.array([len(p) for p in polys], np.int64)
    for i, p in enumerate(polys):
        poly[i, :len(p)] = p
        if last and len(p):
            poly[i, len(p):] = p[-1]
    return (poly if last else pad(poly, count)), count


def _convex(rng, n, centre, radius, stretch=1.0):
    """A convex ``n``-gon, counter-clockwise: corners on an ellipse at random angles."""
    angle = np.sort(rng.uniform(0, 2 * np.pi, n))
    return np.stack([centre[0] + stretch * radius * np.cos(angle), centre[1] + radius * np.sin(angle)], axis=1)


def _moved(poly, angle, offset):
    """``poly`` turned by ``angle`` about the origin and moved by ``offset``."""
    c, s = np.cos(angle), np.sin(angle)
    return poly @ np.array([[c, -s], [s, c]]).T + offset


def _random_regions(rng, n, patch):
    """``n`` convex regions of 3 to 12 corners, a few patches to a few tens of patches wide, some
    smaller than a patch."""
    polys = []
    for _ in range(n):
        size = patch * (rng.uniform(0.1, 0.9) if rng.random() < 0.15 else rng.uniform(1.0, 25.0))
        polys.append(_convex(rng, rng.integers(3, 13), rng.uniform(-30, 30, 2), size, rng.uniform(0.3, 3.0)))
    return _batch(polys, 13)


@pytest.mark.parametrize("seed", range(4))
def test_random_regions(seed):
    rng = np.random.default_rng(seed)
    for patch in (0.25, 0.7, 1.3, 3.0):
        poly, count = _random_regions(rng, 40, patch)
        count[:3] = (0, 1, 2)                       # too few corners: skipped
        for angle in ANGLES[seed::2]:
            for offset in OFFSETS:
                assert _same(_moved(poly, angle, offset), count, patch) > 40


def _rect(x0, y0, x1, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def _grid_regions(patch):
    """Regions with edges and corners exactly on the grid lines of ``patch``, horizontal edges off
    them, corners on grid points, thin strips along a line, and regions within one patch."""
    p = patch
    return [_rect(0, 0, 4 * p, 3 * p), _rect(-2 * p, p, 3 * p, 1.5 * p), _rect(0.5 * p, 0.25 * p, 2.5 * p, 2.75 * p),
            [(2 * p, 0), (4 * p, 2 * p), (2 * p, 4 * p), (0, 2 * p)],             # corners on grid points
            [(0, 0), (3 * p, 0), (3 * p, 3 * p)],                                   # a diagonal through corners
            [(0.3 * p, 0.3 * p), (5.7 * p, 0.3 * p), (4 * p, 2 * p), (p, 2 * p)],   # horizontal edges
            [(0, p), (4 * p, p), (4 * p, p + 1e-13), (0, p + 1e-13)],               # a sliver along a line
            [(p, p), (2 * p, p), (2 * p, 2 * p), (p, 2 * p)],                       # exactly one patch
            [(0.1 * p, 0.1 * p), (0.8 * p, 0.2 * p), (0.5 * p, 0.9 * p)],           # inside one patch
            [(0.9 * p, 0.9 * p), (1.6 * p, 0.9 * p), (1.2 * p, 1.7 * p)],           # small, over a corner
            [(-p, -p), (2 * p, -3 * p), (5 * p, -p), (5 * p, 3 * p), (2 * p, 5 * p), (-p, 3 * p)]]


@pytest.mark.parametrize("last", [False, True])
@pytest.mark.parametrize("patch", [0.25, 0.5, 1.0, 0.7, 3.0])
def test_grid_regions(patch, last):
    poly, count = _batch(_grid_regions(patch), 7, last)
    assert _same(poly, count, patch) > 0
    for offset in ((1e5, -1e5), (-3 * patch, 7 * patch)):
        assert _same(poly + offset, count, patch) > 0
    for angle in ANGLES[1:]:
        assert _same(_moved(poly, angle, OFFSETS[1]), count, patch) > 0


def _rounded(a, b, above):
    """The first of a few values ``x`` near ``a`` for which ``x + (b - x)`` rounds to above ``b``
    (``above``) or below it: an edge from ``x`` ending on ``b`` crosses its end line off ``b``."""
    for x in a + np.arange(-100, 100) * 1e-2 * abs(a):
        if (x + (b - x) > b) if above else (x + (b - x) < b):
            return x
    raise AssertionError("no such value")


@pytest.mark.parametrize("patch", [0.25, 0.5, 1.0, 2.0])
def test_corners_on_lines(patch):
    """Horizontal edges on grid lines whose ends are on grid points, the edges before them ending
    there: the crossing ``p + 1 (q - p)`` rounds off the corner, only the corner-on-line term
    gives the exact extent (and so the whole patches of the rows beside the line)."""
    p = patch
    top, bottom = 2 * p, -2 * p
    # (each edge narrows the region towards the line it ends on, so that the line's extent is
    # the row's inner span)
    x_right = _rounded(2 * p, -3 * p, False)            # the right edge ends short of x = -3 p
    x_left = _rounded(-2 * p, 3 * p, True)              # the left edge ends beyond x = 3 p
    quads = [[(-8 * p, bottom), (x_right, bottom), (-3 * p, top), (-8 * p, top)],
             [(3 * p, bottom), (8 * p, bottom), (8 * p, top), (x_left, top)]]
    poly, count = _batch(quads, 4)
    assert _same(poly, count, p) > 0
    assert _same(poly + (-6 * p, 10 * p), count, p) > 0


def _spans(poly, count, rng):
    """Two half-planes per region (a band ``lo <= g . x <= hi``) cutting some regions partly, some
    not at all and some wholly away."""
    n = len(count)
    theta = rng.uniform(0, np.pi, n)
    g = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    centre = np.array([p[:max(c, 1)].mean(axis=0) for p, c in zip(poly, count)])
    mid = (g * centre).sum(axis=1) + rng.uniform(-8, 8, n)
    half = rng.choice([0.5, 3.0, 1e9], n)
    half[::7] = -1.0                                      # an empty band: every patch left out
    span = np.zeros((n, 2, 3))
    span[:, 0, :2], span[:, 0, 2] = g, -(mid - half)
    span[:, 1, :2], span[:, 1, 2] = -g, mid + half
    return span


@pytest.mark.parametrize("seed", range(3))
def test_spans(seed):
    rng = np.random.default_rng(10 + seed)
    for patch in (0.25, 1.0, 2.2):
        poly, count = _random_regions(rng, 50, patch)
        for angle, offset in ((0.0, OFFSETS[0]), (ANGLES[seed + 2], OFFSETS[1])):
            moved = _moved(poly, angle, offset)
            span = _spans(moved, count, rng)
            assert _same(moved, count, patch, span) > 0
    grid, grid_count = _batch(_grid_regions(0.5), 7)
    span = np.zeros((len(grid), 1, 3))
    span[:, 0] = (1.0, 0.0, -1.0)                         # x >= 1 m: on a grid line
    assert _same(grid, grid_count, 0.5, span) > 0


def test_edge_cases():
    poly, count = _batch(_grid_regions(1.0), 7)
    assert _same(poly[:0], count[:0], 1.0) == 0                       # no regions
    assert _same(poly, np.zeros(len(count), np.int64), 1.0) == 0      # none with corners
    assert _same(poly[8:10], count[8:10], 1.0) == 2                   # only small ones
    assert _same(poly[:1], count[:1], 1.0) == 12                      # one region
    span = np.zeros((len(count), 1, 3))
    span[:, 0] = (0.0, 1.0, -1e6)                                     # every patch left out
    assert _same(poly, count, 1.0, span) == 0


def test_small_batches_and_moments():
    """Below the threshold the reference's own result; ``moments=`` used for the slivers' test
    and the small regions, in both."""
    poly, count = _random_regions(np.random.default_rng(5), 30, 1.0)
    want = piece_cuts.pieces_of(poly, count, 1.0)
    for threshold in (0, 1000):
        calls = []

        def counted(p, c, calls=calls):
            calls.append(len(c))
            return moments(p, c)

        fused.KERNEL_REGIONS = threshold
        got = fused.pieces_of(poly, count, 1.0, moments=counted)
        assert all(np.array_equal(getattr(got, f), getattr(want, f)) for f in FIELDS)
        assert len(calls) == 2


def _shoelace(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)


def _tiles(poly, count, patch):
    """Without the reference: the pieces of each region tile it (their areas add up to its
    shoelace area), whole pieces are patches inside it, border pieces lie in their patches, no
    patch twice."""
    got = fused.pieces_of(poly, count, patch)
    keys = piece_cuts.cell_key(got.region, got.cell)
    assert len(np.unique(keys)) == len(keys)
    area = np.where(got.whole, patch * patch, 0.0)
    rows = got.border[~got.whole]
    area[~got.whole] = [_shoelace(got.polygon[r, :got.count[r]]) for r in rows]
    total = np.bincount(got.region, area, minlength=len(count))
    for k in range(len(count)):
        if count[k] >= 3:
            want = _shoelace(poly[k, :count[k]])
            assert abs(total[k] - want) <= 1e-9 * want, k
    for r, c, w, b in zip(got.region, got.cell, got.whole, got.border):
        p = poly[r, :count[r]]
        edge = np.roll(p, -1, axis=0) - p
        if w:
            corners = (c + np.array([[0, 0], [1, 0], [1, 1], [0, 1]])) * patch
            cross = edge[:, None, 0] * (corners[None, :, 1] - p[:, None, 1]) \
                - edge[:, None, 1] * (corners[None, :, 0] - p[:, None, 0])
            assert np.all(cross >= -1e-9 * patch * np.hypot(*edge.T)[:, None])
        elif np.ptp(p, axis=0).max() > patch:                          # (a small region is its own piece)
            q = got.polygon[b, :got.count[b]] / patch - c
            assert q.min() >= -1e-9 and q.max() <= 1 + 1e-9
    return len(got)


@pytest.mark.parametrize("seed", range(2))
def test_pieces_tile_regions(seed):
    rng = np.random.default_rng(20 + seed)
    for patch in (0.25, 1.0, 3.0):
        poly, count = _random_regions(rng, 30, patch)
        assert _tiles(_moved(poly, ANGLES[seed + 1], (0.0, 0.0)), count, patch) > 30
    grid, grid_count = _batch(_grid_regions(0.5), 7)
    assert _tiles(grid[:6], grid_count[:6], 0.5) > 0


def test_thread_count():
    """The same bits on one Dr.Jit thread and on several (no atomics, no order from timing)."""
    import drjit as dr
    poly, count = _random_regions(np.random.default_rng(30), 200, 0.5)
    threads = dr.thread_count()
    try:
        dr.set_thread_count(1)
        one = fused.pieces_of(poly, count, 0.5)
        dr.set_thread_count(max(threads, 4))
        many = fused.pieces_of(poly, count, 0.5)
    finally:
        dr.set_thread_count(threads)
    assert all(np.array_equal(getattr(one, f), getattr(many, f)) for f in FIELDS)
    assert _same(poly, count, 0.5) > 10000


def test_urban_calls(monkeypatch):
    """Every call of ``simulate("urban")``: the inputs recorded, the device compared."""
    from sarmitsuba.pipeline import simulate
    from sarmitsuba.tracing.driver import mesh_trace
    from sarmitsuba.tracing.visibility import lit_pieces
    calls, reference = [], piece_cuts.pieces_of

    def record(polygon, count, patch, span=None, **kw):
        calls.append((np.array(polygon, copy=True), np.array(count, copy=True), patch,
                      None if span is None else np.array(span, copy=True)))
        return reference(polygon, count, patch, span, **kw)

    modules = [m for m in (piece_cuts, lit_pieces, mesh_trace) if hasattr(m, "pieces_of")]
    for module in modules:
        monkeypatch.setattr(module, "pieces_of", record)
    simulate("urban", integrator_overrides={"geometry": "reference"})
    for module in modules:
        monkeypatch.setattr(module, "pieces_of", reference)
    assert len(calls) > 3 and any(c[3] is not None for c in calls)
    assert sum(_same(*c) for c in calls) > 10000
