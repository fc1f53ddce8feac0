"""Smoke test of the benchmark modules (not a timed test: no assertion on seconds or ratios).

Each of ``benchmarks/ray_density.py``, ``focus_algorithms.py``, ``subaperture.py``, ``ffbp.py``,
``scaling.py``, ``tracing/integration/polarimetry.py``, ``invariance.py``, ``patches.py``, ``trajectory.py`` and
``footprints.py`` (a 200 m crop of Sionna's Munich; skipped without Sionna RT's scenes) runs with
``tiny=True`` (a few settings, small scenes; about 25 s for all three, most of it tracing and
kernel compilation) and must return rows with the expected columns and finite numbers, and
write ``<name>_tiny.csv`` and ``.png`` into the output folder named by ``SARMITSUBA_BENCH_OUT``
(here a temporary folder: the tests never write into the checkout). Their ``checks(rows)`` must return well-formed results (they are not asserted:
tiny settings are not what the checks are about).
"""
from __future__ import annotations

import csv
import importlib
import math
import sys
import time
from pathlib import Path

import pytest

from sarmitsuba.scene.loader import sionna_scenes

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))

#: module -> (columns every row has, numeric columns that must be finite in every row,
#:            numeric columns that must be finite where not empty)
EXPECTED = {
    "ray_density": (
        {"case", "setting", "ray_spacing_m", "tube_m", "rays_per_cell", "rays_per_pulse", "pulses", "seconds",
         "trace_s", "time_ratio", "expected_db", "measured_db", "error_db", "max_db", "speckle_contrast",
         "speckle_contrast_error_db"},
        ("ray_spacing_m", "tube_m", "rays_per_cell", "rays_per_pulse", "seconds", "time_ratio", "measured_db"),
        ("expected_db", "error_db", "max_db", "speckle_contrast", "speckle_contrast_error_db")),
    "focus_algorithms": (
        {"case", "algorithm", "option", "shape", "processed_doppler_hz", "seconds", "time_ratio",
         "irw_range_err_pct", "irw_azimuth_err_pct", "pslr_err_db", "islr_err_db", "position_err_cells",
         "phase_err_deg", "peak_err_db", "nrmse_vs_finest_db"},
        ("seconds", "time_ratio", "irw_range_err_pct", "irw_azimuth_err_pct", "pslr_err_db", "islr_err_db",
         "position_err_cells", "phase_err_deg", "peak_err_db", "nrmse_vs_finest_db"),
        ()),
    "subaperture": (
        {"scene", "setting", "trace_s", "pulses_per_trace", "closest_hit_casts", "shadow_casts", "pulse_paths",
         "pulses", "nrmse_db", "trace_ratio"},
        ("trace_s", "pulses_per_trace", "closest_hit_casts", "shadow_casts", "pulse_paths", "pulses", "trace_ratio"),
        ()),
    "ffbp": (
        {"case", "method", "setting", "seconds", "nrmse_db", "subapertures", "polar_samples", "over_omega_k",
         "over_direct"},
        ("seconds", "over_omega_k", "over_direct"),
        ("subapertures", "polar_samples")),
    "scaling": (
        {"sweep", "n", "buildings", "pulses", "pixels", "triangles", "rays_traced", "load_s", "trace_s", "bin_s",
         "focus_s", "total_s", "exponent_total", "exponent_stage", "reference_s", "reference_over_ours"},
        ("n", "buildings", "pulses", "pixels", "rays_traced", "trace_s", "bin_s", "focus_s", "total_s",
         "exponent_total", "exponent_stage"),
        ("reference_s", "reference_over_ours")),
    "polarimetry": (
        {"scene", "polarization", "pulses", "load_s", "trace_s", "bin_focus_s", "total_s", "closest_hit_casts",
         "shadow_casts", "casts_as_vv", "total_over_vv", "trace_over_vv", "quad_over_4_vv", "nrmse_hh_db",
         "nrmse_vv_db"},
        ("pulses", "load_s", "trace_s", "bin_focus_s", "total_s", "closest_hit_casts", "shadow_casts",
         "total_over_vv", "trace_over_vv"),
        ("quad_over_4_vv", "nrmse_hh_db", "nrmse_vv_db")),
    "trajectory": (
        {"table", "scene", "trace_s_stop_and_hop", "trace_s_continuous", "trace_ratio", "focus_s_stop_and_hop",
         "focus_s_continuous", "focus_ratio", "v_R_over_c_m", "azimuth_error_m",
         "azimuth_shift_as_stop_and_hop_m", "shift_over_closed_form", "peak_phase_change_deg", "peak_loss_db",
         "raw_nrmse_stop_and_hop_db", "amplitude_m", "period_m", "pga_s", "pslr_true_db", "irw_true_m",
         "peak_true", "pslr_nominal_db", "irw_nominal_m", "peak_nominal", "pslr_pga_db", "irw_pga_m",
         "peak_pga", "pga_iterations", "pga_rms_phase_rad"},
        (),
        ("trace_s_stop_and_hop", "trace_s_continuous", "trace_ratio", "focus_s_stop_and_hop",
         "focus_s_continuous", "focus_ratio", "v_R_over_c_m", "azimuth_error_m",
         "azimuth_shift_as_stop_and_hop_m", "shift_over_closed_form", "peak_phase_change_deg", "peak_loss_db",
         "raw_nrmse_stop_and_hop_db", "amplitude_m", "period_m", "pga_s", "pslr_true_db", "irw_true_m",
         "peak_true", "pslr_nominal_db", "irw_nominal_m", "peak_nominal", "pslr_pga_db", "irw_pga_m",
         "peak_pga", "pga_iterations", "pga_rms_phase_rad",)),
    "invariance": (
        {"scene", "mode", "setting", "trace_s", "pulses", "nrmse_db", "compared", "meets", "coherence", "speckle_db"},
        ("trace_s", "pulses"),
        ("nrmse_db", "coherence", "speckle_db")),
    "patches": (
        {"table", "scene", "setting", "trace_s", "total_s", "peak_mib", "value", "unit"},
        ("trace_s",),
        ("total_s", "peak_mib", "value")),
    "gradients": (
        {"scene", "kind", "pulses", "parameters", "seconds", "peak_mib", "over_forward", "memory_over_forward"},
        ("pulses", "parameters", "seconds", "peak_mib", "over_forward", "memory_over_forward"),
        ()),
    "inverse": (
        {"evaluation", "relative_permittivity", "height_m", "loss", "gradient_permittivity", "gradient_height",
         "seconds", "elapsed_s", "permittivity_error", "height_error_m"},
        ("evaluation", "relative_permittivity", "height_m", "loss", "gradient_permittivity", "gradient_height",
         "seconds", "elapsed_s", "permittivity_error", "height_error_m"),
        ()),
    "inverse_city": (
        {"evaluation", *(f"height_{i}_m" for i in range(1, 11)), "loss", "gradient_norm", "max_height_error_m",
         "geometry_changes", *(f"height_{i}_error_m" for i in range(1, 11)), "seconds", "elapsed_s"},
        ("evaluation", *(f"height_{i}_m" for i in range(1, 11)), "loss", "gradient_norm", "max_height_error_m",
         "geometry_changes", *(f"height_{i}_error_m" for i in range(1, 11)), "seconds", "elapsed_s"),
        ()),
    "footprints": (
        {"scene", "case", "footprints", "buildings_in_scene", "height_mean_m", "height_top_mean_m",
         "height_below_top_mean_m", "height_below_top_p95_m", "flat_roof_fraction", "derive_s", "build_s", "write_s",
         "render_original_s", "render_rebuilt_s", "trace_original_s", "trace_rebuilt_s", "resolution_m", "pixels",
         "double_bounce_original_in_rebuilt", "double_bounce_rebuilt_in_original", "single_bounce_original_in_rebuilt",
         "single_bounce_rebuilt_in_original"},
        ("footprints", "buildings_in_scene", "height_mean_m", "height_top_mean_m", "height_below_top_mean_m",
         "height_below_top_p95_m", "flat_roof_fraction", "derive_s", "build_s", "write_s", "render_original_s",
         "render_rebuilt_s", "trace_original_s", "trace_rebuilt_s", "resolution_m", "pixels",
         "double_bounce_original_in_rebuilt",
         "double_bounce_rebuilt_in_original", "single_bounce_original_in_rebuilt", "single_bounce_rebuilt_in_original"),
        ()),
}


