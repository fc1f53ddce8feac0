"""``sbr`` integrator: shoot-and-bounce-rays settings of the SAR tracer.

.. pluginparameters::

 * - max_depth
   - integer
   - Bounce orders traced (default 3). 1 = single bounce only: the compiled kernel then
     has no reflection loop. 2 adds wall-ground double bounce, 3 trihedral returns.
 * - ray_spacing
   - float, m
   - Ray-tube width perpendicular to the line of sight at the scene centre; 0 (default) =
     half of the finer of the slant-range and azimuth resolutions.
 * - range_kernel
   - string
   - How a path reaches the fast-time samples (an accuracy knob; docs/physics.md (D1)-(D4)):
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
   - Seed of the distributed-clutter scatterer phases (default 0); same seed, same speckle.
 * - split_bounces
   - boolean
   - Also produce raw data and images of each bounce order separately (default false; when
     off, the kernel keeps one histogram).
 * - max_batch_rays
   - integer
   - Upper bound of rays in flight per kernel launch (default 4194304); pulses are batched
     to stay below it.

The tracing itself is :func:`sarmitsuba.trace.trace` (a Dr.Jit symbolic loop); this
plugin only carries the settings from the scene file, so ``mi.render`` is not used.
"""
from __future__ import annotations

import mitsuba as mi

from sarmitsuba.radar import ParameterError
from sarmitsuba.trace_inputs import TraceSettings


class SbrIntegrator(mi.SamplingIntegrator):
    """Mitsuba integrator holding a :class:`sarmitsuba.trace.TraceSettings` (see module docstring)."""

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        valid = TraceSettings.names()
        values = {}
        for key in props.keys():
            if key not in valid:
                raise ParameterError(
                    f"sbr integrator: unknown parameter {key!r}; valid parameters: {', '.join(valid)}")
            values[key] = props[key]
        #: Settings exactly as written in the scene, for overrides.
        self.given = dict(values)
        self.settings = TraceSettings.from_mapping(values)

    def sample(self, scene, sampler, ray, medium=None, active=True):
        raise RuntimeError("the sbr integrator is not run through mi.render; use sarmitsuba.pipeline.render "
                           "or `python -m sarmitsuba render SCENE`")

    def aov_names(self):
        return []

    def to_string(self):
        return f"SbrIntegrator[{self.settings}]"


mi.register_integrator("sbr", lambda props: SbrIntegrator(props))
