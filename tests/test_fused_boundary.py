"""The lit boundary on the Dr.Jit device (:func:`sarmitsuba.tracing.fused.boundary.lit_boundary`)
against its NumPy reference (:func:`sarmitsuba.tracing.visibility.occlusion.lit_boundary`): the
same segments in the same order, bit for bit.

Cases: random pieces with a few random convex cut-outs; cut-outs along one line (their insides on
the same side, in both orders, and on opposite sides), along their piece's edge, covering the
piece, nested, overlapping and repeated; a piece with more than a hundred cut-outs; repeated
corners, pieces without edges, no cut-outs at all; all of it moved 1e5 m and turned by angles
that make the shared lines shared only to rounding; and every call of ``simulate("urban")``.

Deliberate bugs these tests were run against (each fails the tests named; ``test_urban_calls``
caught every one too):
  * the earlier-listed rule dropped on a shared line (``same_in = ~is_cut``: both cut-outs keep
    the edge): ``test_shared_lines`` (all), ``test_covering_nested`` (the repeated cut-out),
    ``test_degenerate``;
  * the box test without :data:`~sarmitsuba.tracing.visibility.occlusion.BOX_SLACK`:
    ``test_shared_lines`` with lines shared to rounding (``gap`` > 0) at 0 and 90 degrees,
    ``test_thread_count``;
  * the gaps walked in row order instead of the order of the intervals' starts:
    ``test_random_pieces``, ``test_shared_lines``, ``test_many_cutouts``, ``test_thread_count``;
  * a cut-out's edge outside its piece (``e0 <= s0``) still kept whole: every test;
  * the inside rule on a line swapped (``same`` and ``other``): every test;
  * the tail gap kept without the 1e-12 m length cut: ``test_random_pieces``,
    ``test_shared_lines`` (turned), ``test_covering_nested``, ``test_many_cutouts``,
    ``test_degenerate``, ``test_thread_count``;
  * the on-line tolerance of a cut-out's edge in its piece without its 1 m floor
    (``COINCIDENT * length``): ``test_shared_lines`` on the 0.5 m square;
  * a maximum written ``x >= y ? x : y`` (``_np_max``: the first of two equal zeros):
    ``test_signed_zeros_are_kept``; the comparison is of the arrays' bits (:func:`bits`), as
    ``np.array_equal`` takes ``-0.0`` for ``+0.0`` and passes it.
"""
from __future__ import annotations

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (the variant first)
from sarmitsuba.tracing.fused.boundary import lit_boundary
from sarmitsuba.tracing.mesh.polygons import clip, edge_lines, pad
from sarmitsuba.tracing.visibility import occlusion

ANGLES = (0.0, 0.3, 1.1, np.pi / 2, 2.5, np.radians(37.0), -0.7)
OFFSETS = ((0.0, 0.0), (1e5, -1e5))


def bits(x: np.ndarray) -> np.ndarray:
    """The array's bits as unsigned integers of its own width: ``-0.0`` and ``+0.0`` differ, as
    do NaNs of different payloads (``np.array_equal`` takes the zeros as equal)."""
    x = np.ascontiguousarray(x)
    return x.view(np.dtype(f"u{x.dtype.itemsize}")) if x.dtype.kind in "fc" else x


def _same(*args) -> int:
    """Assert the device's segments are the reference's, bit for bit (signed zeros included);
    their number."""
    want = occlusion.lit_boundary(*args)
    got = lit_boundary(*args)
    assert [x.dtype for x in got] == [x.dtype for x in want]
    assert [x.shape for x in got] == [x.shape for x in want]
    for g, w in zip(got, want):
        assert np.array_equal(bits(g), bits(w))
    return len(want[0])


def _batch(polys, width=None):
    """Corner lists as a padded batch ``(poly [n, W, 2], count [n])``."""
    width = width or max([len(p) for p in polys] + [3])
    poly = np.zeros((len(polys), width, 2))
    count = np.array([len(p) for p in polys], np.int64)
    for i, p in enumerate(polys):
        poly[i, :len(p)] = p
    return pad(poly, count), count


def _moved(args, angle, offset):
    """``args`` turned by ``angle`` about the origin and moved by ``offset`` (counter-clockwise
    stays counter-clockwise)."""
    base, base_count, cut, cut_count, owner = args
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    return base @ rot.T + offset, base_count, cut @ rot.T + offset, cut_count, owner


