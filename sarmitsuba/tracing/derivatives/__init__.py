"""Derivatives of a trace: with respect to a material's reflection table, and with respect to a
shape's geometry by central differences of the lanes of the moved geometry.

Takes: a loaded scene, the parameter (material or shape pose/vertices) and the image's adjoint.

Gives: the kernels that carry tangents (:func:`~.tangents.moved_tracer`) and the lanes of a
geometry moved by ``+-h`` paired with the geometry's own (:mod:`.lane_pairs`).

==========================  ===============================================================
:mod:`.tangents`            material tangents; kernels that carry geometric tangents
:mod:`.geometry_tangents`   the moved geometries of a shape's pose or vertices
:mod:`.lane_pairs`          lanes paired across ``+-h`` and their central differences
==========================  ===============================================================

Physics: docs/physics.md (AD4).
"""
