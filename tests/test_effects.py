"""Optional effects are simulated only when the scene calls for them (docs/design.md section 7, issue #6).

Behavioural checks only (no JIT-kernel inspection, no timing: both depend on the machine and
the Dr.Jit version):

1. An effect's parameter set explicitly to its "off" value gives the same simulation as a
   scene that never mentions it: the same raw data (within 1e-6 of the peak: the renders differ
   in a setting, so the bit-for-bit guarantee of docs/physics.md (D7) is not assumed; measured
   equal; the smallest effect, stop-and-hop switched on, moves them by 2.3e-5 of the peak, 23
   times the tolerance), the same deterministic work counters
   (closest-hit casts per order, shadow casts, PO/clutter returns evaluated, clutter
   scatterers), and the effect absent from ``metadata["effects"]``. Positive control: the
   effect switched on is listed there and changes the output or the work counters, so the
   comparison could have failed.
2. An effect the scene does not contain changes nothing. Which comparisons are exact:

   * the tracer's spectra: the same contributions, but from other settings, scene files and
     kernels than the reference's (not the same render of (D7)), so compared within 1e-6 of the
     peak (measured equal bit for bit); clutter deposited on the plate (gamma -10 dB) moves
     them by 9 times the smooth plate's peak;
   * ``max_depth`` widens the fast-time window (room for longer multi-bounce delays), so
     depth-1 and depth-3 are traced into the same (depth-3) window and compared there;
   * ``split_bounces``: the total is the sum of the per-order deposits, so with single-bounce
     paths only, the order-1 raw data equal the total bit for bit;
   * noise parameters without a noise seed: the same arithmetic, bitwise equal.
3. Post-trace effects: a scene without noise parameters never calls the noise generator, and
   range-compressed output never computes a chirp spectrum (checked by patching them).

Edge diffraction (docs/physics.md (E1)-(E6)) is the one effect on by default (issue 54: it costs
1.04 x the render without it on urban, 1.02 x on Munich, measured by benchmarks/diffraction.py):
the baseline here switches it off, and a scene without overrides lists it.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sarmitsuba.signal import binning, radiometry, signal_model
from sarmitsuba import pipeline
from sarmitsuba.scene import planning
from sarmitsuba.core.geometry import acquisition_geometry
from sarmitsuba.scene.radar_equation import radar_equation

SCENES = Path(__file__).parent / "scenes"
PLANE = str(SCENES / "plane.xml")                   # smooth plate: single bounce, no optional effect
ROUGH = str(SCENES / "rough_ground.xml")            # rough plate: single bounce, strong clutter signal
UNUSED_ROUGH = str(SCENES / "effects_unused_rough.xml")
HIDDEN_ROUGH = str(SCENES / "effects_hidden_rough.xml")
HIDDEN_SMOOTH = str(SCENES / "effects_hidden_smooth.xml")

#: Small runs: 4 pulses, 2 m ray tubes (~1,500 rays), one batch.
SMALL = {"n_pulses": 4}
COARSE = {"max_depth": 1, "ray_spacing": 2.0}
#: Output-comparison runs: 8 pulses, 1 m ray tubes (~10,000-14,000 rays).
EIGHT = {"n_pulses": 8}
FINER = {"max_depth": 1, "ray_spacing": 1.0}
RADIOMETRY = {"transmit_power": 1000.0, "antenna_gain_db": 30.0}


@dataclasses.dataclass
class Traced:
    """A simulation and its deterministic work counters."""

    sim: pipeline.Simulation

    @property
    def casts(self) -> int:
        """Mitsuba ray casts: closest-hit casts of every order plus shadow casts."""
        return int(self.sim.trace.rays_per_order.sum() + self.sim.trace.shadow_rays)

    @property
    def work(self) -> dict:
        """Counters of the tracer's work (machine-independent, unlike its wall time)."""
        t = self.sim.trace
        return {"rays_per_order": t.rays_per_order.tolist(), "shadow_rays": int(t.shadow_rays),
                "pulse_paths": int(t.pulse_paths), "scatterers": int(np.sum(t.scatterers_per_order))}

    @property
    def effects(self) -> list:
        """Names of the active effects, from ``metadata["effects"]`` ("name (reason)")."""
        return [e.split(" (")[0] for e in self.sim.raw.metadata["effects"]]


