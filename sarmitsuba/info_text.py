"""The text and JSON forms of ``sarmitsuba info``: what :func:`sarmitsuba.info.scene_info`
gathered, written for a reader (:func:`format_text`) or for a program (:func:`to_json`).

The functions take the ``SceneInfo`` record and its parts as they are (``SceneSize``,
``RadarSummary``, ``RadiometrySummary``, ``CostEstimate``, the effects) and only format them:
every figure is computed in :mod:`sarmitsuba.info` and :mod:`sarmitsuba.analysis.cost`.
"""
from __future__ import annotations

import dataclasses
import json
import math
from typing import Any

from .core import georef
from .analysis.cost import RETURN_SECONDS, CostEstimate, format_bytes
from .scene.effects import Effect

__all__ = ["to_dict", "to_json", "format_text"]


def to_dict(info: Any) -> dict:
    """The ``SceneInfo`` ``info`` as plain JSON types (numbers as numbers, units in the key names)."""
    return dataclasses.asdict(info)


def to_json(info: Any, indent: int | None = 2) -> str:
    """:func:`to_dict` as a JSON text (one object)."""
    return json.dumps(to_dict(info), indent=indent)


def format_text(info: Any) -> str:
    """A human-readable report of the ``SceneInfo`` ``info`` (what ``sarmitsuba info`` prints)."""
    lines = [f"scene {info.scene.source} ({info.scene.path}): planned, not traced; costs are estimates", ""]
    for title, body in (("Scene", _scene_lines(info.scene)), ("Radar", _radar_lines(info.radar)),
                        ("Ambiguities", [info.ambiguities.line() if info.ambiguities else "not modelled (spotlight or a "
                                         "curved track)"]), ("Radiometry", _radiometry_lines(info.radiometry)), ("Effects", _effect_lines(info.effects)),
                        ("Bounce depth", _depth_lines(getattr(info, "depth", None))),
                        ("Estimated cost", _cost_lines(info.cost, info.radar.bistatic is not None) + _worker_lines(info.workers)), ("Warnings", list(info.warnings) or ["none"])):
        lines += [title] + [f"  {line}" for line in body] + [""]
    return "\n".join(lines).rstrip() + "\n"


def _depth_lines(depth: dict | None) -> list[str]:
    from .analysis.orders import format_depth
    return format_depth(depth) or ["not planned"]


def _scene_lines(s: Any) -> list[str]:
    lines = [f"shapes {s.n_shapes}, triangles {s.n_triangles:,}, sar sensor "
             f"{'in the scene' if s.has_sar_sensor else 'absent (defaults)'}",
             f"bounding box {_vec(s.bbox_min_m)} .. {_vec(s.bbox_max_m)} m",
             f"scene centre {_vec(s.scene_center_m)} m, frame offset {_vec(s.frame_offset_m)} m",
             *([f"windows {s.windows:,} (their recesses and panes are geometry: the estimated cost below "
                "counts them; docs/physics.md (FA1))"] if s.windows else []),
             f"materials ({len(s.materials)}):"]
    for m in s.materials:
        rough = f"rough ({m.roughness})" if m.rough else "smooth"
        lines.append(f"  {m.name:<14} {m.kind:<8} {m.description}; {rough}; {m.n_shapes} shape(s)")
    return lines


