"""Planning an acquisition before tracing: defaults from the scene, fast-time window, ray footprint.

All functions are pure (NumPy, float64) and take the scene's axis-aligned bounding box as
``(lo, hi)``, each float64 [3] in metres.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import fft as sp_fft

from .constants import SPEED_OF_LIGHT
from .radar import AcquisitionGeometry, RadarParameters, track_frame
from .trace import FastTimeWindow, RayFootprint, TraceSettings

__all__ = ["resolve_parameters", "fast_time_window", "ray_footprint", "ray_spacing", "box_corners",
           "check_acquisition", "AcquisitionWarning"]


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
    along-track extent plus the beam footprint at the farthest scene point,
    ``n_pulses = ceil(length * prf / velocity) + 1``.
    """
    if params.scene_center is None:
        params = replace(params, scene_center=(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), float(lo[2])))
    if params.n_pulses == 0 and params.mode == "spotlight":
        angle = params.wavelength / (2.0 * params.slant_range_resolution)
        length = angle * params.slant_range
        params = replace(params, n_pulses=int(math.ceil(length * params.prf / params.velocity)) + 1)
    if params.n_pulses == 0:
        track, look = track_frame(params)
        rel = box_corners(lo, hi) - np.asarray(params.scene_center)
        along = rel @ track
        a_lo, a_hi = beam_offsets(params, lo, hi)
        length = float(along.max() - along.min()) + (a_hi - a_lo)
        params = replace(params, n_pulses=int(math.ceil(length * params.prf / params.velocity)) + 1)
    return params


