"""Truncation rims: where a ground shape's model stops, not where the world does (docs/physics.md (M10)).

Physical optics over a finite plate returns its rim; a plane continuing beyond the beam returns
nothing away from its specular direction. A shape that stands for ground
(:func:`sarmitsuba.scene.ground.ground_shapes`) continues: the free edges of its parts (no other
face meets them, they lie on no other part: :attr:`sarmitsuba.tracing.integration.edges.Wedges.free`)
are truncations. The mesh tracer leaves out

* the physical-optics terms of the boundary segments of stable pieces that lie on a truncation
  rim (:func:`on_rim`): the terms a continuing plane's next patch would cancel (M5);
* the edge currents of those edges, single (E4) and double across a face (E6): they are not
  free edges.

* :func:`ground_parts` -- bool per part: of a ground shape;
* :func:`rim_edges` -- bool [n_parts, V]: each part's border edges that are truncations;
* :func:`without_rims` -- the wedges with the truncation edges no longer free (no edge currents);
* :func:`on_rim` -- bool per segment: lies on one of its part's truncation edges.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ...scene.ground import ground_shapes
from ..mesh.patches import Surfaces, shape_indices
from .edges import ON_EDGE, Wedges

__all__ = ["ground_parts", "rim_edges", "without_rims", "on_rim"]


def ground_parts(scene, surfaces: Surfaces, setting: str) -> np.ndarray:
    """bool [n_parts]: the parts of the shapes ``setting`` (the ``sbr`` ``ground_shapes``) names.
    Raises ParameterError for a shape id the scene does not have."""
    shapes = list(scene.shapes())
    flags = ground_shapes(setting, [shape.id() for shape in shapes])
    if not np.any(flags) or surfaces.n_parts == 0:
        return np.zeros(surfaces.n_parts, bool)
    index = shape_indices(shapes)                       # what Surfaces.shape_id holds
    lookup = np.zeros(max(int(index.max()), int(np.max(surfaces.shape_id))) + 1, bool)
    lookup[index[flags]] = True
    return lookup[np.asarray(surfaces.shape_id, np.int64)]


def rim_edges(s: Surfaces, wedges: Wedges, ground: np.ndarray) -> np.ndarray:
    """bool [n_parts, V]: border edge ``i`` of each part (corner ``i`` to ``i + 1``) is a
    truncation: free (``wedges.free``) and of a ground part (``ground`` bool [n_parts])."""
    rim = np.zeros(s.polygon.shape[:2], bool)
    edge = np.flatnonzero(wedges.free & ground[wedges.part])
    part = wedges.part[edge]
    rim[part, edge - wedges.base[part]] = True
    return rim


def without_rims(wedges: Wedges, rim: np.ndarray) -> Wedges:
    """``wedges`` with its truncation edges (``rim`` [n_parts, V], :func:`rim_edges`) no longer
    free: they neither diffract (E4) nor end a double diffraction across a face (E6)."""
    corner = np.arange(len(wedges.part)) - wedges.base[wedges.part]
    return dataclasses.replace(wedges, free=wedges.free & ~rim[wedges.part, corner])


def on_rim(s: Surfaces, rim: np.ndarray, part: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """bool [m]: segment ``start -> end`` (face coordinates of ``part``, float64 [m, 2]) lies on a
    truncation edge of its part (both ends within ``ON_EDGE (1 + edge length)`` [m] of the edge's
    line, the tolerance :func:`sarmitsuba.tracing.integration.edges.segment_wedges` uses)."""
    out = np.zeros(len(part), bool)
    rows = np.flatnonzero(np.any(np.take(rim, part, axis=0), axis=1)) if len(part) else np.zeros(0, np.int64)
    if len(rows) == 0:
        return out
    p = np.take(part, rows)
    poly = np.take(s.polygon, p, axis=0)                                    # [r, V, 2]
    count = np.take(s.n_corners, p)
    slot = np.arange(poly.shape[1])
    nxt = np.where(slot[None, :] + 1 < count[:, None], slot[None, :] + 1, 0)
    edge = np.take_along_axis(poly, nxt[..., None], axis=1) - poly
    length = np.sqrt(np.einsum("rvi,rvi->rv", edge, edge))
    unit = edge / np.where(length > 0, length, 1.0)[..., None]

    def distance(x):
        rel = x[:, None, :] - poly
        return np.abs(unit[..., 0] * rel[..., 1] - unit[..., 1] * rel[..., 0])

    tolerance = ON_EDGE * (1.0 + length)
    fits = (np.take(rim, p, axis=0) & (slot[None, :] < count[:, None]) & (length > 0)
            & (distance(np.take(start, rows, axis=0)) <= tolerance) & (distance(np.take(end, rows, axis=0)) <= tolerance))
    out[rows] = np.any(fits, axis=1)
    return out