def _radar_lines(r: Any) -> list[str]:
    prf_state = "inside" if r.prf_ok else "OUTSIDE (ambiguities: see warnings)"
    # an orbit's altitude and look angle on the real Earth are the orbit line's; these are the tangent plane's
    orbit = r.orbit_pass is not None
    return [
        f"carrier {_eng(r.frequency_hz, 'Hz')}, wavelength {_eng(r.wavelength_m, 'm')}, "
        f"polarisation {r.polarization}, output {r.output}",
        f"bandwidth {_eng(r.bandwidth_hz, 'Hz')}, pulse {_eng(r.pulse_length_s, 's')}, "
        f"sampling {_eng(r.sampling_rate_hz, 'Hz')}, prf {_eng(r.prf_hz, 'Hz')}",
        f"{r.mode}, looking {r.look_side}, "
        + ("height above the scene's tangent plane" if orbit else "altitude") + f" {r.altitude_m:g} m, velocity "
        f"{r.velocity_m_s:g} m/s, "
        f"azimuth beam {r.azimuth_beamwidth_deg:.3g} deg ("
        + (f"tapered: two-way sinc^2 pattern traced to its first nulls, {r.traced_beamwidth_deg:.3g} deg)"
           if r.beam == "tapered" else "uniform and hard-edged, on request: extended targets streak in azimuth)"),
        f"incidence {r.incidence_angle_deg:g} deg at the centre ({r.incidence_near_deg:.1f} .. "
        f"{r.incidence_far_deg:.1f} deg across the scene), "
        + ("in the scene's tangent plane (the look angle and height on the curved Earth: the orbit line)" if orbit
           else f"look angle {r.look_angle_deg:g} deg (flat earth)"),
        f"slant range to the centre {r.slant_range_m:.1f} m, ground range {r.ground_range_m:.1f} m",
        f"resolution: slant range {r.slant_range_resolution_m:.3g} m = c/(2B); ground range "
        f"{r.ground_range_resolution_m:.3g} m = c/(2B sin theta); azimuth {r.azimuth_resolution_m:.3g} m = "
        f"{r.azimuth_resolution_formula}",
        f"Doppler bandwidth {r.doppler_bandwidth_hz:.1f} Hz = 2 v (sin(squint + beta/2) - sin(squint - beta/2)) / "
        f"lambda (3 dB); traced {r.illuminated_doppler_bandwidth_hz:.1f} Hz over the traced beam",
        f"squint {r.squint_deg:g} deg, Doppler centroid {r.doppler_centroid_hz:.1f} Hz = 2 v sin(squint) / lambda",
        f"PRF limits {_eng(r.prf_min_hz, 'Hz')} .. {_eng(r.prf_max_hz, 'Hz')}: "
        f"prf {_eng(r.prf_hz, 'Hz')} is {prf_state}",
        "  lower: azimuth ambiguity, prf >= illuminated Doppler bandwidth; upper: range ambiguity, "
        "prf <= 1 / (2 dR / c + T_p) (one pulse's echoes fit in one PRI)",
        f"swath: scene {r.swath_ground_m:.1f} m ground range x {r.scene_azimuth_extent_m:.1f} m azimuth, slant "
        f"depth dR {r.swath_slant_m:.1f} m; fast-time window {r.window_samples} samples = "
        f"{_eng(r.window_duration_s, 's')} = {r.window_slant_m:.1f} m slant",
        f"synthetic aperture {r.aperture_length_m:.1f} m = {r.aperture_time_s:.3g} s = {r.pulses_per_point} pulses "
        f"per point; track {r.track_length_m:.1f} m, {r.n_pulses} pulses, {r.acquisition_time_s:.3g} s",
        f"baseline: track_offset {_vec(r.track_offset_m)} m: perpendicular {r.baseline_perpendicular_m:.3f} m, "
        f"parallel {r.baseline_parallel_m:.3f} m; critical {r.critical_baseline_m:.1f} m = lambda R tan(theta) B / c; "
        + ("no height of ambiguity (no perpendicular baseline)" if r.height_of_ambiguity_m is None else
           f"height of ambiguity {r.height_of_ambiguity_m:.4g} m = lambda R sin(theta) / (2 B_perp)"),
        *_bistatic_lines(r.bistatic),
        f"geographic origin: {georef.GeoReference(*r.geo_origin).describe()} (WGS84; world x east, y north, z up), "
        f"UTM EPSG:{r.utm_epsg}" + (" - the default placeholder: set sar geo_origin = \"lat, lon, h\" to place "
                                    "the scene" if r.geo_origin_default else "")] + _orbit_lines(r.orbit_pass)


def _bistatic_lines(b: dict | None) -> list[str]:
    if b is None:
        return []
    return [f"bistatic: angle {b['angle_deg']:.1f} deg at the centre, receiver {b['receiver_range_m']:.1f} m away; "
            f"resolution along the bisector {b['slant_range_resolution_m']:.3g} m = c/(2B cos(beta/2)), on the ground "
            f"{b['ground_range_resolution_m']:.3g} m along {_vec(b['ground_direction'])} (the monostatic figures "
            "above are the transmitter's)"]


def _orbit_lines(o: dict | None) -> list[str]:
    """The orbit's pass at closest approach (docs/physics.md (J6)); nothing for other tracks."""
    if o is None:
        return []
    when = o["utc"] or f"t = {o['time']:.6f} s"
    return [f"orbit at closest approach ({when}): slant range {o['slant_range'] / 1e3:.3f} km, look angle "
            f"{o['look_angle']:.3f} deg, incidence {o['incidence']:.3f} deg (WGS84 ellipsoid normals), squint "
            f"{o['squint']:.4f} deg; {o['height'] / 1e3:.3f} km above the ellipsoid at {o['speed']:.1f} m/s (ECEF)"]


def _radiometry_lines(r: Any) -> list[str]:
    if r is None:
        return ["off (normalised amplitudes, sqrt(m^2)); transmit_power switches it on"]
    lines = [f"antenna gain {r.antenna_gain_dbi:.1f} dBi, radar constant {r.radar_constant_w_m2:.3g} W m^2, "
             f"received power of 1 m^2 at the centre {r.received_power_1m2_w:.3g} W"]
    if r.noise_power_w is None:
        return lines + ["thermal noise off: no SNR / NESZ (noise_figure_db switches it on)"]
    return lines + [f"noise power {r.noise_power_w:.3g} W; SNR of 1 m^2: single pulse "
                    f"{r.single_pulse_snr_1m2_db:.1f} dB, "
                    f"image {r.image_snr_1m2_db:.1f} dB ({r.pulses_integrated} pulses); NESZ {r.nesz_db:.1f} dB"]


