"""Tracer physics and precision against closed forms (docs/physics.md (S1), (PO1)-(PO4))."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.pipeline import simulate

SCENES = Path(__file__).parent / "scenes"


def _wrap_deg(x: float) -> float:
    return (x + 180.0) % 360.0 - 180.0


@pytest.mark.parametrize("slant_range", [100e3, 800e3])
def test_trihedral_phase_and_delay_exact_at_satellite_range(slant_range):
    """(S1): one broadside pulse on a PEC trihedral has its peak at tau = 2 R_apex / c and the
    phase of j * S_VV * exp(-j k 2 R_apex), S_VV = +1 for a PEC trihedral (image theory: three mirrors
    give -M3 M2 M1 = +I, docs/physics.md (P5)), i.e. +90 deg after removing the carrier, at 100 km
    and 800 km alike (float32 lengths would be off by up to 12 rad at 800 km)."""
    inc = 45.0
    altitude = slant_range * math.cos(math.radians(inc))
    sim = simulate("trihedral", sensor_overrides={"altitude": altitude, "n_pulses": 1})
    raw = sim.raw
    apex = np.zeros(3)
    length = 2.0 * np.linalg.norm(raw.tx_position[0] - apex)
    row = raw.data[0]
    i = int(np.argmax(np.abs(row)))
    delay_error = raw.fast_time[i] - length / SPEED_OF_LIGHT
    assert abs(delay_error) <= 0.5 / raw.fs, f"peak {delay_error * 1e9:.2f} ns from 2 R_apex / c"
    k = 2.0 * math.pi * raw.fc / SPEED_OF_LIGHT
    phase = _wrap_deg(math.degrees(np.angle(row[i]) + (k * length) % (2 * math.pi)))
    assert abs(_wrap_deg(phase - 90.0)) < 2.0, f"peak phase {phase:.2f} deg, expected +90 deg"
    assert np.all(np.isfinite(raw.data))


def test_smooth_plane_interior_is_dark():
    """(PO2), (PO4): a smooth plane at 45 deg incidence returns nothing from its interior: every pixel
    there is > 40 dB below a resolution-cell-sized plate at normal incidence (sqrt(4 pi) A / lambda),
    at the default tube size and with 0.1 m tubes alike (the old tube-centre evaluation was
    right only when the rays were dense)."""
    def interior_max(spacing):
        sim = simulate(str(SCENES / "plane.xml"), integrator_overrides={"ray_spacing": spacing})
        im, p = sim.image, sim.loaded.params
        az, gr = np.meshgrid(im.azimuth, im.range, indexing="ij")
        inside = (np.abs(az) < 25) & (np.abs(gr) < 25)
        cell = 2.0 * math.sqrt(math.pi) / p.wavelength * p.azimuth_resolution * p.ground_range_resolution
        return float(np.abs(im.data[inside]).max()) / cell

    default, dense = interior_max(0.0), interior_max(0.1)
    assert 20 * math.log10(default) < -40.0
    assert 20 * math.log10(dense) < -40.0


@pytest.mark.parametrize("lit_regions", ["patches", "tiles"])
def test_energy_per_order_and_rays_are_consistent(lit_regions):
    """Energy per order is finite and non-negative; with max_depth 3 there are exactly 3 orders.
    Tubes: closest-hit casts never increase with the order (rays only leave the scene). Patches:
    every order's rays are counted (its pieces' samples and the discovery rays that found its
    chains, docs/physics.md (M4), (M6)), each sample past the first bounce checked once on its way back."""
    sim = simulate("dihedral", integrator_overrides={"max_depth": 3, "lit_regions": lit_regions})
    t = sim.trace
    assert t.energy_per_order.shape == (3,) and np.all(np.isfinite(t.energy_per_order))
    assert np.all(t.energy_per_order >= 0)
    if lit_regions == "tiles":
        assert np.all(np.diff(t.rays_per_order) <= 0)
    else:
        assert np.all(t.rays_per_order > 0)
    assert t.shadow_rays <= t.rays_per_order.sum()
    assert t.energy_outside_window == 0.0


def test_beam_hitting_nothing_gives_zero_data(monkeypatch):
    """Empty beam: a beam pointed 500 m away from all geometry yields exactly zero raw data
    and a zero image (not NaN), and casts no ray. (Loading refuses such a beam,
    track_checks.check_beam_reach; the tracer's own empty-beam path is tested with that check off.)"""
    from sarmitsuba.scene.planning import AcquisitionWarning
    monkeypatch.setattr("sarmitsuba.scene.loader.check_beam_reach", lambda *args: None)
    with pytest.warns(AcquisitionWarning, match="outside the beam footprint"):
        far = simulate("trihedral", sensor_overrides={"scene_center": "500, 500, 0", "n_pulses": 4})
    assert far.trace.rays_per_order.sum() == 0
    assert np.count_nonzero(far.raw.data) == 0 and np.all(np.isfinite(far.raw.data))
    assert np.count_nonzero(far.image.data) == 0 and np.all(np.isfinite(far.image.data))


def test_split_bounces_sum_to_total_and_separate_orders():
    """Per-order raw data add up to the total (linearity), and the dihedral's fold-line
    return lives in order 2 only."""
    sim = simulate("dihedral", integrator_overrides={"max_depth": 2, "split_bounces": True})
    assert len(sim.raw_per_order) == 2 and len(sim.images_per_order) == 2
    total = sim.raw_per_order[0].data + sim.raw_per_order[1].data
    assert np.abs(total - sim.raw.data).max() <= 1e-4 * np.abs(sim.raw.data).max()
    col = np.argmin(np.abs(sim.image.range))
    fold = [np.abs(im.data[:, col]).max() for im in sim.images_per_order]
    assert fold[1] > 100 * fold[0]
    assert sim.raw_per_order[1].metadata["bounce_order"] == 2


def test_chirped_raw_output_focuses_like_compressed_output():
    """Sensor output = raw: the raw echoes are chirps (range_compressed False, window grown by
    T_p) and, range-compressed by the matched filter, give the same image as compressed output
    (NRMSE < -50 dB; docs/design.md section 5, docs/physics.md (S2))."""
    compressed = simulate("trihedral")
    raw = simulate("trihedral", sensor_overrides={"output": "raw"})
    assert not raw.raw.range_compressed and compressed.raw.range_compressed
    p = raw.loaded.params
    assert raw.raw.n_samples >= compressed.raw.n_samples + int(p.pulse_length * p.sampling_rate) - 8
    # a chirp spreads the target over T_p fs samples of about the target's amplitude
    row = np.abs(raw.raw.data[raw.raw.n_pulses // 2])
    assert np.count_nonzero(row > 0.5 * row.max()) > 0.8 * p.pulse_length * p.sampling_rate
    a, b = raw.image.data, compressed.image.data
    nrmse = np.linalg.norm(a - b) / np.linalg.norm(b)
    assert 20 * math.log10(nrmse) < -50.0, f"NRMSE {20 * math.log10(nrmse):.1f} dB"


def test_info_estimates_bound_what_the_tracer_does():
    """``info`` (no tracing) against a trace of the same scene: the same sub-apertures; its primary
    rays bound the tubes the tracer casts (within a factor 3 from above: cells outside the beam
    are counted), its casts bound the tracer's; the deposit, raw data and image sizes are the
    tracer's."""
    from sarmitsuba.info import scene_info
    overrides = dict(integrator_overrides={"max_depth": 2, "ray_spacing": 0.25})
    c = scene_info("dihedral", **overrides).cost
    sim = simulate("dihedral", **overrides)
    cast = sim.trace.rays_per_order
    assert c.pulses_per_trace == sim.trace.pulses_per_trace > 1
    assert cast[0] <= c.primary_rays <= 3 * cast[0]
    assert cast.sum() <= c.closest_hit_casts and sim.trace.shadow_rays <= c.shadow_casts
    assert c.deposit_bytes == sim.trace.spectrum.nbytes
    assert c.raw_bytes == sim.raw.data.nbytes and c.image_bytes == sim.image.data.nbytes


@pytest.mark.parametrize("lit_regions", ["patches", "tiles"])
def test_max_batch_rays_is_a_ceiling_and_batching_changes_nothing(tmp_path, monkeypatch, lit_regions):
    """A small ``max_batch_rays`` splits the sub-apertures into batches (and, with tiles, a
    sub-aperture's lattice into row chunks and a small object's refined cells into several
    launches: every launch stays within the ceiling, or one refined cell's m^2 tubes, which are
    not split); the raw data equal the default's, on a track whose heading (37 deg) is along no
    axis (a launch placed at the wrong pulse, a chunk dropped or traced twice would show). The
    patches trace each sub-aperture on its own (docs/physics.md (M6)): batches change nothing."""
    from sarmitsuba.scene import canonical as C
    from sarmitsuba.tracing.driver import trace as trace_module

    xml = C.scene_xml(tmp_path, C.trihedral(0.3), C.PEC, 3, extra_shapes=(
        '<shape type="rectangle"><transform name="to_world"><scale x="6" y="6"/></transform>'
        '<bsdf type="radar"><string name="material" value="concrete"/></bsdf></shape>'))
    sensor = {"heading": 37.0, "n_pulses": 24}
    integrator = {"pulses_per_trace": 4, "lit_regions": lit_regions}           # six sub-apertures
    reference = simulate(str(xml), sensor_overrides=sensor, integrator_overrides=integrator)
    launches = []

    class Recording(trace_module.Kernel):
        def __call__(self, launch, **kwargs):
            blocks = launch.blocks
            refined = int((blocks.m.astype(np.int64) ** 2 * (blocks.m > 1)).max(initial=0))
            launches.append((launch.n_lanes, refined, launch.n_subapertures))
            return super().__call__(launch, **kwargs)

    monkeypatch.setattr(trace_module, "Kernel", Recording)
    ceiling = 4096
    small = simulate(str(xml), sensor_overrides=sensor, integrator_overrides={**integrator, "max_batch_rays": ceiling})
    if lit_regions == "tiles":
        assert len(launches) > 8 and any(tubes for _, tubes, _ in launches)       # chunked, refinement included
        assert all(lanes <= max(ceiling, tubes) for lanes, tubes, _ in launches), launches
    else:
        assert len(launches) > 1 and max(subs for _, _, subs in launches) < 6, launches     # batched
    a, b = reference.raw.data, small.raw.data
    assert np.abs(a - b).max() <= 1e-4 * np.abs(a).max()


def test_ray_footprint_covers_the_beam_at_the_far_range_edge():
    """Planner (T1): along track, each pulse's aim cells ``[k0 s, (k0 + n_azimuth) s]`` cover the
    traced beam where it is widest, at the far edge of the scene: offsets ``R_far tan(phi)`` from
    the antenna, ``sin(phi)`` the beam's sines (first nulls), ``R_far`` the perpendicular
    distance from the track to the far edge on the aim plane; and by no more than a few cells
    (the scene, 4 km along track, is far wider than the beam, so only the beam bounds the
    cells). Hand numbers: 45 deg, H = 1000 m, ground range 1000 +- 400 m: R_far = hypot(1000,
    1400) = 1720.5 m, the near edge's hypot(1000, 600) = 1166.2 m would be 11 m (14 cells) short."""
    from sarmitsuba.scene import planning
    from sarmitsuba.core.radar import RadarParameters
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.tracing.driver.trace import TraceSettings
    lo, hi = np.array([-2000.0, -400.0, 0.0]), np.array([2000.0, 400.0, 0.0])
    params = planning.resolve_parameters(RadarParameters(incidence_angle=45.0, altitude=1000.0, n_pulses=4), lo, hi)
    geometry = acquisition_geometry(params)
    fp = planning.ray_footprint(params, geometry, lo, hi, TraceSettings())
    assert params.mode == "stripmap" and params.squint == 0.0
    antenna = geometry.positions - np.asarray(params.scene_center)
    height = float(antenna[0, 2])
    ground = -float(antenna[0] @ fp.look)                              # antenna to scene centre, on the ground
    assert height == pytest.approx(1000.0) and ground == pytest.approx(1000.0, rel=1e-9)
    r_far = math.hypot(height, ground + 400.0)
    tangents = np.tan(np.arcsin(np.array(params.beam_sines)))
    s = fp.spacing_azimuth
    along = antenna @ fp.track
    first, last = fp.k0 * s, (fp.k0 + fp.n_azimuth) * s
    beam_lo, beam_hi = along + r_far * tangents[0], along + r_far * tangents[1]
    assert np.all(beam_hi - beam_lo > 40 * s)                         # the beam spans many cells
    assert np.all(first <= beam_lo) and np.all(last >= beam_hi), "the far edge's beam is not covered"
    assert np.all(first >= beam_lo - 3 * s), "cells start far before the beam"
    assert fp.n_azimuth * s <= (beam_hi - beam_lo)[0] + 6 * s, "cells extend far beyond the beam"
