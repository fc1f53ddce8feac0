"""``sarmitsuba info``: what a scene will simulate, and what it will cost, without tracing.

:func:`scene_info` loads a scene (:func:`sarmitsuba.scene.loader.load_scene`), plans the
acquisition (:mod:`sarmitsuba.scene.planning`) and collects, in one :class:`SceneInfo`:

- the radar summary from the standard formulas (resolutions, Doppler bandwidth, PRF
  limits, swath, synthetic aperture, angles), mostly properties of
  :class:`sarmitsuba.core.radar.RadarParameters`;
- the point-target SNR and NESZ of the radar equation when ``transmit_power`` is given
  (:func:`sarmitsuba.scene.radar_equation.radar_equation`, ``docs/physics.md`` (R1)-(R4));
- the azimuth and range ambiguity-to-signal ratios at the PRF (:mod:`sarmitsuba.analysis.ambiguities`,
  ``docs/physics.md`` (AMB1), (AMB2)), with a warning above -20 dB;
- the scene's size and materials;
- every optional effect, on or off, with the reason (:func:`sarmitsuba.scene.effects.active_effects`,
  computed once and handed to the cost model and the radar equation);
- the depth ``max_depth = auto`` will trace, from the render's own probe (ray tubes to the cap,
  :mod:`sarmitsuba.tracing.driver.depth`), with each order's share, and its predicted seconds
  from the render's tracer on one sub-aperture;
- the estimated cost: sub-apertures, ray casts, returns, trace time, peak memory (the render
  process's peak resident set: runtime, scene, tracer's working set and arrays), image size and
  focusing time (:mod:`sarmitsuba.analysis.cost` and :mod:`sarmitsuba.analysis.memory`, re-exported here: :class:`CostEstimate`,
  :func:`cast_rates`, :func:`check_memory`, ...).

:mod:`sarmitsuba.info_text` writes it as text (:func:`format_text`, what the command prints) or
JSON (:func:`to_json`). Nothing else is traced: the cost is an estimate from the measured rates of :mod:`sarmitsuba.analysis.cost`. Every number is
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
import math
import warnings
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .core import georef, orbit
from .core.trajectory import StateVectors
from .scene import planning
from .scene.baseline import baseline
from .scene.rough_presets import describe_surface
from .core.constants import SPEED_OF_LIGHT
from .analysis.cost import CostEstimate, cast_rates, cost_estimate, synthetic_aperture
from .tracing.driver.depth import choose_depth
from .tracing.driver.workers import WorkerPlan, plan_for
from .analysis.memory import MEMORY_LIMIT_ENV, available_memory, check_memory, memory_problem
from .analysis.ambiguities import Ambiguities, ambiguities
from .analysis import bistatic
from .scene.effects import Effect, EffectSet, active_effects
from .scene.roughness import RoughSurfaceWarning
from .core.radar import RadarParameters
from .core.geometry import AcquisitionGeometry, acquisition_geometry
from .scene.radar_equation import radar_equation
from .signal.radiometry import effective_pulses
from .scene.loader import LoadedScene, load_scene, material_table
from .scene.trace_inputs import FastTimeWindow
from .info_text import format_text, to_dict, to_json

__all__ = ["MaterialInfo", "SceneSize", "RadarSummary", "RadiometrySummary", "CostEstimate", "SceneInfo",
           "scene_info", "cast_rates", "format_text", "to_dict", "to_json", "available_memory", "memory_problem",
           "check_memory", "MEMORY_LIMIT_ENV"]


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
        ``"gamma_db -14"``, ``"scattering_coefficient 0.3"`` or a rough surface's statistics and
        its HH and VV sigma nought at the scene's incidence; ``""`` when smooth.
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
    #: Windows of the facades (panes of the shapes whose id ends in ``-windows``, as
    #: ``scene from-footprints --windows`` and ``scene add-windows`` write them); 0 without.
    windows: int = 0


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
    :func:`sarmitsuba.scene.planning.check_acquisition`.
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
    #: Repeat-pass interferometry (:mod:`sarmitsuba.scene.baseline`): the sensor's ``track_offset``
    #: against the nominal track, its perpendicular and parallel baselines, the critical
    #: perpendicular baseline and the height of ambiguity (None without a perpendicular baseline).
    track_offset_m: tuple = (0.0, 0.0, 0.0)
    baseline_perpendicular_m: float = 0.0
    baseline_parallel_m: float = 0.0
    critical_baseline_m: float = 0.0
    height_of_ambiguity_m: float | None = None
    #: WGS84 position of the world frame's origin (latitude deg, longitude deg, height m;
    #: :mod:`sarmitsuba.core.georef`), whether it is the placeholder default, and its UTM zone's EPSG code.
    geo_origin: tuple = (0.0, 0.0, 0.0)
    geo_origin_default: bool = True
    utm_epsg: int = 32631
    #: An orbit (ECEF state vectors, :mod:`sarmitsuba.core.orbit`) at its closest approach to the
    #: scene centre: time (UTC), slant range, look angle, incidence against the ellipsoid normal,
    #: squint, height above the ellipsoid and speed (docs/physics.md (J6)); None for other tracks.
    orbit_pass: dict | None = None
    #: Bistatic (sensor ``receiver_*``, docs/physics.md (B4)), mid-aperture at the scene centre:
    #: ``angle_deg``, ``slant_range_resolution_m`` ``c / (2 B cos(beta / 2))`` along the bisector,
    #: ``ground_range_resolution_m`` over its horizontal part, ``ground_direction`` (unit, ENU) and
    #: the receiver's ``receiver_range_m``; None when the transmitter receives.
    bistatic: dict | None = None


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
class SceneInfo:
    """Everything ``sarmitsuba info`` reports about a scene (see the module docstring)."""

    scene: SceneSize
    radar: RadarSummary
    radiometry: RadiometrySummary | None
    effects: tuple[Effect, ...]
    cost: CostEstimate
    #: What render would warn about (ambiguities, a scene outside the beam).
    warnings: tuple[str, ...]
    #: AASR and RASR at the PRF (:mod:`sarmitsuba.analysis.ambiguities`); None in spotlight or on a curved track.
    ambiguities: Ambiguities | None = None
    #: The processes the trace will use, the memory's cap on them, and why
    #: (:func:`sarmitsuba.tracing.driver.workers.worker_plan`).
    workers: WorkerPlan | None = None
    #: ``max_depth = auto``: the probe's choice (:meth:`~sarmitsuba.tracing.driver.depth.DepthChoice.as_dict`):
    #: the depth the render will trace, why, and each order's share and predicted seconds;
    #: ``{"mode": "fixed", "depth": N}`` for a fixed depth.
    depth: dict | None = None


def scene_info(source: str | None, *, sensor_overrides: Mapping[str, Any] | None = None,
               integrator_overrides: Mapping[str, Any] | None = None,
               material_overrides: Mapping[str, Any] | None = None) -> SceneInfo:
    """Load and plan a scene, and summarise it; nothing is traced but, with ``max_depth = auto``,
    the probe that chooses the depth (:func:`~sarmitsuba.tracing.driver.depth.choose_depth`), which
    the render repeats exactly, and one sub-aperture for the seconds.

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
    loaded, choice = choose_depth(loaded, timed=True)                     # the render's probe, the render's depth
    if choice is not None:
        window = planning.fast_time_window(params, geometry, lo, hi, loaded.settings)
        footprint = planning.ray_footprint(params, geometry, lo, hi, loaded.settings, shape_boxes=loaded.shape_boxes)
    with warnings.catch_warnings(record=True) as rough:                   # reported in the result instead
        warnings.simplefilter("always", RoughSurfaceWarning)
        effects = active_effects(loaded)                                  # decided once, handed on
    radar = _radar_summary(params, geometry, window, lo, hi)
    radar = dataclasses.replace(radar, orbit_pass=_orbit_pass(params, loaded.offset), bistatic=_bistatic(params, geometry))
    cost = cost_estimate(loaded, geometry, window, footprint, effects)
    memory, ambiguous = memory_problem(cost, params), ambiguities(params)   # the render's Taylor window
    spec = (source, sensor_overrides, {**(integrator_overrides or {}), "max_depth": loaded.settings.max_depth},
            material_overrides)
    workers = plan_for(spec, loaded, effects, cost, available_memory())
    depth = choice.as_dict() if choice is not None else {"mode": "fixed", "depth": loaded.settings.max_depth}
    return SceneInfo(workers=workers, depth=depth, scene=_scene_size(loaded), radar=radar,
                     radiometry=_radiometry(params, radar.pulses_per_point, effects), effects=effects.listed,
                     cost=cost, ambiguities=ambiguous,
                     warnings=tuple(messages) + tuple(str(w.message) for w in rough)
                     + tuple(m for m in (memory, ambiguous and ambiguous.warning) if m))


