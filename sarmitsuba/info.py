"""``sarmitsuba info``: what a scene will simulate, and what it will cost, without tracing.

:func:`scene_info` loads a scene (:func:`sarmitsuba.scene.load_scene`), plans the
acquisition (:mod:`sarmitsuba.planning`) and collects, in one :class:`SceneInfo`:

- the radar summary from the standard formulas (resolutions, Doppler bandwidth, PRF
  limits, swath, synthetic aperture, angles), mostly properties of
  :class:`sarmitsuba.radar.RadarParameters`;
- the point-target SNR and NESZ of the radar equation when ``transmit_power`` is given
  (:func:`sarmitsuba.radiometry.radar_equation`, ``docs/physics.md`` (R1)-(R4));
- the scene's size and materials;
- every optional effect, on or off, with the reason (:func:`sarmitsuba.effects.list_effects`);
- the estimated cost: sub-apertures, ray casts, returns, trace time, memory, image size and
  focusing time.

Nothing is traced: the cost is an estimate from the measured rates below. Every number is
SI with its unit in the field name (``_m``, ``_hz``, ``_s``, ``_deg``, ``_db``, ``_bytes``).

References
----------
.. [1] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar Data*,
   Artech House, 2005, ch. 4: resolutions (eqs. 4.35-4.37), Doppler bandwidth, aperture.
.. [2] J. C. Curlander and R. N. McDonough, *Synthetic Aperture Radar: Systems and Signal
   Processing*, Wiley, 1991, sec. 6.5 (PRF limits from azimuth and range ambiguities),
   eq. 7.6.5 (image SNR).
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import warnings
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from . import planning
from .constants import SPEED_OF_LIGHT
from .effects import Effect, list_effects
from .pipeline import image_grid
from .radar import AcquisitionGeometry, ParameterError, RadarParameters, acquisition_geometry
from .radiometry import effective_pulses, radar_equation
from .scene import LoadedScene, load_scene, material_table
from .deposit import padded_length
from .trace_inputs import FastTimeWindow, RayFootprint

__all__ = ["MaterialInfo", "SceneSize", "RadarSummary", "RadiometrySummary", "CostEstimate", "SceneInfo",
           "scene_info", "cast_rates", "format_text", "to_dict", "to_json", "available_memory", "memory_problem",
           "check_memory", "MEMORY_LIMIT_ENV"]

#: Measured ray-cast rates [casts/s] of Mitsuba's llvm backend on 2 threads of a 2-core x86-64
#: VM, as ``(triangles, closest-hit, shadow)``: a plane and a box (14 triangles: 38-59 M
#: closest-hit, 140-167 M shadow casts/s) and Sionna RT's Munich (38,936 triangles: ~10 M and
#: ~20 M/s), with Mitsuba 3.9.1 / Dr.Jit 1.5.0, variant ``llvm_ad_mono``, on incoherent rays
#: (``ray_intersect`` with ``Minimal`` flags or ``ray_intersect_preliminary``; ``ray_test``);
#: docs/design.md section 10.
CAST_RATE_ANCHORS = ((14, 50e6, 150e6), (38_936, 10e6, 20e6))

#: Factor on the sum of the tracer's parts (casts, returns, spectra) for what is not in them:
#: kernel launches and their Python tracing, compaction between bounce orders. Measured on the
#: 2-core machine (issue 12): 1.2-1.6 for urban and sionna:munich, smooth and rough.
TRACE_OVERHEAD = 1.3

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
#: Clutter scatterers per square metre of tube footprint is ``1 / scatterer_spacing^2``; the
#: estimate assumes every hit is rough when any material is (Munich rough: 2.2 per tube).

#: Bytes per path of the ``exact`` range kernel's path list (int32 pulse, uint8 order,
#: float64 position, complex64 value: :class:`sarmitsuba.trace.PathList`).
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


@dataclass(frozen=True)
class MaterialInfo:
    """One radar material of the scene.

    Attributes
    ----------
    name : str
        The BSDF's id in the scene.
    kind : str
        ``"PEC"`` (perfect conductor), ``"ITU"`` (ITU-R P.2040 named material) or ``"explicit"``
        (relative permittivity and conductivity given).
    description : str
        E.g. ``"ITU concrete, slab 0.3 m"``.
    model : str
        ``"pec"``, ``"half_space"`` or ``"slab"``.
    permittivity_real, permittivity_imag : float or None
        Complex relative permittivity at the carrier (None for PEC).
    thickness_m : float or None
        Slab thickness.
    rough : bool
        Whether it has a clutter model (distributed clutter and speckle).
    roughness : str
        ``"gamma_db -14"`` or ``"scattering_coefficient 0.3"``; ``""`` when smooth.
    n_shapes : int
        Shapes using it.
    """

    name: str
    kind: str
    description: str
    model: str
    permittivity_real: float | None
    permittivity_imag: float | None
    thickness_m: float | None
    rough: bool
    roughness: str
    n_shapes: int


@dataclass(frozen=True)
class SceneSize:
    """Size and contents of the scene. Coordinates are world frame, float, m."""

    source: str
    path: str
    has_sar_sensor: bool
    n_shapes: int
    n_triangles: int
    bbox_min_m: tuple[float, float, float]
    bbox_max_m: tuple[float, float, float]
    #: World position of the local frame the scene is traced in (zero near the origin).
    frame_offset_m: tuple[float, float, float]
    scene_center_m: tuple[float, float, float]
    materials: tuple[MaterialInfo, ...]


@dataclass(frozen=True)
class RadarSummary:
    """Radar parameters and the quantities derived from them (refs. [1], [2]; SI units).

    Resolutions: slant range ``c / (2B)``, ground range ``c / (2B sin(theta))``, azimuth
    ``L / 2`` for the aperture ``L`` of a tapered beam or antenna, ``lambda / (2 beta)`` for a
    uniform beam, or ``lambda / (2 dtheta)`` (spotlight). ``doppler_bandwidth_hz`` is the 3 dB
    Doppler bandwidth ``2 v (sin(squint + beta/2) - sin(squint - beta/2)) / lambda`` of the 3 dB
    beamwidth ``beta`` (``2 v beta cos(squint) / lambda`` for small beams);
    ``illuminated_doppler_bandwidth_hz`` the same over the traced beam (to the pattern's first
    nulls for a tapered beam, about 2.26 beta). PRF limits: lower = the 3 dB Doppler bandwidth
    (azimuth ambiguities; the tapered beam's tails beyond it alias at a low level), upper =
    ``1 / (2 dR / c + T_p)`` with ``dR`` the scene's slant depth seen from the track (range
    ambiguities: one pulse's echoes must fit in one PRI); the same tests as
    :func:`sarmitsuba.planning.check_acquisition`.
    """

    frequency_hz: float
    wavelength_m: float
    bandwidth_hz: float
    pulse_length_s: float
    sampling_rate_hz: float
    prf_hz: float
    velocity_m_s: float
    altitude_m: float
    mode: str
    look_side: str
    polarization: str
    output: str
    #: ``tapered`` (two-way sinc^2 of an aperture) or ``uniform`` (hard-edged, on request).
    beam: str
    azimuth_beamwidth_deg: float
    #: Full width of the traced (and backprojected) beam: to the pattern's first nulls, or the
    #: uniform beam's width.
    traced_beamwidth_deg: float
    incidence_angle_deg: float
    #: Off-nadir look angle at the scene centre (flat earth: equal to the incidence angle).
    look_angle_deg: float
    incidence_near_deg: float
    incidence_far_deg: float
    slant_range_m: float
    ground_range_m: float
    slant_range_resolution_m: float
    ground_range_resolution_m: float
    azimuth_resolution_m: float
    azimuth_resolution_formula: str
    doppler_bandwidth_hz: float
    illuminated_doppler_bandwidth_hz: float
    squint_deg: float
    doppler_centroid_hz: float
    prf_min_hz: float
    prf_max_hz: float
    prf_ok: bool
    #: Scene extent across track (ground range) and along track, from its bounding box.
    swath_ground_m: float
    scene_azimuth_extent_m: float
    #: Slant depth of the scene seen from the whole track, ``(L_max - L_min) / 2``.
    swath_slant_m: float
    window_start_s: float
    window_samples: int
    window_duration_s: float
    window_slant_m: float
    #: Synthetic aperture integrated per point: the beam footprint ``2 R tan(beta / 2)`` in
    #: stripmap, the whole track ``N v / prf`` in spotlight.
    aperture_length_m: float
    aperture_time_s: float
    pulses_per_point: int
    n_pulses: int
    track_length_m: float
    acquisition_time_s: float


@dataclass(frozen=True)
class RadiometrySummary:
    """Radar-equation figures at the scene centre (``docs/physics.md`` (R1)-(R4)).

    SNR fields and NESZ are None when thermal noise is off (no ``noise_figure_db`` /
    ``noise_temperature``). ``nesz_db`` is ``10 log10(1 / (SNR_image(1 m^2) rho_az rho_gr))``:
    the sigma-nought whose clutter equals the noise floor of the focused image.
    """

    antenna_gain_dbi: float
    radar_constant_w_m2: float
    received_power_1m2_w: float
    noise_power_w: float | None
    single_pulse_snr_1m2_db: float | None
    image_snr_1m2_db: float | None
    nesz_db: float | None
    pulses_integrated: int


@dataclass(frozen=True)
class CostEstimate:
    """Estimated work and memory of a render (the times are estimates, within a factor ~2).

    Rays: ``rays_per_pulse`` is the coarse ray grid a pulse aims at the scene (rays outside the
    beam are not cast, so it is an upper bound). A sub-aperture of ``pulses_per_trace`` pulses
    traces the union of its pulses' grids once (docs/physics.md (T3)): ``primary_rays`` are the
    tubes of all ``subapertures``, plus the finer tubes around small objects for the
    sub-apertures that see them. Casts: ``primary_rays`` (low) to ``primary_rays * max_depth``
    (high) closest-hit casts, as many shadow casts. Returns: every pulse evaluates
    :data:`RETURNS_PER_TUBE` PO terms per tube it casts and, when a material is rough, the
    clutter scatterers of its tubes' footprints (``tube area / scatterer_spacing^2`` each):
    ``pulse_paths``. Trace time: :data:`TRACE_OVERHEAD` times the casts at the rates of
    :func:`cast_rates`, the returns at :data:`RETURN_SECONDS` and :data:`SCATTERER_SECONDS` and
    the reduction to the band at :data:`FFT_SECONDS`; ``trace_time_s`` takes the casts halfway
    between low and high.

    Memory: the tracer's spectra, complex64 ``[groups, n_pulses, padded samples]`` (groups
    = ``max_depth`` with ``split_bounces``, else 1; :func:`sarmitsuba.deposit.padded_length`),
    or with the ``exact`` range kernel its term list instead, at most one path per return of
    :data:`PATH_BYTES` each; one raw data set, complex64 ``[n_pulses, fast_time_samples]``; one
    image, complex64 ``image_shape``. ``n_products`` raw/image pairs are made (``1 + max_depth``
    with ``split_bounces``). ``peak_memory_bytes``: the spectra (or path list) and every raw data
    set and image, all held at once at the end of a render (:func:`check_memory` compares it with
    the memory available).

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
    peak_memory_bytes: int