def traced(source, sensor=None, integrator=None, material=None, base_sensor=SMALL, base_integrator=COARSE):
    """simulate() with the small default overrides merged with ``sensor`` / ``integrator``."""
    sim = pipeline.simulate(source, sensor_overrides={**base_sensor, **(sensor or {})},
                            integrator_overrides={**base_integrator, **(integrator or {})},
                            material_overrides=material)
    return Traced(sim)


# ---- 1. an effect's "off" value is the scene that never asked for it ------------------------------

#: effect name (scene/effects.py) -> (overrides setting it off explicitly or None, overrides switching it on).
#: Runs use the scene's own max_depth (1) so that "max_depth = 1" is a real explicit override.
EFFECTS = {
    "bounce orders > 1": ({"integrator": {"max_depth": 1}}, {"integrator": {"max_depth": 3}}),
    "distributed clutter and speckle": (None, {"material": {"gamma_db": -10.0}}),
    "antenna pattern": ({"sensor": {"antenna_height": 0.0, "antenna_length": 0.0}},
                        {"sensor": {"antenna_height": 1.5}}),
    "chirped raw echoes": ({"sensor": {"output": "compressed"}}, {"sensor": {"output": "raw"}}),
    "absolute radiometry": (None, {"sensor": RADIOMETRY}),
    "spotlight": ({"sensor": {"mode": "stripmap"}}, {"sensor": {"mode": "spotlight"}}),
    "squint": ({"sensor": {"squint": 0.0}}, {"sensor": {"squint": 3.0}}),
    "per-bounce-order products": ({"integrator": {"split_bounces": False}},
                                  {"integrator": {"split_bounces": True}}),
    "cross-polarised channels": ({"sensor": {"polarization": "VV"}}, {"sensor": {"polarization": "HV"}}),
    "motion errors": ({"sensor": {"motion_error": "none"}}, {"sensor": {"motion_error": "0.05, 2"}}),
    "curved track": ({"sensor": {"trajectory": "straight"}}, {"sensor": {"trajectory": "circular"}}),   # n_pulses sets the arc
    "stop-and-hop approximation": ({"sensor": {"stop_and_hop": False}}, {"sensor": {"stop_and_hop": True}}),
    "edge diffraction": ({"integrator": {"diffraction": False}}, {"integrator": {"diffraction": True}}),
    "scatterer catalogue": ({"integrator": {"scatterers": False}}, {"integrator": {"scatterers": True}}),
}
#: The baseline: no optional effect, edge diffraction (on by default) off.
NO_DEPTH = {"ray_spacing": 2.0, "diffraction": False}


def _run(overrides=None) -> Traced:
    return traced(PLANE, base_integrator=NO_DEPTH, **(overrides or {}))


@pytest.fixture(scope="module")
def plain() -> Traced:
    return _run()


def test_plain_scene_lists_no_optional_effect(plain):
    """Smooth plane, edge diffraction off: nothing optional is on, one closest-hit cast per primary
    ray. Without that override the plane lists edge diffraction alone (its rims diffract)."""
    assert plain.effects == [], plain.sim.raw.metadata["effects"]
    assert traced(PLANE, base_integrator={"ray_spacing": 2.0}).effects == ["edge diffraction"]
    rays = plain.sim.trace.rays_per_order
    assert rays.shape == (1,) and rays[0] > 0
    assert plain.sim.trace.shadow_rays == 0    # one bounce: each sample's one ray is both legs (M4)
    assert plain.work["scatterers"] == 0                  # no clutter scatterer deposited
    assert plain.sim.trace.spectrum_per_order is None


