"""Stage 1, the scene: what is there and how it is looked at, checked and planned before any tracing.

Stage: 1 (core -> **scene** -> tracing -> signal -> focus -> products -> formats -> stacks -> analysis).

Takes: a Mitsuba XML file (or a folder holding ``scene.xml``), a built-in name (``urban``,
``dihedral``, ``trihedral``), ``sionna:NAME`` or a :class:`~.builder.Scene` built in Python;
sensor overrides (``--set``). Building footprints in GeoJSON become a scene folder first
(:mod:`.city`).

Gives: a loaded scene (``load_scene``) with its ``RadarParameters``, the tracer's inputs
(``TraceSettings``, ``FastTimeWindow``, ``RayFootprint``, ``MaterialTable``) and the effects
it switches on (``EffectSet``):

=======================  ===============================================================
:mod:`.loader`           ``load_scene``: XML, built-in or Sionna scene plus sensor and tracer
:mod:`.builder`          ``Scene``: meshes, materials and sensor from Python
:mod:`.materials`        ITU-R P.2040 permittivities, reflection coefficients
:mod:`.fresnel`          half-space and slab Fresnel coefficients
:mod:`.meshcheck`        degenerate-mesh warnings
:mod:`.canonical`        canonical radar targets and their closed-form RCS
:mod:`.effects`          which optional effects a scene switches on, and why
:mod:`.planning`         defaults from the scene, fast-time window, ray footprint, checks
:mod:`.trace_inputs`     the tracer's input records (the scene -> tracing contract)
:mod:`.radar_equation`   the sensor's radar equation (absolute radiometry)
:mod:`.baseline`         the interferometric baseline of a shifted pass
:mod:`.footprints`       GeoJSON building footprints: outlines, heights, roofs, materials
:mod:`.city`             footprints -> local frame -> meshes -> scene folder (``City``)
:mod:`.buildings`        closed building meshes with flat, gabled, hipped, pyramidal roofs
:mod:`.facades`          windows and balconies as geometry on a wall
:mod:`.windowed`         a copy of any scene whose plain walls get windows
:mod:`.roles`            roof, facade, ground or underside: each surface's role
:mod:`.terrain`          the ground: a plane, or a DEM GeoTIFF meshed at its resolution
:mod:`.mesh_footprints`  a mesh scene's buildings as GeoJSON footprints
=======================  ===============================================================

Physics: (R) reflection coefficients, (R1)-(R3) radar equation, (T1)-(T2) ray footprint and
refinement, (I1)-(I3) baselines, (FP1)-(FP3) scenes from footprints, (RS8) roles, (FA1) windows.

``from sarmitsuba.scene import load_scene`` (the module ``sarmitsuba.scene`` before the stage
packages) still works: names not found here are looked up in :mod:`.loader`.
"""


from ..core.moved import former_module_attributes as _former_module_attributes

__getattr__ = _former_module_attributes(__name__, "loader")