@dataclass(frozen=True)
class SceneInfo:
    """Everything ``sarmitsuba info`` reports about a scene (see the module docstring)."""

    scene: SceneSize
    radar: RadarSummary
    radiometry: RadiometrySummary | None
    effects: tuple[Effect, ...]
    cost: CostEstimate
    #: What render would warn about (ambiguities, a scene outside the beam).
    warnings: tuple[str, ...]


def scene_info(source: str | None, *, sensor_overrides: Mapping[str, Any] | None = None,
               integrator_overrides: Mapping[str, Any] | None = None,
               material_overrides: Mapping[str, Any] | None = None) -> SceneInfo:
    """Load and plan a scene, without tracing, and summarise it.

    Parameters are those of :func:`sarmitsuba.pipeline.render` (no output directory).

    Raises
    ------
    SceneError, ParameterError, materials.MaterialError
        The errors render would raise before tracing.
    """
    loaded = load_scene(source, sensor_overrides, integrator_overrides, material_overrides)
    params, lo, hi = loaded.params, loaded.bbox_lo, loaded.bbox_hi
    geometry = acquisition_geometry(params)
    window = planning.fast_time_window(params, geometry, lo, hi, loaded.settings)
    footprint = planning.ray_footprint(params, geometry, lo, hi, loaded.settings, shape_boxes=loaded.shape_boxes)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", planning.AcquisitionWarning)     # reported in the result instead
        messages = planning.check_acquisition(params, geometry, window, lo, hi)
    material_table(loaded.scene, params.frequency, params.polarization)  # same material checks as render
    radar = _radar_summary(params, geometry, window, lo, hi)
    cost = _cost(loaded, geometry, window, footprint)
    memory = memory_problem(cost, params)
    return SceneInfo(scene=_scene_size(loaded), radar=radar,
                     radiometry=_radiometry(params, radar.pulses_per_point), effects=list_effects(loaded),
                     cost=cost, warnings=tuple(messages) + ((memory,) if memory else ()))


