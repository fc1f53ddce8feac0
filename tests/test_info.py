"""``sarmitsuba info``: radar summary against closed forms, effects, cost model, JSON, no tracing.

Closed forms are written out here independently of the code (Cumming and Wong 2005, ch. 4;
Curlander and McDonough 1991; the radar equation of Skolnik's *Radar Handbook*, eq. 1.1).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest


import sarmitsuba.pipeline
import sarmitsuba.tracing.driver.trace
from sarmitsuba import info as info_mod
from sarmitsuba.scene import planning
from sarmitsuba.cli import main
from sarmitsuba.scene.effects import active_effects, list_effects
from sarmitsuba.info import scene_info
from sarmitsuba.core.geometry import acquisition_geometry
from sarmitsuba.scene.loader import load_scene

C = 299_792_458.0
K_B = 1.380649e-23
SCENES = Path(__file__).parent / "scenes"


@pytest.fixture(autouse=True)
def no_tracing(monkeypatch):
    """Every test here fails if anything traces."""
    def refuse(*args, **kwargs):
        raise AssertionError("info must not trace")
    monkeypatch.setattr(sarmitsuba.tracing.driver.trace, "trace", refuse)
    monkeypatch.setattr(sarmitsuba.pipeline, "trace", refuse)


def effect(info, name):
    return next(e for e in info.effects if e.name == name)


def test_urban_radar_summary_matches_closed_forms():
    # urban.xml: fc 9.6 GHz, B 150 MHz, prf 250 Hz, v 100 m/s, H 1000 m, theta 45 deg, 3 dB beam 1.2 deg
    r = scene_info("urban").radar
    lam, bw, v, beta, theta = C / 9.6e9, 150e6, 100.0, math.radians(1.2), math.radians(45.0)
    aperture = 0.44294647 * lam / math.sin(beta / 2)         # tapered beam: sinc^2 = 1/2 at beta / 2
    assert r.beam == "tapered"
    assert r.wavelength_m == pytest.approx(lam, rel=1e-12)
    assert r.slant_range_resolution_m == pytest.approx(C / (2 * bw), rel=1e-12)
    assert r.ground_range_resolution_m == pytest.approx(C / (2 * bw * math.sin(theta)), rel=1e-12)
    assert r.azimuth_resolution_m == pytest.approx(aperture / 2, rel=1e-7)
    assert r.doppler_bandwidth_hz == pytest.approx(4 * v * math.sin(beta / 2) / lam, rel=1e-12)
    # traced to the pattern's first nulls, sin = lambda / L
    assert r.illuminated_doppler_bandwidth_hz == pytest.approx(4 * v / aperture, rel=1e-7)
    assert r.traced_beamwidth_deg == pytest.approx(math.degrees(2 * math.asin(lam / aperture)), rel=1e-7)
    assert r.slant_range_m == pytest.approx(1000.0 / math.cos(theta), rel=1e-12)
    assert r.look_angle_deg == r.incidence_angle_deg == 45.0
    # the scene spans ground range +-120 m about the centre 1000 m from nadir
    assert r.incidence_near_deg == pytest.approx(math.degrees(math.atan(880.0 / 1000.0)))
    assert r.incidence_far_deg == pytest.approx(math.degrees(math.atan(1120.0 / 1000.0)))
    assert r.swath_ground_m == pytest.approx(240.0) and r.scene_azimuth_extent_m == pytest.approx(240.0)
    # PRF: lower = 3 dB Doppler band, upper = 1 / (2 dR / c + T_p); 250 Hz is inside
    assert r.prf_min_hz == pytest.approx(4 * v * math.sin(beta / 2) / lam)
    assert r.prf_max_hz == pytest.approx(1.0 / (2 * r.swath_slant_m / C + 10e-6))
    assert r.prf_ok
    # aperture: the traced beam's footprint 2 R tan(asin(lambda / L)) at the centre, flown at v
    length = 2 * r.slant_range_m * math.tan(math.asin(lam / aperture))
    assert r.aperture_length_m == pytest.approx(length) and r.aperture_time_s == pytest.approx(length / v)
    assert r.pulses_per_point == round(length * 250.0 / v)
    assert r.track_length_m == pytest.approx((r.n_pulses - 1) * v / 250.0)


@pytest.mark.parametrize("incidence, slant, ground, ground_resolution, near, far", [
    # 30 deg: R = 1000 / cos 30 = 1000 / 0.866025; Y = 1000 tan 30 = 1000 * 0.577350;
    # c / (2B sin 30) = 0.999308 / 0.5; near/far atan((577.350 -+ 120) / 1000)
    (30.0, 1154.7005, 577.3503, 1.998616, 24.577000, 34.890002),
    # 60 deg: R = 1000 / 0.5; Y = 1000 * 1.732051; 0.999308 / 0.866025; atan((1732.051 -+ 120) / 1000)
    (60.0, 2000.0000, 1732.0508, 1.153902, 58.187521, 61.633527),
])
def test_radar_summary_away_from_45_degrees(incidence, slant, ground, ground_resolution, near, far):
    """urban.xml (H = 1000 m, B = 150 MHz, ground range +-120 m) flown at 30 and 60 deg, values
    worked by hand. At 45 deg sin = cos and tan = 1 / tan, so only these catch a swap: slant
    range H / sin instead of H / cos (2000 against 1154.7 m at 30 deg, 1154.7 against 2000 at
    60), ground range H / tan (1732 against 577 m), ground resolution over cos instead of sin
    (1.154 against 1.999 m at 30 deg, the reverse at 60)."""
    r = scene_info("urban", sensor_overrides={"incidence_angle": incidence}).radar
    assert r.look_angle_deg == r.incidence_angle_deg == incidence
    assert r.slant_range_m == pytest.approx(slant, abs=1e-3)
    assert r.ground_range_m == pytest.approx(ground, abs=1e-3)
    assert r.slant_range_resolution_m == pytest.approx(0.999308, abs=1e-6)
    assert r.ground_range_resolution_m == pytest.approx(ground_resolution, abs=1e-6)
    assert r.incidence_near_deg == pytest.approx(near, abs=1e-5)
    assert r.incidence_far_deg == pytest.approx(far, abs=1e-5)


def test_antenna_length_sets_azimuth_resolution_and_doppler_bandwidth():
    """With an antenna of length D (automatic beam): azimuth resolution D / 2, 3-dB Doppler
    bandwidth 4 v (0.443 lambda / D) / lambda = 1.772 v / D; the simulated beam is null to null,
    4 v / D."""
    d, v = 2.0, 100.0
    r = scene_info("trihedral", sensor_overrides={"antenna_length": d, "azimuth_beamwidth": 0}).radar
    assert r.azimuth_resolution_m == pytest.approx(d / 2, rel=1e-12)
    assert r.doppler_bandwidth_hz == pytest.approx(4 * v * 0.44294647 / d, rel=1e-7)
    assert r.prf_min_hz == pytest.approx(4 * v * 0.44294647 / d, rel=1e-7)
    assert r.illuminated_doppler_bandwidth_hz == pytest.approx(4 * v / d, rel=1e-9)
    assert r.azimuth_resolution_formula.startswith("L_a / 2")


def test_prf_outside_the_limits_is_flagged_with_the_render_warning():
    r = scene_info("dihedral", sensor_overrides={"prf": 100.0})        # below the 134 Hz Doppler band
    assert not r.radar.prf_ok and any("azimuth ambiguities" in w for w in r.warnings)
    assert scene_info("dihedral").warnings == ()


def test_spotlight_azimuth_resolution_from_the_integration_angle():
    r = scene_info("dihedral", sensor_overrides={"mode": "spotlight", "n_pulses": 100}).radar
    lam, v, prf = C / 9.6e9, 100.0, 250.0
    dtheta = 100 * v / (prf * r.slant_range_m)
    assert r.azimuth_resolution_m == pytest.approx(lam / (2 * dtheta), rel=1e-12)
    assert r.aperture_length_m == pytest.approx(100 * v / prf) and r.pulses_per_point == 100


def test_radiometry_snr_and_nesz_from_the_radar_equation():
    pt, gain_db, nf_db = 100.0, 30.0, 3.0
    info = scene_info("dihedral", sensor_overrides={"transmit_power": pt, "antenna_gain_db": gain_db,
                                                    "noise_figure_db": nf_db})
    r, radar = info.radiometry, info.radar
    lam, rng, g = radar.wavelength_m, radar.slant_range_m, 10 ** (gain_db / 10)
    power = pt * g**2 * lam**2 / ((4 * math.pi) ** 3 * rng**4)                 # 1 m^2, no losses
    noise = K_B * 290.0 * 150e6 * 10 ** (nf_db / 10)
    # the tapered beam's pulses carry the two-way pattern sinc^2(x), x = L sin(phi) / lambda in
    # [-1, 1] between its nulls: coherent gain N (mean sinc^2)^2, the mean by quadrature
    x = np.linspace(-1.0, 1.0, 200_001)
    mean_g2 = np.trapezoid(np.sinc(x) ** 2, x) / 2.0
    assert mean_g2 == pytest.approx(0.4514, abs=1e-4)
    snr_image = power / noise * 150e6 * 10e-6 * radar.pulses_per_point * mean_g2**2
    assert r.received_power_1m2_w == pytest.approx(power, rel=1e-9)
    assert r.single_pulse_snr_1m2_db == pytest.approx(10 * math.log10(power / noise), abs=1e-9)
    assert r.image_snr_1m2_db == pytest.approx(10 * math.log10(snr_image), abs=0.1)
    cell = radar.azimuth_resolution_m * radar.ground_range_resolution_m
    assert r.nesz_db == pytest.approx(-10 * math.log10(snr_image * cell), abs=0.1)
    assert scene_info("dihedral").radiometry is None


def test_effects_follow_the_flags():
    base = scene_info("dihedral")                        # PEC, max_depth 2, no radiometry
    assert effect(base, "bounce orders > 1").active
    assert not effect(base, "distributed clutter and speckle").active
    assert not effect(base, "absolute radiometry").active
    assert {e.name for e in base.effects} >= {"bounce orders > 1", "distributed clutter and speckle",
                                              "antenna pattern", "thermal noise", "chirped raw echoes",
                                              "absolute radiometry", "spotlight"}
    assert all(e.reason for e in base.effects)           # every effect, on or off, says why

    rough = scene_info("dihedral", material_overrides={"gamma_db": -10})
    assert effect(rough, "distributed clutter and speckle").active
    assert "metal" in effect(rough, "distributed clutter and speckle").reason
    single = scene_info("dihedral", integrator_overrides={"max_depth": 1})
    assert not effect(single, "bounce orders > 1").active
    assert "max_depth = 1" in effect(single, "bounce orders > 1").reason
    power = scene_info("dihedral", sensor_overrides={"transmit_power": 10, "antenna_gain_db": 30})
    radiometry = effect(power, "absolute radiometry")
    assert radiometry.active and "transmit_power 10" in radiometry.reason
    assert effect(scene_info("dihedral", sensor_overrides={"output": "raw"}), "chirped raw echoes").active


def test_metadata_effects_are_the_active_ones_as_strings():
    loaded = load_scene("dihedral", {"mode": "spotlight"}, {"max_depth": 1})
    lines = [str(e) for e in active_effects(loaded)]
    assert lines == [f"{e.name} ({e.reason})" for e in list_effects(loaded) if e.active]
    assert any(line.startswith("spotlight") for line in lines)
    assert not any(line.startswith("bounce orders") for line in lines)


def test_cost_counts_the_planned_sub_apertures():
    """rays_per_pulse is the planner's grid; the sub-apertures are the tracer's (compared with a
    trace in test_trace.py); the trace time lies between its bounds."""
    overrides = {"max_depth": 2, "ray_spacing": 0.25}
    loaded = load_scene("dihedral", None, overrides)
    geometry = acquisition_geometry(loaded.params)
    footprint = planning.ray_footprint(loaded.params, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings)
    window = planning.fast_time_window(loaded.params, geometry, loaded.bbox_lo, loaded.bbox_hi, loaded.settings)
    c = scene_info("dihedral", integrator_overrides=overrides).cost
    n = loaded.params.n_pulses
    assert c.rays_per_pulse == footprint.n_azimuth * footprint.n_range
    assert c.pulses_per_trace == sarmitsuba.tracing.driver.trace.pulses_per_trace(loaded.params, loaded.settings, n) > 1
    assert c.subapertures == math.ceil(n / c.pulses_per_trace)
    # patches (the default): every sample casts at most one ray per leg of its path (two legs at
    # the second bounce), and the later order has fewer pieces than the first
    assert c.closest_hit_casts == c.shadow_casts
    assert c.primary_rays < c.closest_hit_casts <= 3 * c.primary_rays
    tiles = scene_info("dihedral", integrator_overrides={**overrides, "lit_regions": "tiles"}).cost
    assert tiles.closest_hit_casts == tiles.shadow_casts == 2 * tiles.primary_rays       # every tube to max_depth
    assert c.trace_time_low_s <= c.trace_time_s <= c.trace_time_high_s
    hit, shadow = info_mod.cast_rates(4)                                # dihedral: 2 rectangles
    assert (hit, shadow) == (50e6, 150e6)                               # below the small anchor: its rates
    assert c.raw_bytes == n * window.n_samples * 8
    assert c.image_bytes == c.image_shape[0] * c.image_shape[1] * 8
    assert c.focus_time_s > 0 and c.direct_backprojection_time_s > 0


def test_cast_rates_interpolate_log_linearly_between_the_anchors():
    assert info_mod.cast_rates(14) == pytest.approx((50e6, 150e6))
    assert info_mod.cast_rates(38_936) == pytest.approx((10e6, 20e6))
    mid = math.sqrt(14 * 38_936)                                        # halfway in log(triangles)
    assert info_mod.cast_rates(mid) == pytest.approx((math.sqrt(50e6 * 10e6), math.sqrt(150e6 * 20e6)))


def test_scene_size_and_materials():
    s = scene_info("urban").scene
    assert (s.n_shapes, s.has_sar_sensor) == (8, True) and s.n_triangles > 0
    assert s.bbox_min_m == pytest.approx((-120, -120, 0)) and s.frame_offset_m == (0.0, 0.0, 0.0)
    kinds = {m.name: (m.kind, m.rough) for m in s.materials}
    assert kinds == {"soil": ("ITU", True), "brick": ("ITU", True), "concrete": ("ITU", True),
                     "metal": ("PEC", False)}
    assert sum(m.n_shapes for m in s.materials) == s.n_shapes


def test_cli_text_and_json(capsys):
    assert main(["info", "dihedral", "--pulses", "11", "--max-depth", "1"]) == 0
    text = capsys.readouterr().out
    for heading in ("Scene", "Radar", "Ambiguities", "Radiometry", "Effects", "Estimated cost", "Warnings"):
        assert f"\n{heading}\n" in text
    assert "[off] bounce orders > 1" in text and "c/(2B)" in text

    assert main(["info", "dihedral", "--json", "--set", "prf=300", "--integrator-set", "max_depth=1",
                 "--material-set", "gamma_db=-10"]) == 0
    body = json.loads(capsys.readouterr().out)
    assert set(body) == {"scene", "radar", "radiometry", "effects", "cost", "warnings", "ambiguities", "workers", "depth"}
    assert body["depth"] == {"mode": "fixed", "depth": 1}
    assert body["workers"]["workers"] >= 1 and body["workers"]["reason"]
    assert body["radar"]["prf_hz"] == 300.0
    assert body["radar"]["slant_range_resolution_m"] == pytest.approx(C / (2 * 150e6))
    assert {"name", "active", "reason"} == set(body["effects"][0])
    on = {e["name"] for e in body["effects"] if e["active"]}
    assert "distributed clutter and speckle" in on and "bounce orders > 1" not in on
    assert body["cost"]["closest_hit_casts"] == body["cost"]["primary_rays"]     # max_depth 1
    assert isinstance(body["cost"]["trace_time_s"], float) and len(body["cost"]["image_shape"]) == 2


@pytest.mark.parametrize("argv, name", [
    (["--set", "incidence_angle=95"], "incidence_angle"),
    (["--integrator-set", "max_depth=0"], "max_depth"),
    (["--set", "transmit_power=10"], "transmit_power"),
    (["--material-set", "roughness=3"], "roughness"),
])
def test_cli_bad_value_exits_2_naming_the_parameter(capsys, argv, name):
    assert main(["info", "dihedral", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and name in err


def test_cli_missing_scene_exits_2(tmp_path, capsys):
    assert main(["info", str(tmp_path / "missing.xml")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_text_report_of_a_test_scene_has_no_nan():
    text = info_mod.format_text(scene_info(str(SCENES / "tower.xml")))
    assert "nan" not in text.lower() and "inf " not in text.lower()
    assert np.isfinite(scene_info(str(SCENES / "plane.xml")).cost.trace_time_high_s)
