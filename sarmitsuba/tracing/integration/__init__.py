"""Every pulse's return from what is lit: the closed-form physical optics over lit pieces, the
edges' equivalent currents, the rough surfaces' scatterers, antenna pattern and polarimetry.

Takes: lit pieces and their outlines (:mod:`sarmitsuba.tracing.visibility`), the chains they
belong to, the pulses' antenna positions and the material table.

Gives: term lanes (:mod:`.term_lanes`) and the Dr.Jit kernels that evaluate them for every pulse
of a sub-aperture and hand each term's two-way length and complex amplitude to the deposit.

=======================  ============================================================================
:mod:`.term_lanes`       lit boundaries as point and area term lanes; rough pieces as scatterers
:mod:`.patch_terms`      the patch terms in Dr.Jit; :mod:`.patch_reference` their NumPy reference
:mod:`.edges`            the diffracting edges and their currents, NumPy (:mod:`.edge_terms`: Dr.Jit)
:mod:`.junctions`        which border edges lie on another part (free edges, junctions)
:mod:`.truncation`       a ground shape's free rims: truncations, not edges (M10)
:mod:`.surface_clutter`  the rough surfaces' scatterers, fixed in each face's frame
:mod:`.returns`          per-pulse density, reflection, pattern; the tube preview's returns
:mod:`.physical_optics`  ray-tube PO in NumPy, the closed forms it is tested against
:mod:`.clutter_lattice`  the tube preview's scatterer lattice (:mod:`.clutter_terms`: its terms)
:mod:`.jones`            the Jones model in Dr.Jit; :mod:`.polarimetry` its NumPy reference
:mod:`.pulse_view`       a pulse's steering, axes and motion during the echo
=======================  ============================================================================

Physics: docs/physics.md (M5), (M7), (M10), (E1)-(E6), (PO1)-(PO5), (C), (A), (R1), (P1)-(P8).
"""
