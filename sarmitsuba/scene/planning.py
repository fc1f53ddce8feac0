"""Planning an acquisition before tracing: defaults from the scene, fast-time window, ray footprint.

All functions are pure (NumPy, float64) and take the scene's axis-aligned bounding box as
``(lo, hi)``, each float64 [3] in metres.
"""
from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import replace

import numpy as np
from scipy import fft as sp_fft

from ..core.constants import SPEED_OF_LIGHT
from ..core.orbit import footprint_speed
from ..core.radar import VALID_RANGES, ParameterError, RadarParameters
from ..core.geometry import AcquisitionGeometry, aperture_axis, pulse_times, track_frame
from ..core.trajectory import StateVectors, from_state_vectors
from .trace_inputs import FastTimeWindow, RayFootprint, Refinement, TraceSettings
from .track_checks import aperture_note, motion_error_note, receiver_doppler_note, steering_note

__all__ = ["resolve_parameters", "state_vector_parameters", "fast_time_window", "ray_footprint", "ray_spacing", "scatterer_spacing",
           "project_to_aim_plane", "box_corners", "check_ray_spacing", "nearest_range",
           "phase_limited_size", "PATCH_PHASE", "PATCH_PHASE_MAX", "TUBE_PHASE_MAX", "echo_lengths", "check_acquisition", "check_ati_baseline", "AcquisitionWarning",
           "beam_offsets"]


class AcquisitionWarning(UserWarning):
    """Radar settings the user may mean but should know about (ambiguities, an empty beam)."""

#: Samples kept beyond the nearest and farthest scene delay, for the compressed pulse's tails.
WINDOW_MARGIN_SAMPLES = 64