# ============================================================================ scene
def _scene_size(loaded: LoadedScene) -> SceneSize:
    offset = loaded.offset
    center = np.asarray(loaded.params.scene_center) + offset
    return SceneSize(source=loaded.source, path=str(loaded.path or "built in Python"),
                     has_sar_sensor=loaded.has_sensor,
                     n_shapes=loaded.n_shapes, n_triangles=loaded.n_triangles, **_windows(loaded.scene),
                     bbox_min_m=_floats(loaded.bbox_lo + offset), bbox_max_m=_floats(loaded.bbox_hi + offset),
                     frame_offset_m=_floats(offset), scene_center_m=_floats(center),
                     materials=_materials(loaded.scene, loaded.params.frequency, loaded.params.incidence_angle))


def _windows(scene: Any) -> dict:
    """``windows`` of :class:`SceneSize`: two pane triangles a window."""
    panes = sum(s.face_count() for s in scene.shapes() if s.is_mesh() and (s.id() or "").endswith("-windows"))
    return {"windows": panes // 2}


def _materials(scene: Any, frequency: float, incidence_deg: float) -> tuple[MaterialInfo, ...]:
    """One :class:`MaterialInfo` per BSDF object, in order of first use."""
    bsdfs: dict[int, Any] = {}
    counts: dict[int, int] = {}
    for shape in scene.shapes():
        bsdf = shape.bsdf()
        bsdfs.setdefault(bsdf.id_key, bsdf)
        counts[bsdf.id_key] = counts.get(bsdf.id_key, 0) + 1
    return tuple(_material(bsdf, frequency, counts[key], incidence_deg) for key, bsdf in bsdfs.items())


def _material(bsdf: Any, frequency: float, n_shapes: int, incidence_deg: float) -> MaterialInfo:
    material = bsdf.material_at(frequency)
    itu_name = bsdf.itu_name
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
                 2: f"scattering_coefficient {math.sqrt(value / 4.0):g}",
                 3: describe_surface(bsdf.surface, eta, frequency, incidence_deg) if clutter_kind == 3 else ""
                 }[int(clutter_kind)]
    by_role = getattr(bsdf, "role_surfaces", {})        # a preset's role rules (docs/physics.md (RS8))
    for role in sorted(by_role):
        count = sum(1 for r in bsdf.shape_roles.values() if r == role)
        role_eta = bsdf.role_material_at(role, frequency).relative_permittivity
        text = (describe_surface(by_role[role], role_eta, frequency, incidence_deg) if by_role[role] is not None
                else "smooth")
        if bsdf.role_materials.get(role):
            text = f"as ITU {bsdf.role_materials[role]}, {text}"
        roughness = "; ".join(filter(None, [roughness if n_shapes > count * (len(by_role) > 0) else "",
                                            f"{count} {role} shape{'s' if count != 1 else ''}: {text}"]))
    return MaterialInfo(name=bsdf.name, kind=kind, description=description, model=material.model,
                        permittivity_real=None if eta is None else float(eta.real),
                        permittivity_imag=None if eta is None else float(eta.imag),
                        thickness_m=material.thickness,
                        rough=clutter_kind > 0 or any(v is not None for v in by_role.values()), roughness=roughness,
                        n_shapes=n_shapes)


