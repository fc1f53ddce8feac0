"""Where a sensor can image a scene: the checks a scene's acquisition passes before any cost
is estimated or any ray traced (docs/physics.md (G4)).

:func:`check_geometry` refuses a scene beyond the radar horizon, geometry on the side the radar
does not look (imaged as mirrored ghosts), and an automatic track that mostly sees nothing; it
warns when ``scene_center`` lies far outside the shapes' box (:func:`center_outside`).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np

from ..core.geometry import acquisition_geometry, track_frame
from ..core.radar import VALID_RANGES, ParameterError, RadarParameters
from .planning import AcquisitionWarning, beam_offsets, box_corners

__all__ = ["check_geometry", "center_outside", "CENTER_MARGIN_CELLS", "HORIZON_EARTH_RADIUS", "EMPTY_TRACK_FRACTION", "EMPTY_TRACK_PULSES"]


# ============================================================================ geometry checks
#: Effective earth radius [m] of the radar horizon: 4/3 of the mean 6371 km, for standard
#: refraction (docs/physics.md (G4)).
HORIZON_EARTH_RADIUS = 4.0 / 3.0 * 6.371e6
#: An automatic stripmap track is refused when more than this fraction of its pulses ...
EMPTY_TRACK_FRACTION = 0.5
#: ... and more than this many see no geometry (below it the waste costs seconds, above it the
#: empty track dominates the render's memory and time).
EMPTY_TRACK_PULSES = 5000
#: ``scene_center`` is "outside" the shapes' box (:func:`center_outside`) beyond the larger of
#: the box's half diagonal and this many resolution cells. The image grid is centred on
#: ``scene_center`` and reaches the box, 16 cells beyond it (focus/scene_grid.py): a centre
#: farther from the box than its half diagonal leaves over two thirds of the grid's width
#: empty, and below 16 cells the grid grows by less than its own margin.
CENTER_MARGIN_CELLS = 16


def check_geometry(params: RadarParameters, lo: np.ndarray, hi: np.ndarray, shapes: list,
                   automatic_track: bool, offset: np.ndarray | None = None) -> None:
    """Refuse, before any tracing, an acquisition that cannot image the scene or whose automatic
    track is mostly empty (docs/physics.md (G4)).

    Parameters
    ----------
    params : RadarParameters
        Resolved (``scene_center`` and ``n_pulses`` set, :func:`resolve_parameters`).
    lo, hi : float64 [3], m
        The scene's bounding box.
    shapes : list of (str, float64 [n, 3])
        Each shape's name and points (mesh vertices, or an analytic shape's box corners), m.
    automatic_track : bool
        Whether ``n_pulses`` was automatic (0): only then is an empty track refused.
    offset : float64 [3], m, optional
        World position of the local frame's origin, to report ``scene_center`` as the user gave it.

    Raises
    ------
    ParameterError
        - the scene centre beyond the radar horizon (``incidence_angle`` too close to 90 deg for
          the ``altitude``), naming the largest valid incidence;
        - geometry at or beyond the nadir, on the side the radar does not look (mirrored
          ghosts), naming the shape, the geometry's ground-range extent from the nadir and the
          ``altitude``, ``incidence_angle``, ``track_offset`` that would fix it; on a curved
          track (circular, state vectors) at any pulse, naming the shape and the pulse's time;
        - with an automatic stripmap track, more than :data:`EMPTY_TRACK_FRACTION` of its pulses,
          and more than :data:`EMPTY_TRACK_PULSES`, seeing no geometry because shapes lie far
          along track from ``scene_center``, naming the farthest shape.
    """
    shapes = [(name, np.asarray(p, np.float64).reshape(-1, 3)) for name, p in shapes]
    shapes = [(name, p) for name, p in shapes if len(p)] or [("scene", box_corners(lo, hi))]
    names = [name for name, _ in shapes]
    points = np.concatenate([p for _, p in shapes])
    starts = np.r_[0, np.cumsum([len(p) for _, p in shapes])[:-1]]
    shown = np.asarray(params.scene_center, float) + (np.zeros(3) if offset is None else np.asarray(offset, float))
    _check_horizon(params, hi)
    if not params.straight_track:
        _check_side_curved(params, points, starts, names)
        return
    outside = center_outside(params, points.min(axis=0), points.max(axis=0), offset)
    _check_side(params, points, starts, names, outside)
    if automatic_track and params.mode == "stripmap":
        _check_track(params, lo, hi, points, starts, names, shown)
    if outside is not None:
        distance, middle = outside
        track, _ = track_frame(params)
        lo_p, hi_p = points.min(axis=0), points.max(axis=0)
        along = abs(float((0.5 * (lo_p + hi_p) - np.asarray(params.scene_center, float)) @ track))
        longer = automatic_track and params.mode == "stripmap" and along > 0.5 * float(np.abs(track) @ (hi_p - lo_p))
        warnings.warn(f"scene_center = {_xyz(shown)} lies {_distance(distance)} from the nearest point of the shapes' "
                      f"box: the image grid (centred on it) is mostly empty"
                      f"{' and the automatic track longer than the shapes need' if longer else ''}; set scene_center = "
                      f"{_xyz(middle)}, the middle of the shapes' box", AcquisitionWarning, stacklevel=3)


def center_outside(params: RadarParameters, lo: np.ndarray, hi: np.ndarray,
                   offset: np.ndarray | None = None) -> tuple[float, np.ndarray] | None:
    """``(distance [m] from scene_center to the box lo..hi, the box's middle in world coordinates)``
    when ``scene_center`` lies outside the box by more than the larger of its half diagonal and
    :data:`CENTER_MARGIN_CELLS` resolution cells; None otherwise."""
    center = np.asarray(params.scene_center, float)
    distance = float(np.linalg.norm(np.maximum(np.maximum(lo - center, center - hi), 0.0)))
    cell = max(params.ground_range_resolution, params.azimuth_resolution)
    if distance <= max(0.5 * float(np.linalg.norm(hi - lo)), CENTER_MARGIN_CELLS * cell):
        return None
    return distance, 0.5 * (lo + hi) + (np.zeros(3) if offset is None else np.asarray(offset, float))


def _xyz(point: np.ndarray) -> str:
    return ", ".join(f"{float(v):.1f}" for v in point)


def _horizon(height: float) -> float:
    """Slant range [m] to the radar horizon from ``height`` [m] above a flat scene (G4)."""
    height = max(height, 0.0)
    return math.sqrt(2.0 * HORIZON_EARTH_RADIUS * height + height * height)


def _check_horizon(params: RadarParameters, hi: np.ndarray) -> None:
    """The scene centre within the radar horizon of the antenna and the scene's top (G4)."""
    h, theta = params.altitude, math.radians(params.incidence_angle)
    top = max(0.0, float(hi[2]) - float(params.scene_center[2]))
    reach = _horizon(h) + _horizon(top)
    if params.slant_range <= reach:
        return
    limit = math.degrees(math.acos(h / reach))
    # the altitude below which the scene comes into view at this incidence: the larger root of
    # (h / cos - d)^2 = 2 k R h + h^2, d the scene top's horizon
    secant, d = 1.0 / math.cos(theta), _horizon(top)
    b, a = d * secant + HORIZON_EARTH_RADIUS, secant * secant - 1.0
    lowest = (b + math.sqrt(max(b * b - a * d * d, 0.0))) / a
    lowest = math.floor(10.0 * lowest) / 10.0          # rounded down: inside the horizon
    altitude = f", or lower altitude below {lowest:,.1f} m" if lowest >= VALID_RANGES["altitude"].lo else ""
    raise ParameterError(
        f"incidence_angle = {params.incidence_angle:g} deg at altitude = {h:g} m puts the scene centre "
        f"{_distance(params.slant_range)} away in slant range ({_distance(params.ground_range)} from the nadir "
        f"track), beyond the radar horizon: from {h:g} m, over a scene up to {top:.3g} m high, the earth (4/3 "
        f"radius, standard refraction) hides everything farther than {_distance(reach)} in slant range "
        f"(docs/physics.md (G4)); at this altitude incidence_angle must be below {limit:.2f} deg (SAR images at "
        f"about 15-60 deg): lower incidence_angle{altitude}")


def _distance(metres: float) -> str:
    return f"{metres / 1000:,.1f} km" if abs(metres) >= 1000 else f"{metres:.1f} m"


def _check_side(params: RadarParameters, points: np.ndarray, starts: np.ndarray, names: list,
                outside: tuple[float, np.ndarray] | None = None) -> None:
    """Every point on the side the radar looks, at cross-track ground range ``g > 0`` from the nadir (G4)."""
    _, look = track_frame(params)
    center = np.asarray(params.scene_center, float)
    ground = params.ground_range
    g = (points - center) @ look + ground - float(np.asarray(params.track_offset, float) @ look)
    i = int(np.argmin(g))
    if g[i] > 0:
        return
    shape = names[int(np.searchsorted(starts, i, side="right")) - 1]
    needed = ground - float(g[i])                  # the nadir's distance from scene_center that clears it
    theta = math.radians(params.incidence_angle)
    away = np.round(look * float(g[i]), 1) + 0.0         # against the look direction
    first = "" if outside is None else (f"set scene_center = {_xyz(outside[1])}, the middle of the shapes' box "
                                        f"({_distance(outside[0])} from scene_center), or ")
    raise ParameterError(
        f"the track passes over the scene: altitude = {params.altitude:g} m and incidence_angle = "
        f"{params.incidence_angle:g} deg put the nadir track {ground:.1f} m from scene_center (altitude "
        f"tan(incidence_angle)), but the geometry spans {float(g.min()):.1f} .. {float(g.max()):.1f} m in ground range "
        f"from the nadir (look_side = {params.look_side!r}: positive on the side the radar looks) and shape "
        f"{shape!r} reaches {-float(g[i]):.1f} m beyond it; echoes from both sides of the track arrive at the same "
        f"ranges, so that geometry would image as mirrored ghosts (docs/physics.md (G4)): {first}raise altitude above "
        f"{needed / math.tan(theta):.1f} m or incidence_angle above "
        f"{math.degrees(math.atan2(needed, params.altitude)):.2f} deg, or shift the track by more than "
        f"({away[0]:.1f}, {away[1]:.1f}, 0) m with track_offset (or scene_center)")


#: Pulses of a curved track at which the side check looks (evenly spread over the track).
SIDE_CHECK_PULSES = 2000


def _check_side_curved(params: RadarParameters, points: np.ndarray, starts: np.ndarray, names: list) -> None:
    """Every point on the side the radar looks from every pulse of a curved track (G4): at
    ``(X - A_p) . look_p > 0``, ``look_p`` the horizontal normal to the pulse's along-track axis."""
    geometry = acquisition_geometry(replace(params, motion_error=None, stop_and_hop=True))
    pick = np.unique(np.linspace(0, len(geometry.pulse_time) - 1, SIDE_CHECK_PULSES).round().astype(int))
    axis = geometry.beam_axes[pick]
    sign = 1.0 if params.look_side == "right" else -1.0
    look = sign * np.stack([axis[:, 1], -axis[:, 0], np.zeros(len(pick))], axis=1)     # axis x z
    g = np.einsum("pk,npk->np", look, points[:, None, :] - geometry.positions[pick][None, :, :])
    i, p = np.unravel_index(int(np.argmin(g)), g.shape)
    if g[i, p] > 0:
        return
    shape = names[int(np.searchsorted(starts, i, side="right")) - 1]
    extra = (f"; the circle's radius is the ground range {params.ground_range:.1f} m, so every shape must lie within "
             f"it of scene_center: raise incidence_angle or altitude" if params.trajectory == "circular" else
             "; move the track, or scene_center")
    raise ParameterError(
        f"the track passes over the scene: at t = {geometry.pulse_time[pick[p]]:.6g} s the antenna (look_side = "
        f"{params.look_side!r}) has shape {shape!r} {-float(g[i, p]):.1f} m beyond its nadir, on the side it does not "
        f"look; echoes from both sides of a track arrive at the same ranges, so that geometry would image as mirrored "
        f"ghosts (docs/physics.md (G4)){extra}")


def _check_track(params: RadarParameters, lo: np.ndarray, hi: np.ndarray, points: np.ndarray,
                 starts: np.ndarray, names: list, shown: np.ndarray) -> None:
    """An automatic stripmap track whose pulses mostly see no geometry: shapes far along track
    from ``scene_center``, which the track (centred on it) must reach."""
    track, _ = track_frame(params)
    along = (points - np.asarray(params.scene_center, float)) @ track
    s_lo, s_hi = np.minimum.reduceat(along, starts), np.maximum.reduceat(along, starts)
    a_lo, a_hi = beam_offsets(params, lo, hi)
    length = (params.n_pulses - 1) * params.velocity / params.prf
    middle = -params.squint_offset + float(np.asarray(params.track_offset, float) @ track)
    start, end = middle - 0.5 * length, middle + 0.5 * length
    # the antenna positions whose beam holds part of a shape, merged
    covered, reach = 0.0, start
    for a, b in sorted(zip(np.clip(s_lo - a_hi, start, end), np.clip(s_hi - a_lo, start, end))):
        covered += max(0.0, b - max(a, reach))
        reach = max(reach, b)
    empty = length - covered
    empty_pulses = int(empty * params.prf / params.velocity)
    if empty <= EMPTY_TRACK_FRACTION * length or empty_pulses <= EMPTY_TRACK_PULSES:
        return
    distance = np.maximum(np.abs(s_lo), np.abs(s_hi))
    far = int(np.argmax(distance))
    center = ", ".join(f"{c:g}" for c in np.round(shown, 1))
    raise ParameterError(
        f"shape {names[far]!r} lies {float(distance[far]) / 1000:.1f} km along track from scene_center ({center}) "
        f"(the geometry spans {float(along.min()):.0f} .. {float(along.max()):.0f} m along track from it): the "
        f"automatic track, centred on scene_center, needs {params.n_pulses:,} pulses ({_distance(length)}) to sweep "
        f"it and {empty_pulses:,} of them ({100 * empty / length:.0f} %) see no geometry; move scene_center onto the "
        f"scene (left unset it is the scene's centre) or move the shape, or set n_pulses (or aperture_length) for "
        f"a track of your own")