# ============================================================================ scene
def _scene_size(loaded: LoadedScene) -> SceneSize:
    offset = loaded.offset
    center = np.asarray(loaded.params.scene_center) + offset
    return SceneSize(source=loaded.source, path=str(loaded.path or "built in Python"),
                     has_sar_sensor=loaded.has_sensor,
                     n_shapes=loaded.n_shapes, n_triangles=loaded.n_triangles,
                     bbox_min_m=_floats(loaded.bbox_lo + offset), bbox_max_m=_floats(loaded.bbox_hi + offset),
                     frame_offset_m=_floats(offset), scene_center_m=_floats(center),
                     materials=_materials(loaded.scene, loaded.params.frequency))


def _materials(scene: Any, frequency: float) -> tuple[MaterialInfo, ...]:
    """One :class:`MaterialInfo` per BSDF object, in order of first use."""
    bsdfs: dict[int, Any] = {}
    counts: dict[int, int] = {}
    for shape in scene.shapes():
        bsdf = shape.bsdf()
        bsdfs.setdefault(bsdf.id_key, bsdf)
        counts[bsdf.id_key] = counts.get(bsdf.id_key, 0) + 1
    return tuple(_material(bsdf, frequency, counts[key]) for key, bsdf in bsdfs.items())


def _material(bsdf: Any, frequency: float, n_shapes: int) -> MaterialInfo:
    material = bsdf.material_at(frequency)
    itu_name = getattr(bsdf, "_spec", {}).get("material")   # the plugin keeps the ITU name here
    slab = f", slab {material.thickness:g} m" if material.model == "slab" else ""
    eta = material.relative_permittivity
    if material.model == "pec":
        kind, description = "PEC", "perfect conductor"
    elif itu_name is not None:
        kind, description = "ITU", f"ITU {itu_name}{slab or ', half-space'}"
    else:
        kind, description = "explicit", f"explicit permittivity{slab or ', half-space'}"
    if eta is not None:
        description += f", eta = {eta.real:.3g}{eta.imag:+.3g}j"
    clutter_kind, value = bsdf.clutter
    roughness = {0: "", 1: f"gamma_db {10.0 * math.log10(value):g}" if value > 0 else "",
                 2: f"scattering_coefficient {math.sqrt(value / 4.0):g}"}[int(clutter_kind)]
    return MaterialInfo(name=bsdf.name, kind=kind, description=description, model=material.model,
                        permittivity_real=None if eta is None else float(eta.real),
                        permittivity_imag=None if eta is None else float(eta.imag),
                        thickness_m=material.thickness, rough=clutter_kind > 0, roughness=roughness,
                        n_shapes=n_shapes)


