"""Chains of mirrors: which sequences of parts a multi-bounce path runs through, and where.

Takes: :class:`~sarmitsuba.tracing.mesh.patches.Surfaces`, a bounce order's lit pieces
(:mod:`sarmitsuba.tracing.visibility`) and each sub-aperture's reference position [m].

Gives: the next bounce order's chains (:func:`~.specular.discover`: specular rays from a grid
fixed on each transmit-lit piece, cast through :class:`~sarmitsuba.tracing.visibility.rays.Rays`
to the part they meet), and :class:`~.chains.Chains` (each chain unfolded by the image method:
its mirrored frames, the reflection operators ``U_i``, the window half-planes that bound its
exact region, the points where a path meets each mirror, :func:`~.chains.path_points`).

==========================  ===============================================================
:mod:`.specular`            the next order's chains from specular rays (M6)
:mod:`.chains`              chains unfolded; their regions and image sources (float64 NumPy)
==========================  ===============================================================

Physics: docs/physics.md (M3), (M6).
"""
