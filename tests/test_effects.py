"""Optional effects are simulated only when the scene calls for them (docs/design.md section 7, issue #6).

1. Kernel inspection. With Dr.Jit's ``KernelHistory`` flag every launched kernel is recorded
   with its ``operation_count`` and its LLVM IR (present even for cache hits: the IR is what the
   cache is keyed on). The tracer launches one kernel per bounce order (a wavefront: intersect,
   shadow ray, record) and per-pulse return kernels (docs/design.md section 10); a trace is the
   set of its distinct kernels. A scene asking for no optional effect (smooth plane,
   ``max_depth = 1``) compiles one bounce kernel and no reflection, no clutter hash, no elevation
   pattern, no radar-equation spreading and no beam steering; turning each effect on adds
   operations and the effect's signature instruction (more bounce kernels, each with Embree's
   two indirect calls; the scatterer hash's multiplier, the antenna's height in wavelengths, a
   float32 division, a float64 square root, an integer multiplication). The default beam is
   tapered (docs/physics.md (A)): its azimuth pattern is in every kernel except the
   ``uniform`` beam's, which compiles no pattern at all.
   Effects applied after tracing (thermal noise, chirped output) leave the kernel unchanged.
2. An effect the scene does not contain changes nothing. Which comparisons are exact:

   * the tracer's spectra: the same contributions summed by float32 adds whose order may
     depend on thread scheduling, so equal to ~1e-6 relative (bitwise equal in practice at
     these sizes); compared with a 1e-6 relative tolerance;
   * ``max_depth`` widens the fast-time window (room for longer multi-bounce delays), so
     depth-1 and depth-3 are traced into the same (depth-3) window and compared there;
   * ``split_bounces``: the total is the sum of the per-order deposits, so with single-bounce
     paths only, the order-1 raw data equal the total bit for bit;
   * noise parameters without a noise seed: the same arithmetic, bitwise equal.
3. Post-trace effects: a scene without noise parameters never calls the noise generator, and
   range-compressed output never computes a chirp spectrum (checked by patching them).
"""
from __future__ import annotations

import dataclasses
import re
import struct
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from sarmitsuba import binning, pipeline, planning, radiometry   # first: finds libLLVM, sets the variant
from sarmitsuba.focus import range_compression
from sarmitsuba.radar import acquisition_geometry

import drjit as dr  # noqa: E402  (after sarmitsuba)

SCENES = Path(__file__).parent / "scenes"
PLANE = str(SCENES / "plane.xml")                   # smooth plate: single bounce, no optional effect
ROUGH = str(SCENES / "rough_ground.xml")            # rough plate: single bounce, strong clutter signal
UNUSED_ROUGH = str(SCENES / "effects_unused_rough.xml")
HIDDEN_ROUGH = str(SCENES / "effects_hidden_rough.xml")
HIDDEN_SMOOTH = str(SCENES / "effects_hidden_smooth.xml")

#: Kernel-structure runs: 4 pulses, 2 m ray tubes (~1,500 rays), one batch.
SMALL = {"n_pulses": 4}
COARSE = {"max_depth": 1, "ray_spacing": 2.0}
#: Output-comparison runs: 8 pulses, 1 m ray tubes (~10,000-14,000 rays).
EIGHT = {"n_pulses": 8}
FINER = {"max_depth": 1, "ray_spacing": 1.0}
RADIOMETRY = {"transmit_power": 1000.0, "antenna_gain_db": 30.0}

SCATTERER_HASH = re.compile(r"\b(2221713035|-2073254261)\b")   # 0x846ca68b, the scatterer hash's multiplier


@dataclasses.dataclass
class Traced:
    """A simulation and the JIT kernels its tracing stage launched."""

    sim: pipeline.Simulation
    kernels: list

    @property
    def distinct(self) -> list:
        """The distinct JIT kernels launched while tracing (by their IR's hash)."""
        return list({k["hash"]: k for k in self.kernels}.values())

    @property
    def ops(self) -> int:
        """Operations of the trace: summed over its distinct kernels."""
        return int(sum(k["operation_count"] for k in self.distinct))

    @property
    def ir(self) -> str:
        return "\n".join(k["ir"] for k in self.distinct)

    @property
    def casts(self) -> int:
        """Mitsuba ray casts: closest-hit casts of every order plus shadow casts."""
        return int(self.sim.trace.rays_per_order.sum() + self.sim.trace.shadow_rays)