# ============================================================================ radar
def _radar_summary(p: RadarParameters, geometry: AcquisitionGeometry, window: FastTimeWindow,
                   lo: np.ndarray, hi: np.ndarray) -> RadarSummary:
    rel = planning.box_corners(lo, hi) - geometry.scene_center
    along, across = rel @ geometry.track_direction, rel @ geometry.look_direction
    l_min, l_max = planning._echo_lengths(geometry.positions, lo, hi)   # as check_acquisition
    aperture_length, pulses_per_point = _aperture(p)
    sin_lo, sin_hi = p.beam_sines
    prf_min = p.doppler_bandwidth
    prf_max = 1.0 / ((l_max - l_min) / SPEED_OF_LIGHT + p.pulse_length)
    return RadarSummary(
        frequency_hz=p.frequency, wavelength_m=p.wavelength, bandwidth_hz=p.bandwidth, pulse_length_s=p.pulse_length,
        sampling_rate_hz=p.sampling_rate, prf_hz=p.prf, velocity_m_s=p.velocity, altitude_m=p.altitude,
        mode=p.mode, look_side=p.look_side, polarization=p.polarization, output=p.output, beam=p.beam,
        azimuth_beamwidth_deg=p.azimuth_beamwidth, traced_beamwidth_deg=p.traced_beamwidth,
        incidence_angle_deg=p.incidence_angle,
        look_angle_deg=p.incidence_angle,
        incidence_near_deg=math.degrees(math.atan2(p.ground_range + float(across.min()), p.altitude)),
        incidence_far_deg=math.degrees(math.atan2(p.ground_range + float(across.max()), p.altitude)),
        slant_range_m=p.slant_range, ground_range_m=p.ground_range,
        slant_range_resolution_m=p.slant_range_resolution, ground_range_resolution_m=p.ground_range_resolution,
        azimuth_resolution_m=p.azimuth_resolution, azimuth_resolution_formula=_azimuth_formula(p),
        doppler_bandwidth_hz=p.doppler_bandwidth,
        illuminated_doppler_bandwidth_hz=2.0 * p.velocity * (sin_hi - sin_lo) / p.wavelength,
        squint_deg=p.squint, doppler_centroid_hz=p.doppler_centroid,
        prf_min_hz=prf_min, prf_max_hz=prf_max, prf_ok=prf_min <= p.prf <= prf_max,
        swath_ground_m=float(across.max() - across.min()), scene_azimuth_extent_m=float(along.max() - along.min()),
        swath_slant_m=0.5 * (l_max - l_min), window_start_s=window.t0, window_samples=window.n_samples,
        window_duration_s=window.n_samples / window.fs,
        window_slant_m=SPEED_OF_LIGHT * window.n_samples / (2 * window.fs),
        aperture_length_m=aperture_length, aperture_time_s=aperture_length / p.velocity,
        pulses_per_point=pulses_per_point, n_pulses=p.n_pulses,
        track_length_m=(p.n_pulses - 1) * p.velocity / p.prf, acquisition_time_s=(p.n_pulses - 1) / p.prf)


