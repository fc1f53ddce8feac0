"""The mesh tracer's geometry as Dr.Jit kernels (docs/design.md section 10.1).

Takes and gives the arrays of the NumPy stages it replaces; each kernel has that stage as its
readable reference, selected by ``TraceSettings.geometry`` (``reference`` or ``fused``), and
``tests/test_fused.py`` compares the two.

==========================  ===============================================================
:mod:`.matching`            the lone pairs of rows within a tolerance (shared boundary segments
                            and junctions that cancel, eq. (M5)); reference:
                            ``integration.term_lanes`` (a k-d tree)
:mod:`.boundary`            the lit boundary of mixed pieces less their cut-outs, eq. (M4);
                            reference: ``visibility.occlusion.lit_boundary``
:mod:`.moments`             polygon moments (area, centroid, second moments, box diagonal);
                            reference: ``mesh.polygons.moments``
:mod:`.pieces`              regions cut into patch pieces, one lane per grid row (step 1);
                            reference: ``mesh.piece_cuts.pieces_of``
:mod:`.shadows`             the half-planes of occluders' shadows, one lane per (chain,
                            occluder, leg) (step 4); reference:
                            ``visibility.occlusion.shared_shadow_lines``
:mod:`.segments`            the stable flags of pieces and the split kinds of segments (step 8);
                            reference: ``driver.mesh_trace.MeshTracer._never_specular``,
                            ``_split_kinds``
==========================  ===============================================================

:func:`geometry_kernels` gives the functions a tracer calls for the stages that have a kernel:
the kernels, or their references.
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
    lit_boundary : callable
        :func:`sarmitsuba.tracing.visibility.occlusion.lit_boundary` or its kernel.
    moments : callable
        :func:`sarmitsuba.tracing.mesh.polygons.moments` or its kernel.
    pieces_of : callable
        :func:`sarmitsuba.tracing.mesh.piece_cuts.pieces_of` or its kernel, with these ``moments``.
    shadow_lines : callable
        :func:`sarmitsuba.tracing.visibility.occlusion.shared_shadow_lines` or its kernel.
    """

    lit_boundary: Callable
    moments: Callable
    pieces_of: Callable
    shadow_lines: Callable


def geometry_kernels(pipeline: str) -> GeometryKernels:
    """The stages' functions for ``TraceSettings.geometry`` ``pipeline``: ``"fused"`` (the
    kernels) or ``"reference"`` (the NumPy stages). Looked up when called, so that a test may
    replace a module's function first."""
    from ..mesh import piece_cuts, polygons
    from ..visibility import occlusion
    if pipeline != "fused":
        return GeometryKernels(lit_boundary=occlusion.lit_boundary, moments=polygons.moments,
                               pieces_of=piece_cuts.pieces_of, shadow_lines=occlusion.shared_shadow_lines)
    from . import boundary, moments, pieces, shadows
    return GeometryKernels(lit_boundary=boundary.lit_boundary, moments=moments.moments,
                           pieces_of=functools.partial(pieces.pieces_of, moments=moments.moments),
                           shadow_lines=shadows.shared_shadow_lines)
