"""What the antenna sees of a chain's region: lit, transmit-lit and mixed pieces, mixed pieces cut
exactly against their occluders' shadows, and how those boundaries move across a sub-aperture.

Takes: :class:`~sarmitsuba.tracing.discovery.chains.Chains` with their regions cut into
:class:`~sarmitsuba.tracing.mesh.patches.Pieces`, the scene for rays, and each sub-aperture's
views (first pulse, reference, last pulse) [m].

Gives: :class:`~.lit_pieces.LitPieces` (per piece: lit on both legs, transmit-lit only, mixed;
the occluders met), the exact lit outlines of mixed pieces (:class:`~.occlusion.ClippedPieces`),
and per boundary line its rate of motion along the track (M8).

==========================  ===============================================================
:mod:`.rays`                rays aimed at mesh points: free legs, blockers, first hits
:mod:`.lit_pieces`          classification and recheck; the samples as a Dr.Jit kernel
:mod:`.occlusion`           a piece less the union of its occluders' shadows
:mod:`.motion`              the boundary rates (M8) as a Dr.Jit kernel;
                            :mod:`.motion_reference` its readable reference
==========================  ===============================================================

Physics: docs/physics.md (M4), (M8).
"""