@pytest.mark.parametrize("effect", [e for e, (off, _) in EFFECTS.items() if off is not None])
def test_effect_set_off_changes_nothing_and_costs_nothing(effect, plain):
    off = _run(EFFECTS[effect][0])
    assert effect not in off.effects and off.effects == plain.effects
    assert off.work == plain.work, f"{effect} off: work {off.work}, plain scene {plain.work}"
    _assert_close(plain.sim.raw.data, off.sim.raw.data, f"{effect} off: raw data")
    assert off.sim.raw.range_compressed == plain.sim.raw.range_compressed


@pytest.mark.parametrize("effect", list(EFFECTS))
def test_effect_switched_on_is_listed_and_changes_something(effect, plain):
    """Positive control for the test above: turning the effect on is visible in the metadata and
    in the output or the work counters."""
    on = _run(EFFECTS[effect][1])
    assert effect in on.effects, on.sim.raw.metadata["effects"]
    data_changed = (on.sim.raw.data.shape != plain.sim.raw.data.shape
                    or np.abs(on.sim.raw.data - plain.sim.raw.data).max() > 1e-3 * np.abs(plain.sim.raw.data).max())
    per_order = on.sim.trace.spectrum_per_order is not None
    # stop-and-hop moves the receive positions by v tau (0.9 mm here: the data change below 1e-3)
    moved = not np.array_equal(on.sim.raw.rx_position, plain.sim.raw.rx_position)
    catalogue = on.sim.trace.catalogue is not None and plain.sim.trace.catalogue is None
    assert data_changed or on.work != plain.work or per_order or moved or catalogue, f"{effect} on changes nothing"


def test_post_trace_effects_do_no_extra_tracing():
    """Noise and chirps are applied after tracing: the same casts and returns as without them."""
    base = traced(PLANE, sensor=RADIOMETRY)
    noisy = traced(PLANE, sensor={**RADIOMETRY, "noise_figure_db": 3.0})
    raw = traced(PLANE, sensor={"output": "raw"})
    assert noisy.work == base.work and raw.work == traced(PLANE).work
    assert "thermal noise" in noisy.effects and "chirped raw echoes" in raw.effects


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
    from sarmitsuba.scene.loader import load_scene, material_table
    from sarmitsuba.tracing.driver.trace import trace
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
    # order 2 is cast (and misses); no tube is left for order 3
    rays = three.sim.trace.rays_per_order
    assert rays[0] == one.sim.trace.rays_per_order[0] and rays[1] > 0        # order-2 casts ...
    assert three.sim.trace.shadow_rays == one.sim.trace.shadow_rays          # ... that never hit
    assert not np.any(three.sim.trace.energy_per_order[1:])
    # in the same (depth-3) window, depth 1 and depth 3 give the same spectra
    d1 = _trace_in_window(ROUGH, {"max_depth": 3}, {"max_depth": 1}).spectrum
    _assert_close(d1, three.sim.trace.spectrum, "spectrum")


def test_rough_material_used_by_no_shape_changes_nothing():
    """A rough BSDF that no shape references: no clutter effect, no scatterer, plane.xml's output."""
    unused = traced(UNUSED_ROUGH)
    assert "distributed clutter and speckle" not in unused.effects
    plain = traced(PLANE)
    assert unused.work == plain.work
    np.testing.assert_array_equal(unused.sim.trace.rays_per_order, plain.sim.trace.rays_per_order)
    _assert_close(plain.sim.trace.spectrum, unused.sim.trace.spectrum, "spectrum")
    _assert_close(plain.sim.raw.data, unused.sim.raw.data, "raw data")
    _assert_close(plain.sim.image.data, unused.sim.image.data, "image")