# ============================================================================ radar
def _radar_summary(p: RadarParameters, geometry: AcquisitionGeometry, window: FastTimeWindow,
                   lo: np.ndarray, hi: np.ndarray) -> RadarSummary:
    rel = planning.box_corners(lo, hi) - geometry.scene_center
    along, across = rel @ geometry.track_direction, rel @ geometry.look_direction
    l_min, l_max = planning.echo_lengths(geometry.positions, lo, hi)   # as check_acquisition
    aperture_length, pulses_per_point = synthetic_aperture(p)
    sin_lo, sin_hi = p.beam_sines
    prf_min = p.doppler_bandwidth
    prf_max = 1.0 / ((l_max - l_min) / SPEED_OF_LIGHT + p.pulse_length)
    b = baseline(p)
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
        azimuth_resolution_m=p.azimuth_resolution / _sweep(p), azimuth_resolution_formula=_azimuth_formula(p),
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
        track_length_m=(p.n_pulses - 1) * p.velocity / p.prf, acquisition_time_s=(p.n_pulses - 1) / p.prf,
        track_offset_m=tuple(float(v) for v in p.track_offset), baseline_perpendicular_m=b.perpendicular,
        baseline_parallel_m=b.parallel, critical_baseline_m=b.critical,
        height_of_ambiguity_m=b.height_of_ambiguity if math.isfinite(b.height_of_ambiguity) else None,
        geo_origin=georef.of(p).as_tuple(), geo_origin_default=p.geo_origin is None,
        utm_epsg=int(georef.utm_crs(georef.of(p)).to_epsg()))