def _effect_lines(effects: tuple[Effect, ...]) -> list[str]:
    return [f"[{'on ' if e.active else 'off'}] {e.name}: {e.reason}" for e in effects]


def _cost_lines(c: CostEstimate, bistatic: bool = False) -> list[str]:
    memory = (f"spectra {format_bytes(c.deposit_bytes)} ({c.n_pulses} pulses x "
              f"{c.deposit_bytes // (8 * max(c.n_pulses, 1))} padded samples, complex64)"
              if not c.path_list_bytes else f"path list (exact kernel) up to {format_bytes(c.path_list_bytes)}")
    return [
        f"rays: {c.rays_per_pulse:,} per pulse (grid spacing {c.ray_spacing_m:.3g} m; rays outside the beam are "
        f"not cast); {c.n_pulses:,} pulses in {c.subapertures:,} sub-apertures of {c.pulses_per_trace} pulses, each "
        f"traced once: {c.primary_rays:,} primary rays (patches: the pieces' visibility samples)",
        f"casts (upper bound, every ray to max_depth {c.max_depth}): {c.closest_hit_casts:,} closest-hit + "
        f"{c.shadow_casts:,} shadow; returns evaluated ~ {c.pulse_paths:.3g} (pulse x path)",
        f"trace time ~ {_duration(c.trace_time_s)} ({_duration(c.trace_time_low_s)} .. "
        f"{_duration(c.trace_time_high_s)}: primary rays only .. upper-bound casts, at "
        f"{c.closest_hit_rate_per_s / 1e6:.0f} M closest-hit and {c.shadow_rate_per_s / 1e6:.0f} M shadow casts/s "
        f"and {RETURN_SECONDS * 1e9:g} ns per return on 2 cores)",
        *([f"mesh tracer: ~{c.reach_pieces_mean:,.0f} first-order pieces per sub-aperture's reach (at most "
           f"{c.reach_pieces_max:,.0f}), {c.subapertures_per_launch} sub-apertures per launch: host time "
           f"~ {_duration(c.mesh_host_time_s)} of the trace"] if c.reach_pieces_max else []),
        f"memory: runtime and scene {format_bytes(c.runtime_bytes)}, tracer's working set "
        f"{format_bytes(c.trace_working_bytes)} ({c.lanes_per_launch:,} tubes per launch, a histogram of "
        f"{c.histogram_entries:,} entries), {memory}, raw data {format_bytes(c.raw_bytes)} "
        f"({c.n_pulses} x {c.fast_time_samples} complex64), image {format_bytes(c.image_bytes)}, focusing "
        f"{format_bytes(c.focus_working_bytes)}",
        f"peak memory ~ {format_bytes(c.peak_memory_bytes)} (the process's peak resident set, within a factor 2: "
        "runtime and scene plus the larger of tracing and focusing)",
        f"image grid {c.image_shape[0]} x {c.image_shape[1]} (azimuth x ground range)"
        + (f", {c.n_products} images (split_bounces)" if c.n_products > 1 else ""),
        f"focusing ~ {_duration(c.focus_time_s)} (" + ("fast factorised backprojection on the range sum, "
                                                       if bistatic else "fast factorised backprojection, ")
        + f"{c.backprojection_pixel_pulses:.3g} pixel-pulses in the beam; direct backprojection ~ "
        f"{_duration(c.direct_backprojection_time_s)})",
        c.time_basis]


def _worker_lines(w) -> list[str]:
    if w is None:
        return []
    return [f"processes: {w.workers} ({w.reason}); memory holds {w.memory_cap} worker{'s' if w.memory_cap > 1 else ''} "
            f"of ~{format_bytes(w.per_worker_bytes)} each beside the render ({w.cores} cores; SARMITSUBA_WORKERS sets "
            f"the most); peak memory of the render and its workers ~ {format_bytes(w.peak_memory_bytes)}"]


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in v) + ")"


def _eng(value: float, unit: str) -> str:
    """``value`` with an SI prefix, e.g. ``_eng(9.6e9, 'Hz') == '9.6 GHz'``."""
    if value == 0:
        return f"0 {unit}"
    exponent = max(-9, min(9, 3 * math.floor(math.log10(abs(value)) / 3)))
    prefix = {-9: "n", -6: "u", -3: "m", 0: "", 3: "k", 6: "M", 9: "G"}[exponent]
    return f"{value / 10.0 ** exponent:.4g} {prefix}{unit}"


def _duration(seconds: float) -> str:
    return f"{seconds:.2g} s" if seconds < 120 else f"{seconds / 60:.1f} min"