def _aperture(p: RadarParameters) -> tuple[float, int]:
    """Synthetic aperture length [m] integrated per point, and the pulses in it.

    Stripmap: the traced beam's footprint ``2 R tan(h)`` at the scene centre (each point is
    lit while the platform flies that far; capped by the track). Spotlight: the whole
    track, ``N v / prf`` (the length behind :attr:`RadarParameters.integration_angle`).
    """
    if p.mode == "spotlight":
        return p.n_pulses * p.velocity / p.prf, p.n_pulses
    length = p.footprint_length
    return length, int(min(p.n_pulses, max(1, round(length * p.prf / p.velocity))))


def _azimuth_formula(p: RadarParameters) -> str:
    if p.mode == "spotlight":
        return (f"lambda / (2 dtheta), integration angle dtheta = N v / (prf R) = "
                f"{math.degrees(p.integration_angle):.3g} deg")
    if p.antenna_length > 0:
        return f"L_a / 2, antenna_length L_a = {p.antenna_length:g} m"
    if p.pattern_length > 0:
        return (f"L / 2, L = 0.443 lambda / sin(beta / 2) = {p.pattern_length:.3g} m: the aperture whose 3 dB "
                f"beamwidth is azimuth_beamwidth beta = {p.azimuth_beamwidth:g} deg (tapered beam)")
    return f"lambda / (2 beta), uniform beam of width beta = {p.azimuth_beamwidth:g} deg"


def _radiometry(p: RadarParameters, pulses: int) -> RadiometrySummary | None:
    """Radar-equation figures for a 1 m^2 target at the scene centre; None when radiometry is off."""
    equation = radar_equation(p)
    if equation is None:
        return None
    r = p.slant_range
    snr = image = nesz = None
    if equation.noise_power > 0:
        snr = _db(equation.snr(1.0, r))
        image_snr = equation.image_snr(1.0, r, effective_pulses(p, pulses))     # eq. (R3)
        image = _db(image_snr)
        nesz = _db(1.0 / (image_snr * p.azimuth_resolution * p.ground_range_resolution))   # eq. (R4)
    return RadiometrySummary(antenna_gain_dbi=_db(equation.gain), radar_constant_w_m2=equation.constant,
                             received_power_1m2_w=equation.received_power(1.0, r),
                             noise_power_w=equation.noise_power or None, single_pulse_snr_1m2_db=snr,
                             image_snr_1m2_db=image, nesz_db=nesz, pulses_integrated=pulses)


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


