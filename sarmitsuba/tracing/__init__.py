"""Stage 2, tracing: ray tubes shot from the antenna, bounced through the scene, every pulse's return.

Stage: 2 (core -> scene -> **tracing** -> signal -> focus -> products -> formats -> analysis).

Takes: a loaded scene and its plan from :mod:`sarmitsuba.scene` (``RadarParameters``,
``TraceSettings``, ``FastTimeWindow``, ``RayFootprint``, ``MaterialTable``, ``EffectSet``).

Gives: ``TraceResult`` (:func:`.trace.trace`): per pulse the band-limited fast-time spectra of
every path, split by bounce order and polarisation, with the trace's statistics.

=======================  ===============================================================
:mod:`.trace`            ``trace``: pulses in batches through the kernel
:mod:`.kernel`           the Dr.Jit shoot-and-bounce-rays kernel (one launch per sub-aperture)
:mod:`.returns`          every pulse's physical-optics return from the recorded hits
:mod:`.physical_optics`  the NumPy reference of the per-pulse PO terms
:mod:`.jones`            the tube's Jones matrix in Dr.Jit; :mod:`.polarimetry` its NumPy reference
:mod:`.clutter_lattice`  the rough surface's own scatterers
:mod:`.facets`           convex planar parts of the meshes (PO integration domains)
:mod:`.cell_plan`        exact lit regions (``lit_regions = cells``): :mod:`.cell_lanes`,
                         :mod:`.cell_split`, :mod:`.lattice_index`, :mod:`.cell_clip`,
                         :mod:`.cell_terms`
:mod:`.accumulate`       where returns are summed; :mod:`.deposit` the fast-time deposit
:mod:`.distributed`      the same trace as Dask tasks
:mod:`.device`           NumPy arrays in Dr.Jit memory; ``_llvm``, ``_variant``: libLLVM and
                         the Mitsuba variant (used by ``import sarmitsuba``)
=======================  ===============================================================

Physics: (T1)-(T3), (T6) ray tubes and sub-apertures; (PO1)-(PO5) physical optics; (C)
clutter; (A) antenna pattern; (P1)-(P8) polarimetry; (D1)-(D5) the fast-time deposit.
"""
