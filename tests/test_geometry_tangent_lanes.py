"""The pairing of a moved geometry's lanes with the geometry's own (docs/physics.md (AD4),
``tracing/derivatives/lane_pairs.py``, ``geometry_tangents.MovedTracer._tangent``): where no
lane of equal keys lies within the tolerance, the move changed the lit regions' topology and the
answer is a GeometryChange, not a tangent.

Truth: a shape translated by ``h`` moves each of its points by exactly ``h`` times the move's
field, so each lane's tangent is the field; a lane that vanishes while another appears (the
same count, a metre away) or a lane whose only match by features lies under another key (a
segment of another piece) is no lane of the geometry itself.

Deliberate bugs these were run against (each fails a test here): the KD-tree's key coordinate
dropped in ``match_rows`` (``group * 0``: the lanes paired by features alone); the in-order
fast path ignoring the keys; ``ALIGN_TOLERANCE`` made 100 times looser (5,000); the earlier
bounces' factors differenced over ``|step|`` in ``geometry_tangents._difference`` (the one-sided
derivative from ``-h`` with its sign flipped).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (its libLLVM before drjit's)
from sarmitsuba.tracing.derivatives.geometry_tangents import GeometryMove, MovedTracer
from sarmitsuba.tracing.derivatives.lane_pairs import GeometryChange, align_terms, match_rows
from sarmitsuba.tracing.integration.patch_terms import SINC, PieceTable, TermLanes
from sarmitsuba.tracing.integration.surface_clutter import ScattererLanes

STEP = 1e-3


def test_rows_of_equal_features_under_other_keys_are_not_paired():
    """Two rows whose features sit at 0 and 5 m under keys 1 and 2, and their moved rows with
    the same features under the swapped keys (key 1 now at 5 m): no row of key 1 lies within
    the tolerance of key 1's row, so ``match_rows`` raises GeometryChange; with the moved rows
    also swapped in place (each key at its own features, 1e-9 m off) it pairs them across, by
    key. Catches the pairing by features alone (it pairs equal features under different keys,
    [0, 1], and returns)."""
    keys, swapped = np.array([[1], [2]]), np.array([[2], [1]])
    features = np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    with pytest.raises(GeometryChange):
        match_rows(keys, features, swapped, features, 1e-6)
    assert match_rows(keys, features, swapped, features[::-1] + 1e-9, 1e-6).tolist() == [1, 0]


def _two_pieces(segment_mid: np.ndarray) -> tuple[TermLanes, PieceTable]:
    """Two lit pieces 10 m apart, a SINC lane naming each, and one boundary segment each (1 m
    along x, its midpoint ``segment_mid[i]``)."""
    centroid = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    lanes = TermLanes(kind=np.full(2, SINC, np.int32), point=centroid.copy(), unfolded=centroid.copy(),
                      middle=centroid.copy(), middle_unfolded=centroid.copy(), edge=np.tile([1.0, 0, 0], (2, 1)),
                      normal=np.tile([0, 0, 1.0], (2, 1)), fold=np.tile(np.eye(3), (2, 1, 1)), sub=np.zeros(2, np.int64),
                      row=np.zeros(2, np.int64), piece=np.arange(2), stable=np.ones(2, bool))
    table = PieceTable(centroid=centroid, centroid_unfolded=centroid + [0.0, 0.0, 40.0], diagonal=np.ones(2),
                       area=np.ones(2), moments=np.ones((2, 3)), axis_u=np.tile([1.0, 0, 0], (2, 1)),
                       axis_v=np.tile([0, 1.0, 0], (2, 1)), segment_start=np.arange(2, dtype=np.uint32),
                       segment_count=np.ones(2, np.uint32), segment_mid=np.asarray(segment_mid, float),
                       segment_edge=np.tile([1.0, 0, 0], (2, 1)))
    return lanes, table


def test_a_segment_is_not_paired_with_another_pieces_segment():
    """The pieces' boundary segments are keyed by the piece they belong to. Moved, piece 0's
    segment lies 3 m away, exactly where piece 1's segment was, and piece 1's where piece 0's
    was (equal features under the other key): no segment of piece 0 lies within the tolerance,
    so ``align_terms`` raises GeometryChange; moved by 1e-9 m each keeps its own (tangent 1 m/m
    along y for a move of 1e-9 m along y, the closed form of a translation). Catches the
    pairing by features alone: it pairs each segment with the other piece's, tangent 0 (a wrong
    tangent instead of the GeometryChange)."""
    mid = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    lanes, table = _two_pieces(mid)
    moved_lanes = dataclasses.replace(lanes, point=lanes.point + [0.0, 1e-9, 0.0])
    with pytest.raises(GeometryChange):
        align_terms(lanes, table, moved_lanes, dataclasses.replace(table, segment_mid=mid[::-1].copy()), 1e-6)
    _, paired = align_terms(lanes, table, moved_lanes, dataclasses.replace(table, segment_mid=mid + [0.0, 1e-9, 0.0]),
                            1e-6)
    assert np.allclose((paired.segment_mid - mid) / 1e-9, [[0.0, 1.0, 0.0]] * 2, atol=1e-6)


class _Kernel:
    """Stands for the clutter kernel: keeps the tangent lanes ``_tangent`` uploads."""

    def __init__(self):
        self.uploaded = []

    def upload(self, *lanes_and_depth):
        self.uploaded.append(lanes_and_depth[:-1])
        return {}


def _scatterers(x: np.ndarray) -> ScattererLanes:
    n = len(x)
    point = np.column_stack([x, np.zeros(n), np.zeros(n)])
    return ScattererLanes(point=point, unfolded=point + [0.0, 0.0, 40.0], normal=np.tile([0, 0, 1.0], (n, 1)),
                          fold=np.tile(np.eye(3), (n, 1, 1)), sub=np.zeros(n, np.int64), row=np.zeros(n, np.int64),
                          phase=np.zeros(n), phase_cross=np.zeros(n))


def test_a_lane_that_vanishes_as_another_appears_is_a_geometry_change():
    """The shape (field 1 m/m along z, step h = 1 mm: the tracer's tolerance 50 h = 5 cm)
    translated: its scatterers at x = 0 and 1 m come back shuffled, each 1 mm higher, and
    ``MovedTracer._tangent`` pairs them, each tangent the field (0, 0, 1), the closed form of a
    translation. Where the moved geometry instead has the lanes at 1 m and 0.5 m (the one at 0
    gone, one 0.5 m away new: 500 h, ten times the tolerance) it raises GeometryChange. Catches
    the tolerance made 100 times looser (5 m: it pairs 0 with 0.5 m, a tangent of 500 m/m)."""
    field = np.tile([0.0, 0.0, 1.0], (4, 1))
    move = GeometryMove(shape=0, field=field, step=STEP)
    main = _scatterers(np.array([0.0, 1.0]))
    up = _scatterers(np.array([1.0, 0.0]))
    up = dataclasses.replace(up, point=up.point + STEP * field[:2], unfolded=up.unfolded + STEP * field[:2])
    kernel = _Kernel()
    MovedTracer._tangent(kernel, (main,), (up,), move, 0, STEP)
    (tangent,), = kernel.uploaded
    assert np.allclose(tangent.point, field[:2], atol=1e-9) and np.allclose(tangent.unfolded, field[:2], atol=1e-9)
    jumped = _scatterers(np.array([1.0, 0.5]))
    with pytest.raises(GeometryChange):
        MovedTracer._tangent(_Kernel(), (main,), (jumped,), move, 0, STEP)


class _GammaKernel(_Kernel):
    """A kernel whose upload holds an earlier bounce's factor ``gamma = 0.5 + 0.2 cos`` of each
    lane's first window's cosine (float64): linear, so its difference quotient is exact."""

    def upload(self, *lanes_and_depth):
        import mitsuba as mi
        super().upload(*lanes_and_depth)
        return {"gamma": mi.Float64(0.5 + 0.2 * np.asarray(lanes_and_depth[0].window_cos, float)[:, 0])}


@pytest.mark.parametrize("step", [STEP, -STEP], ids=["from above", "one-sided from below"])
def test_an_earlier_bounces_factor_has_its_derivative_from_either_side(step):
    """A second bounce's scatterers (depth 1) whose window's cosine changes at 0.3 per unit of
    the parameter (its lanes at ``p + step`` hold ``cos + 0.3 step``), under an earlier bounce's
    factor ``gamma = 0.5 + 0.2 cos``: the tangent ``MovedTracer._tangent`` keeps for ``gamma`` is
    its derivative, 0.2 x 0.3 = 0.06, and the points' tangent the field, from above (``+h``) and from below (``-h``, the one-sided
    derivative a topology change above asks for). Catches the difference of ``gamma`` divided by
    ``|step|``: -0.06 from below (reached only at depth > 0, where the earlier bounces' factors
    are differenced on the device)."""
    import drjit as dr
    field = np.tile([0.0, 0.0, 1.0], (4, 1))
    move = GeometryMove(shape=0, field=field, step=STEP)
    main = _scatterers(np.array([0.0, 1.0]))
    windows = {"first": np.tile([0.0, 0.6, -0.8], (2, 1)), "window_row": np.zeros((2, 1), np.int64),
               "window_cos": np.array([[0.7], [0.4]]), "window_direction": np.tile([0.0, 0.6, -0.8], (2, 1, 1)),
               "window_normal": np.tile([0.0, 0.0, 1.0], (2, 1, 1))}
    main = dataclasses.replace(main, **windows)
    moved = dataclasses.replace(main, point=main.point + step * field[:2], unfolded=main.unfolded + step * field[:2],
                                window_cos=main.window_cos + 0.3 * step)
    kernel = _GammaKernel()
    tangent = MovedTracer._tangent(kernel, (main,), (moved,), move, 1, step)
    assert np.allclose(kernel.uploaded[0][0].point, field[:2], atol=1e-9)        # the translation's field
    gamma = tangent["gamma"]
    dr.eval(gamma)
    assert np.allclose(np.asarray(gamma.numpy(), float), 0.06, rtol=1e-6)
