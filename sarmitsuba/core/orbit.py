"""Orbits on the real Earth: ECEF state vectors carried into the scene's local frame, and the
geometry of an orbit's pass (docs/physics.md (J5), (J6)).

- Sentinel-1 orbit files and ECEF CSVs are read by :mod:`.state_vectors` (:func:`read_eof`,
  re-exported here) and interpolated as precise orbits are by
  :func:`sarmitsuba.core.trajectory.hermite_window`;
- :func:`in_scene_frame` carries ECEF states into the scene's east-north-up frame at
  ``geo_origin`` with pyproj (:mod:`.georef`): positions by PROJ's topocentric conversion,
  velocities rotated by :func:`~.georef.enu_axes`. ECEF and the ENU frame both turn with the
  Earth, so the map is one fixed rigid motion: ECEF state vectors already hold the Earth's
  rotation, and no flat-earth step is taken;
- :func:`builtin_orbit` is ``trajectory = orbit``: a circular Keplerian orbit in an inertial
  frame turned into ECEF by the Earth's rotation, placed so that the scene is seen at
  ``incidence_angle`` on ``look_side`` at closest approach;
- :func:`closest_approach` is the time an orbit comes closest to a point (its pulses centre
  there), and :func:`pass_geometry` what ``info`` reports of the pass.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from . import georef
from .state_vectors import HERMITE_WINDOW, StateVectors, TrajectoryError, read_eof

__all__ = ["read_eof", "in_scene_frame", "pass_geometry", "PassGeometry", "closest_approach", "builtin_orbit", "orbit_of",
           "orbit_passes", "choose_pass", "PASS_INCIDENCE", "footprint_speed", "EARTH_ROTATION", "GM_EARTH", "ORBIT_STEP"]


# ============================================================================ frames
def in_scene_frame(states: StateVectors, ref: georef.GeoReference) -> StateVectors:
    """``states`` in the scene's east-north-up frame at ``ref`` (docs/physics.md (GEO1), (J6)):
    ECEF positions through PROJ's topocentric conversion (:func:`~.georef.ecef_to_enu`),
    velocities rotated by :func:`~.georef.enu_axes` (``v_enu = v_ecef @ axes.T``). States already
    in the scene frame pass unchanged. The map is rigid and affine, so the Hermite interpolant of
    the carried states is the carried interpolant of the ECEF states."""
    if states.frame != "ecef":
        return states
    axes = georef.enu_axes(ref)
    velocity = None if states.velocity is None else states.velocity @ axes.T
    return replace(states, position=georef.ecef_to_enu(states.position, ref), velocity=velocity, frame="scene")


# ============================================================================ built-in orbit
#: The Earth's rotation rate [rad/s] (WGS84, NIMA TR8350.2 table 3.1).
EARTH_ROTATION = 7.292115e-5
#: The Earth's gravitational constant GM [m^3/s^2] (WGS84, NIMA TR8350.2 table 3.1).
GM_EARTH = 3.986004418e14
#: Spacing [s] of the state vectors of :func:`builtin_orbit` (that of Sentinel-1 orbit files).
ORBIT_STEP = 10.0


def builtin_orbit(ref: georef.GeoReference, altitude: float, incidence_deg: float, look_side: str,
                  inclination_deg: float, ascending: bool, duration: float = 600.0) -> StateVectors:
    """``trajectory = orbit``: ECEF state vectors (every :data:`ORBIT_STEP` s over ``duration`` s,
    closest approach to the scene at the middle, ``t = duration / 2``, relative clock) of a circular
    Keplerian orbit, eq. (J7), placed so that at closest approach

    - the satellite is ``altitude`` [m] above the WGS84 ellipsoid (pyproj),
    - the scene at ``ref`` sees it at ``incidence_deg`` from the ellipsoid normal, on ``look_side``
      of the track (zero Doppler in the Earth-fixed frame),
    - the orbit's plane has ``inclination_deg`` and the satellite moves north (``ascending``) or south.

    The orbit is ``r(t) = a (cos(n t) r0 + sin(n t) w)``, ``n = sqrt(GM / a^3)``, in the inertial
    frame that coincides with ECEF at closest approach, and ECEF is that frame turned by the
    Earth's rotation: ``r_ecef = Rz(-W t) r``, ``v_ecef = Rz(-W t) (v - W x r)``. The zero-Doppler
    condition and the inclination fix the along- and across-track place together: a fixed-point
    iteration turns the line of sight normal to the Earth-fixed velocity (it converges to 1e-9 rad
    in a few steps).

    Raises TrajectoryError when the inclination cannot reach the satellite's latitude (``|lat| >
    inclination`` and ``> 180 deg - inclination``)."""
    from scipy.optimize import brentq
    scene = georef.enu_to_ecef(np.zeros(3), ref)
    axes = georef.enu_axes(ref)
    east, north, up = axes
    inc = math.radians(incidence_deg)
    i = math.radians(inclination_deg)
    omega = np.array([0.0, 0.0, EARTH_ROTATION])
    heading = _track_azimuth(math.radians(ref.latitude_deg), i, ascending, inclination_deg)
    velocity = math.sin(heading) * east + math.cos(heading) * north            # first guess: the ground track
    sign = -1.0 if look_side == "right" else 1.0                               # the satellite left of its track
    for _ in range(50):
        # the line of sight from the scene: cos(incidence) on the normal, normal to the Earth-fixed velocity
        e1 = velocity / np.linalg.norm(velocity)
        e2 = up - (up @ e1) * e1
        e2 /= np.linalg.norm(e2)
        x = math.cos(inc) / float(up @ e2)
        los = x * e2 + sign * math.sqrt(max(1.0 - x * x, 0.0)) * np.cross(e1, e2)
        los_enu = axes @ los                                                 # the same direction in ENU

        def height(rho: float) -> float:
            return float(georef.enu_to_geodetic(rho * los_enu, ref)[2]) - altitude
        rho = brentq(height, 0.0, 10.0 * altitude + 1e5, xtol=1e-6)
        p = scene + rho * los
        radius = float(np.linalg.norm(p))
        r_hat = p / radius
        e_hat = np.cross([0.0, 0.0, 1.0], r_hat)
        e_hat /= np.linalg.norm(e_hat)
        n_hat = np.cross(r_hat, e_hat)
        az = _track_azimuth(math.asin(r_hat[2]), i, ascending, inclination_deg)
        v_inertial = math.sqrt(GM_EARTH / radius) * (math.sin(az) * e_hat + math.cos(az) * n_hat)
        new = v_inertial - np.cross(omega, p)
        done = np.linalg.norm(new / np.linalg.norm(new) - e1) < 1e-12
        velocity = new
        if done:
            break
    mean_motion = math.sqrt(GM_EARTH / radius ** 3)
    w_hat = np.cross(np.cross(p, v_inertial), p)
    w_hat /= np.linalg.norm(w_hat)
    half = int(math.ceil(0.5 * duration / ORBIT_STEP))
    t = ORBIT_STEP * np.arange(-half, half + 1, dtype=np.float64)
    c, s = np.cos(mean_motion * t)[:, None], np.sin(mean_motion * t)[:, None]
    r = radius * (c * r_hat + s * w_hat)
    v = radius * mean_motion * (-s * r_hat + c * w_hat)
    v = v - np.cross(omega, r)
    cw, sw = np.cos(-EARTH_ROTATION * t), np.sin(-EARTH_ROTATION * t)

    def rotate(x: np.ndarray) -> np.ndarray:
        return np.stack([cw * x[:, 0] - sw * x[:, 1], sw * x[:, 0] + cw * x[:, 1], x[:, 2]], axis=1)
    return StateVectors(t + half * ORBIT_STEP, rotate(r), rotate(v), "orbit", 0, frame="ecef",
                        window=HERMITE_WINDOW, closest_approach=True)


def orbit_of(params: Any) -> StateVectors:
    """:func:`builtin_orbit` of radar parameters (``trajectory = "orbit"``): their ``geo_origin``,
    ``altitude``, ``incidence_angle``, ``look_side``, ``orbit_inclination`` and ``orbit_direction``."""
    return builtin_orbit(georef.of(params), float(params.altitude), float(params.incidence_angle), params.look_side,
                         float(params.orbit_inclination), params.orbit_direction == "ascending")


def _track_azimuth(latitude: float, inclination: float, ascending: bool, inclination_deg: float) -> float:
    """Azimuth [rad, from north toward east] of an inertial orbit of ``inclination`` crossing the
    geocentric ``latitude`` [rad] northbound (``ascending``) or southbound: ``sin(az) = cos(i) / cos(lat)``."""
    s = math.cos(inclination) / max(math.cos(latitude), 1e-12)
    if abs(s) > 1.0:
        raise TrajectoryError(f"orbit_inclination = {inclination_deg:g} deg never reaches latitude "
                              f"{math.degrees(latitude):.3f} deg, where the satellite would pass the scene: give an "
                              f"inclination between {abs(math.degrees(latitude)):.1f} and "
                              f"{180 - abs(math.degrees(latitude)):.1f} deg")
    az = math.asin(s)
    return az if ascending else math.pi - az


# ============================================================================ what info reports
@dataclass(frozen=True)
class PassGeometry:
    """An orbit passing the scene, at its closest approach to the scene centre (docs/physics.md (J6)).

    Attributes
    ----------
    time : float, s
        On the state vectors' clock.
    utc : str or None
        The same instant in UTC (ISO 8601), when the clock is absolute.
    slant_range : float, m
    look_angle : float, deg
        Off-nadir angle at the satellite: between the line to the scene and the ellipsoid normal
        through the satellite (pointing down).
    incidence : float, deg
        At the scene: between the line to the satellite and the ellipsoid normal there.
    squint : float, deg
        Of the line of sight from the zero-Doppler plane (``asin(v . u / |v|)``; 0 at closest approach).
    height : float, m
        The satellite's height above the WGS84 ellipsoid.
    speed : float, m/s
        Its speed in the Earth-fixed frame.
    """

    time: float
    utc: str | None
    slant_range: float
    look_angle: float
    incidence: float
    squint: float
    height: float
    speed: float
    look_side: str = ""


def pass_geometry(states: StateVectors, ref: georef.GeoReference, scene_center: Any,
                  offset: Any = (0.0, 0.0, 0.0)) -> PassGeometry:
    """The pass of ``states`` (ECEF, or the scene frame less ``offset`` [m]) at its closest approach
    to ``scene_center`` [m, the frame of the scene-frame states], eq. (J6): slant range, the look
    angle against the WGS84 ellipsoid normal under the satellite, the incidence against the normal
    at the scene centre (normals from pyproj's geodetic coordinates), and the squint."""
    from .trajectory import from_state_vectors
    path = from_state_vectors(in_scene_frame(states, ref))
    center = np.asarray(scene_center, np.float64)
    shift = np.asarray(offset, np.float64)
    return _geometry_at(states, ref, path, closest_approach(path.evaluate, *path.span, center), center, shift)


def _geometry_at(states: StateVectors, ref: georef.GeoReference, path: Any, t: float, center: np.ndarray,
                 shift: np.ndarray) -> PassGeometry:
    """:class:`PassGeometry` of the scene-frame ``path`` at time ``t`` [s] seen from ``center`` [m]."""
    p, v = path.position(t), path.velocity(t)
    los = center - p
    rng = float(np.linalg.norm(los))
    u = los / rng
    scene_llh = georef.enu_to_geodetic(center + shift, ref)
    sat_llh = georef.enu_to_geodetic(p + shift, ref)
    incidence = math.degrees(math.acos(float(np.clip(-u @ _normal_in_enu(scene_llh, ref), -1, 1))))
    look = math.degrees(math.acos(float(np.clip(u @ -_normal_in_enu(sat_llh, ref), -1, 1))))
    squint = math.degrees(math.asin(float(np.clip(v @ u / np.linalg.norm(v), -1, 1))))
    utc = None if states.epoch is None else states.utc(t).isoformat()
    side = "left" if v[0] * los[1] - v[1] * los[0] > 0 else "right"
    return PassGeometry(t, utc, rng, look, incidence, squint, float(sat_llh[2]), float(np.linalg.norm(v)), side)


def closest_approach(evaluate: Any, lo: float, hi: float, point: np.ndarray) -> float:
    """The time in ``[lo, hi]`` [s] at which ``evaluate(t, 0)`` comes closest to ``point`` [m]: the
    best of 2001 samples, refined by scipy's bounded Brent search over its neighbours."""
    from scipy.optimize import minimize_scalar
    grid = np.linspace(lo, hi, 2001)
    d = np.linalg.norm(evaluate(grid, 0) - point, axis=-1)
    k = int(np.argmin(d))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    if a == b:
        return float(a)
    res = minimize_scalar(lambda x: float(np.linalg.norm(evaluate(np.array(x), 0) - point)), bounds=(a, b),
                          method="bounded", options={"xatol": 1e-7})
    return float(res.x)


#: Incidence band [deg] in which a pass of an orbit file sees the scene as a side-looking SAR does
#: (RADARSAT-2's beams span 10-60 deg, Sentinel-1's 19-47 deg): a pass outside it is not chosen (J6).
PASS_INCIDENCE = (10.0, 60.0)


def orbit_passes(states: StateVectors, ref: georef.GeoReference) -> list[PassGeometry]:
    """Every pass of ``states`` (ECEF or the scene frame at ``ref``) by ``geo_origin`` ``ref``: each
    local minimum of the range ``|P(t_j)|`` over the samples inside the span (not at its ends),
    refined by :func:`closest_approach` between its neighbours; as :class:`PassGeometry` (slant
    range, incidence, ``look_side``), in time order, eq. (J6). Empty for a file that holds no whole
    closest approach."""
    from .trajectory import from_state_vectors
    scene = in_scene_frame(states, ref)
    path = from_state_vectors(scene)
    d = np.linalg.norm(scene.position, axis=1)
    inner = np.flatnonzero((d[1:-1] < d[:-2]) & (d[1:-1] <= d[2:])) + 1
    zero = np.zeros(3)
    return [_geometry_at(states, ref, path, closest_approach(path.evaluate, scene.time[k - 1], scene.time[k + 1], zero),
                         zero, zero) for k in inner]


def _describe(p: PassGeometry) -> str:
    import datetime
    when = f"t = {p.time:.1f} s"
    if p.utc is not None:                 # ISO 8601 UTC, rounded to the second
        when = (datetime.datetime.fromisoformat(p.utc) + datetime.timedelta(seconds=0.5)).strftime("%Y-%m-%dT%H:%M:%SZ")
    return f"{when} (incidence {p.incidence:.1f} deg, looking {p.look_side}, slant range {p.slant_range / 1e3:.0f} km)"


def choose_pass(states: StateVectors, ref: georef.GeoReference, look_side: str = "right", side_given: bool = False,
                incidence: float | None = None, pass_time: str | None = None) -> tuple[StateVectors, str | None]:
    """The pass of an orbit file (``states``, ECEF or the scene frame at ``ref``) that the sensor
    images, docs/physics.md (J6): of :func:`orbit_passes`, those seen at an incidence inside
    :data:`PASS_INCIDENCE` (and on ``look_side`` when ``side_given``) qualify; ``pass_time`` (ISO
    8601 UTC, the ``orbit_pass_time`` parameter) picks the pass nearest to it; else, those on
    ``look_side`` first (the default side when not given), the qualifying pass nearest in incidence
    to ``incidence`` [deg] (when given), else the one of least slant range. Returns the states cut
    to that pass (from the range maximum before it to the one after, plus the interpolation window)
    and a warning naming the qualifying passes when several qualify and ``pass_time`` is None
    (else None). A file without a whole pass, or with one
    pass only and nothing asked of it, is returned unchanged. Raises ParameterError (naming the
    passes found) when no pass qualifies, when the pass nearest ``pass_time`` does not, or when
    ``pass_time`` is given for states without an absolute clock."""
    from .state_vectors import utc_instant
    from .valid_ranges import ParameterError
    found = orbit_passes(states, ref)
    if not found:
        if pass_time is not None:
            raise ParameterError(f"orbit_pass_time = {pass_time}: trajectory {states.source} holds no whole closest "
                                 "approach to geo_origin; remove orbit_pass_time")
        return states, None
    listed = "; ".join(_describe(p) for p in found if p.incidence < 90.0) or "none above the horizon"
    lo, hi = PASS_INCIDENCE
    ok = [p for p in found if lo <= p.incidence <= hi and (not side_given or p.look_side == look_side)]
    wanted = (f"incidence {lo:g} .. {hi:g} deg" + (f", look_side = {look_side}" if side_given else ""))
    if pass_time is not None:
        if states.epoch is None:
            raise ParameterError(f"orbit_pass_time = {pass_time}: trajectory {states.source} has no absolute clock "
                                 "(no epoch); remove orbit_pass_time")
        when = utc_instant(pass_time, "orbit_pass_time")
        near = min(found, key=lambda p: abs((states.utc(p.time) - when).total_seconds()))
        if near not in ok:
            raise ParameterError(f"orbit_pass_time = {pass_time}: the nearest pass of trajectory {states.source}, "
                                 f"{_describe(near)}, is not seen as a side-looking SAR sees ({wanted}); its passes: "
                                 f"{listed}: give the time of one of these, or change look_side")
        chosen = near
    elif not ok:
        raise ParameterError(f"trajectory {states.source} has no pass by geo_origin = {ref.as_tuple()} that a "
                             f"side-looking SAR images ({wanted}); its passes: {listed}: set geo_origin to the "
                             "scene's place beside the orbit's ground track, change look_side, or use another orbit file")
    else:
        chosen = min(ok, key=lambda p: (p.look_side != look_side,
                                        abs(p.incidence - incidence) if incidence is not None else p.slant_range))
    if len(found) == 1 and pass_time is None and chosen is found[0]:
        return states, None
    note = None
    if len(ok) > 1 and pass_time is None:
        note = (f"trajectory {states.source} passes geo_origin {len(ok)} times as a side-looking SAR would see it: "
                + "; ".join(_describe(p) for p in ok) + f"; imaging the pass at {_describe(chosen)} ("
                + ("looking " + look_side + ", " if any(p.look_side != look_side for p in ok) else "")
                + ("nearest to incidence_angle" if incidence is not None else "the least slant range")
                + "): set orbit_pass_time to the UTC time of another")
    return _cut(states, ref, chosen.time), note


def _cut(states: StateVectors, ref: georef.GeoReference, t: float) -> StateVectors:
    """``states`` from the last range maximum (to ``ref``) before time ``t`` [s] to the first after
    it, plus the Hermite window's samples beyond each."""
    d = np.linalg.norm(in_scene_frame(states, ref).position, axis=1)
    peak = np.flatnonzero((d[1:-1] > d[:-2]) & (d[1:-1] >= d[2:])) + 1
    before, after = peak[states.time[peak] < t], peak[states.time[peak] > t]
    a = max(int(before[-1]) - HERMITE_WINDOW, 0) if before.size else 0
    b = min(int(after[0]) + HERMITE_WINDOW + 1, states.time.size) if after.size else states.time.size
    velocity = None if states.velocity is None else states.velocity[a:b]
    return replace(states, time=states.time[a:b], position=states.position[a:b], velocity=velocity,
                   first_line=states.first_line + a if states.first_line else 0)


def footprint_speed(params: Any) -> float:
    """The speed [m/s] at which the beam sweeps the scene: ``params.velocity`` on a straight track;
    for an orbit (state vectors centred on the closest approach, already in the scene frame) the
    beam footprint's ground speed at closest approach to ``scene_center`` ``C``, eq. (J7)::

        v_g = (|V|^2 - (C - P) . A) / |V|,

    ``P``, ``V``, ``A`` the antenna's position, velocity and acceleration there. At zero Doppler the
    along-track sine of ``C`` seen from the antenna changes at ``(|V|^2 - (C - P) . A) / (|V| R)``
    (the velocity turns with the orbit's curvature), so a beam of width ``beta`` holds ``C`` for
    ``beta R / v_g`` s, where a straight track would need ``beta R / |V|``: 7.4 % less speed at
    500 km and 40 deg incidence (about ``|V| R_E / (R_E + h)``). The automatic aperture
    (:func:`sarmitsuba.scene.planning.resolve_parameters`) counts pulses with it. Needs resolved
    ``scene_center``; raises what :func:`~sarmitsuba.core.trajectory.from_state_vectors` raises."""
    states = params.trajectory
    if not (isinstance(states, StateVectors) and states.closest_approach):
        return float(params.velocity)
    from .trajectory import from_state_vectors
    path = from_state_vectors(states)
    center = np.asarray(params.scene_center, np.float64)
    t = closest_approach(path.evaluate, *path.span, center)
    v, a = path.velocity(t), path.acceleration(t)
    speed = float(np.linalg.norm(v))
    return (speed * speed - float((center - path.position(t)) @ a)) / speed


def _normal_in_enu(llh: np.ndarray, ref: georef.GeoReference) -> np.ndarray:
    """The ellipsoid normal (up) at geodetic ``llh`` as a unit vector of the ENU frame at ``ref``."""
    here = georef.GeoReference(float(np.clip(llh[0], -90, 90)), float(llh[1]), 0.0)
    up_ecef = georef.enu_axes(here)[2]
    return georef.enu_axes(ref) @ up_ecef          # rows of enu_axes are the ENU axes in ECEF
