"""Stage 2, tracing: scattering anchored to the mesh, every pulse's return.

Stage: 2 (core -> scene -> **tracing** -> signal -> focus -> products -> formats -> analysis).

Takes: a loaded scene and its plan from :mod:`sarmitsuba.scene` (``RadarParameters``,
``TraceSettings``, ``FastTimeWindow``, ``RayFootprint``, ``MaterialTable``, ``EffectSet``).

Gives: ``TraceResult`` (:func:`.trace.trace`): per pulse the band-limited fast-time spectra of
every path, split by bounce order and polarisation, with the trace's statistics.

Rays find the paths; the mesh decides what they integrate (docs/physics.md (M1)-(M8)). The parts,
in the order a trace runs them:

==========================  ===============================================================
**the mesh**
:mod:`.facets`              convex planar parts of the meshes
:mod:`.patches`             each face's frame and patches; regions cut into pieces
:mod:`.polygons`, :mod:`.covers`  batched convex polygons; coplanar faces that cover others
**discovery**
:mod:`.mesh_trace`          one launch, order by order: first bounce, discovery rays, lanes
:mod:`.chains`              chains of mirrors unfolded; their exact regions (image method)
**visibility**
:mod:`.visibility`          rays aimed at mesh points (Embree through Mitsuba, Dr.Jit)
:mod:`.lit_pieces`          lit, transmit-lit and mixed pieces; occluders met
:mod:`.occlusion`           mixed pieces cut exactly against their occluders' shadows
:mod:`.motion`              how their boundaries move with the antenna across a sub-aperture
**integration**
:mod:`.term_lanes`          lit boundaries as per-pulse term lanes, rough pieces as scatterers
:mod:`.integration`         the patch terms in Dr.Jit; :mod:`.patch_reference` its NumPy reference
:mod:`.surface_clutter`     the rough surfaces' scatterers, fixed in each face's frame
:mod:`.returns`, :mod:`.jones`  per-pulse density, reflection, pattern; the Jones model
                            (:mod:`.polarimetry` its NumPy reference)
**deposit**
:mod:`.accumulate`          where returns are summed; :mod:`.deposit` the fast-time deposit
**the driver**
:mod:`.trace`               ``trace``: sub-apertures in launches, the result
:mod:`.kernel`              one launch: the mesh tracer, and the tube preview
                            (``lit_regions = tiles``, shapes that are not meshes)
:mod:`.physical_optics`, :mod:`.clutter_lattice`  the tubes' PO terms and scatterers
:mod:`.distributed`         the same trace as Dask tasks
:mod:`.device`              NumPy arrays in Dr.Jit memory; ``_llvm``, ``_variant``: libLLVM and
                            the Mitsuba variant (used by ``import sarmitsuba``)
==========================  ===============================================================

Physics: (M1)-(M8) the mesh-anchored patches; (T1)-(T3) ray tubes and sub-apertures; (PO1)-(PO5)
physical optics; (C) clutter; (A) antenna pattern; (P1)-(P8) polarimetry; (D1)-(D5) the fast-time
deposit.
"""