def _finite(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


@pytest.mark.parametrize("module_name", list(EXPECTED))
def test_benchmark_runs_tiny(module_name, tmp_path, monkeypatch):
    if module_name == "footprints" and "munich" not in sionna_scenes():
        pytest.skip("Sionna RT's Munich scene is not installed")
    monkeypatch.setenv("SARMITSUBA_BENCH_OUT", str(tmp_path))
    start = time.time()
    module = importlib.import_module(module_name)
    rows = module.run(tiny=True)
    columns, finite, optional = EXPECTED[module_name]
    assert rows, f"{module_name}.run returned no rows"
    for row in rows:
        assert set(row) == columns, f"{module_name}: columns {sorted(set(row) ^ columns)} differ"
        for key in finite:
            assert _finite(row[key]), f"{module_name}: {key} = {row[key]!r} in {row}"
        for key in optional:
            identical = key.startswith("nrmse") and row[key] == -math.inf      # two images equal bit for bit
            assert row[key] == "" or _finite(row[key]) or identical, f"{module_name}: {key} = {row[key]!r} in {row}"
    if module_name == "scaling":
        assert {r["sweep"] for r in rows} == {"buildings", "pulses", "pixels"}
    out = tmp_path
    for suffix in (".csv", ".png"):
        path = out / f"{module.NAME}_tiny{suffix}"
        assert path.is_file() and path.stat().st_size > 0, f"{path} missing"
        assert path.stat().st_mtime >= start - 1.0, f"{path} was not rewritten by this run"
    with open(out / f"{module.NAME}_tiny.csv", newline="") as f:
        table = list(csv.DictReader(f))
    assert len(table) == len(rows) and set(table[0]) == columns
    for check in module.checks(rows):
        name, ok, detail = check
        assert isinstance(name, str) and isinstance(ok, bool) and isinstance(detail, str)


def test_invariance_sweeps_the_beam_in_the_images_frame():
    """``benchmarks/invariance.py`` keeps, for moves along the track, the points the whole beam
    sweeps: the antenna's span must be measured from the scene centre in the world frame, as the
    image's azimuth is. A block 3.6 km from the origin (the loader then traces in a frame shifted
    by whole metres) on a straight track centred on it: the span is symmetric about 0 (with the
    tracing frame's centre it was 3 km off)."""
    invariance = importlib.import_module("invariance")
    shift = (3000.0, 2000.0, 0.0)
    render = invariance._render(invariance.block(64, shift=shift), {"scene_center": shift}, {})
    first, last = render["full_aperture"]["span"]
    assert first < 0.0 < last
    assert first == pytest.approx(-last, abs=1e-6)


def test_invariance_speckle_bound_against_monte_carlo():
    """The magnitude NRMSE of two fully developed speckle images of coherence ``gamma``
    (``invariance.speckle_magnitude_nrmse_db``, from the joint amplitude statistics) against
    correlated circular Gaussian pairs drawn here, at 0.5, 0.9 and 0.99; and the boxcar coherence
    estimate against the coherence drawn (a pair with a linear phase ramp between them, which the
    local estimate must not count as decorrelation)."""
    import numpy as np
    invariance = importlib.import_module("invariance")
    rng = np.random.default_rng(3)
    for gamma in (0.5, 0.9, 0.99):
        a = (rng.standard_normal(400_000) + 1j * rng.standard_normal(400_000)) / math.sqrt(2)
        n = (rng.standard_normal(400_000) + 1j * rng.standard_normal(400_000)) / math.sqrt(2)
        b = gamma * a + math.sqrt(1 - gamma ** 2) * n
        drawn = 10 * math.log10(np.sum((np.abs(a) - np.abs(b)) ** 2) / np.sum(np.abs(a) ** 2))
        assert invariance.speckle_magnitude_nrmse_db(gamma) == pytest.approx(drawn, abs=0.1)
    a = (rng.standard_normal((300, 300)) + 1j * rng.standard_normal((300, 300))) / math.sqrt(2)
    n = (rng.standard_normal((300, 300)) + 1j * rng.standard_normal((300, 300))) / math.sqrt(2)
    ramp = np.exp(0.3j * np.arange(300))[None, :]
    b = (0.9 * a + math.sqrt(1 - 0.81) * n) * ramp
    # the boxcar's estimate of |gamma| is biased up for few looks (49 here): within 0.03
    assert invariance.local_coherence(b, a) == pytest.approx(0.9, abs=0.03)
    assert invariance.speckle_magnitude_nrmse_db(1.0) < -100.0                  # identical images