@contextmanager
def _kernel_history():
    """Record the kernels launched inside the block (Dr.Jit KernelHistory), restoring the flag."""
    before = dr.flag(dr.JitFlag.KernelHistory)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    dr.kernel_history()                                   # discard anything recorded earlier
    launched: list = []
    try:
        yield launched
        launched.extend(dr.kernel_history())
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, before)


def traced(source, sensor=None, integrator=None, material=None, base_sensor=SMALL, base_integrator=COARSE):
    """simulate() recording the JIT kernels of its tracing stage only (pipeline.trace wrapped)."""
    real = pipeline.trace
    kernels: list = []

    def spy(*args, **kwargs):
        with _kernel_history() as launched:
            result = real(*args, **kwargs)
        kernels.extend({**k, "ir": k["ir"].getvalue()} for k in launched if k["type"] == dr.KernelType.JIT)
        return result

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pipeline, "trace", spy)
        sim = pipeline.simulate(source, sensor_overrides={**base_sensor, **(sensor or {})},
                                integrator_overrides={**base_integrator, **(integrator or {})},
                                material_overrides=material)
    assert kernels, "no JIT kernel recorded while tracing"
    assert all(k["ir"] for k in kernels), "kernel history carries no IR"
    return Traced(sim, kernels)


def _float_literal(value: float) -> str:
    """How Dr.Jit's LLVM backend writes a float32 constant: the double's hex of float32(value)."""
    return "0x" + struct.pack(">d", float(np.float32(value))).hex()


def _count(pattern: str, ir: str) -> int:
    return len(re.findall(pattern, ir, flags=re.IGNORECASE))


# ---- signatures: instructions an effect puts in the kernel --------------------------------------

def _loop(t: Traced) -> int:
    """Distinct bounce kernels: those that cast rays (Embree's indirect calls), one per bounce order
    (the first, the middle ones and the last compile differently)."""
    return sum(1 for k in t.distinct if "call void %rd" in k["ir"])


def _hash(t: Traced) -> int:
    return len(SCATTERER_HASH.findall(t.ir))              # the clutter scatterers' hash (kernel._hash)


def _length_in_wavelengths(t: Traced, length: float = 1.5) -> int:
    p = t.sim.loaded.params                               # sinc(H_a sin(phi) / lambda): H_a / lambda
    return _count(re.escape(_float_literal(length / p.wavelength)), t.ir)


def _taper(t: Traced) -> int:
    p = t.sim.loaded.params                               # the tapered beam's L / lambda
    return _count(re.escape(_float_literal(p.pattern_length / p.wavelength)), t.ir) if p.pattern_length else 0


def _f32_divisions(t: Traced) -> int:
    return _count(r"= fdiv <\d+ x float>", t.ir)          # R_ref^2 / (R_tx R_rx)


def _f64_square_roots(t: Traced) -> int:
    return _count(r"@llvm\.sqrt\.v\d+f64", t.ir)          # |A - scene centre| of the steered beam


def _i32_multiplications(t: Traced) -> int:
    return _count(r"= mul <\d+ x i32>", t.ir)            # deposit index + order * order stride


#: effect -> (baseline overrides, effect overrides, signature, minimum extra operations).
EFFECTS = {
    "bounce_loop": ({}, {"integrator": {"max_depth": 3}}, _loop, 50),
    "clutter_gamma": ({}, {"material": {"gamma_db": -10.0}}, _hash, 100),
    "clutter_lambert": ({}, {"material": {"scattering_coefficient": 0.3}}, _hash, 100),
    "antenna_pattern": ({}, {"sensor": {"antenna_height": 1.5}}, _length_in_wavelengths, 20),
    "radiometry": ({}, {"sensor": RADIOMETRY}, _f32_divisions, 5),
    "spotlight": ({}, {"sensor": {"mode": "spotlight"}}, _f64_square_roots, 5),
    "split_bounces": ({"integrator": {"max_depth": 3}},
                      {"integrator": {"max_depth": 3, "split_bounces": True}}, _i32_multiplications, 1),
}


