"""Chains of mirrors: which sequences of parts a multi-bounce path runs through, and where.

Takes: :class:`~sarmitsuba.tracing.mesh.patches.Surfaces`, the parts each chain visits in order,
and each chain's sub-aperture reference position [m].

Gives: :class:`~.chains.Chains` (each chain unfolded by the image method: its mirrored frames,
the reflection operators ``U_i``, the window half-planes that bound its exact region) and the points
where a path through them meets each mirror (:func:`~.chains.path_points`). The rays that *find* a next bounce (specular rays
from a lit piece's points) are cast by the driver (:mod:`sarmitsuba.tracing.driver.mesh_trace`)
through :class:`~sarmitsuba.tracing.visibility.rays.Rays`; this part turns what they met into
chains.

==========================  ===============================================================
:mod:`.chains`              chains unfolded; their regions and image sources (float64 NumPy)
==========================  ===============================================================

Physics: docs/physics.md (M3), (M6).
"""