def _cost(loaded: LoadedScene, geometry: AcquisitionGeometry, window: FastTimeWindow,
          footprint: RayFootprint) -> CostEstimate:
    from .trace import pulses_per_trace
    st, p = loaded.settings, loaded.params
    n_pulses = p.n_pulses
    size = pulses_per_trace(p, st, n_pulses)
    n_subs = math.ceil(n_pulses / size)
    # a sub-aperture's union of its pulses' lattices: the cells its antenna travel adds along track
    spread = math.ceil(min(size - 1, n_pulses - 1) * p.velocity / p.prf / footprint.spacing_azimuth)
    per_sub = (footprint.n_azimuth + spread) * footprint.n_range
    pulses_seeing = _aperture(p)[1]
    primary = per_sub * n_subs + footprint.refined_rays * math.ceil(pulses_seeing / size)
    casts = primary * st.max_depth
    hit_rate, shadow_rate = cast_rates(loaded.n_triangles)
    tube_pulses = footprint.rays_per_pulse * n_pulses + footprint.refined_rays * pulses_seeing
    table = material_table(loaded.scene, p.frequency, p.polarization)
    tube_area = footprint.spacing_azimuth * footprint.spacing_range
    scatterers = (footprint.rays_per_pulse * n_pulses * tube_area / footprint.scatterer_spacing**2
                  if table.has_clutter else 0.0)
    paths = int(RETURNS_PER_TUBE * tube_pulses + scatterers)
    groups = st.max_depth if st.split_bounces else 1
    n_pad = padded_length(window.n_samples)
    work = (RETURNS_PER_TUBE * tube_pulses * RETURN_SECONDS + scatterers * SCATTERER_SECONDS
            + 3 * groups * n_pulses * n_pad * window.oversample * FFT_SECONDS)

    def trace_time(closest: float) -> float:
        return TRACE_OVERHEAD * (closest / hit_rate + closest / shadow_rate + work)

    exact = st.range_kernel == "exact"          # keeps a path list instead of the fine grid
    grid = _image_grid(loaded, geometry)
    n_products = 1 + (st.max_depth if st.split_bounces else 0)
    pixel_pulses, lit, direct = _backprojection(p, grid)
    fast = FFBP_FIXED_SECONDS + pixel_pulses * FFBP_PIXEL_PULSE_SECONDS + lit * FFBP_PIXEL_SECONDS
    deposit = 0 if exact else groups * n_pulses * n_pad * 8
    raw_bytes, image_bytes = n_pulses * window.n_samples * 8, grid.shape[0] * grid.shape[1] * 8
    return CostEstimate(
        ray_spacing_m=footprint.spacing_azimuth, rays_per_pulse=footprint.rays_per_pulse, n_pulses=n_pulses,
        pulses_per_trace=size, subapertures=n_subs, primary_rays=primary, max_depth=st.max_depth,
        closest_hit_casts=casts, shadow_casts=casts, closest_hit_rate_per_s=hit_rate, shadow_rate_per_s=shadow_rate,
        pulse_paths=paths, trace_time_low_s=trace_time(primary), trace_time_high_s=trace_time(casts),
        trace_time_s=trace_time(0.5 * (primary + casts)),
        fast_time_samples=window.n_samples, fine_samples=window.n_fine,
        deposit_bytes=deposit, path_list_bytes=paths * PATH_BYTES if exact else 0, raw_bytes=raw_bytes,
        image_shape=grid.shape, image_bytes=image_bytes, n_products=n_products,
        backprojection_pixel_pulses=n_products * pixel_pulses, focus_time_s=n_products * fast,
        direct_backprojection_time_s=n_products * direct,
        peak_memory_bytes=deposit + (paths * PATH_BYTES if exact else 0) + n_products * (raw_bytes + image_bytes))


