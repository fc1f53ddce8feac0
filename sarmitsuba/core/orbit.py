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
- :func:`closest_approach` is the time an orbit comes closest to a point (its pulses centre
  there), and :func:`pass_geometry` what ``info`` reports of the pass.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from . import georef
from .state_vectors import StateVectors, read_eof

__all__ = ["read_eof", "in_scene_frame", "pass_geometry", "PassGeometry", "closest_approach"]


# ============================================================================ frames
def in_scene_frame(states: StateVectors, ref: georef.GeoReference) -> StateVectors:
    """``states`` in the scene's east-north-up frame at ``ref`` (docs/physics.md (G1), (J6)):
    ECEF positions through PROJ's topocentric conversion (:func:`~.georef.ecef_to_enu`),
    velocities rotated by :func:`~.georef.enu_axes` (``v_enu = v_ecef @ axes.T``). States already
    in the scene frame pass unchanged. The map is rigid and affine, so the Hermite interpolant of
    the carried states is the carried interpolant of the ECEF states."""
    if states.frame != "ecef":
        return states
    axes = georef.enu_axes(ref)
    velocity = None if states.velocity is None else states.velocity @ axes.T
    return replace(states, position=georef.ecef_to_enu(states.position, ref), velocity=velocity, frame="scene")


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
    t = closest_approach(path.evaluate, *path.span, center)
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
    return PassGeometry(t, utc, rng, look, incidence, squint, float(sat_llh[2]), float(np.linalg.norm(v)))


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


def _normal_in_enu(llh: np.ndarray, ref: georef.GeoReference) -> np.ndarray:
    """The ellipsoid normal (up) at geodetic ``llh`` as a unit vector of the ENU frame at ``ref``."""
    here = georef.GeoReference(float(np.clip(llh[0], -90, 90)), float(llh[1]), 0.0)
    up_ecef = georef.enu_axes(here)[2]
    return georef.enu_axes(ref) @ up_ecef          # rows of enu_axes are the ENU axes in ECEF
