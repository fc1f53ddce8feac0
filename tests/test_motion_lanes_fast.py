"""Round-2 speed-ups of the mesh tracer's motion and lanes against the forms they replaced:
:meth:`sarmitsuba.tracing.mesh.patches.Pieces.geometry_of` (each piece's geometry computed once per
:class:`Pieces` object and gathered) against ``select(keep).geometry()``, and the flat
row gather of ``MeshTracer._motion``'s candidate lines against the former ``[k, j]`` gather.
Both bit for bit (the same float operations; only the gathers differ).
"""
from __future__ import annotations

import numpy as np

from sarmitsuba.tracing.mesh.piece_cuts import pieces_of
from sarmitsuba.tracing.visibility.motion import line_rates
from sarmitsuba.tracing.driver.mesh_trace import _unit_rows
from test_patches_fast import _regions


def test_geometry_of_is_select_geometry():
    rng = np.random.default_rng(11)
    patch = 1.3127
    poly, count = _regions(rng, 40, patch)
    p = pieces_of(poly, count, patch)
    assert p.whole.any() and (~p.whole).any()
    asks = [rng.random(len(p)) > 0.6, rng.permutation(len(p))[:50], np.zeros(len(p), bool), np.array([], np.int64),
            np.concatenate([np.arange(5), np.arange(5)]), np.ones(len(p), bool), rng.permutation(len(p))]
    for keep in asks:                       # overlapping asks: some pieces cached, some new, repeats
        got, want = p.geometry_of(keep), p.select(keep).geometry()
        for g, w in zip(got, want):
            assert g.shape == w.shape and g.dtype == w.dtype
            np.testing.assert_array_equal(g, w)
    # a fresh object (as select makes) holds no cache of the one it came from
    q = p.select(np.arange(0, len(p), 2))
    for g, w in zip(q.geometry_of(np.arange(len(q))[::-1]), q.select(np.arange(len(q))[::-1]).geometry()):
        np.testing.assert_array_equal(g, w)


def _add_reference(piece, lines, line_rates_):
    """``MeshTracer._motion``'s ``add`` as it was: the unit rows by ``np.nonzero`` and [k, j] gathers."""
    real = np.abs(np.sqrt(lines[..., 0] * lines[..., 0] + lines[..., 1] * lines[..., 1]) - 1.0) < 1e-6
    k, j = np.nonzero(real)
    return piece[k], lines[k, j], (line_rates_[k, j] if line_rates_ is not None else np.zeros((len(k), 3)))


def test_motion_line_gather_is_the_reference():
    rng = np.random.default_rng(3)
    for n, h in [(0, 6), (7, 0), (1, 1), (50, 8)]:
        angle = rng.uniform(0, 2 * np.pi, (n, h))
        lines_a = np.stack([np.cos(angle), np.sin(angle), rng.normal(size=(n, h))], axis=-1)
        lines_a[rng.random((n, h)) < 0.3] = 0.0                   # padding rows (not unit)
        lines_b = lines_a + 1e-3 * rng.normal(size=lines_a.shape)
        piece = rng.integers(0, 20, n)
        rates = line_rates(lines_a, lines_b, rng.uniform(0, 2, n))
        # (a view that is not contiguous, as lines gathered by a chain index can be)
        for lines, r in [(lines_a, rates), (lines_a, None), (lines_a[:, ::-1], rates[:, ::-1])]:
            for g, w in zip(_unit_rows(piece, lines, r), _add_reference(piece, lines, r)):
                assert g.shape == w.shape and g.dtype == w.dtype
                np.testing.assert_array_equal(g, w)


def test_edges_degenerate_batches_are_the_reference():
    from test_patches_fast import _edges_reference
    rng = np.random.default_rng(5)
    patch = 0.9173
    poly, count = _regions(rng, 25, patch)
    p = pieces_of(poly, count, patch)
    whole_only = p.select(p.whole)
    border_only = p.select(~p.whole)
    for q, rows in [(p, None), (p, np.array([], np.int64)), (whole_only, None), (border_only, None),
                    (border_only, rng.permutation(len(border_only))[:9]), (p.select(np.array([], np.int64)), None)]:
        for g, w in zip(q.edges(rows), _edges_reference(q, rows)):
            assert g.shape == w.shape and g.dtype == w.dtype
            np.testing.assert_array_equal(g, w)


def test_norm2_is_linalg_norm():
    from sarmitsuba.tracing.driver.mesh_trace import _norm2
    rng = np.random.default_rng(8)
    x = np.concatenate([rng.normal(size=(200, 2)) * 10.0 ** rng.integers(-8, 8, (200, 1)), np.zeros((3, 2)),
                        [[1e-300, 1e-300], [1e150, -1e150]]])
    np.testing.assert_array_equal(_norm2(x), np.linalg.norm(x, axis=1))
    assert _norm2(np.zeros((0, 2))).shape == (0,)


def test_norm_is_linalg_norm():
    """``row_norm`` (used by ``_carried`` in place of np.linalg.norm) is the same sum, bit for bit."""
    from sarmitsuba.core.arrays import row_norm as _norm
    rng = np.random.default_rng(9)
    x = np.concatenate([rng.normal(size=(300, 3)) * 10.0 ** rng.integers(-8, 8, (300, 1)), np.zeros((2, 3))])
    np.testing.assert_array_equal(_norm(x), np.linalg.norm(x, axis=1))
