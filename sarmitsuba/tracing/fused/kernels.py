"""The functions a mesh tracer calls for the geometry stages that have a Dr.Jit kernel: the
kernels of this package, or their NumPy references (``TraceSettings.geometry``; docs/design.md
section 10.1).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

__all__ = ["GeometryKernels", "geometry_kernels"]


@dataclass(frozen=True)
class GeometryKernels:
    """The functions of the geometry stages that have a kernel, each with its reference's
    signature and results (docs/design.md section 10.1).

    Attributes
    ----------
    cut_outs : callable
        :func:`sarmitsuba.tracing.visibility.cut_outs.cut_outs` or its kernel.
    lit_boundary : callable
        :func:`sarmitsuba.tracing.visibility.occlusion.lit_boundary` or its kernel.
    moments : callable
        :func:`sarmitsuba.tracing.mesh.polygons.moments` or its kernel.
    pieces_of : callable
        :func:`sarmitsuba.tracing.mesh.piece_cuts.pieces_of` or its kernel, with these ``moments``.
    shadow_lines : callable
        :func:`sarmitsuba.tracing.visibility.occlusion.shared_shadow_lines` or its kernel.
    """

    cut_outs: Callable
    lit_boundary: Callable
    moments: Callable
    pieces_of: Callable
    shadow_lines: Callable


def geometry_kernels(pipeline: str) -> GeometryKernels:
    """The stages' functions for ``TraceSettings.geometry`` ``pipeline``: ``"fused"`` (the
    kernels) or ``"reference"`` (the NumPy stages). Looked up when called, so that a test may
    replace a module's function first."""
    from ..mesh import piece_cuts, polygons
    from ..visibility import cut_outs, occlusion
    if pipeline != "fused":
        return GeometryKernels(cut_outs=cut_outs.cut_outs, lit_boundary=occlusion.lit_boundary, moments=polygons.moments,
                               pieces_of=piece_cuts.pieces_of, shadow_lines=occlusion.shared_shadow_lines)
    from . import boundary, clipping, moments, pieces, shadows
    return GeometryKernels(cut_outs=clipping.cut_outs, lit_boundary=boundary.lit_boundary, moments=moments.moments,
                           pieces_of=functools.partial(pieces.pieces_of, moments=moments.moments),
                           shadow_lines=shadows.shared_shadow_lines)
