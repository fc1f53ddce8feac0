"""The interferometric baseline of a pass shifted by the sensor's ``track_offset`` (docs/physics.md (I1)-(I3)).

A render with ``track_offset = (dx, dy, dz)`` flies the nominal track shifted by that vector: the
secondary pass of a repeat-pass pair whose primary is the same scene without the offset. At the
scene centre ``C`` and the nominal mid-aperture antenna ``A``, with ``t`` the track direction,
``u = (A - C) / R`` the unit vector toward the sensor and ``R = |A - C|``:

* the baseline's part normal to the track, ``B_n = B - (B . t) t``, splits into the parallel
  baseline ``B_par = B_n . u`` (along the line of sight, positive away from the scene) and the
  perpendicular baseline ``B_perp = B_n . e``, ``e = u x t`` for a right-looking radar
  (``t x u`` looking left): the direction normal to the line of sight in which the look angle
  grows (outward and down);
* the critical perpendicular baseline ``B_crit = lambda R tan(theta) B_w / c`` (range bandwidth
  ``B_w``, incidence ``theta``): the two passes' ground-range spectra no longer overlap
  (Gatelli et al., IEEE TGRS 32(4), 1994; Bamler and Hartl, Inverse Problems 14, 1998, eq. 30);
* the height of ambiguity ``h_a = lambda R sin(theta) / (2 |B_perp|)``: the height that adds one
  2 pi cycle of interferometric phase (Hanssen, *Radar Interferometry*, 2001, eq. 2.5.13).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.radar import RadarParameters
from ..core.geometry import acquisition_geometry

__all__ = ["Baseline", "baseline"]


@dataclass(frozen=True)
class Baseline:
    """The baseline of a pass shifted by ``track_offset`` against the nominal pass (module docstring).

    Attributes
    ----------
    vector : float64 [3], m
        The track offset ``B``.
    along_track, parallel, perpendicular : float, m
        ``B . t``, ``B_par`` and ``B_perp``.
    critical : float, m
        The critical perpendicular baseline ``lambda R tan(theta) B_w / c``.
    height_of_ambiguity : float, m
        ``lambda R sin(theta) / (2 |B_perp|)``; infinite for ``B_perp = 0``.
    slant_range : float, m
        ``R``, nominal mid-aperture antenna to scene centre.
    """

    vector: np.ndarray
    along_track: float
    parallel: float
    perpendicular: float
    critical: float
    height_of_ambiguity: float
    slant_range: float


def baseline(params: RadarParameters) -> Baseline:
    """The baseline of ``params.track_offset`` (resolved parameters: ``scene_center`` and
    ``n_pulses`` set, as after :func:`sarmitsuba.scene.loader.load_scene`).

    Raises
    ------
    ParameterError
        Unresolved parameters (:func:`sarmitsuba.core.radar.acquisition_geometry`).
    """
    import dataclasses
    nominal = acquisition_geometry(dataclasses.replace(params, track_offset=(0.0, 0.0, 0.0)))
    b = np.asarray(params.track_offset, dtype=np.float64)
    t = nominal.track_direction
    antenna = nominal.positions[len(nominal.positions) // 2]
    to_sensor = antenna - nominal.scene_center
    r = float(np.linalg.norm(to_sensor))
    u = to_sensor / r
    e = np.cross(u, t) if params.look_side == "right" else np.cross(t, u)
    normal = b - (b @ t) * t
    perpendicular = float(normal @ e)
    theta = math.radians(params.incidence_angle)
    critical = params.wavelength * r * math.tan(theta) * params.bandwidth / SPEED_OF_LIGHT
    ambiguity = params.wavelength * r * math.sin(theta) / (2.0 * abs(perpendicular)) if perpendicular else math.inf
    return Baseline(vector=b, along_track=float(b @ t), parallel=float(normal @ u), perpendicular=perpendicular,
                    critical=critical, height_of_ambiguity=ambiguity, slant_range=r)
