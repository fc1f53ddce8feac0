"""Stage 2, tracing: scattering anchored to the mesh, every pulse's return.

Stage: 2 (core -> scene -> **tracing** -> signal -> focus -> products -> formats -> stacks -> analysis).

Takes: a loaded scene and its plan from :mod:`sarmitsuba.scene` (``RadarParameters``,
``TraceSettings``, ``FastTimeWindow``, ``RayFootprint``, ``MaterialTable``, ``EffectSet``).

Gives: ``TraceResult`` (:func:`.driver.trace.trace`): per pulse the band-limited fast-time spectra of
every path, split by bounce order and polarisation, with the trace's statistics.

Rays find the paths; the mesh decides what they integrate (docs/physics.md (M1)-(M8)). The parts,
each a subpackage whose docstring says what it takes and gives, in the order a trace runs them:

==========================  ===============================================================
:mod:`.mesh`                convex planar parts, their patches and pieces; batched polygons
:mod:`.discovery`           chains of mirrors unfolded by the image method; their regions
:mod:`.visibility`          rays at the pieces: lit, transmit-lit, mixed; mixed pieces clipped
                            exactly; their boundaries' motion across a sub-aperture (M8)
:mod:`.integration`         every pulse's terms: closed-form PO, edge currents, scatterers,
                            pattern and polarimetry (Dr.Jit, each with a NumPy reference)
:mod:`.deposit`             the fast-time deposit and its band-limited spectrum
:mod:`.derivatives`         the traces that carry material and geometric tangents
:mod:`.driver`              ``trace``: sub-apertures in launches, each launch order by order
:mod:`.fused`               the geometry's stages as Dr.Jit kernels, each beside its NumPy
                            reference (``TraceSettings.geometry``)
==========================  ===============================================================

Shared by every part: :mod:`.device` (NumPy arrays in Dr.Jit memory) and :mod:`.loops` (how the
kernels run their loops); ``_llvm`` and ``_variant`` find libLLVM and choose the Mitsuba variant
(used by ``import sarmitsuba``).

Physics: (M1)-(M8) the mesh-anchored patches; (T1)-(T3) ray tubes and sub-apertures; (PO1)-(PO5)
physical optics; (C) clutter; (A) antenna pattern; (P1)-(P8) polarimetry; (D1)-(D5) the fast-time
deposit.
"""