@pytest.fixture(scope="module")
def plain() -> Traced:
    return traced(PLANE)


def test_plain_scene_kernel_has_no_optional_effect(plain):
    """Smooth plane, max_depth 1: one straight-line kernel, one closest-hit cast per primary ray."""
    assert _loop(plain) == 1, "more than one bounce kernel was compiled for max_depth = 1"
    assert _hash(plain) == 0, "the clutter hash was compiled for a smooth scene"
    assert "Symbolic loop: scatterers" not in plain.ir
    rays = plain.sim.trace.rays_per_order
    assert rays.shape == (1,) and rays[0] > 0
    assert 0 < plain.sim.trace.shadow_rays <= rays[0]     # at most one shadow cast per hit
    assert plain.casts == rays[0] + plain.sim.trace.shadow_rays
    # the bounce kernel and the per-pulse PO terms, each evaluated at its own point (reflection
    # coefficient, two-way pattern of the default beam; docs/physics.md (PO4)): about 1900 operations
    assert 300 < plain.ops < 3000, f"plain kernels have {plain.ops} operations"
    print(f"\nplain kernel: {plain.ops} operations, {len(plain.ir)} chars of IR, {plain.casts} casts")


@pytest.mark.parametrize("effect", list(EFFECTS))
def test_effect_adds_its_code_to_the_kernel(effect, plain):
    base_overrides, on_overrides, signature, min_extra = EFFECTS[effect]
    base = traced(PLANE, **base_overrides) if base_overrides else plain
    on = traced(PLANE, **on_overrides)
    extra = on.ops - base.ops
    print(f"\n{effect}: {base.ops} -> {on.ops} operations (+{extra}); signature {signature(base)} -> "
          f"{signature(on)}; casts {base.casts} -> {on.casts}")
    assert extra >= min_extra, f"{effect}: {base.ops} -> {on.ops} operations"
    assert signature(on) > signature(base), f"{effect}: signature instruction missing from the kernel"
    if signature in (_hash, _length_in_wavelengths):
        assert signature(base) == 0 and signature(plain) == 0
    if effect == "bounce_loop":
        assert on.sim.trace.rays_per_order.shape == (3,)
        assert on.casts > base.casts                      # reflected rays are cast (and miss)


def test_uniform_beam_compiles_no_pattern(plain):
    """The tapered default beam weights every return with its azimuth pattern; ``beam = uniform``
    (a hard-edged beam, on request) compiles none: fewer operations, no L / lambda constant."""
    uniform = traced(PLANE, sensor={"beam": "uniform"})
    assert _taper(plain) > 0 and _taper(uniform) == 0
    assert uniform.ops < plain.ops - 20, f"{plain.ops} -> {uniform.ops} operations"


@pytest.mark.parametrize("effect", ["thermal_noise", "chirped_output"])
def test_post_trace_effects_leave_the_kernel_unchanged(effect):
    """Noise and chirps are applied by the binning stage: the tracing kernel is the same."""
    if effect == "thermal_noise":
        base = traced(PLANE, sensor=RADIOMETRY)
        on = traced(PLANE, sensor={**RADIOMETRY, "noise_figure_db": 3.0})
    else:
        base = traced(PLANE)
        on = traced(PLANE, sensor={"output": "raw"})      # only the window's start moves
        assert not on.sim.raw.range_compressed
    assert on.ops == base.ops
    assert on.casts == base.casts


# ---- 2. an effect the scene does not contain changes nothing ---------------------------------------

def _assert_close(a: np.ndarray, b: np.ndarray, what: str, rtol: float = 1e-6) -> None:
    assert a.shape == b.shape, f"{what}: shapes {a.shape} and {b.shape}"
    scale = np.abs(a).max()
    assert scale > 0, f"{what}: all zero (the comparison would be vacuous)"
    err = np.abs(a - b).max()
    assert err <= rtol * scale, f"{what}: max difference {err:.3g} of {scale:.3g}"