def _rect(x0, y0, x1, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def _convex(rng, n, centre, radius):
    angle = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = radius * rng.uniform(0.5, 1.0, n)
    return np.stack([centre[0] + r * np.cos(angle), centre[1] + r * np.sin(angle)], axis=1)


def _random_case(rng, n_base, cuts_per=(1, 5), extra_base=None):
    """Rectangles and convex quadrilaterals with random convex cut-outs clipped to them."""
    bases = []
    for _ in range(n_base):
        w, h = rng.uniform(0.5, 20.0, 2)
        if rng.random() < 0.5:
            bases.append(_rect(0, 0, w, h))
        else:
            bases.append(_convex(rng, 4, (w / 2, h / 2), max(w, h)))
    base, base_count = _batch(bases, 6)
    polys, owner = [], []
    for i in range(n_base):
        k = extra_base if (extra_base is not None and i == 0) else rng.integers(cuts_per[0], cuts_per[1] + 1)
        centre, size = base[i, :base_count[i]].mean(axis=0), np.ptp(base[i, :base_count[i]], axis=0).max()
        for _ in range(k):
            polys.append(_convex(rng, rng.integers(3, 7), centre + rng.normal(0, 0.4 * size, 2),
                                 size * rng.uniform(0.05, 0.6)))
            owner.append(i)
    cut, count = _batch(polys, 6)
    owner = np.array(owner, np.int64)
    cut, count = clip(cut, count, edge_lines(base, base_count)[owner])
    real = count >= 3
    return base, base_count, cut[real], count[real], owner[real]


@pytest.mark.parametrize("seed", range(4))
def test_random_pieces(seed):
    rng = np.random.default_rng(seed)
    args = _random_case(rng, 60)
    assert len(args[2]) > 60
    for angle, offset in [(0.0, (0.0, 0.0)), (ANGLES[seed + 1], OFFSETS[seed % 2])]:
        assert _same(*_moved(args, angle, offset)) > 0


def _shared_case(same_first: bool, scale: float, gap: float):
    """A square ``10 scale`` m wide with cut-outs along one line: A and B on opposite sides of
    x = 5 (B ``gap`` beyond it), C on A's side (``gap`` short of it; listed after A, or before it)
    where B leaves A's edge bare, D along the square's left edge, E along its bottom edge (both
    ``gap`` inside) and overlapping B; a second square with two cut-outs on either side of y = 6."""
    a, b, c = _rect(2, 2, 5, 6), _rect(5 + gap, 3, 8, 5), _rect(3, 4, 5 - gap, 8)
    d, e = _rect(gap, 7, 3, 9), _rect(6, gap, 9, 4)
    cuts = [a, b, c, d, e] if same_first else [c, b, a, d, e]
    base, base_count = _batch([_rect(0, 0, 10, 10), _rect(0, 0, 10, 10)], 5)
    cut, count = _batch(cuts + [_rect(2, 2, 5, 6), _rect(2, 6 + gap, 5, 9)], 5)
    owner = np.array([0, 0, 0, 0, 0, 1, 1], np.int64)
    return base * scale, base_count, cut * scale, count, owner


@pytest.mark.parametrize("scale, gap", [(1.0, 0.0), (1.0, 3e-12), (0.05, 5e-10)])
@pytest.mark.parametrize("same_first", [True, False])
@pytest.mark.parametrize("angle", ANGLES)
def test_shared_lines(same_first, angle, scale, gap):
    """Lines shared exactly, to rounding (the boxes meet by their slack only) and, on edges
    shorter than a metre, to the on-line tolerance's floor (1e-9 m)."""
    args = _shared_case(same_first, scale, gap / scale)
    for offset in OFFSETS:
        assert _same(*_moved(args, angle, offset)) > 0


def test_covering_nested():
    pieces = [_rect(0, 0, 4, 4)] * 5
    base, base_count = _batch(pieces, 4)
    cuts = [(_rect(0, 0, 4, 4), 0),                                     # the whole piece
            (_rect(0, 0, 4, 4), 1), (_rect(1, 1, 2, 2), 1),             # the whole piece, and inside it
            (_rect(0.5, 0.5, 3.5, 3.5), 2), (_rect(1, 1, 2, 2), 2),     # nested
            (_rect(1, 1, 3, 2), 3), (_rect(2, 1.5, 3.5, 3), 3), (_rect(1, 1, 3, 2), 3),   # overlapping, repeated
            ([(2, 0), (4, 2), (2, 4), (0, 2)], 4), ([(1, 1), (3, 1), (3, 3), (1, 3)], 4)]  # corners on edges
    cut, count = _batch([c for c, _ in cuts], 4)
    owner = np.array([o for _, o in cuts], np.int64)
    for angle in ANGLES[:4]:
        for offset in OFFSETS:
            _same(*_moved((base, base_count, cut, count, owner), angle, offset))


def test_many_cutouts():
    rng = np.random.default_rng(7)
    args = _random_case(rng, 8, extra_base=220)
    base, base_count, cut, count, owner = args
    assert np.bincount(owner)[0] > 100
    # long strips across piece 0: every edge meets many cut-outs
    w, h = np.ptp(base[0, :base_count[0]], axis=0)
    x0, y0 = base[0, :base_count[0]].min(axis=0)
    strips = [_rect(x0 + w * t, y0 - h, x0 + w * (t + 0.03), y0 + 2 * h) for t in np.linspace(0.0, 0.9, 30)]
    strips += [[(x0 + w * t, y0 - h), (x0 + w * (t + 0.5), y0 - h), (x0 + w * (t + 0.1), y0 + 2 * h)]
               for t in np.linspace(-0.3, 0.9, 20)]
    more, more_count = _batch(strips, 6)
    more, more_count = clip(more, more_count, np.repeat(edge_lines(base, base_count)[:1], len(strips), axis=0))
    real = more_count >= 3
    width = max(cut.shape[1], more.shape[1])
    cut = np.concatenate([pad(np.concatenate([cut, np.zeros((len(cut), width - cut.shape[1], 2))], axis=1), count),
                          pad(np.concatenate([more[real], np.zeros((int(real.sum()), width - more.shape[1], 2))],
                                             axis=1), more_count[real])])
    args = (base, base_count, cut, np.concatenate([count, more_count[real]]),
            np.concatenate([owner, np.zeros(int(real.sum()), np.int64)]))
    assert _same(*args) > 0
    assert _same(*_moved(args, 0.9, OFFSETS[1])) > 0


def test_degenerate():
    sq = _rect(0, 0, 4, 4)
    repeated = [(0, 0), (0, 0), (4, 0), (4, 4), (4, 4), (0, 4)]
    base, base_count = _batch([repeated, sq, sq, sq], 7)
    base_count[2] = 0                               # nothing, and no cut-outs
    base_count[3] = 0                               # no edges, but cut-outs (their edges stay)
    cuts = [([(1, 1), (1, 1), (3, 1), (3, 3), (1, 3)], 0), (_rect(2, 2, 3, 3), 0),
            ([(0, 0), (2, 0), (2, 0), (2, 2)], 1), (_rect(1, 1, 2, 2), 3), (_rect(1.5, 1, 3, 2), 3)]
    cut, count = _batch([c for c, _ in cuts], 6)
    owner = np.array([o for _, o in cuts], np.int64)
    for angle in ANGLES[:3]:
        for offset in OFFSETS:
            _same(*_moved((base, base_count, cut, count, owner), angle, offset))
    # no cut-outs at all; no pieces at all; only pieces without edges
    _same(base, base_count, np.zeros((0, 4, 2)), np.zeros(0, np.int64), np.zeros(0, np.int64))
    _same(np.zeros((0, 4, 2)), np.zeros(0, np.int64), np.zeros((0, 4, 2)), np.zeros(0, np.int64),
          np.zeros(0, np.int64))
    assert _same(base[2:3], np.zeros(1, np.int64), np.zeros((0, 4, 2)), np.zeros(0, np.int64),
                 np.zeros(0, np.int64)) == 0


@pytest.mark.parametrize("case", ["random", "shared"])
def test_signed_zeros_are_kept(case):
    """The module promises NumPy's bits, signed zeros included: the cases mirrored through the
    origin (every coordinate negated, so corners on the axes carry ``-0.0``) give segments whose
    reference holds ``-0.0`` (232 of them in the random case, 6 in the shared lines), and the
    device's are the same bits. Catches a maximum written ``x >= y ? x : y`` (the first of two
    equal zeros, where NumPy's is the second), which ``np.array_equal`` (``-0.0 == 0.0``) lets
    through."""
    args = (_random_case(np.random.default_rng(0), 200, cuts_per=(3, 8)) if case == "random"
            else _shared_case(True, 1.0, 0.0))
    base, base_count, cut, cut_count, owner = args
    mirrored = (-base, base_count, -cut, cut_count, owner)
    want = occlusion.lit_boundary(*mirrored)
    assert sum(int(np.count_nonzero((w == 0) & np.signbit(w))) for w in want[1:]) > 0
    assert _same(*mirrored) > 0


def test_thread_count():
    """The same bits on one Dr.Jit thread and on several (no atomics, no order from timing)."""
    import drjit as dr
    args = _random_case(np.random.default_rng(11), 200, cuts_per=(3, 8))
    threads = dr.thread_count()
    try:
        dr.set_thread_count(1)
        one = lit_boundary(*args)
        dr.set_thread_count(max(threads, 4))
        many = lit_boundary(*args)
    finally:
        dr.set_thread_count(threads)
    assert all(np.array_equal(bits(x), bits(y)) for x, y in zip(one, many))
    _same(*args)


def test_urban_calls(monkeypatch):
    """Every call of ``simulate("urban")``: the inputs recorded, the device compared."""
    from sarmitsuba.pipeline import simulate
    calls, reference = [], occlusion.lit_boundary

    def record(*args):
        calls.append(tuple(np.array(a, copy=True) for a in args))
        return reference(*args)

    monkeypatch.setattr(occlusion, "lit_boundary", record)
    simulate("urban", integrator_overrides={"geometry": "reference"})
    monkeypatch.undo()
    assert len(calls) > 5 and sum(len(c[2]) for c in calls) > 1000
    assert sum(_same(*c) for c in calls) > 1000
