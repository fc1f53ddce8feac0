"""Checks that a track can image the scene: its beam reaches it (docs/physics.md (G5)), a
spotlight beam is not steered beyond :data:`MAX_STEERING_DEG`, a motion error stays within what
autofocus can correct ((J4)), and a trajectory file is long enough for the synthetic aperture.

:func:`check_beam_reach` refuses (``ParameterError``); the ``*_note`` functions return the
warnings that :func:`sarmitsuba.scene.planning.check_acquisition` issues.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..core.geometry import AcquisitionGeometry
from ..core.radar import ParameterError, RadarParameters
from ..core.trajectory import StateVectors

__all__ = ["MAX_STEERING_DEG", "check_beam_reach", "steering_note", "motion_error_note", "aperture_note",
           "bistatic_doppler_band", "receiver_doppler_note"]


#: The largest angle [deg] from broadside to which a spotlight beam is steered (a gimbal or a phased
#: array): the valid range of ``squint``. Beyond it the antenna model, a pattern steered in sine
#: space with no scan loss, no longer describes a real antenna (phased arrays scan to about 45-60
#: deg), and the geometry is closer to forward-looking than to side-looking SAR.
MAX_STEERING_DEG = 60.0


def _axes(geometry: AcquisitionGeometry) -> np.ndarray:
    """Each pulse's along-track beam axis, float64 [n_pulses, 3]: the geometry's beam axes, else its track."""
    if geometry.beam_axes is not None:
        return geometry.beam_axes
    return np.broadcast_to(geometry.track_direction, geometry.positions.shape)


def _steering_sines(geometry: AcquisitionGeometry, centre) -> np.ndarray:
    """Sine of the angle from broadside [n_pulses] at which each pulse sees ``centre`` [m]: where a
    spotlight beam is steered to."""
    to_centre = np.asarray(centre, float) - geometry.positions
    return np.einsum("pk,pk->p", to_centre, _axes(geometry)) / np.linalg.norm(to_centre, axis=1)


def check_beam_reach(params: RadarParameters, lo: np.ndarray, hi: np.ndarray) -> None:
    """Refuse an acquisition whose beam never reaches the scene (docs/physics.md (G5)).

    Every pulse of the nominal track (motion errors left out) is tested, whatever the trajectory
    (straight, circular, state vectors or any other kind :func:`acquisition_geometry` composes):
    its main beam, to the pattern's first nulls (:attr:`RadarParameters.traced_half_angle` ``h``,
    the support of the traced beam), spans along-track angles ``[squint - h, squint + h]`` from
    broadside in stripmap, about the pulse's own along-track axis; in spotlight ``[asin(s - sin h),
    asin(s + sin h)]`` about the direction ``s`` (a sine) of the scene centre, which it is steered
    to, and only while that steering stays within :data:`MAX_STEERING_DEG` of broadside. The
    scene's box, seen from the pulse as its bounding sphere (centre ``c``, radius ``r``), spans
    along-track angles within ``alpha_c +- asin(r / |c - A|)`` (the angle to a plane changes by
    no more than the angle between two directions). A pulse sees the scene when the two intervals
    meet, so the test never refuses a scene the beam touches.

    Parameters
    ----------
    params : RadarParameters
        Resolved (``scene_center`` and ``n_pulses`` set).
    lo, hi : float64 [3], m
        The scene's bounding box (the frame of ``params``).

    Raises
    ------
    ParameterError
        No pulse sees the scene: names ``trajectory``, where the scene lies from the beam at the
        pulse that comes nearest, and the fix.
    """
    from ..core.geometry import acquisition_geometry
    geometry = acquisition_geometry(replace(params, motion_error=None, stop_and_hop=True))
    antenna = geometry.positions
    axes = _axes(geometry)
    centre, radius = 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))
    to_box = centre - antenna
    distance = np.linalg.norm(to_box, axis=1)
    along = np.einsum("pk,pk->p", to_box, axes)
    alpha = np.arcsin(np.clip(along / np.maximum(distance, 1e-300), -1.0, 1.0))
    spread = np.where(distance > radius, np.arcsin(np.clip(radius / np.maximum(distance, 1e-300), 0.0, 1.0)), np.pi)
    half = params.traced_half_angle
    steer = np.full(len(antenna), math.radians(params.squint))
    if params.mode == "spotlight":
        sine = _steering_sines(geometry, params.scene_center)
        steer = np.arcsin(np.clip(sine, -1.0, 1.0))
        b_lo = np.arcsin(np.clip(sine - math.sin(half), -1.0, 1.0))
        b_hi = np.arcsin(np.clip(sine + math.sin(half), -1.0, 1.0))
    else:
        b_lo, b_hi = steer - half, steer + half
    gap = np.maximum(b_lo - (alpha + spread), (alpha - spread) - b_hi)        # > 0: the box outside the beam
    steerable = np.abs(steer) <= math.radians(MAX_STEERING_DEG) * (1.0 + 1e-12)
    if np.any((gap <= 0.0) & steerable):
        return
    raise ParameterError(_unseen_message(params, geometry, lo, hi, along, distance, alpha, gap, steer, steerable))


def steering_note(params: RadarParameters, geometry: AcquisitionGeometry) -> str | None:
    """A warning when some spotlight pulses steer the beam more than :data:`MAX_STEERING_DEG` from
    broadside (those that all do are refused, :func:`check_beam_reach`), else None. The tracer
    steers the pattern in sine space (docs/physics.md (A), (G5)), so its beam widens as
    ``1 / cos(steer)`` (twice a gimbal's at 60 deg) and loses no gain: those pulses' echoes are
    brighter and wider than any real antenna's."""
    if params.mode != "spotlight":
        return None
    steer = np.degrees(np.arcsin(np.clip(_steering_sines(geometry, geometry.scene_center), -1.0, 1.0)))
    beyond = np.abs(steer) > MAX_STEERING_DEG
    if not np.any(beyond) or np.all(beyond):
        return None
    t = geometry.pulse_time[~beyond]
    return (f"spotlight: {int(beyond.sum())} of {len(steer)} pulses ({100.0 * beyond.mean():.3g} %) steer the beam "
            f"more than {MAX_STEERING_DEG:g} deg from broadside (up to {float(np.abs(steer).max()):.1f} deg), where the "
            "steered pattern (no scan loss, widening as 1 / cos(steer)) describes no real antenna; the pulses from "
            f"t = {float(t.min()):.6g} to {float(t.max()):.6g} s stay within it: trim the trajectory to them, or set "
            f"n_pulses to at most {int((~beyond).sum())}")


def _unseen_message(params: RadarParameters, geometry: AcquisitionGeometry, lo: np.ndarray, hi: np.ndarray,
                    along: np.ndarray, distance: np.ndarray, alpha: np.ndarray, gap: np.ndarray, steer: np.ndarray,
                    steerable: np.ndarray) -> str:
    """The message of :func:`check_beam_reach`: what the beam sees at the pulse that comes nearest."""
    kind = params.trajectory
    name = (f"trajectory = {kind.source!r}" if isinstance(kind, StateVectors) else
            f"trajectory = {kind!r}" if isinstance(kind, str) else f"trajectory {kind}")
    box = f"the scene (bounding box {np.round(lo, 1).tolist()} .. {np.round(hi, 1).tolist()} m)"
    if params.mode == "spotlight" and np.any(gap <= 0.0):       # in the steered beam, but too far from broadside
        p = int(np.argmin(np.where(gap <= 0.0, np.abs(steer), np.inf)))
        where = (f"the spotlight beam, steered at scene_center {np.round(params.scene_center, 1).tolist()} m, would "
                 f"point {math.degrees(abs(float(steer[p]))):.1f} deg from broadside at best (t = "
                 f"{geometry.pulse_time[p]:.6g} s), beyond the {MAX_STEERING_DEG:g} deg an antenna is steered to")
    else:
        p = int(np.argmin(np.where(steerable, gap, np.inf) if np.any(steerable) else gap))
        beam = (f"the stripmap beam spans +-{math.degrees(params.traced_half_angle):.3g} deg about squint "
                f"{params.squint:g} deg along track (to its first nulls)" if params.mode == "stripmap" else
                f"the spotlight beam, steered at scene_center {np.round(params.scene_center, 1).tolist()} m, spans "
                f"+-{math.degrees(params.traced_half_angle):.3g} deg along track about it")
        side = "ahead of" if along[p] > 0 else "behind"
        where = (f"{beam}, but at the pulse that comes nearest (t = {geometry.pulse_time[p]:.6g} s, antenna at "
                 f"{np.round(geometry.positions[p], 1).tolist()} m) the scene's centre lies {abs(along[p]):.1f} m "
                 f"{side} the antenna along its track, {math.degrees(abs(float(alpha[p]))):.1f} deg from broadside, "
                 f"{math.degrees(float(gap[p])):.2f} deg outside the beam")
    fix = ("fly the track past the scene (a trajectory file is in the scene frame: metres, z up, the scene's own "
           "axes), or move it with track_offset")
    if isinstance(kind, str) and kind == "straight":
        fix = ("move scene_center onto the scene (left unset it is the scene's centre), or set n_pulses = 0 for a "
               "track that sweeps the scene")
    elif isinstance(kind, str) and kind == "circular":
        fix = "move scene_center onto the scene (left unset it is the scene's centre): the circle's beam stays on it"
    return (f"{name}: no pulse's beam reaches {box}: {where}; the raw data and the image would be empty "
            f"(docs/physics.md (G5)): {fix}")


def motion_error_note(params: RadarParameters) -> str | None:
    """A warning when the sensor's ``motion_error`` moves the antenna by more than a slant-range
    resolution cell along the line of sight, else None (docs/physics.md (J4)).

    The error is horizontal and across the track, so the antenna's range to the scene changes by
    ``e sin(theta_inc)``; its peak ``e`` is the amplitude of a sinusoid and 3 times the RMS of a
    random error (99.7 % of a Gaussian's values). Beyond ``c / (2 B)`` the echoes of one point
    migrate across range cells during the aperture: focusing on the nominal track
    (``focus --track nominal``) smears them in range as well as azimuth, and phase gradient
    autofocus, which estimates one phase per pulse, cannot correct that (a motion error is
    phase-only within a resolution cell; Carrara, Goodman and Majewski 1995, sec. 6.3). The
    render itself, on the true track, focuses whatever the error."""
    from ..core.trajectory import MotionError
    error = MotionError.parse(params.motion_error)
    if error is None:
        return None
    peak = error.amplitude if error.kind == "sinusoid" else 3.0 * error.amplitude
    shift = peak * math.sin(math.radians(params.incidence_angle))
    if shift <= params.slant_range_resolution:
        return None
    what = f"amplitude {peak:g} m" if error.kind == "sinusoid" else f"3 x RMS = {peak:g} m"
    largest = params.slant_range_resolution / math.sin(math.radians(params.incidence_angle))
    largest = largest if error.kind == "sinusoid" else largest / 3.0
    return (f"motion_error = '{error}' moves the antenna up to {peak:g} m across the track ({what}), "
            f"{shift:.3g} m in slant range at {params.incidence_angle:g} deg incidence: more than the slant-range "
            f"resolution c / (2 B) = {params.slant_range_resolution:.3g} m, so a processor without the true track "
            "(focus --track nominal) sees each point migrate across range cells, which phase gradient autofocus "
            f"cannot correct; the render on the true track focuses. For an error autofocus can remove keep the "
            f"{'amplitude' if error.kind == 'sinusoid' else 'RMS'} below {largest:.3g} m")


def aperture_note(params: RadarParameters, geometry: AcquisitionGeometry) -> str | None:
    """A warning when a trajectory of state vectors is too short for the synthetic aperture its
    resolution needs, else None.

    An aperture of length ``L_a`` seen from slant range ``R`` resolves ``lambda R / (2 L_a)`` in
    azimuth (Cumming and Wong 2005, eq. 4.37 with the beam's angle ``L_a / R``), so the resolution
    ``rho`` needs ``L_a = lambda R / (2 rho)``: ``rho`` the stripmap beam's azimuth resolution
    (:attr:`RadarParameters.azimuth_resolution`), or in spotlight the slant-range resolution (square
    cells, as the automatic spotlight track flies). ``L_a`` is compared with the length the pulses
    fly along the nominal track (motion errors left out)."""
    if not isinstance(params.trajectory, StateVectors) or params.n_pulses < 1:
        return None
    track = geometry.positions if geometry.nominal_positions is None else geometry.nominal_positions
    flown = float(np.sum(np.linalg.norm(np.diff(track, axis=0), axis=1)))
    rho = params.slant_range_resolution if params.mode == "spotlight" else params.azimuth_resolution
    needed = params.wavelength * params.slant_range / (2.0 * rho)
    if flown >= needed:
        return None
    achieved = params.wavelength * params.slant_range / (2.0 * flown) if flown > 0 else math.inf
    span = geometry.pulse_time[-1] - geometry.pulse_time[0]
    states = params.trajectory
    held = float(states.time[-1] - states.time[0])
    seconds = needed / max(params.velocity, 1e-300)
    fix = (f"give state vectors spanning at least {seconds:.3g} s at {params.velocity:.3g} m/s" if held < seconds else
           f"set n_pulses to at least {math.ceil(seconds * params.prf) + 1} (the state vectors' {held:.4g} s hold "
           f"{math.floor(held * params.prf + 1e-9) + 1}; n_pulses = 0 takes them all)")
    return (f"trajectory {states.source}: {params.n_pulses} pulses over {span:.4g} s fly {flown:.3g} m, but a "
            f"{rho:.3g} m azimuth resolution at {params.slant_range:.1f} m slant range needs a synthetic aperture of "
            f"{needed:.3g} m (lambda R / (2 rho)); the image will resolve about {achieved:.3g} m in azimuth: {fix}")


#: Points per side of the scene box's grid, at its lowest and highest z, over which
#: :func:`bistatic_doppler_band` takes the spread.
DOPPLER_GRID = 33
#: Pulses (evenly spread, the first and last among them) at which it is taken.
DOPPLER_PULSES = 9


def bistatic_doppler_band(params: RadarParameters, geometry: AcquisitionGeometry, lo: np.ndarray,
                          hi: np.ndarray) -> tuple[float, float]:
    """The Doppler band [Hz] a bistatic acquisition's echoes span at one pulse, the widest over
    :data:`DOPPLER_PULSES` pulses, and the transmitter's part of it: ``(B, B_t)``.

    A point ``p`` of the scene lit by the transmitter's beam (stripmap: its along-track sine
    within :attr:`RadarParameters.beam_sines`; spotlight: every point) returns at the Doppler
    ``(v_t . u_t + v_r . u_r) / lambda``, ``u`` the unit vector from each platform to ``p``
    (docs/physics.md (B5); Willis, *Bistatic Radar*, 2005, sec. 4.5); ``B`` is the spread of that over the points of a
    :data:`DOPPLER_GRID`-square grid of the box ``lo``..``hi`` (float64 [3], m) at its lowest and
    highest z, ``B_t`` the spread of ``v_t . u_t / lambda`` alone. The receiver's antenna is taken as
    isotropic. ``(0, 0)`` for a monostatic ``geometry`` (no ``receiver_positions``)."""
    if geometry.receiver_positions is None:
        return 0.0, 0.0
    axes = [np.linspace(lo[k], hi[k], DOPPLER_GRID) for k in range(2)]
    x, y, z = np.meshgrid(axes[0], axes[1], [lo[2], hi[2]], indexing="ij")
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    band = own = 0.0
    for i in np.unique(np.linspace(0, len(geometry.positions) - 1, DOPPLER_PULSES).round().astype(int)):
        at = points
        if params.mode == "stripmap":             # and where each grid line crosses the beam's edges
            at = np.concatenate([points, _beam_edges(params, geometry, i, points, lo, hi)])
        u_t = at - geometry.positions[i]
        u_t /= np.linalg.norm(u_t, axis=1, keepdims=True)
        u_r = at - geometry.receiver_positions[i]
        u_r /= np.linalg.norm(u_r, axis=1, keepdims=True)
        lit = np.ones(len(at), bool)
        if params.mode == "stripmap":
            sine = u_t @ geometry.track_direction
            lit = (sine >= params.beam_sines[0] - 1e-12) & (sine <= params.beam_sines[1] + 1e-12)
        if not np.any(lit):
            continue
        f_t = u_t[lit] @ geometry.velocity[i] / params.wavelength
        f = f_t + u_r[lit] @ geometry.receiver_velocity[i] / params.wavelength
        band, own = max(band, float(np.ptp(f))), max(own, float(np.ptp(f_t)))
    return band, own


def _beam_edges(params: RadarParameters, geometry: AcquisitionGeometry, pulse: int, points: np.ndarray,
                lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The points (float64 [m, 3]) where the lines along the track through ``points`` cross the
    edges of pulse ``pulse``'s stripmap beam (its along-track sine at each of
    :attr:`RadarParameters.beam_sines`: offset ``s d / sqrt(1 - s^2)`` along the track, ``d`` the
    distance across it), within the box ``lo``..``hi``."""
    t = geometry.track_direction
    rel = points - geometry.positions[pulse]
    along = rel @ t
    across = np.linalg.norm(rel - along[:, None] * t, axis=1)
    edges = np.concatenate([points + (s * across / math.sqrt(1.0 - s * s) - along)[:, None] * t
                            for s in params.beam_sines])
    return edges[np.all((edges >= lo - 1e-9) & (edges <= hi + 1e-9), axis=1)]


def receiver_doppler_note(params: RadarParameters, geometry: AcquisitionGeometry, lo: np.ndarray,
                          hi: np.ndarray) -> str | None:
    """The warning when a receiver on its own platform spreads the echoes' Doppler band
    (:func:`bistatic_doppler_band`) beyond the PRF, as the monostatic check warns of a PRF below
    the beam's Doppler bandwidth: azimuth ghosts. None when monostatic or within the PRF.

    The receiver's part of the band grows in proportion to its speed (its look directions held),
    so the speed it names, at which the band falls to the PRF, is ``v (prf - B_t) / (B - B_t)``
    (``B``, ``B_t`` the band and the transmitter's part at the receiver's speed ``v``; docs/physics.md
    (B5)), rounded down to three significant digits so that the speed named stays within the PRF."""
    band, own = bistatic_doppler_band(params, geometry, lo, hi)
    if band <= params.prf:
        return None
    speed = float(np.linalg.norm(geometry.receiver_velocity[len(geometry.positions) // 2]))
    slower = f" or slow the receiver to about {_round_down(speed * (params.prf - own) / (band - own), 3):.3g} m/s" \
        if own < params.prf else ""
    return (f"the receiver's motion (receiver_velocity {speed:.3g} m/s) spreads the echoes' Doppler band over the lit "
            f"scene to {band:.0f} Hz (the transmitter's part {own:.0f} Hz), above prf = {params.prf:g} Hz: azimuth "
            f"ghosts will appear; raise prf above {band:.0f} Hz{slower}")


def _round_down(value: float, digits: int) -> float:
    """``value`` (> 0) rounded toward zero to ``digits`` significant digits."""
    if not (math.isfinite(value) and value > 0):
        return value
    step = 10.0 ** (math.floor(math.log10(value)) - digits + 1)
    return math.floor(value / step * (1 + 1e-12)) * step