def _closest_ranges(params: RadarParameters, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    track, look = track_frame(params)
    center = np.asarray(params.scene_center, float)
    mid = center - params.ground_range * look + np.array([0.0, 0.0, params.altitude])
    rel = box_corners(lo, hi) - mid
    rel -= np.outer(rel @ track, track)         # distance at closest approach
    return np.linalg.norm(rel, axis=1)


def _far_range(params: RadarParameters, lo: np.ndarray, hi: np.ndarray) -> float:
    return float(_closest_ranges(params, lo, hi).max())


def beam_offsets(params: RadarParameters, lo: np.ndarray, hi: np.ndarray) -> tuple[float, float]:
    """Along-track interval ``(a_lo, a_hi)`` [m], relative to the antenna, that the stripmap beam
    covers at the scene's closest-approach ranges ``R0``: ``R0 tan(squint -/+ beta / 2)``,
    bounded over the near and far range (ray tube aim and automatic aperture length).
    At broadside it is ``-/+ R_far tan(beta / 2)``."""
    ranges = _closest_ranges(params, lo, hi)
    r = (max(0.0, float(ranges.min()) - float(np.linalg.norm(hi - lo))), float(ranges.max()))
    half, squint = params.traced_half_angle, math.radians(params.squint)
    return (min(x * math.tan(squint - half) for x in r), max(x * math.tan(squint + half) for x in r))


def fast_time_window(params: RadarParameters, geometry: AcquisitionGeometry, lo: np.ndarray,
                     hi: np.ndarray, settings: TraceSettings) -> FastTimeWindow:
    """Fast-time window covering every scene point from every pulse, plus margins.

    Nearest delay: twice the distance from the antenna to the box; farthest: twice the
    farthest corner, plus ``(max_depth - 1) * 10 %`` of the box diagonal for multi-bounce
    paths longer than the direct one (energy still falling outside is reported by the
    tracer, never clamped into edge bins), plus margins for the compressed pulse's tails
    and, for chirped output, half a pulse length. The sample count is a fast FFT length.
    """
    l_min, l_max = _echo_lengths(geometry.positions, lo, hi)
    l_max += (settings.max_depth - 1) * 0.1 * float(np.linalg.norm(hi - lo))
    margin = WINDOW_MARGIN_SAMPLES / params.sampling_rate
    if params.output == "raw":                 # chirps centred on their delay: +-T_p / 2
        margin += 0.5 * params.pulse_length
    t0 = l_min / SPEED_OF_LIGHT - margin
    n = int(math.ceil((l_max / SPEED_OF_LIGHT + margin - t0) * params.sampling_rate))
    return FastTimeWindow(t0=t0, fs=params.sampling_rate, n_samples=sp_fft.next_fast_len(n),
                          oversample=settings.oversample)


def _echo_lengths(positions: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[float, float]:
    """Shortest and longest two-way lengths [m] from the track to the scene's box (direct paths)."""
    closest = np.clip(positions, lo, hi)
    l_min = 2.0 * float(np.linalg.norm(positions - closest, axis=1).min())
    corners = box_corners(lo, hi)
    l_max = 2.0 * max(float(np.linalg.norm(corners - p, axis=1).max()) for p in positions[[0, -1, len(positions) // 2]])
    return l_min, l_max


def ray_spacing(params: RadarParameters, settings: TraceSettings) -> float:
    """Ray-tube width at the scene centre [m]: the setting, or half the finer resolution."""
    if settings.ray_spacing > 0:
        return settings.ray_spacing
    return min(params.slant_range_resolution, params.azimuth_resolution) / 2.0


def ray_footprint(params: RadarParameters, geometry: AcquisitionGeometry, lo: np.ndarray,
                  hi: np.ndarray, settings: TraceSettings) -> RayFootprint:
    """World-fixed ground grid of ray aim points covering the scene (see :class:`RayFootprint`).

    The ground-range extent is the box's, widened so that rays aimed at the grid also reach
    points above the ground plane (up to ``(z_max - z0) tan(theta)`` beyond the far edge)
    and below it (before the near edge). Spacing: ``s`` along track, ``s / cos(theta)`` in
    ground range, so tubes are square, ``s`` wide, perpendicular to the line of sight.
    Along track, each pulse samples the overlap of its beam with the scene's extent (a
    satellite's 17 km footprint over a 2 m target costs a handful of rays, not 45,000).
    """
    s = ray_spacing(params, settings)
    origin = np.asarray(params.scene_center, float)
    track, look = geometry.track_direction, geometry.look_direction
    rel = box_corners(lo, hi) - origin
    along, across = rel @ track, rel @ look
    z0 = origin[2]
    tan_far = (params.ground_range + across.max()) / params.altitude
    g_min = across.min() - max(0.0, z0 - lo[2]) * tan_far - s
    g_max = across.max() + max(0.0, hi[2] - z0) * tan_far + s
    spacing_range = s / math.cos(math.radians(params.incidence_angle))
    g_min = math.floor(g_min / spacing_range) * spacing_range   # lattice anchored at the scene centre, not at
    n_range = int(math.ceil((g_max - g_min) / spacing_range)) + 1   # the box edge (whose rows could sit on it)
    a_lo, a_hi = beam_offsets(params, lo, hi)
    if params.mode == "spotlight":        # the beam stays on the scene centre: a fixed patch
        r_far = _far_range(params, lo, hi)
        a_lo, a_hi = -r_far * math.tan(params.traced_half_angle), r_far * math.tan(params.traced_half_angle)
    width = a_hi - a_lo + 2 * s
    # per pulse, only the overlap of the beam with the scene's along-track extent is sampled
    extent = float(along.max() - along.min()) + 2 * s
    n_azimuth = int(math.ceil(min(width, extent) / s)) + 2
    ant_along = (geometry.positions - origin) @ track
    if params.mode == "spotlight":
        ant_along = np.zeros_like(ant_along)
    k0 = np.floor(np.maximum(ant_along + a_lo - s, along.min() - s) / s).astype(np.int64)
    return RayFootprint(origin=origin, track=track, look=look, spacing_azimuth=s, spacing_range=spacing_range,
                        range_min=float(g_min), n_azimuth=n_azimuth, n_range=n_range,
                        azimuth_limits=(float(along.min() - s), float(along.max() + s)), k0=k0)


def check_acquisition(params: RadarParameters, geometry: AcquisitionGeometry, window: FastTimeWindow,
                      lo: np.ndarray, hi: np.ndarray) -> list[str]:
    """Warn (:class:`AcquisitionWarning`) about settings that give ambiguities or an empty image.

    - azimuth ambiguities: ``prf`` below the Doppler bandwidth ``4 v sin(beta / 2) / lambda``
      (stripmap; Cumming and Wong 2005, eq. 4.36);
    - range ambiguities: the echo window (scene depth plus pulse length) longer than the pulse
      repetition interval, i.e. ``prf > c / (2 swath depth)``: echoes of consecutive pulses
      overlap (Curlander and McDonough 1991, sec. 6.5);
    - a scene outside the beam footprint: no ray can hit it.

    Returns the messages (also issued as warnings).
    """
    import warnings
    messages = []
    if params.mode == "stripmap" and params.prf < params.doppler_bandwidth:
        messages.append(f"prf = {params.prf:g} Hz is below the Doppler bandwidth {params.doppler_bandwidth:.1f} Hz "
                        f"(azimuth_beamwidth {params.azimuth_beamwidth:.3g} deg, velocity {params.velocity:g} m/s): "
                        "azimuth ambiguities (ghosts) will appear; raise prf or narrow the beam")
    l_min, l_max = _echo_lengths(geometry.positions, lo, hi)
    echo = (l_max - l_min) / SPEED_OF_LIGHT + params.pulse_length      # receive time of one pulse's echoes
    if echo > 1.0 / params.prf:
        messages.append(f"prf = {params.prf:g} Hz exceeds 1 / (echo duration) = {1.0 / echo:.1f} Hz "
                        f"(scene depth {0.5 * (l_max - l_min):.0f} m slant plus pulse_length {params.pulse_length:g} s): "
                        "echoes of consecutive pulses overlap (range ambiguities), which this simulation does not "
                        "model; lower prf or shrink the scene")
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
    for message in messages:
        warnings.warn(message, AcquisitionWarning, stacklevel=2)
    return messages
