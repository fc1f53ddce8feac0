"""The cost model of a render: ray casts, returns, trace and focusing time, and peak memory,
estimated without tracing (what ``sarmitsuba info`` reports and what a render checks first).

:func:`cost_estimate` gives a :class:`CostEstimate` for a loaded, planned scene (the fast-time
window and ray footprint of :mod:`sarmitsuba.scene.planning`, the image grid of
:func:`sarmitsuba.focus.scene_grid.image_grid`, the effects of
:func:`sarmitsuba.scene.effects.active_effects`); :func:`sarmitsuba.analysis.memory.check_memory` raises,
before any tracing, when its peak memory exceeds what is available.

Every time is an estimate from the measured rates below, for the 2-core reference machine
(docs/design.md section 10): expect a factor of 2 either way. The peak memory is the whole
render process's peak resident set (Python, Mitsuba and Dr.Jit with its LLVM JIT, the tracer's
working set, the arrays), from the measured constants below: within a factor of 2 of
the measured peak RSS on the scenes and settings listed at :data:`RUNTIME_BYTES`.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import drjit as dr
import numpy as np

from ..tracing.deposit.fast_time import SPECTRAL_ORDERS, padded_length
from ..scene.effects import EffectSet, active_effects
from ..focus.scene_grid import image_grid
from ..core.radar import ParameterError, RadarParameters
from ..core.geometry import AcquisitionGeometry
from ..scene.loader import LoadedScene
from ..tracing.driver.threads import launches_at_once
from ..tracing.driver.trace import HISTOGRAM_ENTRIES, pulses_per_trace
from ..scene.trace_inputs import FastTimeWindow, RayFootprint
from .reach import (CLUTTER_SCATTERER_PULSE_SECONDS, MESH_TRIANGLE_BYTES, REACH_TRIANGLE_BYTES, SETUP_TRIANGLE_SECONDS,
                    SUB_PIECE_SECONDS, SUB_TRIANGLE_SECONDS, SUBAPERTURE_BYTES, reach_work)

__all__ = ["CostEstimate", "cost_estimate", "cast_rates", "synthetic_aperture", "format_bytes"]

#: Measured ray-cast rates [casts/s] of Mitsuba's llvm backend on 2 threads of a 2-core x86-64
#: VM, as ``(triangles, closest-hit, shadow)``: a plane and a box (14 triangles: 38-59 M
#: closest-hit, 140-167 M shadow casts/s) and Sionna RT's Munich (38,936 triangles: ~10 M and
#: ~20 M/s), with Mitsuba 3.9.1 / Dr.Jit 1.5.0, variant ``llvm_ad_mono``, on incoherent rays
#: (``ray_intersect`` with ``Minimal`` flags or ``ray_intersect_preliminary``; ``ray_test``);
#: docs/design.md section 10.
CAST_RATE_ANCHORS = ((14, 50e6, 150e6), (38_936, 10e6, 20e6))

#: Factor on the sum of the tracer's parts (casts, returns, spectra) for what is not in them:
#: kernel launches and their Python tracing, compaction between bounce orders. Measured on the
#: 2-core machine: 1.2-1.6 for urban and sionna:munich, smooth and rough.
TRACE_OVERHEAD = 1.3
#: Moving shapes (docs/physics.md (V1), (V2)): the lit geometries a sub-aperture builds (where the
#: shapes are, and differenced), and the seconds per piece in its reach that each costs with the
#: tracer built anew; calibrated on ``traffic`` (``benchmarks/moving.py --quick``: 19-21 s for the 33
#: sub-apertures of its 260 middle pulses, 26,000 pieces each, 2.7 geometries each; the 779-pulse
#: render: 36 s estimated, 39.6 s measured).
MOVING_GEOMETRIES = 2.7
MOVING_PIECE_SECONDS = 9.4e-6
#: A receiver on its own platform (docs/physics.md (B2)): its return legs cast at every order and
#: the pieces cut by two families of shadows; the automatic bistatic trace over the monostatic one
#: on urban (``benchmarks/bistatic.py --quick``: 1.24 for a drone, 1.30 for a second aircraft).
BISTATIC_TRACE = 1.27
#: Direct backprojection of bistatic data over the monostatic model: both legs' lengths per
#: pixel-pulse; measured on urban received by a drone, 5.0 s against the monostatic model's 1.8 s.
BISTATIC_BACKPROJECTION = 2.8
#: FFBP of bistatic data (docs/physics.md (F10)) over the monostatic FFBP on the same grid: urban received by a
#: drone 300 m up at 3 m/s, 1.65x to 1.9x (``benchmarks/ffbp.py --bistatic``: 0.96 s against 0.51 s).
BISTATIC_FFBP = 1.8

#: Seconds per physical-optics return evaluated for one pulse (a term at its own point, its
#: per-pulse geometry, pattern and deposit): 9.3 ns measured on Munich (157 M returns, 1.46 s).
RETURN_SECONDS = 9e-9
#: Seconds per clutter scatterer deposited for one pulse (hash, length, deposit): about 20 ns
#: (urban: 31.6 M scatterers).
SCATTERER_SECONDS = 2e-8
#: Seconds per fine fast-time sample, spectral order and pulse of the reduction to the band
#: (its FFT, docs/physics.md (D5)): 5.6 ns (Munich: 195 M, 1.1 s).
FFT_SECONDS = 5.6e-9
#: PO returns evaluated per ray tube and pulse (the terms that do not cancel, (PO5)), for the
#: estimate: 0.97 measured in Munich (a city; 0.2 on the urban block's open ground).
RETURNS_PER_TUBE = 1.0
#: Mesh-anchored patches (``lit_regions = "patches"``, docs/physics.md (M1)-(M8)): pieces of the
#: second and later bounce orders per first-order piece, measured on sionna:munich (512 pulses,
#: 215k, 128k and 55k pieces per launch) and used as the estimate's decay per order.
PIECES_PER_ORDER = (1.0, 0.6, 0.26, 0.1, 0.05)
#: Visibility samples per piece (its corners, :func:`sarmitsuba.tracing.visibility.lit_pieces.corner_samples`:
#: four for a whole piece, three to eight for a border piece): the estimate is 1.2 times the
#: first order's samples on urban and 0.75 times on sionna:munich (many small facets) with 5.
SAMPLES_PER_PIECE = 5
#: Clutter scatterers per square metre of tube footprint is ``1 / scatterer_spacing^2``; the
#: estimate assumes every hit is rough when any material is (Munich rough: 2.2 per tube).

#: Bytes per path of the ``exact`` range kernel's path list (int32 pulse, uint8 order,
#: float64 position, complex64 value: :class:`sarmitsuba.tracing.driver.trace.PathList`).
PATH_BYTES = 4 + 1 + 8 + 8

#: Fast factorised backprojection (:func:`sarmitsuba.focus.ffbp`): seconds per in-beam
#: pixel-pulse (its first stage) and per lit pixel (the interpolations onto the grid), fitted to
#: urban (0.97 M pixels, 2.1e8 pixel-pulses: 0.8 s) and sionna:munich (12.2 M pixels, 1.2e9
#: pixel-pulses: 5.5 s) on the 2-core machine; plus a fixed 0.05 s.
FFBP_PIXEL_PULSE_SECONDS = 3.2e-9
FFBP_PIXEL_SECONDS = 1.45e-7
FFBP_FIXED_SECONDS = 0.05

#: Direct backprojection throughput [pixel-pulses/s] on the same machine: 2.1e8 measured by
#: benchmarks/focus_bench.py (1024 x 1024 grid, 1024 pulses, no beam limit).
BACKPROJECTION_RATE = 2e8

#: Fixed cost [s] of one (pixel tile, pulse block) pair of the beam-limited direct
#: backprojection, paid whether or not the tile is in the beam (its float64 reference
#: geometry): fitted to two renders on the 2-core machine, urban (707 x 1041 pixels, 680
#: pulses: 1.0 s) and sionna:munich (3363 x 3287 pixels, 2264 pulses: 24 s), given
#: BACKPROJECTION_RATE.
BACKPROJECTION_TILE_SECONDS = 2.2e-4

#: Pixel tile ``(azimuth, range)`` and pulse block of :func:`sarmitsuba.focus.backproject`
#: (its ``_TILE`` and default ``pulse_block``), the units of the fixed cost above.
BACKPROJECTION_TILE = (16, 128)
BACKPROJECTION_PULSE_BLOCK = 128

# ---------------------------------------------------------------------------- peak memory
# Measured as the peak resident set of `sarmitsuba render` (GNU time's "Maximum resident
# set size", and /proc/self/statm sampled every millisecond per phase) on the 2-core machine,
# variant llvm_ad_mono, Mitsuba 3.9.1, Dr.Jit 1.5.0, libLLVM 19, NumPy 2.4, SciPy 1.17. Fitted on
# trihedral, dihedral (219 and 4,000 pulses), urban (default; 2,000 pulses; ray spacing 0.4 m;
# max_depth 1 and 5; quad; split_bounces; max_batch_rays 65536..524288; 600 MHz), sionna:munich
# and a 498,002-triangle mesh: the estimate is 0.8-1.5 times the measured peak on all of them.

#: Resident bytes of a render before it traces: Python, NumPy/SciPy, Mitsuba and Dr.Jit with the
#: LLVM backend and libLLVM, sarmitsuba and a small scene loaded and planned. Measured 210-213 MiB
#: at the start of the trace for trihedral, dihedral and urban (a render of the tiniest scenes
#: peaks at 313 MiB in all).
RUNTIME_BYTES = 215 * 2**20
#: Scene bytes per triangle and per shape (Mitsuba's meshes, Embree's BVH, the kernel's float64
#: triangle table and convex parts; the peak of loading): 800 B per triangle fitted to a
#: 498,002-triangle mesh (+365 MiB), plus 12 kB per shape to sionna:munich (38,936 triangles in
#: 2,367 shapes: +56 MiB).
SCENE_TRIANGLE_BYTES = 800
SCENE_SHAPE_BYTES = 12_000
#: Working set of the trace that does not grow with its launches [bytes]: the compiled kernels,
#: the JIT's buffers and the FFT block of the reduction to the band (256 pulses of the zero-padded
#: fine grid, :func:`sarmitsuba.tracing.deposit.fast_time.reduce_deposit`); fitted: 52 MiB.
TRACE_FIXED_BYTES = 52 * 2**20
#: Dr.Jit memory per lane of one launch [bytes]: its tubes, hits and records, the returns' term
#: lists of every bounce order and the allocator's cache of their freed arrays (Dr.Jit keeps them
#: until the trace ends). Fitted to urban with max_batch_rays 65,536, 131,072, 262,144 and 524,288
#: (trace working set 163, 288, 541 and 853 MiB): 1.4 kB (1.05 kB at max_depth 1).
LANE_BYTES = 1400
#: Bytes per complex entry of a batch's fine-grid histogram (:data:`HISTOGRAM_ENTRIES` at most):
#: :data:`HISTOGRAM_ENTRY_BYTES` for the NumPy sum of its launches, plus
#: :data:`HISTOGRAM_DEVICE_BYTES` on the device: four int64 words (docs/physics.md (D7)), once the
#: arrays the bounce orders re-zero are counted with the allocator's cache. The deposit adds
#: atomically into arrays larger than Dr.Jit's expand threshold (1 M words, 8 MiB), so they have
#: no per-thread copies, and the smaller ones' copies are bounded by that threshold. Measured on
#: urban (3.4 M entries in all): +120 MiB against the float32 deposit's peak with one launch at a
#: time (+125 MiB with two), the same with 1 and 2 Dr.Jit threads (``dr.set_thread_count``),
#: where the float32 deposit's per-thread copies had grown it by 65 MiB per thread.
HISTOGRAM_ENTRY_BYTES = 8
HISTOGRAM_DEVICE_BYTES = 56
#: What each further launch traced at once on host threads adds to one launch's working set: the
#: launches share Dr.Jit's allocator cache (the arrays one frees, the other reuses) and their peaks
#: do not coincide. Measured on urban (two launches of 4 sub-apertures at once): the render peaked
#: at 483 MiB against 630 MiB with one launch of 9, a working set about 1.07x that of one launch
#: of 4 as modelled; 0.25 leaves a margin for scenes whose launches peak together.
CONCURRENT_LAUNCH_SHARE = 0.25
#: Focusing and writing one image, per pixel [bytes]: fast factorised backprojection's sum grid,
#: polar images and workspaces and the calibrated copy; fitted to urban (0.97 M pixels: +43 MiB),
#: urban at 600 MHz (3.1 M: +121 MiB) and sionna:munich (12.2 M: +193 MiB).
FOCUS_PIXEL_BYTES = 24
#: Writing the products (NPZ files, PNG previews through matplotlib) [bytes]: 25-50 MiB measured.
WRITE_BYTES = 30 * 2**20


@dataclass(frozen=True)
class CostEstimate:
    """Estimated work and memory of a render (the times are estimates, within a factor ~2).

    With mesh-anchored patches (``lit_regions = "patches"``, the default) the rays are the
    visibility samples of the pieces: ``primary_rays`` are :data:`SAMPLES_PER_PIECE` per
    first-order piece in each sub-aperture's reach (:func:`reach_work`), the later
    orders' pieces fall off as :data:`PIECES_PER_ORDER` and each of their samples casts one ray
    per leg; the trace time adds the host work ``mesh_host_time_s`` (below). The tube fields
    below then describe the preview mode (``tiles``) and non-mesh shapes.

    Rays (``tiles``): ``rays_per_pulse`` is the coarse ray grid a pulse aims at the scene (rays outside the
    beam are not cast, so it is an upper bound). A sub-aperture of ``pulses_per_trace`` pulses
    traces the union of its pulses' grids once (docs/physics.md (T3)): ``primary_rays`` are the
    tubes of all ``subapertures``, plus the finer tubes around small objects for the
    sub-apertures that see them. Casts: ``primary_rays`` (low) to ``primary_rays * max_depth``
    (high) closest-hit casts, as many shadow casts. Returns: every pulse evaluates
    :data:`RETURNS_PER_TUBE` PO terms per tube it casts and, when a material is rough, the
    clutter scatterers of its tubes' footprints (``tube area / scatterer_spacing^2`` each):
    ``pulse_paths``. Trace time: :data:`TRACE_OVERHEAD` times the casts at the rates of
    :func:`cast_rates`, the returns at :data:`RETURN_SECONDS` and :data:`SCATTERER_SECONDS` and
    the reduction to the band at :data:`FFT_SECONDS` (once per bounce order: each order's energy is
    measured, docs/physics.md (D6)); ``trace_time_s`` takes the casts halfway
    between low and high.

    Arrays: the tracer's spectra, complex64 ``[groups, n_pulses, padded samples]`` (groups
    = ``max_depth`` with ``split_bounces``, else 1, times the channels: 4 for ``quad``;
    :func:`sarmitsuba.tracing.deposit.fast_time.padded_length`), or with the ``exact`` range kernel its term list
    instead, at most one path per return and channel of :data:`PATH_BYTES` each; one raw data
    set, complex64 ``[n_pulses, fast_time_samples]``; one image, complex64 ``image_shape``.
    ``n_products`` raw/image pairs are made (``1 + max_depth`` with ``split_bounces``, times the
    channels). The casts are the same for every polarisation (one trace for all channels); the
    returns' extra work per channel is not modelled.

    Peak memory [bytes], the render process's peak resident set (measured constants at
    :data:`RUNTIME_BYTES`): ``runtime_bytes`` (the runtime, :data:`RUNTIME_BYTES`, and the scene,
    :data:`SCENE_TRIANGLE_BYTES` and :data:`SCENE_SHAPE_BYTES`), plus the larger of two phases.
    Tracing: ``trace_working_bytes`` (:data:`TRACE_FIXED_BYTES`, :data:`LANE_BYTES` per lane of the
    largest launch, ``lanes_per_launch``, and per entry of a batch's histogram,
    ``histogram_entries``, :data:`HISTOGRAM_ENTRY_BYTES` plus :data:`HISTOGRAM_DEVICE_BYTES`), the
    spectra filled so far and the path list twice (its batches and
    their concatenation). Products: the spectra twice (with their sum over bounce orders), the
    path list, every raw data set twice (with its range-windowed copy) and image, and
    ``focus_working_bytes`` (:data:`FOCUS_PIXEL_BYTES` per pixel and :data:`WRITE_BYTES`).
    ``pulse_memory_bytes`` is the part of the peak that grows with the pulse count (spectra, path
    list, raw data). :func:`check_memory` compares ``peak_memory_bytes`` with the memory available.

    Mesh-anchored trace: ``reach_pieces_mean`` and ``reach_pieces_max`` are the
    first-order pieces in a sub-aperture's along-track reach (:func:`reach_work`);
    ``mesh_host_time_s`` the tracer's host time, :data:`SETUP_TRIANGLE_SECONDS` per triangle,
    :data:`SUB_PIECE_SECONDS` per piece and :data:`SUB_TRIANGLE_SECONDS` per triangle in each
    sub-aperture's reach and
    :data:`CLUTTER_SCATTERER_PULSE_SECONDS` per clutter scatterer-pulse of the area facing the
    sensor there (included in ``trace_time_s``); the working set holds :data:`SUBAPERTURE_BYTES`
    (or :data:`REACH_TRIANGLE_BYTES` per triangle of the largest reach, when less) for each of the
    ``subapertures_per_launch`` sub-apertures of a launch, times the launches traced at once
    (:func:`sarmitsuba.tracing.driver.threads.launches_at_once`), and the runtime
    :data:`MESH_TRIANGLE_BYTES` per triangle of the scene.

    Focusing, per image: the pixel-pulses inside the beam (stripmap: each pulse reaches the beam
    footprint's rows plus one tile; spotlight: every pixel and pulse) and the pixels some pulse
    lights. Fast factorised backprojection (the render's focuser): :data:`FFBP_PIXEL_PULSE_SECONDS`
    per pixel-pulse and :data:`FFBP_PIXEL_SECONDS` per lit pixel; direct backprojection (``bp``):
    :data:`BACKPROJECTION_RATE` plus :data:`BACKPROJECTION_TILE_SECONDS` per (tile, pulse block).
    """

    ray_spacing_m: float
    rays_per_pulse: int
    n_pulses: int
    pulses_per_trace: int
    subapertures: int
    primary_rays: int
    max_depth: int
    closest_hit_casts: int
    shadow_casts: int
    closest_hit_rate_per_s: float
    shadow_rate_per_s: float
    pulse_paths: int
    trace_time_low_s: float
    trace_time_high_s: float
    trace_time_s: float
    fast_time_samples: int
    fine_samples: int
    deposit_bytes: int
    path_list_bytes: int
    raw_bytes: int
    image_shape: tuple[int, int]
    image_bytes: int
    n_products: int
    backprojection_pixel_pulses: int
    focus_time_s: float
    direct_backprojection_time_s: float
    threads: int
    lanes_per_launch: int
    histogram_entries: int
    runtime_bytes: int
    trace_working_bytes: int
    focus_working_bytes: int
    pulse_memory_bytes: int
    peak_memory_bytes: int
    reach_pieces_mean: float = 0.0
    reach_pieces_max: float = 0.0
    subapertures_per_launch: int = 1
    mesh_host_time_s: float = 0.0
    reach_triangles_total: float = 0.0
    clutter_scatterer_pulses: float = 0.0
    time_basis: str = ""

    def __post_init__(self):
        if not self.time_basis:
            object.__setattr__(self, "time_basis", time_basis())


#: What every time of :class:`CostEstimate` assumes: the calibration of the rates above.
TIME_BASIS = ("times are for an idle 2-core x86-64 machine (2 Dr.Jit threads) at the rates calibrated on one "
              "(docs/design.md section 10), within a factor of 2: other processes running (a second render) "
              "lengthen them, and they are not scaled to this machine's cores")


def time_basis() -> str:
    """:data:`TIME_BASIS`, and this machine's cores and load average (where the system gives one)."""
    cores = os.cpu_count() or 1
    try:
        load = f", load average {os.getloadavg()[0]:.1f}"
    except (AttributeError, OSError):
        load = ""
    return f"{TIME_BASIS}; this machine: {cores} cores{load}"


def synthetic_aperture(p: RadarParameters) -> tuple[float, int]:
    """Synthetic aperture length [m, float] integrated per point, and the pulses in it (int).

    Stripmap: the traced beam's footprint ``2 R tan(h)`` at the scene centre (each point is
    lit while the platform flies that far; capped by the track); an orbit flies ``|V| / v_g``
    times the footprint, ``v_g`` the footprint's ground speed
    (:func:`~sarmitsuba.core.orbit.footprint_speed`, docs/physics.md (J7)). Spotlight: the whole
    track, ``N v / prf`` (the length behind :attr:`RadarParameters.integration_angle`).
    """
    if p.mode == "spotlight":
        return p.n_pulses * p.velocity / p.prf, p.n_pulses
    from ..core.orbit import footprint_speed
    length = p.footprint_length * p.velocity / footprint_speed(p)
    return length, int(min(p.n_pulses, max(1, round(length * p.prf / p.velocity))))


# ============================================================================ cost
def cast_rates(n_triangles: int) -> tuple[float, float]:
    """Estimated closest-hit and shadow ray-cast rates [casts/s] for a scene of ``n_triangles``.

    ``log(rate)`` is linear in ``log(n_triangles)`` between the two measured anchors of
    :data:`CAST_RATE_ANCHORS` (Embree's BVH makes the cost grow about logarithmically with
    the triangle count). Below the small anchor the small scene's rates are used; above the
    large one the line is extrapolated (an assumption, not a measurement). An estimate for
    the 2-core reference machine: expect a factor of 2 either way.
    """
    (t0, hit0, shadow0), (t1, hit1, shadow1) = CAST_RATE_ANCHORS
    x = (math.log(max(n_triangles, t0)) - math.log(t0)) / (math.log(t1) - math.log(t0))
    return hit0 * (hit1 / hit0) ** x, shadow0 * (shadow1 / shadow0) ** x


def cost_estimate(loaded: LoadedScene, geometry: AcquisitionGeometry, window: FastTimeWindow,
                  footprint: RayFootprint, effects: EffectSet | None = None) -> CostEstimate:
    """The estimated work and memory of rendering ``loaded`` (the model of :class:`CostEstimate`)
    with its planned ``window`` and ray ``footprint``; ``effects`` default
    :func:`~sarmitsuba.scene.effects.active_effects` of ``loaded``.

    Raises
    ------
    ParameterError
        The image grid would be too large (naming the parameters that set its size).
    """
    effects = active_effects(loaded) if effects is None else effects
    st, p = loaded.settings, loaded.params
    n_pulses = p.n_pulses
    size = pulses_per_trace(p, st, n_pulses, effects.moving_shapes)
    n_subs = math.ceil(n_pulses / size)
    # a sub-aperture's union of its pulses' lattices: the cells its antenna travel adds along track
    spread = math.ceil(min(size - 1, n_pulses - 1) * p.velocity / p.prf / footprint.spacing_azimuth)
    per_sub = (footprint.n_azimuth + spread) * footprint.n_range
    pulses_seeing = synthetic_aperture(p)[1]
    primary = per_sub * n_subs + footprint.refined_rays * math.ceil(pulses_seeing / size)
    casts = primary * st.depth
    hit_rate, shadow_rate = cast_rates(loaded.n_triangles)
    tube_pulses = footprint.rays_per_pulse * n_pulses + footprint.refined_rays * pulses_seeing
    tube_area = footprint.spacing_azimuth * footprint.spacing_range
    scatterers = (footprint.rays_per_pulse * n_pulses * tube_area / footprint.scatterer_spacing**2
                  if effects.clutter else 0.0)
    paths = int(RETURNS_PER_TUBE * tube_pulses + scatterers)      # per channel in the exact kernel's list
    groups = effects.groups * len(effects.channels)      # quad: four channels' spectra from one trace
    deposited = effects.deposit_groups * len(effects.channels)     # each order reduced apart (D6)
    arrays_apart = effects.deposit_groups // effects.groups       # host histograms per device one
    n_pad = padded_length(window.n_samples)
    work = (RETURNS_PER_TUBE * tube_pulses * RETURN_SECONDS + scatterers * SCATTERER_SECONDS
            + 3 * deposited * n_pulses * n_pad * window.oversample * FFT_SECONDS)

    host, piece_bytes, clutter_pulses = 0.0, 0, 0.0
    reach_pieces = reach_triangles = reach_area = np.zeros(0)
    if st.lit_regions == "patches":
        # the pieces' corners are the rays: every part in each sub-aperture's reach, cut into patches
        reach_pieces, reach_triangles, reach_area = reach_work(loaded, geometry, footprint.patch_size, size,
                                              not (effects.spotlight or effects.curved_track))
        orders = [PIECES_PER_ORDER[min(d, len(PIECES_PER_ORDER) - 1)] for d in range(st.depth)]
        primary = int(SAMPLES_PER_PIECE * reach_pieces.sum())
        casts = int(primary * sum(w * (d + 1) for d, w in enumerate(orders)))
        counts = np.minimum(size, n_pulses - size * np.arange(n_subs))          # pulses per sub-aperture
        clutter_pulses = (float(np.sum(reach_area * counts)) / footprint.scatterer_spacing ** 2
                          if effects.clutter else 0.0)
        host = (SETUP_TRIANGLE_SECONDS * loaded.n_triangles + SUB_PIECE_SECONDS * float(reach_pieces.sum())
                + SUB_TRIANGLE_SECONDS * float(reach_triangles.sum()) + CLUTTER_SCATTERER_PULSE_SECONDS * clutter_pulses)
        if effects.moving_shapes is not None:      # (V1), (V2): the tracer built anew, twice or more per sub-aperture
            host += MOVING_GEOMETRIES * MOVING_PIECE_SECONDS * float(reach_pieces.sum())
        piece_bytes = int(min(SUBAPERTURE_BYTES, REACH_TRIANGLE_BYTES * reach_triangles.max(initial=0.0)))

    def trace_time(closest: float) -> float:
        seconds = TRACE_OVERHEAD * (closest / hit_rate + closest / shadow_rate + work) + host
        return seconds * (BISTATIC_TRACE if effects.bistatic else 1.0)

    exact = st.range_kernel == "exact"          # keeps a path list instead of the fine grid
    grid = _checked_grid(loaded, geometry)
    n_products = (1 + (st.depth if effects.split_bounces else 0)) * len(effects.channels)
    pixel_pulses, lit, direct = _backprojection(p, grid)
    fast = FFBP_FIXED_SECONDS + pixel_pulses * FFBP_PIXEL_PULSE_SECONDS + lit * FFBP_PIXEL_SECONDS
    if effects.bistatic:                 # both legs per pixel; FFBP on the range sum's polar images (F10)
        direct *= BISTATIC_BACKPROJECTION
        fast *= BISTATIC_FFBP
    deposit = 0 if exact else groups * n_pulses * n_pad * 8
    path_list = paths * PATH_BYTES * len(effects.channels) if exact else 0
    raw_bytes, image_bytes = n_pulses * window.n_samples * 8, grid.shape[0] * grid.shape[1] * 8
    arrays = dict(apart=arrays_apart, deposit=deposit, path_list=path_list, raw=raw_bytes, image=image_bytes, n_products=n_products,
                  pixels=grid.shape[0] * grid.shape[1])
    memory = _memory(loaded, window, groups, exact, per_sub + footprint.refined_rays // n_subs, (size, n_subs), arrays,
                     piece_bytes, effects.moving_shapes is not None)
    return CostEstimate(
        ray_spacing_m=footprint.spacing_azimuth, rays_per_pulse=footprint.rays_per_pulse, n_pulses=n_pulses,
        pulses_per_trace=size, subapertures=n_subs, primary_rays=primary, max_depth=st.depth,
        closest_hit_casts=casts, shadow_casts=casts, closest_hit_rate_per_s=hit_rate, shadow_rate_per_s=shadow_rate,
        pulse_paths=paths, trace_time_low_s=trace_time(primary), trace_time_high_s=trace_time(casts),
        trace_time_s=trace_time(0.5 * (primary + casts)),
        fast_time_samples=window.n_samples, fine_samples=window.n_fine,
        deposit_bytes=deposit, path_list_bytes=path_list, raw_bytes=raw_bytes,
        image_shape=grid.shape, image_bytes=image_bytes, n_products=n_products,
        backprojection_pixel_pulses=n_products * pixel_pulses, focus_time_s=n_products * fast,
        direct_backprojection_time_s=n_products * direct,
        reach_pieces_mean=float(reach_pieces.mean()) if reach_pieces.size else 0.0,
        reach_pieces_max=float(reach_pieces.max(initial=0.0)), mesh_host_time_s=host,
        reach_triangles_total=float(reach_triangles.sum()), clutter_scatterer_pulses=clutter_pulses, **memory)


def _memory(loaded: LoadedScene, window: FastTimeWindow, groups: int, exact: bool, per_sub: int,
            subs: tuple[int, int], arrays: dict, piece_bytes: int = 0, moving: bool = False) -> dict:
    """The peak-memory fields of :class:`CostEstimate` (its model; constants at :data:`RUNTIME_BYTES`).

    ``groups``: spectra deposited per pulse (channels x bounce groups); ``exact``: the ``exact``
    kernel, which keeps no histogram; ``per_sub``: tubes of one sub-aperture (its lattice and refined
    cells); ``subs``: pulses per sub-aperture and sub-apertures; ``arrays``: the host's histograms per
    device histogram (``apart``: each bounce order's, read apart for its energy, (D6)), the bytes of
    the spectra (``deposit``), ``path_list``, one ``raw`` data set and one ``image``, ``n_products`` and the
    image's ``pixels``; ``piece_bytes``: the mesh tracer's working set of the sub-aperture with the
    sub-apertures of a launch (at most :data:`SUBAPERTURE_BYTES` each; non-zero: the mesh tracer, which also
    holds :data:`MESH_TRIANGLE_BYTES` per scene triangle).
    Batches follow :func:`sarmitsuba.tracing.driver.trace.plan_trace`: as many sub-apertures as fit in
    ``max_batch_rays`` tubes and :data:`HISTOGRAM_ENTRIES` histogram entries.
    """
    st, n_pulses, (size, n_subs) = loaded.settings, loaded.params.n_pulses, subs
    per_pulse_entries = len(SPECTRAL_ORDERS) * max(window.n_fine, 1) * groups
    budget = max(size, HISTOGRAM_ENTRIES // per_pulse_entries)
    per_batch = max(1, min(n_subs, st.max_batch_rays // max(per_sub, 1), budget // size))
    # the mesh tracer's launches at once, each with that share of the sub-apertures (tracing.driver.threads);
    # moving shapes: one sub-aperture per launch, one launch at once (tracing.driver.moving)
    at_once = launches_at_once() if piece_bytes and not moving else 1
    per_batch = 1 if moving else max(1, per_batch // at_once)
    lanes = min(st.max_batch_rays, per_batch * per_sub)
    entries = 0 if exact else per_pulse_entries * min(n_pulses, per_batch * size)
    threads = max(1, dr.thread_count())
    runtime = (RUNTIME_BYTES + (SCENE_TRIANGLE_BYTES + (MESH_TRIANGLE_BYTES if piece_bytes else 0)) * loaded.n_triangles
               + SCENE_SHAPE_BYTES * loaded.n_shapes)
    working = (1 + CONCURRENT_LAUNCH_SHARE * (at_once - 1)) * (
        TRACE_FIXED_BYTES + LANE_BYTES * lanes + piece_bytes * per_batch
        + (HISTOGRAM_ENTRY_BYTES * arrays.get("apart", 1) + HISTOGRAM_DEVICE_BYTES) * entries)
    focusing = FOCUS_PIXEL_BYTES * arrays["pixels"] + WRITE_BYTES
    n, deposit, path_list = arrays["n_products"], arrays["deposit"], arrays["path_list"]
    tracing = (working, deposit + 2 * path_list)                     # (fixed, grows with the pulses)
    products = (n * arrays["image"] + focusing, 2 * deposit + path_list + 2 * n * arrays["raw"])
    phase = max(tracing, products, key=sum)
    return dict(threads=threads, lanes_per_launch=int(lanes), subapertures_per_launch=int(per_batch), histogram_entries=int(entries),
                runtime_bytes=int(runtime), trace_working_bytes=int(working), focus_working_bytes=int(focusing),
                pulse_memory_bytes=int(phase[1]), peak_memory_bytes=int(runtime + sum(phase)))


def _checked_grid(loaded: LoadedScene, geometry: AcquisitionGeometry):
    """The render's image grid (:func:`sarmitsuba.focus.scene_grid.image_grid`); ParameterError naming the
    parameters that set its size when it would be too large."""
    try:
        return image_grid(loaded, geometry)
    except ValueError as exc:
        p = loaded.params
        raise ParameterError(
            f"the image grid is too large ({exc}): its pixels are half the finer of the ground-range resolution "
            f"{p.ground_range_resolution:.3g} m (bandwidth {p.bandwidth / 1e6:g} MHz) and the azimuth resolution "
            f"{p.azimuth_resolution:.3g} m (azimuth_beamwidth / antenna_length) across a scene of "
            f"{np.ptp(np.stack([loaded.bbox_lo, loaded.bbox_hi]), axis=0).max():.4g} m: lower bandwidth, narrow the "
            "beam or use a smaller scene") from None


def _backprojection(p: RadarParameters, grid) -> tuple[int, int, float]:
    """Pixel-pulses inside the beam, pixels some pulse lights, and the estimated seconds of one
    direct beam-limited backprojection onto ``grid`` (the model of :class:`CostEstimate`)."""
    n_az, n_rg = grid.shape
    rows, lit_rows = n_az, n_az
    if p.mode == "stripmap" and n_az > 1:        # the pipeline limits stripmap focusing to the beam
        spacing = float(grid.azimuth[1] - grid.azimuth[0])
        rows = min(n_az, math.ceil(p.footprint_length / spacing) + BACKPROJECTION_TILE[0])
        track = (p.n_pulses - 1) * p.velocity / p.prf
        lit_rows = min(n_az, math.ceil((track + p.footprint_length) / spacing))
    pixel_pulses = p.n_pulses * rows * n_rg
    pairs = (math.ceil(n_az / BACKPROJECTION_TILE[0]) * math.ceil(n_rg / BACKPROJECTION_TILE[1])
             * math.ceil(p.n_pulses / BACKPROJECTION_PULSE_BLOCK))
    return pixel_pulses, lit_rows * n_rg, pixel_pulses / BACKPROJECTION_RATE + pairs * BACKPROJECTION_TILE_SECONDS


def format_bytes(n: int) -> str:
    """``n`` bytes for people: ``'1.5 GiB'``, ``'12.0 MiB'``, ``'3 B'`` (binary prefixes)."""
    for unit, size in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{n} B"