def _image_grid(loaded: LoadedScene, geometry: AcquisitionGeometry):
    """The render's image grid (:func:`sarmitsuba.pipeline.image_grid`); ParameterError naming the
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


# ============================================================================ memory
#: Environment variable that sets the memory [bytes] a render may use (tests, batch jobs); without
#: it :func:`available_memory` reads the machine's.
MEMORY_LIMIT_ENV = "SARMITSUBA_MEMORY_LIMIT"


def available_memory() -> int:
    """Bytes of memory a render may use: ``$SARMITSUBA_MEMORY_LIMIT`` when set, else ``MemAvailable``
    of ``/proc/meminfo`` (Linux), else the physical memory (``os.sysconf``).

    Raises
    ------
    ParameterError
        ``SARMITSUBA_MEMORY_LIMIT`` is not a whole number of bytes > 0.
    """
    text = os.environ.get(MEMORY_LIMIT_ENV)
    if text is not None:
        try:
            limit = int(float(text))
        except ValueError:
            limit = 0
        if limit <= 0:
            raise ParameterError(f"{MEMORY_LIMIT_ENV} = {text!r} must be a number of bytes > 0 (e.g. 8e9)")
        return limit
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def memory_problem(cost: CostEstimate, params: RadarParameters, available: int | None = None) -> str | None:
    """Why a render of estimated ``cost`` cannot fit in ``available`` bytes (default
    :func:`available_memory`) and what to change, led by the term that dominates; None when it fits."""
    available = available_memory() if available is None else available
    if cost.peak_memory_bytes <= available:
        return None
    n = cost.n_products
    terms = {"spectra": cost.deposit_bytes, "path list": cost.path_list_bytes,
             "raw data": n * cost.raw_bytes, "image": n * cost.image_bytes}
    parts = ", ".join(f"{name} {_bytes(size)}" for name, size in terms.items() if size)
    text = (f"the render would need about {_bytes(cost.peak_memory_bytes)} of memory ({parts}) but "
            f"{_bytes(available)} is available ({MEMORY_LIMIT_ENV} overrides it)")
    largest = max(terms, key=terms.get)
    if largest == "image":
        return (f"{text}: the image grid {cost.image_shape[0]} x {cost.image_shape[1]} pixels dominates; its pixels "
                "are half the finer resolution: lower bandwidth, narrow the beam or use a smaller scene")
    per_pulse = (cost.peak_memory_bytes - n * cost.image_bytes) / max(cost.n_pulses, 1)
    fit = max(1, int((available - n * cost.image_bytes) // max(per_pulse, 1)))
    fix = (f"use fewer pulses (--pulses {fit} or fewer; sar n_pulses = {cost.n_pulses} now) or a shorter "
           f"fast-time window ({cost.fast_time_samples} samples: a smaller scene, or --set "
           f"sampling_rate=... closer to bandwidth = {params.bandwidth / 1e6:g} MHz)")
    if largest == "path list":
        fix = f"the exact range kernel's path list dominates: use --range-kernel linear, or {fix}"
    else:
        fix = f"the {largest} (pulses x fast-time samples) dominate: {fix}"
    if n > 1:
        fix += f", or drop split_bounces ({n} raw data sets and images)"
    return f"{text}: {fix}"


def check_memory(loaded: LoadedScene, geometry: AcquisitionGeometry, window: FastTimeWindow,
                 footprint: RayFootprint, available: int | None = None) -> CostEstimate:
    """The cost of rendering ``loaded`` (:class:`CostEstimate`), checked against the memory
    ``available`` [bytes] (default :func:`available_memory`) before any tracing.

    Raises
    ------
    ParameterError
        The estimated peak memory exceeds it (:func:`memory_problem` says what to change), or the
        image grid would be too large.
    """
    cost = _cost(loaded, geometry, window, footprint)
    problem = memory_problem(cost, loaded.params, available)
    if problem is not None:
        raise ParameterError(problem)
    return cost


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


# ============================================================================ output
def to_dict(info: SceneInfo) -> dict:
    """The info as plain JSON types (numbers as numbers, units in the key names)."""
    return dataclasses.asdict(info)


def to_json(info: SceneInfo, indent: int | None = 2) -> str:
    """:func:`to_dict` as a JSON text (one object)."""
    return json.dumps(to_dict(info), indent=indent)


def format_text(info: SceneInfo) -> str:
    """A human-readable report of ``info`` (what ``sarmitsuba info`` prints)."""
    lines = [f"scene {info.scene.source} ({info.scene.path}): planned, not traced; costs are estimates", ""]
    for title, body in (("Scene", _scene_lines(info.scene)), ("Radar", _radar_lines(info.radar)),
                        ("Radiometry", _radiometry_lines(info.radiometry)), ("Effects", _effect_lines(info.effects)),
                        ("Estimated cost", _cost_lines(info.cost)), ("Warnings", list(info.warnings) or ["none"])):
        lines += [title] + [f"  {line}" for line in body] + [""]
    return "\n".join(lines).rstrip() + "\n"


def _scene_lines(s: SceneSize) -> list[str]:
    lines = [f"shapes {s.n_shapes}, triangles {s.n_triangles:,}, sar sensor "
             f"{'in the scene' if s.has_sar_sensor else 'absent (defaults)'}",
             f"bounding box {_vec(s.bbox_min_m)} .. {_vec(s.bbox_max_m)} m",
             f"scene centre {_vec(s.scene_center_m)} m, frame offset {_vec(s.frame_offset_m)} m",
             f"materials ({len(s.materials)}):"]
    for m in s.materials:
        rough = f"rough ({m.roughness})" if m.rough else "smooth"
        lines.append(f"  {m.name:<14} {m.kind:<8} {m.description}; {rough}; {m.n_shapes} shape(s)")
    return lines


def _radar_lines(r: RadarSummary) -> list[str]:
    prf_state = "inside" if r.prf_ok else "OUTSIDE (ambiguities: see warnings)"
    return [
        f"carrier {_eng(r.frequency_hz, 'Hz')}, wavelength {_eng(r.wavelength_m, 'm')}, "
        f"polarisation {r.polarization}, output {r.output}",
        f"bandwidth {_eng(r.bandwidth_hz, 'Hz')}, pulse {_eng(r.pulse_length_s, 's')}, "
        f"sampling {_eng(r.sampling_rate_hz, 'Hz')}, prf {_eng(r.prf_hz, 'Hz')}",
        f"{r.mode}, looking {r.look_side}, altitude {r.altitude_m:g} m, velocity {r.velocity_m_s:g} m/s, "
        f"azimuth beam {r.azimuth_beamwidth_deg:.3g} deg ("
        + (f"tapered: two-way sinc^2 pattern traced to its first nulls, {r.traced_beamwidth_deg:.3g} deg)"
           if r.beam == "tapered" else "uniform and hard-edged, on request: extended targets streak in azimuth)"),
        f"incidence {r.incidence_angle_deg:g} deg at the centre ({r.incidence_near_deg:.1f} .. "
        f"{r.incidence_far_deg:.1f} deg across the scene), look angle {r.look_angle_deg:g} deg (flat earth)",
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
        f"per point; track {r.track_length_m:.1f} m, {r.n_pulses} pulses, {r.acquisition_time_s:.3g} s"]


def _radiometry_lines(r: RadiometrySummary | None) -> list[str]:
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


def _cost_lines(c: CostEstimate) -> list[str]:
    memory = (f"spectra {_bytes(c.deposit_bytes)} ({c.n_pulses} pulses x "
              f"{c.deposit_bytes // (8 * max(c.n_pulses, 1))} padded samples, complex64)"
              if not c.path_list_bytes else f"path list (exact kernel) up to {_bytes(c.path_list_bytes)}")
    return [
        f"rays: {c.rays_per_pulse:,} per pulse (grid spacing {c.ray_spacing_m:.3g} m; rays outside the beam are "
        f"not cast); {c.n_pulses:,} pulses in {c.subapertures:,} sub-apertures of {c.pulses_per_trace} pulses, each "
        f"traced once: {c.primary_rays:,} primary rays",
        f"casts (upper bound, every ray to max_depth {c.max_depth}): {c.closest_hit_casts:,} closest-hit + "
        f"{c.shadow_casts:,} shadow; returns evaluated ~ {c.pulse_paths:.3g} (pulse x path)",
        f"trace time ~ {_duration(c.trace_time_s)} ({_duration(c.trace_time_low_s)} .. "
        f"{_duration(c.trace_time_high_s)}: primary rays only .. upper-bound casts, at "
        f"{c.closest_hit_rate_per_s / 1e6:.0f} M closest-hit and {c.shadow_rate_per_s / 1e6:.0f} M shadow casts/s "
        f"and {RETURN_SECONDS * 1e9:g} ns per return on 2 cores)",
        f"memory: {memory}, raw data {_bytes(c.raw_bytes)} ({c.n_pulses} x {c.fast_time_samples} complex64), "
        f"image {_bytes(c.image_bytes)}; peak ~ {_bytes(c.peak_memory_bytes)}",
        f"image grid {c.image_shape[0]} x {c.image_shape[1]} (azimuth x ground range)"
        + (f", {c.n_products} images (split_bounces)" if c.n_products > 1 else ""),
        f"focusing ~ {_duration(c.focus_time_s)} (fast factorised backprojection, {c.backprojection_pixel_pulses:.3g} "
        f"pixel-pulses in the beam; direct backprojection ~ {_duration(c.direct_backprojection_time_s)})"]


def _db(x: float) -> float:
    return 10.0 * math.log10(x)


def _floats(v: np.ndarray) -> tuple[float, float, float]:
    return tuple(float(x) for x in v)


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in v) + ")"


def _eng(value: float, unit: str) -> str:
    """``value`` with an SI prefix, e.g. ``_eng(9.6e9, 'Hz') == '9.6 GHz'``."""
    if value == 0:
        return f"0 {unit}"
    exponent = max(-9, min(9, 3 * math.floor(math.log10(abs(value)) / 3)))
    prefix = {-9: "n", -6: "u", -3: "m", 0: "", 3: "k", 6: "M", 9: "G"}[exponent]
    return f"{value / 10.0 ** exponent:.4g} {prefix}{unit}"


def _bytes(n: int) -> str:
    for unit, size in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{n} B"


def _duration(seconds: float) -> str:
    return f"{seconds:.2g} s" if seconds < 120 else f"{seconds / 60:.1f} min"
