"""The cut-outs of mixed pieces on the Dr.Jit device (docs/physics.md (M4), docs/design.md
section 10.1, step 4).

:func:`sarmitsuba.tracing.visibility.cut_outs.cut_outs` is the readable NumPy reference: each
(piece, occluder) pair's piece clipped to the occluder's shadow, and the pieces that a cut-out
covers. Here the same results, bit for bit, from two kernels, one lane per pair:

1. *clip*: the lane gathers its piece's corners from the pieces' table on the device (no
   per-pair copy of the polygons on the host) and clips them to its shadow's half-planes
   (:func:`sarmitsuba.tracing.mesh.polygon_kernels.clip_on_device`, Sutherland and Hodgman);
2. *cover*: the cut-out's area and its piece's, each the reference's shoelace sum over the
   batch's slots in NumPy's pairwise order (:func:`sarmitsuba.tracing.fused.moments.lane_moments`;
   the slots unrolled, one kernel per pair of widths), compared as the reference compares them;
   a covering cut-out writes ``True`` to its piece's flag (every writer writes the same value:
   no order from thread timing).

The host reads the counts between the two (their largest is the cut-outs' width, which fixes the
order of the area's sums) and the results. Batches of fewer than :data:`DEVICE_PAIRS` pairs, and
those the kernel leaves (corners that are not finite, polygons not padded, a lane that gains more
than one corner at a half-plane), are the reference's own. The ``cuda`` variants have not been
compared.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..device import device_array, releasing, table_array
from ..mesh.polygon_kernels import clip_on_device
from ..mesh.polygons import REPEAT_DISTANCE, padded
from ..visibility import cut_outs as reference
from .moments import lane_moments

__all__ = ["cut_outs", "DEVICE_PAIRS"]

#: Pairs below which :func:`cut_outs` calls the reference (its kernels' launches and read-backs
#: cost more than NumPy's loops there). Medians on the 2-core VM, one of Munich's batches (5,693
#: pieces, 11 half-planes a shadow) cut to its first pairs: 1,024 pairs 2.0 ms against the
#: reference's 1.7, 2,048 1.3 against 2.8, 8,192 3.0 against 6.6; its 28,167 pairs 9.6 against 14.6.
DEVICE_PAIRS = 2048


@releasing
def cut_outs(poly: np.ndarray, count: np.ndarray, pair_piece: np.ndarray, lines: np.ndarray):
    """:func:`sarmitsuba.tracing.visibility.cut_outs.cut_outs` on the device: the same cut-outs
    and dark flags, bit for bit.

    Parameters and returns as the reference's (``poly`` float64 [g, V, 2], ``count`` int64 [g],
    ``pair_piece`` int64 [m], ``lines`` float64 [m, H, 3]; ``(cut float64 [m, W, 2], cut_count
    int64 [m], dark bool [g])``).
    """
    poly = np.asarray(poly)
    count = np.asarray(count, np.int64)
    pair_piece = np.asarray(pair_piece, np.int64)
    lines = np.asarray(lines, np.float64)
    if len(pair_piece) < DEVICE_PAIRS or poly.dtype != np.float64 or poly.ndim != 3 or poly.shape[1] < 3 \
            or not padded(poly, count) or not np.isfinite(poly).all():
        return reference.cut_outs(poly, count, pair_piece, lines)
    clipped = clip_on_device(poly, count, lines, REPEAT_DISTANCE, rows=pair_piece)
    if clipped is None:
        return reference.cut_outs(poly, count, pair_piece, lines)
    out, cut_count, cap = clipped
    width = max(int(cut_count.max(initial=0)), 3)
    dark = _covered(out, cap, width, cut_count, poly, count, pair_piece)
    cut = np.ascontiguousarray(out.numpy().reshape(len(pair_piece), cap, 2)[:, :width])
    return cut, cut_count, dark


def _covered(out, cap: int, width: int, cut_count: np.ndarray, poly: np.ndarray, count: np.ndarray,
             pair_piece: np.ndarray) -> np.ndarray:
    """The second kernel of :func:`cut_outs`: bool [g], the pieces that some cut-out covers
    (``out`` the clipped corners on the device, ``cap`` slots a lane; ``width`` the cut-outs'
    width)."""
    f64, u32 = mi.Float64, mi.UInt32
    m, slots = len(pair_piece), poly.shape[1]
    lane = dr.arange(u32, m) * cap
    cut_x = [dr.gather(f64, out, (lane + j) * 2) for j in range(width)]
    cut_y = [dr.gather(f64, out, (lane + j) * 2 + 1) for j in range(width)]
    piece = device_array(u32, pair_piece)
    table_x = table_array(f64, poly[..., 0].reshape(-1))
    table_y = table_array(f64, poly[..., 1].reshape(-1))
    base = piece * slots
    piece_x = [dr.gather(f64, table_x, base + j) for j in range(slots)]
    piece_y = [dr.gather(f64, table_y, base + j) for j in range(slots)]
    cut_area = lane_moments(cut_x, cut_y, device_array(mi.Int32, np.minimum(cut_count, 3)))[0]
    piece_area = lane_moments(piece_x, piece_y, dr.gather(mi.Int32, table_array(mi.Int32, np.minimum(count, 3)), piece))[0]
    dark = dr.zeros(mi.Bool, len(poly))
    dr.scatter(dark, True, piece, cut_area >= reference.COVERED * piece_area)
    dr.eval(dark)
    return dark.numpy()
