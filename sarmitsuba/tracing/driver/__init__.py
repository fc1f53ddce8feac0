"""The trace itself: an acquisition's pulses in sub-apertures, sub-apertures in launches, and
each launch bounce order by bounce order through the other parts.

Takes: a loaded scene and its plan (:mod:`sarmitsuba.scene`).

Gives: :class:`~.trace.TraceResult` (:func:`~.trace.trace`).

How one launch runs (:class:`~.mesh_trace.MeshTracer`), for each bounce order::

    chains   -> pieces in the beam's reach   (mesh: the parts cut on their patch grids)
             -> lit / transmit-lit / mixed  (visibility: rays at the pieces' corners)
             -> mixed pieces clipped         (visibility: occluders' shadows, exact)
             -> boundary rates (M8)          (visibility.motion)
             -> term lanes, every pulse      (integration -> deposit)
             -> next order's chains          (discovery.specular: rays from lit pieces)

==========================  ===============================================================
:mod:`.trace`               ``trace``: sub-apertures in launches, launches on host threads
:mod:`.subapertures`        the sub-apertures (T3), their ray starts and lattice blocks
:mod:`.launches`            what one launch traces: its sub-apertures and aim-lattice blocks
:mod:`.kernel`              one launch: the mesh tracer, or the tube preview
                            (``lit_regions = tiles``, and shapes that are not meshes)
:mod:`.mesh_trace`          the mesh tracer's launch, order by order
:mod:`.stages`              the time of each stage (``summary.json``'s ``trace_stages``)
:mod:`.threads`             launches at once on host threads
:mod:`.distributed`         the same trace as Dask tasks
==========================  ===============================================================

Physics: docs/physics.md (T1)-(T3), (M1)-(M8).
"""