def _trace_in_window(source, window_from, integrator):
    """Trace ``source`` with ``integrator`` overrides into the fast-time window and ray lattice
    planned for ``window_from`` (another max_depth): the same samples for both."""
    from sarmitsuba.scene import load_scene, material_table
    from sarmitsuba.trace import trace
    settings = {**FINER, **integrator}
    loaded = load_scene(source, EIGHT, settings)
    planned = load_scene(source, EIGHT, {**FINER, **window_from})
    p = loaded.params
    geometry = acquisition_geometry(p)
    window = planning.fast_time_window(p, geometry, planned.bbox_lo, planned.bbox_hi, planned.settings)
    footprint = planning.ray_footprint(p, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings,
                                       shape_boxes=loaded.shape_boxes)
    return trace(loaded.scene, p, geometry, window, footprint, loaded.settings,
                 material_table(loaded.scene, p.frequency, p.polarization))


def test_bounce_loop_on_a_single_bounce_scene_changes_nothing():
    """Rough plate: reflected rays leave for the sky. max_depth 3 spends casts, adds nothing."""
    one = traced(ROUGH, base_sensor=EIGHT, base_integrator=FINER)
    three = traced(ROUGH, integrator={"max_depth": 3}, base_sensor=EIGHT, base_integrator=FINER)
    # order 2 is cast (and misses); no tube is left for order 3, whose kernel never runs
    assert _loop(three) == 2 and _loop(one) == 1
    rays = three.sim.trace.rays_per_order
    assert rays[0] == one.sim.trace.rays_per_order[0] and rays[1] > 0        # order-2 casts ...
    assert three.sim.trace.shadow_rays == one.sim.trace.shadow_rays          # ... that never hit
    assert not np.any(three.sim.trace.energy_per_order[1:])
    # in the same (depth-3) window, depth 1 and depth 3 give the same spectra
    d1 = _trace_in_window(ROUGH, {"max_depth": 3}, {"max_depth": 1}).spectrum
    _assert_close(d1, three.sim.trace.spectrum, "spectrum")


def test_rough_material_used_by_no_shape_changes_nothing(plain):
    """A rough BSDF that no shape references: no clutter term in the kernel, plane.xml's output."""
    unused = traced(UNUSED_ROUGH)
    assert _hash(unused) == 0
    assert unused.ops == plain.ops
    np.testing.assert_array_equal(unused.sim.trace.rays_per_order, plain.sim.trace.rays_per_order)
    _assert_close(plain.sim.trace.spectrum, unused.sim.trace.spectrum, "spectrum")
    _assert_close(plain.sim.raw.data, unused.sim.raw.data, "raw data")
    _assert_close(plain.sim.image.data, unused.sim.image.data, "image")


def test_rough_shape_no_ray_reaches_changes_nothing():
    """A rough plate buried under the smooth plane: the scene has a rough material, but no hit
    is on it, so no clutter kernel runs (it is launched only for visible rough hits; what runs is
    the selection of rough hits, a handful of operations) and the output is the smooth scene's."""
    rough = traced(HIDDEN_ROUGH, base_sensor=EIGHT, base_integrator=FINER)
    smooth = traced(HIDDEN_SMOOTH, base_sensor=EIGHT, base_integrator=FINER)
    assert _hash(rough) == 0 and _hash(smooth) == 0
    assert 0 <= rough.ops - smooth.ops <= 20, (rough.ops, smooth.ops)
    assert rough.casts == smooth.casts
    _assert_close(smooth.sim.trace.spectrum, rough.sim.trace.spectrum, "spectrum")
    _assert_close(smooth.sim.raw.data, rough.sim.raw.data, "raw data")
    _assert_close(smooth.sim.image.data, rough.sim.image.data, "image")