def box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 8 corners of an axis-aligned box, float64 [8, 3]."""
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def resolve_parameters(params: RadarParameters, lo: np.ndarray, hi: np.ndarray) -> RadarParameters:
    """Fill in ``scene_center`` (bbox centre at its lowest z) and ``n_pulses`` (0 = automatic).

    The automatic aperture sweeps the beam over the scene: its length is the scene's
    along-track extent plus the beam footprint at the farthest scene point, plus twice the
    along-track offset of the scene's middle from ``scene_center`` (the track is centred on
    ``scene_center``, so a scene given an off-centre ``scene_center`` is still swept from end
    to end), ``n_pulses = ceil(length * prf / v) + 1``, ``v`` the beam footprint's speed
    (``velocity``; an orbit's, :func:`~sarmitsuba.core.orbit.footprint_speed`). A circular trajectory flies its
    ``arc_deg`` (docs/physics.md (J1)); state vectors set the platform parameters and their span
    the pulses (:func:`state_vector_parameters`, (J2)).
    """
    if params.scene_center is None:
        params = replace(params, scene_center=(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), float(lo[2])))
    if isinstance(params.trajectory, StateVectors):
        params = state_vector_parameters(params)
    elif params.trajectory == "circular":
        params = _circular_pulses(params)
    if params.n_pulses == 0 and params.mode == "spotlight":
        angle = params.wavelength / (2.0 * params.slant_range_resolution)
        length = angle * params.slant_range
        params = replace(params, n_pulses=int(math.ceil(length * params.prf / params.velocity)) + 1)
    if params.n_pulses == 0:
        track, look = track_frame(params)
        rel = box_corners(lo, hi) - np.asarray(params.scene_center)
        along = rel @ track
        a_lo, a_hi = beam_offsets(params, lo, hi)
        # the track is centred on scene_center: a scene off it along track needs twice its offset more
        offset = abs(0.5 * float(along.max() + along.min()))
        length = float(along.max() - along.min()) + (a_hi - a_lo) + 2.0 * offset
        # at the beam footprint's speed: an orbit's is 7-11 % below the satellite's (J7)
        params = replace(params, n_pulses=int(math.ceil(length * params.prf / footprint_speed(params))) + 1)
    return params


def _circular_pulses(params: RadarParameters) -> RadarParameters:
    """``n_pulses`` of a circular trajectory (J1): ``round(2 pi G prf / v)`` for the full circle,
    ``floor(arc G prf / v) + 1`` for an arc; a given ``n_pulses`` must not exceed the full circle,
    nor come with an ``arc_deg`` below 360 (which it would override)."""
    full = max(1, round(2.0 * math.pi * params.ground_range * params.prf / params.velocity))
    if params.n_pulses > full:
        raise ParameterError(f"n_pulses = {params.n_pulses} with trajectory = 'circular' flies more than the full circle "
                             f"of {full} pulses (radius {params.ground_range:.1f} m at {params.velocity:g} m/s, prf "
                             f"{params.prf:g} Hz): use at most {full}, or n_pulses = 0 and arc_deg")
    if params.n_pulses > 0 and params.arc_deg < 360.0:     # the arc would be ignored: n_pulses sets it
        flown = math.degrees((params.n_pulses - 1) * params.velocity / (params.prf * params.ground_range))
        raise ParameterError(f"n_pulses = {params.n_pulses} and arc_deg = {params.arc_deg:g} deg both set the arc of "
                             f"trajectory = 'circular' (n_pulses flies {flown:.4g} deg at {params.velocity:g} m/s, prf "
                             f"{params.prf:g} Hz, radius {params.ground_range:.1f} m): give one of them (n_pulses = 0 "
                             "flies arc_deg)")
    if params.n_pulses > 0:
        return params
    if params.arc_deg >= 360.0:
        return replace(params, n_pulses=full)
    arc = math.radians(params.arc_deg) * params.ground_range
    return replace(params, n_pulses=int(math.floor(arc * params.prf / params.velocity)) + 1)


def state_vector_parameters(params: RadarParameters) -> RadarParameters:
    """The platform parameters of a trajectory of state vectors, from its mid-aperture state
    (docs/physics.md (J2)): ``altitude`` the antenna's height above the scene centre,
    ``incidence_angle`` the closest-approach incidence ``atan(G / H)``, ``G`` the horizontal distance
    of the scene centre from the line through the antenna along its horizontal velocity (an
    along-track offset, a squint's ``R0 tan(squint)``, does not count),
    ``velocity`` its speed, ``heading`` the direction of the aperture's least-squares line
    (:func:`~sarmitsuba.core.geometry.aperture_axis`, the image frame's azimuth axis; the velocity
    at mid-aperture follows any sway there), ``look_side`` the side the scene centre lies on; ``n_pulses`` (when automatic) every pulse the span holds.

    Raises ParameterError when the mid-aperture antenna is not above the scene centre, stands
    over it (no incidence) or moves vertically."""
    states = params.trajectory
    path = from_state_vectors(states)
    t_lo, t_hi = path.span
    n = params.n_pulses or int(math.floor((t_hi - t_lo) * params.prf + 1e-9)) + 1
    mid = 0.5 * (t_lo + t_hi)
    if states.closest_approach:          # an orbit: the aperture about the closest approach (J6)
        n = params.n_pulses
        mid = float(pulse_times(replace(params, n_pulses=max(n, 1)), path)[max(n, 1) // 2])
    antenna, v = path.position(mid), path.velocity(mid)
    if math.hypot(v[0], v[1]) > 0 and n >= 2:       # the image frame's axis: the aperture's line fit (J2)
        times = pulse_times(replace(params, n_pulses=n), path)
        v = float(np.linalg.norm(v)) * aperture_axis(path.position(times), times)
    rel = np.asarray(params.scene_center, float) - antenna
    horizontal = math.hypot(v[0], v[1])
    along = (rel[0] * v[0] + rel[1] * v[1]) / horizontal if horizontal > 0 else 0.0
    height = -float(rel[2])
    ground = float(math.sqrt(max(rel[0] ** 2 + rel[1] ** 2 - along ** 2, 0.0)))   # from the nadir track
    where = f"the state vectors {states.source} put the mid-aperture antenna (t = {mid:.6g} s) at {np.round(antenna, 2).tolist()} m"
    if not (height >= VALID_RANGES["altitude"].lo and ground > 1e-6 * height and math.hypot(v[0], v[1]) > 0):
        problem = ("not above the scene centre" if height < VALID_RANGES["altitude"].lo else
                   "over the scene centre or on its ground track, ahead or behind (no incidence angle)"
                   if ground <= 1e-6 * height else
                   "moving vertically")
        fix = ("check the frame (metres, z up, the scene's own) or scene_center" if not states.closest_approach else
               f"an orbit is carried into the frame at geo_origin = {params.geo_origin or 'the placeholder 0, 0, 0'}, "
               "so set geo_origin to the scene's latitude, longitude and height, beside the orbit's ground track "
               "and in its view")
        raise ParameterError(f"{where}, {problem} {np.round(params.scene_center, 2).tolist()} m: a side-looking SAR "
                             f"flies above the scene and to its side, moving horizontally; {fix}")
    left = v[0] * rel[1] - v[1] * rel[0] > 0
    return replace(params, n_pulses=n, altitude=height, incidence_angle=math.degrees(math.atan2(ground, height)),
                   velocity=float(np.linalg.norm(v)), heading=math.degrees(math.atan2(v[1], v[0])),
                   look_side="left" if left else "right")


def _closest_ranges(params: RadarParameters, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    track, look = track_frame(params)
    center = np.asarray(params.scene_center, float)
    mid = center - params.ground_range * look + np.array([0.0, 0.0, params.altitude])
    rel = box_corners(lo, hi) - mid
    rel -= np.outer(rel @ track, track)         # distance at closest approach
    return np.linalg.norm(rel, axis=1)


def beam_offsets(params: RadarParameters, lo: np.ndarray, hi: np.ndarray) -> tuple[float, float]:
    """Along-track interval ``(a_lo, a_hi)`` [m], relative to the antenna, that the stripmap beam
    covers at the scene's closest-approach ranges ``R0``: ``R0 tan(squint -/+ beta / 2)``,
    bounded over the near and far range (ray tube aim and automatic aperture length).
    At broadside it is ``-/+ R_far tan(beta / 2)``."""
    ranges = _closest_ranges(params, lo, hi)
    r = (max(0.0, float(ranges.min()) - float(np.linalg.norm(hi - lo))), float(ranges.max()))
    half, squint = params.traced_half_angle, math.radians(params.squint)
    return (min(x * math.tan(squint - half) for x in r), max(x * math.tan(squint + half) for x in r))


#: Extra two-way length allowed per bounce beyond the first, as a fraction of the scene box's
#: diagonal. A bounce inside the box can add up to a whole diagonal, but sizing the window for
#: that would lengthen it by ``max_depth - 1`` diagonals for paths that carry little energy
#: (each bounce multiplies by a reflection coefficient below 1 and most later bounces stay close
#: to the earlier ones: corners, wall-ground); 10 % is that compromise. Longer paths are not
#: clamped into the edge bins: their terms are dropped and their energy is added to
#: ``TraceResult.energy_outside_window`` (copied into the ``RenderSummary``), and
#: :func:`check_window_energy` warns when it exceeds :data:`OUTSIDE_ENERGY_WARNING` of the energy
#: inside (deep canyons, high ``max_depth``).
EXTRA_BOUNCE_FRACTION = 0.1
#: Fraction of the in-window energy that may fall outside the fast-time window before
#: :func:`check_window_energy` warns: 1e-3 (-30 dB), below which the missing returns change no
#: image pixel by more than the ray lattice's own noise (about -30 dB, benchmarks/subaperture.py).
OUTSIDE_ENERGY_WARNING = 1e-3


def fast_time_window(params: RadarParameters, geometry: AcquisitionGeometry, lo: np.ndarray,
                     hi: np.ndarray, settings: TraceSettings) -> FastTimeWindow:
    """Fast-time window covering every scene point from every pulse, plus margins.

    Nearest delay: twice the distance from the antenna to the box; farthest: twice the
    farthest corner, plus ``(max_depth - 1) * EXTRA_BOUNCE_FRACTION`` (10 %) of the box
    diagonal for multi-bounce paths longer than the direct one (energy still falling outside is reported by the
    tracer, never clamped into edge bins), plus margins for the compressed pulse's tails
    and, for chirped output, half a pulse length. The sample count is a fast FFT length.
    """
    l_min, l_max = echo_lengths(geometry.positions, lo, hi, geometry.rx_positions)
    l_max += (settings.depth - 1) * EXTRA_BOUNCE_FRACTION * float(np.linalg.norm(hi - lo))
    margin = WINDOW_MARGIN_SAMPLES / params.sampling_rate
    if params.output == "raw":                 # chirps centred on their delay: +-T_p / 2
        margin += 0.5 * params.pulse_length
    t0 = l_min / SPEED_OF_LIGHT - margin
    n = int(math.ceil((l_max / SPEED_OF_LIGHT + margin - t0) * params.sampling_rate))
    return FastTimeWindow(t0=t0, fs=params.sampling_rate, n_samples=sp_fft.next_fast_len(n),
                          oversample=settings.oversample)


def echo_lengths(positions: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 rx_positions: np.ndarray | None = None) -> tuple[float, float]:
    """Shortest and longest two-way lengths ``(L_min, L_max)`` [m, float] from the track to the
    scene's box (direct paths): ``positions`` float64 [n_pulses, 3] antenna positions at
    transmission and ``rx_positions`` at reception (default: the same), ``lo`` and ``hi`` float64
    [3] the box. ``L_min`` is the distance from the nearest pulse's antennas to the box, both
    ways; ``L_max`` the farthest corner's two-way length from the first, middle and last pulse
    (a straight track's extremes), or from every pulse of a track that is not straight."""
    rx = positions if rx_positions is None else rx_positions
    l_min = float((np.linalg.norm(positions - np.clip(positions, lo, hi), axis=1)
                   + np.linalg.norm(rx - np.clip(rx, lo, hi), axis=1)).min())
    corners = box_corners(lo, hi)
    pick = [0, -1, len(positions) // 2]
    chord = positions[-1] - positions[0]
    middle = positions[len(positions) // 2] - positions[0]
    if np.linalg.norm(np.cross(chord, middle)) > 1e-6 * max(float(np.linalg.norm(chord)) ** 2, 1e-12):
        pick = np.unique(np.linspace(0, len(positions) - 1, 4096).round().astype(int))
    two_way = (np.linalg.norm(corners[None] - positions[pick][:, None], axis=2)
               + np.linalg.norm(corners[None] - rx[pick][:, None], axis=2))
    return l_min, float(two_way.max())


def ray_spacing(params: RadarParameters, settings: TraceSettings) -> tuple[float, float]:
    """Ray-tube lattice spacing ``(along track, ground range)`` [m] on the aim plane.

    With the ``ray_spacing`` setting ``s``: square tubes ``s`` wide normal to the line of sight,
    ``(s, s / cos(theta))``. Automatic: one tube per resolution cell, ``(rho_az, rho_gr)``. Each
    tube's PO return is exact across the band (docs/physics.md (PO2)), clutter has its own
    lattice (:func:`scatterer_spacing`) and small objects get finer tubes (:func:`ray_footprint`),
    so the default tubes only need to place large geometry (edges, shadow and layover
    boundaries) to within a resolution cell."""
    if settings.ray_spacing > 0:
        return settings.ray_spacing, settings.ray_spacing / math.cos(math.radians(params.incidence_angle))
    return params.azimuth_resolution, params.ground_range_resolution


#: Shapes whose bounding-box diagonal is below this many default tubes (resolution cells, whatever
#: the ``ray_spacing`` setting) are refined (docs/physics.md (T2)). Measured at the default spacing
#: without refinement (X band, 45 deg, 1 m tubes): 1-2 m dihedrals and trihedrals are 3 to 40 dB
#: off, 3 m ones up to 1.7 dB, 4-6 m ones (6-8 tubes) within 0.7 dB of the refined result; larger
#: shapes (buildings) gain nothing from it.
SMALL_OBJECT_TUBES = 8

#: Automatic clutter-scatterer cell size in units of ``sqrt(rho_slant rho_az)``.
SCATTERER_CELL = 0.8


def scatterer_spacing(params: RadarParameters, settings: TraceSettings) -> float:
    """Cell size [m] of the clutter scatterers' surface lattice: the setting, or
    ``0.8 sqrt(rho_slant rho_az)``: about ``1.6 / sin(theta)`` scatterers per ground resolution
    cell (2.2 at 45 deg). The jittered lattice and the impulse response's sidelobes make that
    fully developed speckle (intensity contrast 0.95-1.0 measured for 1.7 to 10 scatterers
    per cell; docs/physics.md (C)). It does not depend on the ray spacing, so
    denser rays see the same scatterers."""
    if settings.scatterer_spacing > 0:
        return settings.scatterer_spacing
    return SCATTERER_CELL * math.sqrt(params.slant_range_resolution * params.azimuth_resolution)


#: The largest phase [rad] a patch's quadratic part may reach at its corners, seen from the
#: nearest antenna position: ``k P^2 / (2 R) <= PATCH_PHASE`` (docs/physics.md (M1)).
PATCH_PHASE = math.pi / 8
#: The largest quadratic phase [rad] at the corners of a patch whose ``patch_size`` the user sets
#: (docs/physics.md (M1')): ``pi / 4``, twice the automatic patch's. A split edge end
#: (docs/physics.md (M5)) is evaluated with the phase gradient at its own point while its regime
#: was decided at the edge's midpoint; the two differ by up to ``2 k P^2 / (2 R)`` in ``alpha``, so
#: at ``pi / 4`` an end whose midpoint was split (``|alpha| >= 2``) keeps ``|alpha| >= 2 - pi / 2``
#: and its ``1 / (u . a)`` stays bounded. Larger patches let it cross zero: the dihedral at
#: ``P = 7 m`` (3.5 rad) gave raw data 440 times too strong, a plate with a 10 m box at
#: ``P = 10 m`` 1e27 times.
PATCH_PHASE_MAX = math.pi / 4
#: The largest quadratic phase [rad] across a ray tube whose ``ray_spacing`` the user sets, at its
#: corners (docs/physics.md (T1)): ``pi / 2``. A tube's tile is integrated with a linear phase
#: (PO2); measured on the dihedral's tiles (``lit_regions = tiles``), tubes up to ``pi / 2`` keep
#: the raw energy within 1.4 dB of the automatic spacing's, 5.5 m (2.1 rad) loses 3.9 dB, 6.6 m
#: (pi) gives non-finite samples and 100 m none at all.
TUBE_PHASE_MAX = math.pi / 2


def nearest_range(geometry: AcquisitionGeometry, lo: np.ndarray, hi: np.ndarray) -> float:
    """The antenna's closest distance [m] to the scene's box over all pulses (at least 1 m)."""
    near = float(np.min(np.linalg.norm(np.clip(geometry.positions[:, None], lo, hi) - geometry.positions[:, None],
                                       axis=2)))
    return max(near, 1.0)


def phase_limited_size(params: RadarParameters, near: float, phase: float) -> float:
    """The width [m] whose quadratic phase at its corners reaches ``phase`` [rad] at range
    ``near`` [m]: ``sqrt(2 R phase / k)``, ``k = 2 pi f / c`` (docs/physics.md (M1))."""
    k = 2.0 * math.pi * params.frequency / SPEED_OF_LIGHT
    return math.sqrt(2.0 * near * phase / k)


def patch_size(params: RadarParameters, geometry: AcquisitionGeometry, lo: np.ndarray, hi: np.ndarray,
               settings: TraceSettings, cell: float) -> float:
    """Side [m] of the patches fixed on every face (docs/physics.md (M1)): the setting, or the
    slant-range resolution, kept below the size whose phase departs from linear by
    :data:`PATCH_PHASE` at its corners, ``sqrt(2 R_near PATCH_PHASE / k)`` (``R_near`` the
    antenna's closest distance to the scene's box), and rounded to a whole number (at least one)
    of scatterer cells ``cell``, so that each patch holds whole cells of the clutter lattice.

    Raises ParameterError for a ``patch_size`` setting whose rounded patch exceeds both the
    automatic one and :data:`PATCH_PHASE_MAX`'s size, naming the largest valid value (docs/physics.md (M1'))."""
    near = nearest_range(geometry, lo, hi)
    automatic = cell * max(1, round(min(params.slant_range_resolution,
                                        phase_limited_size(params, near, PATCH_PHASE)) / cell))
    if settings.patch_size <= 0:
        return automatic
    size = cell * max(1, round(settings.patch_size / cell))
    largest = max(automatic, cell * math.floor(phase_limited_size(params, near, PATCH_PHASE_MAX) / cell))
    if size > largest * (1.0 + 1e-9):
        raise ParameterError(_phase_refusal(params, near, f"patch_size = {settings.patch_size:g} m gives patches "
                                            f"{size:g} m wide", size, "P", PATCH_PHASE_MAX,
                                            "where the edge terms break down (docs/physics.md (M1'))",
                                            "patch_size", largest, "automatic"))
    return size


def _phase_refusal(params: RadarParameters, near: float, what: str, width: float, symbol: str, limit: float,
                   why: str, name: str, largest: float, automatic: str) -> str:
    """The one-line refusal of a width whose quadratic phase ``k w^2 / (2 R_near)`` exceeds ``limit``."""
    k = 2.0 * math.pi * params.frequency / SPEED_OF_LIGHT
    return (f"{what}, whose phase departs from linear by {k * width ** 2 / (2.0 * near):.3g} rad at their corners "
            f"(k {symbol}^2 / (2 R_near), R_near = {near:.1f} m, {params.frequency / 1e9:g} GHz): more than "
            f"{limit:.3g} rad, {why}; valid values for this scene are 0 < {name} <= {largest:.4g} m; use {name} = 0 "
            f"({automatic}) or a value in that range")


def check_ray_spacing(params: RadarParameters, geometry: AcquisitionGeometry, lo: np.ndarray, hi: np.ndarray,
                      settings: TraceSettings) -> None:
    """Raise ParameterError for a ``ray_spacing`` setting wider than both the automatic tube (one
    resolution cell normal to the line of sight, ``max(rho_az, rho_gr cos(theta))``) and the
    width whose quadratic phase reaches :data:`TUBE_PHASE_MAX` at the nearest range (docs/physics.md (T1))."""
    if settings.ray_spacing <= 0:
        return
    near = nearest_range(geometry, lo, hi)
    cell = max(params.azimuth_resolution,
               params.ground_range_resolution * math.cos(math.radians(params.incidence_angle)))
    largest = max(cell, phase_limited_size(params, near, TUBE_PHASE_MAX))
    if settings.ray_spacing > largest * (1.0 + 1e-9):
        raise ParameterError(_phase_refusal(params, near, f"ray_spacing = {settings.ray_spacing:g} m gives ray tubes",
                                            settings.ray_spacing, "s", TUBE_PHASE_MAX, "beyond which a tube's "
                                            "linear-phase integral is wrong in amplitude (docs/physics.md (T1))",
                                            "ray_spacing", largest, "automatic, one tube per resolution cell"))


def project_to_aim_plane(points: np.ndarray, antenna: np.ndarray, z0: float) -> np.ndarray:
    """Where the rays from ``antenna`` through ``points`` meet the horizontal plane ``z = z0``.

    ``points`` float64 [..., 3], ``antenna`` float64 [3] or broadcastable; returns float64
    [..., 3]. Raises ParameterError for points at or above the antenna (no downward ray
    reaches them)."""
    points = np.asarray(points, np.float64)
    height = antenna[..., 2] - points[..., 2]
    if np.any(height <= 1e-6 * np.maximum(np.abs(antenna[..., 2] - z0), 1.0)):
        raise ParameterError("the scene reaches the antenna's height or above it: rays aimed down from the antenna "
                             "cannot reach it; raise the sensor's altitude or lower the geometry")
    t = (antenna[..., 2] - z0) / height
    return antenna + (points - antenna) * t[..., None]


def _aim_extent(params: RadarParameters, geometry: AcquisitionGeometry, lo: np.ndarray, hi: np.ndarray):
    """Along-track limits per pulse [n_pulses, 2] and the ground-range interval of the box's
    corners projected from every pulse's antenna onto the aim plane (relative to the scene centre)."""
    origin = np.asarray(geometry.scene_center, float)
    corners = box_corners(lo, hi)
    aim = project_to_aim_plane(corners[None, :, :], geometry.positions[:, None, :], origin[2])
    rel = aim - origin
    along = rel @ geometry.track_direction                       # [n_pulses, 8]
    across = rel @ geometry.look_direction
    return np.stack([along.min(axis=1), along.max(axis=1)], axis=1), (float(across.min()), float(across.max()))


def ray_footprint(params: RadarParameters, geometry: AcquisitionGeometry, lo: np.ndarray,
                  hi: np.ndarray, settings: TraceSettings, shape_boxes: np.ndarray | None = None) -> RayFootprint:
    """World-fixed lattice of ray aim points covering everything the beam sees (see
    :class:`~sarmitsuba.scene.trace_inputs.RayFootprint`; docs/physics.md (T1), (T2)).

    Every corner of the scene's box is projected from every pulse's antenna onto the aim plane
    (horizontal, through the scene centre), so that a ray reaches each point in view, however
    high or low: in ground range the lattice covers the projections of all pulses, along track
    each pulse's own (a point at height ``h`` and horizontal distance ``G + a`` from the
    antenna projects ``(G + a) h / (H - h)`` beyond itself). Spacing: :func:`ray_spacing`.
    Per pulse, only the overlap of the traced beam with that
    pulse's limits is sampled; on a curved track, whose beam turns across the lattice, each pulse's
    whole projection (the kernel casts only the tubes in a pulse's beam).

    ``shape_boxes`` (float64 [n_shapes, 2, 3], each shape's bounding box) switches the
    refinement around small objects on: a shape whose box diagonal ``D`` is below
    :data:`SMALL_OBJECT_TUBES` default tubes (resolution cells) is traced with tubes about
    ``D / tubes_per_object`` wide (at least a quarter wavelength; none when the lattice is that
    fine already), over the cells its box and its mirror image below the aim plane project onto.
    """
    check_ray_spacing(params, geometry, lo, hi, settings)
    s, spacing_range = ray_spacing(params, settings)
    origin = np.asarray(params.scene_center, float)
    track, look = geometry.track_direction, geometry.look_direction
    limits, (g_lo, g_hi) = _aim_extent(params, geometry, lo, hi)
    limits = limits + np.array([-s, s])
    g_min = math.floor((g_lo - spacing_range) / spacing_range) * spacing_range  # lattice anchored at the scene
    n_range = int(math.ceil((g_hi + spacing_range - g_min) / spacing_range)) + 1  # centre, not at the box edge
    # the traced beam on the aim plane: along-track offsets R tan(phi) from the antenna, phi between
    # the beam's sines, for the perpendicular distances R of the aim rows
    height = geometry.positions[0, 2] - origin[2]
    ant_across = float((geometry.positions[0] - origin) @ look)
    r_perp = np.hypot(height, np.array([g_min, g_min + n_range * spacing_range]) - ant_across)
    tangents = np.tan(np.arcsin(np.array(params.beam_sines if params.mode == "stripmap" else
                                         (-math.sin(params.traced_half_angle), math.sin(params.traced_half_angle)))))
    a_lo, a_hi = float((r_perp[:, None] * tangents[0]).min()), float((r_perp[:, None] * tangents[1]).max())
    ant_along = (geometry.positions - origin) @ track
    if params.mode == "spotlight":        # the beam stays on the scene centre
        ant_along = np.zeros_like(ant_along)
        a_lo, a_hi = 1.1 * a_lo, 1.1 * a_hi
    if geometry.curved:                   # the beam turns with the track: every pulse's whole projection,
        ant_along, a_lo, a_hi = np.zeros_like(ant_along), -np.inf, np.inf     # the kernel culls by beam
    lo_p = np.maximum(ant_along + a_lo, limits[:, 0]) - s
    hi_p = np.minimum(ant_along + a_hi, limits[:, 1]) + s
    k0 = np.floor(lo_p / s).astype(np.int64)
    seen = hi_p > lo_p
    n_azimuth = int(np.max(np.ceil(hi_p[seen] / s) - k0[seen])) + 1 if np.any(seen) else 1
    cell = scatterer_spacing(params, settings)
    footprint = RayFootprint(origin=origin, track=track, look=look, spacing_azimuth=s, spacing_range=spacing_range,
                             range_min=float(g_min), n_azimuth=n_azimuth, n_range=n_range, k0=k0,
                             along_limits=limits, scatterer_spacing=cell,
                             patch_size=patch_size(params, geometry, lo, hi, settings, cell))
    if shape_boxes is None or settings.tubes_per_object == 0:
        return footprint
    return dataclasses.replace(footprint, refinements=_refinements(params, geometry, footprint, shape_boxes,
                                                                   settings.tubes_per_object, (a_lo, a_hi)))


def _refinements(params: RadarParameters, geometry: AcquisitionGeometry, fp: RayFootprint, shape_boxes: np.ndarray,
                 tubes: int, beam: tuple[float, float]) -> tuple[Refinement, ...]:
    """Refined cells per subdivision factor for shapes smaller than :data:`SMALL_OBJECT_TUBES`
    default tubes (resolution cells, whatever ``ray_spacing`` is): ``tubes`` tubes across them
    (docs/physics.md (T2))."""
    cos_theta = math.cos(math.radians(params.incidence_angle))
    # the tubes' largest width normal to the line of sight, and that of the default tubes
    s = max(fp.spacing_azimuth, fp.spacing_range * cos_theta)
    cell = max(params.azimuth_resolution, params.ground_range_resolution * cos_theta)
    smallest = params.wavelength / 4.0
    factor = {}
    ant_along = (geometry.positions - fp.origin) @ fp.track
    for box_lo, box_hi in np.asarray(shape_boxes, float).reshape(-1, 2, 3):
        size = float(np.linalg.norm(box_hi - box_lo))
        if not (np.all(np.isfinite(box_lo)) and size < SMALL_OBJECT_TUBES * cell):
            continue
        m = int(math.ceil(s * tubes / max(size, 1e-9)))
        m = max(1, min(m, int(s / smallest)))
        if m < 2:
            continue
        corners = box_corners(box_lo, box_hi)
        points = corners
        if box_lo[2] - fp.origin[2] < size:      # near the ground: its mirror image too (ground bounces)
            points = np.concatenate([corners, corners * np.array([1.0, 1.0, -1.0])
                                     + np.array([0.0, 0.0, 2.0 * fp.origin[2]])])
        along = (points - fp.origin) @ fp.track
        # the pulses whose beam can hold the object: projections from the first and last of them
        first, last = along.min() - beam[1] - s, along.max() - beam[0] + s
        pulses = np.flatnonzero((ant_along >= first) & (ant_along <= last))
        if params.mode == "spotlight" or pulses.size == 0 or geometry.curved:
            pulses = np.arange(len(ant_along))
        ends = geometry.positions[[pulses[0], pulses[-1]]]
        if geometry.curved:               # the projections do not move linearly: from every pulse
            ends = geometry.positions[np.unique(np.linspace(0, len(pulses) - 1, 512).round().astype(int))]
        aim = project_to_aim_plane(points[None, :, :], ends[:, None, :], fp.origin[2]) - fp.origin
        a, g = aim @ fp.track, aim @ fp.look
        # every coarse cell the projections touch (they are exact at the corners; the rays in
        # between move linearly with the antenna)
        i = np.arange(math.floor(a.min() / fp.spacing_azimuth), math.floor(a.max() / fp.spacing_azimuth) + 1)
        j = np.arange(max(0, math.floor((g.min() - fp.range_min) / fp.spacing_range)),
                      min(fp.n_range, math.floor((g.max() - fp.range_min) / fp.spacing_range) + 1))
        for ii in i:
            for jj in j:
                factor[ii, jj] = max(factor.get((ii, jj), 0), m)
    groups = {}
    for cell, m in factor.items():
        groups.setdefault(m, []).append(cell)
    return tuple(Refinement(m, np.array(sorted(cells), np.int64)) for m, cells in sorted(groups.items()))


def check_ati_baseline(params: RadarParameters, geometry: AcquisitionGeometry) -> None:
    """Refuse an along-track baseline ``d`` (``ati_baseline`` [m]) no shorter than the track the
    pulses fly: the trailing channel's phase centres (the lead's moved back by ``d``, docs/physics.md
    (V6)) would share no stretch of track with the lead's, so its aperture would lie wholly outside
    the lead's and the interferogram compare two different looks (or an empty channel).
    Raises ParameterError naming ``ati_baseline``, the track's length and the largest baseline."""
    d = float(params.ati_baseline)
    if d <= 0.0:
        return
    steps = np.diff(np.asarray(geometry.positions, np.float64), axis=0)
    track = float(np.sum(np.sqrt(np.einsum("ij,ij->i", steps, steps))))
    if d >= track:
        raise ParameterError(f"ati_baseline = {d:g} m is not shorter than the track the {params.n_pulses} pulses fly "
                             f"({track:.3g} m): the trailing channel's aperture would not overlap the leading one's; "
                             f"give ati_baseline below {track:.3g} m (along-track baselines are typically a few "
                             f"metres), or fly more pulses")


def check_acquisition(params: RadarParameters, geometry: AcquisitionGeometry, window: FastTimeWindow,
                      lo: np.ndarray, hi: np.ndarray) -> list[str]:
    """Warn (:class:`AcquisitionWarning`) about settings that give ambiguities or an empty image.

    - azimuth ambiguities: ``prf`` below the Doppler bandwidth ``4 v sin(beta / 2) / lambda``
      (stripmap; Cumming and Wong 2005, eq. 4.36);
    - range ambiguities: the echo window (scene depth plus pulse length) longer than the pulse
      repetition interval, i.e. ``prf > c / (2 swath depth)``: echoes of consecutive pulses
      overlap (Curlander and McDonough 1991, sec. 6.5);
    - a scene outside the beam footprint: no ray can hit it;
    - a motion error too large to be focused without the true track (:func:`motion_error_note`);
    - a trajectory file too short for the synthetic aperture (:func:`aperture_note`);
    - spotlight pulses steered beyond :data:`~sarmitsuba.scene.track_checks.MAX_STEERING_DEG` (:func:`steering_note`);
    - a receiver whose motion spreads the Doppler band beyond the PRF (:func:`receiver_doppler_note`).

    Returns the messages (also issued as warnings). Raises ParameterError for an ``ati_baseline``
    no shorter than the track (:func:`check_ati_baseline`).
    """
    check_ati_baseline(params, geometry)
    messages = [note for note in (motion_error_note(params), aperture_note(params, geometry),
                                  steering_note(params, geometry), receiver_doppler_note(params, geometry, lo, hi)) if note]
    if params.mode == "stripmap" and params.prf < params.doppler_bandwidth:
        messages.append(f"prf = {params.prf:g} Hz is below the Doppler bandwidth {params.doppler_bandwidth:.1f} Hz "
                        f"(azimuth_beamwidth {params.azimuth_beamwidth:.3g} deg, velocity {params.velocity:g} m/s): "
                        "azimuth ambiguities (ghosts) will appear; raise prf or narrow the beam")
    l_min, l_max = echo_lengths(geometry.positions, lo, hi)
    echo = (l_max - l_min) / SPEED_OF_LIGHT + params.pulse_length      # receive time of one pulse's echoes
    if echo > 1.0 / params.prf:
        messages.append(f"prf = {params.prf:g} Hz exceeds 1 / (echo duration) = {1.0 / echo:.1f} Hz "
                        f"(scene depth {0.5 * (l_max - l_min):.0f} m slant plus pulse_length {params.pulse_length:g} s): "
                        "echoes of consecutive pulses overlap (range ambiguities), which this simulation does not "
                        "model; lower prf or shrink the scene")
    if geometry.curved:                   # the beam follows the scene centre (circular) or the track
        return _warned(messages)
    rel = box_corners(lo, hi) - geometry.scene_center
    along = rel @ geometry.track_direction
    across = rel @ geometry.look_direction
    a_lo, a_hi = beam_offsets(params, lo, hi)
    track = (geometry.positions - geometry.scene_center) @ geometry.track_direction
    if params.mode == "spotlight":        # the beam follows the scene centre
        a_lo, a_hi, track = -0.5 * (a_hi - a_lo), 0.5 * (a_hi - a_lo), np.zeros(1)
    if (along.max() < track.min() + a_lo or along.min() > track.max() + a_hi
            or across.max() < -params.ground_range * 0.99):
        messages.append(f"the scene (bounding box {lo.round(1).tolist()} .. {hi.round(1).tolist()}) lies outside the "
                        f"beam footprint around scene_center {np.round(geometry.scene_center, 1).tolist()}: "
                        "the raw data and image will be empty")
    return _warned(messages)


def _warned(messages: list[str]) -> list[str]:
    for message in messages:
        warnings.warn(message, AcquisitionWarning, stacklevel=3)
    return messages


def check_window_energy(outside: float, inside: float, max_depth: int) -> str | None:
    """Warn (:class:`AcquisitionWarning`) when returns carrying more than
    :data:`OUTSIDE_ENERGY_WARNING` of the in-window energy fell outside the fast-time window.

    Parameters
    ----------
    outside, inside : float, m^2
        ``TraceResult.energy_outside_window`` and the energy of the returns deposited
        (``TraceResult.energy_per_order.sum()``).
    max_depth : int
        The ``sbr`` bounce limit, named in the advice.

    Returns the message (also issued as a warning), or None.
    """
    if not outside > OUTSIDE_ENERGY_WARNING * max(inside, 0.0):
        return None
    fraction = outside / (outside + inside)
    message = (f"{100 * fraction:.2g} % of the returned energy came back after the fast-time window closed "
               f"(multi-bounce paths longer than the window allows, max_depth = {max_depth}); those returns "
               f"are missing from the image: lower max_depth, or see planning.EXTRA_BOUNCE_FRACTION")
    warnings.warn(message, AcquisitionWarning, stacklevel=2)
    return message

