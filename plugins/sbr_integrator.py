"""``sbr`` integrator: shoot-and-bounce-rays settings of the SAR tracer.

.. pluginparameters::

 * - max_depth
   - integer or string
   - Bounce orders traced. ``auto`` (default): the depth the scene calls for, chosen by a probe
     that traces a few sub-apertures to ``depth_cap`` and keeps the orders until those left out
     hold at most ``depth_tolerance_db`` of the energy (docs/physics.md (DEP1)-(DEP3)).
     A number fixes the depth: 1 = single bounce only (the compiled kernel then has no
     reflection loop), 2 adds wall-ground double bounce, 3 trihedral returns.
 * - depth_cap
   - integer
   - ``max_depth = auto``: the deepest order it may choose, [1, 64] (default 8).
 * - depth_tolerance_db
   - float, dB
   - ``max_depth = auto``: the share of the image's energy the orders left out may hold
     together, in (-200, 0) (default -20: an image NRMSE of about -20 dB against the cap's).
 * - ray_spacing
   - float, m
   - Ray-tube width ``s`` normal to the line of sight: square tubes, ``s`` along track and
     ``s / cos(theta)`` in ground range on the aim plane. 0 (default) = one tube per
     resolution cell, ``(rho_az, rho_gr)``: each tube's physical-optics return is exact
     across the band, so denser rays only place large geometry's boundaries more finely
     (docs/physics.md (T1), (PO2)). At most one resolution cell or the width whose quadratic
     phase reaches pi/2 at the nearest range, ``sqrt(2 R_near (pi/2) / k)``, whichever is larger
     (4.7 m at X band and 1.4 km); wider tubes are refused before tracing.
 * - tubes_per_object
   - integer
   - Shapes smaller than 8 default tubes (bounding-box diagonal) are traced with tubes
     ``diagonal / tubes_per_object`` wide, at least a quarter wavelength (default 48;
     0 = off; docs/physics.md (T2)): a 1 m corner reflector gets about 48 x 48 tubes.
 * - scatterer_spacing
   - float, m
   - Cell of the clutter scatterers' lattice attached to every rough surface, one jittered
     scatterer per cell; 0 (default) = ``0.8 sqrt(rho_slant rho_az)``, about
     ``1.6 / sin(theta)`` scatterers per ground resolution cell (docs/physics.md (C)).
 * - range_kernel
   - string
   - How a path reaches the fast-time samples (an accuracy knob; docs/physics.md (D1)-(D5)):
     ``nearest`` (nearest fine bin; fastest, envelope jitter up to half a fine bin),
     ``linear`` (default; linear splat on the oversampled grid, droop corrected),
     ``sinc`` (8-tap Lanczos-windowed sinc on the grid, droop corrected) or
     ``exact`` (no grid: every path kept and its compressed pulse ``sinc(B t)`` evaluated
     at every sample; cost paths x samples, needs sar ``output = compressed``).
 * - oversample
   - integer
   - Fine-grid oversampling of the fast-time axis for the deposit (default 8).
 * - seed
   - integer
   - Seed of the clutter scatterers' positions and phases (default 0); same seed, same
     speckle, another seed independent speckle.
 * - split_bounces
   - boolean
   - Also produce raw data and images of each bounce order separately (default false; when
     off, the kernel keeps one histogram).
 * - scatterers
   - boolean
   - Also sum every term coherently at its phase centre and write the scatterer catalogue
     (scatterers.csv, scatterers.geojson, fig_scatterers.png; default false; needs
     ``lit_regions = patches``). ``render --scatterers`` sets it.
 * - max_batch_rays
   - integer
   - Ceiling on the ray tubes of one kernel launch (default 262144, at least 1024):
     sub-apertures are batched, and a sub-aperture's lattice split into row chunks, to stay
     below it (one refined cell's tubes are never split).
 * - pulses_per_trace
   - integer
   - Pulses of a sub-aperture: its ray tubes are traced once, from the middle of its track,
     and every pulse's return is evaluated from the recorded hits with its own antenna
     position (docs/physics.md (T3)). An accuracy knob: 1 traces every pulse on its own (the
     reference); 0 (default) = automatic, about 16 azimuth resolution cells of travel
     (``benchmarks/subaperture.py`` measures image error and time against it).
 * - polarimetry
   - string
   - ``jones`` (default): every ray tube carries a Jones matrix through its bounces, the
     polarisation model of docs/physics.md (P1)-(P8), for any sar ``polarization``.
     ``scalar``: one co-polarised channel (``HH`` or ``VV``) with scalar reflection
     coefficients, no Jones algebra compiled; exact only where every facet of a path contains
     H (a concrete trihedral at boresight comes out 16 dB too bright in HH). An accuracy knob,
     measured in ``benchmarks/polarimetry.py``.
 * - lit_regions
   - string
   - ``patches`` (default): scattering anchored to the mesh (docs/physics.md (M1)-(M8)). Every
     planar face carries patches fixed in its own frame; rays aimed at the patches' corners
     decide what is lit, pieces that disagree are cut exactly against their occluders'
     shadows, chains of mirrors found by rays are evaluated by the image method, and every lit
     region's boundary returns Gordon's edge terms, evaluated by every pulse. Nothing depends
     on a ray lattice: a moved scene gives the moved image, the triangulation does not matter.
     ``tiles``: the fast preview (ray tubes on a world-fixed lattice, each integrating its whole
     tile, docs/physics.md (T1)-(T3)): a few times faster on large cities, but a facet's lit
     region ends in the tubes' staircase, which moves with the lattice. Shapes that are not
     meshes (a sphere) are always traced with tubes.
 * - patch_size
   - float
   - Side of the patches [m] (``lit_regions = patches``; docs/physics.md (M1)); 0 (default) =
     automatic: the slant-range resolution, kept below the size whose phase departs from linear
     by pi/8, rounded to whole scatterer cells. An accuracy knob, measured in
     ``benchmarks/patches.py`` (error and time). Bounded by the same phase: a patch whose
     corners depart from linear by more than pi/4 at the scene's nearest range,
     ``k P^2 / (2 R_near)``, is refused before tracing with the largest valid value for the
     scene (docs/physics.md (M1'); about 3.3 m at X band and 1.4 km): beyond it the edge terms'
     ends lose their bound.
 * - cancel_interior
   - boolean
   - Skip the physical-optics terms that neighbouring tubes cancel exactly (default true;
     docs/physics.md (PO5)). False evaluates them all (three to four times the returns;
     up to 1.2x the render time): the reference the cancellation is checked against. With
     patches: false keeps every patch line and every shared split end.
 * - diffraction
   - boolean
   - Fringe waves of the mesh's edges (default true): equivalent edge currents on every wedge and
     free edge of the lit regions, the PTD correction to physical optics (docs/physics.md
     (E1)-(E5)). ``lit_regions = patches`` only. False is physical optics alone.
 * - ground_shapes
   - string
   - The shapes that stand for ground continuing beyond the scene (default ``auto``: ids
     ``ground``, ``*-ground`` and ``*_ground``, as in the built-in scenes, generated cities and
     Sionna RT's scenes; ``none``; or a comma-separated list of shape ids). Their free rims are
     where the model was cut, not edges of the world: they return no physical-optics rim terms
     and no edge currents (docs/physics.md (M10)). ``lit_regions = patches`` only.
 * - geometry
   - string
   - How the mesh tracer's per-sub-aperture geometry runs: ``fused`` (default), the Dr.Jit
     kernels of the stages that have one (the matching of the segments whose terms cancel, the
     shadows, the cut-outs, the lit boundaries, the patch pieces, the moments, the segments'
     kinds) and the NumPy stages elsewhere; ``reference``, the NumPy stages alone, the readable
     reference. The two give the same raw data; rows a kernel cannot hold are finished by
     the NumPy stage and counted in ``summary.json`` (``overflow_rows``).
     ``lit_regions = patches`` only.

The tracing itself is :func:`sarmitsuba.tracing.driver.trace.trace` (Dr.Jit kernels, one per bounce order);
this plugin only carries the settings from the scene file, so ``mi.render`` is not used.
"""
from __future__ import annotations

import difflib

import mitsuba as mi

from sarmitsuba.core.radar import ParameterError
from sarmitsuba.scene.trace_inputs import TraceSettings


class SbrIntegrator(mi.SamplingIntegrator):
    """Mitsuba integrator holding a :class:`sarmitsuba.tracing.driver.trace.TraceSettings` (see module docstring)."""

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        valid = TraceSettings.names()
        values = {}
        for key in props.keys():
            if key not in valid:
                close = difflib.get_close_matches(key, valid, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise ParameterError(
                    f"sbr integrator: unknown parameter {key!r}{hint}; valid parameters: {', '.join(valid)}")
            values[key] = props[key]
        #: Settings exactly as written in the scene, for overrides.
        self.given = dict(values)
        self.settings = TraceSettings.from_mapping(values)

    def sample(self, scene, sampler, ray, medium=None, active=True):
        raise RuntimeError("the sbr integrator is not run through mi.render; use sarmitsuba.pipeline.render "
                           "or `.venv/bin/python -m sarmitsuba render SCENE`")

    def aov_names(self):
        return []

    def to_string(self):
        return f"SbrIntegrator[{self.settings}]"


mi.register_integrator("sbr", lambda props: SbrIntegrator(props))