def test_split_bounces_with_single_bounce_paths_only():
    """Per-order products of a single-bounce scene: order 1 is the total, order 2 is empty."""
    split = traced(ROUGH, integrator={"max_depth": 2, "split_bounces": True},
                   base_sensor=EIGHT, base_integrator=FINER)
    merged = traced(ROUGH, integrator={"max_depth": 2}, base_sensor=EIGHT, base_integrator=FINER)
    sim = split.sim
    assert len(sim.raw_per_order) == 2
    assert np.abs(sim.raw.data).max() > 0
    np.testing.assert_array_equal(sim.raw_per_order[0].data, sim.raw.data)     # exact: total = order 1 + 0
    assert not np.any(sim.raw_per_order[1].data)
    assert not np.any(sim.trace.spectrum_per_order[1])
    _assert_close(merged.sim.trace.spectrum, sim.trace.spectrum, "spectrum")
    _assert_close(merged.sim.raw.data, sim.raw.data, "raw data")


# ---- 3. post-trace effects: the noise generator and the chirp spectrum ------------------------------

def _forbidden(name):
    def fail(*args, **kwargs):
        raise AssertionError(f"{name} was called for a scene that does not ask for it")
    return fail


def _counting(function, calls: list):
    def wrapper(*args, **kwargs):
        calls.append(args)
        return function(*args, **kwargs)
    return wrapper


@pytest.mark.parametrize("sensor", [{}, RADIOMETRY], ids=["normalised", "absolute"])
def test_noiseless_scene_never_calls_the_noise_generator(sensor, monkeypatch):
    monkeypatch.setattr(radiometry, "thermal_noise", _forbidden("thermal_noise"))
    sim = pipeline.simulate(PLANE, sensor_overrides={**SMALL, **sensor}, integrator_overrides=COARSE)
    assert "noise_power_w" not in sim.raw.metadata


def test_noise_parameters_without_noise_seed_change_nothing(monkeypatch):
    """The generator is called when noise is on (so the patch above is effective); with noise
    parameters but no noise seed the binning output is bit-identical to the noiseless sensor's."""
    calls: list = []
    monkeypatch.setattr(radiometry, "thermal_noise", _counting(radiometry.thermal_noise, calls))
    noisy = pipeline.simulate(PLANE, sensor_overrides={**SMALL, **RADIOMETRY, "noise_figure_db": 3.0},
                              integrator_overrides=COARSE)
    assert len(calls) == 1 and noisy.raw.metadata["noise_power_w"] > 0
    calls.clear()
    sim = pipeline.simulate(PLANE, sensor_overrides={**SMALL, **RADIOMETRY}, integrator_overrides=COARSE)
    assert not calls
    loaded = sim.loaded
    geometry = acquisition_geometry(loaded.params)
    window = planning.fast_time_window(loaded.params, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings)
    with_noise_params = dataclasses.replace(loaded.params, noise_figure_db=3.0)
    quiet = binning.to_raw_data(sim.trace.spectrum, sim.trace, window, with_noise_params, geometry,
                                {}, noise_seed=None)
    assert not calls
    assert np.abs(sim.raw.data).max() > 0
    np.testing.assert_array_equal(quiet.data, sim.raw.data)
    seeded = binning.to_raw_data(sim.trace.spectrum, sim.trace, window, with_noise_params, geometry,
                                 {}, noise_seed=0)
    assert len(calls) == 1 and not np.array_equal(seeded.data, sim.raw.data)


def test_compressed_output_computes_no_chirp_spectrum(monkeypatch):
    monkeypatch.setattr(range_compression, "chirp_spectrum", _forbidden("chirp_spectrum"))
    sim = pipeline.simulate(PLANE, sensor_overrides=SMALL, integrator_overrides=COARSE)
    assert sim.raw.range_compressed


def test_raw_output_computes_the_chirp_spectrum(monkeypatch):
    """Positive control for the patch above: chirped output does call it."""
    calls: list = []
    monkeypatch.setattr(range_compression, "chirp_spectrum", _counting(range_compression.chirp_spectrum, calls))
    sim = pipeline.simulate(PLANE, sensor_overrides={**SMALL, "output": "raw"}, integrator_overrides=COARSE)
    assert not sim.raw.range_compressed
    assert len(calls) >= 1
