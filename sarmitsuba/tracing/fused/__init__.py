"""The mesh tracer's geometry as Dr.Jit kernels (docs/design.md section 10.1).

Takes and gives the arrays of the NumPy stages it replaces; each kernel has that stage as its
readable reference, selected by ``TraceSettings.geometry`` (``reference`` or ``fused``), and
``tests/test_fused.py`` compares the two.

==========================  ===============================================================
:mod:`.matching`            the lone pairs of rows within a tolerance (shared boundary segments
                            and junctions that cancel, eq. (M5)); reference:
                            ``integration.term_lanes`` (a k-d tree)
:mod:`.clipping`            the cut-outs of mixed pieces, one lane per (piece, occluder) pair
                            (step 4); reference: ``visibility.cut_outs``
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

:func:`.kernels.geometry_kernels` gives the functions a tracer calls for the stages that have a
kernel: the kernels, or their references.
"""
from __future__ import annotations

from .kernels import GeometryKernels, geometry_kernels

__all__ = ["GeometryKernels", "geometry_kernels"]
