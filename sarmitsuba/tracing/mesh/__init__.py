"""The mesh as the tracer integrates over it: convex planar parts, their patches and pieces.

Takes: a Mitsuba scene's triangle meshes (:class:`mitsuba.Mesh`) and the patch size [m].

Gives: :class:`~.patches.Surfaces` (every part's face frame, corners, normal, material row and
covering faces) and :class:`~.patches.Pieces` (convex regions cut on each face's fixed patch
grid), with the batched convex-polygon operations the other parts build on.

==========================  ===============================================================
:mod:`.facets`              triangle meshes merged into convex planar parts
:mod:`.covers`              coplanar faces of two shapes: the smaller covers the larger
:mod:`.patches`             each face's frame and patches (:class:`~.patches.Surfaces`)
:mod:`.piece_cuts`          regions cut into one piece per patch they meet
:mod:`.polygons`            convex polygons many at once, float64 NumPy: the readable reference
:mod:`.polygon_kernels`     the same clipping as one Dr.Jit kernel (large batches)
==========================  ===============================================================

Physics: docs/physics.md (M1), (M2).
"""
