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
==========================  ===============================================================
"""
