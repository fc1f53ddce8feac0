"""The cut-outs of mixed pieces: each (piece, occluder) pair's piece clipped to the occluder's
shadow, and the pieces that a cut-out covers whole (docs/physics.md (M4)).

The readable NumPy reference of this step of :func:`sarmitsuba.tracing.visibility.occlusion.clip_mixed`;
``tracing/fused/clipping.py`` is its Dr.Jit kernel, tested against it bit for bit.
"""
from __future__ import annotations

import numpy as np

from ..mesh.polygons import clip

__all__ = ["cut_outs", "polygon_areas", "COVERED"]

#: A cut-out whose area is at least this fraction of its piece's covers the piece: nothing of the
#: piece is lit.
COVERED = 1.0 - 1e-12


def cut_outs(poly: np.ndarray, count: np.ndarray, pair_piece: np.ndarray, lines: np.ndarray):
    """Each pair's piece clipped to its shadow, and which pieces a cut-out covers.

    Parameters
    ----------
    poly : float64 [g, V, 2]
        The pieces, counter-clockwise, padded with their first corner (face coordinates, m).
    count : int64 [g]
        Their corners.
    pair_piece : int64 [m]
        Each pair's piece (a row of ``poly``).
    lines : float64 [m, H, 3]
        Each pair's shadow as half-planes ``a x + b y + c >= 0`` (:func:`sarmitsuba.tracing.visibility.occlusion.shadow_lines`).

    Returns
    -------
    cut : float64 [m, W, 2]
        The cut-outs (:func:`sarmitsuba.tracing.mesh.polygons.clip`: padded, ``W`` at least 3).
    cut_count : int64 [m]
        Their corners (0: the shadow misses the piece).
    dark : bool [g]
        The pieces that some cut-out covers (its area at least :data:`COVERED` times the piece's).
    """
    cut, cut_count = clip(np.take(poly, pair_piece, axis=0), np.take(count, pair_piece), lines)
    cut_area = polygon_areas(cut, cut_count)
    piece_area = polygon_areas(poly, count)
    dark = np.zeros(len(poly), bool)
    dark[pair_piece[cut_area >= COVERED * np.take(piece_area, pair_piece)]] = True
    return cut, cut_count, dark


def polygon_areas(poly: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The areas float64 [n] of :func:`sarmitsuba.tracing.mesh.polygons.moments` (its arithmetic, to the
    bit), without the other moments (the shoelace formula about the first corner)."""
    x, y = poly[..., 0] - poly[:, :1, 0], poly[..., 1] - poly[:, :1, 1]   # about the first corner
    cross = x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y
    return np.where(count < 3, 0.0, 0.5 * cross.sum(axis=1))