def test_rough_shape_no_ray_reaches_changes_nothing():
    """A rough plate buried under the smooth plane: the scene has a rough material, but no hit
    is on it, so no clutter scatterer is deposited (the same work counters) and the output is the
    smooth scene's."""
    rough = traced(HIDDEN_ROUGH, base_sensor=EIGHT, base_integrator=FINER)
    smooth = traced(HIDDEN_SMOOTH, base_sensor=EIGHT, base_integrator=FINER)
    assert "distributed clutter and speckle" in rough.effects     # the scene does ask for it ...
    assert rough.work == smooth.work and rough.work["scatterers"] == 0   # ... but no hit is rough
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
    monkeypatch.setattr(signal_model, "chirp_spectrum", _forbidden("chirp_spectrum"))
    sim = pipeline.simulate(PLANE, sensor_overrides=SMALL, integrator_overrides=COARSE)
    assert sim.raw.range_compressed


def test_raw_output_computes_the_chirp_spectrum(monkeypatch):
    """Positive control for the patch above: chirped output does call it."""
    calls: list = []
    monkeypatch.setattr(signal_model, "chirp_spectrum", _counting(signal_model.chirp_spectrum, calls))
    sim = pipeline.simulate(PLANE, sensor_overrides={**SMALL, "output": "raw"}, integrator_overrides=COARSE)
    assert not sim.raw.range_compressed
    assert len(calls) >= 1


# ---- 4. the effect set is decided once and obeyed by those it is handed to -------------------------

def test_tracer_and_radar_equation_follow_the_effect_set_they_are_handed():
    """``active_effects`` decides; the tracer and the radar equation obey the set they are given
    instead of re-deriving it from the parameters or the material table. Fails if the kernel
    re-reads ``material_table.has_clutter``, the mesh tracer re-reads ``settings.diffraction``, or
    radar_equation re-reads ``transmit_power``."""
    from sarmitsuba.scene.effects import active_effects
    from sarmitsuba.scene.loader import load_scene, material_table
    from sarmitsuba.tracing.driver.trace import trace
    # the plate's rims as edges (not a ground's truncations, docs/physics.md (M10)): they diffract
    loaded = load_scene(ROUGH, SMALL, {**COARSE, "ground_shapes": "none"})
    p = loaded.params
    geometry = acquisition_geometry(p)
    window = planning.fast_time_window(p, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings)
    footprint = planning.ray_footprint(p, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings)
    table = material_table(loaded.scene, p.frequency, p.polarization)
    effects = active_effects(loaded)
    assert effects.clutter and [e.name for e in effects] == ["distributed clutter and speckle", "edge diffraction"]
    rough = trace(loaded.scene, p, geometry, window, footprint, loaded.settings, table, effects=effects)
    smooth = trace(loaded.scene, p, geometry, window, footprint, loaded.settings, table,
                   effects=dataclasses.replace(effects, rough_materials=()))
    assert rough.scatterers_per_order.sum() > 0 and smooth.scatterers_per_order.sum() == 0
    # the settings say diffraction = true; the set handed over decides: physical optics alone, as
    # with the settings' diffraction off
    no_edges = dataclasses.replace(effects, diffraction=False)
    po_alone = trace(loaded.scene, p, geometry, window, footprint, loaded.settings, table, effects=no_edges)
    settings_off = dataclasses.replace(loaded.settings, diffraction=False)
    reference = trace(loaded.scene, p, geometry, window, footprint, settings_off, table, effects=no_edges)
    assert loaded.settings.diffraction
    _assert_close(reference.spectrum, po_alone.spectrum, "effects without diffraction")
    assert np.abs(po_alone.spectrum - rough.spectrum).max() > 1e-3 * np.abs(rough.spectrum).max()
    loud = dataclasses.replace(p, **RADIOMETRY)
    assert radar_equation(loud) is not None
    assert radar_equation(loud, dataclasses.replace(effects, radiometry=False)) is None