def _bistatic(p: RadarParameters, geometry: AcquisitionGeometry) -> dict | None:
    """:attr:`RadarSummary.bistatic` of a bistatic acquisition at mid-aperture, else None (B4)."""
    mid = len(geometry.positions) // 2
    return bistatic.bistatic_summary(p.bandwidth, geometry.positions[mid], geometry.rx_positions[mid],
                                     geometry.scene_center) if geometry.bistatic else None


def _orbit_pass(p: RadarParameters, offset: np.ndarray) -> dict | None:
    """:func:`sarmitsuba.core.orbit.pass_geometry` of an orbit's state vectors as a dict; None otherwise."""
    states = p.trajectory
    if not (isinstance(states, StateVectors) and states.closest_approach):
        return None
    return dataclasses.asdict(orbit.pass_geometry(states, georef.of(p), p.scene_center, offset))


def _sweep(p: RadarParameters) -> float:
    """``|V| / v_g`` of a stripmap orbit (its ground resolution is the beam's over it, (J7)); else 1."""
    return p.velocity / orbit.footprint_speed(p) if p.mode == "stripmap" else 1.0


def _azimuth_formula(p: RadarParameters) -> str:
    if _sweep(p) != 1.0:
        straight = _azimuth_formula(dataclasses.replace(p, trajectory="straight"))
        return (f"(that of a straight track) x v_g / |V| = {1.0 / _sweep(p):.4g}, the footprint's ground speed over "
                f"the orbit's (docs/physics.md (J7)); straight: {straight}")
    if p.trajectory == "circular":
        arc = max(p.n_pulses - 1, 1) * p.velocity / (p.prf * p.ground_range)
        return (f"lambda / (4 sin(theta) sin(min(a, pi) / 2)), arc a = (N - 1) v / (prf G) = {math.degrees(arc):.4g} deg "
                "(docs/physics.md (J1))")
    if p.mode == "spotlight":
        return (f"lambda / (2 dtheta), integration angle dtheta = N v / (prf R) = "
                f"{math.degrees(p.integration_angle):.3g} deg")
    if p.antenna_length > 0:
        return f"L_a / 2, antenna_length L_a = {p.antenna_length:g} m"
    if p.pattern_length > 0:
        return (f"L / 2, L = 0.443 lambda / sin(beta / 2) = {p.pattern_length:.3g} m: the aperture whose 3 dB "
                f"beamwidth is azimuth_beamwidth beta = {p.azimuth_beamwidth:g} deg (tapered beam)")
    return f"lambda / (2 beta), uniform beam of width beta = {p.azimuth_beamwidth:g} deg"


def _radiometry(p: RadarParameters, pulses: int, effects: EffectSet) -> RadiometrySummary | None:
    """Radar-equation figures for a 1 m^2 target at the scene centre; None when radiometry is off."""
    equation = radar_equation(p, effects)
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


def _db(x: float) -> float:
    return 10.0 * math.log10(x)


def _floats(v: np.ndarray) -> tuple[float, float, float]:
    return tuple(float(x) for x in v)
